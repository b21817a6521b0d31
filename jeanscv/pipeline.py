"""The pipeline: decode -> silhouette and framing -> fit -> composite, in one call
(:func:`apply_jeans`), and its steps for callers that want them one by one.

Everything takes and returns numpy arrays (and accepts torch tensors for ``S``); the
CLI is a thin layer over :func:`apply_jeans`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .device import resolve_backend, resolve_device
from .errors import JeansError
from .fitting import fitter
from .fitting.fitter import FitResult
from .fitting.garments import Garment
from .io.svg import SVG_EXTENSIONS
from .options import JeansOptions
from .paint.figures import composite, figure
from .plugins import get_garment
from .report import FittedObject, JeansResult
from .subject.drawing import silhouette_from_drawing
from .subject.extraction import extract_silhouettes, object_clicks
from .subject.silhouettes import Silhouette, load_mask, read_svg, silhouette_from_alpha

if TYPE_CHECKING:  # decoding imports Pillow, on first use
    from .io.image import LoadedImage
    from .subject.photo import SharedHypotheses


def load_image(path: str | os.PathLike, max_pixels: int = 100_000_000, raw_half_size: bool = False) -> LoadedImage:
    """Decode a photo or RAW file: RGB(A) uint8, upright, with metadata (``LoadedImage``).

    RAW files decode at the camera's full size, or at half size (faster) with ``raw_half_size``.
    """
    from .io.image import load_image as _load

    return _load(path, max_pixels=max_pixels, raw_half_size=raw_half_size)


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
) -> FitResult:
    """Fit a garment to a :class:`Silhouette` or directly to a 256x256 ``S`` (array or tensor).

    ``posture``: ``upright`` (the default preset hangs the garment upright unless no
    upright placement passes the rule checks) or ``any`` (every posture competes).
    Returns a :class:`jeanscv.fitting.fitter.FitResult`: vertices in canvas pixels (and in image
    pixels, ``vertices_image``, for a Silhouette), per-term losses, the loss history.
    ``backend``: ``"fast"`` (numba kernel, CPU) or ``"torch"`` (the reference, and the
    only one on CUDA); None: ``$JEANSCV_BACKEND``, else fast on the CPU when numba is
    installed. Both give the same fit to rounding.
    """
    canvas = silhouette.canvas if isinstance(silhouette, Silhouette) else silhouette
    result = fitter.fit(
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


def prepare_input(
    source: str | os.PathLike | np.ndarray,
    options: JeansOptions | None = None,
    *,
    shared: SharedHypotheses | None = None,
    **overrides: Any,
) -> tuple[list[Silhouette], str, np.ndarray | None, LoadedImage | None]:
    """Decode and segment an input: ``(silhouettes, kind, pixels, loaded_image)``.

    ``options`` (or the defaults) with ``overrides`` (:class:`JeansOptions`' names) say how.
    ``shared``: a :class:`~jeanscv.subject.photo.SharedHypotheses` that keeps auto's
    hypotheses of the photo for a click session of ``pixels`` (a server clicks on it next).
    Photos give one silhouette per object (see :func:`extract_silhouettes`; ``points``,
    ``background_points``, ``box`` and ``clicks`` are pixels of the photo as displayed, also for a
    RAW file decoded at half size; ``clicks`` may be a clicks file); silhouette drawings
    and SVGs give their one shape.
    """
    options = (options or JeansOptions()).replace(**overrides)
    kind, points = options.kind, list(options.points)
    mask = options.mask
    if isinstance(mask, (str, os.PathLike)):
        mask = load_mask(mask, options.max_pixels)
    if isinstance(options.clicks, (str, os.PathLike)):
        options = options.replace(clicks=_read_clicks(options.clicks))  # read first: any input reports a bad file
    loaded = None
    if _is_svg_path(source):
        return [read_svg(source)], "silhouette", None, None
    if isinstance(source, (str, os.PathLike)):
        loaded = load_image(source, max_pixels=options.max_pixels, raw_half_size=options.raw_half_size)
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
    clicks = None
    if mask is None and (points or options.background_points or options.box is not None or options.clicks is not None):
        # Checked against the photo as displayed, then scaled to the decoded copy.
        clicks = _clicks(options, loaded.original_size if loaded is not None else pixels.shape[1::-1])
        if clicks.image_size != pixels.shape[1::-1]:
            clicks = clicks.scaled(pixels.shape[1::-1])
        points = []
    elif points and loaded is not None and tuple(loaded.original_size) != pixels.shape[1::-1]:
        points = _to_decoded(points, loaded.original_size, pixels.shape[1::-1])
    silhouettes = extract_silhouettes(
        pixels,
        options.silhouette_method,
        objects=options.objects,
        points=points,
        clicks=clicks,
        threshold=options.threshold,
        rect=options.rect,
        mask=mask,
        shared=shared,
        subject=options.subject,
        detector=options.detector,
    )
    return silhouettes, "photo", pixels, loaded


def _is_svg_path(source) -> bool:
    """Whether ``source`` names an SVG file (a silhouette: nothing to decode or segment)."""
    return isinstance(source, (str, os.PathLike)) and Path(source).suffix.lower() in SVG_EXTENSIONS


def _clicks(options: JeansOptions, shown: tuple[int, int]):
    """Every object's clicks of ``options`` (``points`` and ``background_points`` first,
    then ``clicks``), checked against the photo's size as displayed, ``shown`` =
    (width, height)."""
    from .subject.clicks import Clicks

    clicks = options.clicks
    found = Clicks(
        tuple(object_clicks(options.points, options.background_points, clicks, options.box)),
        getattr(clicks, "image_size", None),
    )
    found.check(shown)
    return Clicks(found.objects, tuple(shown))


def _read_clicks(path: str | os.PathLike):
    """A clicks file, or JeansError naming it and the reason."""
    from .subject.clicks import read_clicks

    try:
        return read_clicks(path)
    except JeansError as exc:
        raise JeansError(f"clicks file {Path(path).name}: {exc}") from None


def _to_decoded(points, original_size: tuple[int, int], size: tuple[int, int]) -> list[tuple[float, float]]:
    """Points in pixels of the photo as displayed -> pixels of its (reduced) decoded copy."""
    from .subject.objects import check_point

    width, height = original_size
    scale = np.array([size[0] / width, size[1] / height])
    return [tuple(np.asarray(check_point(point, (height, width))) * scale) for point in points]


def apply_jeans(
    source: str | os.PathLike | np.ndarray,
    options: JeansOptions | None = None,
    *,
    shared: SharedHypotheses | None = None,
    **overrides: Any,
) -> JeansResult:
    """Decode, segment, fit and composite in one call.

    ``source``: a path (photo, RAW, silhouette PNG or SVG) or a uint8 image array.
    ``options``: a :class:`JeansOptions` (default: its defaults); ``overrides``: any of its
    fields by name (``apply_jeans(path, garment="skirt", objects="all")``), over ``options``.
    Silhouette drawings give the paper's figure (black shape, blue jeans on white);
    photos get denim painted on at full resolution. ``objects="all"`` gives every
    separate object of a photo its own garment; ``points`` and ``background_points``
    ((x, y) pixels of the photo as displayed) are one object's positive and negative
    clicks, ``clicks`` (a :class:`jeanscv.subject.clicks.Clicks` or a clicks file) several
    objects' (see :func:`extract_silhouettes`); ``mask`` may be an array or an image file. RAW files are decoded at the camera's full size unless ``raw_half_size``.
    ``posture``: ``upright`` or ``any`` (see :func:`fit`). ``backend``: as in :func:`fit`.
    ``shared``: as in :func:`prepare_input` (auto's hypotheses of this photo, cut once for
    everything done with it; the result is the same without).
    """
    from .fitting import _fast
    from .fitting.presets import get_preset

    options = (options or JeansOptions()).replace(**overrides)
    get_preset(options.preset).with_posture(options.posture)  # a bad preset fails before the decoding
    if resolve_backend(options.backend, resolve_device(options.device)) == "fast":
        _fast.warm_up()  # numba's set-up overlaps decoding and segmentation
    if not _is_svg_path(source):
        from .subject.scene import prepare_lab_tables

        prepare_lab_tables()  # segmentation's colour tables, built on the other core while the photo decodes
    silhouettes, resolved_kind, pixels, loaded = prepare_input(source, options, shared=shared)
    fitted = []
    image = pixels
    for index, silhouette in enumerate(silhouettes):
        fit_result = fit(
            silhouette,
            options.garment,
            options.preset,
            options.iterations,
            options.seed,
            options.device,
            options.starts,
            options.posture,
            options.backend,
        )
        fitted.append(FittedObject(silhouette, fit_result))
        if resolved_kind == "silhouette":
            image = figure(silhouette, fit_result)
        else:
            # Each object gets its own denim noise, painted over the objects before it.
            image = composite(
                image, fit_result, silhouette, style=options.style, clip=options.clip, seed=options.seed + index
            )
    main = fitted[0]
    return JeansResult(image, main.silhouette, main.fit, resolved_kind, loaded, fitted)
