"""Numba kernels of the exact box-filtered rasterizer, with hand-written gradients.

The same scanline as :mod:`jeanscv.fitting.render` (the torch reference), step for step:
every directed edge is cut where it crosses the pixel grid; a piece with midpoint
``x_mid`` and signed height ``w`` in cell ``(row, col)`` adds ``clamp(x_mid - col,
0, 1) * w`` to its cell and ``w`` to every cell left of it in the row; coverage is
``min(|W|, 1)``. Strokes are capsule polygons (8-segment caps whose area equals the
true capsule's) rasterized on 13-cell bands along the segment's major axis.

Backward passes re-enumerate the same pieces: with ``G`` = dL/dW per cell and ``P``
its prefix sums along each row, a piece receives ``dL/dw = P[col] + G[col] *
clamp(x_mid - col, 0, 1)`` and ``dL/dx_mid = G[col] * w``, which flow to the piece's
end parameters ``t`` (grid-line crossings ``t = (line - a) / d``) and on to the edge's
endpoints. Everything is float64.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import njit

#: Cells across a stroke band, and how many lie left of the centre line (as render.py).
BAND_COLUMNS = 13
BAND_LEFT = 6
#: Points of a capsule outline: two 8-segment caps of 9 points each.
OUTLINE_POINTS = 18
_NO_AXIS = 2  # a piece end that is an edge endpoint (t = 0 or 1), not a grid crossing


@njit
def _safe(span: float) -> float:
    """The reference's stand-in divisor for spans so tiny that 1/span would overflow."""
    if abs(span) >= 1e-12:
        return span
    return -1e-12 if span < 0 else 1e-12


@njit
def cut_edge(ax, ay, bx, by, lox, hix, loy, hiy, ts, axes, lines) -> int:
    """Grid crossings of the edge ``a -> b``, sorted by ``t``, endpoints included.

    Only lines within ``[lox, hix]`` (x) and ``[loy, hiy]`` (y) are used. Fills
    ``ts``, ``axes`` (0: x line, 1: y line, 2: endpoint) and ``lines``; returns the
    count. Consecutive entries bound the edge's pieces.
    """
    dx, dy = bx - ax, by - ay
    fx = max(math.floor(min(ax, bx)) + 1.0, lox)
    lx = min(math.ceil(max(ax, bx)) - 1.0, hix)
    fy = max(math.floor(min(ay, by)) + 1.0, loy)
    ly = min(math.ceil(max(ay, by)) - 1.0, hiy)
    nx = int(lx - fx + 1.0) if lx >= fx else 0
    ny = int(ly - fy + 1.0) if ly >= fy else 0
    sdx, sdy = _safe(dx), _safe(dy)
    ts[0], axes[0], lines[0] = 0.0, _NO_AXIS, 0.0
    count = 1
    i = j = 0
    tx = ty = 0.0
    if nx:
        line_x = fx if dx > 0 else lx
        tx = min(max((line_x - ax) / sdx, 0.0), 1.0)
    if ny:
        line_y = fy if dy > 0 else ly
        ty = min(max((line_y - ay) / sdy, 0.0), 1.0)
    while i < nx or j < ny:
        if j >= ny or (i < nx and tx <= ty):
            ts[count], axes[count], lines[count] = tx, 0, line_x
            i += 1
            if i < nx:
                line_x = line_x + 1.0 if dx > 0 else line_x - 1.0
                tx = min(max((line_x - ax) / sdx, 0.0), 1.0)
        else:
            ts[count], axes[count], lines[count] = ty, 1, line_y
            j += 1
            if j < ny:
                line_y = line_y + 1.0 if dy > 0 else line_y - 1.0
                ty = min(max((line_y - ay) / sdy, 0.0), 1.0)
        count += 1
    ts[count], axes[count], lines[count] = 1.0, _NO_AXIS, 1.0
    return count + 1


