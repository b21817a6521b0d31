"""Automatic finding with the shipped detector (:mod:`jeanscv.detect`): which detected
object is the subject, its mask, and how sure that is.

The detector says where the animal is; the cut inside its box stays classical (the box
engine a person's box uses, then what the animal stands or lies on dropped from the
bottom of its box: :func:`.boxed.segment_box` with ``drop_support``). Where it finds
nothing of what is asked for, automatic finding is the classical one, unchanged
(:mod:`.photo`).

Which object: among the detections of the wanted kind (``auto`` and ``animal``: every
animal class as one, since a running dog is called a cat or a horse from frame to frame
while its box stays on it; ``person``; or one animal class, preferred over the others),
overlapping boxes of one object are merged, and the most prominent wins: its score
times the square root of the share of the photo its box covers, so a large clear animal
beats a small sure one in the corner, less for each side of the photo its box touches
(what the frame cuts is seldom the subject).

When to say "needs a look" (``uncertain``, with ``doubts``): a second object of the
wanted kind about as prominent; a weak score; a cut that disagrees with its box (a tight
box's object reaches across it); a cut whose two starts disagree (where the animal ends
is a coin toss between GrabCut's two local optima).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import TypeVar

import numpy as np

from ..detect import ANIMALS, Detection, DetectorUnavailable, detect
from ..errors import JeansError
from ..geometry import mask_box
from ..options import ANIMAL_CLASSES

Boxed = TypeVar("Boxed")  # a detection, or anything else with a ``box``


class DetectorWarning(UserWarning):
    """The detector could not be used (a model file missing or altered): the subject is
    found without it."""


#: Boxes of one object under different classes overlap at least this much (box IoU).
SAME_OBJECT = 0.6
#: An animal's box this close to a likelier person's box (box IoU) is that person
#: (:func:`animals`). Stricter than :data:`SAME_OBJECT`: a rider's box and the horse's
#: overlapped 0.67 on a shared photo; the person's own box called a cat, 0.96.
SAME_PERSON = 0.8
#: A box the photo's edge cuts is less likely the subject (the subject is framed; what
#: the frame cuts lies beside it): its prominence is multiplied by this for each side of
#: the photo it touches, two at most (a corner: a third or a fourth side touched makes a
#: close-up of the subject, not a thing cut off further beside it, and a dog that fills
#: the photo is not weighed down below a smaller animal). On the puppy on a light floor a person's foot and a toy giraffe
#: at the photo's corner were "dog 0.47" beside the puppy's "dog 0.47", and the larger box
#: won (IoU 0.00 -> 0.82 with the factor). ``bench.real_photos``, both shared sets: that
#: photo alone changed its pick, at 0.8 and at 0.7 alike.
EDGE_FACTOR = 0.8
#: A box's side within this share of the photo's long side of its edge touches it.
EDGE_TOUCH = 0.01
#: A second object at least this share of the first's prominence makes the pick unsure.
RIVAL = 0.6
#: A second box that holds at least this share of the chosen box is the chosen animal
#: with its surroundings, no rival (the dog in an armchair, 0.88).
ENCLOSED = 0.8
#: Scores under this make the pick unsure.
WEAK_SCORE = 0.45
#: A cut whose own box overlaps the detection's box less than this disagrees with it.
DISAGREES = 0.55
#: Where the two starts of the cut inside the box (GrabCut's two local optima) agree less
#: than this (the IoU of their cuts), which one wins can turn on a pixel of the box: the
#: pick is unsure. On the shared photos the starts agree 0.88 or more, or 0.75 or less:
#: under it, four wrong picks (a cat on a post, a bulldog on grass with its ball, the
#: dog among people, the dog on a couch; two of them not flagged before) and two right
#: ones (the horse, a young monkey).
STARTS_AGREE = 0.8


def _overlap(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """The area two ``(x0, y0, x1, y1)`` boxes share."""
    width = min(a[2], b[2]) - max(a[0], b[0])
    height = min(a[3], b[3]) - max(a[1], b[1])
    return width * height if width > 0 and height > 0 else 0.0


def _area(box: tuple[float, ...]) -> float:
    return (box[2] - box[0]) * (box[3] - box[1])


def box_iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """IoU of two ``(x0, y0, x1, y1)`` boxes."""
    inter = _overlap(a, b)
    union = _area(a) + _area(b) - inter
    return inter / union if inter > 0 and union > 0 else 0.0


def prominence(detection: Detection, shape: tuple[int, int], framed: bool = True) -> float:
    """Score times the square root of the share of the ``(H, W)`` photo the box covers;
    with ``framed``, times :data:`EDGE_FACTOR` for each side of the photo the box touches,
    two at most (which object to dress; without: how sure and how big it is)."""
    x0, y0, x1, y1 = detection.box
    height, width = shape
    share = max(0.0, x1 - x0) * max(0.0, y1 - y0) / float(height * width)
    near = EDGE_TOUCH * max(height, width)
    touched = min(2, (x0 <= near) + (y0 <= near) + (x1 >= width - near) + (y1 >= height - near))
    return detection.score * math.sqrt(min(1.0, share)) * (EDGE_FACTOR**touched if framed else 1.0)


def animals(detections: Sequence[Detection]) -> list[Detection]:
    """The animal detections, less those that are a person under another name: an animal
    box on nearly the same box (box IoU >= :data:`SAME_PERSON`) as a person scoring higher.
    A man asleep under a blanket was "person 0.47" and "cat 0.38" on one box, beside the
    real cat's own smaller box ("cat 0.41"), which the larger box's prominence beat. A
    rider on a horse, a cat on a lap or in arms have boxes of their own that overlap
    the person's far less."""
    people = [d for d in detections if d.label == "person"]
    return [
        d
        for d in detections
        if d.label in ANIMALS and not any(p.score > d.score and box_iou(p.box, d.box) >= SAME_PERSON for p in people)
    ]


