"""Clicks that fix the subject: the click session on exact synthetic masks, the clicks
file, the API and the command line (``--point``, ``--background-point``, ``--clicks`` and
the clicks saved beside a photo)."""

from __future__ import annotations

import json
import os
from functools import cache

import cv2
import numpy as np
import pytest
from PIL import Image

from jeanscv.api import apply_jeans, extract_silhouettes
from jeanscv.errors import JeansError
from jeanscv.subject.click_masks import depth_in
from jeanscv.subject.clicks import Clicks, ObjectClicks, loads_clicks, read_clicks, sidecar_path, write_clicks
from jeanscv.subject.interactive import ClickSession

FIT = dict(iterations=30, starts=2)
CLI_FIT = ("--iterations", "30", "--starts", "2")
BODY_CLICK, HEAD_CLICK, DISC_CLICK = (90.5, 130.5), (160.5, 130.5), (260.5, 120.5)

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)


@cache
def figure() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 320x240 photo: a red body with a blue head attached, and a green disc apart,
    on grey noise; returns (image, body, head, disc) with the exact masks."""
    rng = np.random.default_rng(0)
    image = np.clip(rng.normal(120, 6, (240, 320, 3)), 0, 255).astype(np.uint8)
    body = np.zeros((240, 320), bool)
    body[80:180, 40:140] = True
    head = np.zeros((240, 320), bool)
    head[100:160, 140:180] = True
    disc = np.zeros((240, 320), np.uint8)
    cv2.circle(disc, (260, 120), 30, 1, -1)
    disc = disc.astype(bool)
    image[body], image[head], image[disc] = (200, 40, 40), (40, 60, 200), (40, 180, 60)
    return image, body, head, disc


def share(mask: np.ndarray, part: np.ndarray) -> float:
    return float((mask & part).sum() / part.sum())


@cache
def session() -> ClickSession:
    return ClickSession(figure()[0])


# ------------------------------------------------------------------ the click session


def test_one_click_takes_the_thing_under_it_only():
    _, body, head, disc = figure()
    mask = session().segment([BODY_CLICK]).mask
    assert share(mask, body) > 0.99 and share(mask, head) > 0.99
    assert share(mask, disc) == 0 and mask.sum() < 1.02 * (body | head).sum()


def test_a_positive_click_on_a_missed_part_adds_it():
    _, body, head, disc = figure()
    mask = session().segment([BODY_CLICK, DISC_CLICK]).mask
    assert share(mask, disc) > 0.98 and share(mask, body) > 0.99 and share(mask, head) > 0.99


def test_a_negative_click_on_a_wrongly_taken_region_removes_it():
    _, body, head, disc = figure()
    mask = session().segment([BODY_CLICK], [HEAD_CLICK]).mask
    assert share(mask, head) < 0.02 and share(mask, body) > 0.99 and share(mask, disc) == 0


def test_every_positive_click_is_in_and_no_negative_one():
    image = figure()[0]
    rng = np.random.default_rng(1)
    checked = 0
    for _ in range(4):
        positive = [tuple(rng.uniform(0, 320, 1).tolist() + rng.uniform(0, 240, 1).tolist()) for _ in range(3)]
        negative = [tuple(rng.uniform(0, 320, 1).tolist() + rng.uniform(0, 240, 1).tolist()) for _ in range(2)]
        try:
            mask = session().segment(positive, negative).mask
        except JeansError as exc:  # all three on plain background: no object there
            assert "nothing clear there" in str(exc)
            continue
        checked += 1
        assert all(mask[int(y), int(x)] for x, y in positive)
        assert not any(mask[int(y), int(x)] for x, y in negative)
        assert image.shape[:2] == mask.shape
    assert checked >= 2


@pytest.mark.fresh_cuts  # two sessions each cutting afresh agree
def test_the_same_clicks_give_the_same_mask():
    image = figure()[0]
    clicks = ([BODY_CLICK, DISC_CLICK], [HEAD_CLICK])
    first = ClickSession(image).segment(*clicks).mask
    again = ClickSession(image).segment(*clicks).mask
    # A session that saw other clicks first gives the same answer (no hidden state).
    warm = session()
    warm.segment([DISC_CLICK], [BODY_CLICK])
    assert np.array_equal(first, again) and np.array_equal(first, warm.segment(*clicks).mask)


@pytest.mark.fresh_cuts  # counts the cuts
def test_auto_and_a_session_cut_the_hypotheses_once_with_the_same_results(monkeypatch):
    from jeanscv.subject import photo

    image = figure()[0]
    alone = photo.segment(image)
    clicks = ([BODY_CLICK, DISC_CLICK], [HEAD_CLICK])
    expected = session().segment(*clicks).mask
    cuts = []
    hypotheses = photo.hypotheses
    monkeypatch.setattr(photo, "hypotheses", lambda *args: cuts.append(1) or hypotheses(*args))
    shared = photo.SharedHypotheses()
    together = photo.segment(image, shared=shared)
    clicked = ClickSession(image, shared=shared).segment(*clicks).mask
    assert len(cuts) == 1
    assert np.array_equal(together.mask, alone.mask) and np.array_equal(together.contour, alone.contour)
    assert json.dumps(together.details) == json.dumps(alone.details)
    assert np.array_equal(clicked, expected)
    # The session first, then auto: still one cut, the same subject.
    shared = photo.SharedHypotheses()
    ClickSession(image, shared=shared)
    assert json.dumps(photo.segment(image, shared=shared).details) == json.dumps(alone.details)
    assert len(cuts) == 2
    # Another photo (here: another working size) is cut anew, not given these.
    smaller = photo.segment(image, working_size=160, shared=shared)
    assert len(cuts) == 3 and json.dumps(smaller.details) == json.dumps(photo.segment(image, working_size=160).details)


def test_session_refuses_clicks_it_cannot_use():
    with pytest.raises(JeansError, match="an object needs a click or a box"):
        session().segment([], [])
    with pytest.raises(JeansError, match=r"click \(320, 5\) is outside the 320x240 image"):
        session().segment([(320, 5)])
    with pytest.raises(JeansError, match="on top of a positive one"):
        session().segment([BODY_CLICK], [(90.9, 130.1)])


# ------------------------------------------------------------------ the clicks file


def test_clicks_file_round_trip(tmp_path):
    clicks = Clicks((ObjectClicks((BODY_CLICK,), (HEAD_CLICK,)), ObjectClicks((DISC_CLICK,))), (320, 240))
    path = tmp_path / "figure.clicks.json"
    write_clicks(path, clicks)
    assert read_clicks(path) == clicks
    data = json.loads(path.read_text())
    assert data == {
        "format": "jeanscv-clicks",
        "version": 1,
        "image": {"width": 320, "height": 240},
        "objects": [
            {"positive": [list(BODY_CLICK)], "negative": [list(HEAD_CLICK)]},
            {"positive": [list(DISC_CLICK)], "negative": []},
        ],
    }
    assert sidecar_path(tmp_path / "cat.photo.jpg") == tmp_path / "cat.photo.clicks.json"


@pytest.mark.parametrize(
    "text, reason",
    [
        ("{not json", "not valid JSON"),
        ("[1, 2]", "not a clicks file"),
        ('{"format": "jeanscv-clicks", "version": 3, "objects": []}', "version 3 is not supported"),
        ('{"format": "jeanscv-clicks", "version": true, "objects": []}', "version True is not supported"),
        ('{"format": "jeanscv-clicks", "version": 1, "objects": [{"box": [1, 2, 30, 40]}]}', "needs a version 2"),
        ('{"format": "jeanscv-clicks", "version": 2, "objects": [{"box": [30, 2, 1, 40]}]}', "x0 < x1"),
        ('{"format": "jeanscv-clicks", "version": 2, "objects": [{"box": [1, 2, 3]}]}', "four numbers"),
        ('{"format": "jeanscv-clicks", "version": 1, "objects": []}', '"objects" must be a non-empty list'),
        ('{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [["a", 1]]}]}', "two numbers"),
        ('{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[1, 2, 3]]}]}', "two numbers"),
        (
            '{"format": "jeanscv-clicks", "version": 2, "objects": [{"negative": []}]}',
            "an object needs a click or a box",
        ),
        (
            '{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[1, 2]], "negative": [[1.5, 2.5]]}]}',
            "on top of a positive one",
        ),
        ('{"format": "jeanscv-clicks", "version": 1, "image": {"width": -3, "height": 2}, "objects": []}', "positive"),
    ],
)
def test_bad_clicks_files_say_why(text, reason):
    with pytest.raises(JeansError, match=reason):
        loads_clicks(text)


def test_clicks_that_do_not_fit_the_image_say_why():
    clicks = Clicks.single([BODY_CLICK], image_size=(640, 480))
    with pytest.raises(JeansError, match="made on a 640x480 image, this one is 320x240"):
        clicks.check((320, 240))
    with pytest.raises(JeansError, match=r"object 2: click \(400, 5\) is outside the 320x240 image"):
        Clicks((ObjectClicks((BODY_CLICK,)), ObjectClicks(((400, 5),)))).check((320, 240))


# ------------------------------------------------------------------ API


def test_extract_silhouettes_one_object_per_click_set():
    image, body, head, disc = figure()
    first, second = extract_silhouettes(
        image, clicks=[{"positive": [BODY_CLICK], "negative": [HEAD_CLICK]}, {"positive": [DISC_CLICK]}]
    )
    assert first.method == second.method == "clicks"
    assert share(first.mask, body) > 0.99 and share(first.mask, head) < 0.02
    assert share(second.mask, disc) > 0.98 and share(second.mask, body) == 0
    assert first.details["clicks"] == {"positive": [list(BODY_CLICK)], "negative": [list(HEAD_CLICK)]}
    (only,) = extract_silhouettes(image, points=[DISC_CLICK])
    assert share(only.mask, disc) > 0.98 and only.details["point"] == list(DISC_CLICK)


def test_apply_jeans_records_the_clicks_in_the_report():
    image, body, head, disc = figure()
    result = apply_jeans(image, points=[DISC_CLICK], **FIT)
    report = result.report()
    assert report["clicks"] == {"objects": [{"positive": [list(DISC_CLICK)], "negative": []}]}
    changed = np.any(result.image != image, axis=-1)
    assert changed[disc].mean() > 0.1 and not changed[body | head].any()


# ------------------------------------------------------------------ command line


@pytest.fixture
def figure_png(tmp_path):
    path = tmp_path / "figure.png"
    Image.fromarray(figure()[0]).save(path)
    return path


def test_cli_points_and_a_clicks_file_written_by_the_api_give_the_same_output(figure_png, run_cli, tmp_path):
    result = run_cli(figure_png, "--point", "90.5,130.5", "--background-point", "160.5,130.5", "--json", "-q", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    output = figure_png.with_name("figure.jeans.png")
    by_points = output.read_bytes()
    report = json.loads(figure_png.with_name("figure.jeans.json").read_text())
    assert report["clicks"] == {"objects": [{"positive": [[90.5, 130.5]], "negative": [[160.5, 130.5]]}]}

    clicks_path = tmp_path / "saved.json"
    write_clicks(clicks_path, Clicks.single([BODY_CLICK], [HEAD_CLICK], image_size=(320, 240)))
    result = run_cli(figure_png, "--clicks", clicks_path, "--json", "-q", "--overwrite", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    assert output.read_bytes() == by_points
    api = apply_jeans(figure_png, clicks=read_clicks(clicks_path), **FIT)
    assert (
        json.loads(figure_png.with_name("figure.jeans.json").read_text())["vertices_image"]
        == (api.report()["vertices_image"])
    )


def test_clicks_saved_beside_a_photo_are_used_and_make_its_output_stale(tmp_path, run_cli):
    folder = tmp_path / "pets"
    folder.mkdir()
    Image.fromarray(figure()[0]).save(folder / "a.png")
    Image.fromarray(figure()[0]).save(folder / "b.png")
    result = run_cli(folder, "--json", "-q", "-j", "1", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    before = {name: (folder / f"{name}.jeans.png").read_bytes() for name in "ab"}
    write_clicks(sidecar_path(folder / "a.png"), Clicks.single([DISC_CLICK], image_size=(320, 240)))
    # The saved clicks are newer than a's output: a is redone, b is skipped.
    stamp = os.stat(folder / "a.jeans.png").st_mtime + 5
    os.utime(sidecar_path(folder / "a.png"), (stamp, stamp))
    result = run_cli(folder, "--json", "-j", "1", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    # a redone, b's output kept; the clicks file is a's, not an input skipped (issue 32).
    assert "1 ok, 0 failed, 1 skipped" in result.stderr
    assert (folder / "b.jeans.png").read_bytes() == before["b"]
    report = json.loads((folder / "a.jeans.json").read_text())
    assert report["clicks"]["objects"][0]["positive"] == [list(DISC_CLICK)]
    _, body, head, disc = figure()
    changed = np.any(np.asarray(Image.open(folder / "a.jeans.png"))[..., :3] != figure()[0], axis=-1)
    assert changed[disc].mean() > 0.1 and not changed[body | head].any()


@pytest.mark.parametrize(
    "content, reason",
    [
        ("{nope", "clicks file figure.clicks.json: clicks file is not valid JSON"),
        ('{"format": "jeanscv-clicks", "version": 9, "objects": []}', "version 9 is not supported"),
        (
            '{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[900, 5]]}]}',
            "click (900, 5) is outside the 320x240 image",
        ),
        (
            '{"format": "jeanscv-clicks", "version": 1, "image": {"width": 100, "height": 100},'
            ' "objects": [{"positive": [[9, 5]]}]}',
            "made on a 100x100 image, this one is 320x240",
        ),
    ],
)
def test_a_bad_saved_clicks_file_fails_that_photo_only(tmp_path, run_cli, content, reason):
    Image.fromarray(figure()[0]).save(tmp_path / "figure.png")
    Image.fromarray(figure()[0]).save(tmp_path / "other.png")
    sidecar_path(tmp_path / "figure.png").write_text(content)
    result = run_cli(tmp_path, "-q", "-j", "1", *CLI_FIT)
    assert result.exit_code == 1
    (line,) = result.stderr.splitlines()
    assert line.startswith(f"jeanscv: {tmp_path / 'figure.png'}: ") and reason in line
    assert not (tmp_path / "figure.jeans.png").exists() and (tmp_path / "other.jeans.png").exists()


def test_cli_click_options_need_one_input(figure_png, run_cli, tmp_path):
    other = tmp_path / "other.png"
    other.write_bytes(figure_png.read_bytes())
    result = run_cli(figure_png, other, "--background-point", "5,5")
    assert result.exit_code == 2 and "--background-point needs exactly one input image" in result.stderr
    result = run_cli(figure_png, other, "--clicks", tmp_path / "x.json")
    assert result.exit_code == 2 and "--clicks needs exactly one input image" in result.stderr
    result = run_cli(figure_png, "--point", "90.5,130.5", "--background-point", "90.5,130.5", *CLI_FIT)
    assert result.exit_code == 1 and "is on top of a positive one" in result.stderr


# ------------------------------------------------------------------ boxes

BODY_BOX = (30.0, 70.0, 150.0, 190.0)  # the body and a few pixels of background round it


def test_a_box_alone_takes_the_object_in_it_and_nothing_outside():
    _, body, head, disc = figure()
    mask = session().segment([], [], BODY_BOX).mask
    assert share(mask, body) > 0.98
    outside = np.ones_like(mask)
    outside[70:190, 30:150] = False
    assert not (mask & outside).any() and share(mask, disc) == 0
    assert mask.sum() < 1.03 * body.sum()  # the grey round it is left out


def test_a_box_keeps_every_piece_in_it_and_its_holes():
    """A box round two apart pieces and a ring: all three are the object (a bicycle's
    wheels, not its largest piece), and the ring's hole, background, stays a hole."""
    image = np.full((160, 240, 3), (90, 140, 90), np.uint8)
    image[40:120, 30:90] = (200, 40, 40)
    image[60:100, 150:210] = (40, 40, 200)
    ring = np.zeros((160, 240), np.uint8)
    cv2.circle(ring, (120, 80), 25, 1, -1)
    cv2.circle(ring, (120, 80), 10, 0, -1)
    image[ring.astype(bool)] = (230, 200, 40)
    expected = ring.astype(bool)
    expected[40:120, 30:90] = expected[60:100, 150:210] = True
    mask = ClickSession(image).segment([], [], (30.0, 40.0, 210.0, 120.0)).mask
    assert np.array_equal(mask, expected)