@njit
def _t_grad(t_axis, line, ax, ay, dx, dy, g_t, g):
    """Add ``g_t * dt/d(a, d)`` of one piece end to ``g = [g_ax, g_ay, g_dx, g_dy]``."""
    if t_axis == _NO_AXIS or g_t == 0.0:
        return
    a = ax if t_axis == 0 else ay
    span = dx if t_axis == 0 else dy
    if abs(span) < 1e-12:
        safe = _safe(span)
        raw = (line - a) / safe
        if 0.0 <= raw <= 1.0:
            g[t_axis] += -g_t / safe
        return
    raw = (line - a) / span
    if 0.0 <= raw <= 1.0:
        g[t_axis] += -g_t / span
        g[2 + t_axis] += -g_t * raw / span


# ----------------------------------------------------------------------------- grids
#
# A "row grid" holds, per row, ``width`` cells starting at column ``col0[row]`` (a
# fill window has the same start on every row; a stroke band shifts it per row).
# Pieces left of a row's cells are dropped and pieces right of them cover the row.


@njit
def _piece(ax, ay, dx, dy, ta, tb, row0, col0, nrows, width):
    """Where the piece ``t in [ta, tb]`` of the edge ``a + t d`` lands on a row grid.

    Returns ``(kept, r, c, x_mid, t_mid, w)``: its grid row and column (clamped to
    ``width`` right of the cells), midpoint x and t, and signed height ``w``.
    """
    tm = 0.5 * (ta + tb)
    r = int(math.floor(ay + tm * dy)) - row0
    if r < 0 or r >= nrows:
        return False, 0, 0, 0.0, 0.0, 0.0
    xm = ax + tm * dx
    c = int(math.floor(xm)) - col0[r]
    if c < 0:
        return False, 0, 0, 0.0, 0.0, 0.0
    return True, r, min(c, width), xm, tm, (tb - ta) * dy


@njit
def _list_cell(touched, listed, counts, r, c):
    """Add cell ``(r, c)`` to row ``r``'s list of touched cells, once."""
    if not touched[r, c]:
        touched[r, c] = 1
        listed[r, counts[r]] = c
        counts[r] += 1


@njit
def scatter_edge(ax, ay, bx, by, lox, hix, loy, hiy, row0, col0, nrows, width, diff, ts, axes, lines, cells):
    """Accumulate one edge's pieces into a difference buffer ``diff`` ``(rows, width + 2)``.

    ``cells``: None, or ``(touched (rows, width + 2) uint8, listed (rows, width + 2),
    counts (rows,))`` to which the cells of the row that it changes (left of ``width``)
    are added, unsorted (:func:`_list_cell`).
    """
    count = cut_edge(ax, ay, bx, by, lox, hix, loy, hiy, ts, axes, lines)
    dx, dy = bx - ax, by - ay
    for k in range(count - 1):
        kept, r, c, xm, _, w = _piece(ax, ay, dx, dy, ts[k], ts[k + 1], row0, col0, nrows, width)
        if not kept:
            continue
        inside_area = min(max(xm - (col0[r] + c), 0.0), 1.0) * w
        diff[r, 0] += w
        diff[r, c] += inside_area - w
        diff[r, c + 1] -= inside_area
        if cells is not None:
            _list_cell(cells[0], cells[1], cells[2], r, 0)
            if c < width:
                _list_cell(cells[0], cells[1], cells[2], r, c)
            if c + 1 < width:
                _list_cell(cells[0], cells[1], cells[2], r, c + 1)


