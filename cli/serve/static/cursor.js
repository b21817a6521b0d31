// The keyboard's pointer on the photo: with the photo focused (Tab), the arrow keys move
// a cross (Shift: farther), Enter or Space clicks there in the current mode, and the
// hover preview shows what that click would take.
import { addPoint } from "./editor.js";
import { clearHover, hoverAt } from "./hover.js";
import { drawOverlay } from "./drawing.js";
import { $, state } from "./state.js";

const STEP = 0.02; // of the photo's long side; Shift: five times

// The cross is drawn with the overlay (state.cursor); the preview follows it.
function showCursor() {
  drawOverlay();
  if (state.cursor) hoverAt(state.cursor[0] / state.width, state.cursor[1] / state.height);
}

function focused() {
  // A mouse click focuses the photo too: the cross is for the keyboard's focus only.
  if (!state.result || state.kind !== "photo" || !$("frame").matches(":focus-visible")) return;
  state.cursor = state.cursor || [state.width / 2, state.height / 2];
  showCursor();
}

function blurred() {
  if (!state.cursor) return;
  state.cursor = null;
  drawOverlay();
  clearHover();
}

function keyOnPhoto(event) {
  const cursor = state.cursor;
  if (!cursor || event.ctrlKey || event.metaKey || event.altKey) return;
  const step = STEP * Math.max(state.width, state.height) * (event.shiftKey ? 5 : 1);
  const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
  if (event.key in moves) {
    const [dx, dy] = moves[event.key];
    state.cursor = [Math.min(state.width - 0.5, Math.max(0, cursor[0] + dx)), Math.min(state.height - 0.5, Math.max(0, cursor[1] + dy))];
    showCursor();
  } else if (event.key === "Enter" || event.key === " ") {
    addPoint([Math.round(cursor[0] * 10) / 10, Math.round(cursor[1] * 10) / 10], state.negative);
    showCursor(); // drawn again over the new markers
  } else {
    return;
  }
  event.preventDefault();
  event.stopPropagation(); // the arrows are the cursor's here, not the folder's
}

function wireCursor() {
  const frame = $("frame");
  frame.addEventListener("focus", focused);
  frame.addEventListener("blur", blurred);
  frame.addEventListener("keydown", keyOnPhoto);
}

export { wireCursor };
