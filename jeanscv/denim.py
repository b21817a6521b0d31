"""Procedural denim: what the jeans painted on a photo look like.

An indigo 2/1 twill whose weave, seams, stitching and hardware are all sized in units
of the garment's own size (:func:`_garment_unit`), so the jeans read the same on a
thumbnail and on a 24-MP photo, shaded by the photo's own blurred luminance so the
object's folds and shadows show through.

The denim is made over a *patch*: the garment polygon's bounding box ``(x0, y0, x1, y1)``
in the photo, with the polygon given in patch pixels. The per-pixel colour is computed
in small row windows around the pixels the paint reaches (:func:`row_windows`), so the
part of the box the object clips away costs nothing; only what needs neighbours
(blurs, distances, noise) covers the whole patch. :func:`denim_windows` yields the
colour window by window, for painting as it is made; :func:`render_denim` fills the
whole patch. The same inputs and seed give the same bytes however the patch is cut
into windows.

Coordinates follow the package convention (x right, y down, pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``). Photos are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``;
colour is ``float32`` RGB in 0..255, as ``(3, m, n)`` planes per window or ``(h, w, 3)``
for a whole patch; coverage, weights and shading fields are ``(h, w) float32`` in
[0, 1] (shading may exceed 1).

One topic in about 730 lines (the denim's look): the construction details and the weave
are layers that the painter reads window by window through the same private helpers
(:class:`_Layer`, :class:`_Field`), which a split would have to export.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from .garments import Garment, polygon_area

# OpenCV sub-pixel drawing: coordinates carry this many fractional bits.
_SHIFT = 4

# Denim palette (RGB, 0..255): deep and worn indigo, the white weft that shows in
# the twill, golden thread, brass hardware.
_INDIGO_DEEP = np.array([16, 30, 68], np.float32)
_INDIGO_WORN = np.array([92, 124, 172], np.float32)
_WEFT = np.array([178, 188, 206], np.float32)
_THREAD = np.array([222, 150, 52], np.float32)
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

    def lines(self, polylines: list[np.ndarray], width: float, value: float = 1.0) -> None:
        """Stroke open polylines ``(k, 2)`` ``width`` px wide.

        OpenCV only draws whole-pixel widths, so a thinner stroke is drawn 1 px wide and
        faded by its width, which keeps its ink (area x alpha) right.
        """
        if polylines:
            cv2.polylines(
                self.ink,
                [_cv_points(p) for p in polylines],
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
        return _Field(_blur(self.window(rows, cols), sigma), rows.start, cols.start)


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


def _blur(field: np.ndarray, sigma: float) -> np.ndarray:
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


def _smoothstep(x: np.ndarray) -> np.ndarray:
    """``x * x * (3 - 2 x)`` of ``x`` clipped to [0, 1], computed in ``x``'s memory."""
    np.clip(x, 0.0, 1.0, out=x)
    square = x * x
    x *= 2.0
    np.subtract(3.0, x, out=x)
    x *= square
    return x


def _dashes(polyline: np.ndarray, dash: float, gap: float, box: tuple[int, int]) -> list[np.ndarray]:
    """Dash segments ``(2, 2)`` along a polyline ``(k, 2)``, dropping those off the patch
    ``box = (h, w)`` so a huge polygon does not make OpenCV draw millions of dashes."""
    steps = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    if arc[-1] < dash:
        return []
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
    return list(seg[keep])


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


# --------------------------------------------------------------------------- denim


@dataclass(frozen=True)
class _Layout:
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


def _layout(vertices: np.ndarray, garment: Garment) -> _Layout:
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
    return _Layout(vertices, unit, across, down, sign)


