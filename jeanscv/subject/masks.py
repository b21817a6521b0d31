"""Bool masks: cleaning, holes, components, border contact and outer contours.

Public API: :func:`clean_mask` (a user's mask, cleaned), and the helpers the
segmentation modules share (:func:`clean`, :func:`outer_contour`, ...). Masks are
``(H, W) bool`` with True on the object; contours are ``(N, 2) float64`` ``(x, y)``
image pixels (pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``).
"""

from __future__ import annotations

import cv2
import numpy as np
from skimage.measure import find_contours

from jeanscv.errors import JeansError

FULL_FRACTION = 0.98  # photo masks covering more than this are "the whole frame"
MIN_AREA_FRACTION = 0.005  # photo masks covering less than this are "nothing found"
KEEP_FRACTION = 0.25  # extra components kept if at least this fraction of the largest
MORPH_FRACTION = 0.01  # open/close radius as a fraction of sqrt(object area)
BORDER_FULL = 0.5  # a border counts as covered when this fraction of it is object
RIM_WIDTH = 0.1  # the rim: a band this fraction of the short side wide along the border
RIM_ONLY = 0.8  # a mask with more than this fraction of its pixels on the rim is not a subject


def resize(array: np.ndarray, size: tuple[int, int], interpolation: int) -> np.ndarray:
    """cv2.resize to ``size`` = (width, height); a no-op when the size already matches."""
    if array.shape[1] == size[0] and array.shape[0] == size[1]:
        return array
    return cv2.resize(array, size, interpolation=interpolation)


