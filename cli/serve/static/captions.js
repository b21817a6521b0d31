// Captions, the side-by-side layout and the meme download's link. The captions shown
// are a picture the server draws with the Meme download's own code (font, wrapping,
// fitting), laid over the result: the preview is what the download holds.
import { $, state } from "./state.js";

let pending = 0;

function updateCaptions() {
  $("original-figure").hidden = !$("side").checked;
  updateMemeLink();
  clearTimeout(pending);
  pending = setTimeout(showCaptions, 120); // one request per pause in typing
}

function showCaptions() {
  const layer = $("captions");
  const top = $("top").value;
  const bottom = $("bottom").value;
  if (!state.result || !(top.trim() || bottom.trim())) {
    layer.hidden = true;
    layer.removeAttribute("src");
    return;
  }
  layer.src = `/api/results/${state.result.result}/captions?${new URLSearchParams({ top, bottom })}`;
  layer.hidden = false;
}

function updateMemeLink() {
  if (!state.result) return;
  const query = new URLSearchParams({ top: $("top").value, bottom: $("bottom").value, side_by_side: $("side").checked ? "1" : "0" });
  $("dl-meme").href = `${state.result.downloads.meme}?${query}`;
}

export { updateCaptions, updateMemeLink };
