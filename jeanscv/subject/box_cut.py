"""The object inside a box a person dragged round it: GrabCut on a crop, two starts (a
third where both collapse).

Public API: :func:`box_cut` (:func:`box_cut_agreed`: with how far its two starts agree),
:func:`box_interior`, :func:`box_recut` and :func:`box_score` (used by
:class:`~jeanscv.subject.interactive.ClickSession`).

Arrays: images ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool``; boxes ``(x0, y0, x1,
y1)`` whole pixels of the array, end exclusive.

How: GrabCut (Rother et al. 2004) on a crop of the box and a margin round it, so the
background's colour model is learned from what surrounds the object rather than from the
whole photo. GrabCut settles in a local optimum that depends on where it starts: its
colour models start from Orchard and Bouman's clustering, which has no randomness (a
photo and its 12-MP copy are cut alike), and it starts twice: everything in the box
"probably the object" (GrabCut's own start), and with what the box's edge reaches
cheaply along the image's gradients "probably background" (the background spreads in
from the box's sides: boundary connectivity, Zhu et al. 2014). Of the two answers the
one kept has the best colour separation from the rest of the crop times its reach across
the box: a tight box's object crosses every row and column of it (the tight-box prior,
Lempitsky et al. 2009), which rules out a cut that collapsed to a corner or to nothing.
Where the answer kept still crosses fewer than half the box's rows or columns, the crop
is cut a third time with an ellipse round the box's centre held as the object (the same
prior: the object is there). Every piece is kept, holes stay holes: the box, not the
largest piece, says what the object is (a bicycle's wheels, a lamp's arm).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .click_parts import gradient_cost, seeded_grabcut, small_copy
from .consensus import iou
from .grabcut import cut_pool, orchard_bouman_models, run_grabcut
from .masks import downscale, resize_mask, shape_for

#: The crop is cut on a copy this long. On the shared photos (a box from each reference
#: mask, the box start alone) the mean IoU was 0.706 / 0.748 (real / pets) at 320, 0.693
#: / 0.750 at 400 and 0.685 / 0.744 at 480: more pixels do not help, and cost time.
#: Cropping the session's 480-pixel working copy instead of the photo lost 0.02 / 0.05.
#: Both starts and the choice (:func:`box_cut`): 0.728 / 0.776 at 320, 0.727 / 0.771 at
#: 288, 0.727 / 0.778 at 256, 0.718 / 0.773 at 240, 0.700 / 0.758 at 192; a median
#: 0.51 s a box at 320 and 0.33 s at 256 (GrabCut's graph cut grows faster than the
#: pixels).
CUT_SIZE = 256
#: The margin round the box, a share of its long side: background for the colour model.
MARGIN = 0.1
#: GrabCut iterations of each start. Five gave a box alone 0.743 / 0.755 (real / pets,
#: box-only script), three 0.738 / 0.756 for 30% less CPU (a box on 12 MP, idle: a median
#: 0.98 s -> 0.78 s).
ITERATIONS = 3
#: The geodesic start: box pixels the box's edge reaches for less than this share of the
#: 99th percentile of its geodesic distances start as probably background. Alone it gave
#: 0.719 / 0.733 (0.1: 0.708 / 0.730; Otsu's threshold: 0.611 / 0.593: too much of the
#: object starts as background); chosen against the box start by :func:`_score`, 0.743 /
#: 0.755 (the better of the two for every photo would give 0.76 / 0.77).
_NEAR_EDGE = 0.15
#: Colour histograms for the separation score: bits a channel.
_COLOUR_BITS = 4
#: A cut that crosses fewer than this share of the box's rows or columns contradicts the
#: box (a tight box's object crosses them all): the core start is tried. On the shared
#: photos only two cuts fall under it, the two cats on a toilet (nothing at all) and the
#: cat by a dark monitor (0.47 of the rows); all others cross 0.62 or more.
_MIN_REACH = 0.5
#: The core start: an ellipse round the box's centre, its half-axes this share of the
#: box's sides, held as the object. For the two cuts above: IoU 0.00 -> 0.59 and 0.46 ->
#: 0.65 (0.1: 0.24 and 0.55).
_CORE = 0.2


def box_cut(rgb: np.ndarray, box: tuple[int, int, int, int], size: int = CUT_SIZE) -> np.ndarray:
    """The object inside ``box`` of ``rgb``: ``(H, W)`` bool, False outside the box."""
    return box_cut_agreed(rgb, box, size)[0]


def box_cut_agreed(rgb: np.ndarray, box: tuple[int, int, int, int], size: int = CUT_SIZE) -> tuple[np.ndarray, float]:
    """:func:`box_cut`'s mask and how far its two starts agree: the IoU of their cuts (1.0
    where only one start could be made). GrabCut settles in one of two local optima, and
    which one a box gets can turn on a pixel of the box (the dog among people, pet58: box
    start 0.403 against the geodesic start's 0.392, IoU 0.78; the box a pixel smaller,
    0.394 against 0.415, IoU 0.53): where the two cuts differ, the object is not sure."""
    height, width = rgb.shape[:2]
    x0, y0, x1, y1 = box
    cx0, cy0, cx1, cy1 = _with_margin(box, (height, width))
    crop = rgb[cy0:cy1, cx0:cx1]
    ch, cw = crop.shape[:2]
    sw, sh = shape_for((ch, cw), size)
    small = np.ascontiguousarray(downscale(crop, (sw, sh)))
    sx, sy = sw / cw, sh / ch
    inner = (
        int(math.floor((x0 - cx0) * sx)),
        int(math.floor((y0 - cy0) * sy)),
        max(int(math.ceil((x1 - cx0) * sx)), 1),
        max(int(math.ceil((y1 - cy0) * sy)), 1),
    )
    inside = np.zeros((sh, sw), bool)
    inside[inner[1] : inner[3], inner[0] : inner[2]] = True
    labels = np.where(inside, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
    if inside.all():
        # A box round the whole photo leaves no background to learn from: its outer ring
        # is probably background (GrabCut cannot start without any).
        ring = max(1, round(0.02 * min(sh, sw)))
        labels[:ring], labels[-ring:], labels[:, :ring], labels[:, -ring:] = (cv2.GC_PR_BGD,) * 4
    # The two starts are cut side by side where OpenCV may use two threads or more, the
    # box's own start already cutting while the geodesic one is made.
    with cut_pool() as pool:
        jobs = {"box": pool.submit(_cut, small, labels)}
        geodesic = _geodesic_start(small, labels, inner)
        if geodesic is not None:
            jobs["geodesic"] = pool.submit(_cut, small, geodesic)
        cuts = {name: job.result() & inside for name, job in jobs.items()}
    chosen = max(cuts, key=lambda name: (_score(small, cuts[name], inner), name == "box"))
    agreement = iou(cuts["box"], cuts["geodesic"]) if len(cuts) == 2 else 1.0
    reach = _reach(cuts[chosen], inner)
    if reach < _MIN_REACH:
        # Both starts collapsed (two black-and-white cats in a box of the same colours as
        # its margin gave nothing at all): a tight box's centre is the object, so cut
        # again with it held as the object. That answer is kept where it spans more of
        # the box and GrabCut took at least as much again as the core it was given (in a
        # box of plain noise it adds a few pixels: nothing is there).
        start = _core_start(labels, inner)
        core = _cut(small, start) & inside
        given = np.count_nonzero(start == cv2.GC_FGD)
        if _reach(core, inner) > reach and np.count_nonzero(core) >= 2 * given:
            cuts[chosen] = core
    # Only the box of the crop: the resized cut may spill over its edge into the margin.
    found = np.zeros((height, width), bool)
    found[y0:y1, x0:x1] = resize_mask(cuts[chosen], (cw, ch))[y0 - cy0 : y1 - cy0, x0 - cx0 : x1 - cx0]
    return found, agreement


def box_recut(
    rgb: np.ndarray,
    box: tuple[int, int, int, int],
    previous: np.ndarray,
    positive: list[tuple[int, int]],
    negative: list[tuple[int, int]],
    radius: int,
    size: int = CUT_SIZE,
) -> np.ndarray:
    """``previous`` (the object in ``box`` of ``rgb``, ``(H, W)`` bool) corrected by clicks
    (whole pixels ``(x, y)`` of ``rgb``): GrabCut on the box and its margin (on a copy no
    longer than ``size``), started from ``previous`` as "probably" each side, with a
    hard disc of ``radius`` at every click; nothing outside the box.

    A click's geodesic correction can take a large region where the object and what
    surrounds it share colours (a negative click beside a cat on a lap took the cat);
    GrabCut re-fits its colour models on the crop and moves the boundary only where the
    colours say so: on the shared pet photos it never lowered the IoU by more than 0.05
    where the geodesic correction did 19 times in 102 clicks, but it gains less per
    click. At 320 pixels rather than the session's 480, after a box and 10 clicks the
    mean IoU was within 0.006 (real / pets: 0.780 / 0.819 / 0.840 and 0.779 / 0.807 /
    0.838 after 1 / 3 / 5 clicks, against 0.781 / 0.820 / 0.834 and 0.778 / 0.812 /
    0.837) and a negative click on 12 MP took a median 0.23 s instead of 0.27 s. It is
    cut at :data:`CUT_SIZE`, as the box's own cut."""
    x0, y0, x1, y1 = box
    cx0, cy0, cx1, cy1 = _with_margin(box, rgb.shape[:2])
    crop = np.ascontiguousarray(rgb[cy0:cy1, cx0:cx1])
    ch, cw = crop.shape[:2]
    inside = np.zeros((ch, cw), bool)
    inside[y0 - cy0 : y1 - cy0, x0 - cx0 : x1 - cx0] = True
    before = previous[cy0:cy1, cx0:cx1]
    labels = np.where(inside, np.where(before, cv2.GC_PR_FGD, cv2.GC_PR_BGD), cv2.GC_BGD).astype(np.uint8)
    small, onto = small_copy(crop, size)
    scale = min(1.0, size / max(ch, cw))
    if scale < 1.0:
        labels = cv2.resize(labels, small.shape[1::-1], interpolation=cv2.INTER_NEAREST)
        radius = max(1, round(radius * scale))
    pos = onto([(x - cx0, y - cy0) for x, y in positive])
    neg = onto([(x - cx0, y - cy0) for x, y in negative])
    found = np.zeros_like(previous)
    found[cy0:cy1, cx0:cx1] = resize_mask(seeded_grabcut(small, labels, pos, neg, radius), (cw, ch)) & inside
    return found


