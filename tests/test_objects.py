"""Several objects in one photo: splitting, picking a user mask's piece by a point, and
``--objects all`` / ``--point`` end to end (API and CLI). Clicks themselves:
``test_clicks.py``."""

from __future__ import annotations

import json
from functools import cache

import cv2
import numpy as np
import pytest
from PIL import Image

from jeanscv.api import apply_jeans, extract_silhouettes
from jeanscv.errors import JeansError, OptionError
from jeanscv.geometry import mask_box
from jeanscv.paint.compositing import polygon_coverage_patch
from jeanscv.subject.objects import check_point, object_at, split_objects
from testkit.synthetic_photos import iou, two_objects

FIT = dict(iterations=40, starts=4)
CLI_FIT = ("--iterations", "40", "--starts", "4")

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)


@cache
def scene():
    return two_objects()


def inside_point(mask: np.ndarray) -> tuple[float, float]:
    """A pixel centre deep inside ``mask`` (the maximum of its distance transform)."""
    distance = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 5)
    y, x = np.unravel_index(np.argmax(distance), distance.shape)
    return float(x) + 0.5, float(y) + 0.5


def share_on(vertices_image, mask: np.ndarray) -> float:
    """The share of the garment polygon's area (exact coverage) that lies on ``mask``."""
    coverage = polygon_coverage_patch(np.asarray(vertices_image, np.float64), *mask.shape)
    return float((coverage * mask).sum() / coverage.sum())


# ---------------------------------------------------------------------- split_objects


def test_split_two_rectangles_exactly():
    mask = np.zeros((40, 60), bool)
    mask[5:25, 4:20] = True  # 320 px
    mask[10:30, 35:57] = True  # 440 px: the larger one comes first
    objects = split_objects(mask)
    assert [obj.box for obj in objects] == [(35, 10, 22, 20), (4, 5, 16, 20)]
    assert [obj.area for obj in objects] == [440, 320]
    assert np.array_equal(objects[0].mask | objects[1].mask, mask)
    assert not (objects[0].mask & objects[1].mask).any()


def test_split_drops_specks_and_keeps_pieces_that_belong_together():
    mask = np.zeros((400, 600), bool)
    mask[100:300, 50:250] = True  # a body
    mask[300:360, 60:70] = True  # a leg, cut off by a one-pixel gap
    mask[299, 60:70] = False
    mask[150:350, 350:550] = True  # a second object
    mask[20:24, 580:584] = True  # a speck: under 10% of the largest
    objects = split_objects(mask)
    assert len(objects) == 2
    body = objects[0] if objects[0].box[0] < 300 else objects[1]
    assert body.box == (50, 100, 200, 260)  # the leg stayed with its body
    assert not any(obj.mask[20:24, 580:584].any() for obj in objects)


def test_split_at_reduced_size_keeps_every_full_resolution_pixel():
    """A 3000x2000 mask is grouped on a 640-px copy; the objects' pixels are the mask's."""
    mask = np.zeros((2000, 3000), bool)
    cv2.circle(mask.view(np.uint8), (700, 1000), 500, 1, -1)
    cv2.ellipse(mask.view(np.uint8), (2200, 900), (600, 300), 20, 0, 360, 1, -1)
    objects = split_objects(mask)
    assert len(objects) == 2
    union = objects[0].mask | objects[1].mask
    assert np.array_equal(union, mask)
    assert objects[1].box == mask_box(mask[:, :1300]) or objects[0].box == mask_box(mask[:, :1300])


def test_split_empty_mask_is_an_error():
    with pytest.raises(JeansError, match="empty"):
        split_objects(np.zeros((10, 10), bool))


# ------------------------------------------------------------------------- points


