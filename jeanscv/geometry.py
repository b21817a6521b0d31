"""Canvas geometry and affine maps between the canvas and input images.

Convention (stated once for the package): x right, y down, pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``; its centre is ``(c + 0.5, r + 0.5)``. Affine maps are 2x3
matrices ``M`` acting on column vectors ``(x, y, 1)``.
"""

from __future__ import annotations

import numpy as np

from .errors import JeansError

CANVAS_SIZE = 256


def apply_affine(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Map ``(..., 2)`` points through the 2x3 affine ``matrix``."""
    points = np.asarray(points, dtype=np.float64)
    matrix = np.asarray(matrix, dtype=np.float64)
    return points @ matrix[:, :2].T + matrix[:, 2]


def invert_affine(matrix: np.ndarray) -> np.ndarray:
    """Inverse of a 2x3 affine map."""
    full = np.vstack([np.asarray(matrix, dtype=np.float64), [0.0, 0.0, 1.0]])
    return np.linalg.inv(full)[:2]


def mask_box(mask: np.ndarray) -> tuple[int, int, int, int]:
    """``(x, y, w, h)`` bounding box of the object in a ``(H, W)`` mask: bool, or float
    alpha where >= 0.5 is object. Raises JeansError when the mask is empty."""
    # A bool mask is used as it is: a float copy of a 24-MP mask costs ~100 MB.
    solid = mask if mask.dtype == bool else mask.astype(np.float32, copy=False) >= 0.5
    rows = np.flatnonzero(solid.any(axis=1))
    cols = np.flatnonzero(solid.any(axis=0))
    if rows.size == 0:
        raise JeansError("silhouette is empty")
    return int(cols[0]), int(rows[0]), int(cols[-1] + 1 - cols[0]), int(rows[-1] + 1 - rows[0])
