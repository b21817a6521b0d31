"""Batch speed of the command line, both fitting backends side by side in one run:
photos per second and peak memory; one photo in a fresh process, and where its time goes.

    python -m bench.batch_speed [--count 100] [--megapixels 12] [--jobs 2]

Makes a folder of ``count`` photos (real textures from scikit-image, an animal-like
object on a ground, JPEG, about ``megapixels`` MP each), runs ``jeanscv FOLDER -o OUT
-j N -q --backend B`` on it for each N and B, and prints wall time, photos per second
and the peak resident memory of the busiest process. Then ``jeanscv PHOTO`` on one
photo in a fresh process (wall time, as a user sees it), the stages of that command
timed in a fresh process, and one 24-MP photo for the memory bound.
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# The parent stays small: a child forked from a 2-GB parent would report the
# parent's pages as its own peak memory, so photos are made in a child process.


def make_photo(path: Path, seed: int, megapixels: float) -> None:
    import numpy as np
    from PIL import Image
    from skimage import data

    from testkit.synthetic import random_creature

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


def make_photos(folder: Path, seeds: range, megapixels: float) -> None:
    """Make the photos in a child process (see above)."""
    code = (
        "import sys; from bench.batch_speed import make_photo; from pathlib import Path; "
        "[make_photo(Path(sys.argv[1]) / f'photo_{s:03d}.jpg', s, float(sys.argv[4])) "
        "for s in range(int(sys.argv[2]), int(sys.argv[3]))]"
    )
    subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            str(folder),
            str(seeds.start),
            str(seeds.stop),
            str(megapixels),
        ],
        check=True,
        cwd=ROOT,  # where ``bench`` and ``testkit`` are importable
    )


_MEASURED = (
    "import resource, runpy, sys\n"
    "report = sys.argv[1]\n"
    "sys.argv = ['jeanscv'] + sys.argv[2:]\n"
    "try:\n"
    "    runpy.run_module('jeanscv', run_name='__main__')\n"
    "except SystemExit:\n"
    "    pass\n"
    "peak = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
    "open(report, 'w').write(str(peak))\n"
)


def run(folder: Path, out: Path, jobs: int, options: list[str] | tuple[str, ...] = ()) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of the busiest process of one CLI run (with more
    ``options``), as the CLI process itself (and its -j workers) saw it."""
    report = out.with_suffix(".peak")
    began = time.perf_counter()
    subprocess.run(
        [
            sys.executable,
            "-c",
            _MEASURED,
            str(report),
            str(folder),
            "-o",
            str(out),
            "-j",
            str(jobs),
            "-q",
            "--overwrite",
            *options,
        ],
        check=True,
    )
    wall = time.perf_counter() - began
    return wall, int(report.read_text()) / 1024.0


BACKENDS = ("fast", "torch")

# The stages of `jeanscv PHOTO`, timed in a fresh process (argv: photo, out, backend).
_STAGES = (
    "import sys, time\n"
    "began = time.perf_counter()\n"
    "marks = []\n"
    "def mark(name):\n"
    "    marks.append((name, time.perf_counter()))\n"
    "from jeanscv import api\n"
    "from jeanscv.io.write import encode_image\n"
    "mark('import jeanscv')\n"
    "loaded = api.load_image(sys.argv[1])\n"
    "mark('decode')\n"
    "silhouette = api.extract_silhouettes(loaded.pixels)[0]\n"
    "mark('segmentation')\n"
    "result = api.fit(silhouette, backend=sys.argv[3])\n"
    "mark('fit')\n"
    "image = api.composite(loaded.pixels, result, silhouette)\n"
    "mark('denim')\n"
    "from jeanscv.fitting.checks import rule_report\n"
    "rule_report(result.vertices, silhouette.canvas)\n"
    "mark('rule checks')\n"
    "data = encode_image(image, 'JPEG', quality=95, exif=loaded.exif, icc_profile=loaded.icc_profile)\n"
    "open(sys.argv[2], 'wb').write(data)\n"
    "mark('encode + write')\n"
    "previous = began\n"
    "for name, when in marks:\n"
    "    print(f'{name}\\t{when - previous:.3f}')\n"
    "    previous = when\n"
    "print(f'torch imported\\t{\"torch\" in sys.modules}')\n"
)


def stages(photo: Path, out: Path, backend: str) -> dict[str, str]:
    """Seconds per stage of one photo in a fresh process."""
    done = subprocess.run(
        [sys.executable, "-c", _STAGES, str(photo), str(out), backend], check=True, capture_output=True, text=True
    )
    return dict(line.split("\t") for line in done.stdout.splitlines())


def one_photo(photo: Path, out: Path, backend: str) -> float:
    """Wall seconds of ``jeanscv PHOTO`` in a fresh process (the second of two runs,
    so the disk cache holds the libraries as it does for a user's repeated runs)."""
    command = [sys.executable, "-m", "jeanscv", str(photo), "-o", str(out), "-q", "--overwrite", "--backend", backend]
    subprocess.run(command, check=True)
    began = time.perf_counter()
    subprocess.run(command, check=True)
    return time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=100)
    parser.add_argument("--megapixels", type=float, default=12.0)
    parser.add_argument("--jobs", type=int, nargs="+", default=[2])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "photos"
        folder.mkdir()
        make_photos(folder, range(args.count), args.megapixels)
        print(f"{args.count} photos of {args.megapixels:g} MP")
        print("| backend | jobs | wall s | photos/s | peak RSS per process (MB) |")
        print("|---|---|---|---|---|")
        for jobs in args.jobs:
            for backend in BACKENDS:
                wall, peak = run(folder, Path(tmp) / f"out{jobs}{backend}", jobs, ["--backend", backend])
                print(f"| {backend} | {jobs} | {wall:.1f} | {args.count / wall:.2f} | {peak:.0f} |", flush=True)

        photo = sorted(folder.glob("*.jpg"))[0]
        print(
            f"\none {args.megapixels:g}-MP photo, `jeanscv PHOTO` in a fresh process: "
            + ", ".join(f"{b} {one_photo(photo, Path(tmp) / 'single', b):.2f} s" for b in BACKENDS)
        )
        timed = {b: stages(photo, Path(tmp) / f"stages_{b}.jpg", b) for b in BACKENDS}
        print("\n| stage (fresh process) | " + " | ".join(f"{b} s" for b in BACKENDS) + " |")
        print("|---|" + "---|" * len(BACKENDS))
        for name in timed[BACKENDS[0]]:
            print(f"| {name} | " + " | ".join(timed[b][name] for b in BACKENDS) + " |")

        big = Path(tmp) / "big"
        big.mkdir()
        make_photos(big, range(7, 8), 24.0)
        wall, peak = run(big, Path(tmp) / "outbig", 1)
        print(f"\none 24-MP photo: {wall:.1f} s, peak RSS {peak:.0f} MB")


if __name__ == "__main__":
    main()
