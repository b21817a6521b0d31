"""How a fitted garment hangs: its tilt from straight down and the posture it names.

Measured on vertices alone, so the fitter (choosing and pruning starts) and the report
(``tilt_degrees``, ``posture``) share one definition.
"""

from __future__ import annotations

import numpy as np

from .garments import Garment


def tilt_degrees(vertices: np.ndarray, garment: Garment) -> float:
    """The angle between straight down the image and the line from the waistband's midpoint
    to the midpoint of the outer hems (:attr:`Garment.hems`): 0 upright, 90 lying on its
    side, 180 upside down. A framing (scale and shift) keeps it, so canvas and image
    vertices give the same tilt."""
    v = np.asarray(vertices, dtype=np.float64)
    down = v[list(garment.hems)].mean(axis=0) - v[list(garment.waist)].mean(axis=0)
    return float(np.degrees(np.arctan2(abs(down[0]), down[1])))


#: Posture names by tilt: upright up to 30 degrees (the issue's bar), lying below 120.
POSTURE_NAMES = ((30.0, "upright"), (120.0, "lying"), (180.0, "upside down"))


def posture_name(tilt: float) -> str:
    """``upright``, ``lying`` or ``upside down`` for a tilt in degrees (:func:`tilt_degrees`)."""
    return next(name for limit, name in POSTURE_NAMES if tilt <= limit)


def posture(vertices: np.ndarray, garment: Garment) -> int:
    """The rules selection's coarse posture: 0 upright, 1 lying, 2 upside down, in 60-degree
    bands of the direction from the waistband to the mean of the other vertices (kept as it
    was, so that ``posture="any"`` reproduces the earlier choices)."""
    v = np.asarray(vertices, dtype=np.float64)
    waist = v[list(garment.waist)].mean(axis=0)
    down = np.delete(v, list(garment.waist), axis=0).mean(axis=0) - waist
    tilt = float(np.degrees(np.arctan2(abs(down[0]), down[1])))
    return int(min(tilt // 60.0001, 2))
