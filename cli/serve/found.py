"""The detected animals the page offers as choices, and which one the jeans are on.

The photo's automatic subject may be the detector's (:mod:`jeanscv.subject.detected`):
the page draws every detected animal's box with its class and score, and a tap on one
dresses it (the page sends that box). Boxes go to the page in pixels of the photo as
displayed.
"""

from __future__ import annotations

import numpy as np

from jeanscv.subject.clicks import Clicks
from jeanscv.subject.silhouettes import box_of


def offered_detections(pixels: np.ndarray, auto: list, size: tuple[int, int], detector: str) -> list[dict]:
    """The detections the page offers as choices: every detected animal, one per object
    (one animal's boxes under several class names merged, as automatic finding merges
    them), most prominent first, and the detection automatic finding dressed when it is
    none of those (a person, with ``subject`` person). ``{"class", "score", "box"}``,
    the box ``[x0, y0, x1, y1]`` in pixels of the photo as displayed (``size``: the
    page's frame; the detector saw the decoded ``pixels``), and ``"automatic": True`` on
    the one automatic finding dressed."""
    from jeanscv.detect import COCO_LABELS, Detection
    from jeanscv.subject import detected

    if detector == "none":
        return []
    details = auto[0].details if auto else {}
    if "detections" in details:  # what automatic finding was told: not detected again
        found = [
            Detection(d["class"], COCO_LABELS.index(d["class"]), float(d["score"]), tuple(d["box"]))
            for d in details["detections"]
            if d["class"] in COCO_LABELS
        ]
    else:  # found classically (no animal of the kind asked for): what the detector sees
        found, _ = detected.find(pixels, detector)
    offered = [detected.detection_json(d) for d in detected.wanted(found, "animal", pixels.shape[:2])]
    for silhouette in auto:  # what automatic finding dressed: "automatic" (the page is not sent it)
        chosen = silhouette.details.get("detection")
        same = [d for d in offered if chosen and _same_box(chosen["box"], d["box"])]
        if same:
            same[0]["automatic"] = True
        elif chosen:
            offered.insert(0, {**chosen, "automatic": True})
    sx, sy = size[0] / pixels.shape[1], size[1] / pixels.shape[0]  # 1 unless decoded at another size
    for entry in offered:
        x0, y0, x1, y1 = entry["box"]
        entry["box"] = [
            round(min(max(x0 * sx, 0.0), size[0]), 1),
            round(min(max(y0 * sy, 0.0), size[1]), 1),
            round(min(max(x1 * sx, 0.0), size[0]), 1),
            round(min(max(y1 * sy, 0.0), size[1]), 1),
        ]
    return offered


def _same_box(a, b, tolerance: float = 0.51) -> bool:
    """Whether two ``[x0, y0, x1, y1]`` boxes are the same (as sent back and forth, to 0.1 pixel)."""
    return a is not None and b is not None and all(abs(float(p) - float(q)) <= tolerance for p, q in zip(a, b))


#: An object wears a detected animal's jeans when at least this share of its box lies in
#: the animal's box and it fills at least :data:`_FILLS` of that box.
_INSIDE, _FILLS = 0.8, 0.25


def page_detections(photo, clicks: Clicks | None, objects: list) -> list[dict]:
    """The offered detections of ``photo`` (the engine's :class:`~.engine.Photo`), each
    with ``dressed``: whether the result's jeans are on it. Automatic: the one automatic
    finding dressed. With clicks: an object whose box is that detection's (a choice on
    the page), or else the detection an object lies in and fills (a click on that
    animal: see :data:`_INSIDE`; the best one an object)."""
    entries = [
        {"class": d["class"], "score": d["score"], "box": d["box"], "dressed": clicks is None and "automatic" in d}
        for d in photo.detections
    ]
    if clicks is None:
        return entries
    for obj, fitted in zip(clicks.objects, objects):
        same = [entry for entry in entries if _same_box(obj.box, entry["box"])]
        if same:
            same[0]["dressed"] = True
            continue
        x, y, w, h = box_of(fitted.silhouette)
        best, most = None, 0.0
        for entry in entries:
            x0, y0, x1, y1 = entry["box"]
            inside = max(0.0, min(x + w, x1) - max(x, x0)) * max(0.0, min(y + h, y1) - max(y, y0))
            area = max((x1 - x0) * (y1 - y0), 1e-9)
            if inside >= _INSIDE * max(w * h, 1) and inside / area >= _FILLS and inside / area > most:
                best, most = entry, inside / area
        if best is not None:
            best["dressed"] = True
    return entries


def caption(photo, entries: list[dict]) -> list[str]:
    """``--top auto``'s meme for a result: ``["how would a cat", "wear jeans?"]`` when a
    detected animal wears the jeans and the detector is sure of its class (judged among
    every detection of ``photo``), else ``["how would this", "wear jeans?"]``."""
    from jeanscv.subject.detected import captions

    dressed = next((entry for entry in entries if entry["dressed"]), None)
    return list(captions({"detection": dressed, "detections": photo.detections} if dressed else {}))
