"""jeanscv on real photographs with reference masks (``../shared/real_photos`` and
``../shared/pet_photos``).

    python -m bench.real_photos [--set real|pets|both] [--subject auto|animal|person|object]
                                [--detector auto|none] [--no-fit] [--only NAME,...]
                                [--sheets FOLDER] [--json PATH]

Per photo and on average, each set on its own: the IoU of the subject mask with the
reference mask, the method chosen (marked uncertain where the subject may be the wrong
thing), the segmentation time, and (unless ``--no-fit``) the share of the jeans' area
on the reference subject, the share of the subject they cover, their tilt and whether
all six rule checks pass. A set's summary line also says how the "unsure" note did: of
the wrong picks (jeans under 85% on the subject) how many it flagged (hits), and of the
right ones how many (false alarms). Writes a contact sheet per set (photo | reference |
found mask, with the detector's boxes, class and score | result) for looking at,
``docs/real_photos.jpg`` and ``docs/pet_photos.jpg`` by default. ``--detector none``
measures classical finding alone (the detector's own time per photo: ``bench.detector``).

The real photos' reference masks are U-2-Net's published predictions (see the folder's
README): a strong learned model's answer, not hand labels. The pet photos' masks are
one animal each, drawn by people (COCO, Oxford-IIIT Pet, DAVIS, GrabCut).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from testkit.real_photo_set import PET_PHOTOS, REAL_PHOTOS, photo_paths, polygon_mask, reference_mask
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


SETS = {"real": REAL_PHOTOS, "pets": PET_PHOTOS}


def _boxes(image: np.ndarray, detections: list[dict], dressed: dict | None) -> np.ndarray:
    """``image`` with each detection's box and ``class score`` drawn (the dressed one in
    green, the others in red)."""
    out = image.copy()
    thickness = max(1, image.shape[0] // 150)
    for detection in detections:
        colour = (40, 220, 40) if detection == dressed else (230, 40, 40)
        x0, y0, x1, y1 = (int(round(v)) for v in detection["box"])
        cv2.rectangle(out, (x0, y0), (x1, y1), colour, thickness)
        text = f"{detection['class']} {detection['score']:.2f}"
        scale = max(0.4, image.shape[0] / 600)
        cv2.putText(out, text, (x0 + 3, max(y0, 12) + int(14 * scale)), cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 2)
    return out


def measure_photo(path: Path, subject: str, fit: bool, detector: str = "auto") -> tuple[dict, list[np.ndarray]]:
    """One photo through auto (and the fit unless not ``fit``): its row's figures and
    its contact-sheet tiles."""
    import jeanscv
    from jeanscv.fitting.posture import tilt_degrees

    pixels = jeanscv.load_image(path).pixels[..., :3]
    reference = reference_mask(path)
    start = time.process_time()
    try:
        silhouette = jeanscv.extract_silhouettes(pixels, subject=subject, detector=detector)[0]
        found, method = silhouette.mask >= 0.5, silhouette.method
    except jeanscv.JeansError as error:
        silhouette, found, method = None, np.zeros_like(reference), f"error: {error}"
    row = {"photo": path.stem, "size": f"{reference.shape[1]}x{reference.shape[0]}", "method": method}
    row["seconds"] = time.process_time() - start
    row["iou"] = iou(found, reference)
    details = {} if silhouette is None else silhouette.details
    # A failure to find anything is a wrong pick the user is told about.
    row["uncertain"] = bool(details.get("uncertain", silhouette is None))
    row["chosen"], row["kind"] = details.get("chosen"), details.get("kind")
    tiles = [
        _label(_tile(pixels), path.stem),
        _label(_tile(_overlay(pixels, reference)), "reference"),
        _label(
            _tile(_boxes(_overlay(pixels, found), details.get("detections", []), details.get("detection"))),
            f"found {row['iou']:.2f}" + (" unsure" if row["uncertain"] else ""),
        ),
    ]
    if fit and silhouette is not None:
        result = jeanscv.fit(silhouette)
        jeans = polygon_mask(result.vertices_image, reference.shape)
        row["on_subject"] = float((jeans & reference).sum() / max(jeans.sum(), 1))
        row["covered"] = float((jeans & reference).sum() / max(reference.sum(), 1))
        row["tilt"] = float(tilt_degrees(result.vertices, result.garment))
        row["rules"] = bool(
            jeanscv.fitting.checks.rule_report(result.vertices, silhouette.canvas, result.garment).passed
        )
        tiles.append(
            _label(_tile(jeanscv.composite(pixels, result, silhouette)), f"on subject {row['on_subject']:.2f}")
        )
    elif fit:
        row.update(on_subject=0.0, covered=0.0, tilt=None, rules=False)
    return row, tiles


def _cells(row: dict) -> str:
    method = row["method"] + (" (uncertain)" if row["uncertain"] and not row["method"].startswith("error") else "")
    cells = [row["photo"], row["size"], method, f"{row['iou']:.3f}", f"{row['seconds']:.2f}"]
    if "on_subject" in row and row.get("tilt") is not None:
        cells += [f"{row['on_subject']:.2f}", f"{row['covered']:.2f}", f"{row['tilt']:.0f}"]
        cells.append("6/6" if row["rules"] else "fail")
    else:
        cells += ["-", "-", "-", "-"]
    return "| " + " | ".join(cells) + " |"


def summary(name: str, rows: list[dict]) -> str:
    """A set's one-line summary: IoU, CPU time, jeans on the subject and the unsure note."""
    ious = np.array([r["iou"] for r in rows])
    seconds = [r["seconds"] for r in rows]
    line = f"{name}: {len(rows)} photos: mean IoU {ious.mean():.3f}, median {np.median(ious):.3f}, "
    line += f"min {ious.min():.3f}; segmentation CPU s median {np.median(seconds):.2f}, max {np.max(seconds):.2f}"
    if all("on_subject" in r for r in rows):
        right = [r["on_subject"] >= ON_SUBJECT for r in rows]
        line += f"; jeans >= {ON_SUBJECT:.0%} on the subject: {sum(right)} of {len(rows)}"
        hits = sum(r["uncertain"] for r, ok in zip(rows, right) if not ok)
        alarms = sum(r["uncertain"] for r, ok in zip(rows, right) if ok)
        line += f"; unsure on {hits} of {len(rows) - sum(right)} wrong picks, on {alarms} of {sum(right)} right ones"
    return line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--set", choices=(*SETS, "both"), default="both", help="which shared folder(s)")
    parser.add_argument("--subject", default="auto", help="auto, animal, person or object")
    parser.add_argument("--detector", choices=("auto", "none"), default="auto", help="auto: the shipped detector")
    parser.add_argument("--no-fit", action="store_true", help="segmentation only")
    parser.add_argument("--only", default="", help="comma-separated photo stems")
    parser.add_argument(
        "--sheets",
        default=str(ROOT / "docs"),
        help="folder for the contact sheets, real_photos.jpg and pet_photos.jpg ('' for none)",
    )
    parser.add_argument("--json", default="", help="also write every row here (JSON)")
    args = parser.parse_args()
    sets = list(SETS) if args.set == "both" else [args.set]
    wanted = set(args.only.split(",")) if args.only else None
    everything, lines = {}, []
    for name in sets:
        paths = [p for p in photo_paths(SETS[name]) if wanted is None or p.stem in wanted]
        if not paths:
            print(f"{name}: no photos in {SETS[name]}", file=sys.stderr)
            continue
        print(f"\n{name} ({SETS[name].name})\n")
        print("| photo | size | method | IoU | seg s | jeans on subject | subject covered | tilt | rules |")
        print("| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | --- |")
        rows, tiles = [], []
        for path in paths:
            row, photo_tiles = measure_photo(path, args.subject, not args.no_fit, args.detector)
            rows.append(row)
            tiles.append(photo_tiles)
            print(_cells(row), flush=True)
        everything[name] = rows
        lines.append(summary(name, rows))
        print("\n" + lines[-1])
        if args.sheets:
            sheet = Path(args.sheets) / f"{SETS[name].name}.jpg"
            sheet.parent.mkdir(parents=True, exist_ok=True)
            image = cv2.cvtColor(contact_sheet(tiles), cv2.COLOR_RGB2BGR)
            cv2.imwrite(str(sheet), image, [cv2.IMWRITE_JPEG_QUALITY, 85])
            print(f"contact sheet: {sheet}")
    if len(lines) > 1:
        print("\n" + "\n".join(lines))
    if args.json:
        Path(args.json).write_text(json.dumps(everything, indent=1))


if __name__ == "__main__":
    main()
