"""How many clicks a person needs: the standard simulated-click protocol on photos with masks.

    python -m bench.clicks                       # ../shared/real_photos
    python -m bench.clicks FOLDER [FOLDER ...]   # any folders of NAME.jpg + NAME.mask.png
    python -m bench.clicks --megapixels 12       # photos upscaled to 12 MP (click latency)
    python -m bench.clicks --sheet docs/clicks.jpg

The protocol (Xu et al. 2016; RITM, Sofiiuk et al. 2022): the first click at the
interior point of the reference mask farthest from its boundary (the image border counts
as boundary); each next click in the largest error region (the one whose interior point
lies farthest from its boundary), at that point: positive where the subject was missed,
negative where background was taken. Prints per photo and on average the IoU after 1, 2,
3 and 5 clicks, NoC@85 and NoC@90 (clicks needed, at most 10; 10 counts a photo that
never gets there), the time to set the image, the first click's time (it chooses among
auto's hypotheses and cuts a GrabCut) and the median time of the later clicks; the
means row gives medians of the times.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from jeanscv.io.image import load_image
from jeanscv.subject.consensus import iou
from jeanscv.subject.interactive import ClickSession, simulated_click

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "real_photos"
MAX_CLICKS = 10


def photo_pairs(folders: list[Path]) -> list[tuple[str, Path, Path]]:
    """(name, photo, mask) for every ``NAME.mask.png`` with a photo beside it."""
    pairs = []
    for folder in folders:
        for mask_path in sorted(folder.glob("*.mask.png")):
            stem = mask_path.name[: -len(".mask.png")]
            photos = [p for p in folder.glob(f"{stem}.*") if p != mask_path and not p.name.endswith(".json")]
            if photos:
                pairs.append((stem, photos[0], mask_path))
    return pairs


def run_photo(pixels: np.ndarray, reference: np.ndarray, clicks: int = MAX_CLICKS) -> dict:
    """Simulate ``clicks`` clicks: IoU after each, the set-up and per-click seconds, the
    clicks made and the mask after (at most) three of them."""
    start = time.perf_counter()
    session = ClickSession(pixels)
    setup = time.perf_counter() - start
    positive: list = []
    negative: list = []
    ious, seconds, made = [], [], []
    predicted = None
    for _ in range(clicks):
        sign, point = simulated_click(reference, predicted)
        (positive if sign else negative).append(point)
        made.append((sign, point))
        start = time.perf_counter()
        predicted = session.segment(positive, negative).mask
        seconds.append(time.perf_counter() - start)
        ious.append(iou(predicted, reference))
        if len(made) <= 3:
            after_three = predicted
    return {"ious": ious, "seconds": seconds, "setup": setup, "clicks": made, "after_three": after_three}


def noc(ious: list[float], level: float) -> int:
    return next((i + 1 for i, value in enumerate(ious) if value >= level), MAX_CLICKS)


def upscale(pixels: np.ndarray, reference: np.ndarray, megapixels: float) -> tuple[np.ndarray, np.ndarray]:
    height, width = reference.shape
    scale = (megapixels * 1e6 / (width * height)) ** 0.5
    size = (round(width * scale), round(height * scale))
    big = cv2.resize(pixels, size, interpolation=cv2.INTER_CUBIC)
    mask = cv2.resize(reference.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST).astype(bool)
    return big, mask


def contact_sheet(rows: list[tuple[str, np.ndarray, np.ndarray, list, float]], path: Path, clicks: int = 3) -> None:
    """A grid of photos after ``clicks`` clicks: the mask tinted, its outline, the clicks
    (green positive, red negative) and the IoU."""
    tiles = []
    for name, pixels, mask, made, score in rows:
        rgb = np.ascontiguousarray(pixels[..., :3])
        scale = 300 / max(rgb.shape[:2])
        size = (round(rgb.shape[1] * scale), round(rgb.shape[0] * scale))
        small = cv2.resize(rgb, size, interpolation=cv2.INTER_AREA)
        small_mask = cv2.resize(mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST).astype(bool)
        tinted = small.copy()
        tinted[~small_mask] = (tinted[~small_mask] * 0.35).astype(np.uint8)
        contours, _ = cv2.findContours(small_mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(tinted, contours, -1, (255, 220, 0), 2)
        for sign, (x, y) in made:
            centre = (int(x * scale), int(y * scale))
            cv2.circle(tinted, centre, 6, (255, 255, 255), -1)
            cv2.circle(tinted, centre, 4, (0, 200, 0) if sign else (230, 0, 0), -1)
        tile = np.full((324, 300, 3), 255, np.uint8)
        tile[: size[1], : size[0]] = tinted
        label = (4, size[1] + 16)
        cv2.putText(tile, f"{name} IoU {score:.2f}", label, cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        tiles.append(tile)
    columns = 6
    while len(tiles) % columns:
        tiles.append(np.full_like(tiles[0], 255))
    grid = np.vstack([np.hstack(tiles[i : i + columns]) for i in range(0, len(tiles), columns)])
    Image.fromarray(grid).save(path, quality=88)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--megapixels", type=float, help="upscale every photo to this size first")
    parser.add_argument("--sheet", type=Path, help="write a contact sheet (after 3 clicks) here")
    parser.add_argument("--clicks", type=int, default=MAX_CLICKS)
    args = parser.parse_args()
    folders = args.folders or [SHARED]
    pairs = photo_pairs([f for f in folders if f.is_dir()])
    if not pairs:
        raise SystemExit(f"no NAME.mask.png with a photo beside it in {', '.join(map(str, folders))}")
    print("| photo | IoU@1 | IoU@2 | IoU@3 | IoU@5 | NoC@85 | NoC@90 | set-up s | first click s | s/click |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    results, sheet = [], []
    for name, photo, mask_path in pairs:
        pixels = np.ascontiguousarray(load_image(photo).pixels[..., :3])
        reference = np.asarray(Image.open(mask_path).convert("L")) >= 128
        if args.megapixels:
            pixels, reference = upscale(pixels, reference, args.megapixels)
        result = run_photo(pixels, reference, args.clicks)
        result["ious"] = ious = result["ious"] + [result["ious"][-1]] * (MAX_CLICKS - len(result["ious"]))
        result["noc85"], result["noc90"] = noc(ious, 0.85), noc(ious, 0.90)
        results.append(result)
        print(
            f"| {name} | {ious[0]:.3f} | {ious[1]:.3f} | {ious[2]:.3f} | {ious[4]:.3f} | {result['noc85']} "
            f"| {result['noc90']} | {result['setup']:.2f} | {result['seconds'][0]:.3f} "
            f"| {statistics.median(result['seconds'][1:] or result['seconds']):.3f} |",
            flush=True,
        )
        if args.sheet:
            sheet.append((name, pixels, result["after_three"], result["clicks"][:3], ious[2]))

    def mean(key, index=None):
        values = [r[key][index] if index is not None else r[key] for r in results]
        return sum(values) / len(values)

    later = [s for r in results for s in r["seconds"][1:]] or [r["seconds"][0] for r in results]
    print(
        f"| **mean of {len(results)}** | **{mean('ious', 0):.3f}** | **{mean('ious', 1):.3f}** "
        f"| **{mean('ious', 2):.3f}** | **{mean('ious', 4):.3f}** | **{mean('noc85'):.2f}** "
        f"| **{mean('noc90'):.2f}** | **{statistics.median([r['setup'] for r in results]):.2f}** "
        f"| **{statistics.median([r['seconds'][0] for r in results]):.3f}** | **{statistics.median(later):.3f}** |"
    )
    if args.sheet:
        contact_sheet(sheet, args.sheet)
        print(f"contact sheet: {args.sheet}")


if __name__ == "__main__":
    main()
