"""Framing: from an object mask at image resolution to the 256x256 silhouette ``S``.

The paper's canvas is the silhouette's own frame: its ``L_center`` pulls the
waistband to the canvas centre. Its seven silhouettes are framed by their bounding
box: the box centre sits within a few pixels of the canvas centre (their centroids
stray up to 20 px) and the longer side spans about 90% of the canvas. jeanscv frames
any mask the same way: a square around the bounding box, centred on it, whose side
is the box's longer side divided by ``fill`` (0.9), scaled to 256x256.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import JeansError
from ..geometry import CANVAS_SIZE, apply_affine, invert_affine, mask_box

#: Fraction of the canvas side that the object's longer side spans.
DEFAULT_FILL = 0.9


@dataclass(frozen=True)
class Framing:
    """The square of the image that became the canvas.

    ``canvas_to_image`` maps canvas pixels to image pixels (2x3, a scale and a
    shift): canvas edge 0 is image ``origin`` and canvas edge 256 is
    ``origin + side``.
    """

    origin: tuple[float, float]  # image (x, y) of the canvas's top-left corner
    side: float  # image pixels spanned by the canvas side
    image_size: tuple[int, int]  # (width, height)

    @property
    def canvas_to_image(self) -> np.ndarray:
        scale = self.side / CANVAS_SIZE
        return np.array([[scale, 0.0, self.origin[0]], [0.0, scale, self.origin[1]]])

    @property
    def image_to_canvas(self) -> np.ndarray:
        return invert_affine(self.canvas_to_image)

    def to_image(self, canvas_points: np.ndarray) -> np.ndarray:
        """Canvas pixels ``(..., 2)`` to image pixels."""
        return apply_affine(self.canvas_to_image, canvas_points)

    def to_canvas(self, image_points: np.ndarray) -> np.ndarray:
        """Image pixels ``(..., 2)`` to canvas pixels."""
        return apply_affine(self.image_to_canvas, image_points)


def identity_framing(width: int = CANVAS_SIZE, height: int = CANVAS_SIZE) -> Framing:
    """The 1:1 framing of an image that already is the 256x256 canvas."""
    return Framing((0.0, 0.0), float(CANVAS_SIZE), (width, height))


def frame_mask(mask: np.ndarray, fill: float = DEFAULT_FILL) -> tuple[np.ndarray, Framing]:
    """Crop a square around the object in ``mask`` and scale it to the canvas.

    Args:
        mask: ``(H, W)`` bool or float alpha in [0, 1] at image resolution.
        fill: fraction of the canvas side that the object's longer side spans.

    Returns:
        ``(S, framing)``: ``S`` is ``(256, 256)`` float32 in [0, 1].
    """
    alpha = np.asarray(mask)
    if alpha.ndim != 2:
        raise JeansError(f"mask must be 2-D, got shape {alpha.shape}")
    x0, y0, box_width, box_height = mask_box(alpha)
    x1, y1 = x0 + box_width, y0 + box_height
    # An integer side and origin keep the crop on the pixel grid, so the resize is
    # a pure area average and canvas_to_image is exact.
    side = int(np.ceil(max(x1 - x0, y1 - y0) / fill))
    left = int(np.floor((x0 + x1 - side) / 2))
    top = int(np.floor((y0 + y1 - side) / 2))
    height, width = alpha.shape
    crop = np.zeros((side, side), np.float32)
    src_x0, src_y0 = max(left, 0), max(top, 0)
    src_x1, src_y1 = min(left + side, width), min(top + side, height)
    crop[src_y0 - top : src_y1 - top, src_x0 - left : src_x1 - left] = alpha[src_y0:src_y1, src_x0:src_x1]
    interpolation = cv2.INTER_AREA if side >= CANVAS_SIZE else cv2.INTER_LINEAR
    silhouette = cv2.resize(crop, (CANVAS_SIZE, CANVAS_SIZE), interpolation=interpolation)
    return np.clip(silhouette, 0.0, 1.0), Framing((float(left), float(top)), float(side), (width, height))
