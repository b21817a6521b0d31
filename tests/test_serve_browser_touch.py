"""Issue 49's page finished for touch and for folders, in a real browser (Debian's
headless Chromium, as in ``test_serve_browser.py``, whose server, browser and page
fixtures these tests share): a box drawn with one finger in Box mode (a pinch still
zooms), the phone page worded for fingers, the mode and the zoom buttons off the photo
(its corners and captions clickable, no jump when the panel appears, the Find list not
cut), and folder mode marking unsure photos as their answers come, with the open photo
clear.

With ``JEANSCV_PHONE_PNG=PATH`` the Box test saves the phone page there, and with
``JEANSCV_FOLDER_PNG=PATH`` the folder test its page (``docs/serve-phone.png`` and
``docs/serve-folder.png`` are made so)."""

from __future__ import annotations

import io
import json
import os
import urllib.request

import numpy as np
import pytest
import test_serve_browser as browser_tests
from PIL import Image
from test_objects import share_on
from test_serve import scene
from test_serve_browser import (
    HOLD_ANSWERS,
    _drop_photo,
    _pinch,
    _point_at,
    _scene_with_renders,
    _serving,
    _wait_for_captions,
    _wait_for_result,
    _wait_until,
)

from testkit.synthetic_photos import photo as synthetic_photo
from testkit.synthetic_photos import two_objects

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)

# The fixtures of test_serve_browser.py: a server for this module, one Chromium, a fresh page a test.
server, browser, page = browser_tests.server, browser_tests.browser, browser_tests.page

PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}


@pytest.fixture
def phone(browser):
    """A fresh page on a 390x844 touch phone whose uncaught exceptions fail the test."""
    context = browser.new_context(**PHONE)
    page = context.new_page()
    page.problems = []
    page.on("pageerror", lambda error: page.problems.append(str(error)))
    try:
        yield page
    finally:
        context.close()


def _save_png(page, path: str, **options) -> None:
    """The page's screenshot as a PNG of at most 256 colours (the docs' pictures, < 150 KB)."""
    with Image.open(io.BytesIO(page.screenshot(type="png", **options))) as shot:
        shot.convert("RGB").quantize(192, dither=Image.Dither.NONE).save(path, optimize=True)


def _touch(page):
    """One finger on the screen, moved and lifted (Chromium's own touch events, through the
    DevTools protocol): ``down(x, y)``, ``move(x, y)``, ``up()``."""
    session = page.context.new_cdp_session(page)

    def send(kind: str, points: list) -> None:
        session.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})

    class Finger:
        def down(self, x, y):
            send("touchStart", [{"x": x, "y": y, "id": 0}])

        def move(self, x, y):
            send("touchMove", [{"x": x, "y": y, "id": 0}])

        def up(self):
            send("touchEnd", [])
            session.detach()

    return Finger()


def _rects_meet(a: dict, b: dict) -> bool:
    return (
        a["x"] < b["x"] + b["width"]
        and b["x"] < a["x"] + a["width"]
        and a["y"] < b["y"] + b["height"]
        and (b["y"] < a["y"] + a["height"])
    )


def _controls_off_the_photo(page) -> None:
    shown = page.locator("#result").bounding_box()
    for control in ("#mode-badge", "#zoom-in", "#zoom-out"):
        assert not _rects_meet(page.locator(control).bounding_box(), shown), f"{control} lies on the photo"


