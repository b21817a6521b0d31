// Zoom: the photo shown larger (the + and − buttons, or a pinch on a touch screen),
// scrolled in its box; clicks land on the photo's pixels whatever the zoom.
import { drawOverlay } from "./drawing.js";
import { $ } from "./state.js";

const MOST = 4;
let level = 1;
let fitted = 0; // the photo's width at level 1 (screen pixels)
const touches = new Map(); // pointer id -> [x, y], the fingers on the photo
let pinch = null; // {distance, level} when two fingers came down
let pinchedAt = -Infinity;

// Zoom to ``wanted`` keeping the photo's point under (x, y) (default: the box's centre) there.
function setZoom(wanted, x = null, y = null) {
  const box = $("zoom");
  const image = $("result");
  const next = Math.min(MOST, Math.max(1, wanted));
  // (The layout's width, not the picture's: a new result's picture may be loading.)
  if (Math.abs(next - level) < 0.01 || !image.clientWidth) return;
  const outer = box.getBoundingClientRect();
  const px = x ?? outer.left + outer.width / 2;
  const py = y ?? outer.top + outer.height / 2;
  const before = image.getBoundingClientRect();
  const fx = (px - before.left) / before.width;
  const fy = (py - before.top) / before.height;
  if (level === 1) fitted = image.clientWidth;
  level = next;
  const zoomed = level > 1;
  box.classList.toggle("zoomed", zoomed);
  image.style.width = zoomed ? `${fitted * level}px` : "";
  image.style.maxWidth = zoomed ? "none" : "";
  image.style.maxHeight = zoomed ? "none" : "";
  const after = image.getBoundingClientRect();
  box.scrollLeft += after.left + fx * after.width - px;
  box.scrollTop += after.top + fy * after.height - py;
  showLevel();
  drawOverlay(); // markers stay their size on the screen
}

// Back to the fitted photo (another photo opened).
function resetZoom() {
  level = 1;
  $("zoom").classList.remove("zoomed");
  const image = $("result");
  image.style.width = image.style.maxWidth = image.style.maxHeight = "";
  showLevel();
}

function showLevel() {
  $("zoom-out").disabled = level <= 1;
  $("zoom-in").disabled = level >= MOST;
  $("zoom").dataset.zoom = level.toFixed(2);
}

function fingerDown(event) {
  if (event.pointerType !== "touch") return;
  touches.set(event.pointerId, [event.clientX, event.clientY]);
  if (touches.size === 2) pinch = { distance: spread(), level };
}

function fingerMove(event) {
  if (!touches.has(event.pointerId)) return;
  touches.set(event.pointerId, [event.clientX, event.clientY]);
  if (!pinch || touches.size !== 2) return;
  const [[ax, ay], [bx, by]] = [...touches.values()];
  setZoom(pinch.level * (spread() / Math.max(pinch.distance, 1)), (ax + bx) / 2, (ay + by) / 2);
  pinchedAt = performance.now();
}

function fingerUp(event) {
  touches.delete(event.pointerId);
  if (touches.size < 2) pinch = null;
}

function spread() {
  const [[ax, ay], [bx, by]] = [...touches.values()];
  return Math.hypot(ax - bx, ay - by);
}

function wireZoom() {
  const box = $("zoom");
  $("zoom-in").addEventListener("click", () => setZoom(level * 1.5));
  $("zoom-out").addEventListener("click", () => setZoom(level / 1.5));
  box.addEventListener("pointerdown", fingerDown);
  box.addEventListener("pointermove", fingerMove);
  box.addEventListener("pointerup", fingerUp);
  box.addEventListener("pointercancel", fingerUp);
  // The fingers of a pinch lifted are no click on the photo.
  box.addEventListener("click", (event) => {
    if (performance.now() - pinchedAt < 500) {
      event.stopPropagation();
      event.preventDefault();
    }
  }, true);
  showLevel();
}

export { resetZoom, wireZoom };
