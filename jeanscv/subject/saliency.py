"""Salient-object maps for real photos: boundary connectivity on superpixels.

Public API: :class:`SuperpixelGraph` (SLIC superpixels of a coarse Lab image) and
:func:`saliency_map` (its superpixels' saliency in [0, 1]).

The method is "robust background detection" (Zhu, Liang, Wei and Sun, CVPR 2014):
the background is what connects to the image border through similar colours. On a
graph of SLIC superpixels whose edges weigh the Lab distance of neighbours (border
superpixels also joined to each other), each superpixel's geodesic "spanning area"
and the part of it on the border give its boundary connectivity
``BndCon = Len_border / sqrt(Area)``: high for background regions, which spread along
the border, low for objects, even objects that touch one or two sides (their share
of the border is small next to their area). ``w_bg = 1 - exp(-BndCon^2 / 2)`` then
weighs a background-weighted colour contrast (foreground evidence), and saliency is
the least-squares solution that is 0 on background, 1 on foreground evidence and
smooth between similar neighbours (the paper's equation 8).

Coordinates: x right, y down; the superpixel centroids are normalised to [0, 1] by the
longer image side so distances are isotropic.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

_SIGMA_COLOUR = 10.0  # Lab units: geodesic distances map to similarity at this scale (paper: 10)
_SIGMA_BORDER = 1.0  # boundary connectivity at which a region counts as background (paper: 1)
_SIGMA_SPACE = 0.25  # spatial reach of the weighted contrast, in image (long side) units (paper: 0.4)
_SMOOTH_FLOOR = 0.1  # the paper's mu: neighbours are smoothed even across colour edges a little


@dataclass
class SuperpixelGraph:
    """SLIC superpixels of a coarse image and their adjacency.

    labels: (h, w) int32 superpixel index per pixel, 0..n-1.
    colour: (n, 3) float64 mean Lab (L 0..100).
    centre: (n, 2) float64 mean (x, y), normalised by the long side.
    area: (n,) pixel counts.
    border: (n, 4) bool, superpixel touches the top, bottom, left, right border.
    edges: (m, 2) int pairs of adjacent superpixels (i < j).
    """

    labels: np.ndarray
    colour: np.ndarray
    centre: np.ndarray
    area: np.ndarray
    border: np.ndarray
    edges: np.ndarray

    @property
    def count(self) -> int:
        return len(self.area)

    @classmethod
    def of(cls, lab: np.ndarray, region_size: int) -> SuperpixelGraph:
        """SLIC (SLICO, no compactness to tune) on a float32 Lab image."""
        slic = cv2.ximgproc.createSuperpixelSLIC(lab, cv2.ximgproc.SLICO, region_size)
        slic.iterate(10)
        slic.enforceLabelConnectivity(max(1, region_size * region_size // 4))
        raw = slic.getLabels()
        # Renumber the labels in use as 0..n-1 (np.unique's inverse, without its sort).
        used = np.bincount(raw.ravel()) > 0
        labels = (np.cumsum(used, dtype=np.int32) - 1)[raw]
        n = int(labels.max()) + 1
        flat = labels.ravel()
        area = np.bincount(flat, minlength=n).astype(np.float64)
        colour = np.stack([np.bincount(flat, lab[..., k].ravel(), n) for k in range(3)], axis=1) / area[:, None]
        height, width = labels.shape
        ys, xs = np.mgrid[0:height, 0:width]
        scale = float(max(height, width))
        centre = (
            np.stack(
                [np.bincount(flat, (xs.ravel() + 0.5) / scale, n), np.bincount(flat, (ys.ravel() + 0.5) / scale, n)],
                axis=1,
            )
            / area[:, None]
        )
        border = np.zeros((n, 4), bool)
        for side, strip in enumerate((labels[0], labels[-1], labels[:, 0], labels[:, -1])):
            border[np.unique(strip), side] = True
        first = np.concatenate([labels[:, :-1].ravel(), labels[:-1].ravel()]).astype(np.int64)
        second = np.concatenate([labels[:, 1:].ravel(), labels[1:].ravel()]).astype(np.int64)
        differ = first != second
        first, second = first[differ], second[differ]
        # Each unordered pair as one integer (i * n + j, i < j): sorted unique rows, fast.
        keys = np.unique(np.minimum(first, second) * n + np.maximum(first, second))
        edges = np.stack([keys // n, keys % n], axis=1)
        return cls(labels, colour, centre, area, border, edges)

    @cached_property
    def contrast_weights(self) -> np.ndarray:
        """(n, n) Lab distance of every pair of superpixels times their spatial weight
        exp(-d^2 / 2 sigma^2) (``_SIGMA_SPACE``): the weighted contrast's kernel, shared
        by every saliency map of the graph."""
        colour_distance = _pairwise_distance(self.colour)
        space_distance = _pairwise_distance(self.centre)
        return colour_distance * np.exp(-(space_distance**2) / (2 * _SIGMA_SPACE**2))

    def mean_of(self, image: np.ndarray) -> np.ndarray:
        """(n,) mean of an (h, w) image over each superpixel."""
        return np.bincount(self.labels.ravel(), np.asarray(image, np.float64).ravel(), self.count) / self.area

    def to_pixels(self, values: np.ndarray) -> np.ndarray:
        """Per-superpixel values painted onto the (h, w) image."""
        return np.asarray(values, np.float32)[self.labels]


def _pairwise_distance(points: np.ndarray) -> np.ndarray:
    """(n, n) Euclidean distances between the rows of (n, d) ``points``: the values of
    ``np.linalg.norm(points[:, None] - points[None], axis=2)`` (squares summed in
    coordinate order), ten times faster than reducing over a length-d axis."""
    total = np.zeros((len(points), len(points)))
    for coordinate in points.T:
        step = coordinate[:, None] - coordinate[None]
        total += step * step
    return np.sqrt(total)


def _minimax(count: int, rows: np.ndarray, cols: np.ndarray, data: np.ndarray) -> np.ndarray:
    """All-pairs minimax path costs (the largest step on the best path), by Kruskal:
    when two components merge over an edge of cost w, every pair across them gets w.

    The edges are taken cheapest first; an edge within one component merges nothing
    (the edges that merge form a minimum spanning tree, and every minimum spanning
    tree gives the same minimax costs). The leaves are then laid out in
    merge-tree order, where every component is a contiguous range and each merge fills
    two blocks of the matrix by slicing."""
    parent = np.arange(count)

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    # Merge tree: cluster count + m joins children[m] over cost[m].
    children, cost = [], []
    cluster = list(range(count))  # union-find root -> its merge-tree node
    for k in np.argsort(data, kind="stable"):
        a, b = find(rows[k]), find(cols[k])
        if a == b:
            continue
        children.append((cluster[a], cluster[b]))
        cost.append(data[k])
        parent[b] = a
        cluster[a] = count + len(children) - 1
    # Leaves in merge-tree order (depth first, left child first), roots one after another.
    size = np.ones(count + len(children), np.int64)
    for m, (left, right) in enumerate(children):
        size[count + m] = size[left] + size[right]
    start = np.zeros(len(size), np.int64)
    roots = sorted({cluster[find(i)] for i in range(count)})
    offset = 0
    for root in roots:
        start[root] = offset
        offset += size[root]
    for m in range(len(children) - 1, -1, -1):
        left, right = children[m]
        start[left] = start[count + m]
        start[right] = start[count + m] + size[left]
    laid = np.zeros((count, count))
    for m, (left, right) in enumerate(children):
        a, b, c = start[left], start[right], start[right] + size[right]
        laid[a:b, b:c] = cost[m]
        laid[b:c, a:b] = cost[m]
    leaves = start[:count]  # leaf i sits at position leaves[i]
    return laid[np.ix_(leaves, leaves)]


def _geodesic(graph: SuperpixelGraph, border_nodes: np.ndarray, path_cost: str, step_floor: float) -> np.ndarray:
    """(n, n) path distances over adjacent superpixels, with all border superpixels
    also joined to each other (the paper's trick: the background around the frame is
    one region). Steps cost their Lab distance less ``step_floor`` (texture and noise
    within a background should not add up); ``path_cost`` "sum" adds the steps
    (geodesic distance, the paper's), "minimax" takes the largest step (a barrier
    distance: gradual shading never separates)."""
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    weight = np.linalg.norm(graph.colour[i] - graph.colour[j], axis=1)
    b = np.flatnonzero(border_nodes)
    bi, bj = np.meshgrid(b, b)
    keep = bi < bj
    bi, bj = bi[keep], bj[keep]
    bw = np.linalg.norm(graph.colour[bi] - graph.colour[bj], axis=1)
    rows = np.concatenate([i, bi])
    cols = np.concatenate([j, bj])
    data = np.maximum(np.concatenate([weight, bw]) - step_floor, 0.0) + 1e-6
    if path_cost == "minimax":
        return _minimax(graph.count, rows, cols, data)
    return _floyd_warshall(graph.count, rows, cols, data)


def _floyd_warshall(count: int, rows: np.ndarray, cols: np.ndarray, data: np.ndarray) -> np.ndarray:
    """(n, n) shortest path lengths of the undirected graph with edges ``rows[k]`` -
    ``cols[k]`` of length ``data[k]`` (> 0), by Floyd-Warshall.

    All pairs on a few hundred densely joined nodes (the border clique): Floyd-Warshall
    is 2-3 times faster than Dijkstra from every node. An edge given twice (two border
    superpixels that are also neighbours) has the sum of its lengths, as in the sparse
    graph this replaced, so the distances are the same bits. The paths through node
    ``k`` are tried for the rows that reach ``k`` only (each step is numpy over rows;
    scipy's import cost a fresh process 0.35 s)."""
    dist = np.zeros((count, count))
    np.add.at(dist, (rows, cols), data)
    dist[dist == 0.0] = np.inf
    np.minimum(dist, dist.T, out=dist)
    np.fill_diagonal(dist, 0.0)
    through = np.empty_like(dist)
    for k in range(count):
        column = dist[:, k]
        reach = np.flatnonzero(column < np.inf)
        if 2 * len(reach) > count:
            np.add(column[:, None], dist[None, k, :], out=through)
            np.minimum(dist, through, out=dist)
        else:
            rows_reaching = dist[reach]
            np.minimum(rows_reaching, column[reach, None] + dist[None, k, :], out=rows_reaching)
            dist[reach] = rows_reaching
    return dist


def boundary_connectivity(
    graph: SuperpixelGraph, border_nodes: np.ndarray, path_cost: str = "sum", step_floor: float = 0.0
) -> np.ndarray:
    """(n,) BndCon of every superpixel (Zhu et al. 2014, equation 5, geodesic form)."""
    distance = _geodesic(graph, border_nodes, path_cost, step_floor)
    similarity = np.exp(-(distance**2) / (2 * _SIGMA_COLOUR**2))
    area = similarity.sum(axis=1)
    length = similarity[:, border_nodes].sum(axis=1)
    return length / np.sqrt(area)


def focus(graph: SuperpixelGraph, detail: np.ndarray) -> np.ndarray:
    """(n,) how sharp each superpixel is, in [0, 1]: its mean ``detail`` (an (h, w)
    high-pass magnitude such as |Laplacian|) over the 95th percentile of those means.

    Photographers focus on the subject: backgrounds are often blurred or smooth (sky,
    studio walls, bokeh), so a subject's superpixels carry more fine detail.
    """
    sharpness = graph.mean_of(detail)
    return np.clip(sharpness / max(float(np.percentile(sharpness, 95)), 1e-9), 0.0, 1.0)


def saliency_map(
    graph: SuperpixelGraph, path_cost: str = "sum", step_floor: float = 0.0, sharpness: np.ndarray | None = None
) -> np.ndarray:
    """(n,) saliency in [0, 1] of each superpixel: robust background detection.

    ``path_cost`` and ``step_floor``: how colour steps add up along a path to the
    border (see :func:`boundary_connectivity`). ``sharpness``: (n,) :func:`focus`;
    when given the map is weighted by ``(1 + sharpness) / 2``, so blurred regions keep
    at most half their saliency. The maximum is scaled to 1.
    """
    if path_cost not in ("sum", "minimax"):
        raise ValueError(f"path_cost must be 'sum' or 'minimax', got {path_cost!r}")
    border_nodes = graph.border.any(axis=1)
    bndcon = boundary_connectivity(graph, border_nodes, path_cost, step_floor)
    background = 1.0 - np.exp(-(bndcon**2) / (2 * _SIGMA_BORDER**2))
    contrast = (graph.contrast_weights * background[None]).sum(axis=1)
    foreground = contrast / (contrast.max() + 1e-9)
    # Equation 8: min sum w_bg s^2 + w_fg (s - 1)^2 + sum_adjacent w_ij (s_i - s_j)^2.
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    w = (
        np.exp(-(np.linalg.norm(graph.colour[i] - graph.colour[j], axis=1) ** 2) / (2 * _SIGMA_COLOUR**2))
        + _SMOOTH_FLOOR
    )
    n = graph.count
    degree = np.bincount(i, w, n) + np.bincount(j, w, n)
    # Laplacian + diag(w_bg + w_fg), dense: a few hundred unknowns solve in 2-3 ms, less
    # than a sparse solver (and its import) takes. Its solution differs from a sparse
    # LU's in the last bits of float64 only; the maps are float32 (to_pixels).
    system = np.zeros((n, n))
    system[i, j] = -w
    system[j, i] = -w
    system[np.arange(n), np.arange(n)] = degree + background + foreground
    solution = np.clip(np.linalg.solve(system, foreground), 0.0, 1.0)
    if sharpness is not None:
        solution = solution * (0.5 + 0.5 * sharpness)
    return solution / max(float(solution.max()), 1e-9)