def test_object_at_picks_under_near_or_none():
    mask = np.zeros((100, 200), bool)
    mask[20:80, 10:60] = True
    mask[30:70, 120:190] = True
    objects = split_objects(mask)
    left, right = objects  # the left one is larger (3000 px against 2800)
    assert left.box == (10, 20, 50, 60) and right.box == (120, 30, 70, 40)
    assert object_at(objects, (30.5, 50.5)) == 0
    assert object_at(objects, (150, 50)) == 1
    assert object_at(objects, (61.5, 50)) == 0  # a click just off the edge: 2% of 200 = 4 px
    assert object_at(objects, (90, 50)) is None  # between them, far from both
    with pytest.raises(OptionError, match=r"^point \(200, 5\) is outside the 200x100 image$"):
        object_at(objects, (200, 5))


@pytest.mark.parametrize("point", [(-0.5, 3), (3, 100), (float("nan"), 3)])
def test_check_point_rejects_points_off_the_image(point):
    with pytest.raises(OptionError, match="is outside the 200x100 image"):
        check_point(point, (100, 200))


# --------------------------------------------------------------------------- API


def test_extract_silhouettes_one_and_all():
    """Classical finding's objects (the detector is left out: these are drawn shapes)."""
    photo = scene()
    one = extract_silhouettes(photo.image, objects="one", detector="none")
    assert len(one) == 1  # the main subject: both animals, as the segmentation found them
    every = extract_silhouettes(photo.image, objects="all", detector="none")
    assert len(every) == 2
    for silhouette, truth in zip(sorted(every, key=lambda s: s.details["box"][0]), photo.masks):
        assert iou(np.asarray(silhouette.mask, bool), truth) > 0.85
        assert silhouette.canvas.shape == (256, 256)
        x, y, w, h = silhouette.details["box"]
        assert (x, y, w, h) == mask_box(silhouette.mask)


def test_apply_jeans_all_gives_each_object_its_own_garment():
    photo = scene()
    result = apply_jeans(photo.image, objects="all", detector="none", **FIT)
    report = result.report()
    assert len(result.objects) == len(report["objects"]) == 2
    entries = sorted(report["objects"], key=lambda entry: entry["box"][0])
    for entry, own, other in zip(entries, photo.masks, photo.masks[::-1]):
        assert share_on(entry["vertices_image"], own) >= 0.9
        assert share_on(entry["vertices_image"], other) < 1e-6
    # Backward compatible: the top-level fields describe the first object.
    assert report["vertices_image"] == report["objects"][0]["vertices_image"]
    assert report["rules"] == report["objects"][0]["rules"]
    # Both garments were painted on the one output picture.
    changed = np.any(result.image != photo.image, axis=-1)
    for own in photo.masks:
        assert changed[own].mean() > 0.1


@pytest.mark.parametrize("which", [0, 1])
def test_apply_jeans_point_picks_that_object(which):
    photo = scene()
    result = apply_jeans(photo.image, points=[inside_point(photo.masks[which])], **FIT)
    (entry,) = result.report()["objects"]
    assert share_on(entry["vertices_image"], photo.masks[which]) >= 0.9
    assert entry["point"] == list(inside_point(photo.masks[which]))
    changed = np.any(result.image != photo.image, axis=-1)
    assert not changed[photo.masks[1 - which]].any()


def test_with_a_user_mask_a_point_picks_its_piece():
    photo = scene()
    left, right = photo.masks
    first, second = extract_silhouettes(photo.image, mask=left | right, points=[inside_point(right)], objects="all")
    assert first.method == second.method == "mask"
    assert iou(np.asarray(first.mask, bool), right) > 0.95 and first.details["point"] == list(inside_point(right))
    assert iou(np.asarray(second.mask, bool), left) > 0.95
    with pytest.raises(JeansError, match=r"^no object of the mask at point"):
        extract_silhouettes(photo.image, mask=right, points=[inside_point(left)])


