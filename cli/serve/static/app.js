// jeanscv serve: the page. Plain JavaScript (ES modules, no build step), no request to any other host.
// Coordinates sent to the server are pixels of the photo as displayed (x right, y down).
// This module loads the options and wires the page; each concern is a module beside it.
import { updateCaptions } from "./captions.js";
import { wireClip } from "./clip.js";
import { drawOverlay, watchFit } from "./drawing.js";
import { addClick, describe, leavePhoto, newObject, pointerDown, pointerMove, pointerUp, redo, rerender, reset, setMode, undo, upload } from "./editor.js";
import { clearHover, hoverMove } from "./hover.js";
import { wireCursor } from "./cursor.js";
import { wireZoom } from "./zoom.js";
import { applyFilter, loadGallery, openNeighbour, saveToFolder } from "./folder.js";
import { answerOf } from "./server.js";
import { $, setStatus, showError, state } from "./state.js";

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
  if (options.compiling) watchCompiling(options.compile_seconds);
  if (options.folder) {
    $("gallery").hidden = false;
    $("folder-name").textContent = options.folder_name;
    loadGallery();
  }
}

// A fresh install's first run: the fit kernels compile in the background (about
// half a minute, once). Said while it lasts; a photo dropped meanwhile waits for them.
function watchCompiling(seconds) {
  const notice = $("first-run");
  notice.textContent = `First run after installing: the fit kernels are being compiled, once (about ${seconds} s). `
    + "A photo dropped now is ready when they are; later runs start at once.";
  notice.hidden = false;
  const poll = setInterval(async () => {
    try {
      const now = await answerOf(await fetch("/api/options"));
      if (now.compiling) return;
    } catch (error) {
      return; // asked again in a moment
    }
    clearInterval(poll);
    notice.hidden = true;
  }, 2000);
}

// ------------------------------------------------------------------ wiring
function wire() {
  const drop = $("drop");
  $("file").addEventListener("change", (e) => upload(e.target.files[0]));
  // Enter or Space on the drop zone opens the file chooser, as a click on its button does.
  drop.addEventListener("keydown", (e) => {
    if (e.target === drop && (e.key === "Enter" || e.key === " ")) {
      e.preventDefault();
      $("file").click();
    }
  });
  // A click or tap anywhere on the zone chooses a file too (its button's own click opens it once).
  drop.addEventListener("click", (e) => {
    if (!e.target.closest("label")) $("file").click();
  });
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
  frame.addEventListener("pointerdown", pointerDown);
  frame.addEventListener("pointermove", pointerMove);
  frame.addEventListener("pointermove", hoverMove);
  frame.addEventListener("pointerleave", clearHover);
  frame.addEventListener("pointerup", pointerUp);
  frame.addEventListener("pointercancel", pointerUp);
  frame.addEventListener("dragstart", (e) => e.preventDefault()); // a drag draws a box, it does not carry the picture off
  frame.addEventListener("click", addClick);
  frame.addEventListener("contextmenu", addClick);
  $("mode-add").addEventListener("click", () => setMode(false));
  $("mode-remove").addEventListener("click", () => setMode(true));
  $("mode-box").addEventListener("click", () => setMode(false, true));
  $("undo").addEventListener("click", undo);
  $("bar-add").addEventListener("click", () => setMode(false));
  $("bar-remove").addEventListener("click", () => setMode(true));
  $("bar-box").addEventListener("click", () => setMode(false, true));
  $("bar-undo").addEventListener("click", undo);
  wireZoom();
  wireCursor();
  $("reset").addEventListener("click", reset);
  $("new-object").addEventListener("click", newObject);
  $("watch").addEventListener("click", watchFit);
  $("save").addEventListener("click", saveToFolder);
  for (const id of ["style", "garment", "posture"]) $(id).addEventListener("change", rerender);
  for (const id of ["top", "bottom", "side"]) $(id).addEventListener("input", updateCaptions);
  $("name-it").addEventListener("click", () => {
    // The meme that names what wears the jeans, where the detector is sure of its class.
    const [top, bottom] = (state.result && state.result.caption) || ["how would this", "wear jeans?"];
    $("top").value = top;
    $("bottom").value = bottom;
    updateCaptions();
  });
  $("result").addEventListener("load", updateCaptions);
  $("another").addEventListener("click", () => {
    leavePhoto();
    state.photo = null;
    state.item = null;
    state.result = null;
    document.dispatchEvent(new CustomEvent("jeanscv:opened", { detail: { item: null, name: null, answer: null } }));
    $("view").hidden = true;
    $("panel").hidden = true;
    $("drop").hidden = false;
    $("file").value = "";
    setStatus("");
    showError("");
  });
  $("redo").addEventListener("click", redo);
  $("dl-gif").addEventListener("click", downloadWithProgress);
  $("folder-filter").addEventListener("change", applyFilter);
  $("marks").addEventListener("change", () => {
    state.marks = $("marks").checked;
    clearHover();
    drawOverlay();
  });
  window.addEventListener("resize", () => drawOverlay());
  document.addEventListener("keydown", keyPressed);
  // A photo pasted (Ctrl+V) is opened as a dropped one is.
  document.addEventListener("paste", (e) => {
    if (["INPUT", "TEXTAREA"].includes(e.target.tagName) && e.target.type !== "file") return; // a caption
    const file = [...(e.clipboardData?.files || [])].find((f) => f.type.startsWith("image/"));
    if (!file) return;
    e.preventDefault();
    upload(file.name && file.name !== "image.png" ? file : new File([file], "pasted.png", { type: file.type }));
  });
  wireClip();
  loadOptions().catch((error) => showError(error.message));
}

