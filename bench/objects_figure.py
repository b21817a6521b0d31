"""The README's picture of several objects: a photo, ``--objects all`` and ``--point``.

    python -m bench.objects_figure [--out docs/objects.jpg]

Uses the two-object test photo (a person and a dog on grass, ``testkit/synthetic_photos.py``)
and prints, for each panel, the share of every garment's area that lies on its own object.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.api import apply_jeans
from jeanscv.paint.compositing import polygon_coverage_patch
from testkit.synthetic_photos import two_objects

ROOT = Path(__file__).resolve().parents[1]


def shares(result, masks) -> list[str]:
    """Per garment: the share of its area on the object it overlaps most."""
    out = []
    for entry in result.report()["objects"]:
        coverage = polygon_coverage_patch(np.asarray(entry["vertices_image"], np.float64), *masks[0].shape)
        out.append(f"{max(float((coverage * m).sum() / coverage.sum()) for m in masks):.1%}")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "objects.jpg")
    args = parser.parse_args()
    photo = two_objects()
    dog = photo.masks[1]
    ys, xs = np.nonzero(dog)
    click = (float(np.median(xs)), float(np.median(ys)))
    panels = [photo.image]
    for label, options in (
        ("--objects all", dict(objects="all")),
        (f"--point {click[0]:g},{click[1]:g}", dict(points=[click])),
    ):
        result = apply_jeans(photo.image, **options)
        print(
            f"{label}: {len(result.objects)} garment(s), on their own object: {', '.join(shares(result, photo.masks))}"
        )
        panels.append(result.image)
    height, width = photo.image.shape[:2]
    gap = np.full((height, 8, 3), 255, np.uint8)
    strip = np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)
    image = Image.fromarray(strip)
    image = image.resize((image.width // 2, image.height // 2), Image.Resampling.BOX)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    image.save(args.out, quality=88)
    print(f"wrote {args.out} ({image.width}x{image.height})")


if __name__ == "__main__":
    main()
