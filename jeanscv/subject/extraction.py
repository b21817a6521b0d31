"""Silhouettes of the objects in a photo: segmented (:mod:`jeanscv.subject`, or a
plugin's method), split into separate objects, picked by clicks, each framed on the canvas."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import JeansError
from ..geometry import mask_box
from ..options import ANIMAL_CLASSES, OBJECTS
from .framing import frame_mask
from .silhouettes import SUBJECT_KEYS, Silhouette
from .silhouettes import box_of as _box_of

if TYPE_CHECKING:  # segmentation imports OpenCV, on first use
    from .photo import SharedHypotheses


def extract_silhouette(
    image: np.ndarray,
    method: str = "auto",
    *,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
    shared: SharedHypotheses | None = None,
    subject: str = "auto",
    several: bool = False,
) -> Silhouette:
    """Segment the main object of a photo ``(H, W, 3|4)`` uint8 and frame it.

    ``method``: ``auto``, ``alpha``, ``threshold``, ``grabcut`` (see the README);
    ``mask``: a user-supplied ``(H, W)`` mask, used instead of segmentation; ``shared``:
    a :class:`~jeanscv.subject.photo.SharedHypotheses` that auto's hypotheses are
    cut into, or taken from (a click session of the same photo shares them);
    ``subject``: what auto looks for (``auto``, ``animal``, ``person``, ``object``;
    see :func:`jeanscv.subject.photo.segment`), ``several``: every animal it finds.
    """
    from .photo import segment
    from .plugins import is_plugin_silhouette_method, segment_with

    if subject in ANIMAL_CLASSES:  # classical cues know animals, not their classes
        subject = "animal"

    if mask is None and is_plugin_silhouette_method(method):
        # A plugin extractor takes the image alone: threshold and rect are built-in options.
        result = segment_with(method, image)
    else:
        method = "mask" if mask is not None else method
        result = segment(
            image,
            method,
            threshold=threshold,
            rect=rect,
            mask=mask,
            shared=shared,
            subject=subject,
            several=several,
        )
    canvas, framing = frame_mask(result.mask)
    return Silhouette(
        result.mask.astype(np.float32), canvas, framing, result.method, result.contour, dict(result.details)
    )


def object_clicks(points, background_points, clicks, box=None) -> list:
    """Every object's clicks (:class:`jeanscv.subject.clicks.ObjectClicks`): ``points``,
    ``background_points`` and ``box`` are one object's, ``clicks`` a
    :class:`jeanscv.subject.clicks.Clicks` or a list of per-object
    ``{"positive": [...], "negative": [...], "box": [x0, y0, x1, y1]}``."""
    from .clicks import VERSION, Clicks, ObjectClicks, parse_clicks

    objects = []
    if points or background_points or box is not None:
        objects.append(ObjectClicks(tuple(points or ()), tuple(background_points or ()), box))
    if clicks is not None:
        if isinstance(clicks, Clicks):
            objects += clicks.objects
        else:
            objects += parse_clicks({"format": "jeanscv-clicks", "version": VERSION, "objects": list(clicks)}).objects
    return objects


def extract_silhouettes(
    image: np.ndarray,
    method: str = "auto",
    *,
    objects: str = "one",
    points: list[tuple[float, float]] | None = None,
    background_points: list[tuple[float, float]] | None = None,
    clicks=None,
    box: tuple[float, float, float, float] | None = None,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
    shared: SharedHypotheses | None = None,
    subject: str = "auto",
    detector: str = "auto",
) -> list[Silhouette]:
    """The objects of a photo ``(H, W, 3|4)`` uint8, each segmented and framed on its own.

    ``objects="one"``: the main subject (as :func:`extract_silhouette`); ``"all"``: every
    separate object of the subject mask, largest first (specks under 10% of the largest
    are dropped). ``subject``: what automatic finding looks for (``auto``, ``animal``,
    ``person``, ``object``): with ``"one"`` the most prominent animal, with ``"all"``
    every animal found (see :func:`jeanscv.subject.photo.segment`); an animal class
    (``dog``) prefers that animal.

    ``detector``: ``auto`` lets the shipped detector (:mod:`jeanscv.detect`) say where the
    subject is: the most prominent detection of the kind asked for (``objects="all"``:
    each) is cut inside its box (:mod:`jeanscv.subject.detected`), method ``detector``;
    where it finds none, or with ``none``, classical finding as before.

    Clicks fix the subject (``(x, y)`` image pixels): ``points`` are the positive clicks
    of one object and ``background_points`` its negative ones; ``clicks`` gives several
    objects, each with its own clicks (a :class:`jeanscv.subject.clicks.Clicks`, or a list of
    ``{"positive": [...], "negative": [...]}``), after the object of ``points``. Each
    clicked object is segmented by a :class:`~jeanscv.subject.interactive.ClickSession`
    (method ``"clicks"``): its mask holds every positive click and none of the negative
    ones. ``box`` ``(x0, y0, x1, y1)`` (pixels, x right, y down) holds the object of
    ``points``: the object is cut inside it, alone or with the clicks; per-object boxes
    come in ``clicks``. A click or box that finds nothing raises JeansError ("nothing
    found there"), never an empty object. The clicked objects come first, in order; with ``"all"`` the automatic objects
    that they do not cover follow. With a user ``mask``, ``points`` pick the mask's pieces
    instead. Every silhouette's ``details`` holds its ``box`` (x, y, w, h); a clicked
    one also its ``clicks`` and ``point`` (its first positive click, else its box's centre). ``shared``: a
    :class:`~jeanscv.subject.photo.SharedHypotheses` for auto's hypotheses of this
    photo (cut once for the automatic subject and the click session; the results are
    the same without it).
    """
    if objects not in OBJECTS:
        raise JeansError(f"unknown objects {objects!r} (use {' or '.join(OBJECTS)})")
    pixels = np.asarray(image)
    if mask is not None:
        if background_points or clicks is not None or box is not None:
            raise JeansError("clicks refine the automatic segmentation: they cannot be combined with a mask")
        return _mask_objects(pixels, method, objects, points, threshold, rect, mask)
    wanted = object_clicks(points, background_points, clicks, box)
    if not wanted and method == "auto" and rect is None:
        found = _detected_silhouettes(pixels, objects, subject, detector)
        if found:
            return found
    if not wanted:
        main = extract_silhouette(
            pixels, method, threshold=threshold, rect=rect, shared=shared, subject=subject, several=objects == "all"
        )
        found = split_objects(main.mask) if objects == "all" else []
        if len(found) <= 1:
            main.details["box"] = list(_box_of(main))
            return [main]
        return [_object_silhouette(obj, main) for obj in found]
    from .clicks import Clicks
    from .interactive import ClickSession
    from .photo import SharedHypotheses

    height, width = pixels.shape[:2]
    Clicks(tuple(wanted)).check((width, height))
    shared = shared or SharedHypotheses()  # the session's hypotheses are auto's too
    # The detector runs once: its boxes start the session's clicks, and it finds the
    # automatic subject that negative clicks alone edit and --objects all's other objects.
    detections = _detections(pixels, detector)
    automatic = None
    if any(obj.edits_automatic for obj in wanted) and method == "auto" and rect is None:
        # Negative clicks alone take something away from the automatic subject as it
        # is found without clicks: the detector's where it finds one (as the page shows it).
        found = _detected_silhouettes(pixels, "one", subject, detector, detections)
        automatic = np.asarray(found[0].mask) >= 0.5 if found else None
    session = ClickSession(pixels, shared=shared, automatic=automatic, detector=detector, detections=detections)
    chosen = clicked_silhouettes(session, wanted)
    if objects == "all":
        covered = np.zeros(pixels.shape[:2], bool)
        for silhouette in chosen:
            covered |= np.asarray(silhouette.mask) >= 0.5
        # The other objects as automatic finding gives them: the detector's animals where
        # it finds some, else classical finding's pieces. One mostly under a clicked
        # object is that object again.
        detected = (
            _detected_silhouettes(pixels, "all", subject, detector, detections)
            if method == "auto" and rect is None
            else []
        )
        if detected:
            for silhouette in detected:
                mask = np.asarray(silhouette.mask) >= 0.5
                if np.count_nonzero(mask & ~covered) > 0.5 * np.count_nonzero(mask):
                    chosen.append(silhouette)
            return chosen
        try:
            main = extract_silhouette(
                pixels, method, threshold=threshold, rect=rect, shared=shared, subject=subject, several=True
            )
        except JeansError:
            return chosen
        for obj in split_objects(main.mask):
            if np.count_nonzero(obj.mask & ~covered) > 0.5 * obj.area:
                chosen.append(_object_silhouette(obj, main))
    return chosen


def _detections(pixels: np.ndarray, detector: str, stacklevel: int = 3) -> list:
    """The photo's detections (:func:`.detected.find`; ``detector`` ``none``: none), with
    one warning line where the model cannot be used (at ``stacklevel``: the caller of
    :func:`extract_silhouettes`)."""
    import warnings

    from . import detected

    found, problem = detected.find(pixels, detector)
    if problem:
        warnings.warn(f"jeanscv: {problem}", detected.DetectorWarning, stacklevel=stacklevel)
    return found


def _detected_silhouettes(
    pixels: np.ndarray, objects: str, subject: str, detector: str, found: list | None = None
) -> list[Silhouette]:
    """The detector's subject (``objects="all"``: every detected object of the kind asked
    for), each cut inside its box; empty where it finds none, or the photo's alpha
    channel already is the silhouette. ``found``: the photo's detections where the caller
    has them (else the detector runs here)."""
    from . import detected
    from .interactive import WORKING_SIZE
    from .photo import _alpha_meaningful

    if pixels.ndim == 3 and pixels.shape[2] == 4 and _alpha_meaningful(pixels[..., 3]):
        return []
    if found is None:
        found = _detections(pixels, detector, stacklevel=4)
    ranked = detected.wanted(found, subject, pixels.shape[:2])
    chosen = ranked[:1] if objects == "one" else ranked
    segmentations = detected.detected_segmentations(pixels, chosen, WORKING_SIZE)
    pairs = [(d, s) for d, s in zip(chosen, segmentations) if s is not None]
    if not pairs:
        return []
    agreements = [s.details.get("starts_agree", 1.0) for _, s in pairs]
    if len(pairs) > 1:
        from .clicks import ObjectClicks

        boxes = [ObjectClicks((), (), d.box) for d, _ in pairs]
        pairs = list(zip([d for d, _ in pairs], _disjoint([s for _, s in pairs], boxes)))
    result = []
    for index, (detection, segmentation) in enumerate(pairs):
        silhouette = _framed(segmentation)
        # A rival about as prominent makes the one dressed unsure; with "all" both are dressed.
        others = [] if objects == "all" else ranked[1:]
        silhouette.details.update(
            detected.subject_details(detection, others, found, segmentation.mask, subject, agreements[index])
        )
        if index:
            silhouette.details["uncertain"] = False  # the note speaks of the main subject
            silhouette.details["doubts"] = []
        result.append(silhouette)
    return result


def clicked_silhouettes(session, objects) -> list[Silhouette]:
    """One framed silhouette per object's clicks (:class:`jeanscv.subject.clicks.ObjectClicks`),
    in order, segmented by ``session`` (a
    :class:`~jeanscv.subject.interactive.ClickSession` of the photo, which a caller
    that clicks often keeps); ``details`` holds the object's ``clicks``, its first
    positive click as ``point`` and its ``box``.

    The objects are disjoint: an object whose mask holds another's positive clicks is
    segmented again with them as negative clicks (the other object is not part of it),
    and a pixel that several masks still take goes to the one with the nearest positive
    click (:func:`~jeanscv.subject.masks.disjoint`)."""
    segmentations = [session.segment(obj.positive, obj.negative, obj.box) for obj in objects]
    if len(segmentations) > 1:
        segmentations = [
            _apart(session, obj, segmentation, objects[:index] + objects[index + 1 :])
            for index, (obj, segmentation) in enumerate(zip(objects, segmentations))
        ]
        segmentations = _disjoint(segmentations, objects)
    found = []
    for obj, segmentation in zip(objects, segmentations):
        silhouette = _framed(segmentation, obj.anchor)
        silhouette.details["clicks"] = obj.to_json()
        found.append(silhouette)
    return found


def _apart(session, obj, segmentation, others):
    """``obj``'s segmentation again with the other objects' positive clicks that its mask
    holds as negative clicks (none on its own clicks' pixels), else as it is."""
    mask = segmentation.mask
    mine = {(int(x), int(y)) for x, y in obj.positive}
    theirs = [
        (x, y) for other in others for x, y in other.positive if mask[int(y), int(x)] and (int(x), int(y)) not in mine
    ]
    if not theirs:
        return segmentation
    return session.segment(obj.positive, obj.negative + tuple(theirs), obj.box)


def _disjoint(segmentations: list, objects) -> list:
    """Clicked objects' segmentations made disjoint (seeds: each object's positive clicks,
    else its mask's deepest pixel); a changed one gets its contour again, and one left
    with nothing is an error naming it."""
    import dataclasses

    from .masks import deepest_point, disjoint, outer_contour

    masks = [s.mask for s in segmentations]
    seeds = [list(obj.positive) or [deepest_point(mask)] for obj, mask in zip(objects, masks)]
    result = []
    for index, (segmentation, mask) in enumerate(zip(segmentations, disjoint(masks, seeds))):
        if mask is not segmentation.mask:
            if not mask.any():
                raise JeansError(f"object {index + 1} lies under another clicked object: click it apart")
            segmentation = dataclasses.replace(segmentation, mask=mask, contour=outer_contour(mask, (1.0, 1.0)))
        result.append(segmentation)
    return result


def split_objects(mask: np.ndarray):
    """The separate objects of a subject mask (:func:`jeanscv.subject.objects.split_objects`)."""
    from .objects import split_objects as _split

    return _split(mask)


def _mask_objects(pixels, method, objects, points, threshold, rect, mask) -> list[Silhouette]:
    """A user mask's objects: with ``points``, the pieces under them first."""
    from .objects import check_point, object_at
    from .photo import binarise, segment

    clicks = [check_point(point, pixels.shape[:2]) for point in points or ()]
    main = extract_silhouette(pixels, method, threshold=threshold, rect=rect, mask=mask)
    subject = binarise(mask)
    # A given mask is split before its cleaning, which keeps only pieces of at least a
    # quarter of the largest one's size: the user said what the objects are.
    found = split_objects(subject) if subject.any() and (clicks or objects == "all") else []
    if not clicks and len(found) <= 1:
        main.details["box"] = list(_box_of(main))
        return [main]

    def pick(obj, point=None) -> Silhouette | None:
        try:
            return _framed(segment(pixels, "mask", mask=obj.mask), point)
        except JeansError:  # a speck of the user's mask, too small to segment
            if point is None:
                return None
            raise

    chosen: list[Silhouette | None] = []
    picked: set[int] = set()
    for point in clicks:
        index = object_at(found, point)
        if index is None:
            raise JeansError(f"no object of the mask at point ({point[0]:g}, {point[1]:g})")
        if index not in picked:
            picked.add(index)
            chosen.append(pick(found[index], point))
    if objects == "all":
        chosen += [pick(obj) for i, obj in enumerate(found) if i not in picked]
    return [silhouette for silhouette in chosen if silhouette is not None]


def _framed(segmentation, point: tuple[float, float] | None = None) -> Silhouette:
    """A :class:`Silhouette` of one object's :class:`Segmentation` (its bool mask kept)."""

    canvas, framing = frame_mask(segmentation.mask)
    details = {**segmentation.details, "box": list(mask_box(segmentation.mask))}
    if point is not None:
        details["point"] = list(point)
    return Silhouette(segmentation.mask, canvas, framing, segmentation.method, segmentation.contour, details)


def _object_silhouette(obj, main: Silhouette, point: tuple[float, float] | None = None) -> Silhouette:
    """A :class:`Silhouette` of one object split from the main subject's mask."""
    canvas, framing = frame_mask(obj.mask)
    details = {"box": list(obj.box), "subject_method": main.method}
    details.update({key: main.details[key] for key in SUBJECT_KEYS if key in main.details})
    if point is not None:
        details["point"] = list(point)
    return Silhouette(obj.mask, canvas, framing, main.method, obj.contour, details)
