"""Plugins: garments and silhouette extractors from other installed distributions, and the
look-ups by name that put them beside the built-ins (:func:`get_garment`, :func:`get_silhouette_method`).

A distribution adds them with entry points (in its ``pyproject.toml``)::

    [project.entry-points."jeanscv.garments"]
    cape = "my_package.garments:CAPE"           # a Garment, or a zero-argument callable returning one

    [project.entry-points."jeanscv.silhouettes"]
    everything_dark = "my_package.masks:extract"  # extract(image, **options) -> (H, W) mask

The entry point's name is the garment's or method's name. Built-in names win over
plugins; a plugin that fails to import or returns the wrong thing is skipped with a
:class:`PluginWarning`, so one broken plugin never breaks jeanscv. Look-ups are cached
for the life of the process (:func:`refresh` forgets them).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
import os
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np

from .errors import JeansError
from .garments import GARMENTS, Garment
from .options import SILHOUETTE_METHODS

GARMENT_GROUP = "jeanscv.garments"
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


def _garment_from(entry_point: importlib.metadata.EntryPoint) -> Garment:
    """Load one garment entry point; raises on anything that is not a valid garment."""
    obj = entry_point.load()
    garment = obj if isinstance(obj, Garment) else obj() if callable(obj) else obj
    if not isinstance(garment, Garment):
        raise TypeError(f"it gave {type(garment).__name__}, not a jeanscv Garment")
    # The entry point's name is the one users type; keep the report consistent with it.
    return garment if garment.name == entry_point.name else dataclasses.replace(garment, name=entry_point.name)


@functools.cache
def _plugin_garments() -> tuple[tuple[str, Garment], ...]:
    found = []
    for entry_point in _entry_points(GARMENT_GROUP, GARMENTS, "garment"):
        try:
            found.append((entry_point.name, _garment_from(entry_point)))
        except Exception as exc:  # noqa: BLE001 - any plugin failure only skips that plugin
            _skip("garment", entry_point, _reason(exc))
    return tuple(found)


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


def refresh() -> None:
    """Forget cached plugin look-ups (after installing a plugin in a running process)."""
    importlib.invalidate_caches()
    _plugin_garments.cache_clear()
    _plugin_silhouette_methods.cache_clear()


def plugin_garments() -> dict[str, Garment]:
    """Garments from installed plugins only, by entry-point name."""
    return dict(_plugin_garments())


def available_garments() -> dict[str, Garment]:
    """Every garment by name: the built-ins first, then plugin garments."""
    return {**GARMENTS, **plugin_garments()}


def _looks_like_path(name: str) -> bool:
    return name.lower().endswith(".toml") or os.sep in name or "/" in name


def load_garment(path_or_name: str | os.PathLike) -> Garment:
    """A garment by name (built-in or plugin) or from a ``.toml`` file path."""
    return get_garment(path_or_name)


def get_garment(name: str | os.PathLike | Garment) -> Garment:
    """Resolve a garment: a :class:`Garment` as is, then a built-in name, then a plugin
    garment (entry-point group ``jeanscv.garments``), then a path to a ``.toml`` file.

    Built-ins win over plugins of the same name; a name that is none of these raises
    :class:`JeansError` listing the known names.
    """
    if isinstance(name, Garment):
        return name
    if isinstance(name, os.PathLike):
        return Garment.from_toml(name)
    if not isinstance(name, str):
        raise JeansError(f"a garment is a name or a .toml path, got {type(name).__name__}")
    if name in GARMENTS:
        return GARMENTS[name]
    if not _looks_like_path(name):
        plugins = plugin_garments()
        if name in plugins:
            return plugins[name]
        if not os.path.isfile(name):
            known = sorted({*GARMENTS, *plugins})
            raise JeansError(f"unknown garment {name!r} (known: {', '.join(known)}; or a .toml file)")
    return Garment.from_toml(name)


def _builtin_method(name: str) -> SilhouetteMethod:
    def extract(image: np.ndarray, **options: Any):
        from .silhouette.photo import segment

        return segment(image, name, **options)

    extract.__name__ = f"segment_{name}"
    extract.__doc__ = f"The built-in {name!r} segmentation (:func:`jeanscv.silhouette.photo.segment`)."
    return extract


def available_silhouette_methods() -> dict[str, SilhouetteMethod]:
    """Every silhouette method by name: built-ins, then plugins.

    Each value is ``extract(image, **options)`` taking an ``(H, W, 3|4) uint8`` image and
    returning an ``(H, W)`` mask or an object with a ``.mask`` attribute (built-ins
    return a :class:`jeanscv.silhouette.photo.Segmentation`).
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
    """A :class:`jeanscv.silhouette.photo.Segmentation` from any method, plugins included.

    Built-ins go straight to ``segment``; a plugin's mask is cleaned like a user mask
    (``segment(image, "mask", mask=...)``: specks removed, holes filled, contour traced)
    and the result carries the plugin's name as its ``method``.
    """
    from .silhouette.photo import segment

    if name in BUILTIN_SILHOUETTE_METHODS or name == "mask":
        return segment(image, name, **options)
    mask = extract_mask(name, image, **options)
    result = segment(image, "mask", mask=mask)
    result.method = name
    result.details["plugin"] = name
    return result


__all__ = [
    "BUILTIN_SILHOUETTE_METHODS",
    "GARMENT_GROUP",
    "PluginWarning",
    "SILHOUETTE_GROUP",
    "available_garments",
    "available_silhouette_methods",
    "extract_mask",
    "get_garment",
    "get_silhouette_method",
    "is_plugin_silhouette_method",
    "load_garment",
    "plugin_garments",
    "refresh",
    "segment_with",
]
