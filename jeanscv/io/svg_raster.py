"""Filling an SVG's shapes on the canvas: the exact nonzero / evenodd rule at
``supersample**2`` sample points per pixel by a vectorised scanline (crossings of every
edge with every sample row, accumulated with ``bincount`` + ``cumsum``), box-averaged.
Part of :mod:`jeanscv.io.svg`, which reads whole documents.
"""

from __future__ import annotations

import numpy as np

from jeanscv.errors import JeansError

from .svg_path import FLATTEN_TOLERANCE, MAX_SEGMENTS, _flatten

_MAX_COORD = 1e9  # canvas px; keeps sample-index arithmetic far from overflow
_CROSSING_BUDGET = 1_000_000  # scanline crossings per chunk: bounds memory (~100 MB)
_BAND_PIXELS = 32  # canvas rows rasterised together


class _Shape:
    """One filled element: its outline in user units and its user-to-canvas map."""

    def __init__(self, cubics: np.ndarray, sub: np.ndarray, ctm: np.ndarray, evenodd: bool):
        self.cubics = cubics  # (n, 4, 2) user units
        self.sub = sub  # (n,) subpath ids
        self.ctm = ctm  # (3, 3) user units -> canvas px
        self.evenodd = evenodd


class _Edges:
    """Non-horizontal edges in sample units, ready for the scanline.

    Sample ``(col, row)`` sits at canvas point ``((col + .5) / s, (row + .5) / s)``;
    an edge crosses sample rows ``j0 <= row < j1`` (half-open in y, so a vertex shared
    by two edges is counted once and an extremum twice with opposite signs).
    """

    def __init__(self, a: np.ndarray, b: np.ndarray, s: int, evenodd: bool):
        flip = b[:, 1] < a[:, 1]
        top = np.where(flip[:, None], b, a) * s - 0.5  # in sample index coordinates
        bottom = np.where(flip[:, None], a, b) * s - 0.5
        j0 = np.ceil(top[:, 1])
        j1 = np.ceil(bottom[:, 1])
        keep = j1 > j0
        self.x = top[keep, 0]
        self.y = top[keep, 1]
        self.dxdy = (bottom[keep, 0] - top[keep, 0]) / (bottom[keep, 1] - top[keep, 1])
        self.dir = np.where(flip[keep], -1.0, 1.0)
        self.j0 = j0[keep].astype(np.int64)
        self.j1 = j1[keep].astype(np.int64)
        self.evenodd = evenodd
        if len(self.x):
            self.rows = (int(self.j0.min()), int(self.j1.max()))
            xs = np.concatenate([top[keep, 0], bottom[keep, 0]])
            self.cols = (int(np.floor(xs.min())) + 1, int(np.floor(xs.max())) + 1)
        else:
            self.rows = self.cols = (0, 0)

    def inside(self, r0: int, r1: int, c0: int, c1: int) -> np.ndarray:
        """``(r1 - r0, c1 - c0)`` bool: which samples the fill rule puts inside."""
        live = (self.j0 < r1) & (self.j1 > r0)
        j0 = np.maximum(self.j0[live], r0)
        counts = np.minimum(self.j1[live], r1) - j0
        total = int(counts.sum())
        if total > _CROSSING_BUDGET and r1 - r0 > 1:
            mid = (r0 + r1) // 2
            return np.vstack([self.inside(r0, mid, c0, c1), self.inside(mid, r1, c0, c1)])
        width = c1 - c0
        edge = np.repeat(np.flatnonzero(live), counts)
        row = np.repeat(j0 - np.cumsum(counts) + counts, counts) + np.arange(total)
        x = self.x[edge] + (row - self.y[edge]) * self.dxdy[edge]
        # a crossing at x flips every sample strictly to its right: cols > x
        col = np.clip(np.floor(np.clip(x, c0 - 2, c1 + 2)).astype(np.int64) + 1 - c0, 0, width)
        acc = np.bincount((row - r0) * (width + 1) + col, weights=self.dir[edge], minlength=(r1 - r0) * (width + 1))
        winding = np.cumsum(acc.reshape(r1 - r0, width + 1)[:, :width], axis=1)
        if self.evenodd:
            return np.remainder(winding, 2) != 0
        return winding != 0


def _rasterize_shapes(shapes: list[_Shape], canvas_size: int, s: int) -> np.ndarray:
    """Union coverage of the shapes: ``(canvas_size, canvas_size)`` float32 in [0, 1]."""
    size = canvas_size * s
    edge_sets = []
    total = 0
    for shape in shapes:
        canvas = shape.cubics @ shape.ctm[:2, :2].T + shape.ctm[:2, 2]
        if not np.all(np.abs(canvas) < _MAX_COORD):  # also catches inf and nan
            raise JeansError("path coordinates are too large (beyond 1e9 canvas px)")
        a, b, piece_sub = _flatten(canvas, shape.sub, FLATTEN_TOLERANCE, canvas_size)
        total += len(a)
        if total > MAX_SEGMENTS:
            raise JeansError(f"path is too complex: over {MAX_SEGMENTS} segments after flattening")
        # implicit close of every subpath: its last point back to its first
        last = np.flatnonzero(np.diff(np.append(piece_sub, -1)) != 0)
        first = np.concatenate([[0], last[:-1] + 1])
        closing_a, closing_b = b[last], a[first]
        edge_sets.append(_Edges(np.concatenate([a, closing_a]), np.concatenate([b, closing_b]), s, shape.evenodd))

    alpha = np.zeros((canvas_size, canvas_size), dtype=np.float32)
    band = _BAND_PIXELS * s
    for r0 in range(0, size, band):
        r1 = min(size, r0 + band)
        mask = None
        for edges in edge_sets:
            if edges.rows[1] <= r0 or edges.rows[0] >= r1:
                continue
            c0, c1 = max(edges.cols[0], 0), min(edges.cols[1], size)
            if c1 <= c0:
                continue
            if mask is None:
                mask = np.zeros((r1 - r0, size), dtype=bool)
            mask[:, c0:c1] |= edges.inside(r0, r1, c0, c1)
        if mask is not None:
            blocks = mask.reshape((r1 - r0) // s, s, canvas_size, s)
            alpha[r0 // s : r1 // s] = blocks.sum(axis=(1, 3), dtype=np.int32) / np.float32(s * s)
    return alpha
