"""A zoo of hand-drawn synthetic silhouettes for tests, benchmarks and the README.

Every shape is drawn procedurally with OpenCV on a 4x supersampled canvas and
averaged down, so ``S`` has anti-aliased edges like the paper's rasterized SVGs.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from jeanscv.geometry import CANVAS_SIZE

_SUPERSAMPLE = 4


def _canvas() -> np.ndarray:
    return np.zeros((CANVAS_SIZE * _SUPERSAMPLE,) * 2, np.uint8)


def _pts(points) -> np.ndarray:
    return np.round(np.asarray(points, dtype=np.float64) * _SUPERSAMPLE).astype(np.int32)


def _ellipse(img, centre, axes, angle=0.0) -> None:
    cv2.ellipse(img, tuple(int(v) for v in _pts(centre)), tuple(int(v) for v in _pts(axes)), angle, 0, 360, 255, -1)


def _limb(img, a, b, width) -> None:
    cv2.line(img, tuple(int(v) for v in _pts(a)), tuple(int(v) for v in _pts(b)), 255, int(width * _SUPERSAMPLE))
    for p in (a, b):
        cv2.circle(img, tuple(int(v) for v in _pts(p)), int(width * _SUPERSAMPLE / 2), 255, -1)


def _poly(img, points) -> None:
    cv2.fillPoly(img, [_pts(points)], 255)


def _finish(img) -> np.ndarray:
    small = img.reshape(CANVAS_SIZE, _SUPERSAMPLE, CANVAS_SIZE, _SUPERSAMPLE).mean(axis=(1, 3))
    return (small / 255.0).astype(np.float32)


def _person(legs_apart: float = 10, arms_up: bool = False, scale: float = 1.0, shift=(0, 0)) -> np.ndarray:
    img = _canvas()
    cx, cy = 128 + shift[0], 128 + shift[1]

    def p(x, y):
        return (cx + (x - 128) * scale, cy + (y - 128) * scale)

    _ellipse(img, p(128, 44), (15 * scale, 18 * scale))
    _poly(img, [p(105, 60), p(151, 60), p(148, 130), p(108, 130)])
    _limb(img, p(116, 125), p(116 - legs_apart, 225), 20 * scale)
    _limb(img, p(140, 125), p(140 + legs_apart, 225), 20 * scale)
    if arms_up:
        _limb(img, p(108, 66), p(80, 15), 12 * scale)
        _limb(img, p(148, 66), p(176, 15), 12 * scale)
    else:
        _limb(img, p(108, 66), p(85, 135), 12 * scale)
        _limb(img, p(148, 66), p(171, 135), 12 * scale)
    return _finish(img)


def _quadruped(neck: float = 0.0, legs: int = 4, body=(70, 28), leg_length: float = 55) -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 118), body)
    xs = np.linspace(128 - body[0] * 0.75, 128 + body[0] * 0.75, legs)
    for x in xs:
        _limb(img, (x, 125), (x + 3, 125 + leg_length), 13)
    _limb(img, (128 + body[0] * 0.8, 105), (128 + body[0] + 15, 90 - neck), 16)
    _ellipse(img, (128 + body[0] + 24, 84 - neck), (18, 11), -15)
    _limb(img, (128 - body[0] * 0.95, 110), (128 - body[0] - 20, 80), 6)
    return _finish(img)


def _spider() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 120), (30, 24))
    _ellipse(img, (128, 82), (17, 15))
    for side in (-1, 1):
        for k, angle in enumerate((-50, -15, 20, 55)):
            a = math.radians(angle)
            knee = (128 + side * (28 + 35 * math.cos(a)), 120 + 35 * math.sin(a) - 25)
            foot = (128 + side * (40 + 70 * math.cos(a)), 150 + 45 * math.sin(a) + 10 * k)
            _limb(img, (128, 120), knee, 8)
            _limb(img, knee, foot, 7)
    return _finish(img)


def _octopus() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 90), (50, 45))
    for k in range(6):
        x = 88 + k * 16
        pts = [(x + 10 * math.sin(t / 12 + k), 110 + t) for t in range(0, 110, 5)]
        for a, b in zip(pts[:-1], pts[1:]):
            _limb(img, a, b, 12 - 5 * (a[1] - 110) / 110)
    return _finish(img)


def _blob(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    angles = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    radius = 70 + sum(rng.normal(0, 14 / (k + 1)) * np.cos(k * angles + rng.uniform(0, 2 * np.pi)) for k in range(1, 7))
    img = _canvas()
    _poly(img, np.stack([128 + radius * np.cos(angles), 128 + radius * np.sin(angles)], axis=1))
    return _finish(img)


def _table() -> np.ndarray:
    img = _canvas()
    _poly(img, [(50, 95), (206, 95), (206, 115), (50, 115)])
    for x in (58, 92, 164, 198):
        _limb(img, (x, 110), (x, 210), 9)
    return _finish(img)


def _tree() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 85), (65, 55))
    _poly(img, [(115, 120), (141, 120), (146, 225), (110, 225)])
    return _finish(img)


def _bird() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 130), (45, 30), -10)
    _ellipse(img, (175, 100), (17, 15))
    _poly(img, [(188, 96), (215, 103), (188, 108)])
    _poly(img, [(110, 120), (60, 60), (150, 115)])
    _poly(img, [(85, 135), (40, 150), (88, 148)])
    _limb(img, (120, 155), (115, 200), 5)
    _limb(img, (138, 155), (140, 200), 5)
    return _finish(img)


def _fish() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (120, 128), (75, 35))
    _poly(img, [(185, 128), (235, 90), (225, 128), (235, 166)])
    _poly(img, [(110, 95), (135, 70), (140, 100)])
    return _finish(img)


def _snake() -> np.ndarray:
    img = _canvas()
    pts = [(40 + t, 128 + 60 * math.sin(t / 28)) for t in range(0, 180, 4)]
    for a, b in zip(pts[:-1], pts[1:]):
        _limb(img, a, b, 26)
    return _finish(img)


def _star() -> np.ndarray:
    angles = np.arange(10) * np.pi / 5 - np.pi / 2
    radius = np.where(np.arange(10) % 2 == 0, 110, 45)
    img = _canvas()
    _poly(img, np.stack([128 + radius * np.cos(angles), 128 + radius * np.sin(angles)], axis=1))
    return _finish(img)


def _sitting_cat() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 150), (50, 60))
    _ellipse(img, (128, 75), (32, 28))
    _poly(img, [(100, 60), (104, 28), (122, 52)])
    _poly(img, [(156, 60), (152, 28), (134, 52)])
    _limb(img, (170, 195), (215, 150), 12)
    _limb(img, (110, 170), (108, 212), 14)
    _limb(img, (146, 170), (148, 212), 14)
    return _finish(img)


def _crab() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 125), (60, 35))
    for side in (-1, 1):
        for k in range(4):
            _limb(img, (128 + side * 40, 135), (128 + side * (85 + 10 * k), 165 + 12 * k), 7)
        _limb(img, (128 + side * 35, 100), (128 + side * 70, 55), 10)
        _ellipse(img, (128 + side * 75, 48), (18, 12), side * 30)
    return _finish(img)


def _bottle() -> np.ndarray:
    img = _canvas()
    _poly(img, [(100, 100), (156, 100), (160, 230), (96, 230)])
    _poly(img, [(118, 40), (138, 40), (140, 100), (116, 100)])
    _ellipse(img, (128, 100), (28, 14))
    return _finish(img)


def _handstand() -> np.ndarray:
    return _person(legs_apart=18)[::-1].copy()


def _kangaroo() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (130, 120), (32, 50), 20)
    _ellipse(img, (148, 64), (16, 13))
    _limb(img, (115, 160), (90, 215), 24)
    _limb(img, (90, 215), (140, 220), 12)
    _limb(img, (110, 155), (40, 200), 14)
    _limb(img, (145, 100), (170, 120), 8)
    return _finish(img)


def _wide_box() -> np.ndarray:
    img = _canvas()
    _poly(img, [(40, 90), (216, 90), (216, 170), (40, 170)])
    return _finish(img)


def _disc() -> np.ndarray:
    img = _canvas()
    _ellipse(img, (128, 128), (80, 80))
    return _finish(img)


def random_creature(seed: int) -> np.ndarray:
    """A random creature: a body, 0-8 limbs, maybe a head and a tail, any pose.

    Used to check the default preset on shapes nobody drew by hand. Framed like
    every mask jeanscv fits (bounding box centred, longer side 90% of the canvas).
    """
    from jeanscv.subject.framing import frame_mask

    rng = np.random.default_rng(seed)
    img = _canvas()
    angle = rng.uniform(-40, 40)
    axes = (rng.uniform(30, 75), rng.uniform(18, 50))
    centre = (128 + rng.uniform(-15, 15), 120 + rng.uniform(-15, 15))
    _ellipse(img, centre, axes, angle)
    for _ in range(int(rng.integers(0, 9))):
        theta = rng.uniform(0, 2 * np.pi)
        root = (centre[0] + 0.8 * axes[0] * math.cos(theta), centre[1] + 0.8 * axes[1] * math.sin(theta))
        length = rng.uniform(20, 80)
        bend = theta + rng.uniform(-0.8, 0.8)
        tip = (root[0] + length * math.cos(bend), root[1] + length * math.sin(bend))
        _limb(img, root, tip, rng.uniform(5, 18))
    if rng.random() < 0.7:
        theta = rng.uniform(-np.pi, 0)
        head = (centre[0] + 0.95 * axes[0] * math.cos(theta), centre[1] + 0.95 * axes[1] * math.sin(theta))
        _ellipse(img, head, (rng.uniform(10, 22), rng.uniform(10, 20)))
    return frame_mask(_finish(img))[0]


ZOO: dict[str, Callable[[], np.ndarray]] = {
    "person": lambda: _person(),
    "person_legs_apart": lambda: _person(legs_apart=28, arms_up=True),
    "small_person_offset": lambda: _person(scale=0.6, shift=(-30, 10)),
    "handstand": _handstand,
    "dog": lambda: _quadruped(),
    "giraffe": lambda: _quadruped(neck=50, body=(55, 25), leg_length=80),
    "caterpillar": lambda: _quadruped(legs=8, body=(90, 18), leg_length=25),
    "spider": _spider,
    "octopus": _octopus,
    "crab": _crab,
    "blob_a": lambda: _blob(1),
    "blob_b": lambda: _blob(7),
    "table": _table,
    "tree": _tree,
    "bird": _bird,
    "fish": _fish,
    "snake": _snake,
    "star": _star,
    "sitting_cat": _sitting_cat,
    "bottle": _bottle,
    "kangaroo": _kangaroo,
    "wide_box": _wide_box,
    "disc": _disc,
}


def silhouette_zoo(names: list[str] | None = None) -> dict[str, np.ndarray]:
    """The synthetic silhouettes by name: ``{name: (256, 256) float32 alpha}``."""
    return {name: ZOO[name]() for name in (names or list(ZOO))}
