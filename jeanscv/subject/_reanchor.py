"""Keep a clip's followed objects on the detected animal (issue 48).

:class:`~.follow.Follower` carries each mask by the object's motion and re-decides its
edge by colour; on real footage the mask loses the legs that swing out of it and walks
onto ground, fences and rocks of the animal's colour (``python -m bench.clips --real``:
mean IoU 0.27 on the shared camel clip, 0.51 on the cows, started from a classical
segmentation; 0.49 and 0.63 started from the detector's cut). Here the shipped detector
(:mod:`jeanscv.detect`), run every :data:`REDETECT_EVERY` frames and at once when the
mask's box leaves where it should be, holds each object to the box of the same object:

- each object keeps the box of its last detection, carried by its motion since: the
  prediction a new detection is matched to by box overlap (any animal class counts: the
  class name flickers from frame to frame, a camel is a horse, a cow now and then a horse,
  while the box stays on the animal);
- every frame, what the mask holds outside that box (grown by :data:`BOX_MARGIN`) goes,
  and the edge band may take what is clearly of the object's colours
  (:data:`HELD_PRIOR`): the box bounds what it can take;
- where the mask's box lay in the detection's box when it was cut is remembered (a cut
  that leaves out a cow's white head keeps leaving it out, and that is no drift); on a
  detection, a mask whose box no longer lies there (IoU under :data:`DRIFTED`) or whose
  area is far from what the cut filled (:data:`SHRUNK`, :data:`GROWN`) is cut again inside
  the detected box, as a still photo's detected subject is (:func:`.boxed.segment_box`
  with ``drop_support``), and followed from that cut, its colour model learnt afresh;
  unless the cut fits the box worse than the mask does (:data:`TIE`): then the mask is
  kept and becomes the reference.

Objects found by the detector are held from the start; an object given by clicks, a box
or a mask only if its mask's box matches a detection on its first frame at
:data:`GIVEN_MATCH` (a mask of the head alone is not made the whole animal); one found
classically, from the first detection that matches it (and cut there). The constants'
figures are ``python -m bench.clips --real`` on the shared camel and cows clips (mean
IoU, and the share of frames with the jeans >= 85% on the animal), one change at a time
from the values here (0.749 and 0.827; 9% and 87%).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..detect import Detection
from ..errors import JeansError
from .detected import box_iou, wanted
from .follow import PRIOR_WEIGHT

#: Frames between two detections (0.02 to 0.1 s each on the project's two cores): 3 gave
#: 0.728 and 0.824 (with 30 and 34 detections against 18 and 22), 10 gave 0.736 and 0.828
#: but the cows' jeans on the animal in 81% of frames, 15 gave 0.731, 0.827 and 73%.
REDETECT_EVERY = 5
#: A detection is the followed object when its box overlaps the object's carried box (or
#: its mask's box) at least this much (the detected animal overlaps its carried box 0.68 to
#: 0.98 on the shared clips; the other camel passing behind, 0.0 to 0.16).
MATCH = 0.3
#: An object given by clicks, a box or a mask is held to detections only when its first
#: mask's box overlaps a detection this much: the whole animal was given.
GIVEN_MATCH = 0.6
#: Below this IoU of the mask's box with where it should lie in the detected box, the mask
#: has drifted (or lost the legs): it is cut again. 0.7: camel 0.649; 0.9: camel 0.765,
#: cows 0.819, with 11 and 7 cuts again instead of 4 and 1 (each 0.2 to 0.3 s).
DRIFTED = 0.8
#: ... or below this share of the area the last cut filled (the box scaled to this one's):
#: it has shrunk; ...
SHRUNK = 0.8
#: ... or above this share: it has grown onto what lies round the animal inside its box.
#: On the shared clips the box's fit decides first (0.6 and 1.25 gave the same figures).
GROWN = 1.2
#: A fresh cut replaces a drifted mask unless its box fits the detection's worse than the
#: mask's own by more than this: on bench.clips' still clip the cut dropped the dog's legs
#: as its support, the band took them back, and the two took turns (IoU 0.87, kept: 0.95).
TIE = 0.02
#: The mask is kept within its box grown by this share of the box's size on each side
#: (the box is carried by the body's motion between detections: the legs swing round it).
#: 0.02 and 0.1 gave the same figures within 0.015.
BOX_MARGIN = 0.06
#: The follower's prior weight in the edge band (:data:`.follow.PRIOR_WEIGHT`) for an
#: object held in a box: below 0.5 a pixel outside the moved mask whose colour is clearly
#: the object's joins it, so a leg that swung out comes back. 0.5: 0.700 and 0.722 (the
#: cows' jeans on the animal in 6% of frames); 0.35: 0.736 and 0.808; 0.15: 0.717, 0.834.
HELD_PRIOR = 0.25
#: Detections in a row that miss the object before its box is no longer trusted (it is
#: matched again from its mask's box alone).
MISSES = 3

Box = tuple[float, float, float, float]


@dataclass
class Held:
    """One followed object's hold on the detections: its box (``(x0, y0, x1, y1)`` image
    pixels, carried by the object's motion since its last detection; None while not held),
    whether it may be held from a later detection, the kind of detection that matches it
    (``person`` or the subject asked for), and, from its last cut (or its first frame),
    where the mask's own box lay in the detection's (its edges as shares of the box, ``x0,
    y0, x1, y1``: a cut that leaves out a white head keeps leaving it out, and that is no
    drift) and the share of the box it filled."""

    box: Box | None
    free: bool
    kind: str
    within: Box | None = None  # None: never held yet
    fill: float = 1.0
    misses: int = 0  # detections in a row that missed it

    def settle(self, mask: np.ndarray, box: Box) -> None:
        """Learn where ``mask`` (just cut, or as given) lies in the detection ``box``."""
        self.box = box
        own = mask_box(mask)
        if own is None:
            return
        x0, y0, x1, y1 = box
        width, height = max(x1 - x0, 1.0), max(y1 - y0, 1.0)
        self.within = ((own[0] - x0) / width, (own[1] - y0) / height, (own[2] - x0) / width, (own[3] - y0) / height)
        self.fill = float(np.count_nonzero(mask)) / max(_area(box), 1.0)

    def expected(self) -> Box | None:
        """Where the mask's box should lie in the object's box now (None while not held)."""
        if self.box is None or self.within is None:
            return None
        x0, y0, x1, y1 = self.box
        a, b, c, d = self.within
        return x0 + a * (x1 - x0), y0 + b * (y1 - y0), x0 + c * (x1 - x0), y0 + d * (y1 - y0)


def mask_box(mask: np.ndarray) -> Box | None:
    """``(x0, y0, x1, y1)`` of a bool mask (end exclusive), None when empty."""
    rows, cols = np.any(mask, axis=1), np.any(mask, axis=0)
    if not rows.any():
        return None
    y0, y1 = np.flatnonzero(rows)[[0, -1]]
    x0, x1 = np.flatnonzero(cols)[[0, -1]]
    return float(x0), float(y0), float(x1 + 1), float(y1 + 1)


def carried_box(box: Box, motion: np.ndarray) -> Box:
    """The axis-aligned box around ``box``'s corners moved by ``motion`` (2x3)."""
    x0, y0, x1, y1 = box
    corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]], np.float64)
    moved = corners @ np.asarray(motion)[:, :2].T + np.asarray(motion)[:, 2]
    return (*moved.min(axis=0).tolist(), *moved.max(axis=0).tolist())  # type: ignore[return-value]


