"""Tests for jeanscv.subject.photo: exact answers on tiny inputs, then the quality bar
(auto reaches IoU >= 0.9 on every synthetic photo of testkit/synthetic_photos.py)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from jeanscv.errors import JeansError
from jeanscv.subject.photo import Segmentation, clean_mask, segment
from testkit.synthetic_photos import case_names, iou, photo

# ----------------------------------------------------------------------------- helpers


def _two_tone(mask: np.ndarray, inside: int, outside: int) -> np.ndarray:
    """(H, W, 3) uint8: ``inside`` grey on the mask, ``outside`` elsewhere."""
    return np.repeat(np.where(mask, inside, outside).astype(np.uint8)[:, :, None], 3, axis=2)


def _rect_mask(shape, top, left, height, width) -> np.ndarray:
    mask = np.zeros(shape, bool)
    mask[top : top + height, left : left + width] = True
    return mask


def _disc_mask(shape, cy, cx, radius) -> np.ndarray:
    rows, cols = np.mgrid[: shape[0], : shape[1]]
    return (rows + 0.5 - cy) ** 2 + (cols + 0.5 - cx) ** 2 <= radius**2


def _polygon_area(xy: np.ndarray) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


# ----------------------------------------------------------------------------- alpha


def test_alpha_channel_is_the_silhouette_exactly():
    rng = np.random.default_rng(0)
    image = np.zeros((60, 80, 4), np.uint8)
    image[..., :3] = rng.integers(0, 256, (60, 80, 3))  # colour under the alpha is irrelevant
    image[10:40, 20:50, 3] = 255
    image[10:40, 50, 3] = 128  # >= 128 counts as object
    image[10:40, 51, 3] = 127  # < 128 does not
    result = segment(image)  # auto: a meaningful alpha channel wins
    assert isinstance(result, Segmentation)
    assert result.method == "alpha"
    expected = _rect_mask((60, 80), 10, 20, 30, 31)
    np.testing.assert_array_equal(result.mask, expected)
    assert result.mask.dtype == bool and result.mask.shape == (60, 80)
    np.testing.assert_array_equal(segment(image, "alpha").mask, expected)


def test_contour_of_a_rectangle_runs_along_pixel_edges():
    image = np.zeros((60, 80, 4), np.uint8)
    image[10:40, 20:51, 3] = 255  # rows 10..39, columns 20..50
    contour = segment(image, "alpha").contour
    assert contour.dtype == np.float64 and contour.ndim == 2 and contour.shape[1] == 2
    # Pixel (c, r) covers [c, c+1) x [r, r+1): the boundary is x in [20, 51], y in [10, 40],
    # with each corner cut by marching squares (4 x 1/8 pixel).
    np.testing.assert_allclose(contour.min(axis=0), [20.0, 10.0])
    np.testing.assert_allclose(contour.max(axis=0), [51.0, 40.0])
    assert _polygon_area(contour) == pytest.approx(31 * 30 - 0.5)  # positive: clockwise on screen
    assert not np.allclose(contour[0], contour[-1])  # not closed


def test_contour_of_one_pixel_is_the_diamond_through_its_edge_midpoints():
    image = np.full((10, 10, 3), 255, np.uint8)
    mask = np.zeros((10, 10), bool)
    mask[4, 6] = True  # pixel (c=6, r=4): the square [6, 7) x [4, 5), centre (6.5, 4.5)
    result = segment(image, "mask", mask=mask)
    np.testing.assert_array_equal(result.mask, mask)
    points = {tuple(p) for p in np.round(result.contour, 6)}
    assert points == {(6.0, 4.5), (6.5, 4.0), (7.0, 4.5), (6.5, 5.0)}
    assert _polygon_area(result.contour) == pytest.approx(0.5)


def test_alpha_errors():
    opaque = np.dstack([np.zeros((40, 40, 3), np.uint8), np.full((40, 40), 255, np.uint8)])
    with pytest.raises(JeansError, match="fully opaque"):
        segment(opaque, "alpha")
    with pytest.raises(JeansError, match="RGBA"):
        segment(np.zeros((40, 40, 3), np.uint8), "alpha")


# ----------------------------------------------------------------------------- threshold


@pytest.mark.parametrize("inside, outside", [(40, 210), (210, 40)], ids=["dark_on_light", "light_on_dark"])
def test_threshold_value_gives_the_object_either_way(inside, outside):
    truth = _rect_mask((90, 120), 20, 30, 40, 50) | _rect_mask((90, 120), 55, 70, 10, 30)
    result = segment(_two_tone(truth, inside, outside), "threshold", threshold=128)
    np.testing.assert_array_equal(result.mask, truth)
    assert result.method == "threshold"
    assert result.details["threshold"]["polarity"] == ("dark" if inside < outside else "light")


@pytest.mark.parametrize("inside, outside", [(40, 210), (210, 40)], ids=["dark_on_light", "light_on_dark"])
def test_otsu_threshold_gives_the_disc_either_way(inside, outside):
    truth = _disc_mask((120, 160), 60, 70, 30)
    result = segment(_two_tone(truth, inside, outside), "threshold")
    info = result.details["threshold"]
    assert info["polarity"] == ("dark" if inside < outside else "light")
    assert 40 < info["threshold"] <= 210
    np.testing.assert_array_equal(result.mask, truth)


def test_threshold_picks_the_colour_channel_for_an_isoluminant_object():
    truth = _disc_mask((100, 140), 50, 60, 25)
    image = np.zeros((100, 140, 3), np.uint8)
    image[truth] = (200, 60, 60)  # red, grey level 102
    image[~truth] = (40, 145, 40)  # green, grey level 102: grey cannot separate them
    result = segment(image, "threshold")
    assert result.details["threshold"]["channel"] != "grey"
    np.testing.assert_array_equal(result.mask, truth)


def test_threshold_out_of_range_is_rejected():
    image = _two_tone(_rect_mask((40, 40), 10, 10, 20, 20), 0, 255)
    for bad in (-1, 256, float("nan"), "dark"):
        with pytest.raises(JeansError, match="threshold"):
            segment(image, "threshold", threshold=bad)


# ----------------------------------------------------------------------------- cleaning


def test_clean_mask_removes_specks_and_fills_holes_exactly():
    mask = np.zeros((14, 16), bool)
    mask[2:8, 2:8] = True  # main object: 36 pixels (too small for morphology)
    mask[4, 5] = False  # a one-pixel hole
    mask[10:13, 10:13] = True  # 9 pixels = 25% of 36: kept
    mask[1, 13:15] = True  # 2 pixels: a speck, dropped
    mask[12, 1] = True  # 1 pixel: a speck, dropped
    expected = np.zeros((14, 16), bool)
    expected[2:8, 2:8] = True
    expected[10:13, 10:13] = True
    np.testing.assert_array_equal(clean_mask(mask), expected)
    np.testing.assert_array_equal(clean_mask(mask.astype(np.uint8) * 255), expected)  # 0/255 input


def test_clean_mask_fills_holes_only_when_enclosed():
    ring = np.zeros((9, 9), bool)
    ring[1:8, 1:8] = True
    ring[3:6, 3:6] = False  # enclosed: filled
    notch = ring.copy()
    notch[4, 1:3] = False  # now the hollow opens to the outside through row 4: kept open
    full = np.zeros((9, 9), bool)
    full[1:8, 1:8] = True
    np.testing.assert_array_equal(clean_mask(ring), full)
    np.testing.assert_array_equal(clean_mask(notch), notch)


def test_clean_mask_opens_large_masks_scaled_to_the_object():
    mask = _disc_mask((240, 240), 120, 120, 80)  # ~20,000 px: opening radius 1
    spur = np.zeros_like(mask)
    spur[120, 200:235] = True  # a 1-pixel wide line sticking out of the disc
    cleaned = clean_mask(mask | spur)
    assert not cleaned[:, 203:].any()  # the spur is gone (bar the pixel touching the disc)
    assert (cleaned ^ mask).sum() <= 0.002 * mask.sum()  # the disc is (nearly) untouched


def test_clean_mask_errors():
    with pytest.raises(JeansError, match="no object"):
        clean_mask(np.zeros((10, 10), bool))
    with pytest.raises(JeansError, match="2-D"):
        clean_mask(np.zeros((4, 4, 3), bool))


# ----------------------------------------------------------------------------- grabcut


def _two_objects() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    image = np.clip(rng.normal(150, 8, (160, 240, 3)), 0, 255).astype(np.uint8)
    left = _disc_mask((160, 240), 80, 60, 30)
    right = _rect_mask((160, 240), 50, 150, 60, 50)
    image[left] = (200, 40, 40)
    image[right] = (40, 60, 200)
    return image, left, right


def test_grabcut_rect_hint_selects_the_object_in_the_box():
    image, left, right = _two_objects()
    result = segment(image, "grabcut", rect=(140, 40, 70, 80))
    assert result.method == "grabcut"
    assert result.details["grabcut"]["variant"] == "rect"
    assert not (result.mask & left).any()
    assert iou(result.mask, right) >= 0.97
    auto = segment(image, rect=(140, 40, 70, 80))  # auto with a rect means grabcut
    assert auto.method == "grabcut" and iou(auto.mask, right) >= 0.97


def test_grabcut_without_hint_finds_a_coloured_disc():
    truth = _disc_mask((150, 200), 70, 110, 35)
    rng = np.random.default_rng(2)
    image = np.clip(rng.normal(120, 10, (150, 200, 3)), 0, 255).astype(np.uint8)
    image[truth] = np.clip(rng.normal((220, 180, 40), 10, (truth.sum(), 3)), 0, 255).astype(np.uint8)
    result = segment(image, "grabcut")
    assert result.details["grabcut"]["variant"] in ("colour", "texture")
    assert iou(result.mask, truth) >= 0.97


def test_orchard_bouman_splits_five_colour_clusters_apart():
    """Five clusters of four colours each, red 10, 40, 130, 160 and 250 (green and blue
    100 plus a little): all of them are cut at their mean red, 118, into {10, 40} and
    {130, 160, 250}; the wider, {130, 160, 250}, at 180; then {10, 40} and {130, 160},
    as wide as each other, at 25 and 145. Five clusters, the five (which gets which
    label number is the eigenvectors' sign)."""
    import cv2

    from jeanscv.subject.grabcut import orchard_bouman, orchard_bouman_models

    centres = np.array([(10, 100, 100), (40, 100, 100), (130, 100, 100), (160, 100, 100), (250, 100, 100)])
    jitter = np.array([(0, 0, 0), (0, 2, 0), (0, 0, 2), (0, 2, 2)])
    colours = (centres[:, None, :] + jitter[None]).reshape(-1, 3)
    truth = np.repeat(np.arange(5), 4)
    labels = orchard_bouman(colours)
    assert sorted(set(labels)) == [0, 1, 2, 3, 4]
    assert all(len(set(labels[truth == t])) == 1 for t in range(5))
    assert np.array_equal(labels, orchard_bouman(colours[::1]))  # no randomness
    # The models of an image whose object holds those colours and whose ground is one
    # grey: weights 0.2 each and the clusters' means; the ground's single colour is one
    # cluster (nothing left to cut) and its covariance the 0.01 added to the diagonal.
    image = np.full((4, 10, 3), 128, np.uint8)
    image[:2] = colours.reshape(2, 10, 3)
    labels_map = np.full((4, 10), cv2.GC_BGD, np.uint8)
    labels_map[:2] = cv2.GC_PR_FGD
    background, foreground = orchard_bouman_models(image, labels_map)
    assert np.allclose(np.sort(foreground[0, :5]), 0.2)
    means = foreground[0, 5:20].reshape(5, 3)
    assert np.allclose(np.sort(means, axis=0), np.sort(centres + jitter.mean(axis=0), axis=0))
    assert background[0, 0] == 1.0 and np.allclose(background[0, 5:8], 128)
    assert np.allclose(background[0, 20:29].reshape(3, 3), 0.01 * np.eye(3))


def test_rect_must_be_a_box_inside_the_image():
    image, _, _ = _two_objects()
    for bad in ((0, 0, 240, 160), (10, 10, 0, 5), (300, 10, 20, 20), (1, 2, 3)):
        with pytest.raises(JeansError, match="rect"):
            segment(image, "grabcut", rect=bad)


# ----------------------------------------------------------------------------- mask, errors


def test_mask_method_uses_the_given_mask_after_cleaning():
    image = np.full((50, 60, 3), 90, np.uint8)
    given = _rect_mask((50, 60), 5, 5, 20, 30)
    given[10, 10] = False  # a hole, filled by cleaning
    given[45, 55] = True  # a speck, dropped
    result = segment(image, mask=given.astype(np.float32))  # auto + mask means mask
    assert result.method == "mask"
    np.testing.assert_array_equal(result.mask, _rect_mask((50, 60), 5, 5, 20, 30))


def test_user_mask_may_nearly_fill_the_frame_but_not_entirely():
    image = np.full((50, 50, 3), 90, np.uint8)
    nearly = np.ones((50, 50), bool)
    nearly[0, :10] = False  # 99.6% of the frame, touching all four borders
    assert segment(image, "mask", mask=nearly).mask.sum() == 2490
    with pytest.raises(JeansError, match="fills the whole frame"):
        segment(image, "mask", mask=np.ones((50, 50), bool))
    with pytest.raises(JeansError, match="does not match"):
        segment(image, "mask", mask=np.ones((10, 50), bool))
    with pytest.raises(JeansError, match="needs a mask"):
        segment(image, "mask")


@pytest.mark.parametrize("method", ["auto", "threshold", "grabcut"])
def test_one_colour_image_has_no_object(method):
    with pytest.raises(JeansError, match="no object found to segment"):
        segment(np.full((120, 160, 3), (30, 120, 200), np.uint8), method)


def test_tiny_object_is_no_object():
    truth = _rect_mask((200, 200), 100, 100, 5, 5)  # 0.06% of the image
    with pytest.raises(JeansError, match="no object found"):
        segment(_two_tone(truth, 0, 255), "threshold", threshold=128)


@pytest.mark.parametrize(
    "image, message",
    [
        (np.zeros((40, 40), np.uint8), "H x W x 3"),
        (np.zeros((40, 40, 2), np.uint8), "H x W x 3"),
        (np.zeros((40, 40, 3), np.float32), "uint8"),
        (np.zeros((4, 40, 3), np.uint8), "too small"),
        ([[0, 1], [2, 3]], "numpy array"),
    ],
)
def test_bad_images_raise_jeans_error(image, message):
    with pytest.raises(JeansError, match=message):
        segment(image)


def test_bad_method_and_working_size():
    image = _two_tone(_rect_mask((40, 40), 10, 10, 20, 20), 0, 255)
    with pytest.raises(JeansError, match="unknown segmentation method"):
        segment(image, "magic")
    with pytest.raises(JeansError, match="working_size"):
        segment(image, working_size=8)


# ----------------------------------------------------------------------------- resolution


def test_large_image_is_segmented_at_working_size_and_upsampled():
    truth = _disc_mask((1500, 2000), 700, 1100, 400)
    result = segment(_two_tone(truth, 30, 220), "threshold", working_size=256)
    assert result.details["working_shape"] == (192, 256)
    assert result.mask.shape == (1500, 2000)
    # The working mask is exact at 256 px; upsampling its steps (7.8 px each) costs
    # 0.75% of IoU on this disc, the bound for any method at this working size.
    assert iou(result.mask, truth) >= 0.99
    # The contour is in full-resolution pixels and encloses the mask's area.
    np.testing.assert_allclose(result.contour.min(axis=0), [700, 300], atol=8)
    np.testing.assert_allclose(result.contour.max(axis=0), [1500, 1100], atol=8)
    assert _polygon_area(result.contour) == pytest.approx(result.mask.sum(), rel=0.01)


def test_given_silhouettes_keep_their_full_resolution_edges():
    truth = _disc_mask((1200, 1600), 600, 700, 350) | _rect_mask((1200, 1600), 300, 1000, 300, 301)
    rgba = np.dstack([np.full((1200, 1600, 3), 80, np.uint8), truth.astype(np.uint8) * 255])
    result = segment(rgba, working_size=200)  # 8 px per working pixel
    assert result.method == "alpha" and result.details["working_shape"] == (150, 200)
    # Cleaned at 200 px, but along the boundary the full-resolution alpha decides.
    np.testing.assert_array_equal(result.mask, truth)
    np.testing.assert_array_equal(segment(rgba[..., :3], mask=truth, working_size=200).mask, truth)


def test_details_are_json_serialisable():
    image, _, _ = _two_objects()
    json.dumps(segment(image).details)
    json.dumps(segment(image, "grabcut").details)


# ----------------------------------------------------------------------------- quality


@pytest.fixture(scope="module")
def auto_results() -> dict[str, tuple[float, str, float]]:
    """name -> (IoU, method chosen, milliseconds) of segment(image, "auto") per photo."""
    results = {}
    for name in case_names():
        case = photo(name)
        if case is None:
            continue
        start = time.perf_counter()
        result = segment(case.image)
        elapsed = 1000 * (time.perf_counter() - start)
        results[name] = (iou(result.mask, case.mask), result.method, elapsed)
    return results


@pytest.mark.parametrize("name", case_names())
def test_auto_reaches_iou_090_on_synthetic_photo(name, auto_results):
    if name not in auto_results:
        pytest.skip(f"{name}: its silhouette or texture is not available here")
    score, method, _ = auto_results[name]
    assert score >= 0.90, f"{name}: IoU {score:.3f} with {method}"


def test_auto_quality_over_the_whole_set(auto_results):
    assert len(auto_results) >= 12  # 16 cases, 4 of them need /work/shared/silhouettes
    scores = np.array([score for score, _, _ in auto_results.values()])
    assert scores.mean() >= 0.94
    methods = {method for _, method, _ in auto_results.values()}
    assert methods == {"threshold", "grabcut"}  # the set exercises both candidates


def test_rim_fraction_counts_pixels_in_the_border_band():
    """On a 20x30 mask the rim is 2 px wide (10% of the short side): of a 4x4 square in
    the corner, all but the inner 2x2 block lies on it."""
    from jeanscv.subject.masks import rim_fraction

    mask = np.zeros((20, 30), bool)
    mask[0:4, 0:4] = True  # corner square: rows/cols 0-1 are on the rim
    assert rim_fraction(mask) == (16 - 4) / 16
    mask[:] = False
    mask[8:12, 10:20] = True  # well inside
    assert rim_fraction(mask) == 0.0
    assert rim_fraction(np.zeros((20, 30), bool)) == 0.0


def test_side_contact_is_the_largest_share_of_one_side():
    """Top, left and right count, each as a share of its own length; the bottom not."""
    from jeanscv.subject.consensus import side_contact

    mask = np.zeros((10, 20), bool)
    mask[0:5, 0] = True  # half the left side
    mask[0, 0:4] = True  # a fifth of the top
    assert side_contact(mask) == 0.5
    mask[:] = False
    mask[-1, 1:-1] = True  # standing on the bottom is no contact
    assert side_contact(mask) == 0.0


def test_horizon_band_spans_left_to_right_off_the_bottom():
    from jeanscv.subject.consensus import spans_width

    band = np.zeros((20, 40), bool)
    band[5:9, :] = True  # a tree line across the frame
    assert spans_width(band)
    close_up = band.copy()
    close_up[9:, 5:35] = True  # a subject as wide as the frame stands on the bottom
    assert not spans_width(close_up)
    band[:, 30:] = False  # it ends before the right side: touches only the left
    assert not spans_width(band)


def test_a_pick_the_other_hypotheses_disagree_with_is_uncertain():
    from jeanscv.subject.consensus import UNCERTAIN_CONSENSUS, choose

    left = np.zeros((20, 40), bool)
    left[5:15, 2:12] = True
    right = np.zeros((20, 40), bool)
    right[5:15, 28:38] = True
    both = {"contrast": 1.0, "agreement": 1.0}
    _, ranked = choose({"left": left, "right": right}, lambda _: both)
    assert ranked[0].consensus == 0.0 and ranked[0].uncertain
    shifted = np.roll(left, 1, axis=1)  # IoU 90/110 with left
    _, ranked = choose({"left": left, "shifted": shifted}, lambda _: both)
    assert ranked[0].consensus == 90 / 110 > UNCERTAIN_CONSENSUS and not ranked[0].uncertain


def test_horizon_bands_are_out_of_the_running_unless_all_are_bands():
    """Two hypotheses taking the same band outvote a third by consensus alone; as bands
    they are left out, and the subject wins; with no subject found, a band still wins."""
    from jeanscv.subject.consensus import choose

    band = np.zeros((20, 40), bool)
    band[5:9, :] = True
    band_too = band.copy()
    band_too[9, :] = True
    subject = np.zeros((20, 40), bool)
    subject[10:16, 15:25] = True
    winner, ranked = choose(
        {"a": band, "b": band_too, "subject": subject}, lambda _: {"contrast": 1.0, "agreement": 1.0}
    )
    assert winner == "subject"
    assert [c.band for c in ranked] == [False, True, True]
    assert ranked[0].consensus == 1.0 and ranked[1].score == 0.0
    winner, ranked = choose({"a": band, "b": band_too}, lambda _: {"contrast": 1.0, "agreement": 1.0})
    assert not any(c.band for c in ranked) and ranked[0].consensus == 0.8  # IoU of 4 rows with 5
