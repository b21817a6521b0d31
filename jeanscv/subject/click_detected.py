"""Which detected animal a click means: a first positive click inside a detected
animal's box starts from that box, as a person's box would (box + click), where the
box's cut holds the click; elsewhere a click works as without the detector. Later
clicks correct that mask as they correct any.

Boxes are ``(x0, y0, x1, y1)`` whole photo pixels (x right, y down), end exclusive;
points ``(x, y)`` photo pixels.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .click_masks import box_pixels

if TYPE_CHECKING:
    from ..detect import Detection

#: Detections scoring under this start no click.
CLICK_SCORE = 0.3
#: Only animals' boxes start clicks. A person's or a thing's box is often one of a group
#: the person means as a whole (one hockey player of a crowd, one wing of an aeroplane
#: the detector split in three). The first simulated click's mean IoU (bench.clicks'
#: protocol, one run): animals' boxes only, shared real photos 0.690 -> 0.701 and pets
#: 0.622 -> 0.718 (one click usable 25 -> 29 of 34); every class's, 0.655 and 0.718;
#: animals' and people's scoring >= 0.5, 0.682 and 0.718; any class scoring >= 0.5,
#: 0.684 and 0.659.

Box = tuple[int, int, int, int]


@dataclass(frozen=True)
class DetectedBox:
    """One detected object as a click session uses it: its box in whole photo pixels,
    its COCO class and score."""

    box: Box
    label: str
    score: float

    def holds(self, point: tuple[float, float]) -> bool:
        """Whether the photo point ``(x, y)`` lies in the box."""
        x0, y0, x1, y1 = self.box
        return x0 <= point[0] < x1 and y0 <= point[1] < y1

    def to_json(self) -> dict:
        """As the report gives a detection: class, score, box."""
        return {"class": self.label, "score": round(self.score, 3), "box": [float(v) for v in self.box]}


def detected_boxes(
    rgb: np.ndarray, detector: str, detections: Sequence[Detection] | None = None
) -> tuple[tuple[DetectedBox, ...], str | None]:
    """The detections of ``rgb`` (``(H, W, 3)`` uint8) a click may start from, smallest
    box first (a click on a cat in a person's lap means the cat), and a warning line
    where the detector cannot be used. ``detector``: ``auto`` (the shipped model) or
    ``none`` (no boxes); ``detections``: the photo's, where the caller has them already."""
    from .detected import animals, find, one_per_object

    found, problem = (list(detections), None) if detections is not None else find(rgb, detector)
    height, width = rgb.shape[:2]
    boxes = [
        DetectedBox(box_pixels(d.box, (width, height)), d.label, d.score)
        for d in animals(found)
        if d.score >= CLICK_SCORE
    ]
    # One animal's boxes under several classes: the likeliest stands for it.
    kept = one_per_object(sorted(boxes, key=lambda d: -d.score))
    kept.sort(key=lambda d: (d.box[2] - d.box[0]) * (d.box[3] - d.box[1]))
    return tuple(kept), problem


def meant_box(
    boxes: Sequence[DetectedBox], point: tuple[float, float], holds_click: Callable[[Box], bool]
) -> DetectedBox | None:
    """The detected object a first positive click at ``point`` means, or None: the
    smallest box holding it whose own cut (``holds_click(box)``: the object a box alone
    finds there holds the click) holds it too; a click on the sofa inside a cat's box
    means the sofa's box, or no box."""
    for detected in boxes:
        if detected.holds(point) and holds_click(detected.box):
            return detected
    return None
