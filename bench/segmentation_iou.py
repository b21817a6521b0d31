"""IoU of ``segment(image, "auto")`` on the synthetic photos of testkit/synthetic_photos.py,
as a markdown table (image, size, method chosen, IoU, ms) for the README.

    python -m bench.segmentation_iou [--seeds 2023] [--working-size 640]

Seed 2023 is the set the tests assert on; other seeds redraw shapes, texture crops and
noise for the same 16 cases (a robustness check). Cases whose paper silhouette is not
in ../shared/silhouettes are left out.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from jeanscv.subject.photo import segment
from testkit.synthetic_photos import iou, photo_set


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", default="2023", help="comma-separated photo seeds (default 2023)")
    parser.add_argument("--working-size", type=int, default=640)
    args = parser.parse_args()
    seeds = [int(seed) for seed in args.seeds.split(",")]
    print("| image | size | method | IoU | ms |")
    print("| --- | --- | --- | ---: | ---: |")
    scores, times = [], []
    for seed in seeds:
        for photo in photo_set(seed):
            start = time.perf_counter()
            result = segment(photo.image, working_size=args.working_size)
            elapsed = 1000 * (time.perf_counter() - start)
            score = iou(result.mask, photo.mask)
            scores.append(score)
            times.append(elapsed)
            label = photo.name if len(seeds) == 1 else f"{photo.name} (seed {seed})"
            print(f"| {label} | {photo.size} | {result.method} | {score:.3f} | {elapsed:.0f} |", flush=True)
    scores = np.array(scores)
    print(
        f"\n{len(scores)} images: mean IoU {scores.mean():.3f}, min {scores.min():.3f}, "
        f"{int((scores >= 0.9).sum())}/{len(scores)} at or above 0.90; median {np.median(times):.0f} ms"
    )


if __name__ == "__main__":
    main()