def test_a_given_mask_keeps_objects_its_cleaning_would_drop():
    """The mask's cleaning keeps pieces of at least 25% of the largest; with objects="all"
    every object of the user's mask of at least 10% of the largest gets its garment."""
    photo = scene()
    owner = photo.masks[0]
    side = int(np.sqrt(0.15 * owner.sum()))
    mask = owner.copy()
    mask[300 : 300 + side, 600 : 600 + side] = True
    assert len(extract_silhouettes(photo.image, mask=mask)) == 1
    first, second = extract_silhouettes(photo.image, mask=mask, objects="all")
    assert first.method == second.method == "mask"
    assert iou(np.asarray(first.mask, bool), owner) > 0.97
    assert second.details["box"] == [600, 300, side, side]


def test_points_on_the_same_object_give_it_one_garment():
    photo = scene()
    left = photo.masks[0]
    x, y, w, h = mask_box(left)
    points = [inside_point(left), (x + w / 2, y + 4)]  # the torso, and the top of the head
    (silhouette,) = extract_silhouettes(photo.image, points=points)
    assert iou(np.asarray(silhouette.mask, bool), left) > 0.9


def test_unknown_objects_value_is_an_error():
    with pytest.raises(JeansError, match="unknown objects 'some'"):
        extract_silhouettes(scene().image, objects="some")


# --------------------------------------------------------------------------- CLI


@pytest.fixture
def two_png(tmp_path):
    path = tmp_path / "two.png"
    Image.fromarray(scene().image).save(path)
    return path


def test_cli_objects_all(two_png, run_cli):
    result = run_cli(two_png, "--objects", "all", "--detector", "none", "--json", "--svg", "-v", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    report = json.loads(two_png.with_name("two.jeans.json").read_text())
    entries = sorted(report["objects"], key=lambda entry: entry["box"][0])
    assert len(entries) == 2
    for entry, own in zip(entries, scene().masks):
        assert share_on(entry["vertices_image"], own) >= 0.9
        assert set(entry) >= {"box", "method", "vertices_image", "vertices_canvas", "rules"}
    assert "object 1: grabcut, box " in result.stderr and "object 2: grabcut, box " in result.stderr
    svg = two_png.with_name("two.jeans.svg").read_text()
    assert 'id="jeans"' in svg and 'id="jeans-2"' in svg


@pytest.mark.parametrize("which", [0, 1])
def test_cli_point_picks_that_object(two_png, run_cli, which):
    x, y = inside_point(scene().masks[which])
    result = run_cli(two_png, "--point", f"{x:g},{y:g}", "--json", "-q", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    report = json.loads(two_png.with_name("two.jeans.json").read_text())
    (entry,) = report["objects"]
    assert share_on(entry["vertices_image"], scene().masks[which]) >= 0.9
    assert share_on(report["vertices_image"], scene().masks[which]) >= 0.9


def test_cli_point_needs_one_input(two_png, run_cli, tmp_path):
    other = tmp_path / "other.png"
    other.write_bytes(two_png.read_bytes())
    result = run_cli(two_png, other, "--point", "10,10")
    assert result.exit_code == 2 and "--point needs exactly one input image" in result.stderr
    result = run_cli(two_png, "--point", "10,ten")
    assert result.exit_code == 2 and "expected two numbers X,Y" in result.stderr


def test_points_are_pixels_of_the_photo_as_displayed_also_for_half_size_raw():
    from conftest import ROOT

    from jeanscv.api import prepare_input

    sample = ROOT / "sample_images" / "coffee.dng"  # 600x400 as displayed
    with pytest.raises(JeansError, match=r"^click \(600, 10\) is outside the 600x400 image$"):
        prepare_input(sample, raw_half_size=True, points=[(600, 10)])
    silhouettes, kind, pixels, loaded = prepare_input(sample, raw_half_size=True, points=[(300, 200)])
    assert kind == "photo" and pixels.shape == (200, 300, 3) and loaded.original_size == (600, 400)
    assert silhouettes[0].details["point"] == [150.0, 100.0]  # in the decoded pixels, like the report
