"""What kind of thing a candidate subject is (a person, an animal, another object), and
which candidate a ``subject`` choice (``auto``, ``animal``, ``person``, ``object``) takes.

Public API (for :mod:`jeanscv.subject.photo`): :class:`KindCues` (one scene's cues,
each computed on first use) and :func:`choose_kind` (the pieces of auto's candidates,
judged, and the ones a subject choice keeps).

People point jeanscv at their pets, and pets live beside their owners, on sofas and in
cluttered rooms. auto's consensus (:mod:`jeanscv.subject.consensus`) finds the most
salient thing; this module then asks what it is, with classical cues that need no
download:

- **People**: OpenCV's built-in HOG people detector (Dalal and Triggs; its SVM is
  compiled into the library) on the scene's coarse copy, and, for figures it misses, a
  standing figure's shape: upright (at least 1.8 times as tall as wide) and plain (no
  fur, see below).
- **Fur**: an animal's coat is finely textured, the sofa, wall or floor around it
  mostly is not. ``fur`` is the mean fine detail (|Laplacian| of the working copy's grey
  levels) inside a piece over the mean in a band around it.

A candidate mask is split into its separate pieces (connected components of at least a
tenth of the largest), and every piece of every candidate is judged. The pieces keep
their candidate's consensus score, so a choice never takes a piece that auto's
hypotheses do not support.

Masks are the scene's coarse ``(h, w) bool`` (long side <= 320).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache, cached_property

import cv2
import numpy as np

from .masks import MIN_AREA_FRACTION, disk, resize

#: A piece at least this much finer-textured than the band around it is furry.
FUR = 1.3
#: A piece this share of which lies in a HOG person box is a person.
PERSON_SHARE = 0.5
#: A plain piece at least this many times as tall as wide is a standing figure.
UPRIGHT = 1.8
#: A piece filling at least this share of its convex hull is compact (a body, not strokes).
COMPACT = 0.6
#: A piece under this share of the largest piece of its candidate is a speck.
_PIECE_FRACTION = 0.1
#: Two pieces overlapping this much (IoU) are the same piece (the better-scored is kept).
_SAME_PIECE = 0.8
#: The band around a piece that its fur is compared with, as a share of sqrt(its area).
_BAND = 0.25
#: HOG's SVM margin above which a window is a person (its default of 0 fires on clutter).
_HOG_MARGIN = 0.5


@cache
def _people_detector() -> cv2.HOGDescriptor:
    """OpenCV's default HOG people detector, made on the first photo that needs it."""
    hog = cv2.HOGDescriptor()
    hog.setSVMDetector(cv2.HOGDescriptor_getDefaultPeopleDetector())
    return hog


@dataclass
class Piece:
    """One connected piece of a candidate mask, judged.

    ``source``: the candidate it came from; ``score``: that candidate's consensus score;
    ``person``: the share of it in HOG person boxes; ``fur``: its fine texture over the
    band around it's; ``upright``: its box's height over its width; ``solidity``: the
    share of its convex hull it fills; ``kind``: "person", "animal" or "object".
    """

    mask: np.ndarray
    source: str
    score: float
    person: float = 0.0
    fur: float = 1.0
    upright: float = 1.0
    solidity: float = 1.0
    kind: str = "object"

    @property
    def area(self) -> int:
        return int(np.count_nonzero(self.mask))

    def summary(self) -> dict:
        """The piece as ``details`` give it (rounded)."""
        return {
            "source": self.source,
            "kind": self.kind,
            "score": round(self.score, 4),
            "fraction": round(float(self.mask.mean()), 4),
            "person": round(self.person, 3),
            "fur": round(self.fur, 3),
            "upright": round(self.upright, 3),
            "solidity": round(self.solidity, 3),
        }


