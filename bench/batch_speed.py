"""Batch speed of the command line: photos per second and peak memory, -j 1 and -j 2.

    python bench/batch_speed.py [--count 100] [--megapixels 12] [--jobs 1 2]

Makes a folder of ``count`` photos (real textures from scikit-image, an animal-like
object on a ground, JPEG, about ``megapixels`` MP each), runs ``jeanscv FOLDER -o OUT
-j N -q`` on it for each N, and prints wall time, photos per second and the peak
resident memory of the busiest process. Then one 24-MP photo for the memory bound.
"""

from __future__ import annotations

import argparse
import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from jeanscv.synthetic import random_creature


def make_photo(path: Path, seed: int, megapixels: float) -> None:
    from skimage import data

    rng = np.random.default_rng(seed)
    width = int(math.sqrt(megapixels * 1e6 * 4 / 3))
    height = int(width * 3 / 4)
    grounds = [data.grass(), data.gravel(), data.brick()]
    ground = grounds[seed % len(grounds)].astype(np.float32)
    ground = np.asarray(Image.fromarray(ground.astype(np.uint8)).resize((width, height), Image.BILINEAR))
    ground = np.stack([ground * 0.8, ground * 0.9, ground * 0.7], axis=-1)
    shape = random_creature(seed)
    mask = np.asarray(Image.fromarray((shape * 255).astype(np.uint8)).resize((height, height), Image.BILINEAR)) / 255.0
    full = np.zeros((height, width), np.float32)
    left = (width - height) // 2
    full[:, left : left + height] = mask
    fur = np.array(rng.uniform(120, 230, 3), np.float32)
    photo = ground * (1 - full[..., None]) + fur * full[..., None]
    Image.fromarray(np.clip(photo, 0, 255).astype(np.uint8)).save(path, quality=90)


def run(folder: Path, out: Path, jobs: int) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of the busiest process of one CLI run."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    began = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "jeanscv", str(folder), "-o", str(out), "-j", str(jobs), "-q", "--overwrite"],
        check=True,
    )
    wall = time.perf_counter() - began
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return wall, max(peak, before) / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--megapixels", type=float, default=12.0)
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "photos"
        folder.mkdir()
        for seed in range(args.count):
            make_photo(folder / f"photo_{seed:03d}.jpg", seed, args.megapixels)
        print(f"{args.count} photos of {args.megapixels:g} MP")
        print("| jobs | wall s | photos/s | peak RSS per process (MB) |")
        print("|---|---|---|---|")
        for jobs in args.jobs:
            wall, peak = run(folder, Path(tmp) / f"out{jobs}", jobs)
            print(f"| {jobs} | {wall:.1f} | {args.count / wall:.2f} | {peak:.0f} |", flush=True)
        big = Path(tmp) / "big"
        big.mkdir()
        make_photo(big / "big.jpg", 7, 24.0)
        wall, peak = run(big, Path(tmp) / "outbig", 1)
        print(f"\none 24-MP photo: {wall:.1f} s, peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
