"""Each built-in garment on the paper's person and on a dog (docs/garments.png).

python -m bench.garments_figure [--out docs]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.garments import GARMENTS
from jeanscv.paint.compositing import render_silhouette_figure
from testkit.synthetic import silhouette_zoo

SHARED = Path(__file__).resolve().parents[2] / "shared" / "silhouettes"


def shapes() -> dict[str, np.ndarray]:
    found = {}
    for name in ("person", "dog"):
        path = SHARED / f"{name}.png"
        found[name] = (
            np.asarray(Image.open(path), dtype=np.float32) / 255.0 if path.exists() else silhouette_zoo([name])[name]
        )
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="docs")
    args = parser.parse_args()
    tiles = []
    print("| garment | silhouette | rules |")
    print("|---|---|---|")
    for garment in GARMENTS.values():
        for name, silhouette in shapes().items():
            result = fit(silhouette, garment=garment)
            report = rule_report(result.vertices, silhouette, garment)
            tile = Image.fromarray(render_silhouette_figure(silhouette, result.vertices, garment))
            ImageDraw.Draw(tile).text((4, 2), f"{garment.name} on {name}", fill=(0, 0, 0))
            tiles.append(tile)
            print(
                f"| {garment.name} | {name} | {'6/6' if report.passed else 'fails ' + ', '.join(k for k, ok in report.checks.items() if not ok)} |"
            )
    sheet = Image.new("RGB", (256 * len(tiles), 256), "white")
    for i, tile in enumerate(tiles):
        sheet.paste(tile, (256 * i, 0))
    Path(args.out).mkdir(exist_ok=True)
    sheet.resize((128 * len(tiles), 128), Image.LANCZOS).save(Path(args.out) / "garments.png")


if __name__ == "__main__":
    main()
