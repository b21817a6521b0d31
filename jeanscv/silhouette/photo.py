"""Classical-CV segmentation of a photo into the silhouette of its main object.

Public API: :func:`segment` (photo -> :class:`Segmentation`) and :func:`clean_mask`.

Arrays: images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; masks are
``(H, W) bool`` with True on the object. Contours are ``(N, 2) float64`` ``(x, y)`` in
image pixels, package convention (pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``).

All heavy work happens on a copy whose long side is at most ``working_size``; GrabCut's
first pass runs on an even smaller copy (long side <= 320) and is then refined in a band
around its boundary at working resolution. The cleaned working mask is upsampled to the
input resolution with linear interpolation and thresholded at 0.5 (a given alpha or mask
decides the pixels within one working pixel of the boundary at full resolution), so a
24-MP photo costs about as much as a 640-pixel one (about 1 s, 0.5 GB peak).

How ``auto`` chooses (no alpha, mask or rect given): the border of the image is taken
as a sample of the background. Candidates are Otsu splits of four channels at two blurs
and GrabCut seeded where colours are rare on the border (weighted by a spectral-residual
saliency map), on the image and on a texture-blurred copy. Each is scored by
``agreement`` (F-measure with the region whose colours the border does not explain) x
``contrast`` (how strongly its boundary separates locally different colours) x
``(1 - border contact)``; the best wins, and ``details`` records every score.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from skimage.measure import find_contours

from jeanscv.errors import JeansError

METHODS = ("auto", "alpha", "threshold", "grabcut", "mask")

_COARSE_SIZE = 320  # long side of GrabCut's first pass (speed: graph cuts are superlinear)
_COARSE_ITERATIONS = 5  # GrabCut iterations of the first pass
# A colour GrabCut scoring this high is not second-guessed by the texture variant,
# which saves a third of GrabCut's time: on 48 synthetic photos the texture variant
# only ever won against colour scores under 0.77.
_CONFIDENT_SCORE = 0.8
_MIN_FRACTION = 0.005  # smaller objects are treated as "nothing found"
_FULL_FRACTION = 0.98  # photo masks covering more than this are "the whole frame"
_KEEP_FRACTION = 0.25  # extra components kept if at least this fraction of the largest
_MORPH_FRACTION = 0.01  # open/close radius as a fraction of sqrt(object area)
_BORDER_FULL = 0.5  # a border counts as covered when this fraction of it is object
_BLUR_MARGIN = 0.02  # texture-blurred thresholds must beat sharp ones by this score
_CONTRAST_SIGMA = 2.0  # neighbourhood (coarse pixels) on which boundary contrast is judged


@dataclass
class Segmentation:
    """Result of :func:`segment`.

    mask: (H, W) bool at the input's resolution, True on the object.
    method: the method actually used ("alpha", "threshold", "grabcut" or "mask").
    contour: (N, 2) float64 (x, y) image pixels: the outer boundary of the largest
        component, clockwise on screen (positive shoelace area with y down), not closed
        (the last point is not repeated).
    details: what was chosen and why (thresholds, channels, candidate scores, ...).
    """

    mask: np.ndarray
    method: str
    contour: np.ndarray
    details: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------- helpers


def _resize(array: np.ndarray, size: tuple[int, int], interpolation: int) -> np.ndarray:
    """cv2.resize to ``size`` = (width, height); a no-op when the size already matches."""
    if array.shape[1] == size[0] and array.shape[0] == size[1]:
        return array
    return cv2.resize(array, size, interpolation=interpolation)


def _shape_for(shape: tuple[int, int], long_side: int) -> tuple[int, int]:
    """(width, height) of ``shape`` = (H, W) scaled down so the long side is <= long_side."""
    height, width = shape
    scale = min(1.0, long_side / max(height, width))
    return max(1, round(width * scale)), max(1, round(height * scale))


def _border_ring(shape: tuple[int, int], width: int) -> np.ndarray:
    """(H, W) bool: the frame of ``width`` pixels along the image border."""
    ring = np.zeros(shape, bool)
    ring[:width], ring[-width:], ring[:, :width], ring[:, -width:] = True, True, True, True
    return ring


def _border_pixels(mask: np.ndarray) -> list[np.ndarray]:
    """The four 1-pixel borders of ``mask`` (top, bottom, left, right)."""
    return [mask[0], mask[-1], mask[:, 0], mask[:, -1]]


def _border_contact(mask: np.ndarray) -> float:
    """Fraction of the image's border pixels that lie on the object."""
    return float(np.concatenate(_border_pixels(mask)).mean())


