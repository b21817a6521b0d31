"""What both detectors share: COCO's class names, letterboxing and per-class NMS."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

_NAMES = (
    "person bicycle car motorcycle airplane bus train truck boat traffic_light fire_hydrant stop_sign "
    "parking_meter bench bird cat dog horse sheep cow elephant bear zebra giraffe backpack umbrella handbag "
    "tie suitcase frisbee skis snowboard sports_ball kite baseball_bat baseball_glove skateboard surfboard "
    "tennis_racket bottle wine_glass cup fork knife spoon bowl banana apple sandwich orange broccoli carrot "
    "hot_dog pizza donut cake chair couch potted_plant bed dining_table toilet tv laptop mouse remote "
    "keyboard cell_phone microwave oven toaster sink refrigerator book clock vase scissors teddy_bear "
    "hair_drier toothbrush"
)
#: The 80 COCO class names, in the models' class order (underscores read as spaces).
COCO_LABELS: tuple[str, ...] = tuple(name.replace("_", " ") for name in _NAMES.split())


@dataclass(frozen=True)
class Letterbox:
    """How a photo was placed in the square model input: input = photo * scale + offset."""

    scale: float
    dx: int
    dy: int

    def to_photo(self, boxes: np.ndarray, width: int, height: int) -> np.ndarray:
        """Boxes (N, 4: x0, y0, x1, y1) in input pixels -> the photo's pixels, clipped to it."""
        out = np.empty_like(boxes, dtype=np.float64)
        out[:, 0::2] = (boxes[:, 0::2] - self.dx) / self.scale
        out[:, 1::2] = (boxes[:, 1::2] - self.dy) / self.scale
        out[:, 0::2] = out[:, 0::2].clip(0, width)
        out[:, 1::2] = out[:, 1::2].clip(0, height)
        return out


def letterbox(image: np.ndarray, size: int) -> tuple[np.ndarray, Letterbox]:
    """``image`` (H, W, 3 uint8) scaled to fit ``size`` x ``size`` keeping its aspect ratio,
    centred on black (as both models' authors do).

    Shrinking uses area averaging rather than the authors' bilinear ``cv2.resize``: a
    12-MP photo shrunk 10x bilinearly aliases, which a model trained on ~640-px COCO
    photos never saw.
    """
    height, width = image.shape[:2]
    scale = size / max(height, width)
    new_w = min(size, max(1, round(width * scale)))
    new_h = min(size, max(1, round(height * scale)))
    interpolation = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
    resized = cv2.resize(np.ascontiguousarray(image), (new_w, new_h), interpolation=interpolation)
    canvas = np.zeros((size, size, 3), np.uint8)
    dx, dy = (size - new_w) // 2, (size - new_h) // 2
    canvas[dy : dy + new_h, dx : dx + new_w] = resized.reshape(new_h, new_w, 3)
    # the scale actually applied on each axis differs by rounding; the mean is close enough
    return canvas, Letterbox((new_w / width + new_h / height) / 2, dx, dy)


def nms(boxes: np.ndarray, scores: np.ndarray, iou: float) -> np.ndarray:
    """Greedy non-maximum suppression: indices kept, best score first."""
    order = np.argsort(-scores, kind="stable")
    area = (boxes[:, 2] - boxes[:, 0]).clip(0) * (boxes[:, 3] - boxes[:, 1]).clip(0)
    keep = []
    while order.size:
        best, rest = order[0], order[1:]
        keep.append(best)
        w = (np.minimum(boxes[best, 2], boxes[rest, 2]) - np.maximum(boxes[best, 0], boxes[rest, 0])).clip(0)
        h = (np.minimum(boxes[best, 3], boxes[rest, 3]) - np.maximum(boxes[best, 1], boxes[rest, 1])).clip(0)
        inter = w * h
        overlap = inter / np.maximum(area[best] + area[rest] - inter, 1e-9)
        order = rest[overlap <= iou]
    return np.array(keep, dtype=np.int64)


def per_class_nms(boxes: np.ndarray, scores: np.ndarray, classes: np.ndarray, iou: float) -> np.ndarray:
    """NMS within each class only (a person's box never suppresses a dog's): indices kept,
    best score first."""
    keep = [
        np.flatnonzero(classes == c)[nms(boxes[classes == c], scores[classes == c], iou)] for c in np.unique(classes)
    ]
    kept = np.concatenate(keep) if keep else np.zeros(0, np.int64)
    return kept[np.argsort(-scores[kept], kind="stable")]
