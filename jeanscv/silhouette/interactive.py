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

from .masks import downscale, fill_holes, outer_contour, resize, shape_for
from .photo import Segmentation, _run_grabcut, _validate_image

#: Long side (pixels) of the copy the clicks are segmented on.
WORKING_SIZE = 480
#: Long side of the copy auto's hypotheses are made from (as :func:`photo.segment`).
SCENE_SIZE = 640
_ITERATIONS = 3

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
        """The mask after one positive click."""
        x, y = point
        candidates = {}
        for name, mask in self._hypotheses.items():
            if mask[y, x]:
                candidates[name] = _component_at(mask, x, y)
        seeded = self._cut(np.full(self.rgb.shape[:2], cv2.GC_PR_BGD, np.uint8), [point], [], point)
        candidates["click"] = seeded
        if len(candidates) == 1:
            return seeded
        names = list(candidates)
        scores = {a: np.mean([_iou(candidates[a], candidates[b]) for b in names if b != a]) for a in names}
        return candidates[max(names, key=lambda n: (scores[n], n == "click"))]

    def _step(self, previous: np.ndarray, clicks: tuple) -> np.ndarray:
        """The mask after one more click, from the mask before it."""
        sign, (x, y) = clicks[-1]
        labels = np.where(previous, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        # The click says its neighbourhood was wrong, as far as the nearest boundary of
        # the current mask reaches: flip it there.
        inside = previous if sign == "-" else ~previous
        distance = cv2.distanceTransform(np.pad(inside, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1]
        radius = max(2.0, float(distance[y, x]))
        zone = np.zeros_like(labels)
        cv2.circle(zone, (x, y), int(round(radius)), 1, -1)
        zone = zone.astype(bool) & inside
        labels[zone] = cv2.GC_PR_FGD if sign == "+" else cv2.GC_PR_BGD
        pos = [p for s, p in clicks if s == "+"]
        neg = [p for s, p in clicks if s == "-"]
        return self._cut(labels, pos, neg, pos[0])

    def _cut(self, labels: np.ndarray, pos: list, neg: list, anchor) -> np.ndarray:
        """GrabCut from ``labels`` with the clicks as hard seeds; the components holding a
        positive click are kept, holes filled unless a negative click is in one."""
        labels = labels.copy()
        short = min(labels.shape)
        radius = max(1, round(0.012 * short))
        for sign, points in ((cv2.GC_FGD, pos), (cv2.GC_BGD, neg)):
            others = neg if sign == cv2.GC_FGD else pos
            for x, y in points:
                r = radius
                if others:
                    gap = min(np.hypot(x - ox, y - oy) for ox, oy in others)
                    r = max(0, min(r, int(gap / 2) - 1))
                cv2.circle(labels, (x, y), r, int(sign), -1)
                labels[y, x] = sign
        if not (labels == cv2.GC_BGD).any() and not (labels == cv2.GC_PR_BGD).any():
            labels[0, :] = labels[-1, :] = labels[:, 0] = labels[:, -1] = cv2.GC_PR_BGD
        try:
            cut = _run_grabcut(self.rgb, labels, _ITERATIONS)
        except JeansError:
            cut = (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
        count, components = cv2.connectedComponents(cut.astype(np.uint8), connectivity=8)
        keep = {components[y, x] for x, y in pos} - {0}
        mask = np.isin(components, list(keep)) if keep else np.zeros_like(cut)
        filled = fill_holes(mask)
        holes = filled & ~mask
        if holes.any() and neg:
            count, hole_labels = cv2.connectedComponents(holes.astype(np.uint8), connectivity=4)
            drop = {hole_labels[y, x] for x, y in neg} - {0}
            filled &= ~np.isin(hole_labels, list(drop))
        for x, y in pos:
            filled[y, x] = True
        for x, y in neg:
            filled[y, x] = False
        return filled


def _component_at(mask: np.ndarray, x: int, y: int) -> np.ndarray:
    count, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    return labels == labels[y, x]


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / union if union else 1.0


def segment_with_clicks(image: np.ndarray, positive: Sequence[Point], negative: Sequence[Point] = ()) -> Segmentation:
    """One object's mask from its clicks (a :class:`ClickSession` used once)."""
    return ClickSession(image).segment(positive, negative)


__all__ = ["ClickSession", "WORKING_SIZE", "segment_with_clicks"]