class _FrameNoise:
    """Smooth noise (about unit std) with feature sizes ``step_across`` by ``step_down``
    px along the garment's own axes, sampled on any rows of the patch.

    White noise on a coarse grid in garment coordinates, warped onto the patch with
    bicubic interpolation: cheap at any resolution, and streaks follow the garment.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        layout: _Layout,
        shape: tuple[int, int],
        step_across: float,
        step_down: float,
    ) -> None:
        h, w = shape
        corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], np.float64)
        u = corners @ layout.across / step_across
        v = corners @ layout.down / step_down
        cols, rows = int(np.ceil(u.max() - u.min())) + 4, int(np.ceil(v.max() - v.min())) + 4
        self.grid = rng.standard_normal((rows, cols)).astype(np.float32)
        # Patch pixel (c, r), centred at (c + .5, r + .5), lands on grid index
        # (u - u_min + 1.5, v - v_min + 1.5), one cell clear of the border.
        self.to_grid = np.array(
            [
                [*(layout.across / step_across), 0.5 * layout.across.sum() / step_across - u.min() + 1.5],
                [*(layout.down / step_down), 0.5 * layout.down.sum() / step_down - v.min() + 1.5],
            ]
        )
        self.width = w

    def rows(self, top: int, bottom: int, right: int | None = None) -> np.ndarray:
        """``(bottom - top, right) float32`` noise for patch rows ``top:bottom``, columns
        ``0:right`` (default: all). Only where the rows start moves the noise: a pixel's
        value does not depend on how far right or down the rows are drawn."""
        matrix = self.to_grid.copy()
        matrix[:, 2] += matrix[:, 1] * top
        noise = cv2.warpAffine(
            self.grid,
            matrix,
            (self.width if right is None else right, bottom - top),
            flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
        )
        noise *= np.float32(1.0 / 0.8)  # bicubic smoothing leaves about 0.8 std
        return noise


def _ray_hit(layout: _Layout, origin: np.ndarray, direction: np.ndarray) -> float:
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
class _Details:
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

    def __init__(self, layout: _Layout, shape: tuple[int, int]) -> None:
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


def _denim_details(layout: _Layout, shape: tuple[int, int], garment: Garment, rng: np.random.Generator) -> _Details:
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
    return _Details(
        wear=tailor.wear.alpha(0.4 * seam_w),
        grooves=tailor.grooves.alpha(0.5 * seam_w),
        outline=outline.alpha(0.25 * seam_w),
        raised=raised,
        flip=tailor.flip,
        thread=tailor.thread,
        metal=metal,
    )


def _photo_shading(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    weight: np.ndarray,
    unit: float,
) -> Callable[[slice, slice], np.ndarray]:
    """Multiplicative shading from the photo under the jeans, as a function of a window
    ``(rows, cols)`` of the patch that returns the shading there, ``float32``.

    The photo's luminance, blurred so fur or print detail does not imprint on the
    cloth, over its weighted mean under the jeans: 1 on average, below 1 in the
    object's shadows and folds, clipped so a black patch does not blacken the denim.
    """
    x0, y0, x1, y1 = box
    sigma = max(1.0, 0.02 * unit)
    pad = int(np.ceil(3 * sigma))
    h_img, w_img = image.shape[:2]
    px0, py0 = max(x0 - pad, 0), max(y0 - pad, 0)
    px1, py1 = min(x1 + pad, w_img), min(y1 + pad, h_img)
    to_grey = cv2.COLOR_RGBA2GRAY if image.shape[2] == 4 else cv2.COLOR_RGB2GRAY
    luma = cv2.cvtColor(image[py0:py1, px0:px1], to_grey)
    luma = _blur(luma.astype(np.float32), sigma)[y0 - py0 : y1 - py0, x0 - px0 : x1 - px0]
    total = float(weight.sum(dtype=np.float64))
    mean = float((luma * weight).sum(dtype=np.float64) / total) if total > 0 else float(luma.mean())
    gain = np.float32(1.0 / max(mean, 1.0))

    def shade(rows: slice, cols: slice) -> np.ndarray:
        out = luma[rows, cols] * gain
        np.clip(out, 0.4, 1.6, out=out)
        return np.power(out, np.float32(0.8), out=out)

    return shade


# Rows of the patch whose noise is drawn at a time, to bound the noise's temporaries.
# The noise of a strip depends on where strips start, so this also fixes the bytes.
_TEXTURE_ROWS = 256
# Rows of the per-pixel work at a time: windows this small keep their float
# temporaries in cache and hug the painted pixels (a divisor of _TEXTURE_ROWS).
_WINDOW_ROWS = 16
# At least this many empty columns split a window in two (between the legs, say):
# narrower gaps cost less to compute than another window's per-call overhead.
_WINDOW_GAP = 128


def row_windows(needed: np.ndarray, top: int = 0) -> list[tuple[slice, slice]]:
    """``(rows, cols)`` boxes of at most ``_WINDOW_ROWS`` rows that hold every True pixel
    of ``needed`` ``(h, w)``, rows offset by ``top``.

    The object clips about half the jeans' bounding box away; per-pixel work done in
    these boxes skips most of that, without the cost of gathering scattered pixels.
    """
    boxes = []
    for start in range(0, needed.shape[0], _WINDOW_ROWS):
        chunk = needed[start : start + _WINDOW_ROWS]
        cols = np.flatnonzero(chunk.any(axis=0))
        if not cols.size:
            continue
        used = np.flatnonzero(chunk.any(axis=1))
        rows = slice(top + start + int(used[0]), top + start + int(used[-1]) + 1)
        gaps = np.flatnonzero(np.diff(cols) > _WINDOW_GAP)
        for left, right in zip(cols[np.r_[0, gaps + 1]], cols[np.r_[gaps, cols.size - 1]]):
            boxes.append((rows, slice(int(left), int(right) + 1)))
    return boxes


@dataclass(frozen=True)
class _Cloth:
    """What the per-pixel denim of one patch reads, made once before the windows."""

    details: _Details
    depth: np.ndarray  # (h, w) float32 distance (px) from the outline, inside the garment
    blotches: _FrameNoise  # blotchy fading
    slubs: _FrameNoise  # slubby warp yarns: streaks along the legs
    wobble: _FrameNoise  # the twill's yarn wobble
    shading: Callable[[slice, slice], np.ndarray]  # see _photo_shading
    seed: int
    to_wear: np.float32  # 1 / (0.16 unit): depth to the panel's wear
    to_occlusion: np.float32  # 1 / (0.07 unit): depth to the outline's occlusion
    scale: np.float32  # the twill's phase per pixel
    across: np.ndarray  # (2,) float32, layout.across
    down: np.ndarray  # (2,) float32, layout.down
    cx: np.ndarray  # (1, w) float32 x of the pixel centres


def _cloth(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    vertices: np.ndarray,
    coverage: np.ndarray,
    weight: np.ndarray,
    garment: Garment,
    seed: int,
) -> _Cloth:
    """The construction details, noise fields and shading of the patch (the arguments
    are those of :func:`denim_windows`); the seed's generator draws the details first,
    then the noise grids, in this fixed order."""
    layout = _layout(vertices, garment)
    shape = coverage.shape
    unit = layout.unit
    rng = np.random.default_rng(seed)
    details = _denim_details(layout, shape, garment, rng)

    # Wear: lighter down the middle of each panel (it rubs), blotchy fading, and
    # slubby warp yarns (streaks along the legs); a soft occlusion towards the outline
    # makes the legs look round.
    depth = cv2.distanceTransform(np.greater(coverage, 0.5).view(np.uint8), cv2.DIST_L2, 3)
    period = max(3.0, unit / 170.0)
    blotches = _FrameNoise(rng, layout, shape, 0.12 * unit, 0.2 * unit)
    slubs = _FrameNoise(rng, layout, shape, 1.3 * period, 25 * period)
    wobble = _FrameNoise(rng, layout, shape, 4 * period, 4 * period)
    shading = _photo_shading(image, box, weight, unit)
    to_wear, to_occlusion = np.float32(1.0 / (0.16 * unit)), np.float32(1.0 / (0.07 * unit))
    return _Cloth(
        details=details,
        depth=depth,
        blotches=blotches,
        slubs=slubs,
        wobble=wobble,
        shading=shading,
        seed=seed,
        to_wear=to_wear,
        to_occlusion=to_occlusion,
        scale=np.float32(2 * np.pi / period),
        across=layout.across.astype(np.float32),
        down=layout.down.astype(np.float32),
        cx=(np.arange(shape[1], dtype=np.float32) + 0.5)[None, :],
    )


@dataclass(frozen=True)
class _StripNoise:
    """The noise of one strip of ``_TEXTURE_ROWS`` rows starting at patch row ``top``,
    as ``(rows, columns) float32`` arrays from the strip's first row and column 0."""

    top: int
    wobble: np.ndarray
    blotches: np.ndarray
    slubs: np.ndarray
    grain: np.ndarray  # blurred white noise: the yarn's grain

    def local(self, rows: slice) -> slice:
        """Patch rows ``rows`` as rows of the strip's arrays."""
        return slice(rows.start - self.top, rows.stop - self.top)


