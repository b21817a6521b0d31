"""Automatic finding with the detector (jeanscv.subject.detected): which detection is the
subject, how sure, and the cut inside its box; the detector itself is stood in for by
fixed detections, so each case has an exact expected answer."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from jeanscv.detect import Detection, DetectorUnavailable
from jeanscv.errors import JeansError
from jeanscv.options import JeansOptions
from jeanscv.subject import detected
from jeanscv.subject.extraction import extract_silhouettes


def _d(label: str, score: float, box: tuple[float, float, float, float]) -> Detection:
    return Detection(label, 0, score, box)


def test_box_iou_exact():
    assert detected.box_iou((0, 0, 10, 10), (0, 0, 10, 10)) == 1.0
    assert detected.box_iou((0, 0, 10, 10), (5, 0, 15, 10)) == pytest.approx(50 / 150)
    assert detected.box_iou((0, 0, 10, 10), (10, 0, 20, 10)) == 0.0


def test_prominence_is_score_times_root_of_the_box_share_less_where_the_edge_cuts_it():
    edge = detected.EDGE_FACTOR
    assert detected.prominence(_d("cat", 0.8, (25, 25, 75, 75)), (100, 100)) == pytest.approx(0.8 * 0.5)
    # Touching the left and top sides (within 1% of the long side: 2 pixels of 200).
    assert detected.prominence(_d("cat", 0.8, (2, 2, 52, 52)), (100, 200)) == pytest.approx(
        0.8 * 0.5**0.5 * 0.5 * edge**2
    )
    assert detected.prominence(_d("cat", 0.8, (3, 3, 53, 53)), (100, 200)) == pytest.approx(0.8 * 0.5**0.5 * 0.5)
    # A third or a fourth side touched makes a close-up, not a thing cut off further.
    assert detected.prominence(_d("cat", 0.8, (0, 36, 100, 100)), (100, 100)) == pytest.approx(0.8 * 0.8 * edge**2)
    assert detected.prominence(_d("cat", 0.8, (0, 0, 500, 500)), (100, 100)) == pytest.approx(0.8 * edge**2)


def test_an_animal_in_the_frame_wins_over_a_larger_one_the_frame_cuts():
    # The puppy on a light floor (a shared photo, 473x500): a foot and a toy giraffe at the
    # photo's corner were called a dog as sure as the puppy, on a larger box.
    puppy = _d("dog", 0.47, (110.8, 163.0, 266.2, 407.8))
    corner = _d("dog", 0.466, (1.7, 315.5, 331.5, 499.6))
    assert detected.prominence(corner, (500, 473)) / detected.EDGE_FACTOR**2 > detected.prominence(puppy, (500, 473))
    assert detected.wanted([corner, puppy], "auto", (500, 473)) == [puppy, corner]
    # A dog filling the photo stays ahead of a sure cat beside it.
    close_up = _d("dog", 0.6, (0, 0, 473, 500))
    cat = _d("cat", 0.9, (20, 20, 170, 170))
    assert detected.wanted([cat, close_up], "auto", (500, 473)) == [close_up, cat]


def test_the_most_prominent_animal_wins_over_a_surer_small_one_and_people():
    shape = (100, 100)
    person = _d("person", 0.95, (0, 0, 100, 100))
    small_cat = _d("cat", 0.9, (0, 0, 10, 10))  # 0.9 * 0.1
    big_dog = _d("dog", 0.5, (20, 20, 80, 80))  # 0.5 * 0.6
    assert detected.wanted([person, small_cat, big_dog], "auto", shape) == [big_dog, small_cat]
    assert detected.wanted([person, small_cat, big_dog], "animal", shape) == [big_dog, small_cat]
    assert detected.wanted([person, small_cat, big_dog], "person", shape) == [person]
    assert detected.wanted([person, small_cat, big_dog], "object", shape) == []
    # A named class comes before the other animals, however prominent they are.
    assert detected.wanted([person, small_cat, big_dog], "cat", shape) == [small_cat, big_dog]


def test_one_animal_called_two_names_is_one_object():
    cat = _d("cat", 0.56, (2, 0, 439, 296))
    dog = _d("dog", 0.40, (1, 0, 440, 297))
    assert detected.wanted([dog, cat], "auto", (300, 451)) == [cat]


def test_a_person_called_an_animal_on_the_same_box_is_not_an_animal():
    shape = (370, 500)
    # A man asleep: "person 0.47" and "cat 0.38" on one box (IoU 0.97); the real cat's own box.
    man = _d("person", 0.47, (2, 5, 491, 366))
    man_as_cat = _d("cat", 0.38, (4, 15, 493, 367))
    cat = _d("cat", 0.41, (27, 239, 204, 367))
    assert detected.box_iou(man.box, man_as_cat.box) >= detected.SAME_PERSON
    assert detected.animals([man, man_as_cat, cat]) == [cat]
    assert detected.wanted([man, man_as_cat, cat], "auto", shape) == [cat]
    # Without the person, or where the animal is the likelier name, it stays.
    assert detected.wanted([man_as_cat, cat], "auto", shape) == [man_as_cat, cat]
    sure_cat = _d("cat", 0.6, man_as_cat.box)
    assert detected.animals([man, sure_cat, cat]) == [sure_cat, cat]
    # A rider on a horse: their boxes overlap, less than one object's would.
    rider = _d("person", 0.55, (129, 98, 299, 341))
    horse = _d("horse", 0.46, (115, 159, 304, 347))
    assert 0.6 < detected.box_iou(rider.box, horse.box) < detected.SAME_PERSON
    assert detected.animals([rider, horse]) == [horse]


def test_doubts_say_why_a_pick_may_be_wrong():
    shape = (100, 100)
    mask = np.zeros(shape, bool)
    mask[20:80, 20:80] = True
    cat = _d("cat", 0.8, (20, 20, 80, 80))
    assert detected.doubts(cat, [], mask, shape) == []
    assert detected.doubts(cat, [_d("dog", 0.7, (2, 2, 57, 57))], mask, shape) == [
        "two of similar size: a cat and a dog"
    ]
    # The same box cut by the photo's corner is less likely the subject, but as big and
    # as sure: still a rival.
    assert detected.doubts(cat, [_d("dog", 0.7, (0, 0, 55, 55))], mask, shape) == [
        "two of similar size: a cat and a dog"
    ]
    assert detected.doubts(cat, [_d("dog", 0.7, (0, 0, 20, 20))], mask, shape) == []  # far less prominent
    # A box round the cat's (the cat with the armchair it sits in) is no second animal;
    # one inside it (a kitten in the arms the box holds) is.
    assert detected.doubts(cat, [_d("dog", 0.7, (10, 10, 90, 90))], mask, shape) == []
    assert detected.doubts(cat, [_d("dog", 0.7, (30, 30, 80, 80))], mask, shape) == [
        "two of similar size: a cat and a dog"
    ]
    assert detected.doubts(_d("cat", 0.4, cat.box), [], mask, shape) == ["the detector is unsure (cat 0.40)"]
    corner = np.zeros(shape, bool)
    corner[20:40, 20:40] = True
    assert detected.doubts(cat, [], corner, shape) == ["the cut does not fill the cat's box"]
    # The two starts of the cut inside the box disagree: where the cat ends is unsure.
    assert detected.doubts(cat, [], mask, shape, agreement=0.7) == [
        "the cut inside the cat's box is unsure where the cat ends"
    ]
    assert detected.doubts(cat, [], mask, shape, agreement=0.9) == []


def _photo() -> tuple[np.ndarray, np.ndarray]:
    """A dark textured disc (the 'animal') on a light textured floor, and its mask."""
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:240, :320]
    disc = (xx - 200) ** 2 + (yy - 130) ** 2 < 55**2
    pixels = np.where(disc[..., None], (70, 45, 30), (210, 205, 190)).astype(np.int16)
    pixels += rng.integers(-10, 11, pixels.shape)
    return np.clip(pixels, 0, 255).astype(np.uint8), disc


@pytest.fixture
def stand_in(monkeypatch):
    """The detector replaced by a function returning what the test sets."""
    found: list = []

    def detect(pixels):
        return list(found)

    monkeypatch.setattr(detected, "detect", detect)
    return found


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_the_detected_animals_box_is_cut_and_reported(stand_in):
    pixels, disc = _photo()
    stand_in += [_d("person", 0.9, (0, 0, 120, 240)), _d("dog", 0.7, (140, 70, 260, 190))]
    (silhouette,) = extract_silhouettes(pixels)
    assert silhouette.method == "detector"
    assert _iou(silhouette.mask >= 0.5, disc) > 0.95
    assert not (silhouette.mask[:, :140] >= 0.5).any()  # nothing outside the dog's box
    details = silhouette.details
    assert details["detection"] == {"class": "dog", "score": 0.7, "box": [140.0, 70.0, 260.0, 190.0]}
    assert [d["class"] for d in details["detections"]] == ["person", "dog"]
    assert details["kind"] == "animal" and details["uncertain"] is False and details["doubts"] == []


def test_a_rival_animal_about_as_prominent_makes_the_pick_unsure(stand_in):
    pixels, _ = _photo()
    stand_in += [_d("dog", 0.7, (140, 70, 260, 190)), _d("cat", 0.6, (20, 60, 130, 180))]
    (silhouette,) = extract_silhouettes(pixels)
    assert silhouette.details["detection"]["class"] == "dog"
    assert silhouette.details["uncertain"] is True
    assert silhouette.details["doubts"] == ["two of similar size: a dog and a cat"]


def test_with_no_animal_detected_or_detector_none_finding_is_classical(stand_in):
    pixels, disc = _photo()
    stand_in += [_d("person", 0.9, (0, 0, 120, 240))]
    (silhouette,) = extract_silhouettes(pixels)
    assert silhouette.method != "detector" and "detection" not in silhouette.details
    classical = extract_silhouettes(pixels, detector="none")[0]
    np.testing.assert_array_equal(silhouette.mask, classical.mask)
    stand_in[:] = [_d("dog", 0.7, (140, 70, 260, 190))]
    assert extract_silhouettes(pixels, detector="none")[0].method != "detector"
    assert extract_silhouettes(pixels, subject="object")[0].method != "detector"


def test_objects_all_dresses_each_detected_animal_apart(stand_in):
    pixels, disc = _photo()
    yy, xx = np.mgrid[:240, :320]
    second = (xx - 70) ** 2 + (yy - 120) ** 2 < 40**2
    pixels[second] = (40, 60, 90)
    stand_in += [_d("dog", 0.7, (140, 70, 260, 190)), _d("cat", 0.6, (25, 75, 115, 165))]
    found = extract_silhouettes(pixels, objects="all")
    assert [s.details["detection"]["class"] for s in found] == ["dog", "cat"]
    assert _iou(found[0].mask >= 0.5, disc) > 0.95 and _iou(found[1].mask >= 0.5, second) > 0.9
    assert not ((found[0].mask >= 0.5) & (found[1].mask >= 0.5)).any()


def test_a_missing_model_warns_in_one_line_and_finding_goes_on(monkeypatch):
    pixels, _ = _photo()

    def broken(pixels):
        raise DetectorUnavailable("detector model file missing: nanodet.bin")

    monkeypatch.setattr(detected, "detect", broken)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (silhouette,) = extract_silhouettes(pixels)
    assert silhouette.method != "detector"
    assert [str(w.message) for w in caught if w.category is detected.DetectorWarning] == [
        "jeanscv: detector model file missing: nanodet.bin; finding the subject without it"
    ]


def test_options_know_the_detector_and_animal_classes():
    assert JeansOptions(subject="dog", detector="none").subject == "dog"
    with pytest.raises(JeansError, match="unknown detector 'yolo'"):
        JeansOptions(detector="yolo")


def test_the_bundled_cat_is_dressed_as_a_cat_and_the_report_says_so(tmp_path, run_cli, compiled_kernels):
    """The README's first command: the detector's cat, named in the report line and the
    JSON, and no "unsure" note (a newcomer's first sight)."""
    import json

    from conftest import ROOT

    report = tmp_path / "run.jsonl"
    result = run_cli(ROOT / "sample_images" / "cat.jpg", "-o", tmp_path, "--json", "--report", report, "-j", "1")
    assert result.exit_code == 0, result.stderr
    assert "note:" not in result.stderr and "may have the wrong subject" not in result.stderr
    (line,) = [json.loads(x) for x in report.read_text().splitlines()]
    assert line["silhouette_method"] == "detector" and line["detected"].startswith("cat 0.")
    subject = json.loads((tmp_path / "cat.jeans.json").read_text())["subject"]
    assert subject["detection"]["class"] == "cat" and subject["uncertain"] is False
    assert {d["class"] for d in subject["detections"]} <= {"cat", "dog"}


def test_top_auto_names_the_class_only_where_it_is_sure():
    cat = {"class": "cat", "score": 0.56, "box": [2.0, 0.0, 439.0, 296.0]}
    dog_same_box = {"class": "dog", "score": 0.40, "box": [1.0, 0.0, 440.0, 297.0]}
    sure = {"detection": cat, "detections": [cat, dog_same_box]}
    assert detected.sure_class(sure) == "cat"
    assert detected.captions(sure) == ("how would a cat", "wear jeans?")
    flicker = {"detection": cat, "detections": [cat, {**dog_same_box, "score": 0.45}]}  # 0.45 > 0.75 * 0.56
    assert detected.sure_class(flicker) is None
    assert detected.captions(flicker) == ("how would this", "wear jeans?")
    weak = {"detection": {**cat, "score": 0.45}, "detections": []}
    assert detected.sure_class(weak) is None
    elsewhere = {"detection": cat, "detections": [cat, {**dog_same_box, "score": 0.9, "box": [500, 0, 600, 90]}]}
    assert detected.sure_class(elsewhere) == "cat"  # another animal elsewhere is no doubt about the name
    elephant = {"class": "elephant", "score": 0.8, "box": [0, 0, 10, 10]}
    assert detected.captions({"detection": elephant})[0] == "how would an elephant"
    assert detected.captions({}) == ("how would this", "wear jeans?")  # classical finding: no class


def test_clicks_with_objects_all_add_the_other_detected_animals(stand_in):
    """A click on the cat and --objects all: the cat from the click (a click on a detected
    animal starts from its box), then the dog as automatic finding gives it, the
    detector's; not classical finding's pieces."""
    pixels, disc = _photo()
    yy, xx = np.mgrid[:240, :320]
    second = (xx - 70) ** 2 + (yy - 120) ** 2 < 40**2
    pixels[second] = (40, 60, 90)
    stand_in += [_d("dog", 0.7, (140, 70, 260, 190)), _d("cat", 0.6, (25, 75, 115, 165))]
    found = extract_silhouettes(pixels, objects="all", points=[(70.5, 120.5)])
    assert [s.method for s in found] == ["clicks", "detector"]
    assert found[0].details["detection"]["class"] == "cat" and found[1].details["detection"]["class"] == "dog"
    assert _iou(found[0].mask >= 0.5, second) > 0.9 and _iou(found[1].mask >= 0.5, disc) > 0.95
    # The cat clicked again is not added twice.
    assert len(extract_silhouettes(pixels, objects="all", points=[(200.5, 130.5)])) == 2


def test_negative_clicks_alone_edit_the_detectors_subject(stand_in):
    """ "The automatic subject minus this" is the subject found without clicks: the
    detector's dog here, where classical finding alone takes the blue square."""
    pixels, disc = _photo()
    pixels[60:200, 20:110] = (40, 60, 90)
    square = np.zeros(disc.shape, bool)
    square[60:200, 20:110] = True
    stand_in.append(_d("dog", 0.7, (140, 70, 260, 190)))
    (minus,) = extract_silhouettes(pixels, background_points=[(300, 10)])
    assert _iou(minus.mask >= 0.5, disc) > 0.95
    (classical,) = extract_silhouettes(pixels, background_points=[(300, 10)], detector="none")
    assert _iou(classical.mask >= 0.5, square) > 0.95
