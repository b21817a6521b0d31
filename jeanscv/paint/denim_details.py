"""The construction details of the painted jeans: seams, stitching, waistband, hems,
front pockets, fly, whiskers, belt loops, button and rivets.

:func:`draw_details` draws them over the denim's *patch* (see :mod:`jeanscv.paint.denim`) as
anti-aliased ink layers (:class:`_Layer`, blurred into :class:`_Field` where they are
soft) in the garment's own frame (:class:`Layout`), every size a fraction of the
garment's size (:func:`_garment_unit`), so the jeans read the same on a thumbnail and on
a 24-MP photo. The painter in :mod:`jeanscv.paint.denim` reads the layers window by window
through :class:`Details`.

Coordinates follow the package convention (x right, y down, pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``); polylines and polygons are ``(k, 2)`` patch pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..fitting.garments import Garment, polygon_area

# OpenCV sub-pixel drawing: coordinates carry this many fractional bits.
_SHIFT = 4

# Hardware (RGB, 0..255): the brass button, the copper rivets.
_BRASS = np.array([196, 162, 98], np.float32)
_COPPER = np.array([178, 104, 58], np.float32)


# --------------------------------------------------------------------------- drawing


def _cv_points(points: np.ndarray) -> np.ndarray:
    """Fixed-point OpenCV coordinates of package-convention points (pixel centres at +0.5)."""
    return np.round((np.asarray(points) - 0.5) * (1 << _SHIFT)).astype(np.int32)


class _Layer:
    """An 8-bit ink layer drawn with OpenCV (anti-aliased, sub-pixel), read back as float.

    Each stroke or polygon carries its own ink ``value`` in [0, 1]; where they overlap
    the later one wins, which is how stacked cloth looks anyway.
    """

    def __init__(self, shape: tuple[int, int]) -> None:
        self.ink = np.zeros(shape, np.uint8)

    def lines(self, polylines: list[np.ndarray] | np.ndarray, width: float, value: float = 1.0) -> None:
        """Stroke open polylines ``(k, 2)`` ``width`` px wide: a list of them, or an
        ``(m, k, 2)`` array of ``m`` (stitches come by the hundred: converted in one call).

        OpenCV only draws whole-pixel widths, so a thinner stroke is drawn 1 px wide and
        faded by its width, which keeps its ink (area x alpha) right.
        """
        if len(polylines):
            points = _cv_points(polylines) if isinstance(polylines, np.ndarray) else map(_cv_points, polylines)
            cv2.polylines(
                self.ink,
                list(points),
                False,
                round(255 * value * min(width, 1.0)),
                max(1, round(width)),
                cv2.LINE_AA,
                _SHIFT,
            )

    def polygons(self, polygons: list[np.ndarray], value: float = 1.0) -> None:
        """Fill polygons ``(k, 2)`` (drawing quality; exact area is for the jeans outline)."""
        if polygons:
            cv2.fillPoly(self.ink, [_cv_points(p) for p in polygons], round(255 * value), cv2.LINE_AA, _SHIFT)

    def window(self, rows: slice, cols: slice) -> np.ndarray | None:
        """The unblurred ink over a window as ``float32`` in [0, 1], or None where there
        is none there (callers skip it: adding 0 or scaling by 1 changes no value)."""
        ink = self.ink[rows, cols]
        return np.multiply(ink, np.float32(1 / 255), dtype=np.float32) if ink.any() else None

    def alpha(self, sigma: float = 0.0) -> _Field:
        """The ink in [0, 1], Gaussian-blurred by ``sigma`` px only around where there
        is ink, and stored only there."""
        x, y, w, h = cv2.boundingRect(self.ink)
        if w == 0:
            return _Field(np.zeros((0, 0), np.float32), 0, 0)
        pad = int(np.ceil(3 * sigma)) + 1
        rows = slice(max(y - pad, 0), min(y + h + pad, self.ink.shape[0]))
        cols = slice(max(x - pad, 0), min(x + w + pad, self.ink.shape[1]))
        return _Field(blur(self.window(rows, cols), sigma), rows.start, cols.start)


@dataclass(frozen=True)
class _Field:
    """A ``(h, w) float32`` field that is 0 except in a box at ``(top, left)``, where
    it is ``values``."""

    values: np.ndarray
    top: int
    left: int

    def window(self, rows: slice, cols: slice) -> np.ndarray | None:
        """The field over a window (read-only: it may be a view), or None where it is 0
        (see :meth:`_Layer.window`)."""
        inner = self.values[
            max(rows.start - self.top, 0) : max(rows.stop - self.top, 0),
            max(cols.start - self.left, 0) : max(cols.stop - self.left, 0),
        ]
        if inner.size == 0:
            return None
        if inner.shape == (rows.stop - rows.start, cols.stop - cols.start):
            return inner
        out = np.zeros((rows.stop - rows.start, cols.stop - cols.start), np.float32)
        top, left = max(self.top - rows.start, 0), max(self.left - cols.start, 0)
        out[top : top + inner.shape[0], left : left + inner.shape[1]] = inner
        return out


def blur(field: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur of a ``(h, w) float32`` field (may reuse its memory).

    Wide blurs run on a copy shrunk so sigma is about 2 px there and are scaled back
    up: the result is smooth anyway, and it keeps a 24-MP photo's blurs cheap.
    """
    if sigma < 0.1:
        return field
    h, w = field.shape
    factor = int(sigma // 2)
    if factor < 2 or min(h, w) < 4 * factor:
        return cv2.GaussianBlur(field, (0, 0), sigma, dst=field, borderType=cv2.BORDER_REPLICATE)
    small = cv2.resize(field, (-(-w // factor), -(-h // factor)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / factor, borderType=cv2.BORDER_REPLICATE)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def _dashes(polyline: np.ndarray, dash: float, gap: float, box: tuple[int, int]) -> np.ndarray:
    """Dash segments ``(m, 2, 2)`` along a polyline ``(k, 2)``, dropping those off the patch
    ``box = (h, w)`` so a huge polygon does not make OpenCV draw millions of dashes."""
    steps = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    if arc[-1] < dash:
        return np.zeros((0, 2, 2))
    starts = np.arange(0.5 * gap, arc[-1] - dash, dash + gap)
    ends = starts + dash
    seg = np.stack(
        [
            np.stack([np.interp(starts, arc, polyline[:, 0]), np.interp(starts, arc, polyline[:, 1])], -1),
            np.stack([np.interp(ends, arc, polyline[:, 0]), np.interp(ends, arc, polyline[:, 1])], -1),
        ],
        axis=1,
    )
    h, w = box
    keep = (
        (seg[:, :, 0].max(1) > -dash)
        & (seg[:, :, 0].min(1) < w + dash)
        & (seg[:, :, 1].max(1) > -dash)
        & (seg[:, :, 1].min(1) < h + dash)
    )
    return seg[keep]


def _offset(polyline: np.ndarray, distance: float) -> np.ndarray:
    """Polyline ``(k, 2)`` moved ``distance`` px to its left (``(-dy, dx)`` side), mitred."""
    tangent = np.diff(polyline, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    at_vertex = np.concatenate([normal[:1], normal[:-1] + normal[1:], normal[-1:]])
    at_vertex /= np.maximum(np.linalg.norm(at_vertex, axis=1, keepdims=True), 1e-9)
    # A mitre is 1/cos(half the turn) long; cap it so a hairpin stays near its vertex.
    cos_half = np.concatenate([[1.0], np.sum(at_vertex[1:-1] * normal[1:], axis=1), [1.0]])
    return polyline + at_vertex * (distance / np.maximum(cos_half, 0.35))[:, None]


def _bezier(p0: np.ndarray, control: np.ndarray, p1: np.ndarray, samples: int = 24) -> np.ndarray:
    t = np.linspace(0.0, 1.0, samples)[:, None]
    return (1 - t) ** 2 * p0 + 2 * (1 - t) * t * control + t**2 * p1


def _closed_chains(garment: Garment) -> list[list[int]]:
    """Vertex index runs along maximal sequences of consecutive closed edges."""
    n = garment.num_vertices
    closed = set(garment.closed_edges)
    if len(closed) == n:
        return [list(range(n)) + [0]]
    chains = []
    for edge in sorted(closed):
        if (edge - 1) % n in closed:
            continue  # not the first edge of its run
        run = [edge]
        while (run[-1] + 1) % n in closed:
            run.append((run[-1] + 1) % n)
        chains.append(run + [(run[-1] + 1) % n])
    return chains


# --------------------------------------------------------------------------- the garment


@dataclass(frozen=True)
class Layout:
    """The garment in patch pixels, with the frame and sizes the denim is drawn in."""

    vertices: np.ndarray  # (n, 2) patch pixels
    unit: float  # garment size in px (see _garment_unit)
    across: np.ndarray  # (2,) unit vector along the waist, from waist[0] to waist[1]
    down: np.ndarray  # (2,) unit vector from the waist into the garment
    inward_sign: float  # +1 if the interior lies left ((-dy, dx)) of each edge

    def inward(self, polyline: np.ndarray, distance: float) -> np.ndarray:
        """A polyline that runs along the garment's outline, moved ``distance`` px inside."""
        return _offset(polyline, self.inward_sign * distance)


def _garment_unit(vertices: np.ndarray, garment: Garment) -> float:
    """Garment size in image pixels: the waistband length of a similar-shaped garment of
    the same area. Area-based, so a fit that squeezes the waist does not shrink details."""
    template_area = abs(polygon_area(garment.template))
    a, b = garment.waist
    template_waist = float(np.linalg.norm(garment.template[b] - garment.template[a]))
    return template_waist * np.sqrt(abs(polygon_area(vertices)) / template_area)


def garment_layout(vertices: np.ndarray, garment: Garment) -> Layout:
    """The garment's frame and size from its ``(n, 2)`` vertices in patch pixels."""
    a, b = garment.waist
    across = vertices[b] - vertices[a]
    length = float(np.linalg.norm(across))
    # A fit that collapsed its waist still gets a frame (upright) to weave in.
    across = across / length if length > 1e-6 else np.array([1.0, 0.0])
    down = np.array([-across[1], across[0]])
    centroid = vertices.mean(axis=0)
    if np.dot(centroid - 0.5 * (vertices[a] + vertices[b]), down) < 0:
        down = -down
    sign = 1.0 if polygon_area(vertices) > 0 else -1.0
    # A self-crossing fit can have zero net area yet cover pixels: keep sizes finite.
    unit = max(_garment_unit(vertices, garment), 4.0)
    return Layout(vertices, unit, across, down, sign)


def _ray_hit(layout: Layout, origin: np.ndarray, direction: np.ndarray) -> float:
    """Distance from ``origin`` along ``direction`` to the first polygon edge (inf if none)."""
    start = layout.vertices
    edge = np.roll(start, -1, axis=0) - start
    # Solve origin + t * direction = start + s * edge for every edge at once (Cramer).
    det = edge[:, 0] * direction[1] - edge[:, 1] * direction[0]
    rel = start - origin
    # Near-parallel edges (tiny det) overflow; the hit test below drops them.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = (edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0]) / det
        s = (direction[0] * rel[:, 1] - direction[1] * rel[:, 0]) / det
    hit = (np.abs(det) > 1e-12) & (s >= 0) & (s <= 1) & (t > 1e-6)
    return float(t[hit].min()) if hit.any() else np.inf


def _towards(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Unit vector from ``p`` to ``q``."""
    return (q - p) / max(float(np.linalg.norm(q - p)), 1e-9)


@dataclass
class Details:
    """What the garment construction adds to the plain cloth.

    Blurred layers are fields, sharp ones stay 8-bit ink; both are read per window, as
    are their combinations, so pixels the paint skips cost nothing.
    """

    wear: _Field  # added lightness (0 deep indigo .. 1 worn)
    grooves: _Field  # seam and hem shadows, 1 = black
    outline: _Field  # the belt loops' dark outline
    raised: _Layer  # belt loops, which stand out of the shadows under them
    flip: _Layer  # 1 where the weave runs the other way (waistband, belt loops)
    thread: _Layer  # golden stitching
    metal: list  # (centre (2,), radius px, rgb (3,)) of button and rivets

    def dark(self, rows: slice, cols: slice) -> np.ndarray:
        """Multiplicative darkening (seams, shadows; 1 = none) over a window."""
        grooves = self.grooves.window(rows, cols)
        if grooves is None:
            dark = np.ones((rows.stop - rows.start, cols.stop - cols.start), np.float32)
        else:
            dark = 1.0 - grooves
        flip = self.flip.window(rows, cols)
        if flip is not None:
            dark *= 1.0 - 0.2 * flip
        loop = self.raised.window(rows, cols)
        if loop is not None:
            dark += loop * (1.0 - dark)  # the loop stands out of the shadow under it
        outline = self.outline.window(rows, cols)
        if outline is not None:
            dark *= 1.0 - outline
        return dark


class _Tailor:
    """The ink layers the construction draws on, with its seam and stitch sizes.

    Sizes are fractions of the garment unit, with pixel floors so a thumbnail still
    shows a stitch.
    """

    def __init__(self, layout: Layout, shape: tuple[int, int]) -> None:
        self.layout, self.shape = layout, shape
        unit = layout.unit
        self.seam_w = max(1.2, 0.016 * unit)
        self.thread_w = max(0.9, 0.0055 * unit)
        self.stitch = max(2.2, 0.014 * unit)
        self.gap = 0.45 * self.stitch
        self.grooves, self.wear, self.thread, self.flip = (_Layer(shape) for _ in range(4))

    def dashes(self, line: np.ndarray) -> None:
        """One row of stitches along the polyline ``line`` ``(k, 2)``."""
        self.thread.lines(_dashes(line, self.stitch, self.gap, self.shape), self.thread_w)

    def stitches(self, polyline: np.ndarray, offsets: tuple[float, ...], inward: bool = True) -> None:
        """A row of stitches ``d`` px beside ``polyline`` for each ``d`` of ``offsets``:
        inside the garment, or to the polyline's left (``(-dy, dx)`` side) when not
        ``inward``."""
        for d in offsets:
            self.dashes(self.layout.inward(polyline, d) if inward else _offset(polyline, d))


@dataclass(frozen=True)
class _Waistband:
    """Where the waistband lies: from the waist vertices ``a`` and ``b`` down to
    ``a_low`` and ``b_low`` on the side seams, which run towards ``side_a`` and
    ``side_b``; ``button`` is the brass button's metal entry."""

    a: int
    b: int
    side_a: np.ndarray
    side_b: np.ndarray
    a_low: np.ndarray
    b_low: np.ndarray
    centre_low: np.ndarray  # the middle of the band's lower edge
    button: tuple


def _closed_seams(tailor: _Tailor, garment: Garment) -> None:
    """Closed edges: dark seam groove with double (flat-felled) topstitching beside it,
    and the felled allowance a slightly raised, lighter ridge between the stitches."""
    layout, seam_w = tailor.layout, tailor.seam_w
    chains = [layout.vertices[c] for c in _closed_chains(garment)]
    tailor.grooves.lines(chains, 2 * seam_w, 0.55)
    for chain in chains:
        tailor.stitches(chain, (1.3 * seam_w, 2.5 * seam_w))
    tailor.wear.lines([layout.inward(c, 1.9 * seam_w) for c in chains], 1.1 * seam_w, 0.18)


def _waistband(tailor: _Tailor, garment: Garment) -> _Waistband:
    """Waistband: a darker band with cross-grain weave, stitched along both edges."""
    layout = tailor.layout
    v, unit, n = layout.vertices, layout.unit, garment.num_vertices
    a, b = garment.waist
    side_a = v[(a - 1) % n] if (a - 1) % n != b else v[(a + 1) % n]
    side_b = v[(b + 1) % n] if (b + 1) % n != a else v[(b - 1) % n]
    band = 0.11 * unit
    a_low = v[a] + _towards(v[a], side_a) * band
    b_low = v[b] + _towards(v[b], side_b) * band
    top, bottom = np.array([v[a], v[b]]), np.array([a_low, b_low])
    tailor.flip.polygons([np.array([v[a], v[b], b_low, a_low])])
    tailor.grooves.lines([bottom], tailor.seam_w, 0.5)
    # _offset moves left of the line; pick the sign that moves down into the band.
    down_is_left = np.sign(layout.down @ (_offset(top, 1.0)[0] - top[0])) or 1.0
    tailor.stitches(top, (down_is_left * 0.25 * band,), inward=False)
    tailor.stitches(bottom, (-down_is_left * 0.25 * band,), inward=False)
    centre_low = 0.5 * (a_low + b_low)
    # The button sits mid-band at the centre front.
    button = (0.25 * (v[a] + v[b]) + 0.5 * centre_low, 0.026 * unit, _BRASS)
    return _Waistband(a, b, side_a, side_b, a_low, b_low, centre_low, button)


def _hems(tailor: _Tailor, garment: Garment) -> None:
    """Hems on the open leg edges: folded band, worn light edge, one stitch row."""
    layout, seam_w = tailor.layout, tailor.seam_w
    v, n = layout.vertices, garment.num_vertices
    a, b = garment.waist
    hem = 0.05 * layout.unit
    for edge in garment.open_edges:
        p, q = v[edge], v[(edge + 1) % n]
        if {edge, (edge + 1) % n} == {a, b}:
            continue
        extend = _towards(p, q) * 0.1 * layout.unit
        line = np.array([p - extend, q + extend])
        fold = layout.inward(line, hem)
        tailor.grooves.polygons([np.vstack([line, fold[::-1]])], 0.15)
        tailor.grooves.lines([fold], seam_w, 0.5)
        tailor.wear.lines([line], 1.5 * seam_w, 0.6)
        tailor.stitches(line, (0.6 * hem,))


def _front_pockets(tailor: _Tailor, band: _Waistband) -> list:
    """Front pockets: scooped openings from the waistband to the side seams, stitched on
    the front-panel side; returns the rivet at the outer end of each (metal entries)."""
    layout, seam_w = tailor.layout, tailor.seam_w
    v, unit = layout.vertices, layout.unit
    rivets = []
    for corner, low, other, side in (
        (v[band.a], band.a_low, band.b_low, band.side_a),
        (v[band.b], band.b_low, band.a_low, band.side_b),
    ):
        start = low + (other - low) * 0.2
        end = corner + _towards(corner, side) * 0.27 * unit
        control = corner + 0.95 * (start - corner) + 0.9 * (end - corner)
        curve = _bezier(start, control, end)
        tailor.grooves.lines([curve], 0.8 * seam_w, 0.6)
        mid = len(curve) // 2
        towards_corner = np.dot(_offset(curve, 1.0)[mid] - curve[mid], corner - curve[mid]) > 0
        away = -1.0 if towards_corner else 1.0
        tailor.stitches(curve, (away * 1.2 * seam_w, away * 2.3 * seam_w), inward=False)
        rivets.append((end + (start - end) * 0.04, 0.011 * unit, _COPPER))
    return rivets


def _fly(tailor: _Tailor, band: _Waistband) -> np.ndarray | None:
    """Fly: centre seam down to the crotch and the J-shaped double stitch beside it.
    Returns the crotch point, or None where the garment is too short for a fly."""
    layout, seam_w = tailor.layout, tailor.seam_w
    unit, centre_low = layout.unit, band.centre_low
    to_crotch = _ray_hit(layout, centre_low, layout.down)
    if not (np.isfinite(to_crotch) and to_crotch > 0.05 * unit):
        return None
    crotch = centre_low + layout.down * to_crotch
    tailor.grooves.lines([np.array([centre_low, crotch])], 0.7 * seam_w, 0.55)
    length = min(0.85 * to_crotch, 0.45 * unit)
    tip = centre_low + layout.down * (length + 0.02 * unit)
    for width in (0.075 * unit, 0.075 * unit - 1.1 * seam_w):
        side = centre_low + layout.across * width
        curve = _bezier(side + layout.down * 0.7 * length, side + layout.down * length, tip)
        tailor.dashes(np.vstack([side, curve]))
    return crotch


def _whiskers(tailor: _Tailor, crotch: np.ndarray, rng: np.random.Generator) -> None:
    """Whiskers: pale creases fanning out from the crotch across the thighs."""
    layout = tailor.layout
    unit = layout.unit
    whiskers = []
    t = np.linspace(0, 1, 16)[:, None]
    for sign in (-1.0, 1.0):
        for k in range(6):
            start = crotch + unit * (layout.across * sign * (0.09 + 0.015 * k) + layout.down * (0.035 * k - 0.07))
            angle = np.deg2rad(rng.uniform(8, 22) + 4 * k)
            direction = layout.across * sign * np.cos(angle) - layout.down * np.sin(angle)
            spine = start + direction * rng.uniform(0.17, 0.27) * unit * t
            normal = np.array([-direction[1], direction[0]])
            half = (0.004 + 0.006 * rng.random()) * unit * np.sin(np.pi * t) ** 0.7
            whiskers.append(np.concatenate([spine + normal * half, (spine - normal * half)[::-1]]))
    tailor.wear.polygons(whiskers, 0.4)


def _belt_loops(tailor: _Tailor, garment: Garment, band: _Waistband) -> tuple[_Layer, _Layer]:
    """Belt loops: raised strips over the waistband with a bar tack at each end, a
    drop shadow on the side away from the light (down-right) and a sharp outline.
    Returns the ``(raised, outline)`` layers (empty for a plain garment)."""
    layout, seam_w, shape = tailor.layout, tailor.seam_w, tailor.shape
    v, unit = layout.vertices, layout.unit
    a, b = band.a, band.b
    loop_w, loop_over = 0.04 * unit, 0.03 * unit
    loops = []
    for f in (0.1, 0.3, 0.7, 0.9) if garment.style != "plain" else ():
        top_pt = v[a] + (v[b] - v[a]) * f
        low_pt = band.a_low + (band.b_low - band.a_low) * f + layout.down * loop_over
        half = layout.across * 0.5 * loop_w
        loops.append(np.array([top_pt - half, top_pt + half, low_pt + half, low_pt - half]))
        tacks = [top_pt + layout.down * 0.014 * unit, low_pt - layout.down * 0.014 * unit]
        tailor.thread.lines([np.array([p - half * 0.7, p + half * 0.7]) for p in tacks], 2.2 * tailor.thread_w)
    tailor.grooves.polygons([q + (layout.across + layout.down) * 0.5 * seam_w for q in loops], 0.6)
    raised, outline = _Layer(shape), _Layer(shape)
    raised.polygons(loops)
    outline.lines([np.vstack([q, q[:1]]) for q in loops], 0.6 * seam_w, 0.45)
    tailor.flip.polygons(loops)
    tailor.wear.polygons(loops, 0.2)
    return raised, outline


def draw_details(layout: Layout, shape: tuple[int, int], garment: Garment, rng: np.random.Generator) -> Details:
    """Seams, stitching, waistband, belt loops, pockets, fly, whiskers and hems.

    Drawn in a fixed order, since where strokes on one layer overlap the later one
    wins; ``rng`` is drawn from only by the whiskers.
    """
    tailor = _Tailor(layout, shape)
    _closed_seams(tailor, garment)
    band = _waistband(tailor, garment)
    metal = [band.button]
    _hems(tailor, garment)
    # Trouser details (pockets, fly, whiskers) only for trousers; a plain garment gets
    # no belt loops either.
    if garment.style in ("jeans", "shorts"):
        metal += _front_pockets(tailor, band)
        crotch = _fly(tailor, band)
        if crotch is not None:
            _whiskers(tailor, crotch, rng)
    raised, outline = _belt_loops(tailor, garment, band)
    seam_w = tailor.seam_w
    return Details(
        wear=tailor.wear.alpha(0.4 * seam_w),
        grooves=tailor.grooves.alpha(0.5 * seam_w),
        outline=outline.alpha(0.25 * seam_w),
        raised=raised,
        flip=tailor.flip,
        thread=tailor.thread,
        metal=metal,
    )
