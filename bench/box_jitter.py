"""How much a box's mask moves when the box moves a little: a detector's box is never the reference box.

    python -m bench.box_jitter                    # both shared sets
    python -m bench.box_jitter --set real         # ../shared/real_photos only (pets: ../shared/pet_photos)
    python -m bench.box_jitter --megapixels 12 --limit 4   # time a box on 12-MP copies
    python -m bench.box_jitter --json out.json    # every box's figures, for a closer look

Per photo: the reference box (the reference mask's tight box, :func:`bench.clicks.reference_box`)
and a fixed, seeded set of boxes round it: :data:`JITTERS` with each side moved
independently by up to :data:`SPREAD` of the box's width or height, in or out, kept
only where their box IoU with the reference box lies in [:data:`LOW`, :data:`HIGH`],
and the box grown and shrunk 5% about its centre. Each box is cut the way a detector's
box is (``extract_silhouettes(rgb, box=...)``: a :class:`ClickSession`'s
``segment([], [], box)``; one session a photo serves every box, the mask is the same);
"nothing found in that box" counts as an empty mask. Printed per photo: the reference
box's mask IoU, the mean and lowest over the other boxes, the largest
|IoU(box) - IoU(reference box)| and the lowest mask-to-mask IoU between a box's mask and
the reference box's; per set: the means, the share of photos whose every box stays
within :data:`STABLE` of the reference box's IoU (the issue's goal: 90%), the share
whose every mask has mask-to-mask IoU >= 0.90 with the reference box's, the worst
photos and the median seconds a box.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import zlib
from pathlib import Path

import numpy as np
from PIL import Image

from bench.clicks import PETS, SHARED, photo_pairs, reference_box, upscale
from jeanscv.errors import JeansError
from jeanscv.io.image import load_image
from jeanscv.subject.consensus import iou
from jeanscv.subject.detected import box_iou
from jeanscv.subject.interactive import ClickSession

#: Jittered boxes a photo.
JITTERS = 8
#: How far a side may move, a share of the box's width (left, right) or height (top, bottom).
SPREAD = 0.07
#: The box IoU with the reference box that a jittered box must have.
LOW, HIGH = 0.85, 0.95
#: The grown and shrunk boxes: scaled about the box's centre.
SCALES = (1.05, 0.95)
#: A box whose mask IoU is within this of the reference box's is stable.
STABLE = 0.05
SETS = {"real": [SHARED], "pets": [PETS], "both": [SHARED, PETS]}

Box = tuple[int, int, int, int]


def _clipped(box, shape: tuple[int, int]) -> Box:
    height, width = shape
    x0, y0, x1, y1 = (int(round(v)) for v in box)
    x0, y0 = min(max(x0, 0), width - 1), min(max(y0, 0), height - 1)
    return x0, y0, max(min(x1, width), x0 + 1), max(min(y1, height), y0 + 1)


def jittered_boxes(reference: Box, shape: tuple[int, int], seed: int, count: int = JITTERS) -> list[Box]:
    """``count`` boxes round ``reference`` (each side moved by up to :data:`SPREAD` of the
    box's size, in or out, within an image of ``shape`` ``(H, W)``) whose box IoU with it
    lies in [:data:`LOW`, :data:`HIGH`]; the same ``seed`` gives the same boxes."""
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = reference
    size = np.array([x1 - x0, y1 - y0, x1 - x0, y1 - y0], float)
    boxes: list[Box] = []
    spread = SPREAD
    for attempt in range(20000):
        if attempt and attempt % 2000 == 0:
            spread *= 1.25  # a box against the photo's edges can only move in: look wider
        moved = np.array(reference, float) + rng.uniform(-spread, spread, 4) * size
        box = _clipped(moved, shape)
        if box != reference and LOW <= box_iou(box, reference) <= HIGH and box not in boxes:
            boxes.append(box)
            if len(boxes) == count:
                break
    return boxes


def scaled_box(reference: Box, shape: tuple[int, int], scale: float) -> Box:
    """``reference`` scaled by ``scale`` about its centre, within an image of ``shape``."""
    x0, y0, x1, y1 = reference
    cx, cy, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, scale * (x1 - x0) / 2, scale * (y1 - y0) / 2
    return _clipped((cx - hw, cy - hh, cx + hw, cy + hh), shape)


def photo_boxes(name: str, reference: Box, shape: tuple[int, int]) -> dict[str, Box]:
    """The boxes a photo is measured with: ``"reference"``, ``"jitter N"`` and ``"scale S"``."""
    boxes = {"reference": reference}
    for index, box in enumerate(jittered_boxes(reference, shape, zlib.crc32(name.encode()))):
        boxes[f"jitter {index}"] = box
    for scale in SCALES:
        boxes[f"scale {scale:g}"] = scaled_box(reference, shape, scale)
    return boxes


def box_mask(session: ClickSession, box: Box) -> np.ndarray:
    """The mask a detector's ``box`` gets (empty where nothing is found in it)."""
    try:
        return session.segment([], [], box).mask
    except JeansError:
        return np.zeros(session.shape, bool)


def run_photo(name: str, pixels: np.ndarray, reference: np.ndarray) -> dict:
    """Every box of :func:`photo_boxes` cut: per box its box IoU with the reference box,
    mask IoU with the reference mask and with the reference box's mask, and seconds."""
    ref_box = reference_box(reference)
    session = ClickSession(pixels)
    boxes, masks = {}, {}
    for label, box in photo_boxes(name, ref_box, reference.shape).items():
        start = time.perf_counter()
        masks[label] = box_mask(session, box)
        boxes[label] = {
            "box": list(box),
            "box_iou": box_iou(box, ref_box),
            "seconds": time.perf_counter() - start,
            "iou": iou(masks[label], reference),
        }
    for label, entry in boxes.items():
        entry["to_reference_box"] = iou(masks[label], masks["reference"])
        entry["shift"] = abs(entry["iou"] - boxes["reference"]["iou"])
    return boxes


def summary(name: str, boxes: dict) -> dict:
    """One photo's line: reference IoU, mean and lowest over the other boxes, largest shift, lowest mask-to-mask IoU."""
    others = [entry for label, entry in boxes.items() if label != "reference"]
    return {
        "name": name,
        "reference": boxes["reference"]["iou"],
        "mean": statistics.fmean(e["iou"] for e in others),
        "lowest": min(e["iou"] for e in others),
        "shift": max(e["shift"] for e in others),
        "agreement": min(e["to_reference_box"] for e in others),
        "seconds": [e["seconds"] for e in boxes.values()],
    }


def run_set(folder: Path, megapixels: float | None, limit: int | None) -> tuple[list[dict], dict]:
    """Every photo of ``folder`` measured; prints its table, returns its lines and every box's figures."""
    pairs = photo_pairs([folder])[:limit]
    print(f"\n## {folder.name} ({len(pairs)} photos)\n")
    print("| photo | reference box | mean of others | lowest | largest shift | lowest agreement | s/box |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    lines, every = [], {}
    for name, photo, mask_path in pairs:
        pixels = np.ascontiguousarray(load_image(photo).pixels[..., :3])
        reference = np.asarray(Image.open(mask_path).convert("L")) >= 128
        if megapixels:
            pixels, reference = upscale(pixels, reference, megapixels)
        every[name] = boxes = run_photo(name, pixels, reference)
        line = summary(name, boxes)
        lines.append(line)
        flag = "" if line["shift"] <= STABLE else " *"
        print(
            f"| {name}{flag} | {line['reference']:.3f} | {line['mean']:.3f} | {line['lowest']:.3f} "
            f"| {line['shift']:.3f} | {line['agreement']:.3f} | {statistics.median(line['seconds']):.3f} |",
            flush=True,
        )
    return lines, every


def set_row(folder: Path, lines: list[dict]) -> str:
    """The set's means row: reference IoU, mean over the other boxes, stable shares, median s/box, worst photos."""
    stable = sum(line["shift"] <= STABLE for line in lines)
    agree = sum(line["agreement"] >= 0.90 for line in lines)
    worst = sorted(lines, key=lambda line: -line["shift"])[:4]
    seconds = statistics.median(s for line in lines for s in line["seconds"])
    named = ", ".join(f"{line['name']} {line['shift']:.2f}" for line in worst)
    return (
        f"| {folder.name} | {statistics.fmean(line['reference'] for line in lines):.3f} "
        f"| {statistics.fmean(line['mean'] for line in lines):.3f} "
        f"| {stable} of {len(lines)} ({100 * stable / len(lines):.0f}%) "
        f"| {agree} of {len(lines)} | {seconds:.3f} "
        f"| {named} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", choices=sorted(SETS), default="both", help="which shared set (default both)")
    parser.add_argument("--megapixels", type=float, help="upscale every photo to this size first (timing)")
    parser.add_argument("--limit", type=int, help="only the first N photos of each set")
    parser.add_argument("--json", type=Path, help="write every box's figures here")
    args = parser.parse_args()
    folders = [folder for folder in SETS[args.set] if folder.is_dir() and photo_pairs([folder])]
    if not folders:
        raise SystemExit(f"no NAME.mask.png with a photo beside it in {', '.join(map(str, SETS[args.set]))}")
    rows, dump = [], {}
    for folder in folders:
        lines, every = run_set(folder, args.megapixels, args.limit)
        rows.append(set_row(folder, lines))
        dump[folder.name] = every
    print()
    print(
        f"| set | reference box | mean over the other boxes | every box within {STABLE} "
        "| every mask-to-mask IoU >= 0.90 | s/box (median) | largest shifts |"
    )
    print("|---|---:|---:|---:|---:|---:|---|")
    print("\n".join(rows))
    if args.json:
        args.json.write_text(json.dumps(dump, indent=1))


if __name__ == "__main__":
    main()
