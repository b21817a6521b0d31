"""Whether an image is a silhouette drawing (an alpha channel, or one flat shape on a flat
ground) rather than a photo, and the drawing's alpha."""

from __future__ import annotations

import numpy as np

#: The drawing-or-photo decision looks at a strided copy at most this many pixels wide.
_PROBE_SIDE = 512


def _two_tone_levels(grey: np.ndarray) -> tuple[float, float] | None:
    """The two tones of a flat dark-on-light (or light-on-dark) drawing, else None.

    A silhouette drawing has two flat tones and anti-aliased edges between them:
    nearly every pixel sits at one of the two extremes.
    """
    low, high = np.percentile(grey, [1, 99])
    if high - low < 64:
        return None
    scaled = (grey.astype(np.float32) - low) / (high - low)
    if np.mean((scaled > 0.1) & (scaled < 0.9)) > 0.03:
        return None
    return float(low), float(high)


def _alpha_between(grey: np.ndarray, low: float, high: float) -> np.ndarray:
    """Alpha of the object between two tones; the object is the tone that touches the border least."""
    scaled = np.clip((grey.astype(np.float32) - low) / (high - low), 0.0, 1.0)
    border = np.concatenate([scaled[0], scaled[-1], scaled[:, 0], scaled[:, -1]])
    return 1.0 - scaled if border.mean() >= 0.5 else scaled


def silhouette_from_drawing(pixels: np.ndarray) -> np.ndarray | None:
    """The alpha of a silhouette image (alpha channel, or one flat shape), else None.

    The decision is made on a strided copy, so a 24-MP photo costs no full-size
    float copies; only a drawing's alpha is computed at full resolution.

    Args:
        pixels: ``(H, W)``, ``(H, W, 3)`` or ``(H, W, 4)`` uint8.

    Returns:
        ``(H, W)`` float32 alpha in [0, 1], or None when the image looks like a photo.
    """
    image = np.asarray(pixels)
    step = max(1, -(-max(image.shape[:2]) // _PROBE_SIDE))
    probe = image[::step, ::step]
    if image.ndim == 2:
        levels = _two_tone_levels(probe)
        return None if levels is None else _alpha_between(image, *levels)
    rgb = probe[..., :3].astype(np.float32)
    if image.shape[-1] == 4 and image[..., 3].min() < 250:
        # A cut-out photo has texture under its alpha; a drawing is one flat colour.
        opaque = probe[..., 3] > 252
        if opaque.any() and rgb[opaque].std(axis=0).max() < 4:
            return image[..., 3].astype(np.float32) / 255.0
        return None
    if np.abs(rgb - rgb.mean(axis=-1, keepdims=True)).max() > 24:
        return None  # coloured: a photo
    levels = _two_tone_levels(rgb.mean(axis=-1))
    if levels is None:
        return None
    return _alpha_between(image[..., :3].mean(axis=-1, dtype=np.float32), *levels)
