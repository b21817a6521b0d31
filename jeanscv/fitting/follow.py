"""A fit that follows: the garment of the previous frame, carried by the subject's motion,
settled on this frame's silhouette in a few steps (no fresh multi-start).

The still fit (:func:`jeanscv.fitting.fitter.fit`) tries a dozen placements over a hundred
steps; between two frames of a clip the subject moves a little, so the previous frame's
garment moved the same way is already close. :func:`refit` runs a few Adam steps from it on
the unblurred canvas, at a smaller learning rate, then pulls the result towards that
starting point (a temporal term, the closed form of ``|v - fitted|^2 + stiffness |v -
start|^2``), so the garment does not jitter with the mask's edge noise, and keeps the start
where the steps would change its posture.
"""

from __future__ import annotations

import numpy as np

from ..geometry import CANVAS_SIZE
from .adam import BatchAdam
from .fitter import _half_width, as_silhouette_array
from .garments import Garment
from .objectives import make_descent, make_objective
from .posture import tilt_degrees
from .presets import Preset
from .terms import TERM_NAMES

#: Steps per frame: with a quarter of the still fit's learning rate, enough to take up
#: the residual of a few pixels that the motion prediction leaves. With the stiffness
#: below, on bench.clips' 40-frame moving and still clips: 0.39 and 0.28 px mean movement
#: away from the subject's a frame, 0.43 and 0.35 px RMS (8 steps and a stiffness of 2:
#: 0.73 and 0.48 px, 0.94 and 0.72 px RMS).
FOLLOW_STEPS = 4
#: The learning rate as a fraction of the preset's: Adam's first steps move every
#: coordinate by about the learning rate, which at full rate would shake a settled garment.
FOLLOW_LEARNING_RATE = 0.25
#: Weight of the start (the motion-carried previous garment) against the new fit.
FOLLOW_STIFFNESS = 6.0
#: Weight of the anchor (the garment where it was found, moved with the subject since):
#: on bench.clips' 300-frame clips 6 px of drift and more became under 2 px (see
#: docs/clips.md); the caller lowers it where the subject changes shape.
FOLLOW_ANCHORING = 3.0
#: A step that turns the garment more than this (degrees) is a posture change: refused.
MAX_TURN = 20.0


def refit(
    silhouette,
    start: np.ndarray,
    preset: Preset,
    garment: Garment,
    *,
    backend: str = "fast",
    device: str = "cpu",
    steps: int = FOLLOW_STEPS,
    stiffness: float = FOLLOW_STIFFNESS,
    anchor: np.ndarray | None = None,
    anchoring: float = FOLLOW_ANCHORING,
) -> tuple[np.ndarray, float, dict[str, float]]:
    """Settle ``start`` (``(N, 2)`` canvas pixels) on the 256x256 ``silhouette``, pulled
    towards ``start`` by ``stiffness`` and towards ``anchor`` (``(N, 2)`` canvas pixels,
    none when None) by ``anchoring``: ``(vertices, objective, terms)``, vertices in canvas
    pixels."""
    s = as_silhouette_array(silhouette)
    start = np.asarray(start, dtype=np.float64)
    vertices = start
    if steps > 0:
        optimizer = BatchAdam(start[None] / CANVAS_SIZE, lr=preset.learning_rate * FOLLOW_LEARNING_RATE)
        descend = make_descent(backend, garment, preset.inter_pairs, preset.weights, device)
        totals, _ = descend(optimizer, s, steps, _half_width(s))
        fitted = optimizer.params[0] * CANVAS_SIZE
        if len(totals) == steps and np.isfinite(fitted).all():
            if anchor is None:
                anchoring = 0.0
                anchor = start
            vertices = (fitted + stiffness * start + anchoring * np.asarray(anchor, np.float64)) / (
                1.0 + stiffness + anchoring
            )
    if abs(tilt_degrees(vertices, garment) - tilt_degrees(start, garment)) > MAX_TURN:
        vertices = start
    evaluate = make_objective(backend, garment, preset.inter_pairs, preset.weights, device)
    totals, _, terms = evaluate(vertices[None], s, _half_width(s), False)
    return vertices, float(totals[0]), {name: float(terms[name][0]) for name in TERM_NAMES}


__all__ = ["FOLLOW_ANCHORING", "FOLLOW_STEPS", "FOLLOW_STIFFNESS", "refit"]
