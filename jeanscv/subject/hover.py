"""What a first click would take, everywhere at once: the map behind the web page's
hover preview (the outline of the thing under the pointer, before any click).

Public API: :func:`first_click_map` (one per :class:`~jeanscv.subject.interactive.ClickSession`)
and :class:`FirstClickMap`.

How: :meth:`ClickSession._first` chooses, for the clicked point, among the pieces of
auto's hypotheses that hold it, a GrabCut seeded at the click, the geodesic region
nearer the click than the border, a GrabCut seeded by that region and what lies inside a
box round it, the candidate the others agree with most and the click lies deepest in.
Here that choice is made once per superpixel (at its pixel nearest its centre), without
the two GrabCuts and the box round the geodesic region (0.2 s a click: 2,000
superpixels would take minutes): the hypotheses' pieces are cut once, the geodesic
regions from one Dijkstra per superpixel, each only as far as it lies from the border,
and agreement is counted per superpixel. Each region is a set of superpixels (a piece:
the superpixels mostly in it), so the page draws it from the superpixel labels alone.
``bench/hover_preview.py`` measures how often the region
shown is what the first click takes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from .masks import MIN_AREA_FRACTION, fill_holes

#: Distances this close (relative) count as equal: float sums in another order.
_TIE = 1e-9


@dataclass(frozen=True)
class FirstClickMap:
    """``labels``: ``(h, w)`` superpixel index of each working pixel (the session's
    working copy); ``choice``: ``(n,)`` the region a first click in each superpixel
    would take (-1: nothing would be found there); ``regions``: each region's
    superpixel indexes."""

    labels: np.ndarray
    choice: np.ndarray
    regions: list[np.ndarray]

    def mask(self, region: int) -> np.ndarray:
        """Region ``region`` as an ``(h, w)`` bool mask of the working copy (-1: empty)."""
        if region < 0:
            return np.zeros(self.labels.shape, bool)
        nodes = np.zeros(len(self.choice), bool)
        nodes[self.regions[region]] = True
        return nodes[self.labels]

    def at(self, x: int, y: int) -> int:
        """The region a first click at working pixel ``(x, y)`` would take (-1: none)."""
        return int(self.choice[self.labels[y, x]])


def first_click_map(session) -> FirstClickMap:
    """The :class:`FirstClickMap` of a :class:`~jeanscv.subject.interactive.ClickSession`
    (about a second; the page asks for it once per photo)."""
    from .click_first import _EDGE_CONTRAST
    from .click_masks import grouped_pieces
    from .click_parts import agreed, interior_distance

    graph = session._graph
    labels, count, area = graph.labels, graph.count, graph.area
    points = _central_pixels(labels, graph.centre_px, count)
    px, py = points[:, 0], points[:, 1]
    least = max(3 * session._smallest, MIN_AREA_FRACTION * labels.size)

    # The hypotheses' pieces, cut once: which piece (if any) holds each point, and per
    # piece its pixels per superpixel, its area and each point's relative depth in it.
    held = []  # per superpixel: the pieces (one per hypothesis at most) that hold its point
    pieces, piece_nodes, piece_depth = [], [], []
    holders = np.full((len(session._hypotheses), count), -1)
    for row, hypothesis in enumerate(session._hypotheses.values()):
        components = grouped_pieces(hypothesis)
        at_points = components[py, px] * hypothesis[py, px]
        for component in np.unique(at_points[at_points > 0]):
            piece = fill_holes((components == component) & hypothesis)
            holders[row, at_points == component] = len(pieces)
            pieces.append(piece)
            piece_nodes.append(np.bincount(labels[piece], minlength=count).astype(np.float64))
            distance = interior_distance(piece)
            piece_depth.append(distance[py, px] / max(float(distance.max()), 1.0))
    piece_area = np.array([float(np.count_nonzero(p)) for p in pieces])
    overlap = np.array([[np.count_nonzero(a & b) for b in pieces] for a in pieces], np.float64).reshape(len(pieces), -1)
    piece_iou = overlap / np.maximum(piece_area[:, None] + piece_area[None, :] - overlap, 1.0)
    piece_nodes = np.array(piece_nodes).reshape(len(pieces), count)
    for node in range(count):
        held.append([int(p) for p in holders[:, node] if p >= 0 and piece_area[p] >= least])

    # The geodesic regions, each scored once however many superpixels lead to it.
    keys, geodesic_of = _geodesic_regions(graph)
    geodesic = {}  # key -> (superpixels (bool), IoU with each piece) or None
    for key, reach in geodesic_of.items():
        reached = float(area[reach].sum())
        if graph.contrast(reach) < _EDGE_CONTRAST or reached < least:
            geodesic[key] = None
            continue
        common = piece_nodes[:, reach].sum(axis=1)
        geodesic[key] = (reach, common / np.maximum(piece_area + reached - common, 1.0))
    depths: dict[bytes, np.ndarray] = {}

    def geodesic_depth(key: bytes, node: int) -> float:
        """The point's relative depth in a geodesic region (made when first asked)."""
        if key not in depths:
            distance = interior_distance(geodesic[key][0][labels])
            depths[key] = distance[py, px] / max(float(distance.max()), 1.0)
        return float(depths[key][node])

    def overlap(geodesic_iou: np.ndarray | None, a: tuple[str, int], b: tuple[str, int]) -> float:
        """Two candidates' IoU: of two pieces, or of a piece and the geodesic region."""
        if a[0] == "piece" and b[0] == "piece":
            return piece_iou[a[1], b[1]]
        return geodesic_iou[a[1] if a[0] == "piece" else b[1]]

    def depth(node: int, a: tuple[str, int]) -> float:
        """The relative depth of superpixel ``node``'s point in candidate ``a``."""
        return piece_depth[a[1]][node] if a[0] == "piece" else geodesic_depth(keys[node], node)

    regions: dict[object, int] = {}
    region_nodes: list[np.ndarray] = []
    choice = np.full(count, -1)
    for node in range(count):
        found = geodesic[keys[node]]
        names = [("piece", p) for p in held[node]] + ([("geodesic", -1)] if found is not None else [])
        if not names:
            continue
        # As the first click chooses, without its GrabCuts.
        best = agreed(names, partial(overlap, found[1] if found else None), partial(depth, node))
        kind, index = best
        key = ("geodesic", keys[node]) if kind == "geodesic" else ("piece", index)
        if key not in regions:
            regions[key] = len(region_nodes)
            nodes = found[0] if kind == "geodesic" else piece_nodes[index] > 0.5 * area
            region_nodes.append(np.union1d(np.flatnonzero(nodes), [node]).astype(np.int64))
        choice[node] = regions[key]
    _detected_choices(session, points, choice, regions, region_nodes)
    return FirstClickMap(labels, choice, region_nodes)


