// One photo: upload, the server's result, and the clicks that fix the subject.
import { updateMemeLink } from "./captions.js";
import { adjusted, handleAt, showHandleCursor } from "./boxes.js";
import { hideClip, showClip } from "./clip.js";
import { drawOverlay, stopAnimation } from "./drawing.js";
import { choiceWords, foundAt, foundWords, onChoose } from "./found.js";
import { clearHover, forgetHover, loadHover } from "./hover.js";
import { resetZoom } from "./zoom.js";
import { post } from "./server.js";
import { $, clickedObjects, fingerWords, setStatus, showError, state } from "./state.js";

function renderOptions() {
  return { style: $("style").value, garment: $("garment").value, posture: $("posture").value };
}

// ------------------------------------------------------------------ upload
// Every answer belongs to one photo: leaving a photo (another dropped or opened, or
// "Another photo") starts a new generation, and an answer of an older one is dropped.
function leavePhoto() {
  state.generation += 1;
  state.inFlight = false;
  state.again = false;
  state.clickPending = false;
  stopAnimation();
  state.photo = null; // no click, render or download for the photo left
  state.result = null;
  state.cursor = null;
  hideClip();
  drawOverlay();
  forgetHover();
  resetZoom();
  return state.generation;
}

async function upload(file) {
  if (!file) return;
  showError("");
  if (state.maxUpload && file.size > state.maxUpload) {
    showError(`${file.name}: the file is larger than the server's upload limit (${Math.round(state.maxUpload / 1048576)} MB)`);
    return;
  }
  const generation = leavePhoto();
  state.item = null;
  opened(null, file.name); // in folder mode: no folder photo is open now, this one is only tried
  setStatus(`Putting jeans on ${file.name}…`, true);
  showLocal(file, generation);
  const form = new FormData();
  form.append("file", file, file.name);
  form.append("subject", $("subject").value);
  try {
    const answer = await post("/api/photos", form);
    if (generation === state.generation) start(answer, null);
  } catch (error) {
    if (generation !== state.generation) return;
    setStatus("");
    showError(error.message);
    $("frame").classList.remove("working");
    $("panel").inert = false;
    if (!state.result) { // nothing to show: back to the drop zone
      $("view").hidden = true;
      $("drop").hidden = false;
    }
  }
}

// The dropped photo at once, as the browser decodes it, veiled while the server works;
// a file the browser cannot show (RAW, TIFF) waits with the drop zone and the status line.
function showLocal(file, generation) {
  $("captions").hidden = true;
  const image = $("result");
  const local = URL.createObjectURL(file);
  image.addEventListener("error", () => {
    if (generation === state.generation && !state.result) {
      $("view").hidden = true;
      $("drop").hidden = false;
    }
  }, { once: true });
  image.src = local;
  $("original-figure").hidden = true;
  $("frame").classList.add("working");
  $("panel").inert = true;
  $("drop").hidden = true;
  $("view").hidden = false;
  setTimeout(() => URL.revokeObjectURL(local), 60_000);
}

function start(answer, item) {
  $("frame").classList.remove("working");
  $("panel").inert = false;
  state.photo = answer.photo;
  state.item = item;
  state.kind = answer.kind;
  state.name = answer.name;
  state.width = answer.width;
  state.height = answer.height;
  state.objects = [];
  state.current = 0;
  state.history = [];
  state.future = [];
  state.saved = null;
  $("drop").hidden = true;
  $("view").hidden = false;
  $("panel").hidden = false;
  $("save").hidden = item === null;
  $("original").src = `/api/photos/${answer.photo}/original`;
  if (answer.clicks && answer.saved_clicks) {
    state.objects = answer.saved_clicks.map((o) => ({ positive: o.positive, negative: o.negative, box: o.box || null }));
    // Each saved box and click is one step to undo, as if it had just been made.
    state.history = state.objects.flatMap((o, object) => [
      ...(o.box ? [{ object, box: o.box, before: null }] : []),
      ...["positive", "negative"].flatMap((sign) => o[sign].map(() => ({ object, sign }))),
    ]);
  }
  if (item !== null) state.saved = clicksKey(); // what the folder holds for this photo
  opened(item, answer.name, answer);
  show(answer);
  showClip(answer);
  updateControls();
  if (answer.kind === "photo") loadHover(answer.photo, state.generation);
}

