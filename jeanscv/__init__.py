"""jeanscv: how would this thing wear jeans?

Coordinate convention, used everywhere in the package: x right, y down, in pixels,
with pixel ``(col, row)`` covering the square ``[col, col+1) x [row, row+1)``, so its
centre is at ``(col + 0.5, row + 0.5)``. The fitting canvas is 256x256 pixels;
"normalised" coordinates are canvas pixels / 256.

The public API (numpy in, numpy out) is imported lazily, so ``import jeanscv``
stays cheap and does not load torch until a function needs it.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "load_image": "jeanscv.pipeline",
    "extract_silhouette": "jeanscv.extraction",
    "extract_silhouettes": "jeanscv.extraction",
    "fit": "jeanscv.pipeline",
    "composite": "jeanscv.figures",
    "apply_jeans": "jeanscv.pipeline",
    "read_svg": "jeanscv.silhouettes",
    "Silhouette": "jeanscv.silhouettes",
    "JeansResult": "jeanscv.report",
    "JeansOptions": "jeanscv.options",
    "JeansError": "jeanscv.errors",
    "JalgorithmLoss": "jeanscv.loss",
    "jalgorithm_terms": "jeanscv.loss",
    "PRESETS": "jeanscv.presets",
    "GARMENTS": "jeanscv.garments",
    "get_garment": "jeanscv.plugins",
    "load_garment": "jeanscv.plugins",
    "available_garments": "jeanscv.plugins",
    "run_on_dask": "jeanscv.distributed",
    "load_mask": "jeanscv.silhouettes",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'jeanscv' has no attribute {name!r}")