def _detected_choices(session, points: np.ndarray, choice: np.ndarray, regions: dict, region_nodes: list) -> None:
    """Where a first click starts from a detected object's box
    (:meth:`~jeanscv.subject.interactive.ClickSession.meant`: inside the box, on its cut),
    the map shows that box's cut, in place (``choice``, ``regions``, ``region_nodes``)."""
    if not session.detections:
        return
    graph = session._graph
    for node, (x, y) in enumerate(points):
        meant = session._meant((int(x), int(y)))
        if meant is None:
            continue
        key = ("detected", meant.box)
        if key not in regions:
            cut = session._boxed(meant.box, ())
            nodes = np.bincount(graph.labels[cut], minlength=graph.count) > 0.5 * graph.area
            regions[key] = len(region_nodes)
            region_nodes.append(np.flatnonzero(nodes).astype(np.int64))
        if node not in region_nodes[regions[key]]:
            region_nodes[regions[key]] = np.union1d(region_nodes[regions[key]], [node]).astype(np.int64)
        choice[node] = regions[key]


def _central_pixels(labels: np.ndarray, centres: np.ndarray, count: int) -> np.ndarray:
    """``(count, 2)`` the pixel ``(x, y)`` of each superpixel nearest its centre (a click's
    stand-in: SLIC's superpixels are compact, the centre is mostly inside)."""
    height, width = labels.shape
    ys, xs = np.mgrid[0:height, 0:width]
    flat = labels.ravel()
    distance = np.hypot(xs.ravel() + 0.5 - centres[flat, 0], ys.ravel() + 0.5 - centres[flat, 1])
    order = np.lexsort((distance, flat))
    first = order[np.searchsorted(flat[order], np.arange(count))]
    return np.stack([xs.ravel()[first], ys.ravel()[first]], axis=1)


def _geodesic_regions(graph) -> tuple[list[bytes], dict[bytes, np.ndarray]]:
    """Per superpixel, the key of its geodesic region (the superpixels nearer it than the
    image border: :meth:`ClickSession._geodesic_first`, whose click's own superpixel is
    no border), and each distinct region, ``(count,) bool``, by key.

    Superpixel ``w`` is in the region of ``v`` when ``d(v, w) < d(border, w)``: rather
    than a search from every ``v`` as far as the farthest superpixel lies from the
    border, each ``w`` searches only as far as it lies from the border itself (the
    graph is undirected), in chunks of similar reach; a border superpixel's own region
    (the border without it) is searched from it. scipy's Dijkstra (C), in chunks that
    keep the distances to a few MB: about a third of the time of a search from every
    superpixel."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    count = graph.count
    i, j = graph._edges
    weights = np.concatenate([graph._weight, graph._weight])
    matrix = csr_matrix((weights, (np.concatenate([i, j]), np.concatenate([j, i]))), shape=(count, count))
    border = np.flatnonzero(graph.on_border)
    if len(border):
        near_border = dijkstra(matrix, indices=border, min_only=True)
    else:
        near_border = np.full(count, np.inf)
    reach = np.zeros((count, count), bool)  # reach[v, w]: w is in the region of v
    by_reach = np.argsort(near_border, kind="stable")
    for start in range(0, count, 256):
        nodes = by_reach[start : start + 256]
        bound = near_border[nodes]
        limit = float(bound.max()) if np.isfinite(bound).all() else np.inf
        # d(w, v) sums the path's steps in the other order than d(v, w), the click's
        # search, so a tie (steps under the graph's floor cost nothing) may come out an
        # ulp either way: ties stay with the border, as the click's search mostly has it.
        below = bound - _TIE * np.maximum(bound, 1.0)
        reach[:, nodes] = (dijkstra(matrix, indices=nodes, limit=limit) < below[:, None]).T
    for node in border:
        others = border[border != node]
        if not len(others):
            reach[node] = True  # the border is this superpixel alone: nothing is nearer it
            continue
        own_bound = dijkstra(matrix, indices=others, min_only=True)
        reach[node] = dijkstra(matrix, indices=[node], limit=float(own_bound.max()))[0] < own_bound
    reach[np.arange(count), np.arange(count)] = True
    keys: list[bytes] = []
    regions: dict[bytes, np.ndarray] = {}
    for node in range(count):
        key = np.packbits(reach[node]).tobytes()
        regions.setdefault(key, reach[node].copy())
        keys.append(key)
    return keys, regions


__all__ = ["FirstClickMap", "first_click_map"]
