// Captions, the side-by-side layout and the meme download's link.
import { $, state } from "./state.js";

function updateCaptions() {
  const frame = $("frame");
  const size = Math.max(12, Math.round(frame.clientHeight / 9));
  for (const [id, input] of [["cap-top", "top"], ["cap-bottom", "bottom"]]) {
    const caption = $(id);
    caption.textContent = $(input).value;
    caption.style.fontSize = `${size}px`;
  }
  $("original-figure").hidden = !$("side").checked;
  updateMemeLink();
}

function updateMemeLink() {
  if (!state.result) return;
  const query = new URLSearchParams({ top: $("top").value, bottom: $("bottom").value, side_by_side: $("side").checked ? "1" : "0" });
  $("dl-meme").href = `${state.result.downloads.meme}?${query}`;
}

export { updateCaptions, updateMemeLink };
