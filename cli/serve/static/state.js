// The page's state, and the status and error lines every part of the page writes to.

const $ = (id) => document.getElementById(id);

const SVG_NS = "http://www.w3.org/2000/svg";

const state = {
  photo: null, // id
  item: null, // folder item index, when opened from the folder
  kind: "photo",
  name: "",
  width: 0,
  height: 0,
  objects: [], // [{positive: [[x, y]], negative: [[x, y]]}]
  current: 0,
  history: [], // [{object, sign}] or [{reset, current}] for undo
  future: [], // the steps undone, for redo
  saved: null, // the folder's clicks for this photo (clicksKey()), null outside folder mode
  result: null, // last answer of the server
  negative: false, // Remove mode (the touch toggle; Shift with a mouse)
  boxing: false, // Box mode: a one-finger drag on the photo draws a box (a mouse's drag always does)
  sequence: 0, // renders sent
  shown: 0, // the newest render shown
  inFlight: false,
  again: false,
  cursor: null, // the keyboard's cross on the photo ([x, y]), while the photo has the keyboard's focus
  dragged: false, // the press that ends now was a drag (its box is made; it is no click)
  clickPending: false, // the next render was asked for by a click (taken back if it fails)
  animating: false,
  marks: true, // the outline, mask and clicks drawn over the photo (O hides them)
  animation: 0, // the running animation's number (a newer one, or a stop, ends it)
  generation: 0, // the photo's number: answers for an earlier one are dropped
  clip: null, // a clip's frames, seconds and format when the photo is a clip's first frame
};

function setStatus(text, busy = false) {
  $("status").textContent = text;
  $("status").classList.toggle("busy", busy);
}

function showError(text) {
  $("error").textContent = text;
  $("error").hidden = !text;
}

// A touch screen (no hover, a coarse pointer: a phone or a tablet): the page speaks of
// fingers there ("tap"), as the CSS's .for-touch and .for-pointer words do.
function touchScreen() {
  return window.matchMedia("(hover: none) and (pointer: coarse)").matches;
}

// The page's words for the screen it is on: "click" becomes "tap" on a touch screen.
function fingerWords(text) {
  return touchScreen() ? text.replace(/\bclick\b/g, "tap").replace(/\bClick\b/g, "Tap") : text;
}

// The clicks to send: the objects that have a click or a box (negative clicks alone are
// an object too: the automatic subject minus them).
function clickedObjects() {
  return state.objects.filter((o) => o.positive.length > 0 || o.negative.length > 0 || o.box)
    .map((o) => (o.box ? { positive: o.positive, negative: o.negative, box: o.box } : { positive: o.positive, negative: o.negative }));
}

export { $, SVG_NS, clickedObjects, fingerWords, setStatus, showError, state, touchScreen };