@njit
def gather_edge(ax, ay, bx, by, lox, hix, loy, hiy, row0, col0, nrows, width, cell_grad, prefix, ts, axes, lines, g):
    """Backward of :func:`scatter_edge`: adds dL/d(a, d) of the edge to ``g``.

    ``cell_grad``: dL/dW per cell ``(rows, width)``; ``prefix``: its exclusive prefix
    sums ``(rows, width + 1)``.
    """
    count = cut_edge(ax, ay, bx, by, lox, hix, loy, hiy, ts, axes, lines)
    dx, dy = bx - ax, by - ay
    for k in range(count - 1):
        ta, tb = ts[k], ts[k + 1]
        kept, r, c, xm, tm, w = _piece(ax, ay, dx, dy, ta, tb, row0, col0, nrows, width)
        if not kept:
            continue
        own = cell_grad[r, c] if c < width else 0.0
        frac = xm - (col0[r] + c)
        g_w = prefix[r, c] + own * min(max(frac, 0.0), 1.0)
        g_xm = own * w if 0.0 <= frac <= 1.0 else 0.0
        if g_w == 0.0 and g_xm == 0.0:
            continue
        g_tm = g_xm * dx
        g[0] += g_xm
        g[2] += g_xm * tm
        g[3] += g_w * (tb - ta)
        _t_grad(axes[k], lines[k], ax, ay, dx, dy, 0.5 * g_tm - g_w * dy, g)
        _t_grad(axes[k + 1], lines[k + 1], ax, ay, dx, dy, 0.5 * g_tm + g_w * dy, g)


@njit
def row_prefix(cell_grad, nrows, width, prefix):
    """Exclusive prefix sums of ``cell_grad`` along each row."""
    for r in range(nrows):
        acc = 0.0
        for c in range(width):
            prefix[r, c] = acc
            acc += cell_grad[r, c]
        prefix[r, width] = acc


@njit
def polygon_winding(vertices, height, width, row0, nrows, diff, ts, axes, lines):
    """Fill ``diff`` ``(nrows, width + 2)`` with the pieces of a closed polygon on rows
    ``row0 .. row0 + nrows`` of a ``height x width`` grid (columns from 0)."""
    n = vertices.shape[0]
    col0 = np.zeros(nrows, np.int64)
    for i in range(n):
        j = (i + 1) % n
        scatter_edge(
            vertices[i, 0],
            vertices[i, 1],
            vertices[j, 0],
            vertices[j, 1],
            0.0,
            float(width),
            0.0,
            float(height),
            row0,
            col0,
            nrows,
            width,
            diff,
            ts,
            axes,
            lines,
            None,
        )


@njit
def polygon_coverage_rows(vertices, height, width, row0, nrows, out):
    """Exact non-zero coverage ``min(|W|, 1)`` of a polygon on rows ``row0 ..`` of a
    ``height x width`` grid, written to ``out`` ``(nrows, width)`` (any float dtype)."""
    diff = np.zeros((nrows, width + 2))
    size = 2 * (height + width) + 8
    ts, axes, lines = np.empty(size), np.empty(size, np.int64), np.empty(size)
    polygon_winding(vertices, height, width, row0, nrows, diff, ts, axes, lines)
    for r in range(nrows):
        acc = 0.0
        for c in range(width):
            acc += diff[r, c]
            out[r, c] = min(abs(acc), 1.0)


# ----------------------------------------------------------------------------- strokes


@njit
def clip_segment(px, py, qx, qy, low, high):
    """Liang-Barsky clip of ``p -> q`` to ``[low, high]^2`` (render._clip_to_box).

    Returns ``(t_enter, t_exit, axis_enter, axis_exit, side_enter, side_exit, empty)``:
    the clipped segment is ``p + t * (q - p)``; ``axis_*`` is the axis whose bound set
    ``t`` (-1 when the clamp to [0, 1] did, so ``t`` does not move with the points) and
    ``side_*`` that bound's value; an empty clip collapses to ``p``.
    """
    inside = low <= px <= high and low <= py <= high and low <= qx <= high and low <= qy <= high
    if inside:
        return 0.0, 1.0, -1, -1, 0.0, 0.0, False
    t_in, t_out = -math.inf, math.inf
    ax_in, ax_out = -1, -1
    side_in = side_out = 0.0
    for axis in range(2):
        s = px if axis == 0 else py
        d = (qx - px) if axis == 0 else (qy - py)
        if abs(d) < 1e-12:
            if not (low <= s <= high):
                t_in, t_out = math.inf, -math.inf
                ax_in = ax_out = -1
            continue
        ta, tb = (low - s) / d, (high - s) / d
        lo_t, lo_side = (ta, low) if ta <= tb else (tb, high)
        hi_t, hi_side = (tb, high) if ta <= tb else (ta, low)
        if lo_t > t_in:
            t_in, ax_in, side_in = lo_t, axis, lo_side
        if hi_t < t_out:
            t_out, ax_out, side_out = hi_t, axis, hi_side
    if t_in < 0.0:
        t_in, ax_in = 0.0, -1
    if t_out > 1.0:
        t_out, ax_out = 1.0, -1
    if t_in > t_out:
        return 0.0, 0.0, -1, -1, 0.0, 0.0, True
    return t_in, t_out, ax_in, ax_out, side_in, side_out, False


