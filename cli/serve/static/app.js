// jeanscv serve: the page. Plain JavaScript, no build step, no request to any other host.
// Coordinates sent to the server are pixels of the photo as displayed (x right, y down).
"use strict";

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
  history: [], // [{object, sign}] for undo
  result: null, // last answer of the server
  negative: false, // the touch toggle
  sequence: 0, // renders sent
  shown: 0, // the newest render shown
  inFlight: false,
  again: false,
  animating: false,
};

function setStatus(text, busy = false) {
  $("status").textContent = text;
  $("status").classList.toggle("busy", busy);
}

function showError(text) {
  $("error").textContent = text;
  $("error").hidden = !text;
}

async function answerOf(response) {
  let data = null;
  try {
    data = await response.json();
  } catch (e) {
    data = null;
  }
  if (!response.ok) {
    const reason = data && data.error ? data.error : `the server answered ${response.status}`;
    const error = new Error(reason);
    error.status = response.status;
    error.retry = Number(response.headers.get("Retry-After") || 0);
    throw error;
  }
  return data;
}

async function post(url, body, retries = 3) {
  for (let attempt = 0; ; attempt++) {
    const response = await fetch(url, body instanceof FormData
      ? { method: "POST", body }
      : { method: "POST", body: JSON.stringify(body), headers: { "Content-Type": "application/json" } });
    if (response.status === 503 && attempt < retries) {
      setStatus("The server is busy: trying again…", true);
      await new Promise((r) => setTimeout(r, 1000 * (Number(response.headers.get("Retry-After")) || 2)));
      continue;
    }
    return answerOf(response);
  }
}

// ------------------------------------------------------------------ options
async function loadOptions() {
  const options = await answerOf(await fetch("/api/options"));
  const fill = (select, values, chosen) => {
    for (const value of values) {
      const option = document.createElement("option");
      option.value = value;
      option.textContent = value;
      option.selected = value === chosen;
      select.appendChild(option);
    }
  };
  fill($("style"), options.styles, "denim");
  fill($("garment"), options.garments, "jeans");
  fill($("posture"), options.postures, "upright");
  state.maxUpload = options.max_upload;
  if (options.folder) {
    $("gallery").hidden = false;
    $("folder-name").textContent = options.folder_name;
    loadGallery();
  }
}

function renderOptions() {
  return { style: $("style").value, garment: $("garment").value, posture: $("posture").value };
}

// ------------------------------------------------------------------ upload
async function upload(file) {
  if (!file) return;
  showError("");
  if (state.maxUpload && file.size > state.maxUpload) {
    showError(`${file.name}: the file is larger than the server's upload limit (${Math.round(state.maxUpload / 1048576)} MB)`);
    return;
  }
  setStatus(`Putting jeans on ${file.name}…`, true);
  const form = new FormData();
  form.append("file", file, file.name);
  try {
    const answer = await post("/api/photos", form);
    start(answer, null);
  } catch (error) {
    setStatus("");
    showError(error.message);
  }
}

function start(answer, item) {
  state.photo = answer.photo;
  state.item = item;
  state.kind = answer.kind;
  state.name = answer.name;
  state.width = answer.width;
  state.height = answer.height;
  state.objects = [];
  state.current = 0;
  state.history = [];
  $("drop").hidden = true;
  $("view").hidden = false;
  $("panel").hidden = false;
  $("save").hidden = item === null;
  $("original").src = `/api/photos/${answer.photo}/original`;
  if (answer.clicks && answer.saved_clicks) {
    state.objects = answer.saved_clicks.map((o) => ({ positive: o.positive, negative: o.negative }));
  }
  show(answer);
  updateControls();
}

// ------------------------------------------------------------------ results
function show(answer) {
  state.result = answer;
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
  const summary = answer.summary;
  const count = summary.objects === 1 ? "1 object" : `${summary.objects} objects`;
  let text = `${state.name}: ${count}, ${answer.clicks ? "from your clicks" : `found by ${summary.method}`}.`;
  if (state.kind === "photo") {
    text += answer.clicks ? "" : " Wrong thing? Click the one that should wear them.";
    if (summary.uncertain && !answer.clicks) text = `${state.name}: not sure what the subject is. Click it.`;
  }
  setStatus(text);
}

