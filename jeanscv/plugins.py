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

The silhouette methods live in the subject stage (:mod:`jeanscv.subject.plugins`, which
extraction asks for a plugin's mask); their names are re-exported here.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
import os

from .errors import JeansError
from .fitting.garments import GARMENTS, Garment
from .subject.plugins import (
    BUILTIN_SILHOUETTE_METHODS,
    SILHOUETTE_GROUP,
    PluginWarning,
    _entry_points,
    _plugin_silhouette_methods,
    _reason,
    _skip,
    available_silhouette_methods,
    extract_mask,
    get_silhouette_method,
    is_plugin_silhouette_method,
    segment_with,
)

GARMENT_GROUP = "jeanscv.garments"


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
    garment (entry-point group ``jeanscv.fitting.garments``), then a path to a ``.toml`` file.

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
