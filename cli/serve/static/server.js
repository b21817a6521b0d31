// The server's API: answers as JSON, or an Error carrying the server's reason; a busy
// server (503) is asked again.
import { setStatus } from "./state.js";

async function answerOf(response) {
  let data = null;
  try {
    data = await response.json();
  } catch (e) {
    data = null;
  }
  if (!response.ok) {
    const reason = data && data.error ? data.error : `the server answered ${response.status}`;
    const error = new Error(reason);
    error.status = response.status;
    error.retry = Number(response.headers.get("Retry-After") || 0);
    throw error;
  }
  return data;
}

async function post(url, body, retries = 3) {
  for (let attempt = 0; ; attempt++) {
    const response = await fetch(url, body instanceof FormData
      ? { method: "POST", body }
      : { method: "POST", body: JSON.stringify(body), headers: { "Content-Type": "application/json" } });
    if (response.status === 503 && attempt < retries) {
      setStatus("The server is busy: trying again…", true);
      await new Promise((r) => setTimeout(r, 1000 * (Number(response.headers.get("Retry-After")) || 2)));
      continue;
    }
    return answerOf(response);
  }
}

export { answerOf, post };
