"""Paint the fitted jeans onto the original photo, and draw the paper's figures.

Everything is computed only inside the jeans polygon's bounding box (plus a small
margin), at the photo's full resolution, so a 24-MP photo costs about as much as the
jeans it wears. Pixels outside that box are returned byte-identical. Inside it, the
painting runs in small row windows around the pixels the paint reaches
(:func:`jeanscv.paint.denim.row_windows`), skipping the part of the box the object clips
away. What the ``"denim"`` style looks like is made in :mod:`jeanscv.paint.denim`; this
module clips it to the object and composites it over the photo.

Coordinates follow the package convention (x right, y down, pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``). Images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA
``uint8``; coverage and masks are ``(h, w) float32`` in [0, 1].
"""

from __future__ import annotations

import cv2
import numpy as np

from ..errors import JeansError
from ..fitting.garments import JEANS, Garment
from ..fitting.objectives import polygon_coverage
from ..options import STYLES
from .denim import denim_windows, render_denim, row_windows

#: The paper's jeans colour (RGB), used by ``style="flat"`` and the figures.
FLAT_BLUE = (0, 0, 255)

# Vertices farther out than this (pixels) cannot come from a sane fit, and would
# overflow OpenCV's fixed-point drawing coordinates.
_MAX_COORD = float(2**22)
# Rows x columns rasterized per coverage strip, to bound memory on huge photos.
_STRIP_PIXELS = 1 << 21