def wanted(detections: list[Detection], subject: str, shape: tuple[int, int]) -> list[Detection]:
    """The detections ``subject`` asks for, one per object, most prominent first (a named
    animal class before the other animals; :func:`animals`); empty for ``object``."""
    if subject in ("auto", "animal") or subject in ANIMAL_CLASSES:
        pool = animals(detections)
    elif subject == "person":
        pool = [d for d in detections if d.label == "person"]
    else:
        return []
    return one_per_object(sorted(pool, key=lambda d: (d.label == subject, prominence(d, shape)), reverse=True))


def one_per_object(ranked: Iterable[Boxed]) -> list[Boxed]:
    """``ranked`` (anything with a ``box``, best first) with one entry per object: a box
    overlapping one kept by :data:`SAME_OBJECT` or more is that object under another class
    name (a dog 0.61 and a sheep 0.32 on one animal), and the first stands for it."""
    kept: list[Boxed] = []
    for candidate in ranked:
        if all(box_iou(candidate.box, other.box) < SAME_OBJECT for other in kept):
            kept.append(candidate)
    return kept


def _held(inner: tuple[float, ...], outer: tuple[float, ...]) -> float:
    """The share of box ``inner``'s area that lies in box ``outer``."""
    area = _area(inner)
    return _overlap(inner, outer) / area if area > 0 else 0.0


def detection_json(detection: Detection) -> dict:
    """A detection as the report gives it: class, score, box in image pixels."""
    return {
        "class": detection.label,
        "score": round(detection.score, 3),
        "box": [round(v, 1) for v in detection.box],
    }


