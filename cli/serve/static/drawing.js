// Drawing on the photo: the objects' outlines and the clicks (an SVG over the picture),
// and the fit played back.
import { currentBox, handleSquares } from "./boxes.js";
import { drawFound } from "./found.js";
import { $, SVG_NS, state } from "./state.js";

function rectangle(box, cls) {
  const rect = document.createElementNS(SVG_NS, "rect");
  rect.setAttribute("x", box[0]);
  rect.setAttribute("y", box[1]);
  rect.setAttribute("width", box[2] - box[0]);
  rect.setAttribute("height", box[3] - box[1]);
  rect.setAttribute("class", cls);
  return rect;
}

// draftBox: the box being dragged, drawn as it goes; with ``adjusting`` it stands for
// the current object's box (a handle is being dragged).
function drawOverlay(animatedJeans = null, draftBox = null, adjusting = false) {
  const svg = $("overlay");
  svg.replaceChildren();
  drawFound(); // the detected animals' boxes and labels
  const answer = state.result;
  if (!answer) return;
  svg.classList.toggle("no-marks", !state.marks);
  // Markers are a constant size on the screen, whatever the photo's size or zoom.
  const shown = $("result").clientWidth;
  const photoPixelsPerScreenPixel = shown > 0 ? answer.width / shown : Math.max(answer.width, answer.height) / 800;
  answer.objects.forEach((object, index) => {
    const other = answer.clicks && index !== state.current ? " other" : "";
    // Every ring in one path: the mask's holes stay holes (even-odd fill).
    const d = object.outline.map((ring) => "M" + ring.map((p) => `${p[0]},${p[1]}`).join("L") + "Z").join("");
    for (const cls of [`mask${other}`, "outline-shadow", `outline${other}`]) {
      const path = document.createElementNS(SVG_NS, "path");
      path.setAttribute("d", d);
      path.setAttribute("class", cls);
      svg.appendChild(path);
    }
  });
  if (animatedJeans) {
    for (const polygon of animatedJeans) {
      const shape = document.createElementNS(SVG_NS, "polygon");
      shape.setAttribute("points", polygon.map((p) => `${p[0]},${p[1]}`).join(" "));
      shape.setAttribute("class", "jeans-anim");
      svg.appendChild(shape);
    }
  }
  state.objects.forEach((object, index) => {
    if (object.box && !(adjusting && index === state.current)) {
      svg.appendChild(rectangle(object.box, `box${index === state.current ? "" : " faded"}`));
    }
  });
  if (draftBox) svg.appendChild(rectangle(draftBox, "box draft"));
  const handled = adjusting ? draftBox : currentBox();
  if (handled) for (const square of handleSquares(handled, 9 * photoPixelsPerScreenPixel, rectangle)) svg.appendChild(square);
  state.objects.forEach((object, index) => {
    for (const [sign, points] of [["pos", object.positive], ["neg", object.negative]]) {
      for (const [x, y] of points) {
        const dot = document.createElementNS(SVG_NS, "circle");
        dot.setAttribute("cx", x);
        dot.setAttribute("cy", y);
        dot.setAttribute("r", 6 * photoPixelsPerScreenPixel);
        dot.setAttribute("class", `click ${sign}${index === state.current ? "" : " faded"}`);
        svg.appendChild(dot);
      }
    }
  });
  if (state.cursor) { // the keyboard's cross (cursor.js)
    const [x, y] = state.cursor;
    const size = 12 * photoPixelsPerScreenPixel;
    const cross = document.createElementNS(SVG_NS, "path");
    cross.setAttribute("d", `M${x - size},${y}H${x + size}M${x},${y - size}V${y + size}`);
    cross.setAttribute("class", "cursor");
    svg.appendChild(cross);
  }
}

// ------------------------------------------------------------------ the fit, animated
// The animation plays the shown result's fit over the photo; a new result (a click
// answered mid-way) or another photo stops it, and the picture shown is always the
// newest result's, never one the animation put aside.
function watchFit() {
  const answer = state.result;
  if (!answer || state.animating) return;
  state.animating = true;
  const run = ++state.animation;
  const image = $("result");
  image.src = `/api/photos/${state.photo}/original`;
  const frames = Math.max(...answer.objects.map((o) => o.trajectory.length));
  const began = performance.now();
  const duration = 2500;
  const step = (now) => {
    if (run !== state.animation) return;
    const index = Math.min(frames - 1, Math.floor(((now - began) / duration) * frames));
    drawOverlay(answer.objects.map((o) => o.trajectory[Math.min(index, o.trajectory.length - 1)]));
    if (index < frames - 1) {
      requestAnimationFrame(step);
    } else {
      setTimeout(() => {
        if (run === state.animation) stopAnimation();
      }, 700);
    }
  };
  requestAnimationFrame(step);
}

function stopAnimation() {
  if (!state.animating) return;
  state.animation += 1;
  state.animating = false;
  if (state.result) $("result").src = state.result.preview;
  drawOverlay();
}

export { drawOverlay, stopAnimation, watchFit };
