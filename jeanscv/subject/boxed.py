"""The object in a box, without clicks: the step a click session makes for a box alone
(:func:`segment_box`), and automatic finding's cut inside a detector's box
(``segment_box(..., drop_support=True)``, for :mod:`.detected`: the same cut, then what
the animal stands or lies on dropped from the bottom of its box), both without the session's
set-up (its superpixel graph and auto's hypotheses, about 0.8 s of a 12-MP photo, which
a box alone does not use).

Arrays: images ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool``; boxes ``(x0, y0, x1,
y1)`` photo pixels (x right, y down), whole pixels end exclusive where they are ints.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from .box_cut import MARGIN, box_cut_agreed
from .click_masks import box_mask, box_pixels
from .click_parts import PixelRefiner
from .masks import downscale, outer_contour, resize_mask, shape_for
from .photo import Segmentation

#: Points are ``(x, y)`` photo pixels.
Point = tuple[float, float]

#: What a detected animal stands or lies on (:func:`without_support`) is looked for in
#: this bottom share of its box, and told from the animal by colour histograms of
#: ``_SUPPORT_BITS`` bits a channel: the animal's side learnt from the cut within the top
#: ``_BODY`` of the box (its body), the support's from the crop's margin beside and below
#: that band and the band's pixels the cut left out. A pixel of the cut in the band goes
#: where its colour (smoothed by a guided filter of ``_SUPPORT_SMOOTH`` of the crop's
#: long side) is likelier on the support's side; the cut is kept as it is where that
#: would take more than ``_MOST_DROPPED`` of it (a white cat on a white toilet: its own
#: chest) or less than ``_LEAST_DROPPED`` (a horse's white socks: no support, a detail).
#: ``python -m bench.real_photos --detector auto``, one run each: the 34 shared pet
#: photos' mean IoU 0.688 -> 0.697, jeans >= 85% on the animal 16 -> 21 of 34; the 18
#: real photos 0.700 either way, 14 of 18 (without ``_LEAST_DROPPED``: 0.699, the
#: horse's socks). Tried on a prototype (the crop's 256-pixel copy; 0.698 and 22 there):
#: a band of 0.4, 0.694 and 20-21; the whole margin as the support's side, 0.695 and 21;
#: only drops that touch the box's bottom, 0.683-0.696 and 17-19 (the ground between
#: legs is often closed off by the paws); GrabCut again from the dropped cut, 0.664-0.678.
_SUPPORT_BAND = 0.33
_BODY = 0.6
_SUPPORT_BITS = 4
_SUPPORT_SMOOTH = 0.02
_MOST_DROPPED = 0.3
_LEAST_DROPPED = 0.04


def box_alone(
    rgb: np.ndarray,
    box: tuple[int, int, int, int],
    size: tuple[int, int],
    refiner: PixelRefiner,
    support_of: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """The object inside ``box`` (whole photo pixels) at working size ``size`` ``(w, h)``:
    :func:`~.box_cut.box_cut` on the photo's own pixels (a crop of it), then onto the
    working copy, where ``refiner`` (of that copy) refines its boundary like a click's.
    ``support_of`` (a detector's box, not a person's: the working copy itself): what the
    object stands or lies on is dropped first (:func:`without_support`). ``(h, w)``
    bool, False outside the box, and how far the box cut's two starts agree
    (:func:`~.box_cut.box_cut_agreed`)."""
    height, width = rgb.shape[:2]
    working_box = box_pixels(box, (width, height), size)
    inside = box_mask(working_box, (size[1], size[0]))
    cut, agreement = box_cut_agreed(rgb, box)
    mask = resize_mask(cut, size) & inside
    if support_of is not None and mask.any():
        mask = without_support(support_of, mask, working_box)
    return (refiner.refine(mask) & inside if mask.any() else mask), agreement


def without_support(rgb: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """``mask`` (the object cut inside ``box``, ``(x0, y0, x1, y1)`` whole pixels of
    ``rgb``) without what the object stands or lies on at the bottom of its box: the
    scratching post under a cat, the railing under it, the ground between a dog's legs.

    A support continues beyond the box (it is ground, furniture, a lap) and is not the
    animal's colour: in the box's bottom band (:data:`_SUPPORT_BAND`), pixels whose colour
    is likelier in the margin round the band (and in the band's pixels the cut left out)
    than in the object's body (the cut within the top :data:`_BODY` of the box) are
    dropped; then the pieces left wholly inside the band. Unchanged where there is too
    little of either side to learn from or where more than :data:`_MOST_DROPPED` of the
    cut would go."""
    x0, y0, x1, y1 = box
    height, width = mask.shape
    if not mask.any() or y1 - y0 < 4:
        return mask
    margin = max(2, round(MARGIN * max(x1 - x0, y1 - y0)))
    cx0, cy0, cx1, cy1 = max(0, x0 - margin), max(0, y0 - margin), min(width, x1 + margin), min(height, y1 + margin)
    crop = rgb[cy0:cy1, cx0:cx1]
    cut = mask[cy0:cy1, cx0:cx1]
    bx0, by0, bx1, by1 = x0 - cx0, y0 - cy0, x1 - cx0, y1 - cy0
    inside = np.zeros(cut.shape, bool)
    inside[by0:by1, bx0:bx1] = True
    top = int(round(by1 - _SUPPORT_BAND * (by1 - by0)))
    band = np.zeros(cut.shape, bool)
    band[top:] = True
    support = band & ~(inside & cut)  # the margin beside and below the band, the band's background
    body = cut.copy()
    body[int(round(by0 + _BODY * (by1 - by0))) :] = False
    if np.count_nonzero(support) < 20 or np.count_nonzero(body) < 20:
        return mask
    bins = (crop >> (8 - _SUPPORT_BITS)).astype(np.int32)
    colour = (bins[..., 0] << (2 * _SUPPORT_BITS)) | (bins[..., 1] << _SUPPORT_BITS) | bins[..., 2]
    count = 1 << (3 * _SUPPORT_BITS)
    there = np.bincount(colour[support], minlength=count) + 0.5
    here = np.bincount(colour[body], minlength=count) + 0.5
    there /= there.sum()
    here /= here.sum()
    likely = (there / (there + here)).astype(np.float32)[colour]
    radius = max(1, round(_SUPPORT_SMOOTH * max(cut.shape)))
    likely = cv2.ximgproc.guidedFilter(np.ascontiguousarray(crop, np.float32) / 255.0, likely, radius, 0.01)
    dropped = cut & band & inside & (likely > 0.5)
    if not _LEAST_DROPPED * np.count_nonzero(cut) <= np.count_nonzero(dropped) <= _MOST_DROPPED * np.count_nonzero(cut):
        return mask
    kept = (cut & ~dropped).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(kept, connectivity=8)
    above = np.zeros(count, bool)
    above[1:] = stats[1:, cv2.CC_STAT_TOP] < top  # pieces that reach above the band
    found = mask.copy()
    found[cy0:cy1, cx0:cx1] = above[labels]
    return found


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


def segment_box(
    rgb: np.ndarray, box: tuple[float, float, float, float], working_size: int, *, drop_support: bool = False
) -> Segmentation:
    """The object inside ``box`` of ``rgb`` as a click session with that box alone gives
    it (the same mask), without the session. ``drop_support`` (a detector's box): without
    what the animal stands or lies on (:func:`without_support`), where upright jeans would
    hang. Its ``details['starts_agree']``: how far the box cut's two starts agree (the
    IoU of their cuts, :func:`~.box_cut.box_cut_agreed`)."""
    height, width = rgb.shape[:2]
    size = shape_for((height, width), working_size)
    small = downscale(rgb, size)
    support_of = small if drop_support else None
    working, agreement = box_alone(rgb, box_pixels(box, (width, height)), size, PixelRefiner(small), support_of)
    found = at_full_size(working, (height, width), box=box, method="detector")
    found.details["starts_agree"] = round(agreement, 3)
    return found