@njit
def clipped_segment(px, py, qx, qy, low, high):
    """The segment as its band sees it: clipped (:func:`clip_segment`), then with x and
    y swapped when it runs more along x. Returns ``(sx, sy, ex, ey, x_major, clip)``."""
    clip = clip_segment(px, py, qx, qy, low, high)
    t_in, t_out = clip[0], clip[1]
    dx, dy = qx - px, qy - py
    sx, sy = px + t_in * dx, py + t_in * dy
    ex, ey = px + t_out * dx, py + t_out * dy
    x_major = abs(ex - sx) > abs(ey - sy)
    if x_major:
        sx, sy, ex, ey = sy, sx, ey, ex
    return sx, sy, ex, ey, x_major, clip


@njit
def band_extent(sy, ey, half_width):
    """The band of a (flipped) segment along y (render._plan_bands): ``(row_start, own_rows)``."""
    y_low, y_high = min(sy, ey), max(sy, ey)
    row_start = math.floor(y_low - half_width)
    return int(row_start), int(math.floor(y_high + half_width) - row_start) + 1


@njit
def band_plan(sx, sy, ex, ey, row_start, rows, col_start):
    """Band placement along y of a (flipped) segment (render._plan_bands): fills
    ``col_start[:rows]`` with the first column of each band row from ``row_start``
    (:func:`band_extent`)."""
    y_low, y_high = min(sy, ey), max(sy, ey)
    span_y = ey - sy
    slope = (ex - sx) / span_y if abs(span_y) > 1e-9 else 0.0
    for r in range(rows):
        centre_y = min(max(row_start + r + 0.5, y_low), y_high)
        col_start[r] = int(math.floor(sx + (centre_y - sy) * slope)) - BAND_LEFT


@njit
def band_rows(px, py, qx, qy, half_width, low, high) -> int:
    """Rows the reference's band of segment ``p -> q`` spans (its ``_plan_bands``)."""
    sx, sy, ex, ey, _, _ = clipped_segment(px, py, qx, qy, low, high)
    y_low, y_high = min(sy, ey), max(sy, ey)
    return int(math.floor(y_high + half_width) - math.floor(y_low - half_width)) + 1


@njit
def capsule_outline(sx, sy, ex, ey, cos_r, sin_r, out):
    """The stroke polygon of ``s -> e`` (render.stroke_outlines): ``out`` ``(18, 2)``.

    Returns ``(direction_x, direction_y, length, tiny)``.
    """
    dx, dy = ex - sx, ey - sy
    length = math.sqrt(dx * dx + dy * dy)
    tiny = length < 1e-9
    if tiny:
        ux, uy = 1.0, 0.0
    else:
        ux, uy = dx / length, dy / length
    nx, ny = -uy, ux
    caps = cos_r.shape[0]
    for k in range(caps):
        out[k, 0] = ex + cos_r[k] * ux + sin_r[k] * nx
        out[k, 1] = ey + cos_r[k] * uy + sin_r[k] * ny
        out[caps + k, 0] = sx - cos_r[k] * ux - sin_r[k] * nx
        out[caps + k, 1] = sy - cos_r[k] * uy - sin_r[k] * ny
    return ux, uy, length, tiny