def test_a_box_drawn_with_one_finger_in_box_mode(server, phone):
    """Issue 49: a box could not be drawn by touch at all (a finger's drag scrolled). In
    Box mode one finger draws it, as it goes; let go, the jeans are on what it holds
    (the owner, where automatic finding dressed the dog); two fingers still zoom and
    draw no box."""
    page = phone
    photo, bodies, answers = _scene_with_renders(page, server)
    assert page.locator("#bar-box").count() == 1, "no Box mode"
    page.tap("#bar-box")
    assert page.inner_text("#mode-badge") == "\u25ad Box" and page.get_attribute("#bar-box", "aria-pressed") == "true"
    assert page.get_attribute("#mode-box", "aria-pressed") == "true"
    _controls_off_the_photo(page)

    rows, cols = np.nonzero(photo.masks[0])  # the owner
    x0, y0, x1, y1 = cols.min() - 8, rows.min() - 8, cols.max() + 8, rows.max() + 8
    finger = _touch(page)
    finger.down(*_point_at(page, x0, y0))
    for step in range(1, 9):
        finger.move(*_point_at(page, x0 + (x1 - x0) * step / 8, y0 + (y1 - y0) * step / 8))
    assert page.locator("#overlay rect.box.draft").count() == 1  # drawn as it is dragged
    finger.up()
    page.wait_for_function("() => document.getElementById('status').textContent.includes('from your clicks')")
    assert page.locator("#overlay rect.box").count() == 1 and page.locator("#overlay circle.click").count() == 0
    sent = bodies[-1]["objects"]
    assert len(sent) == 1 and sent[0]["positive"] == [] and sent[0]["negative"] == []
    assert np.allclose(sent[0]["box"], [x0, y0, x1, y1], atol=3), sent  # a screen pixel is 2 of the photo's
    _wait_until(page, lambda: len(answers) == len(bodies), 60, "no answer to the box")
    jeans = answers[-1]["objects"][0]["jeans"]
    assert share_on(jeans, photo.masks[0]) > 0.7 and share_on(jeans, photo.masks[1]) < 0.02  # on the owner
    if os.environ.get("JEANSCV_PHONE_PNG"):  # docs/serve-phone.png
        page.wait_for_function("() => !document.getElementById('status').classList.contains('busy')")
        _save_png(page, os.environ["JEANSCV_PHONE_PNG"])

    renders = len(bodies)
    frame = page.locator("#zoom").bounding_box()
    _pinch(page, (frame["x"] + frame["width"] / 2, frame["y"] + frame["height"] / 2), 60, 180)
    page.wait_for_function("() => Number(document.getElementById('zoom').dataset.zoom) > 2")
    page.wait_for_timeout(300)
    assert len(bodies) == renders and page.locator("#overlay rect.box").count() == 1  # a pinch draws no box
    assert page.locator("#overlay rect.box.draft").count() == 0
    page.tap("#bar-add")  # one finger scrolls again
    assert page.get_attribute("#bar-box", "aria-pressed") == "false" and "boxing" not in page.get_attribute(
        "#zoom", "class"
    )
    assert page.problems == []


def test_the_phone_page_speaks_of_fingers(server, phone, page):
    """Issue 49: the phone page said "click", "drag a box", "Shift-click" and listed the
    keys, though a finger's drag drew no box. On a touch screen it says "tap", a drag in
    Box mode, and lists no keys (the desktop's page still does); a tap where nothing is
    found says to tap inside the subject."""
    phone.goto(server + "/")
    phone.wait_for_selector("#garment option", state="attached")
    assert "Tap to choose a photo" in phone.inner_text("body") and "Drop" not in phone.inner_text("body")
    photo = scene()
    _drop_photo(phone, photo.image)
    text = phone.inner_text("body")
    words = [word for word in ("click ", "Click ", "Shift", "Ctrl", "Keys:") if word in text]
    assert words == [], words
    unclicked = text.replace("clicks", "").replace("Clicks", "")  # the noun (the clicks file) stays
    assert "click" not in unclicked.lower(), text
    assert phone.evaluate("() => [...document.querySelectorAll('kbd, .key')].every((k) => !k.checkVisibility())")
    assert "Tap the thing to dress" in phone.inner_text("#panel")
    assert "Box: drag a box around it with one finger" in phone.inner_text("#panel")  # a drag only in Box mode
    assert phone.is_visible("#mode-box") and phone.is_visible("#bar-box")
    assert "wrong thing? tap the one that should wear them" in phone.inner_text("#status").lower()
    phone.touchscreen.tap(*_point_at(phone, 20.5, 20.5))  # plain background
    phone.wait_for_function("() => !document.getElementById('error').hidden", timeout=60_000)
    assert "nothing clear there: tap inside the subject" in phone.inner_text("#error")

    page.goto(server + "/")  # a desktop's page: the keys and the mouse's words
    page.wait_for_selector("#garment option", state="attached")
    # (The panel waits for a photo: whether each is shown for this screen, by its own style.)
    shown = (
        "(s) => { const e = document.querySelector(s); return Boolean(e) && getComputedStyle(e).display !== 'none'; }"
    )
    assert page.evaluate(shown, ".hint.keys") and page.evaluate(shown, ".hint.for-pointer")
    assert not page.evaluate(shown, "#mode-box") and not page.evaluate(shown, ".hint.for-touch")
    assert phone.problems == [] and page.problems == []


