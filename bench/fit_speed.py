"""Fit speed of the two backends side by side, measured in the same run: seconds per
100-iteration fit of the default preset (multi-start) and of the paper preset, and
ms per iteration of a one-start fit.

    python -m bench.fit_speed [--repeats 3] [--iterations 100]

Uses ../shared/silhouettes/*.png when present, else the synthetic zoo. One thread
(the fast path is single-threaded; torch is set to one thread, its fastest here), so
the figures are the process's CPU seconds: the wall time of an idle machine, and much
less disturbed than wall time when other jobs share the cores.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.fitting.fitter import fit
from testkit.synthetic import silhouette_zoo

SHARED = Path(__file__).resolve().parents[2] / "shared" / "silhouettes"
BACKENDS = ("fast", "torch")


def shapes(folder: Path = SHARED) -> dict[str, np.ndarray]:
    """The silhouettes ``folder/*.png`` (the paper's figures left out), else the synthetic zoo."""
    found = {
        p.stem: np.asarray(Image.open(p), dtype=np.float32) / 255.0
        for p in sorted(folder.glob("*.png"))
        if not p.stem.endswith("_paper_result")
    }
    return found or silhouette_zoo(["person", "dog", "spider", "blob_a", "kangaroo", "tree", "crab"])


def timed(silhouette: np.ndarray, repeats: int, **options) -> float:
    """Median CPU seconds of ``repeats`` fits."""
    times = []
    for _ in range(repeats):
        began = time.process_time()
        fit(silhouette, **options)
        times.append(time.process_time() - began)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=100)
    args = parser.parse_args()
    for backend in BACKENDS:  # warm-up: kernels loaded, torch imported
        fit(silhouette_zoo(["blob_a"])["blob_a"], iterations=5, backend=backend)

    print("CPU seconds per fit (one thread)\n")
    print(
        "| silhouette | default: fast s | default: torch s | speed-up | paper: fast s | paper: torch s | speed-up "
        "| 1 start: fast ms/it | 1 start: torch ms/it |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    figures: dict[str, list[float]] = {}
    for name, silhouette in shapes().items():
        row = {}
        for backend in BACKENDS:
            common = dict(iterations=args.iterations, backend=backend)
            row[f"default {backend}"] = timed(silhouette, args.repeats, **common)
            row[f"paper {backend}"] = timed(silhouette, 1, preset="paper", **common)
            row[f"single {backend}"] = 1000 * timed(silhouette, args.repeats, starts=1, **common) / args.iterations
        for key, value in row.items():
            figures.setdefault(key, []).append(value)
        print(
            f"| {name} | {row['default fast']:.3f} | {row['default torch']:.2f} "
            f"| {row['default torch'] / row['default fast']:.0f}x | {row['paper fast']:.3f} | {row['paper torch']:.2f} "
            f"| {row['paper torch'] / row['paper fast']:.0f}x | {row['single fast']:.2f} | {row['single torch']:.1f} |",
            flush=True,
        )
    median = {key: statistics.median(values) for key, values in figures.items()}
    print(
        f"\nmedian: default {median['default fast']:.3f} s fast vs {median['default torch']:.2f} s torch "
        f"({median['default torch'] / median['default fast']:.0f}x); paper {median['paper fast']:.3f} s vs "
        f"{median['paper torch']:.2f} s ({median['paper torch'] / median['paper fast']:.0f}x); one start "
        f"{median['single fast']:.2f} vs {median['single torch']:.1f} ms per iteration"
    )


if __name__ == "__main__":
    main()
