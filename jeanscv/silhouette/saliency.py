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
        _, labels = np.unique(raw, return_inverse=True)
        labels = labels.reshape(raw.shape).astype(np.int32)
        n = int(labels.max()) + 1
        flat = labels.ravel()
        area = np.bincount(flat, minlength=n).astype(np.float64)
        colour = np.stack([np.bincount(flat, lab[..., k].ravel(), n) for k in range(3)], axis=1) / area[:, None]
        height, width = labels.shape
        ys, xs = np.mgrid[0:height, 0:width]
        scale = float(max(height, width))
        centre = np.stack(
            [np.bincount(flat, (xs.ravel() + 0.5) / scale, n), np.bincount(flat, (ys.ravel() + 0.5) / scale, n)], axis=1
        ) / area[:, None]
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
        colour_distance = np.linalg.norm(self.colour[:, None] - self.colour[None], axis=2)
        space_distance = np.linalg.norm(self.centre[:, None] - self.centre[None], axis=2)
        return colour_distance * np.exp(-(space_distance**2) / (2 * _SIGMA_SPACE**2))

    def mean_of(self, image: np.ndarray) -> np.ndarray:
        """(n,) mean of an (h, w) image over each superpixel."""
        return np.bincount(self.labels.ravel(), np.asarray(image, np.float64).ravel(), self.count) / self.area

    def to_pixels(self, values: np.ndarray) -> np.ndarray:
        """Per-superpixel values painted onto the (h, w) image."""
        return np.asarray(values, np.float32)[self.labels]


def _minimax(count: int, rows: np.ndarray, cols: np.ndarray, data: np.ndarray) -> np.ndarray:
    """All-pairs minimax path costs (the largest step on the best path), by Kruskal:
    when two components merge over an edge of cost w, every pair across them gets w."""
    distance = np.zeros((count, count))
    parent = np.arange(count)
    members = {i: [i] for i in range(count)}

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k in np.argsort(data, kind="stable"):
        a, b = find(rows[k]), find(cols[k])
        if a == b:
            continue
        left, right = members[a], members[b]
        distance[np.ix_(left, right)] = data[k]
        distance[np.ix_(right, left)] = data[k]
        if len(left) < len(right):
            a, b, left, right = b, a, right, left
        parent[b] = a
        left.extend(right)
        del members[b]
    return distance


def _geodesic(graph: SuperpixelGraph, border_nodes: np.ndarray, path_cost: str, step_floor: float) -> np.ndarray:
    """(n, n) path distances over adjacent superpixels, with all border superpixels
    also joined to each other (the paper's trick: the background around the frame is
    one region). Steps cost their Lab distance less ``step_floor`` (texture and noise
    within a background should not add up); ``path_cost`` "sum" adds the steps
    (geodesic distance, the paper's), "minimax" takes the largest step (a barrier
    distance: gradual shading never separates)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import shortest_path

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
    matrix = coo_matrix((data, (rows, cols)), shape=(graph.count, graph.count)).tocsr()
    # All pairs on a few hundred densely joined nodes (the border clique): Floyd-Warshall
    # is 2-3 times faster than Dijkstra from every node, with the same distances.
    return shortest_path(matrix, method="FW", directed=False)


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
    w = np.exp(-(np.linalg.norm(graph.colour[i] - graph.colour[j], axis=1) ** 2) / (2 * _SIGMA_COLOUR**2)) + _SMOOTH_FLOOR
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    n = graph.count
    degree = np.bincount(i, w, n) + np.bincount(j, w, n)
    rows = np.concatenate([i, j, np.arange(n)])
    cols = np.concatenate([j, i, np.arange(n)])
    data = np.concatenate([-w, -w, degree + background + foreground])
    system = coo_matrix((data, (rows, cols)), shape=(n, n)).tocsc()  # Laplacian + diag(w_bg + w_fg)
    solution = np.clip(spsolve(system, foreground), 0.0, 1.0)
    if sharpness is not None:
        solution = solution * (0.5 + 0.5 * sharpness)
    return solution / max(float(solution.max()), 1e-9)
