"""The fit on CUDA beside the CPU's two backends, in one run on a GPU machine: wall seconds
of a default fit (multi-start, 100 iterations) and of a paper fit, median of ``--repeats``,
after one warm-up fit each; and where a CUDA fit's time goes (``--profile``).

    python -m bench.cuda_speed [--repeats 3] [--silhouettes DIR] [--presets default,paper] [--profile]

Silhouettes: ``DIR/*.png`` (default ../shared/silhouettes), else the synthetic zoo.
The CPU figures use every core torch is given (``torch.get_num_threads()``) for the
torch backend, and one core for the fast one (it is single-threaded).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from bench.fit_speed import SHARED, shapes
from jeanscv.fitting.fitter import fit

#: (label, fit options)
WAYS = (
    ("cuda", {"device": "cuda"}),
    ("cpu fast", {"backend": "fast"}),
    ("cpu torch", {"backend": "torch"}),
)


def timed(silhouette: np.ndarray, repeats: int, **options) -> tuple[float, float]:
    """Median wall seconds of ``repeats`` fits, and the last fit's objective."""
    times, objective = [], float("nan")
    for _ in range(repeats):
        began = time.perf_counter()
        result = fit(silhouette, **options)
        times.append(time.perf_counter() - began)
        objective = result.objective
    return statistics.median(times), objective


def profile_one(silhouette: np.ndarray) -> str:
    """cProfile of one default CUDA fit: the 20 costliest functions by their own time."""
    profiler = cProfile.Profile()
    profiler.enable()
    fit(silhouette, device="cuda")
    profiler.disable()
    out = io.StringIO()
    pstats.Stats(profiler, stream=out).sort_stats("tottime").print_stats(20)
    return out.getvalue()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--silhouettes", type=Path, default=SHARED)
    parser.add_argument("--presets", default="default,paper", help="comma-separated presets to time")
    parser.add_argument("--profile", action="store_true", help="print where a CUDA fit's time goes")
    args = parser.parse_args()
    if not torch.cuda.is_available():
        raise SystemExit("bench.cuda_speed needs CUDA")
    found = shapes(args.silhouettes)
    first = next(iter(found.values()))
    for _, options in WAYS:  # warm-up: kernels loaded, CUDA context and caching allocator
        fit(first, iterations=5, **options)
    print(f"{torch.cuda.get_device_name()}; torch {torch.__version__}, {torch.get_num_threads()} CPU threads\n")
    for preset in args.presets.split(","):
        print(f"{preset} preset: wall seconds per fit (median of {args.repeats}), objective in brackets\n")
        print("| silhouette | " + " | ".join(label for label, _ in WAYS) + " |")
        print("|---|" + "---:|" * len(WAYS))
        totals = dict.fromkeys((label for label, _ in WAYS), 0.0)
        for name, silhouette in found.items():
            cells = []
            for label, options in WAYS:
                seconds, objective = timed(silhouette, args.repeats, preset=preset, **options)
                totals[label] += seconds
                cells.append(f"{seconds:.3f} ({objective:.3f})")
            print(f"| {name} | " + " | ".join(cells) + " |")
        print("| **mean** | " + " | ".join(f"**{totals[label] / len(found):.3f}**" for label, _ in WAYS) + " |\n")
    if args.profile:
        print(profile_one(first))


if __name__ == "__main__":
    main()
