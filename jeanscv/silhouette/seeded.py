"""Segment the object under a point, like a click: GrabCut seeded around the point.

Public API: :func:`segment_at_point` (photo, point -> :class:`Segmentation`) and
:func:`point_labels` (its GrabCut seeds, for other seeded segmentations to reuse).

Arrays: images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; masks ``(H, W)
bool``; points ``(x, y)`` image pixels (pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``).

The seeds: a small disc at the point is certainly the object, a larger disc around it
probably is, the border ring is certainly background (an object may leave the frame
where the point is near the border: the certain disc wins there), and everything else
is probably background. Both discs scale with the image, so the result does not depend
on its resolution. GrabCut runs on a copy with long side <= ``working_size``; the
component under the point is kept, its holes filled, and it is upsampled like
:func:`jeanscv.silhouette.photo.segment` does.
"""

from __future__ import annotations

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .masks import border_ring, disk, fill_holes, outer_contour, resize, shape_for
from .photo import Segmentation, _run_grabcut, _validate_image

#: Radius of the "probably the object" disc, as a fraction of the image's short side.
PROBABLE_RADIUS = 0.4
#: Radius of the "certainly the object" disc, as a fraction of the image's short side.
CERTAIN_RADIUS = 0.02
#: Width of the "certainly background" border ring, as a fraction of the short side.
RING_WIDTH = 0.02
_ITERATIONS = 5


def point_labels(shape: tuple[int, int], point: tuple[float, float]) -> np.ndarray:
    """GrabCut labels ``(h, w) uint8`` seeded around ``point`` (x, y pixels of ``shape``)."""
    height, width = shape
    short = min(height, width)
    centre = (int(point[0]), int(point[1]))
    labels = np.full((height, width), cv2.GC_PR_BGD, np.uint8)
    labels[border_ring((height, width), max(1, round(RING_WIDTH * short)))] = cv2.GC_BGD
    probable = np.zeros((height, width), np.uint8)
    cv2.circle(probable, centre, max(2, round(PROBABLE_RADIUS * short)), 1, -1)
    labels[(probable > 0) & (labels != cv2.GC_BGD)] = cv2.GC_PR_FGD
    cv2.circle(labels, centre, max(1, round(CERTAIN_RADIUS * short)), int(cv2.GC_FGD), -1)
    return labels


def _component_at(mask: np.ndarray, x: int, y: int) -> np.ndarray:
    """The 8-connected component of ``mask`` holding pixel (x, y), holes filled."""
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    label = labels[y, x]
    if count <= 1 or label == 0:
        return np.zeros_like(mask)
    return fill_holes(labels == label)


def segment_at_point(image: np.ndarray, point: tuple[float, float], *, working_size: int = 480) -> Segmentation:
    """Segment the object under ``point`` = ``(x, y)`` image pixels of ``image``.

    Returns a :class:`Segmentation` (method ``"point"``) at the image's resolution.
    Raises JeansError when the point is outside the image or nothing separates from the
    background there (empty, or the whole frame).
    """
    from .objects import check_point

    rgb, _ = _validate_image(image)
    height, width = rgb.shape[:2]
    x, y = check_point(point, (height, width))
    size = shape_for((height, width), working_size)
    small = resize(rgb, size, cv2.INTER_AREA)
    sx, sy = size[0] / width, size[1] / height
    px, py = min(int(x * sx), size[0] - 1), min(int(y * sy), size[1] - 1)
    labels = point_labels(small.shape[:2], (px, py))
    grabbed = _run_grabcut(small, labels, _ITERATIONS)
    # Specks along the object's edge go first, so they do not join it to the background.
    radius = max(1, round(0.005 * max(size)))
    opened = cv2.morphologyEx(grabbed.astype(np.uint8), cv2.MORPH_OPEN, disk(radius)).astype(bool)
    opened[py, px] = True  # the certain disc stays, even if thinner than the opening
    working = _component_at(opened | (labels == cv2.GC_FGD), px, py)
    fraction = float(working.mean())
    if fraction < 0.001:
        raise JeansError(f"no object found at point ({x:g}, {y:g})")
    if fraction > 0.98:
        raise JeansError(f"the object at point ({x:g}, {y:g}) fills the whole frame")
    full = resize(working.astype(np.uint8) * 255, (width, height), cv2.INTER_LINEAR) >= 128
    contour = outer_contour(working, (width / size[0], height / size[1]))
    details = {"point": [x, y], "working_shape": (size[1], size[0]), "area_fraction": round(fraction, 4)}
    return Segmentation(mask=full, method="point", contour=contour, details=details)


__all__ = ["CERTAIN_RADIUS", "PROBABLE_RADIUS", "RING_WIDTH", "point_labels", "segment_at_point"]
