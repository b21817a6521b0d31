"""Fit speed: ms per iteration and seconds per 100-iteration fit, one start and the
multi-start batch, and what multi-start buys in objective.

    python bench/fit_speed.py [--repeats 3] [--device cpu]

Uses ../shared/silhouettes/*.png when present, else the synthetic zoo.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.fitter import fit
from jeanscv.synthetic import silhouette_zoo

SHARED = Path(__file__).resolve().parents[2] / "shared" / "silhouettes"


def shapes() -> dict[str, np.ndarray]:
    found = {
        p.stem: np.asarray(Image.open(p), dtype=np.float32) / 255.0
        for p in sorted(SHARED.glob("*.png"))
        if not p.stem.endswith("_paper_result")
    }
    return found or silhouette_zoo(["person", "dog", "spider", "blob_a", "kangaroo", "tree", "crab"])


def timed(silhouette: np.ndarray, repeats: int, **options) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeats):
        began = time.perf_counter()
        result = fit(silhouette, **options)
        times.append(time.perf_counter() - began)
    return statistics.median(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--iterations", type=int, default=100)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args()
    fit(silhouette_zoo(["blob_a"])["blob_a"], iterations=5, device=args.device)  # warm-up

    print("| silhouette | 1 start: s/fit | ms/iteration | multi-start (18 -> 3 -> 2): s/fit | ratio | objective 1 start | objective multi | paper preset (16 -> 5): s/fit |")
    print("|---|---|---|---|---|---|---|---|")
    singles, multis, papers = [], [], []
    for name, silhouette in shapes().items():
        common = dict(iterations=args.iterations, device=args.device)
        single, single_result = timed(silhouette, args.repeats, starts=1, **common)
        multi, multi_result = timed(silhouette, args.repeats, **common)
        paper, _ = timed(silhouette, 1, preset="paper", **common)
        singles.append(single)
        multis.append(multi)
        papers.append(paper)
        print(
            f"| {name} | {single:.2f} | {1000 * single / args.iterations:.1f} | {multi:.2f} | {multi / single:.1f}x "
            f"| {single_result.objective:.3f} | {multi_result.objective:.3f} | {paper:.2f} |",
            flush=True,
        )
    print(
        f"\nmedian: 1 start {statistics.median(singles):.2f} s, multi-start {statistics.median(multis):.2f} s "
        f"({statistics.median(multis) / statistics.median(singles):.1f}x), paper preset {statistics.median(papers):.2f} s"
    )


if __name__ == "__main__":
    main()
