// Folder mode (jeanscv serve FOLDER): the gallery, opening a photo, saving its clicks.
import { leavePhoto, start } from "./editor.js";
import { answerOf, post } from "./server.js";
import { $, setStatus, showError, state } from "./state.js";

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
  const generation = leavePhoto();
  try {
    const answer = await post(`/api/folder/${item.item}/open`, {});
    if (generation !== state.generation) return; // another photo was opened since
    start(answer, item.item);
    window.scrollTo({ top: $("editor").offsetTop, behavior: "smooth" });
  } catch (error) {
    if (generation !== state.generation) return;
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

export { loadGallery, saveToFolder };
