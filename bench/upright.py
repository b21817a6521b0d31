"""Do the jeans hang upright? The default preset with ``posture="upright"`` against
``posture="any"`` (the earlier selection), back to back in one run.

    python -m bench.upright [--only photos,synthetic,silhouettes,shapes,paper] [--overlays DIR]

Counts, per posture, the fits that are upright (tilt <= 30 degrees, see
``jeanscv.fitting.posture.tilt_degrees``) and pass all six rule checks on:

- the real photos of ``../shared/real_photos`` through the real pipeline (decode,
  segmentation, framing, fit; each photo segmented once, fitted both ways);
- the test suite's synthetic photos (``testkit/synthetic_photos.py``: procedural and paper
  shapes in real textures on real backgrounds, seeds 2023 and 7), the same way;
- 16 silhouettes: the paper's 7 and the 9 of ``testkit/upright_shapes.py``;
- the 60 shapes of ``bench/presets_report.py`` and ``bench/unseen_shapes.py`` (all six
  checks only);

and the IoU of the jeans with the blue of the paper's six published figures, and the
total fit CPU time of each posture. ``--overlays DIR`` writes the photo fits as PNGs.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from bench.presets_report import PAPER_SHAPES, SHARED, load_shapes
from jeanscv.api import draw_figure
from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.posture import posture_name, tilt_degrees
from jeanscv.fitting.render import polygon_coverage
from testkit.real_photo_set import photo_paths
from testkit.synthetic import random_creature
from testkit.synthetic_photos import photo_set
from testkit.upright_shapes import upright_shapes

ROOT = Path(__file__).resolve().parents[1]


POSTURES = ("any", "upright")
UPRIGHT = 30.0  # the bar, degrees
PAPER_FIGURES = ("person", "vitruvian", "dog", "horse", "tripod", "balldragon")


class Tally:
    """Per posture: fits, upright and passing all six, passing all six, fit seconds."""

    def __init__(self) -> None:
        self.count = 0
        self.upright_passed = {p: 0 for p in POSTURES}
        self.passed = {p: 0 for p in POSTURES}
        self.seconds = {p: 0.0 for p in POSTURES}

    def fit_both(self, silhouette: np.ndarray) -> dict[str, tuple]:
        """Fit with each posture, back to back; ``{posture: (result, tilt, passed)}``."""
        self.count += 1
        out = {}
        for posture in POSTURES:
            # CPU time of this process (one torch thread): other work on the machine
            # moves wall-clock times more than the change being measured.
            began = time.process_time()
            result = fit(silhouette, posture=posture)
            self.seconds[posture] += time.process_time() - began
            tilt = tilt_degrees(result.vertices, result.garment)
            passed = rule_report(result.vertices, silhouette, result.garment).passed
            self.passed[posture] += passed
            self.upright_passed[posture] += passed and tilt <= UPRIGHT
            out[posture] = (result, tilt, passed)
        return out


def _cell(tilt: float, passed: bool) -> str:
    return f"{tilt:.0f}° {posture_name(tilt)}{'' if passed else ', fails a check'}"


def _row(name: str, fits: dict[str, tuple]) -> str:
    return f"| {name} | " + " | ".join(_cell(tilt, passed) for _, tilt, passed in fits.values()) + " |"


def photos(tally: Tally, named_pixels, overlays: Path | None) -> None:
    """Each ``(name, pixels)`` through segmentation and framing, then fitted both ways."""
    import jeanscv

    print("\n| photo | posture any | posture upright |\n| --- | --- | --- |")
    for name, pixels in named_pixels:
        try:
            silhouette = jeanscv.extract_silhouette(pixels)
        except jeanscv.JeansError as error:
            print(f"| {name} | {error} | |")
            tally.count += 1
            continue
        fits = tally.fit_both(silhouette.canvas)
        print(_row(name, fits), flush=True)
        if overlays is not None:
            # The canvas figures, posture any | posture upright.
            tiles = [Image.fromarray(draw_figure(silhouette.canvas, result.vertices)) for result, _, _ in fits.values()]
            sheet = Image.new("RGB", (2 * 256 + 8, 256), "grey")
            sheet.paste(tiles[0], (0, 0))
            sheet.paste(tiles[1], (256 + 8, 0))
            overlays.mkdir(parents=True, exist_ok=True)
            sheet.save(overlays / f"{name}.png")


def real_photos():
    """``(stem, RGB pixels)`` of the shared real photos, decoded as the CLI decodes them."""
    import jeanscv

    for path in photo_paths():
        yield path.stem, jeanscv.load_image(path).pixels[..., :3]


def synthetic_photos(seeds=(2023, 7)):
    """``(name, RGB pixels)`` of the test suite's textured photos (``testkit/synthetic_photos.py``)."""
    for seed in seeds:
        for case in photo_set(seed):
            yield f"{case.name}:{seed}", case.image


