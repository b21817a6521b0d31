"""Issue 49's page in a real browser (Debian's headless Chromium, as in
``test_serve_browser.py``, whose server, browser and page fixtures these tests share):
long captions fitted as the Meme download draws them, the page saying when one is too
long even so, and a click where nothing is found answered without a failed request in
the browser's console."""

from __future__ import annotations

import json

import numpy as np
import pytest
import test_serve_browser as browser_tests
from PIL import Image
from test_serve import scene
from test_serve_browser import (
    _captions_match_the_download,
    _click_photo,
    _download,
    _drop_photo,
    _element_pixels,
    _wait_for_captions,
)

pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)

# The fixtures of test_serve_browser.py: a server for this module, one Chromium, a fresh page a test.
server, browser, page = browser_tests.server, browser_tests.browser, browser_tests.page

LONG = (
    "when you finally find the perfect pair of jeans but then you realise the dog has been"
    " wearing them all along and honestly they look better on him than they ever did on you"
)


def _bands(rows: np.ndarray) -> list[tuple[int, int]]:
    """``(first, last)`` row of each run of rows with ink: the lines of a caption."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rows.astype(int), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def _fit(page) -> dict:
    return json.loads(page.get_attribute("#captions", "data-fit") or "{}")


def test_a_long_caption_is_fitted_on_more_lines_as_the_download_draws_it(server, page, tmp_path):
    """Issue 49: a long caption was cut to three lines ending in "…", in the preview and
    in the download. Now it takes more lines (and a smaller size where needed): the page
    says how many lines and what size, the downloaded meme has those lines, and each
    caption's box on the screen is the download's within 2 px; no "too long" note."""
    page.goto(server + "/")
    page.wait_for_selector("#garment option", state="attached")
    photo = scene()
    _drop_photo(page, photo.image)
    plain = _element_pixels(page, "#result")
    page.fill("#top", LONG)
    page.fill("#bottom", "wear jeans?")
    _wait_for_captions(page)
    page.wait_for_timeout(200)
    fit = _fit(page)
    assert fit["top"]["lines"] >= 4 and not fit["top"]["cut"], fit  # three lines and "…" before
    assert fit["bottom"] == {"lines": 1, "size": fit["bottom"]["size"], "cut": False}
    assert page.is_hidden("#caption-long")
    drawn, _ = _captions_match_the_download(page, plain, tmp_path)
    # The download holds the lines the page reports, one line apart at the reported size
    # (a line is its font's ascent, descent and outline: 1.0-1.4 times the size).
    lines = _bands(drawn[:250].any(axis=1))
    assert len(lines) == fit["top"]["lines"], lines
    pitch = np.diff([first for first, _ in lines])
    assert np.ptp(pitch) <= 1 and 1.0 <= pitch.mean() / fit["top"]["size"] <= 1.4, (pitch, fit)
    assert len(_bands(drawn[250:].any(axis=1))) == 1
    assert page.problems == []


def test_a_caption_too_long_even_so_is_cut_and_the_page_says_so(server, page, tmp_path):
    """On a small picture (160x100) 200 letters do not fit even at the smallest size:
    the caption is cut as before (three lines, "…"), and the page says so beside the
    caption boxes; a caption that fits takes the note away."""
    page.goto(server + "/")
    page.wait_for_selector("#garment option", state="attached")
    small = np.ascontiguousarray(scene().image[::5, ::5])
    _drop_photo(page, small, "small.png")
    page.fill("#top", (LONG + " " + LONG)[:200])
    _wait_for_captions(page)
    assert _fit(page) == {"top": {"lines": 3, "size": 8, "cut": True}}
    page.wait_for_selector("#caption-long", state="visible")
    assert "top caption is too long" in page.inner_text("#caption-long")
    with Image.open(_download(page, "#dl-meme", tmp_path)) as meme:
        drawn = np.abs(np.asarray(meme.convert("RGB")).astype(int) - small).max(axis=-1) > 60
    assert len(_bands(drawn[:50].any(axis=1))) == 3  # cut to three lines, as the page says
    page.fill("#top", "how would a dog")
    _wait_for_captions(page)
    assert not _fit(page)["top"]["cut"]
    page.wait_for_selector("#caption-long", state="hidden")
    assert page.problems == []


def test_a_click_where_nothing_is_found_logs_nothing_in_the_console(server, page):
    """Issue 49: every "nothing found" click was answered 422, which the browser logs
    as "Failed to load resource". It is a normal answer now: the page says so and takes
    the click back as before, and the console stays empty."""
    page.goto(server + "/")
    page.wait_for_selector("#garment option", state="attached")
    _drop_photo(page, scene().image)
    page.wait_for_timeout(500)  # the hover preview's map, fetched after the jeans appear
    messages, answers = [], []
    page.on("console", lambda message: messages.append(f"{message.type}: {message.text}"))
    page.on("response", lambda response: "/render" in response.url and answers.append(response.status))
    before = page.get_attribute("#result", "src")
    _click_photo(page, 20.5, 20.5)
    page.wait_for_function("() => !document.getElementById('error').hidden", timeout=60_000)
    assert "nothing clear there: click inside the subject" in page.inner_text("#error")
    page.wait_for_timeout(300)
    assert answers == [200]
    assert page.locator("#overlay circle.click").count() == 0 and page.is_disabled("#undo")  # taken back
    assert page.get_attribute("#result", "src") == before
    assert messages == [] and page.problems == []
