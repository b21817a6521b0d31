"""Classical-CV segmentation of a photo into the silhouette of its main object.

Public API: :func:`segment` (photo -> :class:`Segmentation`), :func:`hypotheses` (auto's
hypotheses of a scene, which a click session reuses), :class:`SharedHypotheses` (one
photo's hypotheses cut once for both) and :func:`clean_mask`.

Here: auto's hypotheses and choice, and :func:`segment`, which calls them. The
threshold method lives in :mod:`.threshold`, GrabCut and its refinement in
:mod:`.grabcut`, the scene and its measures in :mod:`.scene`, the consensus in
:mod:`.consensus`, the subject's kind in :mod:`.kinds` and the masks' helpers in
:mod:`.masks`.

Arrays: images are ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA ``uint8``; masks are
``(H, W) bool`` with True on the object. Contours are ``(N, 2) float64`` ``(x, y)`` in
image pixels, package convention (pixel ``(c, r)`` covers ``[c, c+1) x [r, r+1)``).

All heavy work happens on a copy whose long side is at most ``working_size``; GrabCut's
first pass runs on an even smaller copy (long side <= 320: the :class:`Scene` of
:mod:`jeanscv.subject.scene`, which also scores every candidate) and is then refined
in a band around its boundary at working resolution. The cleaned working mask is
upsampled to the input resolution with linear interpolation and thresholded at 0.5 (a
given alpha or mask decides the pixels within one working pixel of the boundary at full
resolution), so a 24-MP photo costs about as much as a 640-pixel one (about 1 s, 0.5 GB
peak).

How ``auto`` chooses (no alpha, mask or rect given): five hypotheses are made at coarse
resolution: the best Otsu split of four channels (lightly blurred, and texture-blurred
in textured scenes), GrabCut seeded where colours are rare on the border (weighted by
spectral-residual saliency), GrabCut from a centred rectangle, and two GrabCuts seeded
by boundary-connectivity saliency on superpixels (:mod:`jeanscv.subject.saliency`).
The one the others agree with most, along strong colour edges, wins
(:mod:`jeanscv.subject.consensus`); the ``subject`` asked for (``auto``: an animal
rather than the person beside it, ``animal``, ``person``, ``object``) then keeps the
winner or some pieces of the hypotheses (:mod:`jeanscv.subject.kinds`), which are
refined at working resolution; ``details`` records every hypothesis's measures, the
reason, the ``kind`` found and whether the subject is ``uncertain`` (its ``doubts``).
"""

from __future__ import annotations

import copy
import threading
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import cv2
import numpy as np

from jeanscv.errors import JeansError
from jeanscv.options import SILHOUETTE_METHODS, SUBJECTS

from .grabcut import HYPOTHESIS_ITERATIONS, cut_pool, grabcut, grabcut_coarse_best, grabcut_or_none, refine
from .masks import (
    FULL_FRACTION,
    MIN_AREA_FRACTION,
    RIM_ONLY,
    binarise,
    clean,
    clean_mask,
    downscale,
    fills_frame,
    outer_contour,
    resize,
    rim_fraction,
    shape_for,
)
from .scene import Scene
from .threshold import threshold_split as _threshold

if TYPE_CHECKING:  # the kind cues load OpenCV's people detector, on first use
    from .kinds import KindCues

#: :func:`segment`'s methods: the named ones, and ``mask`` (a given mask, cleaned).
METHODS = (*SILHOUETTE_METHODS, "mask")


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


# ----------------------------------------------------------------------------- methods


