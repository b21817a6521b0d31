"""Fit the `default` and `paper` presets on every silhouette we test; print a markdown
table of the four rules' checks and the jeans' posture, and write comparison pictures
into docs/.

    python -m bench.presets_report [--out docs] [--iterations 100]

Uses ../shared/silhouettes/*.png when present and the synthetic zoo always.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.posture import posture_name, tilt_degrees
from jeanscv.paint.compositing import render_silhouette_figure
from testkit.synthetic import silhouette_zoo

SHARED = Path(__file__).resolve().parents[2] / "shared" / "silhouettes"
PAPER_SHAPES = ["person", "vitruvian", "dog", "horse", "tripod", "balldragon", "extra_0"]
PRESETS = ("default", "paper")


def load_shapes() -> dict[str, np.ndarray]:
    shapes = {}
    for name in PAPER_SHAPES:
        path = SHARED / f"{name}.png"
        if path.exists():
            shapes[f"paper:{name}"] = np.asarray(Image.open(path), dtype=np.float32) / 255.0
    shapes.update({f"zoo:{k}": v for k, v in silhouette_zoo().items()})
    return shapes


def tile(silhouette: np.ndarray, vertices: np.ndarray, label: str, ok: bool) -> Image.Image:
    image = Image.fromarray(render_silhouette_figure(silhouette, vertices))
    draw = ImageDraw.Draw(image)
    draw.text((4, 2), label, fill=(0, 0, 0))
    draw.text((4, 244), "all 6 checks pass" if ok else "fails a check", fill=(0, 128, 0) if ok else (200, 0, 0))
    return image


def sheet(rows: list[list[Image.Image]], columns: int) -> Image.Image:
    size = 256
    flat = [im for row in rows for im in row]
    count_rows = (len(flat) + columns - 1) // columns
    out = Image.new("RGB", (columns * size, count_rows * size), "white")
    for i, im in enumerate(flat):
        out.paste(im, ((i % columns) * size, (i // columns) * size))
    return out.resize((columns * size // 2, count_rows * size // 2), Image.LANCZOS)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="docs")
    parser.add_argument("--iterations", type=int, default=100)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    shapes = load_shapes()
    print(
        "| silhouette | default: checks | default: objective | default: tilt | paper: checks | paper: objective (printed weights) |"
    )
    print("|---|---|---|---|---|---|")
    tiles: dict[str, dict[str, Image.Image]] = {p: {} for p in PRESETS}
    passed = {p: 0 for p in PRESETS}
    upright = {p: 0 for p in PRESETS}
    seconds = {p: 0.0 for p in PRESETS}
    for name, silhouette in shapes.items():
        cells = [name]
        for preset in PRESETS:
            began = time.perf_counter()
            result = fit(silhouette, preset, iterations=args.iterations)
            seconds[preset] += time.perf_counter() - began
            report = rule_report(result.vertices, silhouette)
            failed = [k for k, ok in report.checks.items() if not ok]
            passed[preset] += report.passed
            tilt = tilt_degrees(result.vertices, result.garment)
            upright[preset] += posture_name(tilt) == "upright"
            cells += [
                "6/6" if report.passed else f"{6 - len(failed)}/6 (fails {', '.join(failed)})",
                f"{result.objective:.3f}",
            ]
            if preset == "default":
                cells.append(f"{tilt:.0f}° {posture_name(tilt)}")
            tiles[preset][name] = tile(silhouette, result.vertices, f"{name} ({preset})", report.passed)
        print("| " + " | ".join(cells) + " |", flush=True)
    for preset in PRESETS:
        print(
            f"\n{preset}: {passed[preset]}/{len(shapes)} silhouettes pass all six checks, {upright[preset]}/{len(shapes)} "
            f"upright (tilt <= 30 degrees); {seconds[preset] / len(shapes):.2f} s per fit"
        )

    for group in ("paper", "zoo"):
        names = [n for n in shapes if n.startswith(group + ":")]
        if not names:
            continue
        if group == "paper":
            # Top row: the default preset; bottom row: the paper's printed objective.
            rows, columns = [[tiles["default"][n] for n in names], [tiles["paper"][n] for n in names]], len(names)
        else:
            rows, columns = [[tiles["default"][n], tiles["paper"][n]] for n in names], 8
        sheet(rows, columns).save(out / f"presets_{group}.png")
    print(f"\nwrote {out}/presets_paper.png and {out}/presets_zoo.png")


if __name__ == "__main__":
    main()