def silhouettes(tally: Tally) -> None:
    shapes = {name: load_shapes()[f"paper:{name}"] for name in PAPER_SHAPES if (SHARED / f"{name}.png").exists()}
    shapes.update(upright_shapes())
    print("\n| silhouette | posture any | posture upright |\n| --- | --- | --- |")
    for name, silhouette in shapes.items():
        print(_row(name, tally.fit_both(silhouette)), flush=True)


def rule_shapes(tally: Tally) -> None:
    shapes = {name: s for name, s in load_shapes().items()}
    shapes.update({f"creature:{seed}": random_creature(seed) for seed in range(1000, 1030)})
    failed = {p: [] for p in POSTURES}
    for name, silhouette in shapes.items():
        for posture, (_, _, passed) in tally.fit_both(silhouette).items():
            if not passed:
                failed[posture].append(name)
    for posture in POSTURES:
        print(
            f"60 shapes, posture {posture}: {tally.passed[posture]}/{tally.count} pass all six; failing: {failed[posture]}"
        )


def paper_iou() -> None:
    print("\n| figure | IoU, posture any | IoU, posture upright |\n| --- | ---: | ---: |")
    means = {p: [] for p in POSTURES}
    for name in PAPER_FIGURES:
        path = SHARED / f"{name}_paper_result.png"
        if not path.exists():
            continue
        figure = np.asarray(Image.open(path).convert("RGB")).astype(int)
        blue = (figure[..., 2] > 150) & (figure[..., 0] < 120)
        silhouette = load_shapes()[f"paper:{name}"]
        cells = []
        for posture in POSTURES:
            vertices = fit(silhouette, posture=posture).vertices
            jeans = polygon_coverage(torch.as_tensor(vertices)[None], 256, 256)[0].numpy() > 0.5
            means[posture].append((blue & jeans).sum() / (blue | jeans).sum())
            cells.append(f"{means[posture][-1]:.2f}")
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    if means["any"]:
        print("| mean | " + " | ".join(f"{np.mean(means[p]):.3f}" for p in POSTURES) + " |")


def report(label: str, tally: Tally) -> None:
    counts = ", ".join(f"{p}: {tally.upright_passed[p]}/{tally.count}" for p in POSTURES)
    times = ", ".join(f"{p} {tally.seconds[p]:.1f} s" for p in POSTURES) + " CPU"
    print(f"{label}: upright and all six checks passed, posture {counts}; fit time {times}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", default="photos,synthetic,silhouettes,shapes,paper")
    parser.add_argument("--overlays", type=Path, help="write each photo's two fits here as PNG")
    args = parser.parse_args()
    parts = set(args.only.split(","))
    torch.set_num_threads(1)
    tallies = {}
    if "photos" in parts and photo_paths():
        tallies["real photos"] = Tally()
        photos(tallies["real photos"], real_photos(), args.overlays)
    if "synthetic" in parts:
        tallies["synthetic photos"] = Tally()
        photos(tallies["synthetic photos"], synthetic_photos(), args.overlays)
    if "silhouettes" in parts:
        tallies["16 silhouettes"] = Tally()
        silhouettes(tallies["16 silhouettes"])
    if "shapes" in parts:
        tallies["60 shapes"] = Tally()
        rule_shapes(tallies["60 shapes"])
    if "paper" in parts:
        paper_iou()
    print()
    for label, tally in tallies.items():
        report(label, tally)
    total = {p: sum(t.seconds[p] for t in tallies.values()) for p in POSTURES}
    if total["any"]:
        print(f"fit CPU time, all fits: upright / any = {total['upright'] / total['any']:.2f}x")


if __name__ == "__main__":
    main()
