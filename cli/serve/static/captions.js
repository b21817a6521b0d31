// Captions, the side-by-side layout and the meme download's link. The captions shown
// are a picture the server draws with the Meme download's own code (font, wrapping,
// fitting), laid over the result: the preview is what the download holds. The server
// also says how it fitted each caption (lines, font size, cut); the page says when a
// caption is too long to fit even at the smallest size.
import { $, state } from "./state.js";

let pending = 0;
let asked = 0; // caption pictures asked for: only the newest is shown
let shown = ""; // the object URL of the caption picture shown

function updateCaptions() {
  $("original-figure").hidden = !$("side").checked;
  updateMemeLink();
  clearTimeout(pending);
  pending = setTimeout(showCaptions, 120); // one request per pause in typing
}

function setLayer(url, query, fit) {
  const layer = $("captions");
  if (shown) URL.revokeObjectURL(shown);
  shown = url;
  if (url) layer.src = url;
  else layer.removeAttribute("src");
  layer.hidden = !url;
  layer.dataset.query = query; // the captions this picture is for
  layer.dataset.fit = JSON.stringify(fit);
  const cut = ["top", "bottom"].filter((key) => fit[key] && fit[key].cut);
  const long = $("caption-long");
  long.hidden = cut.length === 0;
  long.textContent = cut.length === 0 ? "" : `The ${cut.join(" and ")} caption${cut.length > 1 ? "s are" : " is"} too long for this picture, even in small letters on many lines: cut where it ends in "…". Shorten it.`;
}

async function showCaptions() {
  const top = $("top").value;
  const bottom = $("bottom").value;
  const query = new URLSearchParams({ top, bottom }).toString();
  const number = ++asked;
  if (!state.result || !(top.trim() || bottom.trim())) {
    setLayer("", query, {});
    return;
  }
  const result = state.result;
  let picture = null;
  let fit = {};
  try {
    const response = await fetch(`/api/results/${result.result}/captions?${query}`);
    if (response.ok) {
      fit = JSON.parse(response.headers.get("X-Caption-Fit") || "{}");
      picture = await response.blob();
    }
  } catch (e) {
    picture = null; // the server has gone: no captions shown, as for an expired result
  }
  // Typed on meanwhile, or another result (a photo dropped): a newer picture is on its way.
  if (number !== asked || state.result !== result) return;
  setLayer(picture ? URL.createObjectURL(picture) : "", query, fit);
}

function updateMemeLink() {
  if (!state.result) return;
  const query = new URLSearchParams({ top: $("top").value, bottom: $("bottom").value, side_by_side: $("side").checked ? "1" : "0" });
  $("dl-meme").href = `${state.result.downloads.meme}?${query}`;
}

export { updateCaptions, updateMemeLink };
