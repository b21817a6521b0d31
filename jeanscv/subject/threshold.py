"""The ``threshold`` method of :func:`jeanscv.subject.photo.segment`, also one of auto's
hypotheses: :func:`threshold_split`, a global threshold on one channel.

Arrays: images are ``(H, W, 3)`` RGB ``uint8``; masks ``(H, W) bool`` with True on the
object.
"""

from __future__ import annotations

import cv2
import numpy as np

from jeanscv.errors import JeansError

from .masks import border_contact, clean
from .scene import Scene, rgb_to_lab

_BLUR_MARGIN = 0.02  # texture-blurred thresholds must beat sharp ones by this score


def _channels(rgb: np.ndarray) -> dict[str, np.ndarray]:
    """Candidate 8-bit channels for thresholding: grey, HSV saturation, Lab a and b."""
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)
    lab = rgb_to_lab(rgb)
    return {
        "grey": cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY),
        "saturation": hsv[..., 1],
        "lab_a": lab[..., 1],
        "lab_b": lab[..., 2],
    }


def _split(channel: np.ndarray, threshold: float) -> tuple[np.ndarray, str]:
    """Split at ``threshold``; the object is the side touching less of the border."""
    light = channel >= threshold
    if border_contact(light) <= border_contact(~light):
        return light, "light"
    return ~light, "dark"


def threshold_split(rgb: np.ndarray, threshold: float | None, scene: Scene) -> tuple[np.ndarray, dict]:
    """``grey >= threshold`` when given, else the best-scoring Otsu split among
    grey / saturation / Lab a / Lab b, each lightly blurred (and texture-blurred when
    the scene is scored at its texture scale).
    Returns the cleaned working mask and what was chosen."""
    if threshold is not None:
        raw, polarity = _split(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), threshold)
        cleaned = clean(raw)
        info = {"channel": "grey", "blur_sigma": 0.0, "threshold": float(threshold), "polarity": polarity}
        return cleaned, {**info, "features": scene.features(cleaned)}
    best: tuple[np.ndarray, dict] | None = None
    best_rank = -np.inf
    scores = {}
    sharp = max(1.0, 0.002 * max(rgb.shape[:2]))
    # Texture-blurred channels only where the scene is scored at its texture scale:
    # elsewhere they never won (the same masks on 18 real and 96 synthetic photos
    # without them), and they are half of this function's time.
    blurs = (sharp, scene.texture_sigma * scene.factor) if scene.scale == "texture" else (sharp,)
    for sigma in blurs:
        blurred = cv2.GaussianBlur(rgb, (0, 0), sigma)
        for name, channel in _channels(blurred).items():
            if int(channel.max()) == int(channel.min()):
                continue
            value, _ = cv2.threshold(channel, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
            # Otsu's value t keeps pixels > t, i.e. >= t + 1 on integers.
            raw, polarity = _split(channel, value + 1)
            cleaned = clean(raw)
            features = scene.features(cleaned)
            key = f"{name}@{sigma:.1f}"
            scores[key] = features["score"]
            info = {
                "channel": name,
                "blur_sigma": round(sigma, 2),
                "threshold": float(value + 1),
                "polarity": polarity,
                "features": features,
            }
            # Blurring smooths boundaries: only take it when clearly better.
            rank = features["score"] - (0.0 if sigma == sharp else _BLUR_MARGIN)
            if rank > best_rank:
                best, best_rank = (cleaned, info), rank
    if best is None or best[1]["features"]["score"] <= 0:
        raise JeansError("no object found to segment")
    return best[0], {**best[1], "scores": scores}
