"""The coarse scene that auto's hypotheses are cut on and scored by.

Public API (for the segmentation modules): :class:`Scene` (a coarse copy of the
working image with its border colour model and the measures every candidate mask is
scored by), :func:`object_likelihood`, :func:`spectral_saliency`,
:func:`local_contrast`, and :func:`rgb_to_lab` with :func:`prepare_lab_tables`.

Arrays: images are ``(h, w, 3)`` RGB ``uint8``; masks ``(h, w) bool``, True on the
object; maps ``(h, w) float32`` in [0, 1]. Sizes are ``(width, height)`` as OpenCV
takes them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np

from .masks import MIN_AREA_FRACTION, border_contact, border_ring, clean, disk, fills_frame, resize, shape_for

COARSE_SIZE = 320  # long side of the scene's copy, and of GrabCut's first pass (graph cuts are superlinear)
# auto's hypotheses are cut on a smaller copy (and with fewer iterations, see
# jeanscv.subject.grabcut): GrabCut costs about 370 ms at 320 px and 5 iterations on
# real photos, 190 ms at 240 px and 3, and only the winner needs a sharp boundary (it
# is refined at working resolution). At 160 px the hypotheses got too coarse to judge
# (real photos: mean IoU 0.63 at 320, 0.62 at 240, 0.59 at 160; two synthetic photos
# under 0.9 at 160).
HYPOTHESIS_SIZE = 240
_CONTRAST_SIGMA = 2.0  # neighbourhood (coarse pixels) on which boundary contrast is judged


_lab_tables: threading.Thread | None = None
_lab_tables_lock = threading.Lock()


def prepare_lab_tables(wait: bool = False) -> None:
    """Have OpenCV build its tables for 8-bit RGB to Lab now, in a background thread
    (or before returning, when ``wait``); once a process.

    OpenCV builds them on a process's first such conversion: 0.15 s of one core, a
    tenth of a fresh process's photo. It holds no GIL meanwhile, so started before
    the decoding they are built on the other core. :func:`rgb_to_lab` waits for the
    thread, so no conversion runs while they are being built.
    """
    global _lab_tables
    with _lab_tables_lock:
        if _lab_tables is None:
            pixel = np.zeros((1, 1, 3), np.uint8)
            # Not a daemon: the interpreter joins it (0.15 s at most) before it tears
            # down. A daemon thread still inside cvtColor at exit aborted the process
            # ("terminate called without an active exception"): OpenCV's C++ wrapper
            # takes the GIL back in a destructor, where Python ends the thread.
            _lab_tables = threading.Thread(
                target=cv2.cvtColor, args=(pixel, cv2.COLOR_RGB2LAB), name="jeanscv-lab-tables"
            )
            _lab_tables.start()
    if wait:
        _lab_tables.join()


def rgb_to_lab(rgb: np.ndarray) -> np.ndarray:
    """``cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)`` of a uint8 RGB image (see :func:`prepare_lab_tables`)."""
    prepare_lab_tables(wait=True)
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2LAB)


def object_likelihood(lab: np.ndarray, ring: int, bins: int = 32) -> np.ndarray:
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
    border = _median_of_four(*(histogram(side) for side in sides))
    ratio = border / (histogram(index) + 1e-9)
    return np.clip(1.0 - ratio, 0.0, 1.0).ravel()[index].astype(np.float32)


def _median_of_four(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Elementwise median of four arrays: np.median's value (the mean of the middle two),
    by a min/max network, 30 times faster than np.median over a stacked axis."""
    low, high = np.maximum(np.minimum(a, b), np.minimum(c, d)), np.minimum(np.maximum(a, b), np.maximum(c, d))
    return (low + high) / 2


