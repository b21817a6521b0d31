"""The jalgorithm's eight terms and the weighted total's gradient in one numba call, and the
fit's Adam steps around it (:func:`descend`).

Mirrors :func:`jeanscv.fitting.loss.jalgorithm_terms` (the torch reference) for a shared
``(C, C)`` silhouette, in float64, with the same clamps and the same one-sided
derivatives at them (``clamp`` passes its gradient at the bound, ``abs`` has
derivative 0 at 0), so the two agree to rounding. Term order is
:data:`jeanscv.fitting.terms.TERM_NAMES`.

Stroke terms need, per canvas pixel, the alphas of every stroke touching it: each
stroke's band cells set their edge's bit in a pixel-indexed mask (cleared again after
the candidate), and a pixel that gets a second bit flags its row in its lowest
stroke's band. Only at such overlaps do strokes interact: the unions' excess and the
pair overlaps are sums over the flagged rows' overlaps (the other strokes' alphas read
from their bands), which are listed, and the gradient's corrections to the value a
lone stroke's cell has are made over that list. Everything costs O(band cells +
overlaps), not O(canvas).

One topic in about 830 lines: the kernels below call one another inside numba and are
compiled and cached together (numba's cache keys on this file), so they stay in one
module; the rasterizer they share lives in ``raster.py``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..terms import UPRIGHT_FREE_DEGREES, UPRIGHT_SATURATE_DEGREES
from .jit import njit
from .raster import (
    BAND_COLUMNS,
    OUTLINE_POINTS,
    band_rows,
    gather_edge,
    scatter_edge,
    stroke_band,
    stroke_band_backward,
)

_EPS = 1e-6


class Target(NamedTuple):
    """What the objective measures candidates against, and how (one per target and
    garment; the kernels read it, never write it)."""

    s: np.ndarray  # (C, C) float64, the silhouette
    s_rows: np.ndarray  # (C, C + 1) its prefix sums along rows
    half_width: float  # the strokes' half width, pixels of this canvas
    weights: np.ndarray  # (8,) term weights in TERM_NAMES order
    waist: np.ndarray  # (2,) int64, the waistband's vertices
    hems: np.ndarray  # (2,) int64, the outer hems' vertices
    residual: np.ndarray  # (N, N) the affine residual operator
    is_open: np.ndarray  # (N,) bool edge labels
    is_closed: np.ndarray  # (N,) bool
    pair: np.ndarray  # (N, N) bool, pair[i, j] for i < j when the pair counts in L_inter
    cos_r: np.ndarray  # the capsule cap offsets
    sin_r: np.ndarray


class Scratch(NamedTuple):
    """Work arrays of :func:`objective`, reused across calls so that no call pays for
    fresh pages; those marked "kept zero" (or false) must be so on entry and are left so."""

    mask: np.ndarray  # (C * C,) uint8/16 or int64, kept zero: the strokes at each pixel
    diff: np.ndarray  # (C, C + 2), kept zero
    touched: np.ndarray  # (C, C + 2) uint8, kept zero: the fill's cells touched by pieces
    listed: np.ndarray  # (C, C + 2) int64
    counts: np.ndarray  # (C,) int64, kept zero
    wind: np.ndarray  # (C, C)
    cell_grad: np.ndarray  # (C, C + 2)
    prefix: np.ndarray  # (C, C + 2)
    band_diff: np.ndarray  # (N, rows, 15), rows >= any band's (band_scratch_rows)
    band_wind: np.ndarray  # (N, rows, 13)
    overlap_pixel: np.ndarray  # (C * C,) int64: the overlaps' pixels
    overlap_bits: np.ndarray  # (C * C,) int64: their strokes
    overlap_alpha: np.ndarray  # (C * C, N): their alphas
    overlap_fits: np.ndarray  # (C * C, 2) bool: whether each union stays within 1 there
    overlap_rows: np.ndarray  # (N, rows) bool, kept false: the band rows holding overlaps


class Bands(NamedTuple):
    """Each edge's stroke band for one candidate (:func:`_stroke_bands` fills it): band
    cell ``(r, c)`` of edge ``e`` is canvas ``major = row_start[e] + r``, ``minor =
    col_start[e, r] + c``, x and y swapped when ``x_major[e]``."""

    row_start: np.ndarray  # (N,) int64
    col_start: np.ndarray  # (N, rows) int64
    count: np.ndarray  # (N,) int64, rows of each band
    lo: np.ndarray  # (N, rows) int64: the first column the stroke covers in each row
    hi: np.ndarray  # (N, rows) int64: one past the last
    x_major: np.ndarray  # (N,) bool


class Crossings(NamedTuple):
    """Where an edge crosses the grid lines (raster.cut_edge's work arrays)."""

    ts: np.ndarray  # float64, the crossings' parameters along the edge
    axes: np.ndarray  # int64, which grid lines
    lines: np.ndarray  # float64, which lines


def band_scratch_rows(size: int, half_width: float) -> int:
    """Rows enough for any stroke band on a ``size`` canvas: segments are clipped to
    the canvas plus ``half_width + 2`` and a band adds ``half_width`` and a row each side."""
    return size + 4 * int(math.ceil(half_width)) + 12


(CENTER, COVERAGE, RIGID, OPEN, CLOSED, INTER, INSIDE, UPRIGHT) = range(8)


@njit
def _upright(v, waist, hems, free, saturated, weight, grad, need_grad):
    """``upright`` (loss.upright_term) of one candidate; adds ``weight * d/dv`` to ``grad``."""
    wa, wb, ha, hb = waist[0], waist[1], hems[0], hems[1]
    down_x = (v[ha, 0] + v[hb, 0] - v[wa, 0] - v[wb, 0]) / 2
    down_y = (v[ha, 1] + v[hb, 1] - v[wa, 1] - v[wb, 1]) / 2
    across_x, across_y = v[wb, 0] - v[wa, 0], v[wb, 1] - v[wa, 1]
    down_norm = math.sqrt(down_x * down_x + down_y * down_y)
    across_norm = math.sqrt(across_x * across_x + across_y * across_y)
    down_den, across_den = max(down_norm, _EPS), max(across_norm, _EPS)
    down_cos = down_y / down_den
    level_cos = abs(across_x) / across_den
    raw = free - (down_cos + level_cos) / 2
    value = min(max(raw, 0.0), saturated)
    if not need_grad or weight == 0.0 or raw < 0.0 or raw > saturated:
        return value
    g = -weight / 2  # d value / d(down_cos) and d(level_cos)
    # down_cos = down_y / max(|down|, eps)
    gdx, gdy = 0.0, g / down_den
    if down_norm >= _EPS and down_norm > 0.0:
        scale = -g * down_y / (down_den * down_den * down_norm)
        gdx += scale * down_x
        gdy += scale * down_y
    # level_cos = |across_x| / max(|across|, eps)
    sign = 1.0 if across_x > 0 else (-1.0 if across_x < 0 else 0.0)
    gax, gay = g * sign / across_den, 0.0
    if across_norm >= _EPS and across_norm > 0.0:
        scale = -g * abs(across_x) / (across_den * across_den * across_norm)
        gax += scale * across_x
        gay += scale * across_y
    for vertex, factor in ((ha, 0.5), (hb, 0.5), (wa, -0.5), (wb, -0.5)):
        grad[vertex, 0] += factor * gdx
        grad[vertex, 1] += factor * gdy
    grad[wb, 0] += gax
    grad[wb, 1] += gay
    grad[wa, 0] -= gax
    grad[wa, 1] -= gay
    return value


@njit
def _whole(w: float) -> bool:
    """Whether a winding value is 0, 1 or beyond to rounding: cells between the pieces
    of a row that hold such a value have coverage 0 or 1 and (analytically) no
    gradient, so they are summed by span from row prefix sums of ``S``."""
    a = abs(w)
    return a <= 1e-12 or a >= 1.0 - 1e-12


@njit
def _sorted_cells(touched, listed, counts, r, cols):
    """Row ``r``'s touched cells and cell 0, in order, into ``listed[r]``; returns how many."""
    m = counts[r]
    if not touched[r, 0]:
        touched[r, 0] = 1
        listed[r, m] = 0
        m += 1
    if m <= 32:
        for i in range(1, m):  # insertion sort: a row holds a few pieces
            key = listed[r, i]
            j = i - 1
            while j >= 0 and listed[r, j] > key:
                listed[r, j + 1] = listed[r, j]
                j -= 1
            listed[r, j + 1] = key
    else:  # a near-horizontal edge: read the row's marks in order
        m = 0
        for c in range(cols):
            if touched[r, c]:
                listed[r, m] = c
                m += 1
    counts[r] = m
    return m


@njit
def _fill_terms(v, s, s_rows, s_total, w_cov, w_inside, grad, need_grad, scratch, col0, crossings):
    """``(coverage, inside)`` of one candidate; adds their weighted gradient to ``grad``.

    ``s_rows``: ``(C, C + 1)`` prefix sums of ``S`` along rows. Work is O(pieces + rows
    of the bounding box): the pieces list the cells they touch (``touched``, ``listed``,
    ``counts``; :func:`raster.scatter_edge`), and the cells between two listed ones hold
    the same winding: where it is 0 or 1 they take the run's sums, with no gradient.
    ``scratch.diff``, ``.touched`` and ``.counts`` are all zero before and after.
    """
    touched, listed, counts = scratch.touched, scratch.listed, scratch.counts
    size = s.shape[0]
    n = v.shape[0]
    y_lo, y_hi, x_lo, x_hi = math.inf, -math.inf, math.inf, -math.inf
    for i in range(n):
        x_lo, x_hi = min(x_lo, v[i, 0]), max(x_hi, v[i, 0])
        y_lo, y_hi = min(y_lo, v[i, 1]), max(y_hi, v[i, 1])
    oy = int(max(math.floor(max(y_lo, -1.0)), 0.0))
    ox = int(max(math.floor(max(x_lo, -1.0)), 0.0))
    rows = int(min(math.floor(min(y_hi, size + 1.0)) + 1.0, size)) - oy
    cols = int(min(math.floor(min(x_hi, size + 1.0)) + 1.0, size)) - ox
    rows, cols = max(rows, 0), max(cols, 0)
    area = not_on_body = uncovered_in = s_window = 0.0
    if rows and cols:
        area, not_on_body, uncovered_in, s_window = _fill_sums(
            v, s, s_rows, oy, ox, rows, cols, scratch, col0, crossings
        )
    total = max(s_total, _EPS)
    uncovered = (s_total - s_window) + uncovered_in
    coverage = (0.5 - uncovered / total) ** 2
    area_den = max(area, _EPS)
    inside = not_on_body / area_den
    if not need_grad or not rows or not cols or (w_cov == 0.0 and w_inside == 0.0):
        for r in range(rows if cols else 0):
            for i in range(counts[r]):
                touched[r, listed[r, i]] = 0
            counts[r] = 0
        return coverage, inside
    d_uncovered = w_cov * -2.0 * (0.5 - uncovered / total) / total
    d_area = -w_inside * not_on_body / (area_den * area_den) if area >= _EPS else 0.0
    _fill_gradient(v, s, oy, ox, rows, cols, d_uncovered, d_area, w_inside / area_den, grad, scratch, col0, crossings)
    return coverage, inside


@njit
def _fill_sums(v, s, s_rows, oy, ox, rows, cols, scratch, col0, crossings):
    """The polygon's pieces scattered on its ``rows x cols`` window at ``(ox, oy)`` and
    summed along each row: ``(area, not_on_body, uncovered_in, s_window)``, the sums of
    the fill terms inside the window; each listed cell's winding kept in ``scratch.wind``."""
    diff, touched, listed, counts, wind = scratch.diff, scratch.touched, scratch.listed, scratch.counts, scratch.wind
    ts, axes, lines = crossings
    size = s.shape[0]
    n = v.shape[0]
    area = not_on_body = uncovered_in = s_window = 0.0
    for r in range(rows):
        col0[r] = ox
    cells = (touched, listed, counts)
    for i in range(n):
        j = (i + 1) % n
        scatter_edge(
            v[i, 0], v[i, 1], v[j, 0], v[j, 1], 0.0, float(size), 0.0, float(size), oy, col0, rows, cols, diff,
            ts, axes, lines, cells,
        )  # fmt: skip
    for r in range(rows):
        y = oy + r
        s_window += s_rows[y, ox + cols] - s_rows[y, ox]
        acc = 0.0
        m = _sorted_cells(touched, listed, counts, r, cols)
        for i in range(m):
            c = listed[r, i]
            acc += diff[r, c]
            diff[r, c] = 0.0
            end = listed[r, i + 1] if i + 1 < m else cols
            f = min(abs(acc), 1.0)
            last = end
            if end - c > 1 and _whole(acc):
                # the cells after the first hold f each, with no gradient
                run = end - c - 1
                run_s = s_rows[y, ox + end] - s_rows[y, ox + c + 1]
                area += f * run
                if f >= 0.5:
                    not_on_body += f * run - run_s
                else:
                    uncovered_in += run_s - f * run
                last = c + 1
            wind[r, c] = acc  # (the cells up to the next listed one hold the same)
            for cell in range(c, last):
                sv = s[y, ox + cell]
                area += f
                if f > sv:
                    not_on_body += f - sv
                else:
                    uncovered_in += sv - f
        diff[r, cols] = diff[r, cols + 1] = 0.0  # pieces right of the window
    return area, not_on_body, uncovered_in, s_window


@njit
def _fill_gradient(v, s, oy, ox, rows, cols, d_uncovered, d_area, d_not_on_body, grad, scratch, col0, crossings):
    """Adds the fill terms' gradient to ``grad``: dL/dW per listed cell and its prefix
    sums along the row, gathered back along the pieces of each edge; clears the lists."""
    touched, listed, counts, wind = scratch.touched, scratch.listed, scratch.counts, scratch.wind
    cell_grad, prefix = scratch.cell_grad, scratch.prefix
    ts, axes, lines = crossings
    size = s.shape[0]
    n = v.shape[0]
    for r in range(rows):
        # dL/dW and its prefix sums, written where pieces read them: the listed cells
        running = 0.0
        m = counts[r]
        for i in range(m):
            c = listed[r, i]
            touched[r, c] = 0
            w = wind[r, c]
            end = listed[r, i + 1] if i + 1 < m else cols
            prefix[r, c] = running
            cell_grad[r, c] = 0.0
            if w == 0.0 or abs(w) > 1.0:
                continue
            f = abs(w)
            # a run after a fractional cell: each cell has a gradient (no piece reads it)
            last = c + 1 if end - c > 1 and _whole(w) else end
            for cell in range(c, last):
                sv = s[oy + r, ox + cell]
                g = d_area
                if sv - f >= 0.0:
                    g -= d_uncovered
                if f - sv >= 0.0:
                    g += d_not_on_body
                g = g if w > 0 else -g
                if cell == c:
                    cell_grad[r, c] = g
                running += g
        counts[r] = 0
        prefix[r, cols] = running
    g4 = np.zeros(4)
    for i in range(n):
        j = (i + 1) % n
        g4[0] = g4[1] = g4[2] = g4[3] = 0.0
        gather_edge(
            v[i, 0], v[i, 1], v[j, 0], v[j, 1], 0.0, float(size), 0.0, float(size), oy, col0, rows, cols, cell_grad,
            prefix, ts, axes, lines, g4,
        )  # fmt: skip
        grad[i, 0] += g4[0] - g4[2]
        grad[i, 1] += g4[1] - g4[3]
        grad[j, 0] += g4[2]
        grad[j, 1] += g4[3]


@njit
def _pixel(row_start, row_col_start, x_major, r, c):
    """Canvas ``(x, y)`` of band cell ``(r, c)``; ``row_col_start``: the row's first column."""
    major, minor = row_start + r, row_col_start + c
    return (major, minor) if x_major else (minor, major)


@njit
def _band_alpha(band_wind, bands, k, x, y):
    """Stroke ``k``'s alpha at canvas pixel ``(x, y)``, read from its band."""
    major, minor = (x, y) if bands.x_major[k] else (y, x)
    r = major - bands.row_start[k]
    if r < 0 or r >= bands.count[k]:
        return 0.0
    c = minor - bands.col_start[k, r]
    if c < 0 or c >= BAND_COLUMNS:
        return 0.0
    return min(abs(band_wind[k, r, c]), 1.0)


@njit
def objective(vertices, target, need_grad, totals, terms, grad, scratch):
    """All eight terms of each candidate and the gradient of the weighted total.

    Args:
        vertices: ``(B, N, 2)`` canvas pixels of the ``(C, C)`` silhouette ``target.s``.
        target: a :class:`Target`; need_grad: compute ``grad``.
        totals: ``(B,)`` out, the weighted totals (:func:`weighted_totals`); terms: ``(B, 8)``
            out; grad: ``(B, N, 2)`` out, d(weighted total)/d vertices.
        scratch: a :class:`Scratch` for this canvas and garment.

    Per candidate, in phases: the shape terms (:func:`_shape_terms`), the fill terms
    (:func:`_fill_terms`), the strokes on their bands (:func:`_stroke_bands`), their
    overlaps (:func:`_overlap_sums`), the stroke terms, and the strokes' gradient
    (:func:`_stroke_gradient`).
    """
    s, s_rows, half_width, weights = target.s, target.s_rows, target.half_width, target.weights
    batch, n = vertices.shape[0], vertices.shape[1]
    size = s.shape[0]
    s_total = 0.0
    for y in range(size):
        s_total += s_rows[y, size]
    margin = half_width + 2.0
    low, high = -margin, size + margin
    finite = np.ones(batch, np.bool_)
    rows_limit = _rows_limit(vertices, half_width, low, high, finite)

    crossings = 4 * (size + 4 * int(margin) + 16)
    cuts = Crossings(np.empty(crossings), np.empty(crossings, np.int64), np.empty(crossings))
    col0 = np.empty(max(size, rows_limit), np.int64)
    band_prefix = np.empty((rows_limit, BAND_COLUMNS + 1))
    bands = Bands(
        np.empty(n, np.int64),
        np.empty((n, rows_limit), np.int64),
        np.empty(n, np.int64),
        np.empty((n, rows_limit), np.int64),
        np.empty((n, rows_limit), np.int64),
        np.empty(n, np.bool_),
    )
    labels = np.empty((2, n), np.bool_)  # the open edges, the closed edges (one array: no views in loops)
    for e in range(n):
        labels[0, e], labels[1, e] = target.is_open[e], target.is_closed[e]
    outline = np.empty((OUTLINE_POINTS, 2))
    g_outline = np.empty((OUTLINE_POINTS, 2))
    areas = np.empty(n)
    on_body = np.empty(n)
    overlap = np.empty((n, n))
    pair_excess = np.empty((n, n))

    for b in range(batch):
        v = vertices[b]
        g_v = grad[b]
        for i in range(n):
            g_v[i, 0] = g_v[i, 1] = 0.0
        if not finite[b]:
            for k in range(terms.shape[1]):
                terms[b, k] = np.nan
            continue
        _shape_terms(v, target, need_grad, terms[b], g_v)
        coverage, inside = _fill_terms(
            v, s, s_rows, s_total, weights[COVERAGE], weights[INSIDE], g_v, need_grad, scratch, col0, cuts
        )
        terms[b, COVERAGE] = coverage
        terms[b, INSIDE] = inside

        _stroke_bands(v, target, scratch, low, high, rows_limit, bands, outline, areas, on_body, cuts)
        # unions of the open and the closed edges: excess where their strokes stack past 1
        union = np.zeros((2, 4))  # per union: on-body sum, area, excess, excess on body
        overlaps = _overlap_sums(target, scratch, bands, labels, union, overlap, pair_excess)
        for e in range(n):
            for u in range(2):
                if labels[u, e]:
                    union[u, 0] += on_body[e]
                    union[u, 1] += areas[e]
        union_den = np.empty(2)
        for u in range(2):
            raw = union[u, 1] - union[u, 2]
            union_den[u] = max(raw, _EPS)
        terms[b, OPEN] = -((union[0, 0] - union[0, 3]) / union_den[0])
        terms[b, CLOSED] = (union[1, 0] - union[1, 3]) / union_den[1]
        inter = 0.0
        for e in range(n):
            for k in range(e + 1, n):
                if target.pair[e, k]:
                    inter += overlap[e, k] / max(areas[e] + areas[k] - pair_excess[e, k], _EPS)
        terms[b, INTER] = inter

        if not (need_grad and (weights[OPEN] != 0.0 or weights[CLOSED] != 0.0 or weights[INTER] != 0.0)):
            _clear_mask(scratch.mask, size, bands)
            continue
        _stroke_gradient(
            v, target, scratch, low, high, overlaps, union, union_den, areas, overlap, pair_excess, labels, bands,
            outline, g_outline, band_prefix, cuts, g_v,
        )  # fmt: skip
    weighted_totals(terms, weights, totals)


@njit
def _rows_limit(vertices, half_width, low, high, finite):
    """Rows enough for every stroke band of the candidates with finite vertices; marks
    the others false in ``finite``."""
    batch, n = vertices.shape[0], vertices.shape[1]
    rows_limit = np.int64(1)  # not a literal 1: numba would compile stroke_band for it
    for b in range(batch):
        for i in range(n):
            if not (math.isfinite(vertices[b, i, 0]) and math.isfinite(vertices[b, i, 1])):
                finite[b] = False
        if finite[b]:
            for i in range(n):
                j = (i + 1) % n
                rows_limit = max(
                    rows_limit,
                    band_rows(
                        vertices[b, i, 0],
                        vertices[b, i, 1],
                        vertices[b, j, 0],
                        vertices[b, j, 1],
                        half_width,
                        low,
                        high,
                    ),
                )
    return rows_limit


@njit
def _shape_terms(v, target, need_grad, terms, g_v):
    """``center``, ``rigid`` and ``upright`` of one candidate into ``terms`` ``(8,)``;
    adds their weighted gradient to ``g_v``."""
    n = v.shape[0]
    size = target.s.shape[0]
    waist, weights, residual = target.waist, target.weights, target.residual
    # center and rigid, on normalised coordinates
    wx = (v[waist[0], 0] + v[waist[1], 0]) / size / 2
    wy = (v[waist[0], 1] + v[waist[1], 1]) / size / 2
    terms[CENTER] = (wx - 0.5) ** 2 + (wy - 0.5) ** 2
    rigid = 0.0
    res = np.zeros((n, 2))
    for i in range(n):
        for k in range(n):
            res[i, 0] += residual[i, k] * (v[k, 0] / size)
            res[i, 1] += residual[i, k] * (v[k, 1] / size)
        rigid += res[i, 0] ** 2 + res[i, 1] ** 2
    terms[RIGID] = rigid
    if need_grad:
        for k in range(2):
            g_v[waist[k], 0] += weights[CENTER] * (wx - 0.5) / size
            g_v[waist[k], 1] += weights[CENTER] * (wy - 0.5) / size
        if weights[RIGID] != 0.0:
            for k in range(n):
                for i in range(n):
                    g_v[k, 0] += weights[RIGID] * 2.0 * residual[i, k] * res[i, 0] / size
                    g_v[k, 1] += weights[RIGID] * 2.0 * residual[i, k] * res[i, 1] / size
    free = math.cos(math.radians(UPRIGHT_FREE_DEGREES))
    saturated = free - math.cos(math.radians(UPRIGHT_SATURATE_DEGREES))
    terms[UPRIGHT] = _upright(v, waist, target.hems, free, saturated, weights[UPRIGHT], g_v, need_grad)


@njit
def _stroke_bands(v, target, scratch, low, high, rows_limit, bands, outline, areas, on_body, crossings):
    """Every edge's stroke on its band (alphas in ``scratch.band_wind``, each stroke's
    area and on-body sum), and each stroke's bit in the pixel mask; a pixel that a second
    stroke reaches flags its row in ``scratch.overlap_rows``: overlaps are the only pixels
    where the strokes interact."""
    n = v.shape[0]
    s, mask, band_diff, band_wind = target.s, scratch.mask, scratch.band_diff, scratch.band_wind
    row_start, col_start, band_count, band_lo, band_hi, x_major = bands
    ts, axes, lines = crossings
    size = s.shape[0]
    for e in range(n):
        f = (e + 1) % n
        row_start[e], band_count[e], x_major[e], empty = stroke_band(
            v[e, 0], v[e, 1], v[f, 0], v[f, 1], target.half_width, low, high, rows_limit, target.cos_r, target.sin_r,
            outline, col_start[e], band_diff[e], ts, axes, lines,
        )  # fmt: skip
        bit = mask.dtype.type(1 << e)
        areas[e] = on_body[e] = 0.0
        along_x = x_major[e]
        for r in range(band_count[e]):
            acc = 0.0
            lo, hi = BAND_COLUMNS, 0
            major, start = row_start[e] + r, col_start[e, r]
            # the row's cells on the canvas; the others hold 0
            first = max(-start, 0) if 0 <= major < size else BAND_COLUMNS
            stop = min(size - start, BAND_COLUMNS)
            for c in range(BAND_COLUMNS):
                acc += band_diff[e, r, c]
                if c < first or c >= stop or acc == 0.0:
                    band_wind[e, r, c] = 0.0
                    continue
                band_wind[e, r, c] = acc
                alpha = min(abs(acc), 1.0)
                x, y = (major, start + c) if along_x else (start + c, major)
                lo, hi = min(lo, c), c + 1
                p = y * size + x
                areas[e] += alpha
                on_body[e] += alpha * s[y, x]
                old = mask[p]
                if old != 0 and old & (old - 1) == 0:
                    # a new overlap: its row in the band of its lowest stroke
                    lowest = 0
                    while not (old >> lowest) & 1:
                        lowest += 1
                    scratch.overlap_rows[lowest, (x if x_major[lowest] else y) - row_start[lowest]] = True
                mask[p] = old | bit
            band_lo[e, r], band_hi[e, r] = lo, hi  # later passes visit only the stroke's cells


@njit
def _overlap_sums(target, scratch, bands, labels, union, overlap, pair_excess):
    """The overlaps' pixels, strokes and alphas listed in ``scratch``; the unions' excess
    into ``union[:, 2:]`` and each counted pair's overlap and excess. Returns how many."""
    row_start, col_start, band_count, band_lo, band_hi, x_major = bands
    n = row_start.shape[0]
    s, pair, mask, band_wind = target.s, target.pair, scratch.mask, scratch.band_wind
    size = s.shape[0]
    present = np.empty(n, np.int64)  # the strokes at one pixel
    for e in range(n):
        for k in range(n):
            overlap[e, k] = pair_excess[e, k] = 0.0
    # (visited in band order of each pixel's lowest stroke, row by row: the same order
    # of sums whichever rows hold overlaps)
    overlaps = 0
    for e in range(n):
        for r in range(band_count[e]):
            if not scratch.overlap_rows[e, r]:
                continue
            scratch.overlap_rows[e, r] = False
            for c in range(band_lo[e, r], band_hi[e, r]):
                if band_wind[e, r, c] == 0.0:
                    continue
                x, y = _pixel(row_start[e], col_start[e, r], x_major[e], r, c)
                p = y * size + x
                bits = mask[p]
                if bits & (bits - 1) == 0 or bits & ((1 << e) - 1):
                    continue  # one stroke only, or counted at a lower stroke
                q = overlaps
                overlaps += 1
                scratch.overlap_pixel[q] = p
                scratch.overlap_bits[q] = bits
                here = scratch.overlap_alpha[q]
                # the strokes present, in order (sums over them skip only zeros)
                count = 0
                for k in range(n):
                    if (bits >> k) & 1:
                        present[count] = k
                        count += 1
                    here[k] = _band_alpha(band_wind, bands, k, x, y) if (bits >> k) & 1 else 0.0
                for u in range(2):
                    stacked = 0.0
                    for a in range(count):
                        if labels[u, present[a]]:
                            stacked += here[present[a]]
                    scratch.overlap_fits[q, u] = stacked <= 1.0
                    if stacked > 1.0:
                        union[u, 2] += stacked - 1.0
                        union[u, 3] += (stacked - 1.0) * s[y, x]
                for a in range(count):
                    i = present[a]
                    if here[i] == 0.0:
                        continue
                    for b2 in range(a + 1, count):
                        k = present[b2]
                        if pair[i, k] and here[k] != 0.0:
                            overlap[i, k] += here[i] * here[k]
                            pair_excess[i, k] += max(here[i] + here[k] - 1.0, 0.0)
    return overlaps


@njit
def _stroke_gradient(
    v, target, scratch, low, high, overlaps, union, union_den, areas, overlap, pair_excess, labels, bands,
    outline, g_outline, band_prefix, crossings, g_v,
):  # fmt: skip
    """Adds the gradient of the weighted stroke terms (open, closed, inter) to ``g_v``,
    clearing the pixel mask on the way."""
    n = v.shape[0]
    s, pair, weights = target.s, target.pair, target.weights
    mask, band_diff, band_wind = scratch.mask, scratch.band_diff, scratch.band_wind
    row_start, col_start, band_count, band_lo, band_hi, x_major = bands
    ts, axes, lines = crossings
    size = s.shape[0]
    # d total / d alpha = per-edge constant + per-pixel parts
    union_weight = np.array([-weights[OPEN], weights[CLOSED]])
    union_d_den = np.empty(2)
    for u in range(2):
        raw = union[u, 1] - union[u, 2]
        union_d_den[u] = -(union[u, 0] - union[u, 3]) / union_den[u] ** 2 if raw >= _EPS else 0.0
    base = np.zeros(n)
    pair_d_den = np.zeros((n, n))
    pair_den = np.ones((n, n))
    for e in range(n):
        for k in range(e + 1, n):
            if pair[e, k]:
                raw = areas[e] + areas[k] - pair_excess[e, k]
                pair_den[e, k] = max(raw, _EPS)
                if raw >= _EPS:
                    pair_d_den[e, k] = -weights[INTER] * overlap[e, k] / pair_den[e, k] ** 2
                base[e] += pair_d_den[e, k]
                base[k] += pair_d_den[e, k]
    # every cell as if its stroke were alone there (the band's difference buffer,
    # spent, holds dL/dW), clearing the pixel mask on the way ...
    for e in range(n):
        # d total / d alpha at a pixel no other stroke touches: lone + lone_s * S
        lone, lone_s = base[e], 0.0
        for u in range(2):
            if labels[u, e] and union_weight[u] != 0.0:
                lone += union_weight[u] * union_d_den[u]
                lone_s += union_weight[u] / union_den[u]
        for r in range(band_count[e]):
            for c in range(BAND_COLUMNS + 2):
                band_diff[e, r, c] = 0.0
            for c in range(band_lo[e, r], band_hi[e, r]):
                w = band_wind[e, r, c]
                if w == 0.0:
                    continue
                x, y = _pixel(row_start[e], col_start[e, r], x_major[e], r, c)
                mask[y * size + x] = 0
                if abs(w) > 1.0:
                    continue
                band_diff[e, r, c] = lone + lone_s * s[y, x] if w > 0 else -(lone + lone_s * s[y, x])
    # ... then the overlaps' own values
    _overlap_values(
        target, scratch, overlaps, bands, labels, base, union_weight, union_d_den, union_den, pair_den, pair_d_den
    )
    for e in range(n):
        f = (e + 1) % n
        gpx, gpy, gqx, gqy = stroke_band_backward(
            v[e, 0], v[e, 1], v[f, 0], v[f, 1], target.half_width, low, high, row_start[e], band_count[e],
            target.cos_r, target.sin_r, outline, g_outline, col_start[e], band_diff[e], band_prefix, ts, axes, lines,
        )  # fmt: skip
        g_v[e, 0] += gpx
        g_v[e, 1] += gpy
        g_v[f, 0] += gqx
        g_v[f, 1] += gqy


@njit
def _overlap_values(
    target, scratch, overlaps, bands, labels, base, union_weight, union_d_den, union_den, pair_den, pair_d_den
):
    """dL/dW at each overlap's cells of every stroke there, into the bands' spent
    difference buffers (``scratch.band_diff``), where a lone stroke's value was written."""
    row_start, col_start, x_major = bands.row_start, bands.col_start, bands.x_major
    n = row_start.shape[0]
    s, pair, weights = target.s, target.pair, target.weights
    band_diff, band_wind = scratch.band_diff, scratch.band_wind
    size = s.shape[0]
    for q in range(overlaps):
        p = scratch.overlap_pixel[q]
        y, x = p // size, p % size
        bits = scratch.overlap_bits[q]
        for e in range(n):
            if not (bits >> e) & 1:
                continue
            major, minor = (x, y) if x_major[e] else (y, x)
            r = major - row_start[e]
            c = minor - col_start[e, r]
            w = band_wind[e, r, c]
            if abs(w) > 1.0:
                continue
            alpha = abs(w)
            g = base[e]
            for u in range(2):
                if labels[u, e] and union_weight[u] != 0.0 and scratch.overlap_fits[q, u]:
                    g += union_weight[u] * union_d_den[u] + union_weight[u] / union_den[u] * s[y, x]
            for k in range(n):
                if k == e or not (bits >> k) & 1:
                    continue
                i, j = min(e, k), max(e, k)
                if not pair[i, j]:
                    continue
                other = scratch.overlap_alpha[q, k]
                g += weights[INTER] * other / pair_den[i, j]
                if alpha + other - 1.0 >= 0.0:
                    g -= pair_d_den[i, j]
            band_diff[e, r, c] = g if w > 0 else -g


@njit
def weighted_totals(terms, weights, totals):
    """``totals[b]``: the sum of the terms of non-zero weight times their weights, added
    in term order as loss.weighted_total adds them."""
    for b in range(terms.shape[0]):
        total = 0.0
        for k in range(terms.shape[1]):
            if weights[k] != 0.0:
                total += weights[k] * terms[b, k]
        totals[b] = total


@njit
def _clear_mask(mask, size, bands):
    """Zero the pixel mask where the candidate's strokes set it."""
    row_start, col_start, band_count, band_lo, band_hi, x_major = bands
    n = row_start.shape[0]
    for e in range(n):
        for r in range(band_count[e]):
            for c in range(band_lo[e, r], band_hi[e, r]):
                x, y = _pixel(row_start[e], col_start[e, r], x_major[e], r, c)
                if 0 <= x < size and 0 <= y < size:
                    mask[y * size + x] = 0


# ----------------------------------------------------------------------------- the fit's steps
#
# In this file, not its own: numba's cache of a function is refreshed when its own file
# changes, and the step loop's compiled code holds the objective's.


@njit
def adam_step(params, grad, exp_avg, exp_avg_sq, beta1, beta2, step_size, bias2, eps):
    """:func:`jeanscv.fitting.adam.adam_update` element by element, for ``(B, N, 2)`` arrays: the
    same operations in the same order, so the same bits (tests/test_fast.py), without
    numba's array expressions, which take seconds to compile."""
    keep1, keep2 = 1 - beta1, 1 - beta2
    for b in range(params.shape[0]):
        for i in range(params.shape[1]):
            for j in range(params.shape[2]):
                g = grad[b, i, j]
                m = exp_avg[b, i, j] * beta1
                m += keep1 * g
                v = exp_avg_sq[b, i, j] * beta2
                v += keep2 * g * g
                exp_avg[b, i, j] = m
                exp_avg_sq[b, i, j] = v
                params[b, i, j] -= step_size * (m / (math.sqrt(v / bias2) + eps))


@njit
def descend(params, exp_avg, exp_avg_sq, step_sizes, bias2, beta1, beta2, eps, target, totals, path, scratch):
    """The fit's Adam steps on one target in one call: a step crosses into Python once per
    stretch of steps on the same target instead of a dozen times (about 0.1 ms a step, a
    tenth of a default fit). Adam steps on normalised ``params`` ``(B, N, 2)`` (and its
    moments, in place) by :func:`jeanscv.fitting.adam.adam_update`, one per
    entry of ``step_sizes`` and ``bias2`` (the step's ``lr / (1 - beta1^t)`` and ``1 - beta2^t``).

    Each step evaluates :func:`objective` at ``params * C`` on the ``(C, C)``
    target ``s``, zeroes the gradient of diverged starts and of non-finite components
    (as the fitter does), and updates. Writes the totals ``(steps, B)`` and the params
    after each step ``(steps, B, N, 2)``; returns the number of steps done, fewer when
    every start diverged (that step's totals written, no update made).
    """
    size = float(target.s.shape[0])
    batch = params.shape[0]
    pixels = np.empty(params.shape)
    grad = np.empty(params.shape)
    terms = np.empty((batch, target.weights.shape[0]))
    # A run-time True: a literal one would compile a second objective beside the one
    # that Python calls (numba specialises on literal arguments).
    need_grad = step_sizes.shape[0] > 0
    for k in range(step_sizes.shape[0]):
        for b in range(batch):
            for i in range(params.shape[1]):
                for j in range(2):
                    pixels[b, i, j] = params[b, i, j] * size
        objective(pixels, target, need_grad, totals[k], terms, grad, scratch)
        any_finite = False
        for b in range(batch):
            finite = math.isfinite(totals[k, b])
            any_finite = any_finite or finite
            for i in range(grad.shape[1]):
                for j in range(2):
                    g = grad[b, i, j] * size if finite else 0.0
                    grad[b, i, j] = g if math.isfinite(g) else 0.0
        if not any_finite:
            return k
        adam_step(params, grad, exp_avg, exp_avg_sq, beta1, beta2, step_sizes[k], bias2[k], eps)
        for b in range(batch):
            for i in range(params.shape[1]):
                for j in range(2):
                    path[k, b, i, j] = params[b, i, j]
    return step_sizes.shape[0]
