"""Several objects in one photo: split a subject mask into its objects, pick one by a point.

Public API: :func:`split_objects` (mask -> :class:`PhotoObject` list, largest first) and
:func:`object_at` (which of them a point picks).

Arrays: masks are ``(H, W) bool`` with True on the object; boxes are ``(x, y, w, h)``
image pixels; points and contours are ``(x, y)`` image pixels, package convention
(pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``, so a point picks pixel
``(floor(x), floor(y))``).

Splitting groups pieces the way the segmentation's cleaning does (a closing with a disk
of 1% of sqrt(object area) decides which pieces belong together: a leg cut off by a
thin gap stays with its body), on a copy whose long side is at most ``working_size``,
so a 24-MP mask costs no full-resolution labelling; each object's pixels are then taken
from the full-resolution mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from jeanscv.errors import JeansError, OptionError
from jeanscv.geometry import mask_box

from .masks import MORPH_FRACTION, disk, outer_contour, resize, shape_for

#: Objects smaller than this fraction of the largest are specks, not objects.
MIN_FRACTION = 0.1
#: A point this far from every object (fraction of the image's long side) picks none.
POINT_TOLERANCE = 0.02


@dataclass
class PhotoObject:
    """One object of a subject mask.

    mask: ``(H, W)`` bool, True on this object only.
    box: ``(x, y, w, h)`` its bounding box, image pixels.
    area: its pixel count.
    contour: ``(K, 2)`` float64 ``(x, y)`` image pixels, its outer boundary (traced on
        the reduced copy, so accurate to about one working pixel).
    """

    mask: np.ndarray
    box: tuple[int, int, int, int]
    area: int
    contour: np.ndarray


def split_objects(mask: np.ndarray, min_fraction: float = MIN_FRACTION, working_size: int = 640) -> list[PhotoObject]:
    """Split a subject mask into its separate objects, largest first.

    Pieces are grouped on a copy with long side <= ``working_size`` (any coverage
    counts, so thin parts are not lost), through a closing with a disk of 1% of
    sqrt(object area) as in the segmentation's cleaning; groups under ``min_fraction``
    of the largest are dropped as specks.

    Args:
        mask: ``(H, W)`` bool (or numeric, >= 0.5 is object).

    Returns:
        One :class:`PhotoObject` per object, at the mask's resolution, by area, largest
        first. Raises JeansError when the mask is empty.
    """
    full = np.asarray(mask)
    if full.ndim != 2:
        raise JeansError(f"mask must be 2-D, got shape {full.shape}")
    full = full if full.dtype == bool else full >= 0.5
    height, width = full.shape
    size = shape_for((height, width), working_size)
    coverage = resize(full.astype(np.uint8) * np.uint8(255), size, cv2.INTER_AREA)
    small = coverage > 0
    area = float(coverage.sum()) / 255.0
    if area <= 0:
        raise JeansError("silhouette is empty")
    radius = int(MORPH_FRACTION * np.sqrt(area))
    grouped = small.astype(np.uint8)
    if radius > 0:
        grouped = cv2.morphologyEx(grouped, cv2.MORPH_CLOSE, disk(radius))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(grouped, connectivity=8)
    # Object areas in full-resolution pixels are estimated from the coverage, which
    # the closing does not inflate.
    areas = np.bincount(labels.ravel(), weights=coverage.ravel().astype(np.float64), minlength=count)[1:] / 255.0
    areas *= (height * width) / float(size[0] * size[1])
    keep = [k for k in np.argsort(-areas) + 1 if areas[k - 1] >= min_fraction * areas.max()]
    scale_x, scale_y = width / size[0], height / size[1]
    objects = []
    for k in keep:
        x, y, w, h = (int(v) for v in stats[k, :4])
        # Full-resolution crop of the group's box plus one working pixel each side.
        x0, y0 = int(np.floor(max(x - 1, 0) * scale_x)), int(np.floor(max(y - 1, 0) * scale_y))
        x1 = min(int(np.ceil(min(x + w + 1, size[0]) * scale_x)), width)
        y1 = min(int(np.ceil(min(y + h + 1, size[1]) * scale_y)), height)
        group = cv2.dilate((labels == k).astype(np.uint8), disk(1))
        lx0, ly0 = max(x - 1, 0), max(y - 1, 0)
        region = group[ly0 : min(y + h + 1, size[1]), lx0 : min(x + w + 1, size[0])]
        # Nearest-neighbour upsampling of the dilated group: every full-resolution
        # object pixel lies in a working pixel of its group or next to one.
        region = cv2.resize(region, (x1 - x0, y1 - y0), interpolation=cv2.INTER_NEAREST).astype(bool)
        own = np.zeros((height, width), bool)
        own[y0:y1, x0:x1] = full[y0:y1, x0:x1] & region
        pixels = int(own[y0:y1, x0:x1].sum())
        if pixels == 0:
            continue
        outline = (coverage >= 128) & (labels == k)
        contour = outer_contour(outline if outline.any() else labels == k, (scale_x, scale_y))
        bx, by, bw, bh = mask_box(own[y0:y1, x0:x1])
        objects.append(PhotoObject(own, (bx + x0, by + y0, bw, bh), pixels, contour))
    if not objects:
        raise JeansError("silhouette is empty")
    return objects


def check_point(point, shape: tuple[int, int]) -> tuple[float, float]:
    """A point ``(x, y)`` as floats, or JeansError when it is not inside an ``(H, W)`` image."""
    try:
        x, y = (float(v) for v in point)
    except (TypeError, ValueError):
        raise JeansError(f"a point must be two numbers (x, y), got {point!r}") from None
    height, width = shape
    if not (0 <= x < width and 0 <= y < height):  # also rejects NaN
        raise OptionError(f"point ({x:g}, {y:g}) is outside the {width}x{height} image")
    return x, y


def _distance_to(obj: PhotoObject, x: float, y: float) -> float:
    """Distance (image pixels) from a point to the object: 0 on it, else to its outline."""
    if obj.mask[int(y), int(x)]:
        return 0.0
    if len(obj.contour) == 0:
        return float("inf")
    return float(np.min(np.hypot(obj.contour[:, 0] - x, obj.contour[:, 1] - y)))


def object_at(objects: list[PhotoObject], point, tolerance: float = POINT_TOLERANCE) -> int | None:
    """Index of the object a click at ``point`` = ``(x, y)`` picks, or None.

    The object under the point; else the nearest one within ``tolerance`` x the
    image's long side (a click just off a thin leg); else None.
    """
    if not objects:
        return None
    shape = objects[0].mask.shape
    x, y = check_point(point, shape)
    distances = [_distance_to(obj, x, y) for obj in objects]
    best = int(np.argmin(distances))
    return best if distances[best] <= tolerance * max(shape) else None


__all__ = ["MIN_FRACTION", "POINT_TOLERANCE", "PhotoObject", "check_point", "object_at", "split_objects"]
