"""Silhouette-extractor plugins: segmentation methods from other installed distributions
(entry-point group ``jeanscv.subject.silhouettes``), beside the built-ins (:func:`get_silhouette_method`,
:func:`segment_with`), and the entry-point loading that garment plugins (:mod:`jeanscv.plugins`) share.

It sits in the subject stage because :func:`jeanscv.subject.extraction.extract_silhouette`
asks it for a plugin's mask; :mod:`jeanscv.plugins` (garments, which belong to the fit)
re-exports every public name here, so ``jeanscv.plugins`` stays the one import for plugin users.
A plugin that fails to import or returns the wrong thing is skipped with a
:class:`PluginWarning`; look-ups are cached for the life of the process
(:func:`jeanscv.plugins.refresh` forgets them).
"""

from __future__ import annotations

import functools
import importlib
import importlib.metadata
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import JeansError
from ..options import SILHOUETTE_METHODS

SILHOUETTE_GROUP = "jeanscv.silhouettes"

#: Built-in segmentation methods offered by name (``mask`` needs a mask, so it is not one).
BUILTIN_SILHOUETTE_METHODS = SILHOUETTE_METHODS

SilhouetteMethod = Callable[..., Any]


class PluginWarning(UserWarning):
    """A plugin was skipped (it failed to load or is not what its group expects)."""


def _origin(entry_point: importlib.metadata.EntryPoint) -> str:
    dist = getattr(entry_point, "dist", None)
    return f"{dist.name} {dist.version}" if dist is not None else entry_point.value


def _skip(kind: str, entry_point: importlib.metadata.EntryPoint, reason: str) -> None:
    warnings.warn(
        f"jeanscv: skipping {kind} plugin {entry_point.name!r} ({_origin(entry_point)}): {reason}",
        PluginWarning,
        stacklevel=3,
    )


def _entry_points(group: str, builtins: tuple[str, ...] | dict, kind: str) -> list[importlib.metadata.EntryPoint]:
    """The group's entry points, first of each name only, built-in names left out."""
    seen: dict[str, importlib.metadata.EntryPoint] = {}
    for entry_point in importlib.metadata.entry_points(group=group):
        if entry_point.name in builtins:
            _skip(kind, entry_point, "a built-in has that name")
        elif entry_point.name in seen:
            _skip(kind, entry_point, f"already provided by {_origin(seen[entry_point.name])}")
        else:
            seen[entry_point.name] = entry_point
    return list(seen.values())


@functools.cache
def _plugin_silhouette_methods() -> tuple[tuple[str, SilhouetteMethod], ...]:
    found = []
    for entry_point in _entry_points(SILHOUETTE_GROUP, BUILTIN_SILHOUETTE_METHODS + ("mask",), "silhouette"):
        try:
            extract = entry_point.load()
        except Exception as exc:  # noqa: BLE001 - any plugin failure only skips that plugin
            _skip("silhouette", entry_point, _reason(exc))
            continue
        if not callable(extract):
            _skip("silhouette", entry_point, f"it gave {type(extract).__name__}, not a callable")
            continue
        found.append((entry_point.name, extract))
    return tuple(found)


def _reason(exc: BaseException) -> str:
    detail = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {detail}" if detail else type(exc).__name__


def _builtin_method(name: str) -> SilhouetteMethod:
    def extract(image: np.ndarray, **options: Any):
        from .photo import segment

        return segment(image, name, **options)

    extract.__name__ = f"segment_{name}"
    extract.__doc__ = f"The built-in {name!r} segmentation (:func:`jeanscv.subject.photo.segment`)."
    return extract


def available_silhouette_methods() -> dict[str, SilhouetteMethod]:
    """Every silhouette method by name: built-ins, then plugins.

    Each value is ``extract(image, **options)`` taking an ``(H, W, 3|4) uint8`` image and
    returning an ``(H, W)`` mask or an object with a ``.mask`` attribute (built-ins
    return a :class:`jeanscv.subject.photo.Segmentation`).
    """
    builtins = {name: _builtin_method(name) for name in BUILTIN_SILHOUETTE_METHODS}
    return {**builtins, **dict(_plugin_silhouette_methods())}


def get_silhouette_method(name: str) -> SilhouetteMethod:
    """The ``extract`` callable of a built-in or plugin silhouette method."""
    methods = available_silhouette_methods()
    try:
        return methods[name]
    except KeyError:
        raise JeansError(f"unknown silhouette method {name!r} (known: {', '.join(methods)})") from None


def is_plugin_silhouette_method(name: str) -> bool:
    """True for a method that a plugin provides (not one of ``segment``'s own)."""
    return name in dict(_plugin_silhouette_methods())


def extract_mask(name: str, image: np.ndarray, **options: Any) -> np.ndarray:
    """Run a silhouette method and return its mask as ``(H, W) bool``.

    Masks may be bool, float in [0, 1] (object where >= 0.5) or integer 0/1 or 0..255
    (object where >= 128). Anything a plugin raises other than :class:`JeansError`
    becomes one, naming the method.
    """
    extract = get_silhouette_method(name)
    image = np.asarray(image)
    try:
        result = extract(image, **options)
    except JeansError:
        raise
    except Exception as exc:  # noqa: BLE001 - a plugin's bug is reported as this input's failure
        raise JeansError(f"silhouette method {name!r} failed: {_reason(exc)}") from exc
    return _as_mask(getattr(result, "mask", result), image.shape[:2], name)


def _as_mask(mask: object, shape: tuple[int, ...], name: str) -> np.ndarray:
    try:
        array = np.asarray(mask)
    except Exception:  # noqa: BLE001 - whatever it returned, it is not a mask
        array = np.asarray(None)
    if array.shape != tuple(shape):
        raise JeansError(f"silhouette method {name!r} gave a mask of shape {array.shape}, not {tuple(shape)}")
    if array.dtype == bool:
        return array
    if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise JeansError(f"silhouette method {name!r} gave a {array.dtype} mask, not a boolean or numeric one")
    if np.issubdtype(array.dtype, np.floating):
        if not np.isfinite(array).all():
            raise JeansError(f"silhouette method {name!r} gave a mask with NaN or infinite values")
        return array >= 0.5
    # 0/1 masks and 0..255 masks are both common; anything above 1 is read as 0..255.
    return array >= (1 if array.max(initial=0) <= 1 else 128)


def segment_with(name: str, image: np.ndarray, **options: Any):
    """A :class:`jeanscv.subject.photo.Segmentation` from any method, plugins included.

    Built-ins go straight to ``segment``; a plugin's mask is cleaned like a user mask
    (``segment(image, "mask", mask=...)``: specks removed, holes filled, contour traced)
    and the result carries the plugin's name as its ``method``.
    """
    from .photo import segment

    if name in BUILTIN_SILHOUETTE_METHODS or name == "mask":
        return segment(image, name, **options)
    mask = extract_mask(name, image, **options)
    result = segment(image, "mask", mask=mask)
    result.method = name
    result.details["plugin"] = name
    return result


__all__ = [
    "BUILTIN_SILHOUETTE_METHODS",
    "PluginWarning",
    "SILHOUETTE_GROUP",
    "available_silhouette_methods",
    "extract_mask",
    "get_silhouette_method",
    "is_plugin_silhouette_method",
    "segment_with",
]