@njit
def capsule_backward(ux, uy, length, tiny, cos_r, sin_r, g_out):
    """dL/d(s, e) from dL/d(outline points) ``g_out`` ``(18, 2)``: ``(gsx, gsy, gex, gey)``."""
    caps = cos_r.shape[0]
    gex = gey = gsx = gsy = 0.0
    gux = guy = 0.0
    for k in range(caps):
        ax, ay = g_out[k, 0], g_out[k, 1]
        bx, by = g_out[caps + k, 0], g_out[caps + k, 1]
        gex += ax
        gey += ay
        gsx += bx
        gsy += by
        # point = end + c u + s n, n = (-u_y, u_x); the start cap has the opposite signs.
        cx, cy = ax - bx, ay - by
        gux += cos_r[k] * cx + sin_r[k] * cy
        guy += cos_r[k] * cy - sin_r[k] * cx
    if not tiny:
        dot = gux * ux + guy * uy
        gdx, gdy = (gux - ux * dot) / length, (guy - uy * dot) / length
        gex += gdx
        gey += gdy
        gsx -= gdx
        gsy -= gdy
    return gsx, gsy, gex, gey


@njit
def clip_backward(px, py, qx, qy, t_in, t_out, ax_in, ax_out, side_in, side_out, gsx, gsy, gex, gey):
    """dL/d(p, q) from dL/d(clipped s, e): ``(gpx, gpy, gqx, gqy)``."""
    dx, dy = qx - px, qy - py
    # s = p + t_in d, e = p + t_out d with d = q - p.
    gpx = gsx * (1.0 - t_in) + gex * (1.0 - t_out)
    gpy = gsy * (1.0 - t_in) + gey * (1.0 - t_out)
    gqx = gsx * t_in + gex * t_out
    gqy = gsy * t_in + gey * t_out
    for which in range(2):
        axis = ax_in if which == 0 else ax_out
        if axis < 0:
            continue
        t = t_in if which == 0 else t_out
        g_t = (gsx * dx + gsy * dy) if which == 0 else (gex * dx + gey * dy)
        d = dx if axis == 0 else dy
        # t = (side - p_k) / (q_k - p_k): dt/dp_k = (t - 1) / d, dt/dq_k = -t / d.
        if axis == 0:
            gpx += g_t * (t - 1.0) / d
            gqx += -g_t * t / d
        else:
            gpy += g_t * (t - 1.0) / d
            gqy += -g_t * t / d
    return gpx, gpy, gqx, gqy


@njit
def stroke_band(
    px, py, qx, qy, half_width, low, high, rows_limit, cos_r, sin_r, outline, col_start, diff, ts, axes, lines
):
    """Rasterize the capsule of ``p -> q`` onto its band.

    Fills ``diff`` ``(rows, 15)`` (zeroed here) and ``col_start``; returns ``(row_start,
    rows, x_major, empty)``. The band's cells are ``(major = row_start + r, minor =
    col_start[r] + c)``, with x and y swapped when ``x_major``.
    """
    sx, sy, ex, ey, x_major, clip = clipped_segment(px, py, qx, qy, low, high)
    empty = clip[6]
    row_start, own = band_extent(sy, ey, half_width)
    rows = min(own + 1, rows_limit)
    band_plan(sx, sy, ex, ey, row_start, rows, col_start)
    if empty:
        return row_start, 0, x_major, True
    # The band's width read from its buffer, not the constant: a literal argument would
    # compile scatter_edge once more (numba specialises on literals).
    columns = diff.shape[1] - 2
    for r in range(rows):
        for c in range(diff.shape[1]):
            diff[r, c] = 0.0
    capsule_outline(sx, sy, ex, ey, cos_r, sin_r, outline)
    inf = math.inf
    for k in range(OUTLINE_POINTS):
        m = (k + 1) % OUTLINE_POINTS
        scatter_edge(
            outline[k, 0],
            outline[k, 1],
            outline[m, 0],
            outline[m, 1],
            -inf,
            inf,
            -inf,
            inf,
            row_start,
            col_start,
            rows,
            columns,
            diff,
            ts,
            axes,
            lines,
            None,
        )
    return row_start, rows, x_major, False


