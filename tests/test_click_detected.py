"""Clicks that start from what the detector knows (jeanscv.subject.click_detected): a first
positive click inside a detected animal's box, on its cut, starts from that box; every
other click works as without the detector. Detections are given to the session, so the
tests say exactly which boxes it has (the detector finds nothing on these drawings)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from test_objects import inside_point
from test_serve import scene  # the owner (left) and the dog (right), 800x500, read-only

from jeanscv.detect import Detection
from jeanscv.errors import JeansError
from jeanscv.geometry import mask_box
from jeanscv.subject.click_detected import DetectedBox, detected_boxes, meant_box
from jeanscv.subject.interactive import ClickSession


def tight_box(mask: np.ndarray, pad: int = 6) -> tuple[float, float, float, float]:
    x, y, w, h = mask_box(mask)
    return float(x - pad), float(y - pad), float(x + w + pad), float(y + h + pad)


def dog_detection(label: str = "dog", score: float = 0.8) -> Detection:
    return Detection(label, 16, score, tight_box(scene().masks[1]))


def owner_detection() -> Detection:
    return Detection("person", 0, 0.9, tight_box(scene().masks[0]))


@cache
def sessions() -> tuple[ClickSession, ClickSession]:
    """The same photo with the dog and the owner detected, and with nothing detected."""
    image = scene().image
    return (
        ClickSession(image, detections=[dog_detection(), owner_detection()]),
        ClickSession(image, detections=[]),
    )


def test_only_animals_start_clicks_one_box_an_animal_smallest_first():
    shape = (100, 200, 3)
    found = [
        Detection("person", 0, 0.9, (0.0, 0.0, 200.0, 100.0)),
        Detection("dog", 16, 0.61, (10.2, 20.0, 90.0, 80.5)),
        Detection("sheep", 18, 0.32, (10.0, 20.0, 91.0, 80.0)),  # the dog's box again
        Detection("cat", 15, 0.5, (120.0, 30.0, 150.0, 60.0)),
        Detection("bird", 14, 0.2, (0.0, 0.0, 5.0, 5.0)),  # too weak
    ]
    boxes, problem = detected_boxes(np.zeros(shape, np.uint8), "auto", found)
    assert problem is None
    assert boxes == (DetectedBox((120, 30, 150, 60), "cat", 0.5), DetectedBox((10, 20, 90, 81), "dog", 0.61))
    assert detected_boxes(np.zeros(shape, np.uint8), "none")[0] == ()


def test_the_meant_box_is_the_smallest_whose_cut_holds_the_click():
    big = DetectedBox((0, 0, 100, 100), "dog", 0.9)
    small = DetectedBox((40, 40, 60, 60), "cat", 0.5)
    boxes = (small, big)
    assert meant_box(boxes, (50, 50), lambda box: True) == small
    assert meant_box(boxes, (50, 50), lambda box: box == big.box) == big  # not on the cat's cut
    assert meant_box(boxes, (10, 10), lambda box: True) == big
    assert meant_box(boxes, (150, 10), lambda box: True) is None
    assert meant_box(boxes, (50, 50), lambda box: False) is None


def test_a_click_on_a_detected_animal_starts_from_its_box():
    """The first click on the dog gives the dog's box and that click, exactly, and names
    the detection; the dog is whole, the owner left out."""
    detected, _ = sessions()
    point = inside_point(scene().masks[1])
    box = tight_box(scene().masks[1])
    found = detected.segment([point])
    assert np.array_equal(detected.working_mask([point]), detected.working_mask([point], [], box))
    assert found.details["detection"] == {"class": "dog", "score": 0.8, "box": [float(round(v)) for v in box]}
    assert detected.meant(point).label == "dog"
    dog, owner = scene().masks[1], scene().masks[0]
    assert np.count_nonzero(found.mask & dog) / np.count_nonzero(found.mask | dog) > 0.85
    assert not (found.mask & owner).any()


def test_clicks_off_every_animal_work_as_without_the_detector():
    """On the owner (a person's box starts nothing), on the grass inside the dog's box but
    off its cut, and on the grass outside every box: the masks without the detector."""
    detected, plain = sessions()
    owner_point = inside_point(scene().masks[0])
    x0, y0, x1, y1 = tight_box(scene().masks[1])
    corner = (x0 + 2.5, y1 - 2.5)  # grass in the dog's box, not on the dog
    dog = scene().masks[1]
    assert not dog[int(corner[1]), int(corner[0])]
    for point in (owner_point, corner, (30.5, 480.5)):
        assert detected.meant(point) is None
        assert np.array_equal(detected.working_mask([point]), plain.working_mask([point]))
        try:
            plain.segment([point])
        except JeansError as exc:  # plain grass: nothing found, with the detector too
            with pytest.raises(JeansError, match=str(exc)):
                detected.segment([point])
            continue
        assert "detection" not in detected.segment([point]).details


def test_a_negative_click_beside_the_dog_never_pulls_it_in():
    """A positive click on the owner and a negative one on the grass beside the dog: the
    dog takes no part, and the mask is the one without the detector."""
    detected, plain = sessions()
    dog = scene().masks[1]
    x0, y0, x1, y1 = tight_box(dog)
    beside = (x0 - 20.5, (y0 + y1) / 2)
    positive, negative = [inside_point(scene().masks[0])], [beside]
    mask = detected.segment(positive, negative).mask
    assert np.array_equal(mask, plain.segment(positive, negative).mask)
    assert np.count_nonzero(mask & dog) < 0.01 * np.count_nonzero(dog)


def test_a_later_click_inside_the_box_changes_only_what_lies_near_it():
    """After the first click on the dog, a negative click on the dog's far side: outside
    a quarter of the box's diagonal round it, the mask is the first click's."""
    detected, _ = sessions()
    dog = scene().masks[1]
    first = inside_point(dog)
    x0, y0, x1, y1 = (int(round(v)) for v in tight_box(dog))
    ys, xs = np.nonzero(dog[y0:y1, x0:x1])
    far = (float(xs.max() + x0) - 3.5, float(ys[np.argmax(xs)] + y0) + 0.5)  # the dog's rightmost part
    before = detected.working_mask([first])
    after = detected.working_mask([first], [far])
    changed = before ^ after
    w, h = detected.size
    sx, sy = w / dog.shape[1], h / dog.shape[0]
    reach = 0.25 * np.hypot((x1 - x0) * sx, (y1 - y0) * sy) + 1
    rows, columns = np.nonzero(changed)
    assert changed.any()
    assert np.all(np.hypot(columns - far[0] * sx, rows - far[1] * sy) <= reach)


def test_the_report_names_the_detected_animal_a_click_dressed():
    """The shipped detector sees the drawn dog (a dog, 0.61): a click on it is that
    detection in the object's report entry; a click on the owner names none."""
    from jeanscv import apply_jeans

    image = np.array(scene().image)
    dog = apply_jeans(image, points=[inside_point(scene().masks[1])], iterations=30, starts=2).report("two.png")
    assert dog["objects"][0]["detection"]["class"] == "dog"
    owner = apply_jeans(image, points=[inside_point(scene().masks[0])], iterations=30, starts=2).report("two.png")
    assert "detection" not in owner["objects"][0]
