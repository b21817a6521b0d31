"""CPU seconds of automatic segmentation on 12-MP copies of the real photos, one thread.

    python -m bench.segmentation_speed [--set real|pets] [--subject SUBJECT] [--only NAME,...]
                                       [--width 4000] [--stages]

Each photo of ``../shared/real_photos`` (``--set pets``: ``../shared/pet_photos``) is upscaled (bicubic) to ``--width`` pixels
wide (4000: 9-16 MP, 12 MP for a 4:3 photo) and segmented by
``jeanscv.subject.photo.segment(image, "auto", subject=SUBJECT)`` with OpenCV on one
thread (``--subject object`` leaves out the subject-kind cues of
:mod:`jeanscv.subject.kinds`: the cost before them);
the figure is ``time.process_time()`` around that call (it counts every thread of the
process), the best of ``--repeat`` runs. Prints one row per photo and the median; the
issue's target is 0.6 s.

``--stages`` also times the stages of the pipeline (per-thread CPU of the functions
named in ``STAGES``, inclusive of what they call) and prints them per photo and summed.
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from testkit.real_photo_set import PET_PHOTOS, REAL_PHOTOS, photo_paths

ROOT = Path(__file__).resolve().parents[1]


TARGET_SECONDS = 0.6
# (label, module, attribute path): functions whose own-thread CPU time is one stage.
STAGES = (
    ("scene", "jeanscv.subject.scene", "Scene.__init__"),
    ("saliency labels", "jeanscv.subject.consensus", "hypothesis_labels"),
    ("hypothesis cuts", "jeanscv.subject.photo", "grabcut_or_none"),
    ("border-colour cut", "jeanscv.subject.photo", "_grabcut_hypothesis"),
    ("threshold", "jeanscv.subject.photo", "_threshold"),
    ("choose", "jeanscv.subject.consensus", "choose"),
    ("subject kind", "jeanscv.subject.kinds", "choose_kind"),
    ("refine", "jeanscv.subject.photo", "refine"),
    ("working size (all)", "jeanscv.subject.photo", "_segment_photo"),
)


def _instrument(spent: dict[str, float]) -> None:
    """Wrap each stage's function so that its thread's CPU time adds to ``spent``."""
    import importlib

    for label, module_name, path in STAGES:
        owner = importlib.import_module(module_name)
        *parents, name = path.split(".")
        for parent in parents:
            owner = getattr(owner, parent, None)
        original = getattr(owner, name, None)
        if original is None:
            continue

        def timed(*args, _original=original, _label=label, **kwargs):
            start = time.thread_time()
            try:
                return _original(*args, **kwargs)
            finally:
                spent[_label] += time.thread_time() - start

        setattr(owner, name, functools.wraps(original)(timed))


def upscaled(path: Path, width: int) -> np.ndarray:
    """The photo as RGB uint8, resized (bicubic) to ``width`` pixels wide."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    height = round(bgr.shape[0] * width / bgr.shape[1])
    return cv2.cvtColor(cv2.resize(bgr, (width, height), interpolation=cv2.INTER_CUBIC), cv2.COLOR_BGR2RGB)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--set", choices=("real", "pets"), default="real", help="which shared folder")
    parser.add_argument("--subject", default="auto", help="auto, animal, person or object")
    parser.add_argument("--only", default="", help="comma-separated photo stems")
    parser.add_argument("--width", type=int, default=4000, help="width of the upscaled copies (pixels)")
    parser.add_argument("--repeat", type=int, default=1, help="runs per photo; the best counts")
    parser.add_argument("--stages", action="store_true", help="also print CPU seconds per stage")
    args = parser.parse_args()
    folder = {"real": REAL_PHOTOS, "pets": PET_PHOTOS}[args.set]
    paths = photo_paths(folder)
    if args.only:
        paths = [p for p in paths if p.stem in set(args.only.split(","))]
    if not paths:
        sys.exit(f"no photos in {folder}: nothing to measure")

    cv2.setNumThreads(1)
    from jeanscv.errors import JeansError
    from jeanscv.subject import photo

    spent: dict[str, float] = defaultdict(float)
    if args.stages:
        _instrument(spent)
    photo.segment(upscaled(paths[0], 320), "auto", subject=args.subject)  # first call: lazy imports, caches
    labels = [label for label, *_ in STAGES] if args.stages else []
    print("| photo | size | seg CPU s |" + "".join(f" {label} |" for label in labels))
    print("| --- | --- | ---: |" + " ---: |" * len(labels))
    seconds, totals = [], defaultdict(float)
    for path in paths:
        image = upscaled(path, args.width)
        best, best_stages = np.inf, {}
        for _ in range(args.repeat):
            spent.clear()
            start = time.process_time()
            try:
                photo.segment(image, "auto", subject=args.subject)
            except JeansError:
                pass  # a photo where nothing is found still costs its time
            elapsed = time.process_time() - start
            if elapsed < best:
                best, best_stages = elapsed, dict(spent)
        seconds.append(best)
        for label in labels:
            totals[label] += best_stages.get(label, 0.0)
        height, width = image.shape[:2]
        cells = "".join(f" {best_stages.get(label, 0.0):.3f} |" for label in labels)
        print(f"| {path.stem} | {width}x{height} | {best:.3f} |{cells}", flush=True)
    if labels:
        print("| **sum** | | " + f"{sum(seconds):.3f} |" + "".join(f" {totals[label]:.3f} |" for label in labels))
    print(
        f"\n{len(seconds)} photos at {args.width} px wide, subject {args.subject}, one thread: segmentation CPU s median "
        f"{np.median(seconds):.3f}, max {np.max(seconds):.3f} (target {TARGET_SECONDS})"
    )


if __name__ == "__main__":
    main()
