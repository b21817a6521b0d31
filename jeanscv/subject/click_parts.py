"""Parts of the click engine (:mod:`.interactive`): the superpixel graph its geodesic
corrections walk on, the pixel refinement of a mask's boundary, GrabCut from click
seeds, and the first click's geodesic GrabCut.

Arrays: images ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool``; clicks ``(x, y)``
whole pixels of the array they index (x right, y down).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Hashable, Sequence
from typing import TypeVar

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .grabcut import run_grabcut
from .masks import downscale, resize_mask, shape_for

Name = TypeVar("Name", bound=Hashable)

#: GrabCut iterations of a click-seeded cut.
_ITERATIONS = 3
#: Superpixel size, as a fraction of the working copy's long side.
REGION_FRACTION = 0.02
#: Lab steps between neighbouring superpixels below this cost nothing (noise, texture).
_STEP_FLOOR = 4.0
#: Width (Lab units) of the Gaussian kernel a superpixel's mean colour is weighed with
#: against others' (:func:`colour_density`).
COLOUR_KERNEL = 8.0
#: The pixel refinement: colour histograms of ``_COLOUR_BITS`` bits a channel, learned
#: within ``_MODEL_REACH`` superpixel widths of the boundary; the mask's weight as a
#: prior; the guided filter's radius (a share of a superpixel's width) and its
#: regularisation (RGB in [0, 1]). On the shared photos a prior of 0.15 gives IoU@5
#: 0.859 and 0.3 gives 0.854, but 0.15 lets white trousers leak into a white sky and
#: loses 0.08 on the hockey players after three clicks: the stronger prior is safer.
_COLOUR_BITS = 4
_MODEL_REACH = 2.0
_PRIOR_WEIGHT = 0.3
_FILTER_FRACTION = 0.4
_FILTER_EPS = 0.01
#: Radius of a click's hard seed, as a fraction of the copy's short side.
SEED_FRACTION = 0.012
#: The geodesic GrabCut runs on a copy this long (see :func:`geodesic_grabcut`): 0.12 s
#: of CPU at 160 px, 1.7 s at 480. As the first click's candidate (then a voter of its
#: own) it gave IoU after 1, 3 and 5 clicks of 0.695 / 0.822 / 0.872 (real photos) and
#: 0.572 / 0.669 / 0.771 (pets) at 160, 0.668 / 0.793 / 0.859 and 0.592 / 0.665 / 0.772
#: at 240 (two real photos under their floors), 0.695 / 0.819 / 0.870 and 0.596 / 0.676
#: / 0.776 at 480.
GEODESIC_CUT_SIZE = 160
#: Weight of the click's relative depth against agreement when a click chooses among
#: candidates (:func:`agreed`).
DEPTH_WEIGHT = 0.5


def seeded_grabcut(rgb: np.ndarray, labels: np.ndarray, pos: list, neg: list, radius: int) -> np.ndarray:
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
        return run_grabcut(rgb, labels, _ITERATIONS)
    except JeansError:
        return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


class PixelRefiner:
    """Re-decides the pixels near a superpixel mask's boundary, where superpixels are too
    coarse (thin parts, fine outlines): each pixel of a band one superpixel wide takes
    the side its colour is likelier on, by histograms of the colours just inside and just
    outside the mask (GrabCut's colour models, Rother et al. 2004, learned locally), with
    a little of the mask itself as a prior; the probabilities are smoothed with a guided
    filter of the image (edge-aware smoothing in place of a graph cut's: cost-volume
    filtering, Rhemann et al. 2011; guided filter, He et al. 2010), then halved."""

    def __init__(self, rgb: np.ndarray):
        self.guide = rgb.astype(np.float32) / 255.0
        bins = (rgb >> (8 - _COLOUR_BITS)).astype(np.int32)
        self.colour = (bins[..., 0] << (2 * _COLOUR_BITS)) | (bins[..., 1] << _COLOUR_BITS) | bins[..., 2]
        self.band = max(2, round(REGION_FRACTION * max(rgb.shape[:2])))
        self.radius = max(1, round(_FILTER_FRACTION * self.band))

    def refine(self, mask: np.ndarray) -> np.ndarray:
        if mask.all() or not mask.any():
            return mask
        inside = interior_distance(mask)
        outside = interior_distance(~mask)
        depth = np.maximum(inside, outside)  # distance to the boundary, either side
        near = depth <= _MODEL_REACH * self.band
        band = depth <= self.band
        count = 1 << (3 * _COLOUR_BITS)
        fg = np.bincount(self.colour[near & mask], minlength=count) + 1.0
        bg = np.bincount(self.colour[near & ~mask], minlength=count) + 1.0
        fg /= fg.sum()
        bg /= bg.sum()
        likely = (fg / (fg + bg)).astype(np.float32)[self.colour]
        belief = (1.0 - _PRIOR_WEIGHT) * likely + _PRIOR_WEIGHT * mask.astype(np.float32)
        smooth = cv2.ximgproc.guidedFilter(self.guide, belief, self.radius, _FILTER_EPS)
        refined = mask.copy()
        refined[band] = smooth[band] >= 0.5
        return refined


class ClickGraph:
    """SLIC superpixels of the working copy and their adjacency, weighted by the Lab
    distance of neighbours (less a noise floor), for geodesic distances."""

    def __init__(self, rgb: np.ndarray):
        from .saliency import SuperpixelGraph

        lab = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)
        region = max(4, round(REGION_FRACTION * max(rgb.shape[:2])))
        graph = SuperpixelGraph.of(lab, region)
        self.labels, self.count, self.area = graph.labels, graph.count, graph.area
        self.colour = graph.colour  # (n, 3) mean Lab of each superpixel
        self.centre_px = graph.centre * float(max(rgb.shape[:2]))
        self.on_border = graph.border.any(axis=1)
        i, j = graph.edges[:, 0], graph.edges[:, 1]
        weight = np.maximum(np.linalg.norm(graph.colour[i] - graph.colour[j], axis=1) - _STEP_FLOOR, 0.0) + 1e-3
        # Each node's neighbours and step costs, as Python lists: Dijkstra's loop reads
        # them one at a time, which lists serve several times faster than arrays.
        self._edges, self._weight = (i, j), weight
        heads, tails, steps = np.concatenate([i, j]), np.concatenate([j, i]), np.concatenate([weight, weight])
        order = np.argsort(heads, kind="stable")
        self._first = np.searchsorted(heads[order], np.arange(self.count + 1)).tolist()
        self._next, self._step = tails[order].tolist(), steps[order].tolist()

    def contrast(self, region: np.ndarray) -> float:
        """Mean step cost (Lab units over the noise floor) across the boundary of
        ``region`` ((n,) bool over the superpixels); 0 when it has none."""
        i, j = self._edges
        across = region[i] != region[j]
        return float(self._weight[across].mean()) if across.any() else 0.0

    def mean_of(self, mask: np.ndarray) -> np.ndarray:
        return np.bincount(self.labels.ravel(), mask.ravel().astype(np.float64), self.count) / self.area

    def distances(self, allowed: np.ndarray, sources) -> np.ndarray:
        """(n,) geodesic distance to the nearest of ``sources`` through ``allowed`` nodes
        (a source outside them stays at 0 and leads nowhere).

        Dijkstra on a binary heap: a few thousand superpixels take 1-6 ms. (A node's
        distance is the least sum along a path, added up from the source, so every
        correct shortest-path routine gives the same bits; scipy's, used before, cost a
        fresh process 0.35 s to import.)"""
        usable = np.asarray(allowed, bool).tolist()
        first, following, step = self._first, self._next, self._step
        distance = [math.inf] * self.count
        heap = []
        for source in np.asarray(sources, int).ravel().tolist():
            distance[source] = 0.0
            heap.append((0.0, source))
        heapq.heapify(heap)
        while heap:
            reached, node = heapq.heappop(heap)
            if reached > distance[node] or not usable[node]:
                continue
            for k in range(first[node], first[node + 1]):
                other = following[k]
                if usable[other]:
                    candidate = reached + step[k]
                    if candidate < distance[other]:
                        distance[other] = candidate
                        heapq.heappush(heap, (candidate, other))
        return np.array(distance)


def agreed(
    names: Sequence[Name],
    overlap: Callable[[Name, Name], float],
    depth: Callable[[Name], float],
    votes: dict[Name, float] | None = None,
    tie: Name | None = None,
) -> Name:
    """The candidate the others agree with most: the mean of ``overlap(a, b)`` (their
    IoU) over the other candidates ``b``, each weighted by ``votes`` (1 by default),
    plus :data:`DEPTH_WEIGHT` times ``depth(a)``, the click's relative depth in ``a`` (a
    person clicks the middle of the thing: a mask the click only grazes is likely the
    wrong one). ``tie`` wins ties, else the first of equals. The one rule of the first
    click (:class:`~.interactive.ClickSession`) and of its preview (:mod:`.hover`)."""
    if len(names) == 1:
        return names[0]
    votes = votes or {}
    scores = {
        a: np.average([overlap(a, b) for b in names if b != a], weights=[votes.get(b, 1.0) for b in names if b != a])
        + DEPTH_WEIGHT * depth(a)
        for a in names
    }
    return max(names, key=lambda name: (scores[name], name == tie))


def colour_density(
    colours: np.ndarray, samples: np.ndarray, weights: np.ndarray, sigma: float = COLOUR_KERNEL
) -> np.ndarray:
    """``(n,)`` density of each of ``colours`` (``(n, 3)`` Lab) under Gaussian kernels of
    width ``sigma`` at ``samples`` (``(m, 3)``) weighted by ``weights`` (``(m,)``, their
    areas), over the weights' sum; zeros when there are no samples."""
    if len(samples) == 0:
        return np.zeros(len(colours))
    squared = ((colours[:, None, :] - samples[None, :, :]) ** 2).sum(-1)
    return (np.exp(-squared / (2 * sigma**2)) * weights[None]).sum(1) / max(float(weights.sum()), 1e-9)