def resize_mask(mask: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A bool mask at ``size`` = (width, height): linearly interpolated, then halved (the
    mask itself when the size already matches)."""
    return resize(mask.astype(np.uint8) * 255, size, cv2.INTER_LINEAR) >= 128


def downscale(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """An image area-averaged down to ``size`` = (width, height), halved first by
    ``cv2.pyrDown`` while it is at least 4 times that size: OpenCV's area resampling
    is about 10 times slower at non-integer factors (a 12-MP photo to 640 px: 48 ms,
    against 22 ms this way)."""
    while image.shape[1] >= 4 * size[0] and image.shape[0] >= 4 * size[1]:
        image = cv2.pyrDown(image)
    return resize(image, size, cv2.INTER_AREA)


def shape_for(shape: tuple[int, int], long_side: int) -> tuple[int, int]:
    """(width, height) of ``shape`` = (H, W) scaled down so the long side is <= long_side."""
    height, width = shape
    scale = min(1.0, long_side / max(height, width))
    return max(1, round(width * scale)), max(1, round(height * scale))


def border_ring(shape: tuple[int, int], width: int) -> np.ndarray:
    """(H, W) bool: the frame of ``width`` pixels along the image border."""
    ring = np.zeros(shape, bool)
    ring[:width], ring[-width:], ring[:, :width], ring[:, -width:] = True, True, True, True
    return ring


def border_pixels(mask: np.ndarray) -> list[np.ndarray]:
    """The four 1-pixel borders of ``mask`` (top, bottom, left, right)."""
    return [mask[0], mask[-1], mask[:, 0], mask[:, -1]]


def border_contact(mask: np.ndarray) -> float:
    """Fraction of the image's border pixels that lie on the object."""
    return float(np.concatenate(border_pixels(mask)).mean())


def fills_frame(mask: np.ndarray) -> bool:
    """True when the mask is "the whole frame": > 98% of it, or most of all four borders."""
    if mask.mean() > FULL_FRACTION:
        return True
    return all(side.mean() > BORDER_FULL for side in border_pixels(mask))


def rim_fraction(mask: np.ndarray) -> float:
    """Fraction of the mask's pixels on the rim (a band ``RIM_WIDTH`` of the short side
    wide along the border). Subjects reach into the frame; corners and edge strips left
    around an object that fills the frame do not."""
    area = int(mask.sum())
    if area == 0:
        return 0.0
    width = max(2, round(RIM_WIDTH * min(mask.shape)))
    return float(mask[border_ring(mask.shape, width)].sum() / area)


def fill_holes(mask: np.ndarray) -> np.ndarray:
    """Fill background regions not 4-connected to the outside (objects are 8-connected)."""
    padded = np.pad(mask.astype(np.uint8), 1)
    outside = padded.copy()
    cv2.floodFill(outside, None, (0, 0), 2)  # 4-connected fill of the outer background
    return (outside != 2)[1:-1, 1:-1]


def disk(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def clean(mask: np.ndarray) -> np.ndarray:
    """Open scaled to the object, keep the main components, fill holes.

    The radius is 1% of sqrt(object area), so 0 (no morphology) for objects under
    10,000 pixels. Opening removes specks and thin spurs; a closing of the opened mask
    with the same disk only decides which pieces belong together (a leg cut off by a
    one-pixel gap stays with its body), and is not added to the result, so narrow gaps
    (between legs, tail and body) are not bridged and then filled as holes. Pieces are
    8-connected; the largest group is kept with every other one at least 25% of its
    area. Holes are background regions not 4-connected to the image border.
    """
    mask = np.asarray(mask, bool)
    area = int(np.count_nonzero(mask))
    if area == 0:
        return mask.copy()
    radius = int(MORPH_FRACTION * np.sqrt(area))
    # Work on the object's bounding box grown by 2 radii + 2 pixels: the opening stays
    # inside the box, its closing within a radius of it, and the background left
    # around both reaches the border outside, so every step gives the same pixels as
    # on the whole mask, for less work on small objects.
    x, y, w, h = cv2.boundingRect(mask.view(np.uint8))
    margin = 2 * radius + 2
    box = slice(max(y - margin, 0), y + h + margin), slice(max(x - margin, 0), x + w + margin)
    cleaned = np.zeros_like(mask)
    cleaned[box] = _clean_box(mask[box], radius)
    return cleaned


def _clean_box(mask: np.ndarray, radius: int) -> np.ndarray:
    """:func:`clean` of a bool mask with the object well inside, at a given radius."""
    opened = mask.astype(np.uint8)
    grouped = opened
    if radius > 0:
        opened = cv2.morphologyEx(opened, cv2.MORPH_OPEN, disk(radius))
        grouped = cv2.morphologyEx(opened, cv2.MORPH_CLOSE, disk(radius))
    # Plain labelling and bincount: OpenCV's labelling with statistics is 7 times slower.
    count, labels = cv2.connectedComponents(grouped, connectivity=8)
    if count <= 1:
        return np.zeros_like(mask)
    if count == 2:  # one group, all kept (the closing only adds to the opened mask)
        return fill_holes(opened.astype(bool))
    areas = np.bincount(labels.ravel(), minlength=count)[1:]
    kept = np.zeros(count, bool)
    kept[1:] = areas >= KEEP_FRACTION * areas.max()
    return fill_holes(opened.astype(bool) & np.take(kept, labels))  # take: 3x faster than kept[labels]


def largest_component(mask: np.ndarray) -> np.ndarray:
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return mask.copy()
    return labels == 1 + int(np.argmax(np.bincount(labels.ravel(), minlength=count)[1:]))


def deepest_point(mask: np.ndarray) -> tuple[int, int]:
    """The pixel ``(x, y)`` of a non-empty bool mask farthest from its boundary (the image
    border counts; OpenCV's 3x3 Euclidean distance; ties: the first in row order)."""
    depth = cv2.distanceTransform(np.pad(mask.astype(np.uint8), 1), cv2.DIST_L2, 3)[1:-1, 1:-1]
    y, x = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return int(x), int(y)


def disjoint(masks: list[np.ndarray], seeds: list[list[tuple[float, float]]]) -> list[np.ndarray]:
    """``masks`` ``(H, W) bool`` made disjoint: a pixel that several claim goes to the one
    with the nearest seed (``(x, y)`` pixels, each mask's own; ties: the earlier mask),
    and each keeps only its pieces (8-connected) that hold one of its seeds. Masks that
    claim no pixel in common come back as they are (the same arrays)."""
    claims = np.zeros(masks[0].shape, np.uint8) if masks else None
    for mask in masks:
        claims += mask
    if claims is None or not (claims > 1).any():
        return list(masks)
    ys, xs = np.nonzero(claims > 1)
    nearest = np.full(len(ys), np.inf)
    owner = np.full(len(ys), -1)
    for index, (mask, points) in enumerate(zip(masks, seeds)):
        distance = np.full(len(ys), np.inf)
        for x, y in points:  # pixel centres against the seed's own pixel's centre
            distance = np.minimum(distance, np.hypot(xs - int(x), ys - int(y)))
        distance[~mask[ys, xs]] = np.inf
        better = distance < nearest
        owner[better], nearest[better] = index, distance[better]
    result = []
    for index, (mask, points) in enumerate(zip(masks, seeds)):
        lost = owner != index
        if not lost.any() or not mask[ys, xs].any():
            result.append(mask)
            continue
        mine = mask.copy()
        mine[ys[lost], xs[lost]] = False
        _, labels = cv2.connectedComponents(mine.view(np.uint8), connectivity=8)
        held = {int(labels[int(y), int(x)]) for x, y in points} - {0}
        result.append(np.isin(labels, list(held)) & mine if held else np.zeros_like(mine))
    return result


def outer_contour(mask: np.ndarray, scale_xy: tuple[float, float]) -> np.ndarray:
    """Outer boundary of the largest component of a bool mask as (N, 2) (x, y) float64.

    It is the 0.5 iso-line of the mask between pixel centres (marching squares, with
    8-connected foreground), shifted to the package convention (centre = index + 0.5)
    and scaled by ``scale_xy`` to the output resolution.
    """
    main = largest_component(mask)
    # Traced on the component's bounding box: its squares come in the same order as on
    # the whole mask, so the same contours, moved back by the box's corner (exactly:
    # the vertices are multiples of 0.5).
    x, y, w, h = cv2.boundingRect(main.view(np.uint8))
    padded = np.pad(main[y : y + h, x : x + w].astype(np.float64), 1)
    contours = [c + (y, x) for c in find_contours(padded, 0.5, fully_connected="high")]
    if not contours:
        return np.zeros((0, 2))
    best = max(contours, key=lambda c: abs(_shoelace(c[:, ::-1])))
    xy = best[:, ::-1] - 1.0 + 0.5  # (row, col) in the padded array -> (x, y) pixels
    if len(xy) > 1 and np.allclose(xy[0], xy[-1]):
        xy = xy[:-1]
    if _shoelace(xy) < 0:
        xy = xy[::-1]
    return np.ascontiguousarray(xy * np.asarray(scale_xy))


def _shoelace(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def binarise(mask: np.ndarray) -> np.ndarray:
    """A user mask as bool: bool as is; numbers >= the midpoint of their range.

    So 0/1, 0/255 and soft [0, 1] masks all work; a constant mask is all object when it
    is non-zero.
    """
    array = np.asarray(mask)
    if array.dtype == bool:
        return array
    if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise JeansError("mask must be boolean or numeric")
    array = array.astype(np.float64)
    if not np.isfinite(array).all():
        raise JeansError("mask contains NaN or infinite values")
    low, high = float(array.min()), float(array.max())
    if low == high:
        return np.full(array.shape, high != 0)
    return array >= 0.5 * (low + high)


def clean_mask(mask: np.ndarray) -> np.ndarray:
    """Clean a (H, W) mask: morphology scaled to the object, main components, no holes.

    ``mask`` is bool, or numeric (thresholded at the midpoint of its range, so 0/1,
    0/255 and soft masks work). Opens with a disk of radius 1% of sqrt(object area)
    (none under 10,000 object pixels); groups pieces through a closing with the same
    disk; keeps the largest group and any other at least 25% of its area; fills holes
    (background not 4-connected to the border). Returns (H, W) bool at the same
    resolution (no downscaling). Raises JeansError if nothing is left.
    """
    array = np.asarray(mask)
    if array.ndim != 2 or min(array.shape) < 1:
        raise JeansError("mask must be a 2-D array")
    cleaned = clean(binarise(array))
    if not cleaned.any():
        raise JeansError("no object found to segment")
    return cleaned
