// Clips: a GIF or a short video. Its first frame is the photo the editor shows and
// takes clicks on (they refer to frame 0); "Make the clip" sends the same clicks and
// options, shows how far the making is, then plays the clip with its jeans beside the
// frame and offers its download.
import { clickedObjects } from "./editor.js";
import { answerOf, post } from "./server.js";
import { $, setStatus, showError, state } from "./state.js";

let making = 0; // the newest making's number: leaving the clip or making it again ends the older one

function showClip(answer) {
  state.clip = answer.clip || null;
  hideResult();
  $("clip-group").hidden = !state.clip;
  if (!state.clip) return;
  const { frames, seconds } = state.clip;
  const length = `${frames ? `${frames} frames` : "several frames"}${seconds ? `, ${seconds} s` : ""}`;
  $("clip-about").textContent = `A clip (${length}): this is its first frame. Click the subject on it if needed, then make the clip.`;
  $("make-clip").disabled = false;
}

function hideClip() {
  making += 1;
  state.clip = null;
  $("clip-group").hidden = true;
  hideResult();
}

function hideResult() {
  $("clip-figure").hidden = true;
  $("clip-progress").hidden = true;
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

async function makeClip() {
  if (!state.photo || !state.clip) return;
  const number = ++making;
  const photo = state.photo;
  const total = state.clip.frames;
  hideResult();
  showError("");
  $("make-clip").disabled = true;
  const bar = $("clip-progress");
  bar.hidden = false;
  bar.removeAttribute("value"); // under way, how far not known yet
  if (total) bar.max = total;
  setStatus("Making the clip…", true);
  // A progress answer can arrive after the clip's own (its request was under way when
  // the clip was done): once finished, it says nothing.
  let finished = false;
  const timer = setInterval(async () => {
    try {
      const progress = await answerOf(await fetch(`/api/photos/${photo}/clip/progress`));
      if (finished || number !== making || !progress.done) return;
      if (total) bar.value = Math.min(progress.done, total);
      setStatus(`Making the clip: frame ${progress.done}${total ? ` of ${total}` : ""}…`, true);
    } catch (error) {
      // the making's own answer says what went wrong
    }
  }, 400);
  try {
    const answer = await post(`/api/photos/${photo}/clip`, { objects: clickedObjects(), options: clipOptions() });
    finished = true;
    if (number !== making) return;
    playClip(answer);
    const lost = answer.frames_without_jeans ? `, ${answer.frames_without_jeans} without jeans (the subject was out of sight)` : "";
    setStatus(`${answer.name}: ${answer.frames} frames${lost}.`);
  } catch (error) {
    finished = true;
    if (number !== making) return;
    setStatus("");
    showError(error.message);
  } finally {
    clearInterval(timer);
    if (number === making) {
      $("make-clip").disabled = false;
      bar.hidden = true;
    }
  }
}

// The clip plays beside the first frame: an animated picture in an <img>, a video in a <video>.
function playClip(answer) {
  const isVideo = answer.media.startsWith("video/");
  const player = isVideo ? $("clip-video") : $("clip-image");
  player.src = answer.clip;
  player.hidden = false;
  $("clip-figure").hidden = false;
  const link = $("dl-clip");
  link.href = `${answer.clip}?download=1`;
  link.download = answer.name;
  link.textContent = `Download the clip (${answer.format.toUpperCase()})`;
  link.hidden = false;
}

function wireClip() {
  $("make-clip").addEventListener("click", makeClip);
}

export { hideClip, showClip, wireClip };
