// A drawn box's handles: eight (corners and edges) on the current object's box, sized in
// screen pixels; dragging one moves those sides, and the release segments again.
import { $, state } from "./state.js";

const HANDLES = ["nw", "n", "ne", "e", "se", "s", "sw", "w"];
const CURSORS = { nw: "nwse-resize", se: "nwse-resize", ne: "nesw-resize", sw: "nesw-resize", n: "ns-resize", s: "ns-resize", e: "ew-resize", w: "ew-resize" };
const REACH = 10; // screen pixels from a handle's centre that grab it (a finger: twice that)

// A handle's point on the box (photo pixels).
function handlePoint(box, handle) {
  const x = handle.includes("w") ? box[0] : handle.includes("e") ? box[2] : (box[0] + box[2]) / 2;
  const y = handle.includes("n") ? box[1] : handle.includes("s") ? box[3] : (box[1] + box[3]) / 2;
  return [x, y];
}

// The current object's box, when it has one that can be adjusted now.
function currentBox() {
  const object = state.objects[state.current];
  return state.kind === "photo" && state.result && state.marks && object && object.box ? object.box : null;
}

// The handle under the pointer (the nearest within REACH screen pixels), or null.
function handleAt(event) {
  const box = currentBox();
  if (!box) return null;
  const rect = $("result").getBoundingClientRect();
  let best = null;
  let nearest = event.pointerType === "touch" ? 2 * REACH : REACH;
  for (const handle of HANDLES) {
    const [x, y] = handlePoint(box, handle);
    const distance = Math.hypot(rect.left + (x / state.width) * rect.width - event.clientX,
      rect.top + (y / state.height) * rect.height - event.clientY);
    if (distance <= nearest) {
      best = handle;
      nearest = distance;
    }
  }
  return best;
}

// The box with the handle's sides moved to ``point``, as (x0, y0, x1, y1) again.
function adjusted(box, handle, point) {
  let [x0, y0, x1, y1] = box;
  if (handle.includes("w")) x0 = point[0];
  if (handle.includes("e")) x1 = point[0];
  if (handle.includes("n")) y0 = point[1];
  if (handle.includes("s")) y1 = point[1];
  return [Math.min(x0, x1), Math.min(y0, y1), Math.max(x0, x1), Math.max(y0, y1)];
}

// The handles as squares (the overlay's own SVG elements), ``size`` photo pixels wide.
function handleSquares(box, size, make) {
  return HANDLES.map((handle) => {
    const [x, y] = handlePoint(box, handle);
    return make([x - size / 2, y - size / 2, x + size / 2, y + size / 2], `handle ${handle}`);
  });
}

// The pointer's cursor over the photo: a resize arrow over a handle.
function showHandleCursor(event) {
  const handle = event.buttons === 0 ? handleAt(event) : null;
  $("frame").style.cursor = handle ? CURSORS[handle] : "";
}

export { adjusted, currentBox, handleAt, handleSquares, showHandleCursor };
