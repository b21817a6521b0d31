"""The public pipeline: decode -> silhouette and framing -> fit -> composite -> report.

Everything takes and returns numpy arrays (and accepts torch tensors for ``S``); the
CLI is a thin layer over :func:`apply_jeans`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .device import resolve_backend, resolve_device
from .errors import JeansError
from .framing import Framing, frame_mask, identity_framing
from .garments import JEANS, Garment
from .geometry import CANVAS_SIZE, mask_box
from .io.svg import SVG_EXTENSIONS
from .plugins import get_garment

KINDS = ("auto", "silhouette", "photo")
#: ``one``: the main subject; ``all``: every separate object, each with its own garment.
OBJECTS = ("one", "all")


@dataclass
class Silhouette:
    """An object's silhouette at image resolution and on the canvas.

    ``mask``: ``(H, W)`` float32 alpha at image resolution (bool for one of several
    objects split from a photo, which saves memory on large photos); ``canvas``: the paper's
    ``S``, ``(256, 256)`` float32; ``framing`` maps canvas pixels to image pixels.
    """

    mask: np.ndarray
    canvas: np.ndarray
    framing: Framing
    method: str
    contour: np.ndarray | None = None  # (K, 2) image pixels, outer boundary
    details: dict = field(default_factory=dict)
    mask_is_canvas: bool = False  # an SVG's mask is drawn on the canvas, not in image units

    def to_mask(self, canvas_points: np.ndarray) -> np.ndarray:
        """Canvas pixels ``(..., 2)`` to pixels of ``mask``."""
        points = np.asarray(canvas_points, dtype=np.float64)
        return points.copy() if self.mask_is_canvas else self.framing.to_image(points)


#: The drawing-or-photo decision looks at a strided copy at most this many pixels wide.
_PROBE_SIDE = 512


def _two_tone_levels(grey: np.ndarray) -> tuple[float, float] | None:
    """The two tones of a flat dark-on-light (or light-on-dark) drawing, else None.

    A silhouette drawing has two flat tones and anti-aliased edges between them:
    nearly every pixel sits at one of the two extremes.
    """
    low, high = np.percentile(grey, [1, 99])
    if high - low < 64:
        return None
    scaled = (grey.astype(np.float32) - low) / (high - low)
    if np.mean((scaled > 0.1) & (scaled < 0.9)) > 0.03:
        return None
    return float(low), float(high)


def _alpha_between(grey: np.ndarray, low: float, high: float) -> np.ndarray:
    """Alpha of the object between two tones; the object is the tone that touches the border least."""
    scaled = np.clip((grey.astype(np.float32) - low) / (high - low), 0.0, 1.0)
    border = np.concatenate([scaled[0], scaled[-1], scaled[:, 0], scaled[:, -1]])
    return 1.0 - scaled if border.mean() >= 0.5 else scaled


def silhouette_from_drawing(pixels: np.ndarray) -> np.ndarray | None:
    """The alpha of a silhouette image (alpha channel, or one flat shape), else None.

    The decision is made on a strided copy, so a 24-MP photo costs no full-size
    float copies; only a drawing's alpha is computed at full resolution.

    Args:
        pixels: ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` uint8.

    Returns:
        ``(H, W)`` float32 alpha in [0, 1], or None when the image looks like a photo.
    """
    image = np.asarray(pixels)
    step = max(1, -(-max(image.shape[:2]) // _PROBE_SIDE))
    probe = image[::step, ::step]
    if image.ndim == 2:
        levels = _two_tone_levels(probe)
        return None if levels is None else _alpha_between(image, *levels)
    rgb = probe[..., :3].astype(np.float32)
    if image.shape[-1] == 4 and image[..., 3].min() < 250:
        # A cut-out photo has texture under its alpha; a drawing is one flat colour.
        opaque = probe[..., 3] > 252
        if opaque.any() and rgb[opaque].std(axis=0).max() < 4:
            return image[..., 3].astype(np.float32) / 255.0
        return None
    if np.abs(rgb - rgb.mean(axis=-1, keepdims=True)).max() > 24:
        return None  # coloured: a photo
    levels = _two_tone_levels(rgb.mean(axis=-1))
    if levels is None:
        return None
    return _alpha_between(image[..., :3].mean(axis=-1, dtype=np.float32), *levels)


def silhouette_contours(silhouette: Silhouette) -> list[np.ndarray]:
    """Boundary polylines ``[(K, 2)]`` of a silhouette in image pixels.

    Photos carry their outer contour (``Silhouette.contour``); for drawings and SVGs
    every boundary (holes included, for an even-odd fill) is traced as the 0.5
    iso-line of the mask, between pixel centres.
    """
    if silhouette.contour is not None and len(silhouette.contour) >= 3:
        return [np.asarray(silhouette.contour, dtype=np.float64)]
    from skimage.measure import find_contours

    # Padding closes the contours of shapes that touch the border.
    padded = np.pad(np.asarray(silhouette.mask, dtype=np.float32), 1)
    contours = []
    for rc in find_contours(padded, 0.5):
        if len(rc) < 3:
            continue
        xy = rc[:, ::-1] - 1.0 + 0.5  # (row, col) of padded centres -> (x, y) of pixel centres
        contours.append(silhouette.framing.to_image(xy) if silhouette.mask_is_canvas else xy)
    return contours


def load_mask(path: str | os.PathLike, max_pixels: int = 100_000_000) -> np.ndarray:
    """A ``(H, W)`` bool mask from an image file: its alpha when it has some, else grey >= 128."""
    try:
        loaded = load_image(path, max_pixels=max_pixels)
    except JeansError as exc:
        raise JeansError(f"cannot read mask {path}: {exc}") from None
    pixels = loaded.pixels
    if loaded.alpha_meaningful:
        return pixels[..., 3] >= 128
    return pixels[..., :3].mean(axis=-1) >= 128


def silhouette_from_alpha(alpha: np.ndarray, method: str) -> Silhouette:
    """Frame a soft alpha ``(H, W)``: a 256x256 one is the canvas, others are framed."""
    alpha = np.clip(np.asarray(alpha, dtype=np.float32), 0.0, 1.0)
    if alpha.sum() < 1.0:
        raise JeansError("silhouette is empty")
    if alpha.shape == (CANVAS_SIZE, CANVAS_SIZE):
        return Silhouette(alpha, alpha, identity_framing(), method)
    canvas, framing = frame_mask(alpha)
    return Silhouette(alpha, canvas, framing, method)


def read_svg(path: str | os.PathLike) -> Silhouette:
    """An SVG silhouette: its 256 canvas is the viewBox, fitted with aspect kept."""
    from .io.svg import read_svg_silhouette

    if not Path(path).is_file():
        raise JeansError("file not found" if not Path(path).exists() else "not a file")
    svg = read_svg_silhouette(path)
    framing = Framing(
        (float(svg.canvas_to_image[0, 2]), float(svg.canvas_to_image[1, 2])),
        float(svg.canvas_to_image[0, 0] * CANVAS_SIZE),
        (int(round(svg.width)), int(round(svg.height))),
    )
    return Silhouette(svg.alpha, svg.alpha, framing, "svg", mask_is_canvas=True)


def load_image(path: str | os.PathLike, max_pixels: int = 100_000_000, raw_half_size: bool = False):
    """Decode a photo or RAW file: RGB(A) uint8, upright, with metadata (``LoadedImage``).

    RAW files decode at the camera's full size, or at half size (faster) with ``raw_half_size``.
    """
    from .io.image import load_image as _load

    return _load(path, max_pixels=max_pixels, raw_half_size=raw_half_size)


def extract_silhouette(
    image: np.ndarray,
    method: str = "auto",
    *,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
) -> Silhouette:
    """Segment the main object of a photo ``(H, W, 3|4)`` uint8 and frame it.

    ``method``: ``auto``, ``alpha``, ``threshold``, ``grabcut`` (see the README);
    ``mask``: a user-supplied ``(H, W)`` mask, used instead of segmentation.
    """
    from .plugins import is_plugin_silhouette_method, segment_with
    from .silhouette.photo import segment

    if mask is None and is_plugin_silhouette_method(method):
        # A plugin extractor takes the image alone: threshold and rect are built-in options.
        result = segment_with(method, image)
    else:
        result = segment(image, "mask" if mask is not None else method, threshold=threshold, rect=rect, mask=mask)
    canvas, framing = frame_mask(result.mask)
    return Silhouette(
        result.mask.astype(np.float32), canvas, framing, result.method, result.contour, dict(result.details)
    )


def extract_silhouettes(
    image: np.ndarray,
    method: str = "auto",
    *,
    objects: str = "one",
    points: list[tuple[float, float]] | None = None,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
) -> list[Silhouette]:
    """The objects of a photo ``(H, W, 3|4)`` uint8, each segmented and framed on its own.

    ``objects="one"``: the main subject (as :func:`extract_silhouette`); ``"all"``: every
    separate object of the subject mask, largest first (specks under 10% of the largest
    are dropped). ``points``: ``(x, y)`` image pixels, like clicks: each picks the object
    under it (or within 2% of the image's long side of it), else, or when the automatic
    subject is uncertain (``details["uncertain"]``: its hypotheses disagreed), the object
    around it is segmented by GrabCut seeded at the point (method ``"point"``); the
    picked objects come first, in point order, and with ``"all"`` the other objects follow. Every
    silhouette's ``details`` holds its ``box`` (x, y, w, h) and, when a point picked
    it, the ``point``.
    """
    from .silhouette.objects import check_point, object_at, split_objects
    from .silhouette.photo import binarise, segment
    from .silhouette.seeded import segment_at_point

    if objects not in OBJECTS:
        raise JeansError(f"unknown objects {objects!r} (use {' or '.join(OBJECTS)})")
    pixels = np.asarray(image)
    clicks = [check_point(point, pixels.shape[:2]) for point in points or ()]
    try:
        main = extract_silhouette(pixels, method, threshold=threshold, rect=rect, mask=mask)
    except JeansError:
        if not clicks or mask is not None:
            raise
        main = None  # nothing found automatically: every point segments its own object
    found = []
    if clicks or objects == "all":
        # A given mask is split before its cleaning, which keeps only pieces of at least
        # a quarter of the largest one's size: the user said what the objects are.
        subject = binarise(mask) if mask is not None else None if main is None else main.mask
        found = [] if subject is None or not subject.any() else split_objects(subject)
    if not clicks and len(found) <= 1:
        main.details["box"] = list(_box_of(main))
        return [main]

    def pick(obj, point=None) -> Silhouette | None:
        if mask is None:
            return _object_silhouette(obj, main, point)
        try:
            return _framed(segment(pixels, "mask", mask=obj.mask), point)
        except JeansError:  # a speck of the user's mask, too small to segment
            if point is None:
                return None
            raise

    chosen: list[Silhouette | None] = []
    picked: set[int] = set()
    # When auto's hypotheses disagreed, its subject may be a wrong blob that holds the
    # clicked thing (players joined by the boards behind them): the click is then
    # segmented on its own, and the blob under it gets no garment of its own.
    uncertain = main is not None and bool(main.details.get("uncertain"))
    for point in clicks:
        index = object_at(found, point)
        if index is None or uncertain:
            if index is not None:
                picked.add(index)
            chosen.append(_framed(segment_at_point(pixels, point), point))
        elif index not in picked:
            picked.add(index)
            chosen.append(pick(found[index], point))
    if objects == "all":
        chosen += [pick(obj) for i, obj in enumerate(found) if i not in picked]
    return [silhouette for silhouette in chosen if silhouette is not None]


def _framed(segmentation, point: tuple[float, float] | None = None) -> Silhouette:
    """A :class:`Silhouette` of one object's :class:`Segmentation` (its bool mask kept)."""

    canvas, framing = frame_mask(segmentation.mask)
    details = {**segmentation.details, "box": list(mask_box(segmentation.mask))}
    if point is not None:
        details["point"] = list(point)
    return Silhouette(segmentation.mask, canvas, framing, segmentation.method, segmentation.contour, details)


def _object_silhouette(obj, main: Silhouette, point: tuple[float, float] | None = None) -> Silhouette:
    """A :class:`Silhouette` of one object split from the main subject's mask."""
    canvas, framing = frame_mask(obj.mask)
    details = {"box": list(obj.box), "subject_method": main.method}
    if point is not None:
        details["point"] = list(point)
    return Silhouette(obj.mask, canvas, framing, main.method, obj.contour, details)


def fit(
    silhouette: Silhouette | np.ndarray,
    garment: str | os.PathLike | Garment = "jeans",
    preset: str = "default",
    iterations: int = 100,
    seed: int = 0,
    device: str = "cpu",
    starts: int | None = None,
    posture: str = "upright",
    backend: str | None = None,
):
    """Fit a garment to a :class:`Silhouette` or directly to a 256x256 ``S`` (array or tensor).

    ``posture``: ``upright`` (the default preset hangs the garment upright unless no
    upright placement passes the rule checks) or ``any`` (every posture competes).
    Returns a :class:`jeanscv.fitter.FitResult`: vertices in canvas pixels (and in image
    pixels, ``vertices_image``, for a Silhouette), per-term losses, the loss history.
    ``backend``: ``"fast"`` (numba kernel, CPU) or ``"torch"`` (the reference, and the
    only one on CUDA); None: ``$JEANSCV_BACKEND``, else fast on the CPU when numba is
    installed. Both give the same fit to rounding.
    """
    from .fitter import fit as _fit

    canvas = silhouette.canvas if isinstance(silhouette, Silhouette) else silhouette
    result = _fit(
        canvas,
        preset,
        get_garment(garment),
        iterations=iterations,
        seed=seed,
        starts=starts,
        device=resolve_device(device),
        posture=posture,
        backend=backend,
    )
    if isinstance(silhouette, Silhouette):
        result.vertices_image = silhouette.framing.to_image(result.vertices)
    return result


def composite(
    image: np.ndarray,
    fit_result,
    silhouette: Silhouette,
    style: str = "denim",
    clip: bool = True,
    seed: int = 0,
) -> np.ndarray:
    """Paint the fitted garment onto ``image`` (the photo the silhouette came from)."""
    from .compositing import composite_jeans

    vertices = silhouette.to_mask(fit_result.vertices)
    return composite_jeans(
        image, vertices, fit_result.garment, silhouette.mask if clip else None, style=style, clip=clip, seed=seed
    )


def draw_garment(
    image: np.ndarray, vertices_image: np.ndarray, garment: Garment = JEANS, style: str = "flat"
) -> np.ndarray:
    """Paint a garment polygon given in image pixels onto ``image`` (no clipping):
    for drawing intermediate states, such as the frames of an optimisation animation."""
    from .compositing import composite_jeans

    return composite_jeans(image, vertices_image, garment, None, style=style, clip=False)


def draw_figure(mask: np.ndarray, vertices_mask: np.ndarray | None, garment: Garment = JEANS) -> np.ndarray:
    """The paper's figure of a ``(H, W)`` alpha with a garment polygon in its pixels."""
    from .compositing import render_silhouette_figure

    return render_silhouette_figure(mask, vertices_mask, garment)


def figure(silhouette: Silhouette, fit_result=None) -> np.ndarray:
    """The paper's figure style at the mask's resolution: black shape, blue jeans, white ground.

    Without a fit, the silhouette alone.
    """
    from .compositing import render_silhouette_figure

    if fit_result is None:
        return render_silhouette_figure(silhouette.mask, None)
    return render_silhouette_figure(silhouette.mask, silhouette.to_mask(fit_result.vertices), fit_result.garment)


def _box_of(silhouette: Silhouette) -> tuple[int, int, int, int]:
    """The object's bounding box ``(x, y, w, h)`` in image pixels (an SVG's, through its framing)."""
    if "box" in silhouette.details:
        return tuple(silhouette.details["box"])

    x, y, w, h = mask_box(silhouette.mask)
    if not silhouette.mask_is_canvas:
        return x, y, w, h
    (x0, y0), (x1, y1) = silhouette.framing.to_image(np.array([[x, y], [x + w, y + h]], np.float64))
    return int(np.floor(x0)), int(np.floor(y0)), int(np.ceil(x1) - np.floor(x0)), int(np.ceil(y1) - np.floor(y0))


#: The auto segmentation's ``details`` that the report gives as ``subject``: the winning
#: hypothesis, why it won, its mean IoU with the others and whether that is under half.
SUBJECT_KEYS = ("chosen", "reason", "consensus", "uncertain")


@dataclass
class FittedObject:
    """One object of a result: its silhouette and the garment fitted to it."""

    silhouette: Silhouette
    fit: object  # FitResult

    def report(self) -> dict:
        """The object's entry in the report's ``objects`` list; ``tilt_degrees`` and
        ``posture`` are measured on its ``vertices_image`` as reported."""
        from .checks import rule_report
        from .posture import posture_name, tilt_degrees

        framing = self.silhouette.framing
        rules = rule_report(self.fit.vertices, self.silhouette.canvas, self.fit.garment)
        vertices_image = _rounded(framing.to_image(self.fit.vertices))
        tilt = tilt_degrees(np.asarray(vertices_image), self.fit.garment)
        entry = {
            "box": list(_box_of(self.silhouette)),
            "method": self.silhouette.method,
            "vertices_canvas": _rounded(self.fit.vertices),
            "vertices_image": vertices_image,
            "canvas_to_image": _rounded(framing.canvas_to_image),
            "objective": _round(self.fit.objective),
            "tilt_degrees": _round(tilt),
            "posture": posture_name(tilt),
            "rules": {k: (_round(v) if isinstance(v, float) else v) for k, v in rules.to_json().items()},
        }
        if "point" in self.silhouette.details:
            entry["point"] = [_round(v) for v in self.silhouette.details["point"]]
        return entry


@dataclass
class JeansResult:
    """Everything :func:`apply_jeans` produced.

    ``silhouette`` and ``fit`` are the main (first) object's; ``objects`` lists every
    object that got a garment, the main one first.
    """

    image: np.ndarray  # the output picture, uint8
    silhouette: Silhouette
    fit: object  # FitResult
    kind: str  # "silhouette" or "photo"
    source: object | None = None  # LoadedImage for files that were decoded
    objects: list[FittedObject] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not self.objects:
            self.objects = [FittedObject(self.silhouette, self.fit)]

    def report(self, input_name: str = "", output_name: str = "") -> dict:
        """The JSON-able report (the CLI's ``--json`` sidecar): the top-level fields
        describe the main object, ``objects`` every object."""
        fit_result = self.fit
        framing = self.silhouette.framing
        entries = [obj.report() for obj in self.objects]
        report = {
            "input": input_name,
            "output": output_name,
            "kind": self.kind,
            "garment": fit_result.garment.name,
            "preset": fit_result.preset.name,
            "iterations": fit_result.iterations,
            "seed": fit_result.seed,
            "device": fit_result.device,
            "canvas_size": CANVAS_SIZE,
            "silhouette_method": self.silhouette.method,
            "vertices_canvas": entries[0]["vertices_canvas"],
            "vertices_image": entries[0]["vertices_image"],
            "canvas_to_image": entries[0]["canvas_to_image"],
            "image_size": list(framing.image_size),
            "tilt_degrees": entries[0]["tilt_degrees"],
            "posture": entries[0]["posture"],
            "paper_terms": _rounded_dict(fit_result.paper_terms),
            "paper_total": _round(fit_result.paper_total),
            "objective": _round(fit_result.objective),
            "terms": _rounded_dict(fit_result.terms),
            "weights": dict(fit_result.preset.weights),
            "inter_pairs": fit_result.preset.inter_pairs,
            "starts": fit_result.num_starts,
            "finished_starts": fit_result.start_ids,
            "start_index": fit_result.start_index,
            "start_objectives": [_round(v) for v in fit_result.start_objectives],
            "rules": entries[0]["rules"],
            "objects": entries,
            "seconds": round(fit_result.seconds, 3),
        }
        # Why auto segmentation took this subject, and whether its hypotheses agreed.
        subject = {key: self.silhouette.details[key] for key in SUBJECT_KEYS if key in self.silhouette.details}
        if subject:
            report["subject"] = subject
        return report


def _round(value: float) -> float:
    return float(f"{float(value):.6g}")


def _rounded(array: np.ndarray) -> list:
    return np.vectorize(_round, otypes=[float])(np.asarray(array, dtype=np.float64)).tolist()


def _rounded_dict(values: dict[str, float]) -> dict[str, float]:
    return {k: _round(v) for k, v in values.items()}


def prepare_input(
    source: str | os.PathLike | np.ndarray,
    kind: str = "auto",
    silhouette_method: str = "auto",
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
    max_pixels: int = 100_000_000,
    raw_half_size: bool = False,
    objects: str = "one",
    points: list[tuple[float, float]] | None = None,
) -> tuple[list[Silhouette], str, np.ndarray | None, object | None]:
    """Decode and segment an input: ``(silhouettes, kind, pixels, loaded_image)``.

    Photos give one silhouette per object (see :func:`extract_silhouettes`; ``points``
    are pixels of the photo as displayed, also for a RAW file decoded at half size);
    silhouette drawings and SVGs give their one shape.
    """
    if kind not in KINDS:
        raise JeansError(f"unknown input kind {kind!r} (use {', '.join(KINDS)})")
    if objects not in OBJECTS:
        raise JeansError(f"unknown objects {objects!r} (use {' or '.join(OBJECTS)})")
    loaded = None
    if isinstance(source, (str, os.PathLike)):
        if Path(source).suffix.lower() in SVG_EXTENSIONS:
            return [read_svg(source)], "silhouette", None, None
        loaded = load_image(source, max_pixels=max_pixels, raw_half_size=raw_half_size)
        pixels = loaded.pixels
    else:
        pixels = np.asarray(source)
        if pixels.dtype != np.uint8 or pixels.ndim not in (2, 3):
            raise JeansError("image must be a uint8 array of shape (H, W), (H, W, 3) or (H, W, 4)")
    if pixels.ndim == 2:
        pixels = np.repeat(pixels[..., None], 3, axis=-1)
    if kind != "photo" and mask is None:
        alpha = silhouette_from_drawing(pixels)
        if alpha is not None or kind == "silhouette":
            if alpha is None:
                raise JeansError("not a silhouette image (no alpha and not two-toned)")
            return [silhouette_from_alpha(alpha, "drawing")], "silhouette", pixels, loaded
    if points and loaded is not None and tuple(loaded.original_size) != pixels.shape[1::-1]:
        points = _to_decoded(points, loaded.original_size, pixels.shape[1::-1])
    silhouettes = extract_silhouettes(
        pixels, silhouette_method, objects=objects, points=points, threshold=threshold, rect=rect, mask=mask
    )
    return silhouettes, "photo", pixels, loaded


def _to_decoded(points, original_size: tuple[int, int], size: tuple[int, int]) -> list[tuple[float, float]]:
    """Points in pixels of the photo as displayed -> pixels of its (reduced) decoded copy."""
    from .silhouette.objects import check_point

    width, height = original_size
    scale = np.array([size[0] / width, size[1] / height])
    return [tuple(np.asarray(check_point(point, (height, width))) * scale) for point in points]


def apply_jeans(
    source: str | os.PathLike | np.ndarray,
    *,
    garment: str | Garment = "jeans",
    preset: str = "default",
    iterations: int = 100,
    seed: int = 0,
    device: str = "cpu",
    starts: int | None = None,
    kind: str = "auto",
    silhouette_method: str = "auto",
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
    style: str = "denim",
    clip: bool = True,
    max_pixels: int = 100_000_000,
    raw_half_size: bool = False,
    objects: str = "one",
    points: list[tuple[float, float]] | None = None,
    posture: str = "upright",
    backend: str | None = None,
) -> JeansResult:
    """Decode, segment, fit and composite in one call.

    ``source``: a path (photo, RAW, silhouette PNG or SVG) or a uint8 image array.
    Silhouette drawings give the paper's figure (black shape, blue jeans on white);
    photos get denim painted on at full resolution. ``objects="all"`` gives every
    separate object of a photo its own garment; ``points`` ((x, y) pixels, like clicks)
    pick the objects (see :func:`extract_silhouettes`). RAW files are decoded at the
    camera's full size unless ``raw_half_size``. ``posture``: ``upright`` or ``any`` (see
    :func:`fit`). ``backend``: as in :func:`fit`.
    """
    from . import _fast
    from .presets import get_preset

    get_preset(preset).with_posture(posture)  # a bad preset or posture fails before the decoding
    if resolve_backend(backend, resolve_device(device)) == "fast":
        _fast.warm_up()  # numba's set-up overlaps decoding and segmentation
    silhouettes, resolved_kind, pixels, loaded = prepare_input(
        source, kind, silhouette_method, threshold, rect, mask, max_pixels, raw_half_size, objects, points
    )
    fitted = []
    image = pixels
    for index, silhouette in enumerate(silhouettes):
        fit_result = fit(silhouette, garment, preset, iterations, seed, device, starts, posture, backend)
        fitted.append(FittedObject(silhouette, fit_result))
        if resolved_kind == "silhouette":
            image = figure(silhouette, fit_result)
        else:
            # Each object gets its own denim noise, painted over the objects before it.
            image = composite(image, fit_result, silhouette, style=style, clip=clip, seed=seed + index)
    main = fitted[0]
    return JeansResult(image, main.silhouette, main.fit, resolved_kind, loaded, fitted)


__all__ = [
    "JEANS",
    "JeansResult",
    "Silhouette",
    "apply_jeans",
    "composite",
    "extract_silhouette",
    "extract_silhouettes",
    "FittedObject",
    "OBJECTS",
    "draw_figure",
    "draw_garment",
    "figure",
    "fit",
    "load_image",
    "load_mask",
    "silhouette_contours",
    "prepare_input",
    "read_svg",
    "resolve_device",
]
