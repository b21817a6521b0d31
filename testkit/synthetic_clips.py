"""Synthetic clips with an exact mask on every frame: a cut-out subject moving, turning
and growing over a background, for the clip tests and ``bench/clips.py``.

A *sprite* (an RGB picture of the subject and its mask) is pasted onto a background
through a similarity transform per frame (:class:`Motion`), with an anti-aliased edge; the
frame's true mask is the sprite's mask through the same transform. The sprite is a real
pet cut out of ``/work/shared/pet_photos`` (:func:`pet_sprite`) or a procedural animal
filled with a skimage texture (:func:`texture_sprite`, always available).

Arrays: frames ``(H, W, 3) uint8`` RGB, masks ``(H, W) bool``; transforms are 2x3 maps
from sprite pixels to frame pixels (centres at +0.5, as everywhere in jeanscv).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .synthetic_photos import animal_mask, texture

PET_PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "pet_photos"
REAL_PHOTOS = Path(__file__).resolve().parents[2] / "shared" / "real_photos"


@dataclass(frozen=True)
class Sprite:
    """A cut-out subject: ``pixels`` ``(h, w, 3)`` and ``alpha`` ``(h, w)`` float32 0..1."""

    pixels: np.ndarray
    alpha: np.ndarray


@dataclass(frozen=True)
class Motion:
    """How the sprite moves: its centre goes from ``start`` to ``start + travel`` (frame
    pixels) along a smooth path, turning by up to ``turn`` degrees and scaling between
    ``1 - grow`` and ``1 + grow`` (times ``scale``), over ``frames`` frames; ``still``
    frames hold it in place first."""

    start: tuple[float, float]
    travel: tuple[float, float] = (0.0, 0.0)
    turn: float = 0.0
    grow: float = 0.0
    scale: float = 1.0
    frames: int = 30

    def transform(self, index: int, sprite: Sprite) -> np.ndarray:
        """The 2x3 map from sprite pixels to frame pixels at frame ``index``."""
        t = index / max(self.frames - 1, 1)
        ease = 0.5 - 0.5 * math.cos(math.pi * t)  # smooth start and stop
        centre = np.array(self.start) + ease * np.array(self.travel)
        angle = math.radians(self.turn * math.sin(2 * math.pi * t))
        scale = self.scale * (1 + self.grow * math.sin(math.pi * t))
        h, w = sprite.alpha.shape
        c, s = math.cos(angle) * scale, math.sin(angle) * scale
        rotate = np.array([[c, -s], [s, c]])
        shift = centre - rotate @ np.array([w / 2, h / 2])
        return np.hstack([rotate, shift[:, None]])


def pet_sprite(name: str, long_side: int | None = None) -> Sprite | None:
    """The pet of ``PET_PHOTOS/name.jpg`` cut out by its mask (None when absent), its
    longer side scaled to ``long_side``."""
    photo, mask_path = PET_PHOTOS / f"{name}.jpg", PET_PHOTOS / f"{name}.mask.png"
    if not photo.is_file() or not mask_path.is_file():
        return None
    pixels = cv2.cvtColor(cv2.imread(str(photo)), cv2.COLOR_BGR2RGB)
    mask = cv2.imread(str(mask_path), cv2.IMREAD_GRAYSCALE) > 127
    ys, xs = np.nonzero(mask)
    pad = 4
    y0, y1 = max(ys.min() - pad, 0), min(ys.max() + pad + 1, mask.shape[0])
    x0, x1 = max(xs.min() - pad, 0), min(xs.max() + pad + 1, mask.shape[1])
    pixels, alpha = pixels[y0:y1, x0:x1], mask[y0:y1, x0:x1].astype(np.float32)
    if long_side:
        factor = long_side / max(alpha.shape)
        size = (max(1, round(alpha.shape[1] * factor)), max(1, round(alpha.shape[0] * factor)))
        pixels = cv2.resize(pixels, size, interpolation=cv2.INTER_AREA)
        alpha = cv2.resize(alpha, size, interpolation=cv2.INTER_AREA)
    return Sprite(np.ascontiguousarray(pixels), alpha)


def texture_sprite(
    size: int = 60, seed: int = 1, name: str = "chelsea", tint: tuple[float, float, float] = (1.0, 1.0, 1.0)
) -> Sprite:
    """A procedural animal ``size`` pixels tall filled with skimage texture ``name``
    (times ``tint`` per channel)."""
    rng = np.random.default_rng(seed)
    mask = animal_mask(size, size, rng)
    pixels = texture(name, size, size, rng, tint=tint)
    return Sprite(pixels, mask.astype(np.float32))


def background(
    width: int,
    height: int,
    photo: str | None = None,
    window: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0),
    seed: int = 2,
    name: str = "gravel",
    tint: tuple[float, float, float] = (1.0, 1.0, 1.0),
) -> np.ndarray:
    """A background: the ``window`` (fractions x0, y0, x1, y1) of ``REAL_PHOTOS/photo``
    covering the frame when given and present, else skimage texture ``name`` (times ``tint``)."""
    if photo is not None and (REAL_PHOTOS / photo).is_file():
        image = cv2.cvtColor(cv2.imread(str(REAL_PHOTOS / photo)), cv2.COLOR_BGR2RGB)
        h, w = image.shape[:2]
        image = image[int(window[1] * h) : int(window[3] * h), int(window[0] * w) : int(window[2] * w)]
        h, w = image.shape[:2]
        scale = max(width / w, height / h)
        image = cv2.resize(image, (math.ceil(w * scale), math.ceil(h * scale)), interpolation=cv2.INTER_AREA)
        y0, x0 = (image.shape[0] - height) // 2, (image.shape[1] - width) // 2
        return np.ascontiguousarray(image[y0 : y0 + height, x0 : x0 + width])
    return texture(name, height, width, np.random.default_rng(seed), tint=tint)


def _pixel_centred(matrix: np.ndarray) -> np.ndarray:
    """A map between pixel-centre coordinates (+0.5) as OpenCV's integer-pixel one."""
    full = np.vstack([matrix, [0, 0, 1]])
    shift = np.array([[1, 0, 0.5], [0, 1, 0.5], [0, 0, 1]])
    unshift = np.array([[1, 0, -0.5], [0, 1, -0.5], [0, 0, 1]])
    return (unshift @ full @ shift)[:2]