def test_the_controls_leave_the_photo_clear(server, page):
    """Issue 49: the "+ Add" badge and the zoom buttons sat on the photo's corners, over
    the captions, and the buttons took the clicks there; the photo jumped left when the
    panel appeared; the Find list's text was cut. Now every corner and caption of the
    photo is the photo's (a click there lands), the photo stays where it was first shown,
    and the Find list shows its whole choice."""
    page.add_init_script(HOLD_ANSWERS)
    page.goto(server + "/")
    page.wait_for_selector("#garment option", state="attached")
    page.evaluate("() => { window.__hold = true; }")
    _drop_photo(page, scene().image, wait=False)
    page.wait_for_function(
        "() => !document.getElementById('view').hidden && document.getElementById('result').complete"
    )
    page.wait_for_function("() => window.__held.some((h) => h.url.endsWith('/api/photos'))", timeout=60_000)
    before = page.locator("#result").bounding_box()  # shown at once, veiled, the panel not yet there
    page.evaluate(
        "() => { window.__hold = false; for (const h of window.__held) if (!h.gone) { h.gone = true; h.go(); } }"
    )
    _wait_for_result(page, "pets.png")
    page.wait_for_timeout(300)
    after = page.locator("#result").bounding_box()
    assert page.is_visible("#panel")

    page.fill("#top", "how would a dog")
    page.fill("#bottom", "wear jeans?")
    _wait_for_captions(page)
    box = page.locator("#result").bounding_box()
    inset = 16  # inside where the zoom buttons and the badge were (6-41 px from the corners)
    spots = {
        "top left": (box["x"] + inset, box["y"] + inset),
        "top right": (box["x"] + box["width"] - inset, box["y"] + inset),
        "bottom left": (box["x"] + inset, box["y"] + box["height"] - inset),
        "bottom right": (box["x"] + box["width"] - inset, box["y"] + box["height"] - inset),
        "top caption": (box["x"] + box["width"] / 2, box["y"] + box["height"] * 0.06),
        "bottom caption": (box["x"] + box["width"] / 2, box["y"] + box["height"] * 0.94),
    }
    for where, (x, y) in spots.items():
        hit = page.evaluate(
            "([x, y]) => { const e = document.elementFromPoint(x, y); return e && e.closest('#frame') ? '' : e.outerHTML; }",
            [x, y],
        )
        assert hit == "", f"the photo's {where} is covered by {hit[:80]}"
    _controls_off_the_photo(page)  # nor seen over it (the badge let clicks through, but hid the caption)
    # A click on the top right corner lands on the photo (it was the zoom button's).
    bodies = []
    page.on("request", lambda r: r.url.endswith("/render") and bodies.append(json.loads(r.post_data)))
    page.mouse.click(*spots["top right"])
    _wait_until(page, lambda: bodies, 10, "the click on the photo's corner made no render")
    point = (bodies[0]["objects"][0]["positive"] or bodies[0]["objects"][0]["negative"])[0]
    assert point[0] > 800 - 2 * inset * 800 / box["width"] and point[1] < 2 * inset * 800 / box["width"], point
    page.wait_for_function("() => !document.getElementById('status').classList.contains('busy')", timeout=60_000)

    # The Find list as wide as its choice needs (the text measured in the list's own font).
    room = page.evaluate(
        """() => {
            const select = document.getElementById('subject');
            const style = getComputedStyle(select);
            const context = document.createElement('canvas').getContext('2d');
            context.font = `${style.fontWeight} ${style.fontSize} ${style.fontFamily}`;
            const needed = context.measureText(select.selectedOptions[0].text).width;
            const inside = select.clientWidth - parseFloat(style.paddingLeft) - parseFloat(style.paddingRight) - 20;
            return inside - needed;
        }"""
    )
    assert room >= 0, f"the Find list cuts its text by {-room:.0f} px"
    # Where the photo was shown at once, it stays when the panel appears beside it.
    assert abs(after["x"] - before["x"]) <= 1 and abs(after["width"] - before["width"]) <= 1, (before, after)
    assert page.problems == []