def spectral_saliency(rgb: np.ndarray) -> np.ndarray:
    """Spectral-residual saliency (opencv-contrib), smoothed, scaled to [0, 1]."""
    detector = cv2.saliency.StaticSaliencySpectralResidual_create()
    ok, saliency = detector.computeSaliency(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    if not ok:
        return np.ones(rgb.shape[:2], np.float32)
    saliency = resize(saliency.astype(np.float32), rgb.shape[1::-1], cv2.INTER_LINEAR)
    saliency = cv2.GaussianBlur(saliency, (0, 0), 0.01 * max(rgb.shape[:2]) + 1)
    return saliency / (float(saliency.max()) + 1e-6)


@dataclass
class LabMoments:
    """A Lab image (float32), its square, and both Gaussian-blurred by ``sigma``: what
    :func:`local_contrast` needs that does not depend on the mask."""

    image: np.ndarray
    square: np.ndarray
    blurred: np.ndarray
    blurred_square: np.ndarray
    sigma: float

    @classmethod
    def of(cls, lab: np.ndarray, sigma: float = _CONTRAST_SIGMA) -> LabMoments:
        image = lab.astype(np.float32)
        square = image * image
        blur = (0, 0), sigma
        return cls(image, square, cv2.GaussianBlur(image, *blur), cv2.GaussianBlur(square, *blur), sigma)


def local_contrast(moments: LabMoments, mask: np.ndarray, floor: float = 4.0) -> float:
    """How well the boundary of ``mask`` separates locally different colours, in [0, 1].

    At every boundary pixel (either side), the Gaussian-weighted (``moments.sigma``)
    mean Lab colours of the inside and of the outside neighbourhoods are compared, in
    units of their pooled local standard deviation (at least ``floor``): z = |mean_in -
    mean_out| / std. Returns the mean of min(z, 3) / 3: near 1 where the boundary sits on
    real colour edges, low where it cuts through a uniform or textured region.
    """
    eight = mask.astype(np.uint8)
    boundary = cv2.dilate(eight, disk(1)) > cv2.erode(eight, disk(1))
    if not boundary.any():
        return 0.0
    # Only the boundary's neighbourhood is blurred: a box around it, grown by the
    # kernel's reach (OpenCV's float kernels reach 4 sigma), gives the same values there.
    rows, cols = np.nonzero(boundary)
    reach = int(np.ceil(4 * moments.sigma)) + 1
    box = (
        slice(max(rows.min() - reach, 0), rows.max() + reach + 1),
        slice(max(cols.min() - reach, 0), cols.max() + reach + 1),
    )
    at = rows - box[0].start, cols - box[1].start  # the boundary pixels in the box
    inside = mask[box].astype(np.float32)
    inside3 = cv2.merge([inside] * 3)  # cv2.multiply: numpy's broadcast product is 10x slower
    blur = (0, 0), moments.sigma
    # The blur is linear, so the outside sums are the unweighted ones less the inside
    # ones; and only boundary pixels are compared, so only they are divided out.
    weight_in = cv2.GaussianBlur(inside, *blur)[at][:, None]
    sum_in = cv2.GaussianBlur(cv2.multiply(moments.image[box], inside3), *blur)[at]
    square_in = cv2.GaussianBlur(cv2.multiply(moments.square[box], inside3), *blur)[at]
    sides = []
    for weight, total, square in (
        (weight_in, sum_in, square_in),
        (1.0 - weight_in, moments.blurred[rows, cols] - sum_in, moments.blurred_square[rows, cols] - square_in),
    ):
        mean = total / (weight + 1e-6)
        sides.append((mean, np.clip(square / (weight + 1e-6) - mean**2, 0, None)))
    (mean_in, var_in), (mean_out, var_out) = sides
    difference = np.sqrt(((mean_in - mean_out) ** 2).sum(axis=1))
    spread = np.sqrt((0.5 * (var_in + var_out)).sum(axis=1) + floor**2)
    return float(np.minimum(difference / spread, 3.0).mean() / 3.0)


class Scene:
    """A coarse copy (long side <= 320) of the working image with its border model.

    Two scales: "fine" (the image, lightly blurred) and "texture" (blurred by
    ``texture_sigma`` coarse pixels, so that textures average into their mean colour).
    At each, ``likelihood[scale]`` (h, w) float32 is the colour not explained by the
    border (:func:`object_likelihood`) and ``unlike[scale]`` (h, w) bool its cleaned
    > 0.5 region inside the ring. ``scale`` is the one used for scoring: "fine" unless
    its unexplained region is mostly scattered specks and the texture one is not.
    """

    def __init__(self, rgb: np.ndarray):
        self.working_size = rgb.shape[1::-1]
        self.size = shape_for(rgb.shape[:2], COARSE_SIZE)
        self.factor = rgb.shape[1] / self.size[0]
        self.rgb = resize(rgb, self.size, cv2.INTER_AREA)
        height, width = self.rgb.shape[:2]
        self.ring_width = max(2, round(0.03 * min(height, width)))
        self.ring = border_ring((height, width), self.ring_width)
        self.texture_sigma = max(2.0, 0.012 * max(self.size))
        self.images = {
            "fine": cv2.GaussianBlur(self.rgb, (0, 0), 1.0),
            "texture": cv2.GaussianBlur(self.rgb, (0, 0), self.texture_sigma),
        }
        labs, self.likelihood, self.unlike, tidiness = {}, {}, {}, {}
        for scale, image in self.images.items():
            lab = rgb_to_lab(image)
            raw = object_likelihood(lab, self.ring_width)
            labs[scale] = lab
            self.likelihood[scale] = cv2.GaussianBlur(raw, (0, 0), 1.0)
            # Cleaned like an object mask: scattered rare background colours (specks,
            # craters) drop out, leaving the main region the border does not explain.
            unexplained = (raw > 0.5) & ~self.ring
            self.unlike[scale] = clean(unexplained)
            tidiness[scale] = float((self.unlike[scale] & unexplained).sum()) / max(float(unexplained.sum()), 1.0)
        # tidiness: the share of unexplained pixels that survive cleaning. Under 0.65 at
        # the fine scale means mostly texture specks; switch when the texture scale is
        # clearly tidier (low-contrast textures: the object shows as a mean shift).
        self.tidiness = tidiness
        textured = tidiness["fine"] < 0.65 and tidiness["texture"] > tidiness["fine"] + 0.3
        self.scale = "texture" if textured else "fine"
        # Every candidate is scored at this scale: blur its moments once.
        self.contrast_moments = LabMoments.of(labs[self.scale])
        # Coarse mask bytes -> measures: the threshold and border-colour winners are
        # measured again when the candidates are chosen.
        self._measured: dict[bytes, dict[str, float]] = {}

    @property
    def hypothesis_size(self) -> tuple[int, int]:
        """(width, height) of the copy that auto's hypotheses are cut on."""
        return shape_for(self.rgb.shape[:2], HYPOTHESIS_SIZE)

    def hypothesis(self) -> np.ndarray:
        """The coarse image at :attr:`hypothesis_size`."""
        return resize(self.rgb, self.hypothesis_size, cv2.INTER_AREA)

    def detail(self) -> np.ndarray:
        """(h, w) float32 |Laplacian| of the coarse image's grey levels, area-averaged to
        :attr:`hypothesis_size`: fine detail measured finer than the hypotheses are cut."""
        grey = cv2.cvtColor(self.rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
        return resize(np.abs(cv2.Laplacian(grey, cv2.CV_32F, ksize=3)), self.hypothesis_size, cv2.INTER_AREA)

    def from_hypothesis(self, mask: np.ndarray) -> np.ndarray:
        """A hypothesis-size mask upsampled to coarse size and cleaned."""
        return clean(resize(mask.astype(np.float32), self.size, cv2.INTER_LINEAR) >= 0.5)

    def to_coarse(self, mask: np.ndarray) -> np.ndarray:
        """A working-resolution bool mask at coarse resolution (area coverage >= 0.5)."""
        return resize(mask.astype(np.float32), self.size, cv2.INTER_AREA) >= 0.5

    def features(self, mask: np.ndarray) -> dict:
        """Score a bool mask (working or coarse resolution), at ``self.scale``.

        ``agreement``: F-measure between the mask and the pixels whose colour the
        border does not explain (completeness: how many of those it covers; precision:
        how much of it they fill), both counted more than one pixel from the mask's
        boundary. ``contrast``: :func:`local_contrast` of its boundary. ``border``:
        fraction of the image border on the mask. ``score = agreement * contrast *
        (1 - border)``; 0 for masks under 0.5% of the image or filling the frame.
        Rounded to 4 decimals (:meth:`measures`: the same unrounded).
        """
        return {name: round(value, 4) for name, value in self.measures(mask).items()}

    def measures(self, mask: np.ndarray) -> dict[str, float]:
        """:meth:`features`, unrounded."""
        small = mask if mask.shape == self.rgb.shape[:2] else self.to_coarse(mask)
        key = np.packbits(small).tobytes()
        if key not in self._measured:
            self._measured[key] = self._measure(small)
        return dict(self._measured[key])

    def _measure(self, small: np.ndarray) -> dict[str, float]:
        """:meth:`measures` of a coarse bool mask, computed."""
        fraction = float(small.mean())
        border = border_contact(small)
        result = {"fraction": fraction, "border": border}
        if fraction < MIN_AREA_FRACTION or fills_frame(small):
            zero = dict.fromkeys(("completeness", "precision", "agreement", "contrast", "score"), 0.0)
            return {**result, **zero}
        # Mixed colours along any edge are "unexplained" too: judge away from the
        # candidate's own boundary (1 coarse pixel either side) so they bias no side.
        eight = small.astype(np.uint8)
        near = cv2.dilate(eight, disk(1)) > cv2.erode(eight, disk(1))
        inside, unlike = small & ~near, self.unlike[self.scale] & ~near
        hits = float((inside & unlike).sum())
        completeness = hits / max(float(unlike.sum()), 1.0)
        precision = hits / max(float(inside.sum()), 1.0)
        agreement = 2 * completeness * precision / max(completeness + precision, 1e-9)
        contrast = local_contrast(self.contrast_moments, small)
        return {
            **result,
            "completeness": completeness,
            "precision": precision,
            "agreement": agreement,
            "contrast": contrast,
            "score": agreement * contrast * (1.0 - border),
        }
