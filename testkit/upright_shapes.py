"""Nine silhouettes of things that stand, sit or lie, for measuring whether jeans hang
upright on them (tests and ``bench/upright.py``; not part of the package).

Each is drawn with the zoo's pens (:mod:`testkit.synthetic`) in a 256x192 picture and
framed like a photo's mask (:func:`jeanscv.subject.framing.frame_mask`), so wide things sit in
the middle of the canvas with empty bands above and below, as in a fitted photo.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from jeanscv.subject.framing import frame_mask
from testkit import synthetic

_SCALE = 0.25  # the shapes are written in pixels of a 1024x768 picture


def _image() -> np.ndarray:
    return synthetic._canvas()


def _ellipse(img: np.ndarray, centre, axes, angle: float = 0.0) -> None:
    synthetic._ellipse(img, np.multiply(centre, _SCALE), np.multiply(axes, _SCALE), angle)


def _limb(img: np.ndarray, a, b, width: float) -> None:
    synthetic._limb(img, np.multiply(a, _SCALE), np.multiply(b, _SCALE), width * _SCALE)


def _poly(img: np.ndarray, points) -> None:
    synthetic._poly(img, np.multiply(points, _SCALE))


def lying_dog() -> np.ndarray:
    """A dog lying on its belly: a long low body, front legs stretched forward, head up."""
    img = _image()
    _ellipse(img, (500, 470), (230, 75))
    _limb(img, (650, 520), (820, 535), 40)  # front legs along the ground
    _limb(img, (360, 515), (300, 535), 50)  # folded hind leg
    _limb(img, (680, 430), (740, 330), 70)  # neck
    _ellipse(img, (770, 310), (70, 45), -10)
    _limb(img, (280, 450), (170, 420), 22)  # tail
    return _finish(img)


def lying_cow() -> np.ndarray:
    """A big animal lying down: a round body, head resting forward, no legs to speak of."""
    img = _image()
    _ellipse(img, (480, 430), (260, 120))
    _ellipse(img, (760, 430), (80, 55), 20)
    _limb(img, (620, 520), (760, 540), 45)
    _limb(img, (250, 400), (200, 520), 20)
    return _finish(img)


def car() -> np.ndarray:
    """A car from the side: a low body, a cabin on top, two wheels below."""
    img = _image()
    _poly(img, [(180, 480), (200, 400), (330, 380), (420, 300), (640, 300), (740, 390), (850, 410), (860, 480)])
    _ellipse(img, (320, 490), (65, 65))
    _ellipse(img, (720, 490), (65, 65))
    return _finish(img)


def bus() -> np.ndarray:
    """A long box on wheels."""
    img = _image()
    _poly(img, [(120, 250), (900, 250), (910, 520), (110, 520)])
    for x in (250, 760):
        _ellipse(img, (x, 530), (55, 55))
    return _finish(img)


def sitting_person() -> np.ndarray:
    """A person sitting on the ground, seen from the side, legs stretched out."""
    img = _image()
    _ellipse(img, (360, 170), (50, 58))
    _poly(img, [(310, 230), (420, 230), (440, 520), (300, 520)])
    _limb(img, (380, 480), (760, 520), 80)
    _limb(img, (400, 280), (520, 420), 40)
    return _finish(img)


def cat_walking() -> np.ndarray:
    """A cat walking: a long body on four short legs, head forward, tail up."""
    img = _image()
    _ellipse(img, (500, 380), (200, 75))
    for x in (350, 410, 600, 650):
        _limb(img, (x, 420), (x + 10, 560), 38)
    _ellipse(img, (720, 310), (65, 55))
    _limb(img, (310, 360), (230, 220), 25)
    return _finish(img)


def seal() -> np.ndarray:
    """A seal on a rock: a teardrop lying on its side, head raised."""
    img = _image()
    _poly(img, [(150, 520), (300, 440), (560, 400), (700, 360), (760, 420), (700, 520)])
    _ellipse(img, (740, 330), (60, 48))
    _limb(img, (180, 510), (120, 470), 40)
    return _finish(img)


def sofa() -> np.ndarray:
    """A sofa: a wide seat, a back and two arms, short feet."""
    img = _image()
    _poly(img, [(200, 280), (820, 280), (820, 420), (200, 420)])
    _poly(img, [(150, 360), (870, 360), (870, 520), (150, 520)])
    for x in (190, 830):
        _limb(img, (x, 520), (x, 560), 30)
    return _finish(img)


def penguin() -> np.ndarray:
    """A standing penguin: tall body, head, short feet, flippers."""
    img = _image()
    _ellipse(img, (512, 430), (120, 220))
    _ellipse(img, (512, 190), (75, 70))
    _limb(img, (400, 380), (360, 520), 35)
    _limb(img, (624, 380), (664, 520), 35)
    _ellipse(img, (470, 660), (50, 20))
    _ellipse(img, (555, 660), (50, 20))
    return _finish(img)


def _finish(img: np.ndarray) -> np.ndarray:
    canvas, _ = frame_mask(synthetic._finish(img))
    return canvas


UPRIGHT_SHAPES: dict[str, Callable[[], np.ndarray]] = {
    "lying_dog": lying_dog,
    "lying_cow": lying_cow,
    "car": car,
    "bus": bus,
    "sitting_person": sitting_person,
    "cat_walking": cat_walking,
    "seal": seal,
    "sofa": sofa,
    "penguin": penguin,
}


def upright_shapes() -> dict[str, np.ndarray]:
    """``{name: (256, 256) float32 alpha}`` of the nine shapes."""
    return {name: draw() for name, draw in UPRIGHT_SHAPES.items()}
