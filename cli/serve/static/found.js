// What the detector found: each detected animal's box, a thin outline labelled with its
// class and score ("cat 0.82"), the one wearing the jeans highlighted. The label is a
// button: a click or tap on it dresses that animal (its box is sent as the object's box,
// as a drawn box is). A click inside an animal's box that is not dressed does the same
// while the current object has no clicks of its own; everywhere else the photo takes
// clicks as before: the outlines, and the dressed one's label, let every pointer event
// through to it.
import { $, clickedObjects, state } from "./state.js";

let chooser = null; // editor.js's: dress the detection of this index
let drawnKey = ""; // what the layer shows now (it is rebuilt only when that changes)

function onChoose(choose) {
  chooser = choose;
}

function same(a, b) {
  return Boolean(a && b) && a.every((v, i) => Math.abs(v - b[i]) <= 0.51);
}

// The current clicks hold an object made from this box (a choice, or a box drawn on it).
function chosen(box) {
  return state.objects.some((o) => o.box && same(o.box, box));
}

// Per detection, whether it wears the jeans: the server's word for the shown result, and
// at once for a box just chosen (before the server answers).
function dressedFlags() {
  const answer = state.result;
  const found = (answer && answer.detections) || [];
  const stale = !answer || answer.key !== JSON.stringify(clickedObjects()); // the answer is for other clicks
  return found.map((d) => chosen(d.box) || (!stale && d.dressed));
}

// The detection a click at ``point`` (photo pixels) dresses, or null: an animal's box not
// dressed, while the current object has no clicks of its own (none, or only a box), the
// outlines are shown and the click is a positive one. The smallest such box holding it.
function foundAt(point, negative = state.negative) {
  const answer = state.result;
  if (!answer || !answer.detections || !answer.detections.length || state.kind !== "photo" || !state.marks || negative) return null;
  const object = state.objects[state.current];
  if (object && (object.positive.length || object.negative.length)) return null;
  const dressed = dressedFlags();
  let best = null;
  let area = Infinity;
  answer.detections.forEach((d, index) => {
    const [x0, y0, x1, y1] = d.box;
    if (dressed[index] || point[0] < x0 || point[0] >= x1 || point[1] < y0 || point[1] >= y1) return;
    if ((x1 - x0) * (y1 - y0) < area) {
      best = index;
      area = (x1 - x0) * (y1 - y0);
    }
  });
  return best;
}

// The box a pointer over it would dress, outlined brighter (null: none).
function showFoundAt(index) {
  for (const box of $("found").querySelectorAll(".found-box")) box.classList.toggle("hovered", Number(box.dataset.index) === index);
}

function percent(value, whole) {
  return `${((100 * value) / whole).toFixed(3)}%`;
}

// The layer over the photo (HTML, laid out in shares of the photo: it follows the zoom).
function drawFound() {
  const layer = $("found");
  const answer = state.result;
  const found = (answer && answer.detections) || [];
  const dressed = dressedFlags();
  const key = JSON.stringify([state.photo, state.width, state.height, found.map((d) => d.box), dressed,
    state.objects.map((o) => o.box), state.marks, state.kind]);
  if (key === drawnKey) return;
  drawnKey = key;
  const focused = document.activeElement && layer.contains(document.activeElement) ? document.activeElement.dataset.index : null;
  layer.replaceChildren();
  layer.hidden = !found.length || state.kind !== "photo" || !state.marks;
  if (layer.hidden) return;
  found.forEach((d, index) => {
    const [x0, y0, x1, y1] = d.box;
    const place = (element) => {
      element.style.left = percent(x0, state.width);
      element.style.top = percent(y0, state.height);
      element.style.width = percent(x1 - x0, state.width);
      element.style.height = percent(y1 - y0, state.height);
    };
    // A box the current clicks hold is drawn as theirs (dashed, with handles): not twice.
    if (!chosen(d.box)) {
      const box = document.createElement("div");
      box.className = `found-box${dressed[index] ? " dressed" : ""}`;
      box.dataset.index = index;
      place(box);
      layer.appendChild(box);
    }
    const label = document.createElement("button");
    label.type = "button";
    label.className = `found-label${dressed[index] ? " dressed" : ""}${chosen(d.box) ? " handled" : ""}`;
    label.dataset.index = index;
    const score = Number(d.score).toFixed(2);
    label.textContent = `${d.class} ${score}`;
    label.setAttribute("aria-pressed", String(dressed[index]));
    label.setAttribute("aria-label", dressed[index] ? `the ${d.class} (${score}) wears the jeans` : `dress the ${d.class} (${score})`);
    label.title = dressed[index] ? "wears the jeans" : `dress this ${d.class}`;
    if (dressed[index]) label.tabIndex = -1; // no choice to make there (Tab goes on to the others)
    // Its bottom-left corner on the box's (inside the photo, where the box reaches its top).
    label.style.left = percent(x0, state.width);
    label.style.bottom = percent(state.height - y1, state.height);
    // The label is the photo's no click: a press on it starts no box and adds no point.
    for (const type of ["pointerdown", "contextmenu"]) label.addEventListener(type, (e) => e.stopPropagation());
    label.addEventListener("click", (e) => {
      e.stopPropagation();
      e.preventDefault();
      if (!dressed[index] && chooser) chooser(index);
    });
    layer.appendChild(label);
  });
  if (focused !== null) layer.querySelector(`button[data-index="${focused}"]`)?.focus();
}

// The status line's words for what was found: "found a cat (0.82)", or "found the subject".
function foundWords(answer) {
  const detection = answer && answer.summary && answer.summary.detection;
  if (!detection) return "found the subject";
  const name = detection.class;
  return `found ${/^[aeiou]/.test(name) ? "an" : "a"} ${name} (${Number(detection.score).toFixed(2)})`;
}

// The detection every clicked object was chosen as, when each was (e.g. "the cat (0.51)").
function choiceWords(answer) {
  const found = (answer && answer.detections) || [];
  const objects = state.objects.filter((o) => o.positive.length || o.negative.length || o.box);
  if (!objects.length || objects.some((o) => o.positive.length || o.negative.length)) return "";
  const names = objects.map((o) => found.find((d) => same(d.box, o.box)));
  if (names.some((d) => !d)) return "";
  return names.map((d) => `the ${d.class} (${Number(d.score).toFixed(2)})`).join(" and ");
}

export { choiceWords, drawFound, foundAt, foundWords, onChoose, showFoundAt };
