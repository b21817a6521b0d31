"""Interactive segmentation: positive and negative clicks that fix the subject's mask.

Public API: :class:`ClickSession` (set a photo once, then each call with the current
clicks of one object returns its mask quickly) and :func:`segment_with_clicks` (the same,
stateless).

Arrays: images ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; masks ``(H, W) bool``;
clicks ``(x, y)`` image pixels, package convention (pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``).
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .masks import MORPH_FRACTION, disk, downscale, fill_holes, outer_contour, resize, shape_for
from .photo import Segmentation, _run_grabcut, _validate_image

#: Long side (pixels) of the copy the clicks are segmented on.
WORKING_SIZE = 480
#: Long side of the copy auto's hypotheses are made from (as :func:`photo.segment`).
SCENE_SIZE = 640
_ITERATIONS = 3
#: Radius of a click's hard seed, as a fraction of the working copy's short side.
_SEED_FRACTION = 0.012
#: A corrective click flips a region at most this many times its distance to the boundary.
_REACH = 2.0
#: Weight of the click's relative depth against agreement when the first click chooses.
_DEPTH_WEIGHT = 0.5
#: A corrective click re-decides a window this many times its radius (half-width).
_WINDOW = 3.0
#: Colour steps (Lab units between neighbours) the flood fill tries, in order.
_FLOOD_STEPS = (1, 2, 3, 4, 6, 8, 11, 16)
#: A flood that grows this many times at once has leaked through an edge.
_LEAK = 4.0

Point = tuple[float, float]


class ClickSession:
    """One photo, segmented again after each click (in the spirit of Segment Anything's
    predictor): the constructor does the work that does not depend on the clicks
    (downscaling, auto's hypotheses); :meth:`segment` takes one object's clicks.

    Results are remembered by click sequence, so adding a click to a sequence already
    segmented costs one step; the same clicks always give the same mask.
    """

    def __init__(self, image: np.ndarray, *, working_size: int = WORKING_SIZE):
        from .photo import hypotheses
        from .scene import Scene

        rgb, _ = _validate_image(image)
        self.shape = rgb.shape[:2]
        height, width = self.shape
        self.size = shape_for(self.shape, working_size)  # (w, h) of the working copy
        self.rgb = downscale(rgb, self.size)
        scene_rgb = downscale(rgb, shape_for(self.shape, SCENE_SIZE))
        self._scene = Scene(scene_rgb)
        self._details: dict = {}
        try:
            found = hypotheses(scene_rgb, self._scene, self._details)
            self._hypotheses = {
                name: resize(mask.astype(np.uint8) * 255, self.size, cv2.INTER_LINEAR) >= 128
                for name, mask in found.coarse.items()
            }
        except JeansError:
            self._hypotheses = {}
        self._cache: dict[tuple, np.ndarray] = {}
        self._seed_radius = max(1, round(_SEED_FRACTION * min(self.size)))
        self._smooth_lab = cv2.cvtColor(cv2.GaussianBlur(self.rgb, (0, 0), 1.0), cv2.COLOR_RGB2LAB)

    # ------------------------------------------------------------------ coordinates
    def _to_working(self, point: Point) -> tuple[int, int]:
        height, width = self.shape
        x, y = float(point[0]), float(point[1])
        if not (0 <= x < width and 0 <= y < height):
            raise JeansError(f"click ({x:g}, {y:g}) is outside the {width}x{height} image")
        w, h = self.size
        return min(int(x * w / width), w - 1), min(int(y * h / height), h - 1)

    # ------------------------------------------------------------------ public
    def segment(self, positive: Sequence[Point], negative: Sequence[Point] = ()) -> Segmentation:
        """The mask of the object these clicks describe, at the photo's resolution.

        Clicks are applied in order: positive ones first as given, then negative ones;
        the mask holds every positive click and none of the negative ones.
        """
        if not positive:
            raise JeansError("an object needs at least one positive click")
        pos = [self._to_working(p) for p in positive]
        neg = [self._to_working(p) for p in negative]
        if set(pos) & set(neg):
            raise JeansError("a negative click is on top of a positive one")
        working = self._working_mask(pos, neg)
        height, width = self.shape
        full = resize(working.astype(np.uint8) * 255, (width, height), cv2.INTER_LINEAR) >= 128
        for x, y in positive:  # the clicked pixels themselves, whatever the upsampling did
            full[int(y), int(x)] = True
        for x, y in negative:
            full[int(y), int(x)] = False
        contour = outer_contour(working, (width / self.size[0], height / self.size[1]))
        details = {
            "positive": [list(map(float, p)) for p in positive],
            "negative": [list(map(float, p)) for p in negative],
            "working_shape": (self.size[1], self.size[0]),
            "area_fraction": round(float(working.mean()), 4),
        }
        return Segmentation(mask=full, method="clicks", contour=contour, details=details)

    def working_mask(self, positive: Sequence[Point], negative: Sequence[Point] = ()) -> np.ndarray:
        """The mask at working resolution (``(h, w)`` bool), for previews."""
        pos = [self._to_working(p) for p in positive]
        neg = [self._to_working(p) for p in negative]
        return self._working_mask(pos, neg).copy()

    # ------------------------------------------------------------------ steps
    def _working_mask(self, pos: list, neg: list) -> np.ndarray:
        clicks = tuple(("+", p) for p in pos) + tuple(("-", p) for p in neg)
        return self._after(clicks)

    def _after(self, clicks: tuple) -> np.ndarray:
        if clicks in self._cache:
            return self._cache[clicks]
        if len(clicks) == 1:
            mask = self._first(clicks[0][1])
        else:
            mask = self._step(self._after(clicks[:-1]), clicks)
        self._cache[clicks] = mask
        return mask

    def _first(self, point: tuple[int, int]) -> np.ndarray:
        """The mask after one positive click: of auto's hypotheses that hold the click
        (the piece under it: a person clicks each thing that should wear the jeans) and
        a GrabCut seeded at the click, the one the others agree with most."""
        x, y = point
        candidates = {name: _constrained(m, [point], []) for name, m in self._hypotheses.items() if m[y, x]}
        seeded = self._cut(np.full(self.rgb.shape[:2], cv2.GC_PR_BGD, np.uint8), [point], [])
        candidates["click"] = seeded
        if len(candidates) == 1:
            return seeded
        names = list(candidates)
        # Agreement with the others, and how deep inside the click lies (a person clicks
        # the middle of the thing): a mask the click only grazes is likely the wrong one.
        scores = {
            a: np.mean([_iou(candidates[a], candidates[b]) for b in names if b != a])
            + _DEPTH_WEIGHT * _relative_depth(candidates[a], x, y)
            for a in names
        }
        best = candidates[max(names, key=lambda n: (scores[n], n == "click"))]
        return _constrained(best, [point], [])

    def _step(self, previous: np.ndarray, clicks: tuple) -> np.ndarray:
        """The mask after one more click, from the mask before it.

        The click says that the region around it is on the wrong side. Its radius ``r``
        is the click's distance to the current mask's boundary; the region is
        flood-filled from the click on the wrong side (:meth:`_flood`) and handed to the
        other side as hard seeds. GrabCut decides again inside a window of ``_WINDOW r``
        around the click, with colour models learned there; the window's rim and
        everything outside it keep the current mask, so an edit stays where it was asked.
        """
        sign, (x, y) = clicks[-1]
        wrong = previous if sign == "-" else ~previous
        pos = [p for s, p in clicks if s == "+"]
        neg = [p for s, p in clicks if s == "-"]
        radius = _depth(wrong, x, y)
        region = np.zeros(wrong.shape, np.uint8)
        cv2.circle(region, (x, y), int(round(radius)), 1, -1)
        region = region.astype(bool) & wrong
        height, width = previous.shape
        reach = int(np.ceil(_WINDOW * radius)) + 2
        x0, x1 = max(0, x - reach), min(width, x + reach + 1)
        y0, y1 = max(0, y - reach), min(height, y + reach + 1)
        crop = previous[y0:y1, x0:x1]
        labels = np.where(crop, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        rim = np.zeros(labels.shape, bool)
        rim[0, :] |= y0 > 0
        rim[-1, :] |= y1 < height
        rim[:, 0] |= x0 > 0
        rim[:, -1] |= x1 < width
        labels[rim] = np.where(crop[rim], cv2.GC_FGD, cv2.GC_BGD)
        labels[region[y0:y1, x0:x1]] = cv2.GC_PR_FGD if sign == "+" else cv2.GC_PR_BGD
        inside = [(s, (px - x0, py - y0)) for s, (px, py) in clicks if x0 <= px < x1 and y0 <= py < y1]
        local_pos = [p for s, p in inside if s == "+"]
        local_neg = [p for s, p in inside if s == "-"]
        cut = _seeded_grabcut(self.rgb[y0:y1, x0:x1], labels, local_pos, local_neg, self._seed_radius)
        mask = previous.copy()
        mask[y0:y1, x0:x1] = cut
        return _constrained(mask, pos, neg)

    def _flood(self, wrong: np.ndarray, point: tuple[int, int], radius: float, others: list) -> np.ndarray:
        """The region around ``point`` on the ``wrong`` side that the click flips: a
        flood fill in Lab (neighbour to neighbour) with the largest colour step whose
        region stays within ``_REACH * radius`` of the click, away from clicks of the
        other sign, and does not jump in area (a jump means it got through an edge)."""
        x, y = point
        height, width = wrong.shape
        allowed = np.zeros((height, width), np.uint8)
        cv2.circle(allowed, (x, y), int(round(_REACH * radius)), 1, -1)
        allowed &= wrong.astype(np.uint8)
        for ox, oy in others:
            cv2.circle(allowed, (ox, oy), self._seed_radius, 0, -1)
        best = np.zeros((height, width), bool)
        cv2.circle(best.view(np.uint8), (x, y), self._seed_radius, 1, -1)
        best &= wrong
        for step in _FLOOD_STEPS:
            fill_mask = np.pad(1 - allowed, 1)
            flags = 4 | cv2.FLOODFILL_MASK_ONLY | (2 << 8)
            cv2.floodFill(self._smooth_lab, fill_mask, (x, y), 0, (step,) * 3, (step,) * 3, flags)
            region = fill_mask[1:-1, 1:-1] == 2
            if region.sum() > _LEAK * max(best.sum(), np.pi * (radius / 2) ** 2):
                break
            best |= region
        return best

    def _cut(self, labels: np.ndarray, pos: list, neg: list) -> np.ndarray:
        """GrabCut of the whole working copy from ``labels`` with the clicks as hard seeds,
        constrained (:func:`_constrained`)."""
        return _constrained(_seeded_grabcut(self.rgb, labels, pos, neg, self._seed_radius), pos, neg)


def _seeded_grabcut(rgb: np.ndarray, labels: np.ndarray, pos: list, neg: list, radius: int) -> np.ndarray:
    """GrabCut from ``labels`` with discs of ``radius`` at the clicks as hard seeds (a disc
    stops short of halfway to the nearest click of the other sign)."""
    labels = labels.copy()
    for sign, points, others in ((cv2.GC_FGD, pos, neg), (cv2.GC_BGD, neg, pos)):
        for x, y in points:
            r = radius
            if others:
                gap = min(np.hypot(x - ox, y - oy) for ox, oy in others)
                r = max(0, min(r, int(gap / 2) - 1))
            cv2.circle(labels, (x, y), r, int(sign), -1)
            labels[y, x] = sign
    has_fg = ((labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)).any()
    has_bg = ((labels == cv2.GC_BGD) | (labels == cv2.GC_PR_BGD)).any()
    if not (has_fg and has_bg) or min(labels.shape) < 4:
        return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
    try:
        return _run_grabcut(rgb, labels, _ITERATIONS)
    except JeansError:
        return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


def _constrained(mask: np.ndarray, pos: list, neg: list) -> np.ndarray:
    """``mask`` made to obey the clicks: the pieces that hold a positive click (pieces
    that a closing of 1% of the object's size joins count as one, as in
    :func:`~jeanscv.silhouette.objects.split_objects`: a leg cut off by a thin gap stays),
    holes filled unless a negative click is in one; every positive click in, every
    negative click out."""
    eight = mask.astype(np.uint8)
    radius = int(MORPH_FRACTION * np.sqrt(max(int(eight.sum()), 1)))
    grouped = cv2.morphologyEx(eight, cv2.MORPH_CLOSE, disk(radius)) if radius > 0 else eight
    grouped |= eight
    _, components = cv2.connectedComponents(grouped, connectivity=8)
    keep = {int(components[y, x]) for x, y in pos} - {0}
    kept = (np.isin(components, list(keep)) & mask) if keep else np.zeros_like(mask, dtype=bool)
    filled = fill_holes(kept)
    holes = filled & ~kept
    if holes.any() and neg:
        _, hole_labels = cv2.connectedComponents(holes.astype(np.uint8), connectivity=4)
        drop = {int(hole_labels[y, x]) for x, y in neg} - {0}
        filled &= ~np.isin(hole_labels, list(drop))
    for x, y in pos:
        filled[y, x] = True
    for x, y in neg:
        filled[y, x] = False
    return filled


def _depth(region: np.ndarray, x: int, y: int) -> float:
    """Distance (pixels, at least 2) from (x, y) to the boundary of ``region``."""
    distance = cv2.distanceTransform(np.pad(region, 1).astype(np.uint8), cv2.DIST_L2, 5)
    return max(2.0, float(distance[y + 1, x + 1]))


def _relative_depth(mask: np.ndarray, x: int, y: int) -> float:
    """The click's distance to the mask's boundary over the mask's deepest distance."""
    distance = cv2.distanceTransform(np.pad(mask, 1).astype(np.uint8), cv2.DIST_L2, 5)
    return float(distance[y + 1, x + 1]) / max(float(distance.max()), 1.0)


def _component_at(mask: np.ndarray, x: int, y: int) -> np.ndarray:
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    return labels == labels[y, x]


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / union if union else 1.0


def _interior_distance(region: np.ndarray) -> np.ndarray:
    """Distance of each pixel of ``region`` to its boundary (the image border counts)."""
    return cv2.distanceTransform(np.pad(region.astype(np.uint8), 1), cv2.DIST_L2, 5)[1:-1, 1:-1]


def simulated_click(reference: np.ndarray, predicted: np.ndarray | None) -> tuple[bool, Point]:
    """The next click of the standard simulated user (Xu et al. 2016; RITM, Sofiiuk et
    al. 2022), for measuring: ``(positive?, (x, y))``.

    The first click (``predicted`` None) at the interior point of ``reference`` farthest
    from its boundary (the image border counts as boundary); each next click in the
    largest error region (the one whose interior point lies farthest from its boundary),
    at that point: positive where the subject was missed, negative where background was
    taken. ``reference`` and ``predicted`` are ``(H, W)`` bool.
    """
    if predicted is None:
        distance = _interior_distance(reference)
        y, x = np.unravel_index(np.argmax(distance), distance.shape)
        return True, (x + 0.5, y + 0.5)
    missed = _interior_distance(reference & ~predicted)
    taken = _interior_distance(~reference & predicted)
    positive = missed.max() >= taken.max()
    distance = missed if positive else taken
    y, x = np.unravel_index(np.argmax(distance), distance.shape)
    return bool(positive), (x + 0.5, y + 0.5)


def segment_with_clicks(image: np.ndarray, positive: Sequence[Point], negative: Sequence[Point] = ()) -> Segmentation:
    """One object's mask from its clicks (a :class:`ClickSession` used once)."""
    return ClickSession(image).segment(positive, negative)


__all__ = ["ClickSession", "WORKING_SIZE", "segment_with_clicks", "simulated_click"]