def interior_distance(region: np.ndarray) -> np.ndarray:
    """Distance of each pixel of ``region`` to its boundary (the image border counts)."""
    return cv2.distanceTransform(np.pad(region.astype(np.uint8), 1), cv2.DIST_L2, 5)[1:-1, 1:-1]


def geodesic_grabcut(rgb: np.ndarray, positive: list, negative: list = (), size: int = GEODESIC_CUT_SIZE) -> np.ndarray:
    """The object the clicks describe, by geodesic distances and then GrabCut: ``(H, W)``
    bool at ``rgb``'s size (clicks in its pixels).

    On a copy with long side ``size``, every pixel goes to the side it reaches more
    cheaply along the image's Lab gradient: the positive clicks, or the negative clicks
    and the image border (the background spreads along the border: Zhu et al. 2014;
    geodesic segmentation, Bai and Sapiro 2007). That partition seeds GrabCut as
    "probably" each side, with hard discs at the clicks (Rother et al. 2004), so its
    colour models, learned from the whole partition, settle the edge. Its global colour
    models suit a first click that must find the whole object (an everyday photo's pet
    beside its owner); the session's later clicks stay local.
    """
    from skimage.graph import MCP_Geometric  # only when a click is made

    small, onto = small_copy(rgb, size)
    pos, neg = onto(positive), onto(negative)
    cost = gradient_cost(small)
    h, w = cost.shape
    border = (
        [(0, x) for x in range(w)]
        + [(h - 1, x) for x in range(w)]
        + [(y, 0) for y in range(h)]
        + [(y, w - 1) for y in range(h)]
    )
    near_object = MCP_Geometric(cost).find_costs([(y, x) for x, y in pos])[0]
    near_background = MCP_Geometric(cost).find_costs([(y, x) for x, y in neg] + border)[0]
    labels = np.where(near_object < near_background, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
    radius = max(1, round(SEED_FRACTION * min(h, w)))
    cut = seeded_grabcut(small, labels, pos, neg, radius)
    return resize_mask(cut, (rgb.shape[1], rgb.shape[0]))


def gradient_cost(rgb: np.ndarray) -> np.ndarray:
    """``(H, W) float32`` cost of stepping on each pixel for geodesic distances: the Lab
    gradient's magnitude (Sobel), plus 1 (a flat stretch still costs its length)."""
    lab = cv2.cvtColor(rgb.astype(np.float32) / 255.0, cv2.COLOR_RGB2LAB)
    gx = cv2.Sobel(lab, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(lab, cv2.CV_32F, 0, 1, ksize=3)
    return np.sqrt((gx**2 + gy**2).sum(axis=-1)) + 1.0


def small_copy(rgb: np.ndarray, size: int) -> tuple[np.ndarray, Callable[[Sequence], list[tuple[int, int]]]]:
    """``rgb`` area-averaged onto a copy with long side ``size`` (as it is when smaller),
    and the map of ``(x, y)`` pixels of ``rgb`` onto the copy's whole pixels."""
    height, width = rgb.shape[:2]
    small_size = shape_for((height, width), size)
    sx, sy = small_size[0] / width, small_size[1] / height

    def onto(points: Sequence) -> list[tuple[int, int]]:
        return [(min(int(x * sx), small_size[0] - 1), min(int(y * sy), small_size[1] - 1)) for x, y in points]

    return np.ascontiguousarray(downscale(rgb, small_size)), onto


def simulated_click(reference: np.ndarray, predicted: np.ndarray | None) -> tuple[bool, tuple[float, float]]:
    """The next click of the standard simulated user (Xu et al. 2016; RITM, Sofiiuk et
    al. 2022), for measuring: ``(positive?, (x, y))``.

    The first click (``predicted`` None) at the interior point of ``reference`` farthest
    from its boundary (the image border counts as boundary); each next click in the
    largest error region (the one whose interior point lies farthest from its boundary),
    at that point: positive where the subject was missed, negative where background was
    taken. ``reference`` and ``predicted`` are ``(H, W)`` bool.
    """
    if predicted is None:
        distance = interior_distance(reference)
        y, x = np.unravel_index(np.argmax(distance), distance.shape)
        return True, (x + 0.5, y + 0.5)
    missed = interior_distance(reference & ~predicted)
    taken = interior_distance(~reference & predicted)
    positive = missed.max() >= taken.max()
    distance = missed if positive else taken
    y, x = np.unravel_index(np.argmax(distance), distance.shape)
    return bool(positive), (x + 0.5, y + 0.5)