// The photo now open, said to the page (folder.js marks its tile, or none for a photo
// only tried): ``item`` is its folder index or null, ``answer`` the server's when it is in.
function opened(item, name, answer = null) {
  document.dispatchEvent(new CustomEvent("jeanscv:opened", { detail: { item, name, answer } }));
}

// ------------------------------------------------------------------ results
function show(answer) {
  if (answer.key === undefined) answer.key = clicksKey(); // the clicks it was made from
  state.result = answer;
  stopAnimation();
  const image = $("result");
  image.src = answer.preview;
  const svg = $("overlay");
  svg.setAttribute("viewBox", `0 0 ${answer.width} ${answer.height}`);
  svg.setAttribute("preserveAspectRatio", "none");
  drawOverlay();
  for (const kind of ["image", "json", "svg", "gif", "clicks"]) {
    const link = $(`dl-${kind}`);
    link.href = answer.downloads[kind];
    link.classList.toggle("disabled", kind === "clicks" && !answer.clicks);
  }
  updateMemeLink();
  describe(answer);
}

// The status line for a result: its photo, and what wears the jeans: what was found
// ("found a cat (0.82)": the detector's class and score; "found the subject": classical
// finding), the animal chosen on the page, or the objects from the clicks.
function describe(answer) {
  if (!answer) return;
  const summary = answer.summary;
  const count = summary.objects === 1 ? "1 object" : `${summary.objects} objects`;
  if (state.kind !== "photo") {
    setStatus(`${state.name}: ${count}, found by ${summary.method}.`);
    return;
  }
  const others = (answer.detections || []).some((d) => !d.dressed);
  const choice = answer.clicks ? choiceWords(answer) : "";
  let text;
  if (choice) text = `${choice}, as you chose.`;
  else if (answer.clicks) text = `${count}, from your clicks.`;
  else if (summary.uncertain) text = `${foundWords(answer)}, but not sure it is the subject. ${others ? "Tap another box or click" : "Click"} the right thing.`;
  else text = `${foundWords(answer)}. Wrong thing? ${others ? "Tap another box, or click" : "Click"} the one that should wear them.`;
  setStatus(`${state.name}: ${fingerWords(text)}`); // "tap" on a touch screen
}

// A reason from the server in the page's words ("nothing clear there: tap inside the
// subject" on a touch screen); the photo's name at its start is left as it is.
function reasonWords(reason) {
  const name = `${state.name}: `;
  return reason.startsWith(name) ? name + fingerWords(reason.slice(name.length)) : fingerWords(reason);
}

async function rerender() {
  if (!state.photo) return;
  if (state.inFlight) {
    state.again = true; // send the newest clicks once this answer is in
    return;
  }
  state.inFlight = true;
  state.again = false;
  const fromClick = state.clickPending;
  state.clickPending = false;
  const sequence = ++state.sequence;
  const generation = state.generation;
  setStatus("Fitting…", true);
  try {
    const objects = clickedObjects();
    const answer = await post(`/api/photos/${state.photo}/render`, { objects, options: renderOptions() });
    answer.key = JSON.stringify(objects);
    if (generation !== state.generation) return; // another photo since: not this one's
    if (answer.nothing) {
      // Nothing found where clicked: an answer of its own (not a failed request), shown
      // as the reason, and the click is taken back.
      notUsed(answer.nothing, fromClick);
    } else if (sequence > state.shown) {
      state.shown = sequence;
      showError("");
      if (!state.again) show(answer);
    }
  } catch (error) {
    if (generation !== state.generation) return;
    notUsed(error.message, fromClick && error.status === 422);
  } finally {
    if (generation === state.generation) {
      state.inFlight = false;
      if (state.again) rerender();
    }
  }
}

