// The hover preview: as the pointer moves over the photo, the outline and a light fill of
// what a first click there would take. The server sends the photo's first-click map once
// (superpixel labels, the region each superpixel's click takes, each region's
// superpixels); every pointer move is a lookup and a cached picture, no request.
import { foundAt, showFoundAt } from "./found.js";
import { $, state } from "./state.js";

let map = null; // the shown photo's map, once it is in
let shown = -1; // the region drawn (-1: none)
const pictures = new Map(); // region -> ImageData, the latest few

async function unpack(text) {
  const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

// Asked for once a photo's result is shown; an answer for a photo left is dropped.
async function loadHover(photo, generation) {
  forgetHover();
  try {
    const response = await fetch(`/api/photos/${photo}/hover`);
    if (!response.ok) return; // no preview (the photo expired, or the server is busy): clicks still work
    const data = await response.json();
    const [labels, choice, regions] = await Promise.all([data.labels, data.choice, data.regions].map(unpack));
    if (generation !== state.generation) return;
    map = {
      width: data.width,
      height: data.height,
      count: data.count,
      labels: new Uint16Array(labels.buffer),
      choice: new Int16Array(choice.buffer),
      regions,
      rowBytes: Math.ceil(data.count / 8),
    };
    map.seams = seams(map.labels, map.width);
    // The centre's region drawn now, off screen: the first move then finds the drawing
    // code compiled (interpreted, its first picture took the page 30-70 ms).
    const centre = map.choice[map.labels[(map.height >> 1) * map.width + (map.width >> 1)]];
    if (centre >= 0) picture(centre);
    const canvas = $("hover");
    canvas.width = map.width;
    canvas.height = map.height;
    $("frame").dataset.hover = "ready";
  } catch (error) {
    // The preview is a help, not a step: without it the page works as before.
  }
}

// The pixels with a 4-neighbour in another superpixel (where a region's edge can be).
function seams(labels, width) {
  const found = [];
  for (let i = 0; i < labels.length; i++) {
    const x = i % width;
    if ((x < width - 1 && labels[i + 1] !== labels[i]) || (x > 0 && labels[i - 1] !== labels[i])
      || (i + width < labels.length && labels[i + width] !== labels[i]) || (i >= width && labels[i - width] !== labels[i])) found.push(i);
  }
  return Int32Array.from(found);
}

function forgetHover() {
  map = null;
  pictures.clear();
  clearHover();
  delete $("frame").dataset.hover;
}

// Whether a click now would be a first click of an object (the preview's promise).
function previewing() {
  if (!map || !state.result || !state.marks || state.negative || state.kind !== "photo" || state.animating) return false;
  const object = state.objects[state.current];
  return !object || (object.positive.length === 0 && object.negative.length === 0 && !object.box);
}

function hoverMove(event) {
  if (event.pointerType === "touch" || event.buttons !== 0 || !state.result) {
    clearHover();
    return;
  }
  const began = performance.now();
  const rect = $("result").getBoundingClientRect();
  hoverAt((event.clientX - rect.left) / rect.width, (event.clientY - rect.top) / rect.height);
  $("frame").dataset.hoverMs = (performance.now() - began).toFixed(1); // for measuring (docs/serve.md)
}

// The preview at a point given as shares of the photo's width and height (the pointer's,
// or the keyboard's cursor).
function hoverAt(fx, fy) {
  // Over a detected animal's box that a click would dress: that box is lit, not a region.
  const found = state.result ? foundAt([fx * state.width, fy * state.height]) : null;
  if (found !== null || !previewing()) {
    clearHover();
    showFoundAt(found);
    return;
  }
  showFoundAt(null);
  const x = Math.min(map.width - 1, Math.max(0, Math.floor(fx * map.width)));
  const y = Math.min(map.height - 1, Math.max(0, Math.floor(fy * map.height)));
  const region = map.choice[map.labels[y * map.width + x]];
  if (region !== shown) draw(region);
}

function clearHover() {
  showFoundAt(null);
  if (shown === -1) return;
  shown = -1;
  const canvas = $("hover");
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
  canvas.hidden = true;
}

function draw(region) {
  if (region < 0) {
    clearHover();
    return;
  }
  shown = region;
  const canvas = $("hover");
  canvas.hidden = false;
  canvas.getContext("2d").putImageData(picture(region), 0, 0);
}

// The region's picture at the map's size: a light cyan fill, a bright edge inside, a dark one outside.
function picture(region) {
  if (pictures.has(region)) return pictures.get(region);
  const { width, height, labels, regions, rowBytes, count } = map;
  const inside = new Uint8Array(count);
  for (let k = 0; k < count; k++) inside[k] = (regions[region * rowBytes + (k >> 3)] >> (7 - (k & 7))) & 1;
  const image = new ImageData(width, height);
  const pixels = new Uint32Array(image.data.buffer); // little-endian RGBA: 0xAABBGGRR
  const FILL = 0x5cf0c94c; // #4cc9f0 at 36%: not the yellow of the subject's own mask
  const EDGE = 0xfff0c94c;
  const SHADOW = 0x8c000000;
  for (let i = 0; i < labels.length; i++) if (inside[labels[i]]) pixels[i] = FILL;
  // A region's edge lies on superpixels' edges: only those pixels are looked at again.
  for (const i of map.seams) {
    const here = inside[labels[i]];
    const x = i % width;
    const edge = (x > 0 && inside[labels[i - 1]] !== here) || (x < width - 1 && inside[labels[i + 1]] !== here)
      || (i >= width && inside[labels[i - width]] !== here) || (i + width < labels.length && inside[labels[i + width]] !== here);
    if (edge) pixels[i] = here ? EDGE : SHADOW;
  }
  if (pictures.size >= 24) pictures.delete(pictures.keys().next().value);
  pictures.set(region, image);
  return image;
}

export { clearHover, forgetHover, hoverAt, hoverMove, loadHover };