def grown(box: Box, share: float, shape: tuple[int, int]) -> Box:
    """``box`` grown by ``share`` of its size on each side, within the ``(H, W)`` image."""
    x0, y0, x1, y1 = box
    dx, dy = share * (x1 - x0), share * (y1 - y0)
    return max(x0 - dx, 0.0), max(y0 - dy, 0.0), min(x1 + dx, float(shape[1])), min(y1 + dy, float(shape[0]))


def _area(box: Box) -> float:
    return max(box[2] - box[0], 0.0) * max(box[3] - box[1], 0.0)


def shipped_cut(pixels: np.ndarray, box: Box) -> np.ndarray | None:
    """The still photo's cut of a detected subject inside ``box`` (what it stands on
    dropped), None where it holds no object."""
    from .detected import detected_segmentations
    from .interactive import WORKING_SIZE

    found = detected_segmentations(pixels, [Detection("animal", -1, 1.0, box)], WORKING_SIZE)[0]
    return None if found is None else np.asarray(found.mask, bool)


class Reanchor:
    """Holds a :class:`~.follow.Follower`'s objects to the detector's boxes.

    ``detect(pixels) -> list[Detection]``: the detector (the shipped one, or a stand-in);
    ``subject``: what the clip's automatic finding looks for (as :func:`.detected.wanted`);
    ``cut(pixels, box) -> mask | None``: the cut inside a box (:func:`shipped_cut`).
    """

    def __init__(
        self,
        detect: Callable[[np.ndarray], list[Detection]],
        subject: str = "auto",
        every: int | None = None,
        cut: Callable[[np.ndarray, Box], np.ndarray | None] = shipped_cut,
    ) -> None:
        self.detect = detect
        self.subject = subject
        self.every = every or REDETECT_EVERY
        self.cut = cut
        self.held: list[Held] = []
        self.since = 0  # frames since the last detection
        self.recuts = 0  # how many cuts were made again (for the benches)
        self.detections = 0  # how many frames were detected on

    def _detections(self, pixels: np.ndarray, kind: str) -> list[Detection]:
        try:
            found = self.detect(pixels)
        except JeansError:  # the model cannot be used: the objects are followed without it
            self.detect = lambda _pixels: []
            found = []
        return wanted(found, kind, pixels.shape[:2])

    def start(
        self, pixels: np.ndarray, masks: list[np.ndarray], details: list[dict], given: bool, follower=None
    ) -> None:
        """Begin holding objects found on ``pixels``: their ``masks`` and silhouette
        ``details`` (a detector's subject names its ``detection``); ``given``: the objects
        were given by clicks, a box or a mask; ``follower``: the
        :class:`~.follow.Follower` just started on them."""
        self.held, self.since = [], 0
        found: list[Detection] | None = None
        for mask, info in zip(masks, details):
            mask = np.asarray(mask) >= 0.5
            detection = info.get("detection")
            kind = "person" if detection and detection.get("class") == "person" else self.subject
            held = Held(None, not given, kind)
            own = mask_box(mask)
            if detection is not None:
                held.free = True
                held.settle(mask, tuple(float(v) for v in detection["box"]))  # type: ignore[arg-type]
            elif given and own is not None:
                found = self._detections(pixels, kind) if found is None else found
                best = max(found, key=lambda d: box_iou(d.box, own), default=None)
                if best is not None and box_iou(best.box, own) >= GIVEN_MATCH:
                    held.free = True
                    held.settle(mask, best.box)
            self.held.append(held)
        if follower is not None:
            self._trust(follower)

    def _trust(self, follower) -> None:
        """Held in a box, the edge band may take what has the object's colours (a leg that
        swung out): the box bounds what it can take."""
        for obj, held in zip(follower.objects, self.held):
            obj.prior = HELD_PRIOR if held.box is not None else PRIOR_WEIGHT

    def holding(self) -> list[bool]:
        """Per object, whether it is held: the last detection matched it, and its box has
        been carried by its motion since."""
        return [held.box is not None and held.misses == 0 for held in self.held]

    def step(
        self, pixels: np.ndarray, follower, masks: list[np.ndarray | None], motions: list[np.ndarray | None]
    ) -> tuple[list[np.ndarray | None], list[bool]]:
        """This frame's masks (as :meth:`.follow.Follower.step` gave them) held to the
        detections, and per object whether it was cut afresh (its jeans re-anchor).
        ``follower`` is updated to match."""
        self.since += 1
        masks = list(masks)
        recut = [False] * len(masks)
        off = False
        for held, mask, motion in zip(self.held, masks, motions):
            if held.box is not None and motion is not None:
                held.box = carried_box(held.box, motion)
            own = None if mask is None else mask_box(mask)
            expected = held.expected()
            if expected is not None and own is not None and box_iou(own, expected) < DRIFTED:
                off = True  # a large change: look now
        if self.since >= self.every or off:
            self.since = 0
            self.detections += 1
            self._redetect(pixels, follower, masks, recut)
        self._trust(follower)
        for index, (held, mask) in enumerate(zip(self.held, masks)):
            if held.box is not None and mask is not None and not recut[index]:
                limit = grown(held.box, BOX_MARGIN, mask.shape)
                if (mask & ~_box_mask(limit, mask.shape)).any():
                    masks[index] = follower.keep_within(index, limit)
        return masks, recut

    def _redetect(self, pixels: np.ndarray, follower, masks: list[np.ndarray | None], recut: list[bool]) -> None:
        """Match each object to this frame's detections; cut again those that drifted."""
        by_kind: dict[str, list[Detection]] = {}
        taken: set[int] = set()
        for index, (held, mask) in enumerate(zip(self.held, masks)):
            own = None if mask is None else mask_box(mask)
            if own is None or not (held.box is not None or held.free):
                continue
            if held.kind not in by_kind:
                by_kind[held.kind] = self._detections(pixels, held.kind)
            boxes = [own] if held.box is None else [own, held.box]
            candidates = [
                (max(box_iou(d.box, b) for b in boxes), k, d)
                for k, d in enumerate(by_kind[held.kind])
                if k not in taken
            ]
            score, k, best = max(candidates, key=lambda c: c[0], default=(0.0, -1, None))
            if best is None or score < MATCH:
                held.misses += 1
                if held.misses >= MISSES:
                    held.box = None
                continue
            taken.add(k)
            held.misses = 0
            held.box = best.box
            expected = held.expected()  # None the first time: whatever it was, it is cut in the box
            filled = float(np.count_nonzero(mask)) / max(held.fill * _area(best.box), 1.0)
            if expected is not None and box_iou(own, expected) >= DRIFTED and SHRUNK <= filled <= GROWN:
                continue
            fresh = self.cut(pixels, best.box)
            cut = None if fresh is None else mask_box(fresh)
            if cut is None or box_iou(cut, best.box) < box_iou(own, best.box) - TIE:
                # The followed mask fits the detector's box better than a fresh cut (the
                # cut drops a dog's legs as its support, the band took them back): it
                # is kept, and becomes the reference its later drift is measured from.
                held.settle(mask, best.box)
                continue
            self.recuts += 1
            masks[index] = follower.reseed(index, pixels, fresh)
            held.settle(masks[index], best.box)
            recut[index] = True


def _box_mask(box: Box, shape: tuple[int, int]) -> np.ndarray:
    """``(H, W)`` bool: the pixels whose centres lie inside ``box``."""
    x0, y0, x1, y1 = (max(int(np.ceil(v - 0.5)), 0) for v in box)
    inside = np.zeros(shape, bool)
    inside[y0:y1, x0:x1] = True
    return inside
