// Folder mode (jeanscv serve FOLDER): the gallery, opening a photo, saving its clicks
// (or reverting it to automatic).
import { clickedObjects, clicksKey, leavePhoto, start, updateControls } from "./editor.js";
import { answerOf, post } from "./server.js";
import { $, setStatus, showError, state } from "./state.js";

const items = new Map(); // item index -> its listing entry

async function loadGallery() {
  const answer = await answerOf(await fetch("/api/folder"));
  const grid = $("grid");
  grid.replaceChildren();
  items.clear();
  $("drop-folder-note").hidden = false;
  document.querySelector(".folder-keys").hidden = false;
  const tiles = answer.items.map((item) => {
    items.set(item.item, item);
    const tile = document.createElement("button");
    tile.type = "button";
    tile.className = "tile";
    tile.dataset.item = item.item;
    const name = document.createElement("div");
    name.className = "name";
    name.textContent = item.name;
    tile.append(placeholder(), name);
    setBadge(tile, item.clicks);
    if (item.uncertain) {
      const unsure = document.createElement("span");
      unsure.className = "unsure";
      unsure.textContent = " ? unsure";
      name.appendChild(unsure);
    }
    tile.addEventListener("click", () => openItem(item, tile));
    grid.appendChild(tile);
    return { item, tile };
  });
  updateCounts();
  applyFilter();
  // One thumbnail at a time: each may be made on demand, and the pool is small.
  for (const { item, tile } of tiles) await loadThumb(item, tile);
}

// Where a thumbnail will be: a grey box saying it is being made (never a broken image).
function placeholder() {
  const box = document.createElement("div");
  box.className = "thumb placeholder";
  box.textContent = "making its jeans…";
  return box;
}

function setBadge(tile, clicks) {
  const name = tile.querySelector(".name");
  let badge = name.querySelector(".badge");
  if (clicks && !badge) {
    badge = document.createElement("span");
    badge.className = "badge";
    badge.textContent = " \u2713 clicks";
    name.appendChild(badge);
  } else if (!clicks && badge) {
    badge.remove();
  }
}

function updateCounts() {
  const all = [...items.values()];
  const fixed = all.filter((item) => item.clicks).length;
  // "uncertain" (automatic finding was unsure) comes with the listing where the server knows it.
  const unsure = all.filter((item) => item.uncertain && !item.clicks).length;
  $("folder-counts").textContent = `${all.length} photo${all.length === 1 ? "" : "s"}: ${fixed} fixed with clicks, `
    + `${all.length - fixed} left${unsure ? ` (${unsure} unsure)` : ""}.`;
}

// The gallery as chosen: all photos in the folder's order; those that need a look (not
// fixed yet, the ones automatic finding was unsure of first); or those fixed. Previous
// and next (arrow keys) follow this order.
function applyFilter() {
  const chosen = $("folder-filter").value;
  const grid = $("grid");
  const tiles = [...grid.querySelectorAll(".tile")];
  const entry = (tile) => items.get(Number(tile.dataset.item));
  const rank = (tile) => (chosen === "look" && entry(tile).uncertain ? 0 : 1);
  tiles.sort((a, b) => rank(a) - rank(b) || entry(a).item - entry(b).item);
  for (const tile of tiles) {
    const item = entry(tile);
    tile.hidden = (chosen === "look" && item.clicks) || (chosen === "fixed" && !item.clicks);
    grid.appendChild(tile);
  }
}

async function loadThumb(item, tile) {
  for (let attempt = 0; attempt < 20; attempt++) {
    // POST: making a missing output writes to the folder, which only this page may ask for.
    const response = await fetch(item.thumb, { method: "POST" });
    if (response.status === 503) {
      await new Promise((r) => setTimeout(r, 1000 * (Number(response.headers.get("Retry-After")) || 2)));
      continue;
    }
    const shown = tile.querySelector(".thumb");
    tile.querySelector(".bad")?.remove();
    if (response.ok) {
      const thumb = document.createElement("img");
      thumb.className = "thumb";
      thumb.alt = `${item.name} with its jeans`;
      thumb.src = URL.createObjectURL(await response.blob());
      thumb.addEventListener("load", () => shown.replaceWith(thumb), { once: true });
    } else {
      const data = await response.json().catch(() => ({}));
      shown.textContent = "";
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
  const generation = leavePhoto();
  $("frame").classList.add("working"); // the photo before stays in sight, veiled, until this one is in
  $("panel").inert = true;
  try {
    const answer = await post(`/api/folder/${item.item}/open`, {});
    if (generation !== state.generation) return; // another photo was opened since
    start(answer, item.item);
    window.scrollTo({ top: $("editor").offsetTop, behavior: "smooth" });
  } catch (error) {
    if (generation !== state.generation) return;
    $("frame").classList.remove("working");
    $("panel").inert = false;
    setStatus("");
    showError(error.message);
  }
}

// The folder's previous (-1) or next (+1) photo, from the one open (in the gallery's order).
function openNeighbour(step) {
  if (state.item === null) return;
  const tiles = [...document.querySelectorAll(".tile:not([hidden])")];
  const at = tiles.findIndex((tile) => Number(tile.dataset.item) === state.item);
  const tile = tiles[at + step];
  if (tile) tile.click();
}

// Save the clicks to the folder; with none left (after Reset or Undo), revert the photo
// to automatic: its clicks file is removed, after a confirmation.
async function saveToFolder() {
  if (state.item === null) return;
  const objects = clickedObjects();
  const revert = objects.length === 0;
  const stem = state.name.replace(/\.[^.]*$/, "");
  if (revert && !window.confirm(`Revert ${state.name} to automatic? This removes ${stem}.clicks.json from the folder and makes its jeans again without clicks.`)) return;
  const item = state.item;
  const key = clicksKey();
  setStatus(revert ? "Removing the clicks and making the automatic output…" : "Saving the clicks and the new output…", true);
  try {
    const entry = await post(`/api/folder/${item}/clicks`, revert ? { photo: state.photo, objects: [], revert: true } : { photo: state.photo, objects });
    items.set(item, { ...items.get(item), clicks: entry.clicks });
    updateCounts();
    applyFilter();
    if (item === state.item) {
      state.saved = key;
      updateControls();
    }
    setStatus(revert
      ? `Reverted: ${state.name} is automatic again (its clicks file is removed).`
      : `Saved: ${state.name}'s clicks and its jeans are in the folder; 'jeanscv FOLDER' uses them.`);
    const tile = document.querySelector(`.tile[data-item="${item}"]`);
    if (tile) {
      setBadge(tile, entry.clicks);
      tile.querySelector(".thumb").replaceWith(placeholder());
      loadThumb(items.get(item), tile);
    }
  } catch (error) {
    setStatus("");
    showError(error.message);
  }
}

export { applyFilter, loadGallery, openNeighbour, saveToFolder };