def frame(
    sprite: Sprite, ground: np.ndarray, matrix: np.ndarray, noise: float = 0.0, rng=None
) -> tuple[np.ndarray, np.ndarray]:
    """The sprite pasted on ``ground`` through ``matrix``: ``(frame, true mask)``."""
    height, width = ground.shape[:2]
    cv_matrix = _pixel_centred(matrix)
    alpha = cv2.warpAffine(sprite.alpha, cv_matrix, (width, height), flags=cv2.INTER_LINEAR)
    pixels = cv2.warpAffine(sprite.pixels, cv_matrix, (width, height), flags=cv2.INTER_LINEAR)
    out = ground.astype(np.float32) * (1 - alpha[..., None]) + pixels.astype(np.float32) * alpha[..., None]
    if noise:
        out += (rng or np.random.default_rng(0)).normal(0, noise, out.shape).astype(np.float32)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8), alpha >= 0.5


def true_mask(sprite: Sprite, matrix: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The frame's true mask alone (what :func:`frame` gives, without the pixels)."""
    alpha = cv2.warpAffine(sprite.alpha, _pixel_centred(matrix), (shape[1], shape[0]), flags=cv2.INTER_LINEAR)
    return alpha >= 0.5


def clip(
    sprite: Sprite, ground: np.ndarray, motion: Motion, noise: float = 0.0, seed: int = 0
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``motion.frames`` frames: ``(frame, true mask, sprite->frame 2x3 map)`` each,
    made one at a time (a long clip takes a frame's memory)."""
    rng = np.random.default_rng(seed)
    for index in range(motion.frames):
        matrix = motion.transform(index, sprite)
        pixels, mask = frame(sprite, ground, matrix, noise, rng)
        yield pixels, mask, matrix


def inner_point(mask: np.ndarray) -> tuple[float, float]:
    """The pixel centre of ``mask`` farthest from its edge: a click surely on the object."""
    depth = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 5)
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return col + 0.5, row + 0.5


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two bool masks (1 when both are empty)."""
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def carried(vertices: np.ndarray, from_matrix: np.ndarray, to_matrix: np.ndarray) -> np.ndarray:
    """Frame-pixel ``vertices`` placed on the sprite at ``from_matrix``, where they are
    when the sprite is at ``to_matrix``: how a garment that follows the subject moves."""
    inverse = cv2.invertAffineTransform(from_matrix)
    on_sprite = vertices @ inverse[:, :2].T + inverse[:, 2]
    return on_sprite @ to_matrix[:, :2].T + to_matrix[:, 2]
