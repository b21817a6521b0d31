"""What a person waits for, side by side in one run: the first command after install (kernels
not compiled yet), one 12-MP photo in a fresh process, the imports on that path, a folder of
varied 12-MP photos with ``-j 2`` (and where a photo's time goes), and the default fit.

    python -m bench.latency [--photos N] [--skip-cold] [--pets] [--detector auto|none|both]

- *first run*: ``jeanscv sample_images/cat.jpg`` with an empty kernel cache
  (``JEANSCV_CACHE_DIR``), as after ``pip install`` (which leaves the modules' bytecode
  compiled); then the same command again (cached), and whether both wrote the same bytes.
- *fresh process*: ``jeanscv PHOTO`` on a 12-MP copy of a shared photo, kernels cached,
  median of three runs after one to warm the disk cache.
- *imports*: seconds of each heavy import on that path, each measured in its own fresh
  process after the ones before it (numpy, OpenCV, the library, numba, loading the cached
  kernels).
- *batch*: the shared real photos (``../shared/real_photos``) upscaled to 12 MP, and a few
  textured synthetic scenes (bench.batch_speed), through ``jeanscv FOLDER -j 2``; then the
  stages of each photo in one process on one core as a ``-j`` worker runs them (decode,
  segmentation, fit, denim, encode; the detector's own seconds apart), in CPU seconds per
  photo after a warm-up photo. ``--pets``: the shared pet photos instead.
- ``--detector both``: the fresh process, the batch and the stages with ``--detector
  none`` (classical finding, as before the detector) and ``auto``, side by side in one run.
- *fit*: CPU seconds of the default fit on the paper's silhouettes (median).

Every process started here runs without ``PYTHONDONTWRITEBYTECODE``: ``pip install``
compiles the modules' bytecode, so a user's fresh process reads it instead of compiling
the library's source (about 0.1 s more in a shell that sets it, as some containers do).

Timings drift with other jobs on the machine: compare figures from one run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.batch_speed import make_photos, run
from bench.clicks import PETS as PET_PHOTOS
from bench.clicks import SHARED as PHOTOS
from bench.clicks import photo_pairs

ROOT = Path(__file__).resolve().parents[1]
TARGETS = {
    "first run": "<= 10 s",
    "fresh process": "<= 1.2 s",
    "imports": "<= 0.4 s",
    "batch": "<= 0.40 s a photo",
    "fit": "<= 0.05 s",
}


def _command(args: list[str], env: dict | None = None) -> float:
    began = time.perf_counter()
    subprocess.run([sys.executable, "-m", "jeanscv", *args], check=True, env=env, capture_output=True)
    return time.perf_counter() - began


def first_run(tmp: Path) -> tuple[float, float, bool]:
    """Wall seconds of the README's first command with empty caches, then cached, and
    whether the two outputs are the same bytes."""
    env = {**os.environ, "JEANSCV_CACHE_DIR": str(tmp / "cache")}
    photo = str(ROOT / "sample_images" / "cat.jpg")
    cold = _command([photo, "-o", str(tmp / "cold"), "-q"], env)
    warm = _command([photo, "-o", str(tmp / "warm"), "-q"], env)
    same = (tmp / "cold" / "cat.jeans.jpg").read_bytes() == (tmp / "warm" / "cat.jeans.jpg").read_bytes()
    return cold, warm, same


# Each import of the photo path in a fresh process after the ones listed before it, so
# that a figure is that module's own cost (argv: how many of IMPORTS to do first).
IMPORTS = (
    ("numpy", "import numpy"),
    ("OpenCV", "import cv2"),
    ("the library and command line", "import jeanscv_cli.main, jeanscv.pipeline"),
    ("numba", "import numba"),
    ("the kernels' module", "import jeanscv.fitting._fast.kernels"),
    (
        "loading the cached kernels",
        "from jeanscv.fitting._fast import Objective; from jeanscv.fitting.garments import JEANS; import numpy as np;"
        "from jeanscv.fitting.adam import BatchAdam;"
        "k = Objective(JEANS, 'all', {'coverage': 1.0}); k(JEANS.template[None], np.ones((16, 16)), 0.25);"
        "k.descend(BatchAdam(JEANS.template[None] / 16, 0.01), np.ones((16, 16)), 1, 0.25)",
    ),
    ("torch (the detector's)", "import torch"),
    ("loading the detector", "from jeanscv.detect import load; load()"),
)

# The snippets come as arguments, not by importing this module, whose own imports
# (numpy and OpenCV, through bench.batch_speed and bench.clicks) would be timed as free.
_TIMED_IMPORT = (
    "import sys, time\n"
    "*before, timed = sys.argv[1:]\n"
    "for code in before:\n"
    "    exec(code)\n"
    "began = time.perf_counter()\n"
    "exec(timed)\n"
    "print(time.perf_counter() - began)\n"
)


def imports() -> list[tuple[str, float]]:
    """Median seconds of each import of IMPORTS over three fresh processes."""
    figures = []
    for count, (name, _) in enumerate(IMPORTS):
        times = []
        snippets = [code for _, code in IMPORTS[: count + 1]]
        for _ in range(3):
            done = subprocess.run(
                [sys.executable, "-c", _TIMED_IMPORT, *snippets], check=True, capture_output=True, text=True, cwd=ROOT
            )
            times.append(float(done.stdout.split()[-1]))
        figures.append((name, statistics.median(times)))
    return figures


def upscaled_folder(folder: Path, count: int, synthetic: int, source: Path = PHOTOS) -> None:
    """The shared photos of ``source`` (first ``count``) as 12-MP JPEGs, plus ``synthetic`` textured scenes."""
    from PIL import Image

    folder.mkdir(parents=True)
    for name, path, _ in photo_pairs([source])[:count]:
        with Image.open(path) as image:
            image = image.convert("RGB")
            scale = (12e6 / (image.width * image.height)) ** 0.5
            image.resize((round(image.width * scale), round(image.height * scale)), Image.LANCZOS).save(
                folder / f"{name}.jpg", quality=92
            )
    make_photos(folder, range(synthetic), 12.0)


# The stages of each photo of a folder, as a -j worker runs them (OpenCV on one thread,
# freed memory kept for the next photo): CPU seconds, which other jobs on the machine
# disturb far less than wall time, after one photo that warms up (lazy imports, the
# kernels). argv: the folder.
_STAGES = (
    "import sys, time, json\n"
    "from pathlib import Path\n"
    "import cv2\n"
    "cv2.setNumThreads(1)\n"
    "from jeanscv import api\n"
    "from jeanscv.io.write import encode_image\n"
    "from jeanscv_cli.worker import reuse_freed_memory\n"
    "reuse_freed_memory()\n"
    "totals = {}\n"
    "detector = sys.argv[2]\n"
    "from jeanscv.subject import detected\n"
    "plain_detect = detected.detect\n"
    "def timed_detect(pixels):\n"
    "    began = time.process_time()\n"
    "    found = plain_detect(pixels)\n"
    "    totals['detector'] = totals.get('detector', 0.0) + time.process_time() - began\n"
    "    return found\n"
    "detected.detect = timed_detect\n"
    "def timed(name, began):\n"
    "    now = time.process_time()\n"
    "    totals[name] = totals.get(name, 0.0) + now - began\n"
    "    return now\n"
    "def one(path):\n"
    "    began = time.process_time()\n"
    "    loaded = api.load_image(path)\n"
    "    began = timed('decode', began)\n"
    "    spent = totals.get('detector', 0.0)\n"
    "    silhouette = api.extract_silhouettes(loaded.pixels, detector=detector)[0]\n"
    "    began = timed('segmentation', began)\n"
    "    totals['segmentation'] -= totals.get('detector', 0.0) - spent\n"
    "    result = api.fit(silhouette)\n"
    "    began = timed('fit', began)\n"
    "    image = api.composite(loaded.pixels, result, silhouette)\n"
    "    began = timed('denim', began)\n"
    "    encode_image(image, 'JPEG', quality=95, exif=loaded.exif, icc_profile=loaded.icc_profile)\n"
    "    timed('encode', began)\n"
    "paths = sorted(Path(sys.argv[1]).glob('*.jpg'))\n"
    "one(paths[0])\n"
    "totals.clear()\n"
    "for path in paths:\n"
    "    one(path)\n"
    "print(json.dumps(totals))\n"
)


def stages(folder: Path, detector: str = "auto") -> dict[str, float]:
    """CPU seconds per photo of each stage, one process, one core, after a warm-up photo
    (the detector's own seconds apart from the rest of segmentation)."""
    import json

    done = subprocess.run(
        [sys.executable, "-c", _STAGES, str(folder), detector],
        check=True,
        capture_output=True,
        text=True,
        cwd=ROOT,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    count = len(list(folder.glob("*.jpg")))
    return {name: seconds / count for name, seconds in json.loads(done.stdout.splitlines()[-1]).items()}


def fit_seconds() -> float:
    """Median CPU seconds of the default fit over the paper's silhouettes (or the zoo)."""
    from bench.fit_speed import shapes, timed
    from jeanscv.fitting.fitter import fit

    silhouettes = shapes()
    fit(next(iter(silhouettes.values())), iterations=5)  # kernels loaded
    return statistics.median(timed(s, 3) for s in silhouettes.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--photos", type=int, default=18, help="shared photos in the batch (at most 18)")
    parser.add_argument("--synthetic", type=int, default=4, help="textured synthetic scenes in the batch")
    parser.add_argument("--skip-cold", action="store_true", help="skip the first run (a minute or so)")
    parser.add_argument("--pets", action="store_true", help="the shared pet photos instead of the real photos")
    parser.add_argument(
        "--detector",
        choices=("auto", "none", "both"),
        default="auto",
        help="automatic finding with the shipped detector, without, or both side by side",
    )
    args = parser.parse_args()
    detectors = ("none", "auto") if args.detector == "both" else (args.detector,)
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)  # as after pip install (see the module's docstring)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if not args.skip_cold:
            cold, warm, same = first_run(tmp / "first")
            rows.append(("first run", f"{cold:.1f} s (then {warm:.1f} s cached; same bytes: {same})"))
        folder = tmp / "photos"
        upscaled_folder(folder, args.photos, args.synthetic, PET_PHOTOS if args.pets else PHOTOS)
        photos = sorted(folder.glob("*.jpg"))
        for detector in detectors:
            one = [str(photos[0]), "-o", str(tmp / "one"), "-q", "--overwrite", "--detector", detector]
            _command(one)
            fresh = statistics.median(_command(one) for _ in range(3))
            rows.append(("fresh process", f"{fresh:.2f} s ({photos[0].name}, 12 MP, --detector {detector})"))
        figures = imports()
        heavy = sum(seconds for name, seconds in figures if name not in ("numpy", "OpenCV"))
        rows.append(
            (
                "imports",
                f"{heavy:.2f} s beyond numpy and OpenCV ("
                + ", ".join(f"{name} {seconds:.2f}" for name, seconds in figures)
                + ")",
            )
        )
        per_stage = {}
        for detector in detectors:
            wall, _ = run(folder, tmp / f"out-{detector}", 2, ["--detector", detector])
            rows.append(
                (
                    "batch",
                    f"{wall / len(photos):.2f} s a photo ({len(photos)} photos, -j 2, {wall:.0f} s, --detector {detector})",
                )
            )
            per_stage[detector] = stages(folder, detector)
        rows.append(("fit", f"{fit_seconds():.3f} s"))
    print("| what a person waits for | now | target |\n|---|---|---|")
    for name, figure in rows:
        print(f"| {name} | {figure} | {TARGETS[name]} |")
    print("\nOne photo's stages (12 MP, one process, one core, as a -j worker: CPU seconds a photo):\n")
    names = list(dict.fromkeys(name for figures in per_stage.values() for name in figures))
    print("| --detector | " + " | ".join(names) + " | total |\n|" + "---|" * (len(names) + 2))
    for detector, figures in per_stage.items():
        cells = " | ".join(f"{figures.get(name, 0.0):.3f}" for name in names)
        print(f"| {detector} | {cells} | {sum(figures.values()):.3f} |")


if __name__ == "__main__":
    main()
