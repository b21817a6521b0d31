"""How well one click segments an object: :func:`segment_at_point` at the deepest pixel.

    python bench/point_clicks.py

For each photo with a known mask (the 16 synthetic test photos, the two objects of
the two-object test photo, and the real photos in ``../shared/real_photos`` when they
are there), clicks the deepest pixel of the mask's largest object and prints the IoU of
the point segmentation with that object, and the seconds it took; then the means.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "real_photos"
sys.path.insert(0, str(ROOT / "tests"))

from synthetic_photos import iou, photo_set, two_objects  # noqa: E402

from jeanscv.errors import JeansError  # noqa: E402
from jeanscv.io.image import load_image  # noqa: E402
from jeanscv.silhouette.seeded import segment_at_point  # noqa: E402


def largest(mask: np.ndarray) -> np.ndarray:
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8))
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA])) if count > 1 else mask


def deepest(mask: np.ndarray) -> tuple[float, float]:
    distance = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 5)
    y, x = np.unravel_index(np.argmax(distance), distance.shape)
    return float(x) + 0.5, float(y) + 0.5


def cases():
    """(set, name, image, object mask) for every photo with a known mask."""
    for photo in photo_set():
        yield "synthetic", photo.name, photo.image, photo.mask
    scene = two_objects()
    for index, mask in enumerate(scene.masks):
        yield "synthetic", f"{scene.name}[{index}]", scene.image, mask
    for mask_path in sorted(REAL.glob("*.mask.png")) if REAL.is_dir() else []:
        stem = mask_path.name[: -len(".mask.png")]
        photo_path = next(p for p in REAL.glob(f"{stem}.*") if p != mask_path)
        pixels = np.ascontiguousarray(load_image(photo_path).pixels[..., :3])
        yield "real", photo_path.name, pixels, largest(np.asarray(Image.open(mask_path).convert("L")) >= 128)


def main() -> None:
    scores: dict[str, list[float]] = {}
    print("| set | photo | IoU | seconds |")
    print("|---|---|---:|---:|")
    for group, name, image, mask in cases():
        began = time.perf_counter()
        try:
            score = iou(segment_at_point(image, deepest(mask)).mask, mask)
        except JeansError:
            score = 0.0
        seconds = time.perf_counter() - began
        scores.setdefault(group, []).append(score)
        print(f"| {group} | {name} | {score:.3f} | {seconds:.2f} |", flush=True)
    for group, values in scores.items():
        print(f"\n{group}: mean IoU {np.mean(values):.3f} on {len(values)} objects")


if __name__ == "__main__":
    main()