def test_a_box_with_clicks():
    """With positive clicks the click engine segments and the box clips: the head and
    body as one click takes them, minus what lies outside the box."""
    _, body, head, _ = figure()
    both = (20.0, 60.0, 200.0, 200.0)  # body and head
    whole = session().segment([], [], both).mask
    assert share(whole, body) > 0.98 and share(whole, head) > 0.95
    clicked = session().segment([BODY_CLICK], [], both).mask
    assert np.array_equal(clicked, session().segment([BODY_CLICK]).mask)  # all inside the box
    clipped = session().segment([BODY_CLICK], [], (20.0, 60.0, 150.0, 200.0)).mask
    assert share(clipped, body) > 0.98 and share(clipped, head) <= 0.25 and not clipped[:, 150:].any()
    negative = session().segment([], [HEAD_CLICK], both).mask
    assert share(negative, body) > 0.98 and not negative[130, 160]


def test_a_recut_after_a_box_gives_back_what_a_negative_click_says_is_background():
    """box_recut: a mask that took the object and a strip of the ground beside it, and a
    negative click on the strip: GrabCut on the box re-fits its colours and gives back
    the object exactly, and nothing outside the box."""
    from jeanscv.subject.box_cut import box_recut

    image = np.full((120, 160, 3), (90, 140, 90), np.uint8)
    image[40:90, 50:100] = (200, 40, 40)
    expected = np.zeros((120, 160), bool)
    expected[40:90, 50:100] = True
    previous = expected.copy()
    previous[40:90, 100:115] = True  # the ground beside it, taken
    box = (45, 35, 120, 95)
    recut = box_recut(image, box, previous, [(75, 65)], [(108, 65)], 2)
    assert np.array_equal(recut, expected)
    assert np.array_equal(box_recut(image, box, previous, [], [(108, 65)], 2), expected)
    # Four times the size: the crop (360 pixels) is cut on a 320-pixel copy, the answer
    # brought back to the photo's pixels, still nothing outside the box.
    big = cv2.resize(image, (640, 480), interpolation=cv2.INTER_NEAREST)
    big_expected = cv2.resize(expected.astype(np.uint8), (640, 480), interpolation=cv2.INTER_NEAREST) > 0
    big_previous = cv2.resize(previous.astype(np.uint8), (640, 480), interpolation=cv2.INTER_NEAREST) > 0
    big_box = tuple(4 * v for v in box)
    big_recut = box_recut(big, big_box, big_previous, [(300, 260)], [(432, 260)], 8)
    # The copy's pixels are 1.1 of the photo's: the boundary may move by up to two.
    near_edge = cv2.dilate(big_expected.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    near_edge &= ~cv2.erode(big_expected.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert not ((big_recut ^ big_expected) & ~near_edge).any()
    assert not big_recut[:140].any() and not big_recut[:, 480:].any()


def test_box_score_is_colour_separation_times_the_share_of_the_box_crossed():
    """box_score, exact: a red square on green ground in a box round it. The square
    itself: histograms apart (separation 1), every row and column crossed (reach 1). Its
    left half: separation 1 - sqrt(share of red in the rest of the crop) (the right
    half is red outside the mask), reach 0.5 (half the columns)."""
    from jeanscv.subject.box_cut import box_score

    image = np.full((120, 160, 3), (90, 140, 90), np.uint8)
    image[40:80, 60:100] = (200, 40, 40)
    square = np.zeros((120, 160), bool)
    square[40:80, 60:100] = True
    box = (60, 40, 100, 80)  # the margin: 4 pixels each way, a crop of 48 x 48
    assert box_score(image, square, box) == 1.0
    half = np.zeros_like(square)
    half[40:80, 60:80] = True
    red_outside = 40 * 20 / (48 * 48 - 40 * 20)
    assert box_score(image, half, box) == pytest.approx((1 - np.sqrt(red_outside)) * 0.5, abs=1e-12)
    assert box_score(image, np.zeros_like(square), box) == 0.0


def test_the_core_start_holds_an_ellipse_round_the_boxs_centre():
    """_core_start, exact: box (2, 2, 12, 12) of a 14 x 14 copy, half-axes 0.2 of 10 = 2
    round (7, 7): the 13 pixels of a radius-2 disc held as the object, the rest kept."""
    from jeanscv.subject.box_cut import _core_start

    labels = np.full((14, 14), cv2.GC_BGD, np.uint8)
    labels[2:12, 2:12] = cv2.GC_PR_FGD
    start = _core_start(labels, (2, 2, 12, 12))
    expected = labels.copy()
    for y, x0, x1 in ((5, 7, 8), (6, 6, 9), (7, 5, 10), (8, 6, 9), (9, 7, 8)):
        expected[y, x0:x1] = cv2.GC_FGD
    assert np.array_equal(start, expected)


def test_the_geodesic_start_is_the_distance_from_both_sides_of_the_boxs_edge():
    """_geodesic_start searches within the box from its inner ring only; the reference
    searches the whole crop from the ring on both sides of the box's edge (the two
    pixel-wide band of the earlier version). A path into the box crosses the inner ring,
    so the labels are the same, pixel for pixel."""
    from skimage.graph import MCP_Geometric

    from jeanscv.subject.box_cut import _NEAR_EDGE, _geodesic_start
    from jeanscv.subject.click_parts import gradient_cost

    rng = np.random.default_rng(3)
    small = np.clip(rng.normal(110, 25, (60, 80, 3)), 0, 255).astype(np.uint8)
    small[20:45, 25:60] = (200, 60, 40)
    for box in ((8, 6, 72, 54), (0, 0, 80, 60), (30, 10, 79, 59)):
        x0, y0, x1, y1 = box
        inside = np.zeros((60, 80), bool)
        inside[y0:y1, x0:x1] = True
        labels = np.where(inside, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
        three = np.ones((3, 3), np.uint8)
        grown = cv2.dilate(inside.astype(np.uint8), three).astype(bool)
        shrunk = cv2.erode(inside.astype(np.uint8), three, borderType=cv2.BORDER_CONSTANT, borderValue=0)
        edge = [tuple(p) for p in np.argwhere(grown & ~shrunk.astype(bool))]
        distance = MCP_Geometric(gradient_cost(small)).find_costs(edge)[0]
        expected = labels.copy()
        near = inside & (distance < _NEAR_EDGE * np.percentile(distance[inside], 99))
        expected[near] = cv2.GC_PR_BGD
        assert np.array_equal(_geodesic_start(small, labels, box), expected)


def test_what_a_click_changes_far_from_itself_goes_back_where_it_has_the_other_sides_colours():
    """After a box, a click's step is checked by colour: of what it moved farther from
    the click than the click's depth, what looks like the side it left goes back. Here a
    negative click on a grey strip wrongly taken with two white squares took the strip
    and the far square too (a leak through steps too small to cost): the square, white
    like the object kept, comes back exactly; a grey one, like the strip, stays out."""
    image = np.full((160, 240, 3), 120, np.uint8)
    kept, far, strip = (np.zeros((160, 240), bool) for _ in range(3))
    kept[50:110, 20:80] = True
    far[50:110, 170:230] = True
    strip[60:100, 100:130] = True
    clicks = (("+", (50, 80)), ("-", (115, 80)))
    for colour, comes_back in (((235, 235, 235), True), ((120, 120, 120), False)):
        image[kept] = (235, 235, 235)
        image[far] = colour
        image[strip] = (120, 120, 120)
        session = ClickSession(image)
        previous = kept | far | strip
        keep = [(50, 80), (200, 80)]  # a deepest point of each piece, as after a box
        depth = depth_in(previous, 115, 80)  # the negative click's, in what it corrects
        away = np.hypot(*(session._graph.centre_px - np.array([115, 80])).T)
        checked = session._colour_checked(previous, kept.copy(), clicks, keep, depth, away)
        assert np.array_equal(checked, (kept | far) if comes_back else kept)


def test_colour_density_is_a_weighted_mixture_of_gaussian_kernels():
    from jeanscv.subject.click_parts import colour_density

    samples = np.array([[50.0, 0.0, 0.0], [50.0, 8.0, 0.0]])
    weights = np.array([3.0, 1.0])
    colours = np.array([[50.0, 0.0, 0.0], [50.0, 0.0, 8.0]])
    # The first colour sits on the first sample and 8 (one kernel width) from the second;
    # the second lies 8 from the first and 8 * sqrt(2) from the second.
    expected = [(3 + np.exp(-0.5)) / 4, (3 * np.exp(-0.5) + np.exp(-1.0)) / 4]
    np.testing.assert_allclose(colour_density(colours, samples, weights, 8.0), expected, rtol=1e-12)
    assert np.array_equal(colour_density(colours, samples[:0], weights[:0]), [0.0, 0.0])


def test_a_box_whose_starts_collapse_is_cut_again_from_its_centre(monkeypatch):
    """Where both starts give nothing (two cats in a box of the margin's colours), the
    box is cut again with its centre held as the object: a red square on green ground
    comes back exactly. In a box of plain noise that cut adds only a few pixels to the
    core it was given, so nothing is found there still."""
    import jeanscv.subject.box_cut as box_cut_module

    real_cut = box_cut_module._cut

    def collapsing(small, labels):  # the two starts collapse; the core start cuts
        return real_cut(small, labels) if (labels == cv2.GC_FGD).any() else np.zeros(labels.shape, bool)

    monkeypatch.setattr(box_cut_module, "_cut", collapsing)
    image = np.full((120, 160, 3), (90, 140, 90), np.uint8)
    image[40:80, 60:100] = (200, 40, 40)
    expected = np.zeros((120, 160), bool)
    expected[40:80, 60:100] = True
    assert np.array_equal(box_cut_module.box_cut(image, (56, 36, 104, 84)), expected)
    assert not box_cut_module.box_cut(figure()[0], (200, 200, 240, 238)).any()


def test_a_box_that_holds_nothing_says_so():
    with pytest.raises(JeansError, match="nothing found in that box"):
        session().segment([], [], (200.0, 200.0, 240.0, 238.0))  # grey noise only
    with pytest.raises(JeansError, match=r"click \(90.5, 130.5\) is outside its object's box"):
        Clicks((ObjectClicks((BODY_CLICK,), (), (200, 10, 300, 60)),)).check((320, 240))
    with pytest.raises(JeansError, match="not inside the 320x240 image"):
        Clicks((ObjectClicks((), (), (200, 10, 330, 60)),)).check((320, 240))


def test_boxes_in_the_clicks_file_are_version_2_and_version_1_is_still_read(tmp_path):
    clicks = Clicks((ObjectClicks((), (HEAD_CLICK,), BODY_BOX), ObjectClicks((DISC_CLICK,))), (320, 240))
    path = tmp_path / "figure.clicks.json"
    write_clicks(path, clicks)
    assert read_clicks(path) == clicks
    data = json.loads(path.read_text())
    assert data["version"] == 2 and data["objects"][0] == {
        "positive": [],
        "negative": [list(HEAD_CLICK)],
        "box": list(BODY_BOX),
    }
    old = '{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[90.5, 130.5]]}]}'
    assert loads_clicks(old) == Clicks.single([BODY_CLICK])


def test_extract_silhouettes_and_the_command_line_with_a_box(figure_png, run_cli, tmp_path):
    image, body, _, _ = figure()
    (found,) = extract_silhouettes(image, box=BODY_BOX)
    assert found.method == "clicks" and share(found.mask, body) > 0.98
    assert found.details["clicks"] == {"positive": [], "negative": [], "box": list(BODY_BOX)}
    result = run_cli(figure_png, "--box", "30,70,150,190", "-o", tmp_path, "--json", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    report = json.loads((tmp_path / "figure.jeans.json").read_text())
    api = apply_jeans(str(figure_png), box=BODY_BOX, **FIT).report("figure.png")
    assert report["vertices_image"] == api["vertices_image"]
    other = tmp_path / "other.png"
    other.write_bytes(figure_png.read_bytes())
    refused = run_cli(figure_png, other, "--box", "30,70,150,190")
    assert refused.exit_code == 2 and "--box needs exactly one input image" in refused.stderr
    refused = run_cli(figure_png, "--box", "150,70,30,190")
    assert refused.exit_code == 2 and "X0 < X1" in refused.stderr


def test_a_click_on_plain_background_says_nothing_was_found():
    """It was a one-pixel object, and jeans fitted to it."""
    rng = np.random.default_rng(0)
    noise = np.clip(rng.normal(120, 6, (240, 320, 3)), 0, 255).astype(np.uint8)
    with pytest.raises(JeansError, match="nothing clear there: click inside the subject"):
        ClickSession(noise).segment([(160.5, 120.5)])
    image, _, _, disc = figure()
    with pytest.raises(JeansError, match="nothing clear there"):
        extract_silhouettes(image, points=[(300.5, 220.5)])  # the grey corner
    assert share(session().segment([DISC_CLICK]).mask, disc) > 0.98  # a click on something still takes it


# ------------------------------------------------------------------ negative clicks alone


def test_a_negative_click_alone_takes_that_away_from_the_automatic_subject():
    """The jeans cover the owner and the dog: "automatic, minus this"."""
    _, body, head, disc = figure()
    assert np.array_equal(session().segment([], [HEAD_CLICK]).mask, body)
    assert np.array_equal(session().segment([], [BODY_CLICK]).mask, head)
    untouched = session().segment([], [(300.5, 220.5)]).mask  # off the subject: auto's own
    assert share(untouched, body) == 1 and share(untouched, head) == 1 and share(untouched, disc) == 0
    assert np.count_nonzero(untouched & ~(body | head)) <= 8  # a few pixels of anti-aliased corner
    with pytest.raises(JeansError, match="nothing is left of the automatic subject"):
        session().segment([], [HEAD_CLICK, BODY_CLICK])


def test_negative_clicks_alone_on_the_command_line_and_in_the_clicks_file(figure_png, run_cli, tmp_path):
    _, body, _, _ = figure()
    (found,) = extract_silhouettes(figure()[0], background_points=[HEAD_CLICK])
    assert np.array_equal(found.mask, body) and "point" not in found.details
    result = run_cli(figure_png, "--background-point", "160.5,130.5", "-o", tmp_path, "--json", *CLI_FIT)
    assert result.exit_code == 0, result.stderr
    report = json.loads((tmp_path / "figure.jeans.json").read_text())
    assert report["clicks"]["objects"] == [{"positive": [], "negative": [list(HEAD_CLICK)]}]
    clicks = Clicks((ObjectClicks((), (HEAD_CLICK,)),), (320, 240))
    assert clicks.to_json()["version"] == 2 and loads_clicks(clicks.dumps()) == clicks
    old = '{"format": "jeanscv-clicks", "version": 1, "objects": [{"negative": [[160.5, 130.5]]}]}'
    with pytest.raises(JeansError, match="negative clicks alone need version 2"):
        loads_clicks(old)


# ------------------------------------------------------------------ several objects


def test_clicked_objects_do_not_overlap():
    """A click on the body and, as a second object, one on the head attached to it: each
    click alone takes both, but a pixel belongs to one object."""
    _, body, head, _ = figure()
    assert share(session().segment([HEAD_CLICK]).mask, body) == 1  # alone, the head's click takes the body too
    first, second = extract_silhouettes(figure()[0], clicks=[{"positive": [BODY_CLICK]}, {"positive": [HEAD_CLICK]}])
    assert np.array_equal(first.mask, body) and np.array_equal(second.mask, head)


def test_disjoint_gives_a_shared_pixel_to_the_nearest_seed_and_drops_cut_off_pieces():
    from jeanscv.subject.masks import disjoint

    a = np.zeros((6, 10), bool)
    a[1:5, 0:7] = True
    b = np.zeros((6, 10), bool)
    b[1:5, 3:10] = True
    b[5, 0] = True  # a speck of b's, apart from its seed once the shared pixels are gone
    left, right = disjoint([a, b], [[(1.5, 2.5)], [(8.5, 2.5)]])
    expected_left = np.zeros((6, 10), bool)
    expected_left[1:5, 0:5] = True  # columns 3 and 4 nearer x=1, 5 and 6 nearer x=8
    expected_right = np.zeros((6, 10), bool)
    expected_right[1:5, 5:10] = True
    assert np.array_equal(left, expected_left) and np.array_equal(right, expected_right)
    untouched = np.zeros((6, 10), bool)
    untouched[0, 0] = True
    same = disjoint([untouched, expected_right], [[(0.5, 0.5)], [(8.5, 2.5)]])
    assert same[0] is untouched and same[1] is expected_right


# ------------------------------------------------------------------ size


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


@pytest.mark.parametrize("factor", [0.75, 5])
def test_the_same_photo_at_another_pixel_size_gives_the_same_subject(factor):
    """Small photos are scaled up to the working sizes and big ones averaged down, so a
    click (the automatic subject, a box) takes the same thing at any size: IoU within 0.05
    (issue 31's bar; what is left is the answer resampled to the photo's pixels)."""
    image, body, head, disc = figure()
    size = (round(320 * factor), round(240 * factor))
    other = cv2.resize(image, size, interpolation=cv2.INTER_CUBIC if factor > 1 else cv2.INTER_AREA)
    scaled = {
        name: cv2.resize(part.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST).astype(bool)
        for name, part in (("body", body), ("head", head), ("disc", disc))
    }
    far = ClickSession(other)
    for clicks, parts in (([BODY_CLICK], ("body", "head")), ([DISC_CLICK], ("disc",))):
        here = session().segment(clicks).mask
        there = far.segment([(x * factor, y * factor) for x, y in clicks]).mask
        reference = np.logical_or.reduce([{"body": body, "head": head, "disc": disc}[p] for p in parts])
        scaled_reference = np.logical_or.reduce([scaled[p] for p in parts])
        assert _iou(here, reference) > 0.97 and abs(_iou(there, scaled_reference) - _iou(here, reference)) < 0.05
    automatic = extract_silhouettes(image)[0].mask >= 0.5
    automatic_there = extract_silhouettes(other)[0].mask >= 0.5
    both = body | head
    assert abs(_iou(automatic_there, scaled["body"] | scaled["head"]) - _iou(automatic, both)) < 0.05
    box = (20.0, 60.0, 200.0, 200.0)
    boxed, boxed_there = session().segment([], [], box).mask, far.segment([], [], [v * factor for v in box]).mask
    assert (
        _iou(boxed, both) > 0.95 and abs(_iou(boxed_there, scaled["body"] | scaled["head"]) - _iou(boxed, both)) < 0.05
    )


def test_the_geodesic_grabcut_takes_the_clicked_shape_exactly():
    """Two touching rectangles (red, green) on blue: a click on red alone takes the whole
    red-green shape (nearer the click than the border), a negative click on green leaves
    red alone; both exactly, at the image's size though the cut runs on a 160-px copy."""
    from jeanscv.subject.click_parts import geodesic_grabcut

    image = np.zeros((240, 320, 3), np.uint8)
    image[...] = (40, 60, 200)
    image[60:180, 80:160] = (220, 40, 30)
    image[60:180, 160:240] = (30, 200, 60)
    shape = np.zeros((240, 320), bool)
    shape[60:180, 80:240] = True
    red = np.zeros_like(shape)
    red[60:180, 80:160] = True
    np.testing.assert_array_equal(geodesic_grabcut(image, [(120, 120)]), shape)
    np.testing.assert_array_equal(geodesic_grabcut(image, [(120, 120)], [(200, 120)]), red)


def test_the_first_clicks_region_box_takes_the_object_round_a_part_of_it():
    """The first click's box candidate: the box round a 70x70 part of the 100x100 red
    body, grown 1.5 times about its centre (105x105), holds the body, grey ground and a
    strip of the blue head along its edge. What the box's edge does not reach cheaply is
    the whole body and at most the pixels beside its outline (the 3x3 gradient straddles
    the edge); the grey ground and the head's strip, which the edge reaches for nothing,
    are out."""
    image, body, head, disc = figure()
    part = np.zeros_like(body)
    part[95:165, 55:125] = True
    found = session()._region_box(part)
    beside = cv2.dilate(body.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=2).astype(bool)
    assert found[body].all() and not found[~beside].any()
    assert not found[head & ~beside].any()


# ------------------------------------------------------------------ the hover preview's map


def test_the_first_click_map_shows_what_a_first_click_takes():
    """The page's hover preview: the region the map gives under a point is the first
    click's mask there (as superpixels), and nothing where a click finds nothing."""
    from jeanscv.subject.consensus import iou
    from jeanscv.subject.hover import first_click_map

    image, body, head, disc = figure()
    found = first_click_map(session())
    assert found.labels.shape == body.shape  # 320x240: the working copy is the photo
    for click, part in ((BODY_CLICK, body | head), (DISC_CLICK, disc)):
        x, y = int(click[0]), int(click[1])
        shown = found.mask(found.at(x, y))
        assert iou(shown, session().working_mask([click])) > 0.9
        assert share(shown, part) > 0.97 and np.count_nonzero(shown & ~part) < 0.05 * part.sum()
    assert found.at(300, 220) == -1  # the grey corner: "nothing clear there"
    assert found.mask(-1).sum() == 0