// A render the server could not make from the clicks: its reason shown, and the click
// that asked for it (takeBackClick) taken back: the picture, outline and markers
// stay as they were before it.
function notUsed(reason, takeBackClick) {
  showError(reasonWords(reason));
  if (takeBackClick && !state.again) takeBack();
  else setStatus("");
}

function takeBack() {
  const last = state.history.pop();
  if (!last) return;
  stepBack(last);
  drawOverlay();
  updateControls();
  describe(state.result);
}

// ------------------------------------------------------------------ clicks
function photoPoint(event) {
  const rect = $("result").getBoundingClientRect();
  const x = ((event.clientX - rect.left) / rect.width) * state.width;
  const y = ((event.clientY - rect.top) / rect.height) * state.height;
  const clamp = (v, top) => Math.min(Math.max(v, 0), top - 0.01);
  return [Math.round(clamp(x, state.width) * 10) / 10, Math.round(clamp(y, state.height) * 10) / 10];
}

// ------------------------------------------------------------------ boxes
// A drag on the photo (mouse or pen; a finger in Box mode, where one finger does not
// scroll the zoomed photo) draws a box around the object; a click or tap stays a click.
// A second finger on the photo makes the drag a pinch (zoom.js): no box.
let drag = null;

function boxOf(a, b) {
  return [Math.min(a[0], b[0]), Math.min(a[1], b[1]), Math.max(a[0], b[0]), Math.max(a[1], b[1])];
}

function pointerDown(event) {
  if (drag && event.pointerId !== drag.pointer) { // a second finger: a pinch, not a box
    drag = null;
    state.dragged = true; // nor a click
    drawOverlay();
    return;
  }
  state.dragged = false;
  if (state.kind !== "photo" || !state.result || event.button !== 0) return;
  if (event.pointerType === "touch" && (!state.boxing || !event.isPrimary)) return; // a finger scrolls, outside Box mode
  // On a handle of the current object's box: that box's sides move (no click, no new box).
  drag = { pointer: event.pointerId, start: photoPoint(event), x: event.clientX, y: event.clientY, moved: false, handle: handleAt(event) };
}

function pointerMove(event) {
  if (!drag) {
    showHandleCursor(event);
    // Over an animal's box that a click would dress: a hand, as over a link.
    if (!$("frame").style.cursor && state.result && foundAt(photoPoint(event), state.negative || event.shiftKey) !== null) {
      $("frame").style.cursor = "pointer";
    }
    return;
  }
  if (event.pointerId !== drag.pointer) return;
  if (!drag.moved && Math.hypot(event.clientX - drag.x, event.clientY - drag.y) < 6) return;
  if (!drag.moved) $("frame").setPointerCapture(event.pointerId);
  drag.moved = true;
  if (drag.handle) drawOverlay(null, adjusted(state.objects[state.current].box, drag.handle, photoPoint(event)), true);
  else drawOverlay(null, boxOf(drag.start, photoPoint(event)));
}

function pointerUp(event) {
  if (!drag || event.pointerId !== drag.pointer) return;
  const done = drag;
  drag = null;
  if (done.handle) {
    adjustBox(done, event);
    return;
  }
  if (!done.moved) return; // a click: the click event adds it
  if (event.type === "pointercancel") {
    drawOverlay();
    return;
  }
  state.dragged = true;
  const box = boxOf(done.start, photoPoint(event));
  if (box[2] - box[0] < 2 || box[3] - box[1] < 2) {
    drawOverlay();
    return;
  }
  if (!state.objects[state.current]) state.objects[state.current] = emptyObject();
  const object = state.objects[state.current];
  state.history.push({ object: state.current, box, before: object.box || null });
  object.box = box;
  state.future = [];
  state.clickPending = true; // taken back if nothing is found in it
  changed();
}

