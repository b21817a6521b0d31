// Folder mode (jeanscv serve FOLDER): the gallery, opening a photo, saving its clicks
// (or reverting it to automatic). Whether a photo's automatic subject may be the wrong
// thing ("? unsure") is marked as the server learns it (each thumbnail's answer, each
// photo opened or saved), with the counts and the "needs a look" order: no reload.
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
  $("drop").classList.add("tried"); // a strip under the gallery, for a photo only tried
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
    setUnsure(tile, item);
    if (item.item === state.item) markOpen(item.item);
    tile.addEventListener("click", () => openItem(item));
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

// A mark after the tile's name (a span of class ``kind``), shown or removed.
function setMark(tile, kind, shown, text, title) {
  const name = tile.querySelector(".name");
  let mark = name.querySelector(`.${kind}`);
  if (shown && !mark) {
    mark = document.createElement("span");
    mark.className = kind;
    mark.textContent = text;
    if (title) mark.title = title;
    name.appendChild(mark);
  } else if (!shown && mark) {
    mark.remove();
  }
}

function setBadge(tile, clicks) {
  setMark(tile, "badge", Boolean(clicks), " \u2713 clicks");
}

// The "? unsure" mark: automatic finding was unsure of its subject, and it has no clicks.
function setUnsure(tile, item) {
  const unsure = Boolean(item.uncertain) && !item.clicks;
  setMark(tile, "unsure", unsure, " ? unsure", "automatic finding was unsure: it may have dressed the wrong thing");
}

// What the server now says of an item (``uncertain``, ``clicks``): its tile, the counts
// and the gallery's order follow at once.
function learn(index, known) {
  const item = items.get(index);
  if (!item) return;
  const now = { ...item, ...known };
  if (now.uncertain === item.uncertain && now.clicks === item.clicks) return;
  items.set(index, now);
  const tile = document.querySelector(`.tile[data-item="${index}"]`);
  if (tile) {
    setBadge(tile, now.clicks);
    setUnsure(tile, now);
  }
  updateCounts();
  applyFilter();
}

// The photo open on the page: its tile marked (in words too), every other plain; none
// for a photo only tried (dropped), which the line above the photo says is not the folder's.
function markOpen(index) {
  for (const tile of document.querySelectorAll(".tile")) {
    const open = index !== null && Number(tile.dataset.item) === index;
    tile.classList.toggle("open", open);
    if (open) tile.setAttribute("aria-current", "true");
    else tile.removeAttribute("aria-current");
  }
}

function opened(event) {
  if ($("gallery").hidden) return; // not folder mode
  const { item, name, answer } = event.detail;
  markOpen(item);
  const note = $("open-note");
  note.hidden = !name;
  note.classList.toggle("tried", item === null);
  note.textContent = !name ? "" : item === null
    ? `${name} is only tried: it is not in the folder, and nothing of it is saved there.`
    : `Open: ${name}, from the folder (Save to folder keeps its clicks).`;
  // Opened by the server: whether its automatic subject is unsure is known now.
  if (item !== null && answer && answer.summary) learn(item, { uncertain: !answer.clicks && Boolean(answer.summary.uncertain) });
}
document.addEventListener("jeanscv:opened", opened);

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
    // Made (or found) by the server: whether its subject may be the wrong thing, where known.
    const uncertain = response.headers.get("X-Uncertain");
    if (uncertain === "true" || uncertain === "false") learn(item.item, { uncertain: uncertain === "true" });
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

async function openItem(item) {
  showError("");
  setStatus(`Opening ${item.name}…`, true);
  markOpen(item.item);
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
    learn(item, { clicks: entry.clicks, uncertain: entry.uncertain });
    if (item === state.item) {
      state.saved = key;
      updateControls();
    }
    setStatus(revert
      ? `Reverted: ${state.name} is automatic again (its clicks file is removed).`
      : `Saved: ${state.name}'s clicks and its jeans are in the folder; 'jeanscv FOLDER' uses them.`);
    const tile = document.querySelector(`.tile[data-item="${item}"]`);
    if (tile) {
      tile.querySelector(".thumb").replaceWith(placeholder());
      loadThumb(items.get(item), tile);
    }
  } catch (error) {
    setStatus("");
    showError(error.message);
  }
}

export { applyFilter, loadGallery, openNeighbour, saveToFolder };
