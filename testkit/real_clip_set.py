"""The real animal clips with a reference mask on every frame in ``../shared/clips`` (see
its README: DAVIS 2016 sequences as ``NNNNN.jpg`` frames with ``NNNNN.mask.png``):
finding them, reading them one frame at a time, and scoring a clip run against them, for
the tests and ``bench.clips --real``."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .real_photo_set import polygon_mask
from .synthetic_clips import iou

CLIPS = Path(__file__).resolve().parents[2] / "shared" / "clips"
#: The issue's bar: jeans with at least this share of their pixels on the animal.
ON_SUBJECT = 0.85


def clip_folders(root: Path = CLIPS) -> list[Path]:
    """The clip folders under ``root`` that hold masked frames, sorted (empty when absent)."""
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.is_dir() and frame_paths(p))


def frame_paths(folder: Path) -> list[Path]:
    """The frames of a clip folder that have a ``STEM.mask.png`` beside them, in order."""
    return sorted(
        p for p in folder.glob("*.jpg") if not p.name.endswith(".mask.png") and p.with_suffix(".mask.png").is_file()
    )


def read_frame(path: Path) -> np.ndarray:
    """A frame as ``(H, W, 3)`` uint8 RGB."""
    return cv2.cvtColor(cv2.imread(str(path), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def read_frames(paths: list[Path]) -> Iterator[np.ndarray]:
    """The frames, read one at a time as they are asked for (memory does not grow)."""
    for path in paths:
        yield read_frame(path)


def reference(path: Path) -> np.ndarray:
    """The reference mask of the frame ``path``, ``(H, W)`` bool."""
    return cv2.imread(str(path.with_suffix(".mask.png")), cv2.IMREAD_GRAYSCALE) >= 128


@dataclass
class ClipScore:
    """A clip run scored frame by frame against its reference masks (the first followed
    object): the mask's IoU, the share of the jeans' pixels on the animal (0 on a frame
    without jeans), the jeans' vertices (image pixels, None without jeans), and the share
    of the jeans' pixels on the followed mask itself (did the jeans leave the mask, or the
    mask the animal)."""

    ious: list[float] = field(default_factory=list)
    on_subject: list[float] = field(default_factory=list)
    vertices: list[np.ndarray | None] = field(default_factory=list)
    in_mask: list[float] = field(default_factory=list)
    centres: list[np.ndarray | None] = field(default_factory=list)

    def add(self, result, truth: np.ndarray) -> np.ndarray:
        """Score one :class:`~jeanscv.run.clips.ClipFrameResult`; returns its followed mask."""
        ys, xs = np.nonzero(truth)
        self.centres.append(np.array([[xs.mean(), ys.mean()]]) if xs.size else None)
        obj = result.objects[0] if result.objects else None
        if obj is None:
            self.ious.append(iou(np.zeros_like(truth), truth))
            self.on_subject.append(0.0)
            self.vertices.append(None)
            self.in_mask.append(0.0)
            return np.zeros_like(truth)
        mask = np.asarray(obj.silhouette.mask) >= 0.5
        vertices = obj.silhouette.framing.to_image(obj.fit.vertices)
        jeans = polygon_mask(vertices, truth.shape)
        self.ious.append(iou(mask, truth))
        self.on_subject.append(float((jeans & truth).sum() / max(jeans.sum(), 1)))
        self.vertices.append(vertices)
        self.in_mask.append(float((jeans & mask).sum() / max(jeans.sum(), 1)))
        return mask

    def jitter(self) -> float:
        """The jeans' shake (px): the RMS over frames of their vertices' mean second
        difference (``v[t+1] - 2 v[t] + v[t-1]``), which a steady motion leaves at 0 and a
        jump of the jeans (a re-anchoring) counts in."""
        return shake(self.vertices)

    def centre_jitter(self) -> float:
        """The jeans' shake as a whole (px): :func:`shake` of their vertices' mean, to hold
        against the animal's own (:meth:`own_motion`)."""
        return shake([None if v is None else v.mean(axis=0, keepdims=True) for v in self.vertices])

    def own_motion(self) -> float:
        """The animal's own shake (px), to hold the jeans' against: :func:`shake` of the
        reference mask's centroid (a walking camel's is about 1.4 px, its box corners'
        2.5)."""
        return shake(self.centres)

    def summary(self) -> dict:
        """``frames``, ``iou_mean``, ``iou_min``, ``on_animal`` (share of frames with the
        jeans >= :data:`ON_SUBJECT` on the animal), ``without`` (frames without jeans),
        ``jitter``, the jeans' shake as a whole (``centre_jitter``) and the animal's
        ``own``."""
        return {
            "frames": len(self.ious),
            "iou_mean": float(np.mean(self.ious)),
            "iou_min": float(np.min(self.ious)),
            "on_animal": float(np.mean([s >= ON_SUBJECT for s in self.on_subject])),
            "without": sum(v is None for v in self.vertices),
            "jitter": self.jitter(),
            "centre_jitter": self.centre_jitter(),
            "own": self.own_motion(),
        }


def shake(points: list[np.ndarray | None]) -> float:
    """The RMS over frames of the mean second difference (``p[t+1] - 2 p[t] + p[t-1]``,
    px) of ``points`` (per frame ``(N, 2)`` image pixels, None where missing): 0 for a
    steady motion, a jump counts."""
    shakes = [
        float(np.linalg.norm(c - 2 * b + a, axis=1).mean())
        for a, b, c in zip(points, points[1:], points[2:])
        if a is not None and b is not None and c is not None
    ]
    return float(np.sqrt(np.mean(np.square(shakes)))) if shakes else float("nan")
