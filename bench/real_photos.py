"""jeanscv on real photographs with reference masks (``../shared/real_photos``).

    python -m bench.real_photos [--no-fit] [--only NAME,...] [--sheet PATH]

Per photo and on average: the IoU of the subject mask with the reference mask, the
method chosen (marked uncertain where auto's hypotheses disagreed), the segmentation
time, and (unless ``--no-fit``) the share of the jeans' area on the reference subject,
the share of the subject they cover, their tilt and whether all six rule checks pass.
Writes a contact sheet (photo | reference | found mask | result) for looking at,
``docs/real_photos.jpg`` by default.

The reference masks are U-2-Net's published predictions (see the folder's README): a
strong learned model's answer, not hand labels.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from testkit.real_photo_set import REAL_PHOTOS, photo_paths, polygon_mask, reference_mask
from testkit.synthetic_photos import iou

ROOT = Path(__file__).resolve().parents[1]


TILE_HEIGHT = 150
ON_SUBJECT = 0.85  # the bar: jeans with at least this share of their area on the subject


def _tile(image: np.ndarray) -> np.ndarray:
    height, width = image.shape[:2]
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    return cv2.resize(
        image[..., :3], (max(1, round(width * TILE_HEIGHT / height)), TILE_HEIGHT), interpolation=cv2.INTER_AREA
    )


def _overlay(photo: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The photo dimmed outside ``mask``, with its outline in yellow."""
    out = photo[..., :3].copy()
    out[~mask] = (out[~mask] * 0.3).astype(np.uint8)
    outline = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)).astype(bool)
    out[cv2.dilate(outline.astype(np.uint8), np.ones((max(1, photo.shape[0] // 200),) * 2, np.uint8)).astype(bool)] = (
        255,
        230,
        0,
    )
    return out


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    tile = tile.copy()
    cv2.putText(tile, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 3, cv2.LINE_AA)
    cv2.putText(tile, text, (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1, cv2.LINE_AA)
    return tile


def contact_sheet(rows: list[list[np.ndarray]], columns: int = 2, gap: int = 6) -> np.ndarray:
    """Rows of tiles (each row one photo), laid out ``columns`` photos across."""
    strips = [
        np.concatenate(sum(([t, np.full((TILE_HEIGHT, gap, 3), 255, np.uint8)] for t in row), [])[:-1], axis=1)
        for row in rows
    ]
    width = max(s.shape[1] for s in strips)
    strips = [np.pad(s, ((0, 0), (0, width - s.shape[1]), (0, 0)), constant_values=255) for s in strips]
    lines = []
    for i in range(0, len(strips), columns):
        group = strips[i : i + columns] + [np.full_like(strips[0], 255)] * (columns - len(strips[i : i + columns]))
        lines.append(
            np.concatenate(
                sum(([s, np.full((TILE_HEIGHT, 3 * gap, 3), 255, np.uint8)] for s in group), [])[:-1], axis=1
            )
        )
        lines.append(np.full((gap, lines[-1].shape[1], 3), 255, np.uint8))
    return np.concatenate(lines[:-1], axis=0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--no-fit", action="store_true", help="segmentation only")
    parser.add_argument("--only", default="", help="comma-separated photo stems")
    parser.add_argument(
        "--sheet", default=str(ROOT / "docs" / "real_photos.jpg"), help="contact sheet path ('' for none)"
    )
    parser.add_argument("--objects", default="one", help="passed to the pipeline where supported")
    args = parser.parse_args()
    if not photo_paths():
        sys.exit(f"no photos in {REAL_PHOTOS}: nothing to measure")

    import jeanscv
    from jeanscv.fitting.posture import tilt_degrees

    paths = photo_paths()
    if args.only:
        wanted = set(args.only.split(","))
        paths = [p for p in paths if p.stem in wanted]
    print("| photo | size | method | IoU | seg s | jeans on subject | subject covered | tilt | rules |")
    print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |")
    ious, seconds, on_subject, rows = [], [], [], []
    for path in paths:
        loaded = jeanscv.load_image(path)
        pixels = loaded.pixels[..., :3]
        reference = reference_mask(path)
        start = time.process_time()
        try:
            silhouette = jeanscv.extract_silhouette(pixels)
            found, method = silhouette.mask >= 0.5, silhouette.method
            if silhouette.details.get("uncertain"):
                method += " (uncertain)"
        except jeanscv.JeansError as error:
            silhouette, found, method = None, np.zeros_like(reference), f"error: {error}"
        elapsed = time.process_time() - start
        score = iou(found, reference)
        ious.append(score)
        seconds.append(elapsed)
        cells = [f"{score:.3f}", f"{elapsed:.2f}"]
        tiles = [
            _label(_tile(pixels), path.stem),
            _label(_tile(_overlay(pixels, reference)), "reference"),
            _label(_tile(_overlay(pixels, found)), f"found {score:.2f}"),
        ]
        if not args.no_fit and silhouette is not None:
            fit = jeanscv.fit(silhouette)
            jeans = polygon_mask(fit.vertices_image, reference.shape)
            share = float((jeans & reference).sum() / max(jeans.sum(), 1))
            covered = float((jeans & reference).sum() / max(reference.sum(), 1))
            rules = jeanscv.fitting.checks.rule_report(fit.vertices, silhouette.canvas, fit.garment)
            on_subject.append(share)
            tilt = tilt_degrees(fit.vertices, fit.garment)
            cells += [f"{share:.2f}", f"{covered:.2f}", f"{tilt:.0f}", "6/6" if rules.passed else "fail"]
            result = jeanscv.composite(pixels, fit, silhouette)
            tiles.append(_label(_tile(result), f"on subject {share:.2f}"))
        elif not args.no_fit:
            on_subject.append(0.0)
            cells += ["-", "-", "-", "-"]
        else:
            cells += ["-", "-", "-", "-"]
        rows.append(tiles)
        height, width = reference.shape
        print(f"| {path.stem} | {width}x{height} | {method} | " + " | ".join(cells) + " |", flush=True)
    ious = np.array(ious)
    summary = f"\n{len(ious)} photos: mean IoU {ious.mean():.3f}, median {np.median(ious):.3f}, min {ious.min():.3f}; "
    summary += f"segmentation CPU s median {np.median(seconds):.2f}, max {np.max(seconds):.2f}"
    if on_subject:
        hits = int((np.array(on_subject) >= ON_SUBJECT).sum())
        summary += f"; jeans >= {ON_SUBJECT:.0%} on the subject: {hits} of {len(on_subject)}"
    print(summary)
    if args.sheet:
        sheet = contact_sheet(rows)
        Path(args.sheet).parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(args.sheet, cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 85])
        print(f"contact sheet: {args.sheet}")


if __name__ == "__main__":
    main()