def _check_vertices(vertices: np.ndarray, garment: Garment) -> np.ndarray:
    try:
        vertices = np.asarray(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise JeansError("jeans vertices are not numbers") from None
    if vertices.shape != (garment.num_vertices, 2):
        raise JeansError(f"jeans vertices must have shape ({garment.num_vertices}, 2), got {vertices.shape}")
    if not np.all(np.isfinite(vertices)):
        raise JeansError("jeans vertices are not finite")
    if np.abs(vertices).max() > _MAX_COORD:
        raise JeansError("jeans vertices lie too far outside the image")
    return vertices


def _patch_box(vertices: np.ndarray, height: int, width: int, margin: int = 2) -> tuple[int, int, int, int] | None:
    """``(x0, y0, x1, y1)`` of the polygon's pixels plus ``margin``, clipped to the image;
    None when the polygon misses the image."""
    x0 = max(int(np.floor(vertices[:, 0].min())) - margin, 0)
    y0 = max(int(np.floor(vertices[:, 1].min())) - margin, 0)
    x1 = min(int(np.ceil(vertices[:, 0].max())) + margin, width)
    y1 = min(int(np.ceil(vertices[:, 1].max())) + margin, height)
    return (x0, y0, x1, y1) if x1 > x0 and y1 > y0 else None


def polygon_coverage_patch(vertices: np.ndarray, height: int, width: int) -> np.ndarray:
    """Exact anti-aliased coverage of a polygon on an ``height x width`` pixel grid.

    Args:
        vertices: ``(n, 2)`` polygon in the grid's pixels (non-zero fill rule).

    Returns:
        ``(height, width) float32`` pixel area covered, in [0, 1]: the exact box-filtered
        area (the fitter's own rasterizer), computed in row strips so memory stays small.
    """
    out = np.empty((height, width), np.float32)
    rows = max(1, _STRIP_PIXELS // max(width, 1))
    for top in range(0, height, rows):
        strip = min(rows, height - top)
        out[top : top + strip] = polygon_coverage(vertices - np.array([0.0, top]), strip, width)
    return out


# --------------------------------------------------------------------------- public API


def _check_image(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] not in (3, 4):
        raise JeansError(f"image must be an H x W x 3 or 4 uint8 array, got {image.dtype} {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise JeansError("image is empty")
    return image


def _clip_weight(image: np.ndarray, mask: np.ndarray | None, box: tuple[int, int, int, int]) -> np.ndarray | None:
    """The object's coverage ``(h, w) float32`` over the patch (a new array, which callers
    may scale in place), or None for no clipping.

    A float mask is taken as alpha; a boolean one is softened over about one pixel, so
    its staircase edge does not show on the jeans' outline.
    """
    x0, y0, x1, y1 = box
    if mask is None:
        if image.shape[2] == 4:
            return image[y0:y1, x0:x1, 3].astype(np.float32) / 255.0
        return None
    mask = np.asarray(mask)
    if mask.shape != image.shape[:2]:
        raise JeansError(f"mask shape {mask.shape} does not match the image {image.shape[:2]}")
    if mask.dtype == bool:
        # Blur with a 1-px apron so the patch edge sees the mask beyond it.
        top, left = max(y0 - 1, 0), max(x0 - 1, 0)
        crop = mask[top : y1 + 1, left : x1 + 1].astype(np.float32)
        crop = cv2.GaussianBlur(crop, (3, 3), 0.6, borderType=cv2.BORDER_REPLICATE)
        return np.ascontiguousarray(crop[y0 - top : y1 - top, x0 - left : x1 - left])
    if not np.issubdtype(mask.dtype, np.number):
        raise JeansError(f"mask must be boolean or numeric, got {mask.dtype}")
    crop = mask[y0:y1, x0:x1].astype(np.float32, copy=False)  # clipped into a new array below
    if mask.dtype == np.uint8:
        crop /= 255.0
    if not np.all(np.isfinite(crop)):
        raise JeansError("mask is not finite")
    return np.clip(crop, 0.0, 1.0)


def _painted(alpha: np.ndarray) -> np.ndarray:
    """Where paint of ``alpha`` ``(h, w)`` shows: below half a level it changes no byte of
    an opaque pixel, and skipping it keeps float dust from the coverage's sums off the
    untouched pixels."""
    return alpha > 0.5 / 255


def _paint_over(patch: np.ndarray, colour: np.ndarray, alpha: np.ndarray, painted: np.ndarray) -> None:
    """Composite ``colour`` (``(3, h, w)`` float32 planes, or one ``(3,)`` colour) over
    the uint8 ``patch`` (RGB or RGBA, in place) with ``alpha`` ``(h, w)``; "over" on RGBA.

    One channel at a time and only where the paint shows (``painted``, from
    :func:`_painted`), so untouched pixels keep their bytes.
    """
    if patch.shape[2] == 4:
        below = patch[..., 3].astype(np.float32) * np.float32(1 / 255)
        below *= 1.0 - alpha  # the photo's share of the result
        over = alpha + below
        safe_over = np.maximum(over, 1e-6)
        np.copyto(patch[..., 3], np.rint(over * 255.0), casting="unsafe", where=painted)
    for c in range(3):
        src = patch[..., c].astype(np.float32)
        if patch.shape[2] == 4:
            mixed = (colour[c] * alpha + src * below) / safe_over
        else:
            mixed = colour[c] - src
            mixed *= alpha
            mixed += src
        np.clip(np.rint(mixed, out=mixed), 0, 255, out=mixed)
        np.copyto(patch[..., c], mixed, casting="unsafe", where=painted)


def _paint_windows(patch: np.ndarray, colour: np.ndarray, alpha: np.ndarray, painted: np.ndarray) -> None:
    """:func:`_paint_over` window by window (:func:`row_windows` of ``painted``), so a huge
    patch needs no float images; ``colour`` is ``(3, h, w)`` planes or one ``(3,)`` colour."""
    for rows, cols in row_windows(painted):
        window = colour[:, rows, cols] if colour.ndim == 3 else colour
        _paint_over(patch[rows, cols], window, alpha[rows, cols], painted[rows, cols])


def composite_jeans(
    image: np.ndarray,
    vertices: np.ndarray,
    garment: Garment = JEANS,
    mask: np.ndarray | None = None,
    *,
    style: str = "denim",
    clip: bool = True,
    seed: int = 0,
) -> np.ndarray:
    """Paint the fitted jeans onto a photo.

    Args:
        image: ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8`` photo, full resolution.
        vertices: ``(n, 2)`` fitted garment polygon in image pixels, garment vertex order.
        garment: the garment the polygon is a fit of (its waist and open edges place
            the waistband, hems and seams).
        mask: ``(H, W)`` object silhouette, bool or float alpha in [0, 1] (uint8 is
            read as 0..255). With ``clip=True`` the jeans are painted only on it; without
            a mask, an RGBA image's alpha is used, and an RGB image is not clipped.
        style: ``"denim"`` (procedural indigo jeans shaded by the photo) or ``"flat"``
            (the paper's opaque blue ``(0, 0, 255)``).
        clip: paint only on the object (True) or the whole polygon (False).
        seed: seeds the denim's noise; the same inputs and seed give the same bytes.

    Returns:
        A new array of the same shape and dtype. Pixels outside the polygon's bounding
        box (plus 2 px) are byte-identical to ``image``; alpha is composited "over",
        so jeans painted on transparent pixels get alpha equal to their coverage.
    """
    image = _check_image(image)
    vertices = _check_vertices(vertices, garment)
    if style not in STYLES:
        raise JeansError(f"unknown style {style!r} (known: {', '.join(STYLES)})")
    out = image.copy()
    box = _patch_box(vertices, *image.shape[:2])
    if box is None:
        return out
    x0, y0, x1, y1 = box
    local = vertices - np.array([x0, y0], np.float64)
    if style != "flat" and (y1 - y0) * (x1 - x0) > DENIM_MAX_PIXELS:
        _composite_large(out, image, box, local, mask if clip else None, clip, garment, seed)
        return out
    coverage = polygon_coverage_patch(local, y1 - y0, x1 - x0)
    weight = _clip_weight(image, mask, box) if clip else None
    alpha = coverage if weight is None else np.multiply(weight, coverage, out=weight)
    painted = _painted(alpha)
    if not painted.any():
        return out

    patch = out[y0:y1, x0:x1]
    if style == "flat":
        _paint_windows(patch, np.array(garment.extra.get("colour", FLAT_BLUE), np.float32), alpha, painted)
        return out
    # Each window of denim is painted as soon as it is made, while it is in cache.
    denim = denim_windows(image, box, local, coverage, alpha, garment, seed, painted)
    for rows, cols, colour in denim:
        _paint_over(patch[rows, cols], colour, alpha[rows, cols], painted[rows, cols])
    return out


#: Largest garment box (pixels) whose denim is rendered at full resolution. Bigger ones
#: are rendered on a reduced grid and upsampled, which bounds the memory of the many
#: float layers (about 70 bytes a pixel) on 24-MP photos; the texture scales with the
#: garment, so it only softens slightly.
DENIM_MAX_PIXELS = 4_000_000


def _composite_large(
    out: np.ndarray,
    image: np.ndarray,
    box: tuple[int, int, int, int],
    local: np.ndarray,
    mask: np.ndarray | None,
    clip: bool,
    garment: Garment,
    seed: int,
) -> None:
    """Denim over a box larger than ``DENIM_MAX_PIXELS``, painted into ``out`` in place.

    The denim is rendered on a reduced grid of at most ``DENIM_MAX_PIXELS`` (the texture
    scales with the garment, so it only softens) and the full-resolution work
    (coverage, clip weight, upsampling, painting) runs in row strips, so memory stays
    bounded whatever the photo's size.
    """
    x0, y0, x1, y1 = box
    h, w = y1 - y0, x1 - x0
    factor = float(np.sqrt(DENIM_MAX_PIXELS / float(h * w)))
    small_w, small_h = max(1, round(w * factor)), max(1, round(h * factor))
    sx, sy = small_w / w, small_h / h
    small_vertices = local * np.array([sx, sy])
    small_image = cv2.resize(image[y0:y1, x0:x1], (small_w, small_h), interpolation=cv2.INTER_AREA)
    small_coverage = polygon_coverage_patch(small_vertices, small_h, small_w)
    small_alpha = small_coverage
    if clip:
        small_weight = _clip_weight(small_image, _resized_mask(mask, box, (small_w, small_h)), (0, 0, small_w, small_h))
        if small_weight is not None:
            small_alpha = np.multiply(small_weight, small_coverage, out=small_weight)
    small = render_denim(
        small_image,
        (0, 0, small_w, small_h),
        small_vertices,
        small_coverage,
        small_alpha,
        garment,
        seed,
    )
    rows = max(1, _STRIP_PIXELS // max(w, 1))
    for top in range(0, h, rows):
        strip = (x0, y0 + top, x1, min(y0 + top + rows, y1))
        height = strip[3] - strip[1]
        coverage = polygon_coverage_patch(local - np.array([0.0, top]), height, w)
        weight = _clip_weight(image, mask, strip) if clip else None
        alpha = coverage if weight is None else np.multiply(weight, coverage, out=weight)
        painted = _painted(alpha)
        if not painted.any():
            continue
        # The strip's rows of the upsampled denim: INTER_LINEAR resize with pixel
        # centres at +0.5, written as the inverse affine map of warpAffine.
        to_small = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, (top + 0.5) * sy - 0.5]])
        jeans = cv2.warpAffine(
            small,
            to_small,
            (w, height),
            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
            borderMode=cv2.BORDER_REPLICATE,
        )
        _paint_windows(out[strip[1] : strip[3], x0:x1], np.moveaxis(jeans, -1, 0), alpha, painted)


def _resized_mask(mask: np.ndarray | None, box: tuple[int, int, int, int], size: tuple[int, int]) -> np.ndarray | None:
    """The mask's crop over ``box`` as float alpha resized to ``size`` (area averaging)."""
    if mask is None:
        return None
    x0, y0, x1, y1 = box
    crop = np.asarray(mask)[y0:y1, x0:x1]
    if crop.dtype == bool:
        crop = crop.astype(np.uint8) * np.uint8(255)
    elif crop.dtype != np.uint8:
        crop = np.clip(crop.astype(np.float32), 0.0, 1.0)
    resized = cv2.resize(crop, size, interpolation=cv2.INTER_AREA)
    return resized.astype(np.float32) / 255.0 if resized.dtype == np.uint8 else resized


def render_silhouette_figure(
    silhouette: np.ndarray,
    vertices: np.ndarray | None,
    garment: Garment = JEANS,
    supersample: int = 4,
) -> np.ndarray:
    """The paper's figure: black silhouette on white, blue jeans on top.

    Args:
        silhouette: ``(H, W)`` float alpha in [0, 1] (bool accepted), used as coverage.
        vertices: ``(n, 2)`` jeans polygon in the silhouette's pixels, or None to draw
            the silhouette alone.
        supersample: accepted for API stability; the jeans' coverage is the exact pixel
            area (the fitter's rasterizer), which any supersampling only approximates.

    Returns:
        ``(H, W, 3) uint8`` RGB.
    """
    sil = np.asarray(silhouette)
    if sil.ndim != 2 or sil.size == 0:
        raise JeansError(f"silhouette must be a non-empty H x W array, got shape {sil.shape}")
    if not (np.issubdtype(sil.dtype, np.number) or sil.dtype == bool):
        raise JeansError(f"silhouette must be boolean or numeric, got {sil.dtype}")
    if int(supersample) < 1:
        raise JeansError("supersample must be at least 1")
    sil = np.clip(sil.astype(np.float32), 0.0, 1.0)
    if not np.all(np.isfinite(sil)):
        raise JeansError("silhouette is not finite")
    figure = np.repeat((255.0 * (1.0 - sil))[..., None], 3, axis=2)
    if vertices is not None:
        vertices = _check_vertices(vertices, garment)
        box = _patch_box(vertices, *sil.shape)
        if box is not None:
            x0, y0, x1, y1 = box
            cover = polygon_coverage_patch(vertices - np.array([x0, y0], np.float64), y1 - y0, x1 - x0)
            patch = figure[y0:y1, x0:x1]
            colour = np.array(garment.extra.get("colour", FLAT_BLUE), np.float32)
            patch += cover[..., None] * (colour - patch)
    return np.clip(np.rint(figure), 0, 255).astype(np.uint8)
