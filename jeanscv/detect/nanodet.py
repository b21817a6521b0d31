"""NanoDet (RangiLyu/nanodet, the GFL-head version with ``reg_max`` 10, 416x416 input):
pre- and post-processing around the graph.

Fed as upstream feeds it: BGR, ``(x - mean) / std`` per channel, NCHW. The graph's class
outputs already went through a sigmoid (its last ops), so they are scores; each box side
is a distribution over ``reg_max + 1`` distance bins, read as its expectation (softmax,
then the mean bin) times the level's stride, from the cell centre.
"""

from __future__ import annotations

import numpy as np
import torch

from ._common import letterbox, per_class_nms
from ._graph import GraphExecutor

SIZE = 416
STRIDES = (8, 16, 32)
REG_MAX = 10
#: BGR, as upstream's config (``data.*.pipeline.normalize``).
MEAN = np.array([103.53, 116.28, 123.675], np.float32)
STD = np.array([57.375, 57.12, 58.395], np.float32)
INPUTS = ["input_1"]
#: Class scores per level (strides 8, 16, 32), then the box distributions.
OUTPUTS = ["Identity", "Identity_1", "Identity_2", "Identity_3", "Identity_4", "Identity_5"]
#: Candidates per level before NMS, and the NMS overlap, as upstream's test config.
PRE_NMS = 1000
IOU = 0.6


def graph_input(rgb_square: np.ndarray) -> torch.Tensor:
    """A SIZE x SIZE RGB uint8 image -> the graph's input (1, 3, SIZE, SIZE) float32."""
    bgr = rgb_square[:, :, ::-1].astype(np.float32)
    return torch.from_numpy(((bgr - MEAN) / STD).transpose(2, 0, 1)[None].copy())


def decode(outputs: list[np.ndarray], min_score: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The graph's outputs -> boxes (N, 4, input pixels), scores (N,), class ids (N,),
    per-class NMS done, best first."""
    all_boxes, all_scores, all_classes = [], [], []
    bins = np.arange(REG_MAX + 1, dtype=np.float32)
    for level, stride in enumerate(STRIDES):
        scores, reg = outputs[level][0], outputs[level + 3][0]
        side = SIZE // stride
        cells, classes = np.nonzero(scores > min_score)
        if cells.size > PRE_NMS:
            top = np.argpartition(-scores[cells, classes], PRE_NMS)[:PRE_NMS]
            cells, classes = cells[top], classes[top]
        if not cells.size:
            continue
        logits = reg[cells].reshape(-1, 4, REG_MAX + 1)
        prob = np.exp(logits - logits.max(axis=2, keepdims=True))
        distance = (prob / prob.sum(axis=2, keepdims=True)) @ bins * stride  # left, top, right, bottom
        cx = (cells % side + 0.5) * stride
        cy = (cells // side + 0.5) * stride
        all_boxes.append(
            np.stack([cx - distance[:, 0], cy - distance[:, 1], cx + distance[:, 2], cy + distance[:, 3]], 1)
        )
        all_scores.append(scores[cells, classes])
        all_classes.append(classes)
    if not all_boxes:
        return np.zeros((0, 4)), np.zeros(0), np.zeros(0, np.int64)
    boxes, scores, classes = np.concatenate(all_boxes), np.concatenate(all_scores), np.concatenate(all_classes)
    keep = per_class_nms(boxes, scores, classes, IOU)
    return boxes[keep], scores[keep], classes[keep]


def run(executor: GraphExecutor, rgb: np.ndarray, min_score: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Detections in ``rgb``'s pixels: boxes (N, 4), scores (N,), class ids (N,)."""
    square, placement = letterbox(rgb, SIZE)
    with torch.inference_mode():
        outputs = [t.numpy() for t in executor(graph_input(square))]
    boxes, scores, classes = decode(outputs, min_score)
    return placement.to_photo(boxes, rgb.shape[1], rgb.shape[0]), scores, classes