def _coverage(mask8: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A 0..255 uint8 coverage (alpha, or a bool mask x 255) at ``size``, area-averaged,
    as bool >= 128 (exactly ``alpha >= 128`` when no downscaling happens)."""
    return resize(mask8, size, cv2.INTER_AREA) >= 128


def _alpha_meaningful(alpha: np.ndarray) -> bool:
    """An alpha channel is a silhouette when 0.5%..98% of the image is opaque (>= 128)."""
    fraction = float((alpha >= 128).mean())
    return MIN_AREA_FRACTION <= fraction <= FULL_FRACTION


def _grabcut_hypothesis(scene: Scene) -> tuple[str, np.ndarray | None]:
    """(variant, coarse mask or None) of the border-colour GrabCut hypothesis."""
    try:
        variant, mask, _ = grabcut_coarse_best(scene, hypothesis=True)
    except JeansError:
        return "colour", None
    return variant, mask


@dataclass
class Hypotheses:
    """auto's hypotheses of one scene: ``coarse`` masks at the scene's size by name (the
    usable ones: not tiny, not filling the frame, not a rim), the threshold split at
    working size, and the GrabCut hypothesis's variant."""

    coarse: dict[str, np.ndarray]
    threshold_mask: np.ndarray | None
    grabcut_variant: str


def hypotheses(rgb: np.ndarray, scene: Scene, details: dict) -> Hypotheses:
    """Cut every hypothesis of auto at coarse resolution (``details`` gets the threshold's
    choice). Raises JeansError when none is usable."""
    from .consensus import hypothesis_labels

    small = scene.hypothesis()
    labelings = hypothesis_labels(small, scene.detail())
    # The GrabCuts are independent and OpenCV releases the GIL: cut them side by side on
    # the threads OpenCV may use, or here one after the other when it may use one (a
    # batch worker gets its share of the cores, often 1).
    with cut_pool() as pool:
        grabcut_job = pool.submit(_grabcut_hypothesis, scene)
        cut_jobs = {
            name: pool.submit(grabcut_or_none, small, labels, HYPOTHESIS_ITERATIONS)
            for name, labels in labelings.items()
        }
        coarse: dict[str, np.ndarray] = {}
        threshold_mask = None
        try:
            threshold_mask, threshold_info = _threshold(rgb, None, scene)
            coarse["threshold"] = scene.to_coarse(threshold_mask)
            details["threshold"] = {k: v for k, v in threshold_info.items() if k not in ("features", "scores")}
        except JeansError:
            pass
        grabcut_variant, grabcut_mask = grabcut_job.result()
        if grabcut_mask is not None:
            coarse["grabcut"] = grabcut_mask
        for name, job in cut_jobs.items():
            mask = job.result()
            if mask is not None:
                coarse[name] = scene.from_hypothesis(mask)
    usable = {
        name: m
        for name, m in coarse.items()
        if m.mean() >= MIN_AREA_FRACTION and not fills_frame(m) and rim_fraction(m) <= RIM_ONLY
    }
    if not usable:
        raise JeansError("no object found to segment")
    return Hypotheses(usable, threshold_mask, grabcut_variant)


@dataclass(frozen=True)
class PreparedScene:
    """auto's working copy ``rgb``, its :class:`Scene` and its hypotheses (``found``;
    None, with JeansError's ``reason``, when none is usable), and what the hypotheses
    wrote to ``details`` (the threshold's choice). The masks are read-only: shared."""

    rgb: np.ndarray
    scene: Scene
    found: Hypotheses | None
    reason: str
    details: dict

    @classmethod
    def of(cls, rgb: np.ndarray) -> PreparedScene:
        """Cut the hypotheses of a working copy (:func:`hypotheses`)."""
        scene, details = Scene(rgb), {}
        try:
            found = hypotheses(rgb, scene, details)
        except JeansError as error:
            return cls(rgb, scene, None, str(error), details)
        for mask in (*found.coarse.values(), found.threshold_mask):
            if mask is not None:
                mask.flags.writeable = False
        return cls(rgb, scene, found, "", details)

    @cached_property
    def cues(self) -> KindCues:
        """What kind of thing the candidates are (:mod:`jeanscv.subject.kinds`), each
        cue computed on first use."""
        from .kinds import KindCues

        return KindCues(self.scene.rgb, self.rgb)

    @property
    def nbytes(self) -> int:
        """About the memory it holds: the copy, the scene's planes (measured: 23 times
        its coarse copy, 5.7 MB for a 640-pixel copy) and the masks."""
        masks = () if self.found is None else (*self.found.coarse.values(), self.found.threshold_mask)
        cues = self.__dict__["cues"].nbytes if "cues" in self.__dict__ else 0  # once the subject's kind was asked
        return self.rgb.nbytes + 24 * self.scene.rgb.nbytes + sum(m.nbytes for m in masks if m is not None) + cues


class SharedHypotheses:
    """auto's hypotheses of one photo, cut once for everyone who asks.

    :func:`segment` (method ``auto``) and
    :class:`~jeanscv.subject.interactive.ClickSession` both cut auto's hypotheses of
    the same 640-pixel copy of a photo, most of either's set-up (a second or more on a
    busy machine). Given the same ``SharedHypotheses``, the second
    reuses the first's scene and hypotheses: same results, cut once. The working copies
    are compared pixel for pixel, so another photo (or another working size) gets its
    own; the latest is kept. Thread-safe: a second caller waits for the first's cut.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._prepared: PreparedScene | None = None

    def of(self, rgb: np.ndarray) -> PreparedScene:
        """The prepared scene of the working copy ``rgb`` (cut now unless held)."""
        with self._lock:
            held = self._prepared
            if held is None or held.rgb.shape != rgb.shape or not np.array_equal(held.rgb, rgb):
                held = self._prepared = PreparedScene.of(rgb)
            return held

    @property
    def nbytes(self) -> int:
        """About the memory it holds (0 before the first cut)."""
        held = self._prepared
        return 0 if held is None else held.nbytes


def _auto(
    rgb: np.ndarray, prepared: PreparedScene, details: dict, subject: str = "auto", several: bool = False
) -> tuple[np.ndarray, str]:
    """Every hypothesis at coarse resolution, the consensus pick
    (:mod:`jeanscv.subject.consensus`), then the ``subject`` choice among its pieces
    (:func:`jeanscv.subject.kinds.choose_kind`), at working resolution: the threshold
    split as it is, a GrabCut hypothesis or a chosen piece refined along its boundary."""
    from .consensus import choose
    from .kinds import choose_kind

    details.update(copy.deepcopy(prepared.details))
    found, scene = prepared.found, prepared.scene
    if found is None:
        raise JeansError(prepared.reason)
    usable = found.coarse
    winner, ranked = choose(usable, scene.measures)
    best = ranked[0]
    if best.contrast <= 0:
        raise JeansError("no object found to segment")
    details["candidates"] = {
        c.name: {
            "consensus": round(c.consensus, 4),
            "contrast": round(c.contrast, 4),
            "agreement": round(c.agreement, 4),
            "side_contact": round(c.side_contact, 4),
            "band": c.band,
            "score": round(c.score, 4),
            "fraction": round(float(c.mask.mean()), 4),
        }
        for c in ranked
    }
    details["chosen"] = winner
    details["consensus"] = round(best.consensus, 4)
    bands = [c.name for c in ranked if c.band]
    reason = (
        f"{winner} agrees most with the other {len(ranked) - len(bands) - 1} hypotheses (mean IoU {best.consensus:.2f}) "
        f"along strong colour edges (contrast {best.contrast:.2f}; border-colour agreement {best.agreement:.2f})"
        + (f"; left out as horizon bands across the frame: {', '.join(bands)}" if bands else "")
    )
    kind = choose_kind(prepared.cues, [c for c in ranked if not c.band], winner, subject, several)
    details["subject"], details["kind"] = subject, kind.kind
    doubts = list(best.doubts)
    if kind.pieces:
        source = next(c for c in ranked if c.name == kind.pieces[0].source)
        doubts = list(source.doubts)
        details["pieces"] = [piece.summary() for piece in kind.pieces]
    if kind.reason:
        reason += f"; {kind.reason}"
    if not kind.found:
        doubts.insert(0, f"no {subject} found")
    details["uncertain"] = bool(doubts)
    details["doubts"] = doubts
    details["reason"] = reason + ("; unsure: " + ", ".join(doubts) if doubts else "")
    if kind.pieces and not np.array_equal(kind.mask, usable[winner]):
        return refine(rgb, kind.mask, scene, "colour", source_width=scene.hypothesis_size[0]), "grabcut"
    if winner == "threshold":
        return found.threshold_mask, "threshold"
    variant = found.grabcut_variant if winner == "grabcut" else "colour"
    return refine(rgb, usable[winner], scene, variant, source_width=scene.hypothesis_size[0]), "grabcut"


# ----------------------------------------------------------------------------- public


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
    shared: SharedHypotheses | None = None,
    subject: str = "auto",
    several: bool = False,
) -> Segmentation:
    """Segment the main object of ``image`` ((H, W, 3) RGB or (H, W, 4) RGBA uint8).

    Methods: ``"alpha"`` (alpha >= 128, area-averaged at working size), ``"threshold"``
    (Otsu on the best-scoring of grey / saturation / Lab a / Lab b, lightly blurred and,
    in a textured scene, texture-blurred, or
    ``grey >= threshold`` when given; the object is the side touching less of the
    border), ``"grabcut"`` (from ``rect`` = (x, y, w, h), else from a border colour
    model and a spectral-residual saliency map), ``"mask"`` (the given (H, W) ``mask``,
    cleaned) and ``"auto"``: ``mask``/``rect`` when given, the alpha channel when it is
    a silhouette (0.5%..98% opaque), else the better-scoring of threshold and grabcut.

    Work happens at ``working_size`` (long side, pixels); the mask is upsampled, with
    a given alpha or mask deciding the boundary band at full resolution. ``shared``:
    auto's hypotheses, cut once for this call and a click session of the same photo
    (:class:`SharedHypotheses`); the result is the same. ``subject`` (auto only): what
    to find, ``auto`` (an animal beside a person rather than the person), ``animal``,
    ``person`` or ``object`` (the most salient thing, whatever it is); ``several``:
    every animal found rather than the most prominent one (``--objects all``). See
    :mod:`jeanscv.subject.kinds`; ``details`` say which ``kind`` was found and whether
    the subject is ``uncertain`` (with the ``doubts``).

    Returns a :class:`Segmentation` at the input's resolution. Raises JeansError for bad
    input, for no plausible object (empty or under 0.5% of the image) and, for photo
    methods (threshold, grabcut, auto without alpha/mask), when the object fills the
    frame (over 98% of it, or more than half of each of the four borders): then the
    background could not be told apart. Alpha and user masks may fill the frame, short
    of all of it (the user said so).
    """
    arguments = _check_arguments(method, image, threshold, rect, mask, working_size)
    if subject not in SUBJECTS:
        raise JeansError(f"unknown subject {subject!r} (use {', '.join(SUBJECTS)})")
    height, width = arguments.rgb.shape[:2]
    size = shape_for((height, width), int(working_size))
    details: dict = {"working_shape": (size[1], size[0])}
    if method == "auto":
        method = _auto_given(arguments, details)
    photo = method in ("auto", "threshold", "grabcut")
    given = _given_silhouette(method, arguments)
    if given is not None:
        working, used = clean(_coverage(given, size)), method
    else:
        rgb = downscale(arguments.rgb, size)
        factor = width / size[0]
        working, used = _segment_photo(
            rgb, method, arguments.threshold, arguments.rect, factor, details, shared, subject, several
        )
    _check_area(working, photo, details)
    full = _full_resolution(working, given, size, (width, height))
    contour = outer_contour(working, (width / size[0], height / size[1]))
    return Segmentation(mask=full, method=used, contour=contour, details=details)


@dataclass(frozen=True)
class _Arguments:
    """:func:`segment`'s image and options, checked: ``rgb`` ``(H, W, 3)`` and ``alpha``
    ``(H, W)`` or None, the given ``mask`` ``(H, W)`` and ``rect`` (clipped to the
    image) or None."""

    rgb: np.ndarray
    alpha: np.ndarray | None
    threshold: float | None
    mask: np.ndarray | None
    rect: tuple[int, int, int, int] | None


def _check_arguments(method: str, image: np.ndarray, threshold, rect, mask, working_size) -> _Arguments:
    """:func:`segment`'s arguments checked one after the other: JeansError for the
    first bad one."""
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
    user_mask = None
    if mask is not None:
        user_mask = np.asarray(mask)
        if user_mask.shape != (height, width):
            raise JeansError(f"mask shape {user_mask.shape} does not match the image ({height}, {width})")
    rect_full = _validate_rect(rect, (height, width)) if rect is not None else None
    return _Arguments(rgb, alpha, threshold, user_mask, rect_full)


def _auto_given(arguments: _Arguments, details: dict) -> str:
    """What auto uses when the caller handed it the object: ``mask`` or ``rect``
    when given, the alpha channel when it is a silhouette, else ``"auto"``; the
    reason goes to ``details``."""
    if arguments.mask is not None:
        details["reason"] = "a mask was given"
        return "mask"
    if arguments.rect is not None:
        details["reason"] = "a rect was given"
        return "grabcut"
    if arguments.alpha is not None and _alpha_meaningful(arguments.alpha):
        details["reason"] = "the alpha channel is a silhouette"
        return "alpha"
    return "auto"


def _given_silhouette(method: str, arguments: _Arguments) -> np.ndarray | None:
    """The full-resolution ``(H, W) uint8`` 0..255 silhouette that methods ``alpha`` and
    ``mask`` are handed (JeansError where it is missing or empty); None for the
    photo methods."""
    if method == "alpha":
        alpha = arguments.alpha
        if alpha is None:
            raise JeansError("method 'alpha' needs an RGBA image")
        if not (alpha < 128).any():
            raise JeansError("alpha channel is fully opaque: no silhouette in it")
        return alpha
    if method == "mask":
        if arguments.mask is None:
            raise JeansError("method 'mask' needs a mask")
        return binarise(arguments.mask).astype(np.uint8) * 255
    return None


def _check_area(working: np.ndarray, photo: bool, details: dict) -> None:
    """JeansError unless the working mask holds a plausible object: not under 0.5% of
    the image, not all of it, and for the photo methods not filling the frame."""
    fraction = float(working.mean())
    details["area_fraction"] = round(fraction, 4)
    if fraction < MIN_AREA_FRACTION:
        raise JeansError("no object found to segment")
    if working.all() or (photo and fills_frame(working)):
        raise JeansError("the object fills the whole frame: no background to separate it from")


def _full_resolution(
    working: np.ndarray, given: np.ndarray | None, size: tuple[int, int], full_size: tuple[int, int]
) -> np.ndarray:
    """The working mask (``size``, ``(width, height)``) upsampled to ``full_size``, a
    given silhouette deciding the pixels along its boundary."""
    width, height = full_size
    # Linear upsampling of 0/255 then >= 128 is the "resize the float mask, threshold
    # at 0.5" rule in a quarter of the memory (matters for 24-MP photos).
    soft = resize(working.astype(np.uint8) * 255, (width, height), cv2.INTER_LINEAR)
    full = soft >= 128
    if given is not None and size != (width, height):
        # A given silhouette is exact at full resolution: within one working pixel of
        # the cleaned boundary (where the upsampled mask is neither 0 nor 255) use it.
        band = (soft > 0) & (soft < 255)
        full[band] = given[band] >= 128
    return full


def _segment_photo(
    rgb: np.ndarray,
    method: str,
    threshold: float | None,
    rect_full: tuple[int, int, int, int] | None,
    factor: float,
    details: dict,
    shared: SharedHypotheses | None = None,
    subject: str = "auto",
    several: bool = False,
) -> tuple[np.ndarray, str]:
    """threshold / grabcut / auto on the working-size RGB; returns (clean mask, method).

    auto weighs every hypothesis by consensus, then takes the ``subject`` asked for
    (:func:`_auto`); ``shared`` may hold the hypotheses.
    """
    if method == "auto":
        return _auto(rgb, (shared or SharedHypotheses()).of(rgb), details, subject, several)
    scene = Scene(rgb)
    if method == "threshold":
        mask, info = _threshold(rgb, threshold, scene)
    else:
        rect_work = None if rect_full is None else tuple(v / factor for v in rect_full)
        mask, info = grabcut(rgb, scene, rect_work)
    details[method] = info
    return mask, method


__all__ = ["Hypotheses", "PreparedScene", "Segmentation", "SharedHypotheses", "clean_mask", "hypotheses", "segment"]