def box_interior(rgb: np.ndarray, box: tuple[int, int, int, int], size: int = CUT_SIZE) -> np.ndarray:
    """What the edge of ``box`` does not reach cheaply: the part of the box that
    :func:`box_cut`'s geodesic start leaves probably the object, on a copy of the box
    no longer than ``size``, without a GrabCut (a fifth of a small one's time). ``(H,
    W)`` bool, False outside the box, and everywhere when the edge reaches all or none of it."""
    x0, y0, x1, y1 = box
    crop = rgb[y0:y1, x0:x1]
    ch, cw = crop.shape[:2]
    small, _ = small_copy(crop, size)
    sh, sw = small.shape[:2]
    start = _geodesic_start(small, np.full((sh, sw), cv2.GC_PR_FGD, np.uint8), (0, 0, sw, sh))
    found = np.zeros(rgb.shape[:2], bool)
    if start is not None:
        found[y0:y1, x0:x1] = resize_mask(start == cv2.GC_PR_FGD, (cw, ch))
    return found


def box_score(rgb: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int]) -> float:
    """How good ``mask`` (``(H, W)`` bool) looks as the object in ``box`` of ``rgb``,
    without knowing the answer: :func:`_score` on the box's crop (the box and its
    margin), the score that chooses between :func:`box_cut`'s two starts."""
    x0, y0, x1, y1 = box
    cx0, cy0, cx1, cy1 = _with_margin(box, rgb.shape[:2])
    inner = (x0 - cx0, y0 - cy0, x1 - cx0, y1 - cy0)
    return _score(rgb[cy0:cy1, cx0:cx1], mask[cy0:cy1, cx0:cx1], inner)