function drawOverlay(animatedJeans = null) {
  const svg = $("overlay");
  svg.replaceChildren();
  const answer = state.result;
  if (!answer) return;
  const unit = Math.max(answer.width, answer.height) / 100;
  answer.objects.forEach((object, index) => {
    for (const ring of object.outline) {
      const d = "M" + ring.map((p) => `${p[0]},${p[1]}`).join("L") + "Z";
      for (const cls of ["outline-shadow", index === state.current || !answer.clicks ? "outline" : "outline other"]) {
        const path = document.createElementNS(SVG_NS, "path");
        path.setAttribute("d", d);
        path.setAttribute("class", cls);
        svg.appendChild(path);
      }
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
    for (const [sign, points] of [["pos", object.positive], ["neg", object.negative]]) {
      for (const [x, y] of points) {
        const dot = document.createElementNS(SVG_NS, "circle");
        dot.setAttribute("cx", x);
        dot.setAttribute("cy", y);
        dot.setAttribute("r", unit * 0.9);
        dot.setAttribute("class", `click ${sign}${index === state.current ? "" : " faded"}`);
        svg.appendChild(dot);
      }
    }
  });
}

async function rerender() {
  if (!state.photo) return;
  if (state.inFlight) {
    state.again = true; // send the newest clicks once this answer is in
    return;
  }
  state.inFlight = true;
  state.again = false;
  const sequence = ++state.sequence;
  setStatus("Fitting…", true);
  try {
    const objects = state.objects.filter((o) => o.positive.length > 0);
    const answer = await post(`/api/photos/${state.photo}/render`, { objects, options: renderOptions() });
    if (sequence > state.shown) {
      state.shown = sequence;
      showError("");
      if (!state.again) show(answer);
    }
  } catch (error) {
    setStatus("");
    showError(error.message);
  } finally {
    state.inFlight = false;
    if (state.again) rerender();
  }
}

// ------------------------------------------------------------------ clicks
function photoPoint(event) {
  const rect = $("result").getBoundingClientRect();
  const x = ((event.clientX - rect.left) / rect.width) * state.width;
  const y = ((event.clientY - rect.top) / rect.height) * state.height;
  const clamp = (v, top) => Math.min(Math.max(v, 0), top - 0.01);
  return [Math.round(clamp(x, state.width) * 10) / 10, Math.round(clamp(y, state.height) * 10) / 10];
}

function addClick(event) {
  if (state.kind !== "photo" || !state.result) return;
  event.preventDefault();
  const negative = state.negative || event.shiftKey || event.altKey || event.ctrlKey || event.metaKey || event.button === 2;
  if (!state.objects[state.current]) state.objects[state.current] = { positive: [], negative: [] };
  const object = state.objects[state.current];
  if (negative && object.positive.length === 0) {
    showError("Add a positive click on the object first, then remove what is not part of it.");
    return;
  }
  (negative ? object.negative : object.positive).push(photoPoint(event));
  state.history.push({ object: state.current, sign: negative ? "negative" : "positive" });
  drawOverlay();
  updateControls();
  rerender();
}

function undo() {
  const last = state.history.pop();
  if (!last) return;
  state.objects[last.object][last.sign].pop();
  if (state.objects[last.object].positive.length === 0 && state.objects[last.object].negative.length === 0
      && last.object === state.objects.length - 1 && last.object > 0) {
    state.objects.pop();
    state.current = Math.min(state.current, state.objects.length - 1);
  }
  drawOverlay();
  updateControls();
  rerender();
}

function reset() {
  state.objects = [];
  state.current = 0;
  state.history = [];
  updateControls();
  rerender();
}

function newObject() {
  const last = state.objects[state.objects.length - 1];
  if (last && last.positive.length === 0) {
    state.current = state.objects.length - 1;
  } else {
    state.objects.push({ positive: [], negative: [] });
    state.current = state.objects.length - 1;
  }
  drawOverlay();
  updateControls();
  setStatus(`Object ${state.current + 1}: click it.`);
}

function setMode(negative) {
  state.negative = negative;
  $("mode-add").setAttribute("aria-pressed", String(!negative));
  $("mode-remove").setAttribute("aria-pressed", String(negative));
}

function updateControls() {
  const photo = state.kind === "photo";
  for (const id of ["mode-add", "mode-remove", "new-object", "undo", "reset"]) $(id).disabled = !photo;
  $("undo").disabled = !photo || state.history.length === 0;
  $("reset").disabled = !photo || state.objects.length === 0;
  $("new-object").disabled = !photo || !state.objects.some((o) => o.positive.length > 0);
  $("save").disabled = !state.objects.some((o) => o.positive.length > 0);
  const list = $("objects");
  list.replaceChildren();
  state.objects.forEach((object, index) => {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = `Object ${index + 1} (${object.positive.length}+ ${object.negative.length}\u2212)`;
    button.setAttribute("aria-pressed", String(index === state.current));
    button.addEventListener("click", () => {
      state.current = index;
      updateControls();
      drawOverlay();
    });
    list.appendChild(button);
  });
}

// ------------------------------------------------------------------ captions, layout
function updateCaptions() {
  const frame = $("frame");
  const size = Math.max(12, Math.round(frame.clientHeight / 9));
  for (const [id, input] of [["cap-top", "top"], ["cap-bottom", "bottom"]]) {
    const caption = $(id);
    caption.textContent = $(input).value;
    caption.style.fontSize = `${size}px`;
  }
  $("original-figure").hidden = !$("side").checked;
  updateMemeLink();
}

function updateMemeLink() {
  if (!state.result) return;
  const query = new URLSearchParams({ top: $("top").value, bottom: $("bottom").value, side_by_side: $("side").checked ? "1" : "0" });
  $("dl-meme").href = `${state.result.downloads.meme}?${query}`;
}

// ------------------------------------------------------------------ the fit, animated
function watchFit() {
  const answer = state.result;
  if (!answer || state.animating) return;
  state.animating = true;
  const image = $("result");
  const finished = image.src;
  image.src = `/api/photos/${state.photo}/original`;
  const frames = Math.max(...answer.objects.map((o) => o.trajectory.length));
  const began = performance.now();
  const duration = 2500;
  const step = (now) => {
    const index = Math.min(frames - 1, Math.floor(((now - began) / duration) * frames));
    drawOverlay(answer.objects.map((o) => o.trajectory[Math.min(index, o.trajectory.length - 1)]));
    if (index < frames - 1) {
      requestAnimationFrame(step);
    } else {
      setTimeout(() => {
        image.src = finished;
        state.animating = false;
        drawOverlay();
      }, 700);
    }
  };
  requestAnimationFrame(step);
}

// ------------------------------------------------------------------ folder mode
async function loadGallery() {
  const answer = await answerOf(await fetch("/api/folder"));
  const grid = $("grid");
  grid.replaceChildren();
  const tiles = answer.items.map((item) => {
    const tile = document.createElement("button");
    tile.type = "button";
    tile.className = "tile";
    tile.dataset.item = item.item;
    const thumb = document.createElement("img");
    thumb.className = "thumb";
    thumb.alt = item.name;
    const name = document.createElement("div");
    name.className = "name";
    name.textContent = item.name;
    if (item.clicks) {
      const badge = document.createElement("span");
      badge.className = "badge";
      badge.textContent = " \u2713 clicks";
      name.appendChild(badge);
    }
    tile.append(thumb, name);
    tile.addEventListener("click", () => openItem(item, tile));
    grid.appendChild(tile);
    return { item, tile, thumb };
  });
  // One thumbnail at a time: each may be made on demand, and the pool is small.
  for (const { item, tile, thumb } of tiles) await loadThumb(item, tile, thumb);
}

async function loadThumb(item, tile, thumb) {
  for (let attempt = 0; attempt < 20; attempt++) {
    // POST: making a missing output writes to the folder, which only this page may ask for.
    const response = await fetch(item.thumb, { method: "POST" });
    if (response.status === 503) {
      await new Promise((r) => setTimeout(r, 1000 * (Number(response.headers.get("Retry-After")) || 2)));
      continue;
    }
    if (response.ok) {
      thumb.src = URL.createObjectURL(await response.blob());
    } else {
      const data = await response.json().catch(() => ({}));
      thumb.hidden = true;
      const bad = document.createElement("span");
      bad.className = "bad";
      bad.textContent = data.error || `failed (${response.status})`;
      tile.appendChild(bad);
    }
    return;
  }
}

async function openItem(item, tile) {
  showError("");
  setStatus(`Opening ${item.name}…`, true);
  for (const other of document.querySelectorAll(".tile")) other.classList.toggle("open", other === tile);
  try {
    const answer = await post(`/api/folder/${item.item}/open`, {});
    start(answer, item.item);
    window.scrollTo({ top: $("editor").offsetTop, behavior: "smooth" });
  } catch (error) {
    setStatus("");
    showError(error.message);
  }
}

async function saveToFolder() {
  if (state.item === null) return;
  setStatus("Saving the clicks and the new output…", true);
  try {
    const objects = state.objects.filter((o) => o.positive.length > 0);
    await post(`/api/folder/${state.item}/clicks`, { photo: state.photo, objects });
    setStatus(`Saved: ${state.name}'s clicks and its jeans are in the folder; 'jeanscv FOLDER' uses them.`);
    const tile = document.querySelector(`.tile[data-item="${state.item}"]`);
    if (tile) {
      const item = { item: state.item, thumb: `/api/folder/${state.item}/thumb` };
      loadThumb(item, tile, tile.querySelector("img"));
    }
  } catch (error) {
    setStatus("");
    showError(error.message);
  }
}

// ------------------------------------------------------------------ wiring
function wire() {
  const drop = $("drop");
  $("file").addEventListener("change", (e) => upload(e.target.files[0]));
  // Drops anywhere on the page (the drop zone's bubble up here): one upload per drop.
  document.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  document.addEventListener("dragleave", () => drop.classList.remove("over"));
  document.addEventListener("drop", (e) => {
    e.preventDefault();
    drop.classList.remove("over");
    if (e.dataTransfer && e.dataTransfer.files.length) upload(e.dataTransfer.files[0]);
  });
  const frame = $("frame");
  frame.addEventListener("click", addClick);
  frame.addEventListener("contextmenu", addClick);
  $("mode-add").addEventListener("click", () => setMode(false));
  $("mode-remove").addEventListener("click", () => setMode(true));
  $("undo").addEventListener("click", undo);
  $("reset").addEventListener("click", reset);
  $("new-object").addEventListener("click", newObject);
  $("watch").addEventListener("click", watchFit);
  $("save").addEventListener("click", saveToFolder);
  for (const id of ["style", "garment", "posture"]) $(id).addEventListener("change", rerender);
  for (const id of ["top", "bottom", "side"]) $(id).addEventListener("input", updateCaptions);
  $("result").addEventListener("load", updateCaptions);
  window.addEventListener("resize", updateCaptions);
  $("another").addEventListener("click", () => {
    state.photo = null;
    state.result = null;
    $("view").hidden = true;
    $("panel").hidden = true;
    $("drop").hidden = false;
    $("file").value = "";
    setStatus("");
    showError("");
  });
  document.addEventListener("keydown", (e) => {
    if ((e.ctrlKey || e.metaKey) && e.key === "z" && e.target.tagName !== "INPUT") {
      e.preventDefault();
      undo();
    }
  });
  loadOptions().catch((error) => showError(error.message));
}

wire();
