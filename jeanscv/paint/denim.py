"""Procedural denim: what the jeans painted on a photo look like.

An indigo 2/1 twill, worn and shaded by the photo's own blurred luminance so the
object's folds and shadows show through, under the construction details of
:mod:`jeanscv.paint.denim_details` (seams, stitching, hardware). Everything is sized in units
of the garment's own size, so the jeans read the same on a thumbnail and on a 24-MP
photo.

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
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from ..fitting.garments import Garment
from .denim_details import Details, Layout, blur, draw_details, garment_layout

# Denim palette (RGB, 0..255): deep and worn indigo, the white weft that shows in
# the twill, golden thread.
_INDIGO_DEEP = np.array([16, 30, 68], np.float32)
_INDIGO_WORN = np.array([92, 124, 172], np.float32)
_WEFT = np.array([178, 188, 206], np.float32)
_THREAD = np.array([222, 150, 52], np.float32)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    """``x * x * (3 - 2 x)`` of ``x`` clipped to [0, 1], computed in ``x``'s memory."""
    np.clip(x, 0.0, 1.0, out=x)
    square = x * x
    x *= 2.0
    np.subtract(3.0, x, out=x)
    x *= square
    return x


class _FrameNoise:
    """Smooth noise (about unit std) with feature sizes ``step_across`` by ``step_down``
    px along the garment's own axes, sampled on any rows of the patch.

    White noise on a coarse grid in garment coordinates, warped onto the patch with
    bicubic interpolation: cheap at any resolution, and streaks follow the garment.
    """

    def __init__(
        self,
        rng: np.random.Generator,
        layout: Layout,
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


#: The cloth's shading over a window ``(rows, cols)`` of the patch (see :func:`_photo_shading`).
_Shading = Callable[[slice, slice], np.ndarray]


def _photo_shading(
    image: np.ndarray,
    box: tuple[int, int, int, int],
    weight: np.ndarray,
    unit: float,
) -> _Shading:
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
    luma = blur(luma.astype(np.float32), sigma)[y0 - py0 : y1 - py0, x0 - px0 : x1 - px0]
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
# temporaries in cache and hug the painted pixels (a divisor of _TEXTURE_ROWS). 32
# rather than 16 halves the windows' per-call overhead: on the 18 shared photos at
# 12 MP and 4 textured scenes the denim took 0.173 s a photo against 0.185 (64: 0.177).
_WINDOW_ROWS = 32
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

    details: Details
    depth: np.ndarray  # (h, w) float32 distance (px) from the outline, inside the garment
    blotches: _FrameNoise  # blotchy fading
    slubs: _FrameNoise  # slubby warp yarns: streaks along the legs
    wobble: _FrameNoise  # the twill's yarn wobble
    shading: _Shading
    seed: int
    to_wear: np.float32  # 1 / (0.16 unit): depth to the panel's wear
    to_occlusion: np.float32  # 1 / (0.07 unit): depth to the outline's occlusion
    scale: np.float32  # the twill's phase per pixel
    across: np.ndarray  # (2,) float32, layout.across
    down: np.ndarray  # (2,) float32, layout.down
    cx: np.ndarray  # (1, w) float32 x of the pixel centres


def _cloth(layout: Layout, coverage: np.ndarray, shading: _Shading, garment: Garment, seed: int) -> _Cloth:
    """The patch's construction details, depth and noise fields, with the photo's
    ``shading``; the seed's generator draws the details first, then the noise grids
    (keyword arguments run in the order written)."""
    shape = coverage.shape
    unit = layout.unit
    rng = np.random.default_rng(seed)
    period = max(3.0, unit / 170.0)
    return _Cloth(
        details=draw_details(layout, shape, garment, rng),
        # Wear: lighter down the middle of each panel (it rubs), blotchy fading, and
        # slubby warp yarns (streaks along the legs); a soft occlusion towards the
        # outline makes the legs look round.
        depth=cv2.distanceTransform(np.greater(coverage, 0.5).view(np.uint8), cv2.DIST_L2, 3),
        blotches=_FrameNoise(rng, layout, shape, 0.12 * unit, 0.2 * unit),
        slubs=_FrameNoise(rng, layout, shape, 1.3 * period, 25 * period),
        wobble=_FrameNoise(rng, layout, shape, 4 * period, 4 * period),
        shading=shading,
        seed=seed,
        to_wear=np.float32(1.0 / (0.16 * unit)),
        to_occlusion=np.float32(1.0 / (0.07 * unit)),
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
    grain = blur(strip_rng.standard_normal((grain_rows, w), dtype=np.float32), 0.5)
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
    layout = garment_layout(vertices, garment)
    cloth = _cloth(layout, coverage, _photo_shading(image, box, weight, layout.unit), garment, seed)
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