def _fills_frame(mask: np.ndarray) -> bool:
    """True when the mask is "the whole frame": > 98% of it, or most of all four borders."""
    if mask.mean() > _FULL_FRACTION:
        return True
    return all(side.mean() > _BORDER_FULL for side in _border_pixels(mask))


def _fill_holes(mask: np.ndarray) -> np.ndarray:
    """Fill background regions not 4-connected to the outside (objects are 8-connected)."""
    padded = np.pad(mask.astype(np.uint8), 1)
    outside = padded.copy()
    cv2.floodFill(outside, None, (0, 0), 2)  # 4-connected fill of the outer background
    return (outside != 2)[1:-1, 1:-1]


def _disk(radius: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _clean(mask: np.ndarray) -> np.ndarray:
    """Open scaled to the object, keep the main components, fill holes.

    The radius is 1% of sqrt(object area), so 0 (no morphology) for objects under
    10,000 pixels. Opening removes specks and thin spurs; a closing of the opened mask
    with the same disk only decides which pieces belong together (a leg cut off by a
    one-pixel gap stays with its body), and is not added to the result, so narrow gaps
    (between legs, tail and body) are not bridged and then filled as holes. Pieces are
    8-connected; the largest group is kept with every other one at least 25% of its
    area. Holes are background regions not 4-connected to the image border.
    """
    mask = np.asarray(mask, bool)
    area = int(mask.sum())
    if area == 0:
        return mask.copy()
    radius = int(_MORPH_FRACTION * np.sqrt(area))
    opened = mask.astype(np.uint8)
    grouped = opened
    if radius > 0:
        opened = cv2.morphologyEx(opened, cv2.MORPH_OPEN, _disk(radius))
        grouped = cv2.morphologyEx(opened, cv2.MORPH_CLOSE, _disk(radius))
    count, labels, stats, _ = cv2.connectedComponentsWithStats(grouped, connectivity=8)
    if count <= 1:
        return np.zeros_like(mask)
    areas = stats[1:, cv2.CC_STAT_AREA]
    keep = np.flatnonzero(areas >= _KEEP_FRACTION * areas.max()) + 1
    return _fill_holes(opened.astype(bool) & np.isin(labels, keep))


def _largest_component(mask: np.ndarray) -> np.ndarray:
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if count <= 1:
        return mask.copy()
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def _outer_contour(mask: np.ndarray, scale_xy: tuple[float, float]) -> np.ndarray:
    """Outer boundary of the largest component of a bool mask as (N, 2) (x, y) float64.

    It is the 0.5 iso-line of the mask between pixel centres (marching squares, with
    8-connected foreground), shifted to the package convention (centre = index + 0.5)
    and scaled by ``scale_xy`` to the output resolution.
    """
    main = _largest_component(mask)
    padded = np.pad(main.astype(np.float64), 1)
    contours = find_contours(padded, 0.5, fully_connected="high")
    if not contours:
        return np.zeros((0, 2))
    best = max(contours, key=lambda c: abs(_shoelace(c[:, ::-1])))
    xy = best[:, ::-1] - 1.0 + 0.5  # (row, col) in the padded array -> (x, y) pixels
    if len(xy) > 1 and np.allclose(xy[0], xy[-1]):
        xy = xy[:-1]
    if _shoelace(xy) < 0:
        xy = xy[::-1]
    return np.ascontiguousarray(xy * np.asarray(scale_xy))


def _shoelace(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _binarise(mask: np.ndarray) -> np.ndarray:
    """A user mask as bool: bool as is; numbers >= the midpoint of their range.

    So 0/1, 0/255 and soft [0, 1] masks all work; a constant mask is all object when it
    is non-zero.
    """
    array = np.asarray(mask)
    if array.dtype == bool:
        return array
    if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise JeansError("mask must be boolean or numeric")
    array = array.astype(np.float64)
    if not np.isfinite(array).all():
        raise JeansError("mask contains NaN or infinite values")
    low, high = float(array.min()), float(array.max())
    if low == high:
        return np.full(array.shape, high != 0)
    return array >= 0.5 * (low + high)


# ----------------------------------------------------------------------------- the scene


def _object_likelihood(lab: np.ndarray, ring: int, bins: int = 32) -> np.ndarray:
    """Per pixel, how much its colour is *not* explained by the border.

    ``1 - h_border / h_all`` over Lab histograms (bins^3, smoothed along each axis,
    normalised), where ``h_border`` is the median over the four border strips (``ring``
    pixels wide) of their own histograms: a colour counts as background only if it is
    common along at least two sides, so an object leaving the frame on one side does
    not teach the model its colours. (H, W) float32 in [0, 1]; 1 = absent from the border.
    """
    q = (lab.astype(np.int32) * bins) >> 8
    index = (q[..., 0] * bins + q[..., 1]) * bins + q[..., 2]
    cube = (bins, bins, bins)

    def histogram(pixels: np.ndarray) -> np.ndarray:
        hist = np.bincount(pixels.ravel(), minlength=bins**3).reshape(cube).astype(np.float32)
        for axis in range(3):  # neighbouring colours share evidence (noise, JPEG)
            hist = 0.25 * np.roll(hist, 1, axis) + 0.5 * hist + 0.25 * np.roll(hist, -1, axis)
        return hist / hist.sum()

    sides = [index[:ring], index[-ring:], index[:, :ring], index[:, -ring:]]
    border = np.median(np.stack([histogram(side) for side in sides]), axis=0)
    ratio = border / (histogram(index) + 1e-9)
    return np.clip(1.0 - ratio, 0.0, 1.0).ravel()[index].astype(np.float32)


def _saliency(rgb: np.ndarray) -> np.ndarray:
    """Spectral-residual saliency (opencv-contrib), smoothed, scaled to [0, 1]."""
    detector = cv2.saliency.StaticSaliencySpectralResidual_create()
    ok, saliency = detector.computeSaliency(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        return np.ones(rgb.shape[:2], np.float32)
    saliency = _resize(saliency.astype(np.float32), rgb.shape[1::-1], cv2.INTER_LINEAR)
    saliency = cv2.GaussianBlur(saliency, (0, 0), 0.01 * max(rgb.shape[:2]) + 1)
    return saliency / (float(saliency.max()) + 1e-6)


@dataclass
class _LabMoments:
    """A Lab image (float32), its square, and both Gaussian-blurred by ``sigma``: what
    :func:`_local_contrast` needs that does not depend on the mask."""

    image: np.ndarray
    square: np.ndarray
    blurred: np.ndarray
    blurred_square: np.ndarray
    sigma: float

    @classmethod
    def of(cls, lab: np.ndarray, sigma: float = _CONTRAST_SIGMA) -> _LabMoments:
        image = lab.astype(np.float32)
        square = image * image
        blur = (0, 0), sigma
        return cls(image, square, cv2.GaussianBlur(image, *blur), cv2.GaussianBlur(square, *blur), sigma)


def _local_contrast(moments: _LabMoments, mask: np.ndarray, floor: float = 4.0) -> float:
    """How well the boundary of ``mask`` separates locally different colours, in [0, 1].

    At every boundary pixel (either side), the Gaussian-weighted (``moments.sigma``)
    mean Lab colours of the inside and of the outside neighbourhoods are compared, in
    units of their pooled local standard deviation (at least ``floor``): z = |mean_in -
    mean_out| / std. Returns the mean of min(z, 3) / 3: near 1 where the boundary sits on
    real colour edges, low where it cuts through a uniform or textured region.
    """
    eight = mask.astype(np.uint8)
    boundary = cv2.dilate(eight, _disk(1)) > cv2.erode(eight, _disk(1))
    if not boundary.any():
        return 0.0
    inside = mask.astype(np.float32)
    blur = (0, 0), moments.sigma
    # The blur is linear, so the outside sums are the unweighted ones less the inside
    # ones; and only boundary pixels are compared, so only they are divided out.
    weight_in = cv2.GaussianBlur(inside, *blur)[boundary][:, None]
    sum_in = cv2.GaussianBlur(moments.image * inside[..., None], *blur)[boundary]
    square_in = cv2.GaussianBlur(moments.square * inside[..., None], *blur)[boundary]
    sides = []
    for weight, total, square in (
        (weight_in, sum_in, square_in),
        (1.0 - weight_in, moments.blurred[boundary] - sum_in, moments.blurred_square[boundary] - square_in),
    ):
        mean = total / (weight + 1e-6)
        sides.append((mean, np.clip(square / (weight + 1e-6) - mean**2, 0, None)))
    (mean_in, var_in), (mean_out, var_out) = sides
    difference = np.sqrt(((mean_in - mean_out) ** 2).sum(axis=1))
    spread = np.sqrt((0.5 * (var_in + var_out)).sum(axis=1) + floor**2)
    return float(np.minimum(difference / spread, 3.0).mean() / 3.0)


class _Scene:
    """A coarse copy (long side <= 320) of the working image with its border model.

    Two scales: "fine" (the image, lightly blurred) and "texture" (blurred by
    ``texture_sigma`` coarse pixels, so that textures average into their mean colour).
    At each, ``likelihood[scale]`` (h, w) float32 is the colour not explained by the
    border (:func:`_object_likelihood`) and ``unlike[scale]`` (h, w) bool its cleaned
    > 0.5 region inside the ring. ``scale`` is the one used for scoring: "fine" unless
    its unexplained region is mostly scattered specks and the texture one is not.
    """

    def __init__(self, rgb: np.ndarray):
        self.working_size = rgb.shape[1::-1]
        self.size = _shape_for(rgb.shape[:2], _COARSE_SIZE)
        self.factor = rgb.shape[1] / self.size[0]
        self.rgb = _resize(rgb, self.size, cv2.INTER_AREA)
        height, width = self.rgb.shape[:2]
        self.ring_width = max(2, round(0.03 * min(height, width)))
        self.ring = _border_ring((height, width), self.ring_width)
        self.texture_sigma = max(2.0, 0.012 * max(self.size))
        self.images = {
            "fine": cv2.GaussianBlur(self.rgb, (0, 0), 1.0),
            "texture": cv2.GaussianBlur(self.rgb, (0, 0), self.texture_sigma),
        }
        labs, self.likelihood, self.unlike, tidiness = {}, {}, {}, {}
        for scale, image in self.images.items():
            lab = cv2.cvtColor(image, cv2.COLOR_RGB2LAB)
            raw = _object_likelihood(lab, self.ring_width)
            labs[scale] = lab
            self.likelihood[scale] = cv2.GaussianBlur(raw, (0, 0), 1.0)
            # Cleaned like an object mask: scattered rare background colours (specks,
            # craters) drop out, leaving the main region the border does not explain.
            unexplained = (raw > 0.5) & ~self.ring
            self.unlike[scale] = _clean(unexplained)
            tidiness[scale] = float((self.unlike[scale] & unexplained).sum()) / max(float(unexplained.sum()), 1.0)
        # tidiness: the share of unexplained pixels that survive cleaning. Under 0.65 at
        # the fine scale means mostly texture specks; switch when the texture scale is
        # clearly tidier (low-contrast textures: the object shows as a mean shift).
        self.tidiness = tidiness
        textured = tidiness["fine"] < 0.65 and tidiness["texture"] > tidiness["fine"] + 0.3
        self.scale = "texture" if textured else "fine"
        # Every candidate is scored at this scale: blur its moments once.
        self.contrast_moments = _LabMoments.of(labs[self.scale])

    def to_coarse(self, mask: np.ndarray) -> np.ndarray:
        """A working-resolution bool mask at coarse resolution (area coverage >= 0.5)."""
        return _resize(mask.astype(np.float32), self.size, cv2.INTER_AREA) >= 0.5

    def features(self, mask: np.ndarray) -> dict:
        """Score a bool mask (working or coarse resolution), at ``self.scale``.

        ``agreement``: F-measure between the mask and the pixels whose colour the
        border does not explain (completeness: how many of those it covers; precision:
        how much of it they fill), both counted more than one pixel from the mask's
        boundary. ``contrast``: :func:`_local_contrast` of its boundary. ``border``:
        fraction of the image border on the mask. ``score = agreement * contrast *
        (1 - border)``; 0 for masks under 0.5% of the image or filling the frame.
        """
        small = mask if mask.shape == self.rgb.shape[:2] else self.to_coarse(mask)
        fraction = float(small.mean())
        border = _border_contact(small)
        result = {"fraction": round(fraction, 4), "border": round(border, 4)}
        if fraction < _MIN_FRACTION or _fills_frame(small):
            zero = dict.fromkeys(("completeness", "precision", "agreement", "contrast", "score"), 0.0)
            return {**result, **zero}
        # Mixed colours along any edge are "unexplained" too: judge away from the
        # candidate's own boundary (1 coarse pixel either side) so they bias no side.
        eight = small.astype(np.uint8)
        near = cv2.dilate(eight, _disk(1)) > cv2.erode(eight, _disk(1))
        inside, unlike = small & ~near, self.unlike[self.scale] & ~near
        hits = float((inside & unlike).sum())
        completeness = hits / max(float(unlike.sum()), 1.0)
        precision = hits / max(float(inside.sum()), 1.0)
        agreement = 2 * completeness * precision / max(completeness + precision, 1e-9)
        contrast = _local_contrast(self.contrast_moments, small)
        return {
            **result,
            "completeness": round(completeness, 4),
            "precision": round(precision, 4),
            "agreement": round(agreement, 4),
            "contrast": round(contrast, 4),
            "score": round(agreement * contrast * (1.0 - border), 4),
        }


# ----------------------------------------------------------------------------- methods


def _coverage(mask8: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A 0..255 uint8 coverage (alpha, or a bool mask x 255) at ``size``, area-averaged,
    as bool >= 128 (exactly ``alpha >= 128`` when no downscaling happens)."""
    return _resize(mask8, size, cv2.INTER_AREA) >= 128


def _alpha_meaningful(alpha: np.ndarray) -> bool:
    """An alpha channel is a silhouette when 0.5%..98% of the image is opaque (>= 128)."""
    fraction = float((alpha >= 128).mean())
    return _MIN_FRACTION <= fraction <= _FULL_FRACTION


def _channels(rgb: np.ndarray) -> dict[str, np.ndarray]:
    """Candidate 8-bit channels for thresholding: grey, HSV saturation, Lab a and b."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    lab = cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)
    return {
        "grey": cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY),
        "saturation": hsv[..., 1],
        "lab_a": lab[..., 1],
        "lab_b": lab[..., 2],
    }


def _split(channel: np.ndarray, threshold: float) -> tuple[np.ndarray, str]:
    """Split at ``threshold``; the object is the side touching less of the border."""
    light = channel >= threshold
    if _border_contact(light) <= _border_contact(~light):
        return light, "light"
    return ~light, "dark"


def _threshold(rgb: np.ndarray, threshold: float | None, scene: _Scene) -> tuple[np.ndarray, dict]:
    """``grey >= threshold`` when given, else the best-scoring Otsu split among
    grey / saturation / Lab a / Lab b, each lightly blurred and texture-blurred.
    Returns the cleaned working mask and what was chosen."""
    if threshold is not None:
        raw, polarity = _split(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), threshold)
        cleaned = _clean(raw)
        info = {"channel": "grey", "blur_sigma": 0.0, "threshold": float(threshold), "polarity": polarity}
        return cleaned, {**info, "features": scene.features(cleaned)}
    best: tuple[np.ndarray, dict] | None = None
    best_rank = -np.inf
    scores = {}
    sharp = max(1.0, 0.002 * max(rgb.shape[:2]))
    for sigma in (sharp, scene.texture_sigma * scene.factor):
        blurred = cv2.GaussianBlur(rgb, (0, 0), sigma)
        for name, channel in _channels(blurred).items():
            if int(channel.max()) == int(channel.min()):
                continue
            value, _ = cv2.threshold(channel, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
            # Otsu's value t keeps pixels > t, i.e. >= t + 1 on integers.
            raw, polarity = _split(channel, value + 1)
            cleaned = _clean(raw)
            features = scene.features(cleaned)
            key = f"{name}@{sigma:.1f}"
            scores[key] = features["score"]
            info = {"channel": name, "blur_sigma": round(sigma, 2), "threshold": float(value + 1),
                    "polarity": polarity, "features": features}
            # Blurring smooths boundaries: only take it when clearly better.
            rank = features["score"] - (0.0 if sigma == sharp else _BLUR_MARGIN)
            if rank > best_rank:
                best, best_rank = (cleaned, info), rank
    if best is None or best[1]["features"]["score"] <= 0:
        raise JeansError("no object found to segment")
    return best[0], {**best[1], "scores": scores}


def _run_grabcut(image: np.ndarray, labels: np.ndarray, iterations: int, rect=None) -> np.ndarray:
    """cv2.grabCut from a label mask (or a rect); returns the bool object mask."""
    background, foreground = np.zeros((1, 65)), np.zeros((1, 65))
    labels = labels.copy()
    mode = cv2.GC_INIT_WITH_RECT if rect is not None else cv2.GC_INIT_WITH_MASK
    cv2.setRNGSeed(2023)  # grabCut's k-means draws from OpenCV's global RNG: be repeatable
    try:
        cv2.grabCut(image, labels, rect, background, foreground, iterations, mode)
    except cv2.error as error:  # e.g. no foreground or no background samples
        raise JeansError("grabcut could not separate an object") from error
    return (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)


def _seed_labels(scene: _Scene, scale: str) -> np.ndarray | None:
    """GrabCut labels from the border model and the saliency map.

    prior = likelihood x (0.5 + 0.5 saliency); probable foreground where it exceeds its
    Otsu threshold (at least 0.25), eroded by a pixel; the border ring is definite
    background except on the seeds (objects may leave the frame); probable background
    elsewhere. None when there is no seed.
    """
    prior = scene.likelihood[scale] * (0.5 + 0.5 * _saliency(scene.rgb))
    prior8 = np.clip(prior * 255, 0, 255).astype(np.uint8)
    otsu, _ = cv2.threshold(prior8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    seed = (prior8 > max(float(otsu), 0.25 * 255)).astype(np.uint8)
    # Edge pixels mix object and background colours: keep them out of the object model.
    seed = cv2.erode(seed, _disk(1)).astype(bool)
    if not seed.any() or seed.all():
        return None
    labels = np.full(seed.shape, cv2.GC_PR_BGD, np.uint8)
    labels[seed] = cv2.GC_PR_FGD
    labels[scene.ring & ~seed] = cv2.GC_BGD
    return labels


def _grabcut_coarse(scene: _Scene, variant: str, rect=None) -> np.ndarray | None:
    """One GrabCut at coarse resolution, cleaned; None if it cannot start.

    Variants: "colour" (seeds and cut on the image), "texture" (on the texture-blurred
    image, where regions differing in mean colour under a texture separate) and "rect"
    (``rect`` = (x, y, w, h) in coarse pixels).
    """
    if variant == "rect":
        labels = np.zeros(scene.rgb.shape[:2], np.uint8)
        return _clean(_run_grabcut(scene.rgb, labels, _COARSE_ITERATIONS, rect=rect))
    scale = "fine" if variant == "colour" else "texture"
    labels = _seed_labels(scene, scale)
    if labels is None:
        return None
    return _clean(_run_grabcut(scene.rgb if scale == "fine" else scene.images["texture"], labels, _COARSE_ITERATIONS))


def _refine(rgb: np.ndarray, coarse: np.ndarray, scene: _Scene, variant: str) -> np.ndarray:
    """Redo a coarse GrabCut mask at working resolution in a band around its boundary.

    Pixels farther than ~1.5 coarse pixels from the upsampled boundary keep their label
    (definite); the band is re-labelled by a short GrabCut on the bounding box crop.
    """
    width, height = scene.working_size
    upsampled = _resize(coarse.astype(np.float32), (width, height), cv2.INTER_LINEAR) >= 0.5
    if scene.factor <= 1.0 or not upsampled.any():
        return upsampled
    band = max(2, int(np.ceil(1.5 * scene.factor)))
    rows, cols = np.nonzero(upsampled)
    y0, y1 = max(rows.min() - 2 * band, 0), min(rows.max() + 2 * band + 1, height)
    x0, x1 = max(cols.min() - 2 * band, 0), min(cols.max() + 2 * band + 1, width)
    crop = upsampled[y0:y1, x0:x1]
    inside = crop.astype(np.uint8)
    kernel = _disk(band)
    near = cv2.dilate(inside, kernel).astype(bool) & ~cv2.erode(inside, kernel).astype(bool)
    labels = np.where(crop, cv2.GC_FGD, cv2.GC_BGD).astype(np.uint8)
    labels[near & crop] = cv2.GC_PR_FGD
    labels[near & ~crop] = cv2.GC_PR_BGD
    image = rgb[y0:y1, x0:x1]
    if variant == "texture":
        image = cv2.GaussianBlur(image, (0, 0), scene.texture_sigma * scene.factor)
    refined = upsampled.copy()
    try:
        refined[y0:y1, x0:x1] = _run_grabcut(np.ascontiguousarray(image), labels, 2)
    except JeansError:  # one class missing from the crop: keep the coarse answer
        return upsampled
    return _clean(refined)


def _grabcut(rgb: np.ndarray, scene: _Scene, rect_work=None) -> tuple[np.ndarray, dict]:
    """GrabCut variants at coarse resolution, the best-scoring one refined at working
    resolution. With ``rect_work`` (x, y, w, h, working pixels) only the rect variant
    runs, else "colour" and, unless colour scored at least ``_CONFIDENT_SCORE``,
    "texture"."""
    if rect_work is not None:
        x, y, w, h = (v / scene.factor for v in rect_work)
        rect = (int(np.floor(x)), int(np.floor(y)), max(2, int(np.ceil(w))), max(2, int(np.ceil(h))))
        jobs = {"rect": dict(rect=rect)}
    else:
        jobs = {"colour": {}, "texture": {}}
    variants = {}
    for variant, kwargs in jobs.items():
        if variant == "texture" and "colour" in variants and variants["colour"][1]["score"] >= _CONFIDENT_SCORE:
            continue
        try:
            mask = _grabcut_coarse(scene, variant, **kwargs)
        except JeansError:
            mask = None
        if mask is not None and mask.any():
            variants[variant] = (mask, scene.features(mask))
    if not variants:
        raise JeansError("no object found to segment")
    chosen = max(variants, key=lambda name: variants[name][1]["score"])
    refined = _refine(rgb, variants[chosen][0], scene, chosen)
    info = {
        "variant": chosen,
        "coarse_shape": scene.rgb.shape[:2],
        "variant_scores": {name: features["score"] for name, (_, features) in variants.items()},
        "features": scene.features(refined),
    }
    if rect_work is not None:
        info["rect"] = tuple(int(v) for v in rect_work)
    return refined, info


# ----------------------------------------------------------------------------- public


def clean_mask(mask: np.ndarray) -> np.ndarray:
    """Clean a (H, W) mask: morphology scaled to the object, main components, no holes.

    ``mask`` is bool, or numeric (thresholded at the midpoint of its range, so 0/1,
    0/255 and soft masks work). Opens with a disk of radius 1% of sqrt(object area)
    (none under 10,000 object pixels); groups pieces through a closing with the same
    disk; keeps the largest group and any other at least 25% of its area; fills holes
    (background not 4-connected to the border). Returns (H, W) bool at the same
    resolution (no downscaling). Raises JeansError if nothing is left.
    """
    array = np.asarray(mask)
    if array.ndim != 2 or min(array.shape) < 1:
        raise JeansError("mask must be a 2-D array")
    cleaned = _clean(_binarise(array))
    if not cleaned.any():
        raise JeansError("no object found to segment")
    return cleaned


def _validate_image(image: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Split an RGB/RGBA uint8 image into (rgb (H, W, 3), alpha (H, W) or None)."""
    if not isinstance(image, np.ndarray):
        raise JeansError("image must be a numpy array")
    if image.dtype != np.uint8:
        raise JeansError(f"image must be uint8, got {image.dtype}")
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise JeansError(f"image must be H x W x 3 (RGB) or H x W x 4 (RGBA), got shape {image.shape}")
    if min(image.shape[:2]) < 8:
        raise JeansError("image is too small to segment (under 8 pixels on a side)")
    rgb = np.ascontiguousarray(image[..., :3])
    alpha = np.ascontiguousarray(image[..., 3]) if image.shape[2] == 4 else None
    return rgb, alpha


def _validate_rect(rect, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    try:
        x, y, w, h = (int(v) for v in rect)
    except (TypeError, ValueError) as error:
        raise JeansError("rect must be four integers (x, y, w, h)") from error
    height, width = shape
    x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + w, width), min(y + h, height)
    if w <= 0 or h <= 0 or x1 - x0 < 2 or y1 - y0 < 2:
        raise JeansError("rect must be a box of at least 2x2 pixels inside the image")
    if x0 == 0 and y0 == 0 and x1 == width and y1 == height:
        raise JeansError("rect must leave some background around the object")
    return x0, y0, x1 - x0, y1 - y0


def segment(
    image: np.ndarray,
    method: str = "auto",
    *,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
    working_size: int = 640,
) -> Segmentation:
    """Segment the main object of ``image`` ((H, W, 3) RGB or (H, W, 4) RGBA uint8).

    Methods: ``"alpha"`` (alpha >= 128, area-averaged at working size), ``"threshold"``
    (Otsu on the best-scoring of grey / saturation / Lab a / Lab b at two blurs, or
    ``grey >= threshold`` when given; the object is the side touching less of the
    border), ``"grabcut"`` (from ``rect`` = (x, y, w, h), else from a border colour
    model and a spectral-residual saliency map), ``"mask"`` (the given (H, W) ``mask``,
    cleaned) and ``"auto"``: ``mask``/``rect`` when given, the alpha channel when it is
    a silhouette (0.5%..98% opaque), else the better-scoring of threshold and grabcut.

    Work happens at ``working_size`` (long side, pixels); the mask is upsampled, with
    a given alpha or mask deciding the boundary band at full resolution.

    Returns a :class:`Segmentation` at the input's resolution. Raises JeansError for bad
    input, for no plausible object (empty or under 0.5% of the image) and, for photo
    methods (threshold, grabcut, auto without alpha/mask), when the object fills the
    frame (over 98% of it, or more than half of each of the four borders): then the
    background could not be told apart. Alpha and user masks may fill the frame, short
    of all of it (the user said so).
    """
    if method not in METHODS:
        raise JeansError(f"unknown segmentation method {method!r} (choose from {', '.join(METHODS)})")
    rgb, alpha = _validate_image(image)
    if not isinstance(working_size, (int, np.integer)) or working_size < 32:
        raise JeansError("working_size must be an integer >= 32")
    if threshold is not None:
        try:
            threshold = float(threshold)
        except (TypeError, ValueError) as error:
            raise JeansError("threshold must be a number between 0 and 255") from error
        if not 0 <= threshold <= 255:  # also rejects NaN
            raise JeansError("threshold must be a number between 0 and 255")
    height, width = rgb.shape[:2]
    size = _shape_for((height, width), int(working_size))
    details: dict = {"working_shape": (size[1], size[0])}
    user_mask = None
    if mask is not None:
        user_mask = np.asarray(mask)
        if user_mask.shape != (height, width):
            raise JeansError(f"mask shape {user_mask.shape} does not match the image ({height}, {width})")
    rect_full = _validate_rect(rect, (height, width)) if rect is not None else None

    if method == "auto":
        if user_mask is not None:
            method, details["reason"] = "mask", "a mask was given"
        elif rect_full is not None:
            method, details["reason"] = "grabcut", "a rect was given"
        elif alpha is not None and _alpha_meaningful(alpha):
            method, details["reason"] = "alpha", "the alpha channel is a silhouette"

    photo = method in ("auto", "threshold", "grabcut")
    given = None  # (H, W) uint8 0..255: a full-resolution silhouette handed to us
    if method == "alpha":
        if alpha is None:
            raise JeansError("method 'alpha' needs an RGBA image")
        if not (alpha < 128).any():
            raise JeansError("alpha channel is fully opaque: no silhouette in it")
        given = alpha
        used = "alpha"
    elif method == "mask":
        if user_mask is None:
            raise JeansError("method 'mask' needs a mask")
        given = _binarise(user_mask).astype(np.uint8) * 255
        used = "mask"
    if given is not None:
        working = _clean(_coverage(given, size))
    else:
        working, used = _segment_photo(
            _resize(rgb, size, cv2.INTER_AREA), method, threshold, rect_full, width / size[0], details
        )

    fraction = float(working.mean())
    details["area_fraction"] = round(fraction, 4)
    if fraction < _MIN_FRACTION:
        raise JeansError("no object found to segment")
    if working.all() or (photo and _fills_frame(working)):
        raise JeansError("the object fills the whole frame: no background to separate it from")

    # Linear upsampling of 0/255 then >= 128 is the "resize the float mask, threshold
    # at 0.5" rule in a quarter of the memory (matters for 24-MP photos).
    soft = _resize(working.astype(np.uint8) * 255, (width, height), cv2.INTER_LINEAR)
    full = soft >= 128
    if given is not None and size != (width, height):
        # A given silhouette is exact at full resolution: within one working pixel of
        # the cleaned boundary (where the upsampled mask is neither 0 nor 255) use it.
        band = (soft > 0) & (soft < 255)
        full[band] = given[band] >= 128
    contour = _outer_contour(working, (width / size[0], height / size[1]))
    return Segmentation(mask=full, method=used, contour=contour, details=details)


def _segment_photo(
    rgb: np.ndarray,
    method: str,
    threshold: float | None,
    rect_full: tuple[int, int, int, int] | None,
    factor: float,
    details: dict,
) -> tuple[np.ndarray, str]:
    """threshold / grabcut / auto on the working-size RGB; returns (clean mask, method).

    auto runs the threshold search and the GrabCut variants and keeps whichever of the
    two best scores higher.
    """
    scene = _Scene(rgb)
    results: dict[str, tuple[np.ndarray, dict]] = {}
    if method in ("threshold", "auto"):
        try:
            results["threshold"] = _threshold(rgb, threshold, scene)
        except JeansError:
            if method == "threshold":
                raise
    if method in ("grabcut", "auto"):
        rect_work = None if rect_full is None else tuple(v / factor for v in rect_full)
        try:
            results["grabcut"] = _grabcut(rgb, scene, rect_work)
        except JeansError:
            if method == "grabcut":
                raise
    if method == "auto":
        if not results:
            raise JeansError("no object found to segment")
        ranked = sorted(results, key=lambda name: results[name][1]["features"]["score"], reverse=True)
        details["candidates"] = {name: results[name][1]["features"] for name in results}
        chosen = ranked[0]
        if results[chosen][1]["features"]["score"] <= 0:
            raise JeansError("no object found to segment")
        details["reason"] = f"{chosen} scored best: " + ", ".join(
            f"{name} {results[name][1]['features']['score']:.3f}" for name in ranked
        )
    else:
        chosen = method
    mask, info = results[chosen]
    details[chosen] = info
    return mask, chosen
