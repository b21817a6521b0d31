// Clips: a GIF or a short video. Its first frame is the photo the editor shows and
// takes clicks on (they refer to frame 0); "Make the clip" sends the same clicks and
// options, shows how far the making is frame by frame, then plays the clip with its
// jeans beside the frame, scrolled into view, and offers its download.
import { clickedObjects } from "./editor.js";
import { answerOf } from "./server.js";
import { $, fingerWords, setStatus, showError, state } from "./state.js";

let making = 0; // the newest making's number: leaving the clip or making it again ends the older one
let request = null; // the running making's AbortController: aborting closes its connection,
// and the server stops the making at its next frame (it makes clips only for someone waiting)
const POLL_MS = 250; // how often the page asks how far the making is (a tiny answer)

function stopMaking() {
  making += 1;
  if (request) request.abort();
  request = null;
}

function showClip(answer) {
  state.clip = answer.clip || null;
  hideResult();
  $("clip-group").hidden = !state.clip;
  if (!state.clip) return;
  const { frames, seconds } = state.clip;
  const length = `${frames ? `${frames} frames` : "several frames"}${seconds ? `, ${seconds} s` : ""}`;
  $("clip-about").textContent = fingerWords(`A clip (${length}): this is its first frame. Click the subject on it if needed, then make the clip.`);
  $("make-clip").disabled = false;
}

function hideClip() {
  stopMaking();
  state.clip = null;
  $("clip-group").hidden = true;
  hideResult();
}

function hideResult() {
  $("clip-figure").hidden = true;
  $("clip-progress").hidden = true;
  counter().hidden = true;
  $("dl-clip").hidden = true;
  const image = $("clip-image");
  image.hidden = true;
  image.removeAttribute("src");
  const video = $("clip-video");
  video.hidden = true;
  if (video.getAttribute("src")) {
    video.pause();
    video.removeAttribute("src");
    video.load();
  }
}

function clipOptions() {
  return {
    style: $("style").value,
    garment: $("garment").value,
    posture: $("posture").value,
    top: $("top").value,
    bottom: $("bottom").value,
    side_by_side: $("side").checked,
  };
}

// The words under the bar ("frame 2 of 3"), made once beside it.
function counter() {
  let line = $("clip-count");
  if (!line) {
    line = document.createElement("p");
    line.id = "clip-count";
    line.className = "hint";
    line.hidden = true;
    $("clip-progress").after(line);
  }
  return line;
}

// How far the making is: `done` frames made of `total` (null: unknown), shown on the bar,
// under it and in the status line. The frame under way is the one named.
function showProgress(done, total) {
  const bar = $("clip-progress");
  let words;
  if (total) {
    bar.max = total;
    bar.value = Math.min(done, total);
    words = done < total ? `frame ${done + 1} of ${total}` : `all ${total} frames made, writing the clip`;
  } else {
    bar.removeAttribute("value"); // under way, how far not known
    words = `frame ${done + 1}`;
  }
  bar.setAttribute("aria-valuetext", words);
  const line = counter();
  line.textContent = `Making the clip: ${words}…`;
  line.hidden = false;
  setStatus(`Making the clip: ${words}…`, true);
}

// POST the making, as server.js's post does (a busy server is asked again), but abortable.
async function postMaking(url, body, signal, retries = 3) {
  for (let attempt = 0; ; attempt++) {
    const response = await fetch(url, {
      method: "POST",
      body: JSON.stringify(body),
      headers: { "Content-Type": "application/json" },
      signal,
    });
    if (response.status === 503 && attempt < retries) {
      setStatus("The server is busy: trying again…", true);
      await new Promise((r) => setTimeout(r, 1000 * (Number(response.headers.get("Retry-After")) || 2)));
      if (signal.aborted) throw new DOMException("aborted", "AbortError");
      continue;
    }
    return answerOf(response);
  }
}

async function makeClip() {
  if (!state.photo || !state.clip) return;
  stopMaking(); // an older making of this page is stopped (its connection closed)
  const number = making;
  const controller = new AbortController();
  request = controller;
  const photo = state.photo;
  const total = state.clip.frames;
  hideResult();
  showError("");
  $("make-clip").disabled = true;
  $("clip-progress").hidden = false;
  showProgress(0, total); // from the first moment: the clip's length is known from its header
  // A progress answer can arrive after the clip's own (its request was under way when
  // the clip was done): once finished, it says nothing.
  let finished = false;
  let asking = false;
  const timer = setInterval(async () => {
    if (asking) return; // one question at a time on a slow server
    asking = true;
    try {
      const progress = await answerOf(await fetch(`/api/photos/${photo}/clip/progress`));
      if (!finished && number === making) showProgress(progress.done, progress.frames || total);
    } catch (error) {
      // the making's own answer says what went wrong
    } finally {
      asking = false;
    }
  }, POLL_MS);
  try {
    const answer = await postMaking(
      `/api/photos/${photo}/clip`,
      { objects: clickedObjects(), options: clipOptions() },
      controller.signal,
    );
    finished = true;
    if (number !== making) return;
    playClip(answer);
    const lost = answer.frames_without_jeans ? `, ${answer.frames_without_jeans} without jeans (the subject was out of sight)` : "";
    setStatus(`${answer.name}: ${answer.frames} frames${lost}.`);
  } catch (error) {
    finished = true;
    if (number !== making) return; // stopped by the page: a newer making or another photo
    setStatus("");
    showError(error.message);
  } finally {
    clearInterval(timer);
    if (number === making) {
      request = null;
      $("make-clip").disabled = false;
      $("clip-progress").hidden = true;
      counter().hidden = true;
    }
  }
}

// The clip plays beside the first frame: an animated picture in an <img>, a video in a <video>.
function playClip(answer) {
  const isVideo = answer.media.startsWith("video/");
  const player = isVideo ? $("clip-video") : $("clip-image");
  // Scrolled into view once its size is known (it appears beside or below the frame,
  // often out of view), and at once, so that the first look goes there.
  player.addEventListener(isVideo ? "loadedmetadata" : "load", showMade, { once: true });
  player.src = answer.clip;
  player.hidden = false;
  $("clip-figure").hidden = false;
  showMade();
  const link = $("dl-clip");
  link.href = `${answer.clip}?download=1`;
  link.download = answer.name;
  link.textContent = `Download the clip (${answer.format.toUpperCase()})`;
  link.hidden = false;
}

function showMade() {
  const figure = $("clip-figure");
  if (figure.hidden) return;
  const still = window.matchMedia("(prefers-reduced-motion: reduce)").matches;
  figure.scrollIntoView({ block: "nearest", inline: "nearest", behavior: still ? "auto" : "smooth" });
}

function wireClip() {
  $("make-clip").addEventListener("click", makeClip);
}

export { hideClip, showClip, wireClip };
