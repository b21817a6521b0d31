"""The real photographs with reference masks in ``../shared/real_photos`` and
``../shared/pet_photos`` (see their READMEs): finding them and reading their masks, for
tests and benches."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

REAL_PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "real_photos"
PET_PHOTOS = REAL_PHOTOS.with_name("pet_photos")


def photo_paths(folder: Path = REAL_PHOTOS) -> list[Path]:
    """The photos in ``folder`` that have a ``STEM.mask.png`` beside them, sorted
    (empty when the folder is absent)."""
    if not folder.is_dir():
        return []
    return sorted(
        p
        for p in folder.iterdir()
        if p.suffix.lower() in (".jpg", ".jpeg", ".png")
        and not p.name.endswith(".mask.png")
        and (folder / f"{p.stem}.mask.png").is_file()
    )


def reference_mask(photo: Path) -> np.ndarray:
    """The reference mask of ``photo`` as (H, W) bool (255 = subject)."""
    return cv2.imread(str(photo.with_name(f"{photo.stem}.mask.png")), cv2.IMREAD_GRAYSCALE) >= 128


def polygon_mask(vertices: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool: pixel centres inside the polygon (image pixels, x right, y down)."""
    canvas = np.zeros(shape, np.uint8)
    # fillPoly takes integer coordinates as pixel centres; ours sit at +0.5.
    points = np.round((np.asarray(vertices) - 0.5) * 16).astype(np.int32)
    cv2.fillPoly(canvas, [points], 1, lineType=cv2.LINE_8, shift=4)
    return canvas.astype(bool)
