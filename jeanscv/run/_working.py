"""A large clip's working copy (issue 48, "Large frames"): its later frames are followed,
held to the detector and fitted on a copy at most a given side long, and painted at full
size. The objects move between the two sizes here.

Arrays: frames ``(H, W, 3)`` uint8; masks ``(H, W)``; scales ``(sx, sy)`` working size
over full size.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from ..geometry import mask_box
from ..report import FittedObject


def working_copy(pixels: np.ndarray, side: int) -> tuple[np.ndarray, tuple[float, float]]:
    """``pixels`` at most ``side`` long (the frame itself when it fits) and its scale
    ``(sx, sy)`` against the frame (``(1.0, 1.0)`` when it fits)."""
    height, width = pixels.shape[:2]
    if max(height, width) <= side:
        return pixels, (1.0, 1.0)
    factor = side / max(height, width)
    size = (max(1, round(width * factor)), max(1, round(height * factor)))
    return cv2.resize(pixels, size, interpolation=cv2.INTER_AREA), (size[0] / width, size[1] / height)


def rescaled(fitted: FittedObject, scale: tuple[float, float], to_work: bool, shape: tuple[int, int]) -> FittedObject:
    """``fitted`` (a frame's object) moved by ``scale`` ``(sx, sy)``: onto the working copy
    (``to_work``) or from it onto the frame at full size. Its mask is resized to ``shape``
    ``(H, W)``, its framing, box, detection box and contour scaled; its canvas and its fit's
    canvas vertices are the same."""
    sx, sy = scale
    silhouette = fitted.silhouette
    height, width = shape
    mask = np.asarray(silhouette.mask)
    if to_work:
        mask = cv2.resize(mask.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)
    else:  # bool, without a float copy of the frame's size
        mask = (mask >= 0.5).view(np.uint8) * np.uint8(255)
        mask = cv2.resize(mask, (width, height), interpolation=cv2.INTER_LINEAR) >= 128
    side = 0.5 * (sx + sy)  # the framing's canvas is square: the mean scale
    framing = dataclasses.replace(
        silhouette.framing,
        origin=(silhouette.framing.origin[0] * sx, silhouette.framing.origin[1] * sy),
        side=silhouette.framing.side * side,
        image_size=(width, height),
    )
    details = dict(silhouette.details or {})
    if not to_work:  # the box of the mask as painted, as a followed frame's
        details["box"] = list(mask_box(mask))
    elif details.get("box") is not None:
        x, y, w, h = details["box"]
        details["box"] = [round(x * sx), round(y * sy), round(w * sx), round(h * sy)]
    if isinstance(details.get("detection"), dict) and details["detection"].get("box") is not None:
        x0, y0, x1, y1 = details["detection"]["box"]
        details["detection"] = {**details["detection"], "box": [x0 * sx, y0 * sy, x1 * sx, y1 * sy]}
    contour = None if silhouette.contour is None else np.asarray(silhouette.contour) * np.array([sx, sy])
    moved = dataclasses.replace(silhouette, mask=mask, framing=framing, contour=contour, details=details)
    fit = dataclasses.replace(fitted.fit, vertices_image=framing.to_image(fitted.fit.vertices))
    return FittedObject(moved, fit)
