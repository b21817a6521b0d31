"""Silhouettes of the objects in a photo: segmented (:mod:`jeanscv.silhouette`, or a
plugin's method), split into separate objects, picked by clicks, each framed on the canvas."""

from __future__ import annotations

import numpy as np

from .errors import JeansError
from .framing import frame_mask
from .geometry import mask_box
from .silhouettes import Silhouette
from .silhouettes import box_of as _box_of

#: ``one``: the main subject; ``all``: every separate object, each with its own garment.
OBJECTS = ("one", "all")


def extract_silhouette(
    image: np.ndarray,
    method: str = "auto",
    *,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
) -> Silhouette:
    """Segment the main object of a photo ``(H, W, 3|4)`` uint8 and frame it.

    ``method``: ``auto``, ``alpha``, ``threshold``, ``grabcut`` (see the README);
    ``mask``: a user-supplied ``(H, W)`` mask, used instead of segmentation.
    """
    from .plugins import is_plugin_silhouette_method, segment_with
    from .silhouette.photo import segment

    if mask is None and is_plugin_silhouette_method(method):
        # A plugin extractor takes the image alone: threshold and rect are built-in options.
        result = segment_with(method, image)
    else:
        result = segment(image, "mask" if mask is not None else method, threshold=threshold, rect=rect, mask=mask)
    canvas, framing = frame_mask(result.mask)
    return Silhouette(
        result.mask.astype(np.float32), canvas, framing, result.method, result.contour, dict(result.details)
    )


def extract_silhouettes(
    image: np.ndarray,
    method: str = "auto",
    *,
    objects: str = "one",
    points: list[tuple[float, float]] | None = None,
    threshold: float | None = None,
    rect: tuple[int, int, int, int] | None = None,
    mask: np.ndarray | None = None,
) -> list[Silhouette]:
    """The objects of a photo ``(H, W, 3|4)`` uint8, each segmented and framed on its own.

    ``objects="one"``: the main subject (as :func:`extract_silhouette`); ``"all"``: every
    separate object of the subject mask, largest first (specks under 10% of the largest
    are dropped). ``points``: ``(x, y)`` image pixels, like clicks: each picks the object
    under it (or within 2% of the image's long side of it), else, or when the automatic
    subject is uncertain (``details["uncertain"]``: its hypotheses disagreed), the object
    around it is segmented by GrabCut seeded at the point (method ``"point"``); the
    picked objects come first, in point order, and with ``"all"`` the other objects follow. Every
    silhouette's ``details`` holds its ``box`` (x, y, w, h) and, when a point picked
    it, the ``point``.
    """
    from .silhouette.objects import check_point, object_at, split_objects
    from .silhouette.photo import binarise, segment
    from .silhouette.seeded import segment_at_point

    if objects not in OBJECTS:
        raise JeansError(f"unknown objects {objects!r} (use {' or '.join(OBJECTS)})")
    pixels = np.asarray(image)
    clicks = [check_point(point, pixels.shape[:2]) for point in points or ()]
    try:
        main = extract_silhouette(pixels, method, threshold=threshold, rect=rect, mask=mask)
    except JeansError:
        if not clicks or mask is not None:
            raise
        main = None  # nothing found automatically: every point segments its own object
    found = []
    if clicks or objects == "all":
        # A given mask is split before its cleaning, which keeps only pieces of at least
        # a quarter of the largest one's size: the user said what the objects are.
        subject = binarise(mask) if mask is not None else None if main is None else main.mask
        found = [] if subject is None or not subject.any() else split_objects(subject)
    if not clicks and len(found) <= 1:
        main.details["box"] = list(_box_of(main))
        return [main]

    def pick(obj, point=None) -> Silhouette | None:
        if mask is None:
            return _object_silhouette(obj, main, point)
        try:
            return _framed(segment(pixels, "mask", mask=obj.mask), point)
        except JeansError:  # a speck of the user's mask, too small to segment
            if point is None:
                return None
            raise

    chosen: list[Silhouette | None] = []
    picked: set[int] = set()
    # When auto's hypotheses disagreed, its subject may be a wrong blob that holds the
    # clicked thing (players joined by the boards behind them): the click is then
    # segmented on its own, and the blob under it gets no garment of its own.
    uncertain = main is not None and bool(main.details.get("uncertain"))
    for point in clicks:
        index = object_at(found, point)
        if index is None or uncertain:
            if index is not None:
                picked.add(index)
            chosen.append(_framed(segment_at_point(pixels, point), point))
        elif index not in picked:
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
    if point is not None:
        details["point"] = list(point)
    return Silhouette(obj.mask, canvas, framing, main.method, obj.contour, details)