def _with_margin(box: tuple[int, int, int, int], shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """``box`` grown by :data:`MARGIN` of its long side (at least 2 pixels) each way,
    within an image of ``shape`` ``(H, W)``: the crop GrabCut learns the background on."""
    x0, y0, x1, y1 = box
    margin = max(2, round(MARGIN * max(x1 - x0, y1 - y0)))
    return max(0, x0 - margin), max(0, y0 - margin), min(shape[1], x1 + margin), min(shape[0], y1 + margin)


def _cut(small: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """GrabCut from ``labels``, its colour models started by Orchard and Bouman's
    clustering (no randomness: the same box on a photo and on a resampled copy of it is
    cut the same way); nothing where it cannot start."""
    try:
        return run_grabcut(small, labels, ITERATIONS, start=orchard_bouman_models(small, labels))
    except JeansError:
        return np.zeros(labels.shape, bool)


def _geodesic_start(small: np.ndarray, labels: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray | None:
    """``labels`` with the pixels of ``box`` (``(x0, y0, x1, y1)`` of the copy) that its
    edge reaches cheaply (geodesic distance along the Lab gradient under ``_NEAR_EDGE``
    of its 99th percentile) made probably background; None when that leaves either side
    empty.

    The distances run from the box's inner ring within the box alone: a path from the
    ring out of the box and back crosses the ring again, where it could as well have
    started, so they are the distances from the ring on both sides of the edge over the
    whole crop: the same labels, on the 104 crops of the shared photos (each reference
    mask's box, and the whole frame) a mean 0.051 s against 0.065 s."""
    from skimage.graph import MCP_Geometric  # only when a box is drawn

    x0, y0, x1, y1 = box
    cost = gradient_cost(small)[y0:y1, x0:x1]  # the gradient as over the whole crop
    h, w = cost.shape
    ring = np.ones((h, w), bool)
    ring[1:-1, 1:-1] = False
    distance = MCP_Geometric(cost).find_costs([tuple(p) for p in np.argwhere(ring)])[0]
    near = distance < _NEAR_EDGE * np.percentile(distance, 99)
    if not near.any() or near.all():
        return None
    start = labels.copy()
    start[y0:y1, x0:x1][near] = cv2.GC_PR_BGD
    return start


def _core_start(labels: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    """``labels`` with an ellipse round the centre of ``box`` (``(x0, y0, x1, y1)`` of
    the copy; half-axes :data:`_CORE` of its sides) held as the object."""
    x0, y0, x1, y1 = box
    core = np.zeros(labels.shape, np.uint8)
    centre = ((x0 + x1) // 2, (y0 + y1) // 2)
    axes = (max(1, round(_CORE * (x1 - x0))), max(1, round(_CORE * (y1 - y0))))
    cv2.ellipse(core, centre, axes, 0, 0, 360, 1, -1)
    start = labels.copy()
    start[core.astype(bool)] = cv2.GC_FGD
    return start


def _reach(mask: np.ndarray, box: tuple[int, int, int, int]) -> float:
    """The share of ``box``'s rows or columns, the fewer, that ``mask`` crosses."""
    x0, y0, x1, y1 = box
    within = mask[y0:y1, x0:x1]
    return float(min(within.any(axis=1).mean(), within.any(axis=0).mean()))


def _score(small: np.ndarray, mask: np.ndarray, box: tuple[int, int, int, int]) -> float:
    """How good a cut looks without knowing the answer: the colour separation of the
    mask from the rest of the crop (1 minus the Bhattacharyya coefficient of their
    colour histograms) times the share of the box's rows or columns, the fewer, that it
    crosses (a tight box's object crosses them all)."""
    if not mask.any() or mask.all():
        return 0.0
    reach = _reach(mask, box)
    shift = 8 - _COLOUR_BITS
    bins = (small >> shift).astype(np.int32)
    colour = (bins[..., 0] << (2 * _COLOUR_BITS)) | (bins[..., 1] << _COLOUR_BITS) | bins[..., 2]
    count = 1 << (3 * _COLOUR_BITS)
    inner = np.bincount(colour[mask], minlength=count) / np.count_nonzero(mask)
    outer = np.bincount(colour[~mask], minlength=count) / np.count_nonzero(~mask)
    return float((1.0 - np.sqrt(inner * outer).sum()) * reach)


__all__ = ["box_cut", "box_cut_agreed", "box_interior", "box_recut", "box_score", "CUT_SIZE"]
