"""The object in a box, without clicks: the step a click session makes for a box alone,
also taken by automatic finding for a detector's box (:mod:`.detected`) without the
session's set-up (its superpixel graph and auto's hypotheses, about 0.8 s of a 12-MP
photo, which a box alone does not use).

Arrays: images ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool``; boxes ``(x0, y0, x1,
y1)`` photo pixels (x right, y down), whole pixels end exclusive where they are ints.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .box_cut import box_cut
from .click_masks import box_mask, box_pixels
from .click_parts import PixelRefiner
from .masks import downscale, outer_contour, resize_mask, shape_for
from .photo import Segmentation

#: Points are ``(x, y)`` photo pixels.
Point = tuple[float, float]


def box_alone(
    rgb: np.ndarray, box: tuple[int, int, int, int], size: tuple[int, int], refiner: PixelRefiner
) -> np.ndarray:
    """The object inside ``box`` (whole photo pixels) at working size ``size`` ``(w, h)``:
    :func:`~.box_cut.box_cut` on the photo's own pixels (a crop of it), then onto the
    working copy, where ``refiner`` (of that copy) refines its boundary like a click's.
    ``(h, w)`` bool, False outside the box."""
    height, width = rgb.shape[:2]
    inside = box_mask(box_pixels(box, (width, height), size), (size[1], size[0]))
    mask = resize_mask(box_cut(rgb, box), size) & inside
    return refiner.refine(mask) & inside if mask.any() else mask


def at_full_size(
    working: np.ndarray,
    shape: tuple[int, int],
    positive: Sequence[Point] = (),
    negative: Sequence[Point] = (),
    box: tuple[float, float, float, float] | None = None,
    method: str = "clicks",
) -> Segmentation:
    """A working-size mask as the :class:`~.photo.Segmentation` of the ``shape`` ``(H, W)``
    photo: upsampled, cut to the box, the clicked pixels themselves set as clicked."""
    height, width = shape
    size = (working.shape[1], working.shape[0])
    full = resize_mask(working, (width, height))
    if box is not None:
        full &= box_mask(box_pixels(box, (width, height)), full.shape)
    for x, y in positive:  # the clicked pixels themselves, whatever the upsampling did
        full[int(y), int(x)] = True
    for x, y in negative:
        full[int(y), int(x)] = False
    contour = outer_contour(working, (width / size[0], height / size[1]))
    details = {
        "positive": [list(map(float, p)) for p in positive],
        "negative": [list(map(float, p)) for p in negative],
        **({"box": [float(v) for v in box]} if box is not None else {}),
        "working_shape": (size[1], size[0]),
        "area_fraction": round(float(working.mean()), 4),
    }
    return Segmentation(mask=full, method=method, contour=contour, details=details)


def segment_box(rgb: np.ndarray, box: tuple[float, float, float, float], working_size: int) -> Segmentation:
    """The object inside ``box`` of ``rgb`` as a click session with that box alone gives
    it (the same mask), without the session."""
    height, width = rgb.shape[:2]
    size = shape_for((height, width), working_size)
    small = downscale(rgb, size)
    working = box_alone(rgb, box_pixels(box, (width, height)), size, PixelRefiner(small))
    return at_full_size(working, (height, width), box=box, method="detector")