def _folder_photo(name: str) -> np.ndarray:
    case = synthetic_photo(name)
    if case is None:
        pytest.skip(f"the synthetic photo {name} needs textures not available here")
    image = case.image
    return np.ascontiguousarray(image[::2, ::2] if image.shape[1] > 500 else image)


def test_folder_marks_unsure_photos_as_their_answers_come(browser, tmp_path):
    """Issue 49: the "? unsure" marks, the count of unsure photos and the unsure-first
    order of "needs a look" came only with a reload, though the server knew. They follow
    each thumbnail's answer now. A photo dropped on the folder page replaced the open
    folder photo while its tile stayed highlighted: no tile is marked open then, and the
    line above the photo says it is only tried. The drop zone for such a photo is a strip,
    not half the page. (a.png, an animal on grass, is sure; b.png, a horse on bricks, is
    unsure: the server's listing is checked to say so.)"""
    photos = tmp_path / "photos"
    photos.mkdir()
    Image.fromarray(_folder_photo("animal_on_grass")).save(photos / "a.png")
    Image.fromarray(_folder_photo("horse_on_brick")).save(photos / "b.png")
    context = browser.new_context(viewport={"width": 1280, "height": 860})
    try:
        with _serving({"folder": photos}) as (server, _):
            page = context.new_page()
            problems = []
            page.on("pageerror", lambda error: problems.append(str(error)))
            loads = []
            page.on("load", lambda _: loads.append(1))
            page.goto(server + "/")
            page.wait_for_selector(".tile")
            page.select_option("#folder-filter", "look")
            drop = page.locator("#drop").bounding_box()
            assert page.locator(".tile .unsure").count() == 0  # nothing known yet
            names = (
                "() => [...document.querySelectorAll('.tile:not([hidden]) .name')].map((n) => n.firstChild.textContent)"
            )
            # As the thumbnails come, without a reload.
            page.wait_for_function("() => document.querySelectorAll('.tile img.thumb').length === 2", timeout=120_000)
            with urllib.request.urlopen(server + "/api/folder") as answer:
                listing = {item["name"]: item["uncertain"] for item in json.load(answer)["items"]}
            assert listing == {"a.png": False, "b.png": True}, listing  # the photos this test needs
            page.wait_for_function(
                "() => document.getElementById('folder-counts').textContent.includes('(1 unsure)')", timeout=5_000
            )
            assert page.inner_text("#folder-counts") == "2 photos: 0 fixed with clicks, 2 left (1 unsure)."
            assert page.evaluate(names) == ["b.png", "a.png"]  # the unsure one first
            assert page.locator('.tile[data-item="1"] .unsure').count() == 1
            assert page.locator('.tile[data-item="0"] .unsure').count() == 0
            assert len(loads) == 1
            assert drop["height"] < 150, drop  # a strip under the gallery (55% of the window before)

            page.locator(".tile").first.click()  # b.png, first in this order
            _wait_for_result(page, "b.png")
            assert page.evaluate("() => [...document.querySelectorAll('.tile.open')].map((t) => t.dataset.item)") == [
                "1"
            ]
            assert page.get_attribute('.tile[data-item="1"]', "aria-current") == "true"
            assert page.inner_text("#open-note").startswith("Open: b.png, from the folder")
            if os.environ.get("JEANSCV_FOLDER_PNG"):  # docs/serve-folder.png
                page.wait_for_timeout(800)  # the smooth scroll to the photo, over
                page.evaluate("() => window.scrollTo({ top: 0, behavior: 'instant' })")
                _save_png(page, os.environ["JEANSCV_FOLDER_PNG"])

            _drop_photo(page, two_objects(width=400, height=250).image, "tried.png")
            assert page.locator(".tile.open").count() == 0 and page.locator(".tile[aria-current]").count() == 0
            assert page.inner_text("#open-note").startswith("tried.png is only tried: it is not in the folder")
            assert page.is_hidden("#save")
            page.click("#another")
            assert page.is_hidden("#open-note") and page.locator("#drop").bounding_box()["height"] < 150
            assert len(loads) == 1 and problems == []
    finally:
        context.close()