@dataclass
class KindCues:
    """One scene's cues: ``rgb`` the scene's coarse copy, ``working`` the working copy
    (finer, for texture). The detector and the texture map are computed on first use."""

    rgb: np.ndarray
    working: np.ndarray
    _pieces: dict = field(default_factory=dict)

    @cached_property
    def people(self) -> np.ndarray:
        """``(h, w) bool``: inside a HOG person box (margin over :data:`_HOG_MARGIN`);
        none in a copy smaller than the detector's window."""
        inside = np.zeros(self.rgb.shape[:2], bool)
        detector = _people_detector()
        window_width, window_height = detector.winSize
        if self.rgb.shape[0] < window_height or self.rgb.shape[1] < window_width:
            # OpenCV's detectMultiScale crashes the process (a segmentation fault) on an
            # image smaller than its window: a 128x96 photo did.
            return inside
        bgr = np.ascontiguousarray(cv2.cvtColor(self.rgb, cv2.COLOR_RGB2BGR))
        boxes, weights = detector.detectMultiScale(bgr, winStride=(8, 8), scale=1.05)
        for (x, y, w, h), weight in zip(np.reshape(boxes, (-1, 4)), np.ravel(weights)):
            if weight > _HOG_MARGIN:
                inside[max(y, 0) : y + h, max(x, 0) : x + w] = True
        return inside

    @cached_property
    def detail(self) -> np.ndarray:
        """``(h, w) float32``: |Laplacian| of the working copy's grey levels, area-averaged
        to the coarse size (fur is finer than the coarse copy shows)."""
        grey = cv2.cvtColor(self.working, cv2.COLOR_RGB2GRAY)
        laplacian = np.abs(cv2.Laplacian(grey, cv2.CV_32F, ksize=3))
        return resize(laplacian, self.rgb.shape[1::-1], cv2.INTER_AREA)

    @property
    def nbytes(self) -> int:
        """About the memory it holds: the maps computed so far and the judged pieces."""
        maps = sum(self.__dict__[name].nbytes for name in ("people", "detail") if name in self.__dict__)
        return maps + sum(piece.mask.nbytes for pieces in self._pieces.values() for piece in pieces)

    def judge(self, piece: Piece) -> Piece:
        """Fill in ``piece``'s cues and kind."""
        mask = piece.mask
        area = max(piece.area, 1)
        piece.person = float(np.count_nonzero(mask & self.people)) / area
        eight = mask.astype(np.uint8)
        reach = max(2, round(_BAND * np.sqrt(area)))
        band = cv2.dilate(eight, disk(reach)).astype(bool) & ~cv2.dilate(eight, disk(1)).astype(bool)
        core = cv2.erode(eight, disk(1)).astype(bool)
        inside = float(self.detail[core].mean()) if core.any() else float(self.detail[mask].mean())
        around = float(self.detail[band].mean()) if band.any() else inside
        piece.fur = (inside + 1.0) / (around + 1.0)
        rows, cols = np.nonzero(mask)
        piece.upright = float(rows.max() + 1 - rows.min()) / float(cols.max() + 1 - cols.min())
        outlines, _ = cv2.findContours(eight, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        hull = cv2.contourArea(cv2.convexHull(np.concatenate(outlines)))
        piece.solidity = min(1.0, area / max(hull, 1.0))
        if piece.person >= PERSON_SHARE or (piece.upright >= UPRIGHT and piece.fur < FUR):
            piece.kind = "person"
        elif piece.fur >= FUR:
            piece.kind = "animal"
        else:
            piece.kind = "object"
        return piece

    def pieces(self, name: str, mask: np.ndarray, score: float) -> list[Piece]:
        """The judged pieces of candidate ``name`` (kept: a choice looks at the winner's
        twice)."""
        key = (name, score, np.packbits(mask).tobytes())
        if key not in self._pieces:
            self._pieces[key] = [self.judge(Piece(m, name, score)) for m in split_pieces(mask)]
        return self._pieces[key]


def split_pieces(mask: np.ndarray) -> list[np.ndarray]:
    """The connected pieces of a coarse mask of at least a tenth of the largest one (and
    of :data:`MIN_AREA_FRACTION` of the image), largest first."""
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    if count <= 1:
        return []
    floor = max(_PIECE_FRACTION * areas.max(), MIN_AREA_FRACTION * mask.size)
    order = np.argsort(-areas)
    return [labels == index + 1 for index in order if areas[index] >= floor]


@dataclass
class KindChoice:
    """What :func:`choose_kind` decided: the pieces kept (their union is the subject;
    empty: keep the consensus winner), the kind of subject it is, and why."""

    pieces: list[Piece]
    kind: str
    reason: str
    found: bool = True  # False: the subject asked for was not found (the pick is a guess)

    @property
    def mask(self) -> np.ndarray | None:
        if not self.pieces:
            return None
        union = np.zeros_like(self.pieces[0].mask)
        for piece in self.pieces:
            union |= piece.mask
        return union


def _pool(cues: KindCues, candidates: list) -> list[Piece]:
    """Every judged piece of the running candidates, best-scored first, duplicates (IoU
    over :data:`_SAME_PIECE` with a better-scored one) left out."""
    from .consensus import iou

    pool: list[Piece] = []
    for candidate in sorted(candidates, key=lambda c: c.score, reverse=True):
        for piece in cues.pieces(candidate.name, candidate.mask, candidate.score):
            if all(iou(piece.mask, kept.mask) < _SAME_PIECE for kept in pool):
                pool.append(piece)
    return pool


def _prominence(piece: Piece) -> float:
    """How much a piece is the photo's subject: its candidate's score, times its size
    (square root: a cat twice the size of another is not twice the subject)."""
    return piece.score * float(np.sqrt(piece.mask.mean()))


def _body(piece: Piece) -> bool:
    """A furry, compact piece: an animal's body (not a stroke of calligraphy)."""
    return piece.kind == "animal" and piece.solidity >= COMPACT


def _animal_rank(piece: Piece) -> float:
    """:func:`_prominence`, furry pieces first among pieces of like prominence."""
    return _prominence(piece) * (1.5 if piece.kind == "animal" else 1.0)


#: In ``auto``, a piece of another candidate replaces a person winner when its
#: candidate's score is at least this share of the winner's.
_RIVAL = 0.5


def choose_kind(cues: KindCues, candidates: list, winner: str, subject: str, several: bool = False) -> KindChoice:
    """Which pieces the ``subject`` choice keeps among auto's ``candidates``
    (:class:`~jeanscv.subject.consensus.Candidate`, the running ones), ``winner`` being
    the consensus pick.

    ``object``: the winner as it is. ``person``: the winner's most prominent person
    piece, else the most prominent person piece of any candidate. ``animal``: the
    winner's pieces that are no person (the most prominent, furry ones first; all of
    them when ``several``), else the most prominent such piece of any candidate.
    ``auto``: the winner, unless a person is part of it and something furry is found
    beside: among the winner's pieces, or else of a candidate scoring at least half as
    well (people photograph their pets beside them); when the winner is several
    animals (furry, compact pieces), the most prominent unless ``several``. When the kind
    asked for is not found, the winner is kept and ``found`` is False.
    """
    by_name = {c.name: c for c in candidates}
    if subject == "object" or winner not in by_name:
        return KindChoice([], "object", "")
    top = by_name[winner]
    mine = cues.pieces(winner, top.mask, top.score)
    kinds = {p.kind for p in mine}
    if subject == "person":
        people = [p for p in mine if p.kind == "person"]
        people = people or [p for p in _pool(cues, candidates) if p.kind == "person"]
        if not people:
            return KindChoice([], "object", "no person found: the most salient thing instead", found=False)
        best = max(people, key=_prominence)
        return KindChoice([best], "person", f"the most prominent person (from {best.source})")
    if subject == "auto" and not several and len(mine) > 1 and all(_body(p) for p in mine):
        best = max(mine, key=_prominence)  # two cats on a sofa: one pair, on the main one
        return KindChoice([best], "animal", f"several animals: the most prominent (fur {best.fur:.2f})")
    if subject == "auto" and "person" not in kinds:
        return KindChoice([], kinds.pop() if len(kinds) == 1 else "object", "")
    # auto leaves a person only for something furry; animal for anything but a person.
    wanted = ("animal",) if subject == "auto" else ("animal", "object")
    others = [p for p in mine if p.kind in wanted]
    if not others:
        floor = _RIVAL * top.score if subject == "auto" else 0.0
        pool = [p for p in _pool(cues, candidates) if p.kind in wanted and p.score >= floor]
        others = [p for p in pool if p.kind == "animal"] or pool
    if not others:
        if subject == "auto":
            return KindChoice([], "person", "")
        return KindChoice([], "object", "no animal found: the most salient thing instead", found=False)
    ranked = sorted(others, key=_animal_rank, reverse=True)
    kept = ranked[:1]
    for piece in ranked[1:] if several else ():
        # Another candidate's piece of an animal already kept is that animal again.
        if all(np.count_nonzero(piece.mask & other.mask) < 0.2 * piece.area for other in kept):
            kept.append(piece)
    kind = "animal" if kept[0].kind == "animal" else "object"
    why = "a person and an animal: the animal" if subject == "auto" else f"the most prominent {kind}"
    return KindChoice(kept, kind, f"{why} (from {kept[0].source}, fur {kept[0].fur:.2f})")