def _strip_noise(cloth: _Cloth, strip: int, top: int, boxes: list[tuple[slice, slice]]) -> _StripNoise:
    """The noise of strip number ``strip`` (from row ``top``), drawn only as far right
    and down as its windows ``boxes`` need (the grain's blur reaches 2 rows further)."""
    h, w = cloth.depth.shape
    bottom = max(rows.stop for rows, _ in boxes)
    right = max(cols.stop for _, cols in boxes)
    wobble = cloth.wobble.rows(top, bottom, right)
    blotches = cloth.blotches.rows(top, bottom, right)
    slubs = cloth.slubs.rows(top, bottom, right)
    strip_rng = np.random.default_rng([cloth.seed, strip])
    grain_rows = min(bottom + 2, top + _TEXTURE_ROWS, h) - top
    grain = _blur(strip_rng.standard_normal((grain_rows, w), dtype=np.float32), 0.5)
    return _StripNoise(top, wobble, blotches, slubs, grain)


# The per-window helpers below run their arithmetic in place but keep the float32
# operations and their order as written in their docstrings, so the bytes do not
# depend on the windows; a layer with no ink in a window is skipped (x * 1, x + 0).


def _twill(cloth: _Cloth, noise: _StripNoise, rows: slice, cols: slice) -> np.ndarray:
    """2/1 twill over a window: ridges at 45 degrees to the garment axes, rising to the
    right as on right-hand twill (mirrored where ``flip``: on the cross-grain
    waistband), wobbling like real yarn; sharpened from a sine into flat-topped ridges
    in [0, 1]:
    smoothstep(0.5 + 0.9 * sin((along + downs * (1 - 2 flip)) * scale + 0.35 wobble)).
    """
    cy = (np.arange(rows.start, rows.stop, dtype=np.float32) + 0.5)[:, None]
    x = cloth.cx[:, cols]
    across, down = cloth.across, cloth.down
    twill = x * down[0] + cy * down[1]
    flip = cloth.details.flip.window(rows, cols)
    if flip is not None:
        twill *= 1.0 - 2.0 * flip
    twill += x * across[0] + cy * across[1]
    twill *= cloth.scale
    twill += np.float32(0.35) * noise.wobble[noise.local(rows), cols]
    np.sin(twill, out=twill)
    twill *= 0.9
    twill += 0.5
    return _smoothstep(twill)


