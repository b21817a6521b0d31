"""jeanscv: how would this thing wear jeans?

Coordinate convention, used everywhere in the package: x right, y down, in pixels,
with pixel ``(col, row)`` covering the square ``[col, col+1) x [row, row+1)``, so its
centre is at ``(col + 0.5, row + 0.5)``. The fitting canvas is 256x256 pixels;
"normalised" coordinates are canvas pixels / 256.

The public API (numpy in, numpy out) is imported lazily, so ``import jeanscv``
stays cheap and does not load torch until a function needs it.

The package's folders are the stages of the data flow, each importing only those below
it (``tests/test_imports.py`` checks the order): :mod:`jeanscv.io` (decode, encode),
:mod:`jeanscv.detect` (photo -> the objects a shipped detector sees),
:mod:`jeanscv.subject` (photo -> subject mask -> Silhouette), :mod:`jeanscv.fitting`
(Silhouette's canvas -> fitted polygon), :mod:`jeanscv.paint` (fit -> picture), then
:mod:`jeanscv.pipeline` and :mod:`jeanscv.api`, which tie them, and :mod:`jeanscv.run`
(many inputs). ``errors``, ``geometry``, ``device`` and ``options`` sit below them all.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "load_image": "jeanscv.pipeline",
    "extract_silhouette": "jeanscv.subject.extraction",
    "extract_silhouettes": "jeanscv.subject.extraction",
    "fit": "jeanscv.pipeline",
    "composite": "jeanscv.paint.figures",
    "apply_jeans": "jeanscv.pipeline",
    "apply_jeans_to_clip": "jeanscv.run.clips",
    "read_svg": "jeanscv.subject.silhouettes",
    "Silhouette": "jeanscv.subject.silhouettes",
    "JeansResult": "jeanscv.report",
    "JeansOptions": "jeanscv.options",
    "JeansError": "jeanscv.errors",
    "JalgorithmLoss": "jeanscv.fitting.loss",
    "jalgorithm_terms": "jeanscv.fitting.loss",
    "PRESETS": "jeanscv.fitting.presets",
    "GARMENTS": "jeanscv.fitting.garments",
    "get_garment": "jeanscv.plugins",
    "load_garment": "jeanscv.plugins",
    "available_garments": "jeanscv.plugins",
    "run_on_dask": "jeanscv.run.distributed",
    "load_mask": "jeanscv.subject.silhouettes",
}

__all__ = ["__version__", *_LAZY]

#: Import paths from before the stage folders that the docs showed and plugins use:
#: old name -> the module it now is (the same module object, not a copy). A package's
#: modules follow it: ``jeanscv.silhouette.photo`` is ``jeanscv.subject.photo``.
_MOVED = {
    "jeanscv.garments": "jeanscv.fitting.garments",
    "jeanscv.clicks": "jeanscv.subject.clicks",
    "jeanscv.distributed": "jeanscv.run.distributed",
    "jeanscv.silhouette": "jeanscv.subject",
}


def _moved(name: str) -> str | None:
    """The module an old path of :data:`_MOVED` (or a module of an old package) is now."""
    for old, new in _MOVED.items():
        if name == old or name.startswith(old + "."):
            return new + name[len(old) :]
    return None


class _MovedFinder:
    """Imports an old path of :data:`_MOVED` as the module it names now (a meta path
    finder and its loader; not derived from importlib.abc, which costs ``import jeanscv``
    20 ms)."""

    def __init__(self) -> None:
        self._specs: dict[str, Any] = {}  # old name -> the module's own spec

    def find_spec(self, name, path=None, target=None):
        return importlib.machinery.ModuleSpec(name, self) if _moved(name) else None

    def create_module(self, spec):
        module = importlib.import_module(_moved(spec.name))
        self._specs[spec.name] = module.__spec__  # the import system sets the alias' spec on it: put it back
        return module

    def exec_module(self, module) -> None:
        module.__spec__ = self._specs[module.__spec__.name]


if not any(type(finder).__qualname__ == "_MovedFinder" for finder in sys.meta_path):  # once, also after a reload
    sys.meta_path.insert(0, _MovedFinder())


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'jeanscv' has no attribute {name!r}")