@njit
def stroke_band_backward(
    px,
    py,
    qx,
    qy,
    half_width,
    low,
    high,
    row_start,
    rows,
    cos_r,
    sin_r,
    outline,
    g_outline,
    col_start,
    cell_grad,
    prefix,
    ts,
    axes,
    lines,
):
    """Backward of :func:`stroke_band`: dL/d(p, q) from dL/dW on the band."""
    sx, sy, ex, ey, x_major, clip = clipped_segment(px, py, qx, qy, low, high)
    t_in, t_out, ax_in, ax_out, side_in, side_out, _ = clip
    ux, uy, length, tiny = capsule_outline(sx, sy, ex, ey, cos_r, sin_r, outline)
    columns = cell_grad.shape[1] - 2  # (not the literal constant: see stroke_band)
    row_prefix(cell_grad, rows, columns, prefix)
    inf = math.inf
    g = np.zeros(4)
    for k in range(OUTLINE_POINTS):
        g_outline[k, 0] = g_outline[k, 1] = 0.0
    for k in range(OUTLINE_POINTS):
        m = (k + 1) % OUTLINE_POINTS
        g[0] = g[1] = g[2] = g[3] = 0.0
        gather_edge(
            outline[k, 0],
            outline[k, 1],
            outline[m, 0],
            outline[m, 1],
            -inf,
            inf,
            -inf,
            inf,
            row_start,
            col_start,
            rows,
            columns,
            cell_grad,
            prefix,
            ts,
            axes,
            lines,
            g,
        )
        # g = dL/d(a, d) of the outline edge a = point k, d = point m - point k.
        g_outline[k, 0] += g[0] - g[2]
        g_outline[k, 1] += g[1] - g[3]
        g_outline[m, 0] += g[2]
        g_outline[m, 1] += g[3]
    gsx, gsy, gex, gey = capsule_backward(ux, uy, length, tiny, cos_r, sin_r, g_outline)
    if x_major:
        gsx, gsy, gex, gey = gsy, gsx, gey, gex
    return clip_backward(px, py, qx, qy, t_in, t_out, ax_in, ax_out, side_in, side_out, gsx, gsy, gex, gey)


@njit
def stroke_maps(start, end, height, width, half_width, cos_r, sin_r, out):
    """Full ``(M, height, width)`` coverage maps of the strokes ``start[m] -> end[m]``
    (render.stroke_coverage): ``out`` must be zero."""
    count = start.shape[0]
    margin = half_width + 2.0
    low, high = -margin, max(height, width) + margin
    rows_limit = np.int64(1)  # not a literal 1: numba would compile stroke_band for it
    for m in range(count):
        rows_limit = max(rows_limit, band_rows(start[m, 0], start[m, 1], end[m, 0], end[m, 1], half_width, low, high))
    crossings = 4 * (max(height, width) + 4 * int(margin) + 16)
    ts, axes, lines = np.empty(crossings), np.empty(crossings, np.int64), np.empty(crossings)
    outline = np.empty((OUTLINE_POINTS, 2))
    col_start = np.empty(rows_limit, np.int64)
    diff = np.empty((rows_limit, BAND_COLUMNS + 2))
    for m in range(count):
        row_start, rows, x_major, empty = stroke_band(
            start[m, 0],
            start[m, 1],
            end[m, 0],
            end[m, 1],
            half_width,
            low,
            high,
            rows_limit,
            cos_r,
            sin_r,
            outline,
            col_start,
            diff,
            ts,
            axes,
            lines,
        )
        for r in range(rows):
            acc = 0.0
            for c in range(BAND_COLUMNS):
                acc += diff[r, c]
                major, minor = row_start + r, col_start[r] + c
                x, y = (major, minor) if x_major else (minor, major)
                if 0 <= x < width and 0 <= y < height:
                    out[m, y, x] = min(abs(acc), 1.0)