def _fade(cloth: _Cloth, noise: _StripNoise, rows: slice, cols: slice) -> np.ndarray:
    """The indigo's fading over a window, 0 (deep) .. 1 (worn):
    clip(wear + (0.15 + 0.32 * smoothstep(depth / (0.16 unit))) + 0.12 blotches
    + 0.06 slubs, 0, 1)."""
    local = noise.local(rows)
    fade = 0.15 + 0.32 * _smoothstep(cloth.depth[rows, cols] * cloth.to_wear)
    wear = cloth.details.wear.window(rows, cols)
    if wear is not None:
        fade += wear
    fade += 0.12 * noise.blotches[local, cols]
    fade += 0.06 * noise.slubs[local, cols]
    np.clip(fade, 0.0, 1.0, out=fade)
    return fade


def _light(cloth: _Cloth, rows: slice, cols: slice) -> np.ndarray:
    """The cloth's lighting over a window: construction shadows, occlusion, the photo's
    folds, dark * (0.7 + 0.3 * smoothstep(depth / (0.07 unit))) * shading."""
    light = cloth.details.dark(rows, cols)
    light *= 0.7 + 0.3 * _smoothstep(cloth.depth[rows, cols] * cloth.to_occlusion)
    light *= cloth.shading(rows, cols)
    return light


def _window_colour(cloth: _Cloth, noise: _StripNoise, rows: slice, cols: slice) -> np.ndarray:
    """The denim's ``(3, m, n) float32`` colour planes (0..255) over a window."""
    twill = _twill(cloth, noise, rows, cols)
    fade = _fade(cloth, noise, rows, cols)
    grain = 0.07 * noise.grain[noise.local(rows), cols]
    grain += 1.0
    weft = 0.22 * fade
    weft += 0.1
    weft *= twill  # (0.1 + 0.22 * fade) * twill
    thread = cloth.details.thread.window(rows, cols)
    light = _light(cloth, rows, cols)
    ridge = 0.3 * twill
    weave = ridge + 0.82
    ridge += 0.75
    colour = np.empty((3, *fade.shape), np.float32)
    base, mix = np.empty_like(fade), np.empty_like(fade)
    for c in range(3):
        # base = (deep + (worn - deep) * fade) * (0.82 + 0.3 twill), darker in
        # the twill's valleys; base += weft * (WEFT - base), the weft showing;
        # base *= grain; base += thread * (THREAD * (0.75 + 0.3 twill) - base);
        # colour = base * light.
        np.multiply(fade, _INDIGO_WORN[c] - _INDIGO_DEEP[c], out=base)
        base += _INDIGO_DEEP[c]
        base *= weave
        np.subtract(_WEFT[c], base, out=mix)
        mix *= weft
        base += mix
        base *= grain
        if thread is not None:
            np.multiply(ridge, _THREAD[c], out=mix)
            mix -= base
            mix *= thread
            base += mix
        np.multiply(base, light, out=colour[c])
    _paint_metal(colour, light, rows, cols, cloth.details.metal)
    return colour


