"""CenterNet with a MobileNetV3 backbone (610265158/mobilenetv3_centernet, 512x512 input):
pre- and post-processing around the graph.

Fed as its author's ``preprocess`` does: RGB pixel values 0..255 (the graph normalizes
itself), the photo scaled to fit and centred on black, aspect ratio kept. The graph's own
decoding (``tower_0/detections``) is redone here in numpy from its two heads: a peak of the
class heatmap (``keypoints``, already a sigmoid) that equals its 3x3 max is an object
centre; ``wh`` holds its four distances (left, top, right, bottom) in input pixels.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from ._common import letterbox, per_class_nms
from ._graph import GraphExecutor

SIZE = 512
STRIDE = 4
INPUTS = ["tower_0/images"]
OUTPUTS = ["tower_0/keypoints", "tower_0/wh"]
#: Peaks kept, as the graph's own TopKV2.
TOP_K = 100
#: Neighbouring peaks of one object (one cell apart) give near-identical boxes; NMS within
#: each class keeps the best (the author's demo ran none; this only drops duplicates).
IOU = 0.6


def graph_input(rgb_square: np.ndarray) -> torch.Tensor:
    """A SIZE x SIZE RGB uint8 image -> the graph's input (1, SIZE, SIZE, 3) float32."""
    return torch.from_numpy(rgb_square.astype(np.float32)[None])


def decode(keypoints: torch.Tensor, wh: torch.Tensor, min_score: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heads (1, H, W, 80) and (1, H, W, 4) -> boxes (N, 4, input pixels), scores,
    class ids, best first, NMS within each class only."""
    heat = keypoints[0].permute(2, 0, 1)
    peaks = heat * (heat == F.max_pool2d(heat[None], 3, 1, 1)[0])
    scores, index = torch.topk(peaks.reshape(-1), min(TOP_K, peaks.numel()))
    keep = scores > min_score
    scores, index = scores[keep].numpy(), index[keep].numpy()
    classes, cell = np.divmod(index, heat.shape[1] * heat.shape[2])
    y, x = np.divmod(cell, heat.shape[2])
    dist = wh[0].numpy()[y, x]
    boxes = np.stack(
        [x * STRIDE - dist[:, 0], y * STRIDE - dist[:, 1], x * STRIDE + dist[:, 2], y * STRIDE + dist[:, 3]], 1
    )
    keep = per_class_nms(boxes, scores, classes, IOU)
    return boxes[keep], scores[keep], classes[keep]


def run(executor: GraphExecutor, rgb: np.ndarray, min_score: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detections in ``rgb``'s pixels: boxes (N, 4), scores (N,), class ids (N,)."""
    square, placement = letterbox(rgb, SIZE)
    with torch.inference_mode():
        keypoints, wh = executor(graph_input(square))
        boxes, scores, classes = decode(keypoints, wh, min_score)
    return placement.to_photo(boxes, rgb.shape[1], rgb.shape[0]), scores, classes