// A handle let go: the box takes its new sides (one step to undo) and is segmented again.
function adjustBox(done, event) {
  state.dragged = true; // a press on a handle is no click, moved or not
  const object = state.objects[state.current];
  const box = done.moved && event.type !== "pointercancel" ? adjusted(object.box, done.handle, photoPoint(event)) : null;
  if (!box || box[2] - box[0] < 2 || box[3] - box[1] < 2) {
    drawOverlay();
    return;
  }
  state.history.push({ object: state.current, box, before: object.box });
  object.box = box;
  state.future = [];
  state.clickPending = true; // taken back if nothing is found in it
  changed();
}

function addClick(event) {
  if (state.kind !== "photo" || !state.result) return;
  event.preventDefault();
  const negative = state.negative || event.shiftKey || event.altKey || event.ctrlKey || event.metaKey || event.button === 2;
  if (state.dragged) { // the end of a drag: its box is made
    state.dragged = false;
    return;
  }
  addPoint(photoPoint(event), negative);
}

// A click at ``point`` (photo pixels) for the current object: the pointer's, or the keyboard cursor's.
// Inside a detected animal's box that is not dressed (the current object without clicks),
// it dresses that animal instead (found.js).
function addPoint(point, negative) {
  if (state.kind !== "photo" || !state.result) return;
  const found = foundAt(point, negative);
  if (found !== null) {
    chooseDetection(found);
    return;
  }
  if (!state.objects[state.current]) state.objects[state.current] = emptyObject();
  const object = state.objects[state.current];
  // A negative click first means "the automatic subject, minus this" (the server does it).
  (negative ? object.negative : object.positive).push(point);
  state.history.push({ object: state.current, sign: negative ? "negative" : "positive" });
  state.future = [];
  state.clickPending = true;
  changed();
}

function emptyObject() {
  return { positive: [], negative: [], box: null };
}

// A detected animal chosen (its label, or a click in its box): the current object becomes
// that animal's box, sent as a drawn box is (one step to undo; its clicks, if it had
// any, come back with Undo).
function chooseDetection(index) {
  const detection = state.result && state.result.detections && state.result.detections[index];
  if (!detection || state.kind !== "photo" || !state.photo) return;
  const box = detection.box.slice();
  if (!state.objects[state.current]) state.objects[state.current] = emptyObject();
  const object = state.objects[state.current];
  if (object.positive.length || object.negative.length) {
    state.history.push({ object: state.current, choose: box, before: JSON.stringify(object) });
    state.objects[state.current] = { positive: [], negative: [], box };
  } else {
    state.history.push({ object: state.current, box, before: object.box || null });
    object.box = box;
  }
  state.future = [];
  state.clickPending = true; // taken back if nothing is found in it
  changed();
}
onChoose(chooseDetection);

function clicksKey() {
  return JSON.stringify(clickedObjects());
}

// Undo and Redo: each step is a click ({object, sign}), a box ({object, box, before}), an
// animal chosen over clicks ({object, choose: its box, before: the object's clicks}) or a
// Reset ({reset: the clicks it cleared, current}); a new step forgets what could be redone.
function undo() {
  const last = state.history.pop();
  if (!last) return;
  state.future.push(stepBack(last));
  changed();
}

// Undo one step; what Redo needs to make it again.
function stepBack(last) {
  if (last.reset) { // the clicks a Reset cleared come back
    state.objects = JSON.parse(last.reset);
    state.current = last.current;
    return last;
  }
  if (last.choose) { // the object's clicks come back
    state.objects[last.object] = JSON.parse(last.before);
    return last;
  }
  const object = state.objects[last.object];
  let step = last;
  if ("box" in last) object.box = last.before;
  else step = { ...last, point: object[last.sign].pop() };
  if (object.positive.length === 0 && object.negative.length === 0 && !object.box
      && last.object === state.objects.length - 1 && last.object > 0) {
    state.objects.pop();
    state.current = Math.min(state.current, state.objects.length - 1);
  }
  return step;
}