def denim_windows(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    vertices: np.ndarray,
    coverage: np.ndarray,
    weight: np.ndarray,
    garment: Garment,
    seed: int,
    needed: np.ndarray,
) -> Iterator[tuple[slice, slice, np.ndarray]]:
    """Denim colour over the patch ``box`` of ``image``, one window at a time.

    Args:
        image: the photo, whose luminance under the patch shades the denim.
        box: the patch ``(x0, y0, x1, y1)`` in ``image`` pixels.
        vertices: ``(n, 2)`` garment polygon in patch pixels, garment vertex order.
        coverage: ``(h, w)`` the polygon's pixel coverage over the patch.
        weight: ``(h, w)`` the jeans' final alpha, which sets the shading's mean.
        garment: what the polygon is a fit of (waist, open edges, style).
        seed: seeds the noise; the same inputs give the same bytes.
        needed: ``(h, w) bool``, the pixels whose colour is wanted.

    Yields:
        ``(rows, cols, colour)`` for each of the :func:`row_windows` of ``needed``,
        ``colour`` being the window's ``(3, m, n) float32`` planes (0..255).
    """
    cloth = _cloth(image, box, vertices, coverage, weight, garment, seed)
    for strip, top in enumerate(range(0, coverage.shape[0], _TEXTURE_ROWS)):
        boxes = row_windows(needed[top : top + _TEXTURE_ROWS], top)
        if not boxes:
            continue
        noise = _strip_noise(cloth, strip, top, boxes)
        for rows, cols in boxes:
            yield rows, cols, _window_colour(cloth, noise, rows, cols)


def render_denim(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    vertices: np.ndarray,
    coverage: np.ndarray,
    weight: np.ndarray,
    garment: Garment,
    seed: int,
) -> np.ndarray:
    """Denim colour ``(h, w, 3) float32`` (0..255) over the whole patch ``box`` of
    ``image``; the arguments are those of :func:`denim_windows`."""
    out = np.empty((*coverage.shape, 3), np.float32)
    everywhere = np.broadcast_to(np.True_, coverage.shape)  # no memory
    for rows, cols, colour in denim_windows(image, box, vertices, coverage, weight, garment, seed, everywhere):
        out[rows, cols] = np.moveaxis(colour, 0, -1)
    return out


def _paint_metal(colour: np.ndarray, light: np.ndarray, rows: slice, cols: slice, metal: list) -> None:
    """Domed brass button and copper rivets, lit from the top left, painted onto the
    ``(3, m, n)`` colour planes of the patch window ``(rows, cols)``, whose cloth
    lighting is ``light`` ``(m, n)``. Each is drawn only where its own box meets the window."""
    for centre, radius, rgb in metal:
        r = radius * 1.6
        c0, c1 = max(int(centre[0] - r), cols.start), min(int(np.ceil(centre[0] + r)) + 1, cols.stop)
        r0, r1 = max(int(centre[1] - r), rows.start), min(int(np.ceil(centre[1] + r)) + 1, rows.stop)
        if c1 <= c0 or r1 <= r0:
            continue
        dx = (np.arange(c0, c1, dtype=np.float32) + 0.5 - centre[0])[None, :] / radius
        dy = (np.arange(r0, r1, dtype=np.float32) + 0.5 - centre[1])[:, None] / radius
        dist = np.sqrt(dx * dx + dy * dy)
        aa = 1.0 / max(radius, 1.0)
        disc = np.clip((1.0 - dist) / aa + 0.5, 0, 1)
        shadow = np.clip((1.0 - np.sqrt((dx - 0.25) ** 2 + (dy - 0.3) ** 2)) / 0.3, 0, 1)
        # Dome normal's z, and the highlight where it faces the light.
        nz = np.sqrt(np.clip(1 - dist * dist, 0, 1))
        lit = np.clip(0.5 + 0.6 * (-0.5 * dx - 0.6 * dy + 0.6 * nz), 0.25, 1.4)
        spec = np.clip(1 - np.sqrt((dx + 0.35) ** 2 + (dy + 0.4) ** 2) / 0.35, 0, 1) ** 2
        rim = np.clip((dist - 0.72) / 0.28, 0, 1)
        inside = (slice(r0 - rows.start, r1 - rows.start), slice(c0 - cols.start, c1 - cols.start))
        window = np.moveaxis(colour[:, inside[0], inside[1]], 0, -1)
        window *= (1 - 0.5 * shadow)[..., None]
        paint = rgb * (lit * (1 - 0.45 * rim))[..., None] + 255 * spec[..., None] * 0.7
        paint *= np.sqrt(light[inside])[..., None]
        window += disc[..., None] * (paint - window)
