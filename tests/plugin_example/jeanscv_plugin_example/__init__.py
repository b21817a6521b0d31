"""Example jeanscv plugin: one garment and one silhouette extractor.

Imports jeanscv only inside the functions, so merely discovering the plugin stays cheap.
"""

from __future__ import annotations

import numpy as np

#: Six vertices in canvas pixels: 0 hem left, 1 shoulder left, 2 neck left, 3 neck
#: right, 4 shoulder right, 5 hem right. Open: the neckline (edge 2) and the hem (edge 5).
CAPE_VERTICES = [[80.0, 180.0], [92.0, 80.0], [112.0, 70.0], [134.0, 70.0], [154.0, 80.0], [166.0, 180.0]]


def cape():
    """The ``cape`` garment (a zero-argument factory, as the entry point allows)."""
    from jeanscv.garments import Garment  # the path plugins have always used (jeanscv.fitting.garments)

    return Garment(
        name="cape",
        template=np.array(CAPE_VERTICES),
        open_edges=(2, 5),
        waist=(2, 3),
        description="A six-vertex cape, from the example plugin.",
        extra={"style": "plain", "colour": (128, 0, 32)},
    )


def everything_dark(image: np.ndarray, level: int = 128) -> np.ndarray:
    """``(H, W) bool``: every pixel whose mean RGB is below ``level`` is the object."""
    return np.asarray(image)[..., :3].mean(axis=-1) < level