function redo() {
  const next = state.future.pop();
  if (!next) return;
  if (next.reset) {
    clearClicks();
  } else {
    while (state.objects.length <= next.object) state.objects.push(emptyObject());
    const object = state.objects[next.object];
    if (next.choose) {
      state.objects[next.object] = { positive: [], negative: [], box: next.choose.slice() };
      state.history.push(next);
    } else if ("box" in next) {
      object.box = next.box;
      state.history.push(next);
    } else {
      object[next.sign].push(next.point);
      state.history.push({ object: next.object, sign: next.sign });
    }
    state.current = next.object;
  }
  changed();
}

function reset() {
  if (state.objects.length === 0) return;
  state.future = [];
  clearClicks();
  changed(); // the markers go now, not when the automatic result is in
}

function clearClicks() {
  state.history.push({ reset: JSON.stringify(state.objects), current: state.current }); // Undo brings them back
  state.objects = [];
  state.current = 0;
}

function changed() {
  clearHover(); // the next pointer move shows it again if a click would still be a first one
  drawOverlay();
  updateControls();
  rerender();
}

function newObject() {
  const last = state.objects[state.objects.length - 1];
  if (last && last.positive.length === 0 && last.negative.length === 0 && !last.box) {
    state.current = state.objects.length - 1;
  } else {
    state.objects.push(emptyObject());
    state.current = state.objects.length - 1;
  }
  drawOverlay();
  updateControls();
  setStatus(fingerWords(`Object ${state.current + 1}: click it.`));
}

// The click mode: Add, Remove (``negative``) or Box (``boxing``: a finger's drag draws a
// box, a tap adds as in Add mode). Shown on the buttons, the phone's bar and the badge.
function setMode(negative, boxing = false) {
  state.negative = negative;
  state.boxing = boxing && !negative;
  clearHover();
  const mode = state.boxing ? "box" : negative ? "remove" : "add";
  for (const [name, ids] of [["add", ["mode-add", "bar-add"]], ["remove", ["mode-remove", "bar-remove"]], ["box", ["mode-box", "bar-box"]]]) {
    for (const id of ids) $(id).setAttribute("aria-pressed", String(mode === name));
  }
  $("zoom").classList.toggle("boxing", state.boxing); // one finger draws there, it does not scroll
  const badge = $("mode-badge");
  badge.textContent = { add: "+ Add", remove: "\u2212 Remove", box: "\u25ad Box" }[mode];
  badge.classList.toggle("remove", mode === "remove");
  badge.classList.toggle("box", mode === "box");
}

function updateControls() {
  const photo = state.kind === "photo";
  for (const id of ["mode-add", "mode-remove", "mode-box", "new-object", "undo", "redo", "reset"]) $(id).disabled = !photo;
  $("undo").disabled = !photo || state.history.length === 0;
  $("bar-undo").disabled = $("undo").disabled;
  $("bar-add").disabled = $("bar-remove").disabled = $("bar-box").disabled = !photo;
  $("mode-badge").hidden = !photo;
  $("redo").disabled = !photo || state.future.length === 0;
  $("reset").disabled = !photo || state.objects.length === 0;
  $("new-object").disabled = !photo || clickedObjects().length === 0;
  // Save what differs from the folder's: new clicks, or none (back to automatic).
  const clicked = clickedObjects().length > 0;
  $("save").disabled = state.saved === null || clicksKey() === state.saved;
  $("save").textContent = clicked || state.saved === clicksKey() ? "Save to folder" : "Revert to automatic";
  const list = $("objects");
  list.replaceChildren();
  state.objects.forEach((object, index) => {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = `Object ${index + 1} (${object.positive.length}+ ${object.negative.length}\u2212${object.box ? ", box" : ""})`;
    button.setAttribute("aria-pressed", String(index === state.current));
    button.addEventListener("click", () => {
      state.current = index;
      updateControls();
      drawOverlay();
    });
    list.appendChild(button);
  });
}

export { addClick, addPoint, clickedObjects, describe, pointerDown, pointerMove, pointerUp, clicksKey, leavePhoto, newObject, redo, rerender, reset, setMode, start, undo, updateControls, upload };