def doubts(
    chosen: Detection, others: list[Detection], mask: np.ndarray, shape: tuple[int, int], agreement: float = 1.0
) -> list[str]:
    """Why the detector's pick may be the wrong thing (empty: sure). ``agreement``: how
    far the two starts of the cut inside its box agree (:func:`.box_cut.box_cut_agreed`)."""
    found = []
    # A box round the chosen one (it holds most of it) is that animal with what it sits
    # in, not a second animal: the dog in an armchair was also "dog 0.39" on the chair.
    # Two animals of similar size and sureness, wherever the frame cuts them: the frame
    # only says which of the two is likelier the subject.
    rivals = [other for other in others if _held(chosen.box, other.box) < ENCLOSED]
    rival = max(rivals, key=lambda other: prominence(other, shape, framed=False), default=None)
    if rival is not None and prominence(rival, shape, framed=False) >= RIVAL * prominence(chosen, shape, framed=False):
        found.append(f"two of similar size: a {chosen.label} and a {rival.label}")
    if chosen.score < WEAK_SCORE:
        found.append(f"the detector is unsure ({chosen.label} {chosen.score:.2f})")
    cut = mask_box(mask)  # (x, y, w, h)
    if box_iou((cut[0], cut[1], cut[0] + cut[2], cut[1] + cut[3]), chosen.box) < DISAGREES:
        found.append(f"the cut does not fill the {chosen.label}'s box")
    if agreement < STARTS_AGREE:
        found.append(f"the cut inside the {chosen.label}'s box is unsure where the {chosen.label} ends")
    return found


def find(pixels: np.ndarray, detector: str) -> tuple[list[Detection], str | None]:
    """The detections of ``pixels`` (``detector``: ``auto`` the shipped model, ``none``
    nothing), and a warning line where the model cannot be used (then none)."""
    if detector == "none":
        return [], None
    try:
        return detect(pixels), None
    except DetectorUnavailable as exc:
        return [], f"{exc}; finding the subject without it"


def detected_segmentations(pixels: np.ndarray, chosen: list[Detection], working_size: int) -> list:
    """The cut inside each chosen box (:func:`.boxed.segment_box`, what the animal stands
    on dropped), None where it holds no object (fewer than 0.5% of the photo's pixels)."""
    from .boxed import segment_box
    from .masks import MIN_AREA_FRACTION

    rgb = np.ascontiguousarray(pixels[..., :3])
    found = []
    for detection in chosen:
        try:
            segmentation = segment_box(rgb, detection.box, working_size, drop_support=True)
        except JeansError:
            segmentation = None
        if segmentation is not None and segmentation.mask.mean() < MIN_AREA_FRACTION:
            segmentation = None
        found.append(segmentation)
    return found


def subject_details(
    chosen: Detection,
    others: list[Detection],
    all_found: list[Detection],
    mask,
    subject: str,
    agreement: float = 1.0,
):
    """The silhouette's ``details`` that say what was dressed and how sure that is
    (``agreement``: see :func:`doubts`)."""
    shape = mask.shape
    reasons = doubts(chosen, others, mask, shape, agreement)
    kind = "person" if chosen.label == "person" else "animal"
    return {
        "chosen": "detector",
        "reason": f"the detector found a {chosen.label} ({chosen.score:.2f})",
        "subject": subject,
        "kind": kind,
        "uncertain": bool(reasons),
        "doubts": reasons,
        "detections": [detection_json(d) for d in all_found],
        "detection": detection_json(chosen),
    }


#: The detector's class names a subject only from this score, and only when no other
#: animal class on the same box comes within this share of it (on real footage a goat was
#: called a bird at 0.3-0.5 while its box stayed right: the box is trusted before the name).
SURE_SCORE = 0.5
SURE_MARGIN = 0.75


def sure_class(details: dict) -> str | None:
    """The class of the detection a silhouette's ``details`` dressed, where the detector
    is sure of the name (see :data:`SURE_SCORE`); else None."""
    chosen = details.get("detection")
    if not chosen or chosen["score"] < SURE_SCORE:
        return None
    for other in details.get("detections", ()):
        if (
            other["class"] != chosen["class"]
            and other["class"] in ANIMALS
            and box_iou(other["box"], chosen["box"]) >= SAME_OBJECT
            and other["score"] > SURE_MARGIN * chosen["score"]
        ):
            return None
    return chosen["class"]


def captions(details: dict) -> tuple[str, str]:
    """``--top auto``'s meme: ("how would a cat", "wear jeans?") where the class is sure,
    else ("how would this", "wear jeans?")."""
    name = sure_class(details)
    if name is None:
        return "how would this", "wear jeans?"
    article = "an" if name[0] in "aeiou" else "a"
    return f"how would {article} {name}", "wear jeans?"
