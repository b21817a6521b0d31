"""How many clicks a person needs: the standard simulated-click protocol on photos with masks.

    python -m bench.clicks                       # ../shared/real_photos
    python -m bench.clicks FOLDER [FOLDER ...]   # any folders of NAME.jpg + NAME.mask.png
    python -m bench.clicks --megapixels 12       # photos upscaled to 12 MP (click latency)
    python -m bench.clicks --sheet docs/clicks.jpg
    python -m bench.clicks --sheet S.jpg --sheet-after 1 --clicks 1   # the sheet after one click
    python -m bench.clicks --box                 # a box first (the reference mask's), then clicks
    python -m bench.clicks --width 4000          # every photo resized to 4000 px wide first

The protocol (Xu et al. 2016; RITM, Sofiiuk et al. 2022): the first click at the
interior point of the reference mask farthest from its boundary (the image border counts
as boundary); each next click in the largest error region (the one whose interior point
lies farthest from its boundary), at that point: positive where the subject was missed,
negative where background was taken; a photo that reaches IoU 0.90 stops there and keeps
that value for the later clicks (issue 31's counting). Prints per photo and on average
the IoU after 1, 2, 3 and 5 clicks, NoC@85 and NoC@90 (clicks needed, at most 10; 11
counts a photo that never gets there), the time to set the image, the first click's
time (it chooses among auto's hypotheses and cuts a GrabCut) and the median time of the
later clicks; the means row gives medians of the times. With several sets, a line per
set also counts the empty answers and the harmful clicks (ones that lowered the IoU by
more than 0.05), and ``--sheet S.jpg`` writes ``S-SET.jpg`` for each.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

from jeanscv.errors import JeansError
from jeanscv.io.image import load_image
from jeanscv.subject.consensus import iou
from jeanscv.subject.interactive import ClickSession, simulated_click

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "real_photos"
PETS = ROOT.parent / "shared" / "pet_photos"
MAX_CLICKS = 10
#: A photo whose mask reaches this IoU gets no more clicks and keeps it (the protocol's
#: "done": a person stops clicking when the mask is good).
DONE = 0.90


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


def photo_sets(folders: list[Path]) -> list[tuple[Path, list[tuple[str, Path, Path]]]]:
    """(folder, its :func:`photo_pairs`) for each folder that has any (default: both
    shared sets); exits saying so when none has."""
    folders = folders or [SHARED, PETS]
    sets = [(folder, photo_pairs([folder])) for folder in folders if folder.is_dir()]
    sets = [(folder, pairs) for folder, pairs in sets if pairs]
    if not sets:
        raise SystemExit(f"no NAME.mask.png with a photo beside it in {', '.join(map(str, folders))}")
    return sets


def reference_box(reference: np.ndarray) -> tuple[int, int, int, int]:
    """The tight box ``(x0, y0, x1, y1)`` of the reference mask (end exclusive), as a person drags it."""
    ys, xs = np.nonzero(reference)
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def run_photo(
    pixels: np.ndarray,
    reference: np.ndarray,
    clicks: int = MAX_CLICKS,
    box: bool = False,
    shown: int = 3,
    detector: str = "auto",
) -> dict:
    """Simulate ``clicks`` clicks (after the reference's box, with ``box``), or fewer
    where the IoU reaches :data:`DONE`: IoU after each, the set-up and per-click seconds,
    the clicks made and the mask after (at most) ``shown`` of them (``"shown"``; 0 with
    ``box``: the box's own); with ``box`` also the box alone's IoU (``box_iou``)."""
    start = time.perf_counter()
    session = ClickSession(pixels, detector=detector)
    setup = time.perf_counter() - start
    positive: list = []
    negative: list = []
    ious, seconds, made = [], [], []
    predicted = after = None
    drawn = reference_box(reference) if box else None
    result: dict = {}
    if drawn is not None:
        start = time.perf_counter()
        predicted = _segment(session, [], [], drawn)
        result["box_seconds"] = time.perf_counter() - start
        result["box_iou"] = iou(predicted, reference)
        after = predicted
    for _ in range(clicks):
        sign, point = simulated_click(reference, predicted)
        (positive if sign else negative).append(point)
        made.append((sign, point))
        start = time.perf_counter()
        predicted = _segment(session, positive, negative, drawn)
        seconds.append(time.perf_counter() - start)
        ious.append(iou(predicted, reference))
        if len(made) <= shown:
            after = predicted
        if ious[-1] >= DONE:
            break
    return result | {"ious": ious, "seconds": seconds, "setup": setup, "clicks": made, "shown": after}


def _segment(session: ClickSession, positive: list, negative: list, box) -> np.ndarray:
    """The session's mask; where it found nothing, the positive clicks' pixels alone (what
    it answered before it said so), so the next simulated click is made as then."""
    try:
        return session.segment(positive, negative, box).mask
    except JeansError:
        found = np.zeros(session.shape, bool)
        for x, y in positive:
            found[int(y), int(x)] = True
        return found


def noc(ious: list[float], level: float) -> int:
    """Clicks needed to reach ``level``; ``MAX_CLICKS + 1`` for a photo that never does."""
    return next((i + 1 for i, value in enumerate(ious) if value >= level), MAX_CLICKS + 1)


def upscale(pixels: np.ndarray, reference: np.ndarray, megapixels: float) -> tuple[np.ndarray, np.ndarray]:
    height, width = reference.shape
    scale = (megapixels * 1e6 / (width * height)) ** 0.5
    size = (round(width * scale), round(height * scale))
    big = cv2.resize(pixels, size, interpolation=cv2.INTER_CUBIC)
    mask = cv2.resize(reference.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST).astype(bool)
    return big, mask


def resize_to_width(pixels: np.ndarray, reference: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """``pixels`` and ``reference`` resized to ``width`` pixels wide, keeping the aspect
    (:func:`upscale` at the matching megapixels)."""
    return upscale(pixels, reference, width**2 * reference.shape[0] / reference.shape[1] / 1e6)


def contact_sheet(rows: list[tuple[str, np.ndarray, np.ndarray, list, float]], path: Path) -> None:
    """A grid of photos, each with a mask, the clicks made for it and its IoU: the mask
    tinted, its outline, the clicks (green positive, red negative) and the IoU."""
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
    parser.add_argument("--sheet", type=Path, help="write a contact sheet (after --sheet-after clicks) here")
    parser.add_argument(
        "--sheet-after", type=int, default=3, help="clicks shown on the sheet (default 3; 0 with --box: the box alone)"
    )
    parser.add_argument("--clicks", type=int, default=MAX_CLICKS)
    parser.add_argument("--box", action="store_true", help="a box (the reference mask's) first, then the clicks")
    parser.add_argument("--width", type=int, help="resize every photo to this width first")
    parser.add_argument(
        "--detector", choices=("auto", "none"), default="auto", help="the detector's boxes start clicks (default auto)"
    )
    args = parser.parse_args()
    if args.sheet_after < (0 if args.box else 1):
        parser.error("--sheet-after must be at least 1 (0 only with --box: the box alone)")
    sets = photo_sets(args.folders)
    sheets = {folder: _sheet_path(args.sheet, folder, len(sets) > 1) for folder, _ in sets}
    means = [(folder, run_set(pairs, args, sheets[folder])) for folder, pairs in sets]
    if len(means) > 1 or args.box:
        print()
        print(
            f"| set | {'box | ' if args.box else ''}IoU@1 | IoU@3 | IoU@5 | NoC@85 | IoU@1 >= 0.5 | empty answers "
            "| harmful clicks |"
        )
        print(f"|---|{'---:|' if args.box else ''}---:|---:|---:|---:|---:|---:|---:|")
        for folder, line in means:
            print(f"| {folder.name} | {line} |")


def _sheet_path(sheet: Path | None, folder: Path, several: bool) -> Path | None:
    """Where a set's contact sheet goes: ``--sheet`` itself, or with several sets
    ``NAME-SET.EXT`` beside it."""
    if sheet is None or not several:
        return sheet
    return sheet.with_name(f"{sheet.stem}-{folder.name}{sheet.suffix}")


def harmful(result: dict) -> tuple[int, int]:
    """(clicks that lowered the IoU by more than 0.05, clicks made) of one photo's run
    (after a box, the first click is compared with the box alone)."""
    before = [result["box_iou"]] if "box_iou" in result else []
    made = len(result["clicks"])
    ious = before + result["ious"][:made]
    return sum(b < a - 0.05 for a, b in zip(ious, ious[1:])), made


def run_set(pairs: list, args, sheet_path: Path | None = None) -> str:
    """Simulate every photo of one set; prints its table and returns its means' row."""
    print("| photo | IoU@1 | IoU@2 | IoU@3 | IoU@5 | NoC@85 | NoC@90 | set-up s | first click s | s/click |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    results, sheet = [], []
    for name, photo, mask_path in pairs:
        pixels = np.ascontiguousarray(load_image(photo).pixels[..., :3])
        reference = np.asarray(Image.open(mask_path).convert("L")) >= 128
        if args.megapixels:
            pixels, reference = upscale(pixels, reference, args.megapixels)
        if args.width:
            pixels, reference = resize_to_width(pixels, reference, args.width)
        result = run_photo(pixels, reference, args.clicks, box=args.box, shown=args.sheet_after, detector=args.detector)
        result["ious"] = ious = result["ious"] + [result["ious"][-1]] * (MAX_CLICKS - len(result["ious"]))
        result["noc85"], result["noc90"] = noc(ious, 0.85), noc(ious, 0.90)
        results.append(result)
        print(
            f"| {name} | {ious[0]:.3f} | {ious[1]:.3f} | {ious[2]:.3f} | {ious[4]:.3f} | {result['noc85']} "
            f"| {result['noc90']} | {result['setup']:.2f} | {result['seconds'][0]:.3f} "
            f"| {statistics.median(result['seconds'][1:] or result['seconds']):.3f} |",
            flush=True,
        )
        if sheet_path:
            count = min(args.sheet_after, len(result["clicks"]))  # a photo done at 0.90 stopped sooner
            score = ious[count - 1] if count else result["box_iou"]
            sheet.append((name, pixels, result["shown"], result["clicks"][:count], score))

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
    if sheet_path:
        contact_sheet(sheet, sheet_path)
        print(f"contact sheet: {sheet_path}")
    usable = sum(r["ious"][0] >= 0.5 for r in results)
    empty = sum(value < 0.001 for r in results for value in r["ious"] + [r.get("box_iou", 1.0)])
    box = f"{mean('box_iou'):.3f} | " if args.box else ""
    worse, made = (sum(values) for values in zip(*(harmful(r) for r in results)))
    return (
        f"{box}{mean('ious', 0):.3f} | {mean('ious', 2):.3f} | {mean('ious', 4):.3f} | {mean('noc85'):.2f} "
        f"| {usable} of {len(results)} | {empty} | {worse} of {made} ({100 * worse / max(made, 1):.1f}%)"
    )


if __name__ == "__main__":
    main()