// The GIF takes seconds to make: fetched here, with a busy status, then saved.
async function downloadWithProgress(event) {
  event.preventDefault();
  const link = event.currentTarget;
  if (link.classList.contains("disabled") || link.getAttribute("aria-busy") === "true") return;
  const generation = state.generation;
  link.setAttribute("aria-busy", "true");
  setStatus(`Making the GIF of the fit (a few seconds)…`, true);
  try {
    const response = await fetch(link.href);
    if (!response.ok) {
      const data = await response.json().catch(() => ({}));
      throw new Error(data.error || `the server answered ${response.status}`);
    }
    const name = /filename="([^"]+)"/.exec(response.headers.get("Content-Disposition") || "")?.[1] || "jeans.gif";
    const url = URL.createObjectURL(await response.blob());
    const save = document.createElement("a");
    save.href = url;
    save.download = name;
    save.click();
    setTimeout(() => URL.revokeObjectURL(url), 60_000);
  } catch (error) {
    showError(error.message);
  } finally {
    link.removeAttribute("aria-busy");
    if (generation === state.generation) describe(state.result);
  }
}

// The keys (each control's title and the panel's hint say them). Not while typing a
// caption or choosing from a list: those keys are the control's own.
function keyPressed(e) {
  const tag = e.target.tagName;
  if (tag === "TEXTAREA" || tag === "SELECT" || (tag === "INPUT" && e.target.type !== "checkbox")) return;
  const key = e.key.length === 1 ? e.key.toLowerCase() : e.key;
  const command = e.ctrlKey || e.metaKey;
  let action = null;
  if (command && !e.altKey) {
    if (key === "z") action = e.shiftKey ? redo : undo;
    else if (key === "y") action = redo;
  } else if (!e.altKey && !$("panel").hidden) {
    action = {
      a: () => setMode(false),
      r: () => setMode(true),
      n: newObject,
      Delete: reset,
      d: () => $("dl-meme").click(),
      o: () => $("marks").click(),
      ArrowLeft: () => openNeighbour(-1),
      ArrowRight: () => openNeighbour(1),
      "[": () => openNeighbour(-1),
      "]": () => openNeighbour(1),
    }[key];
  }
  if (action) {
    e.preventDefault();
    action();
  }
}

wire();
