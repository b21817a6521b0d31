"""``jeanscv serve`` stops the clips nobody waits for (issue 48): a client that leaves
while its clip is made stops the making at the next frame, and abandoned clips never
hold up a photo (clips have their own worker and queue). On a real uvicorn server in a
thread, with the command's own HTTP protocol, since only a real connection can close."""

from __future__ import annotations

import json
import socket
import time

import pytest
from test_serve import png_bytes
from test_serve_clips import walking

from bench.serve_client import request, upload
from jeanscv.io.clip import clip_bytes

pytest.importorskip("uvicorn")


#: Seconds each frame of the clips made here is held up: far longer than the server takes
#: to hear that a connection closed, so "the next frame" is a count, not a race.
FRAME_SECONDS = 0.25


@pytest.fixture
def live_server(live_app):
    """``live_server(**config)`` -> ``(port, state)`` of a real server in a thread; after
    the test, its clip makings finish first (they take no core from the next test)."""
    states = []

    def make(**overrides):
        port, state = live_app(**overrides)
        states.append(state)
        return port, state

    yield make
    for state in states:
        _wait_idle(state)


@pytest.fixture
def slow_frames(monkeypatch):
    """Each clip frame held up :data:`FRAME_SECONDS` after the making counted it (in the
    server's per-frame decoration: what the making does is unchanged)."""
    from jeanscv_cli import worker

    made = worker.clip_decorate

    def decorate_slowly(options):
        decorate = made(options)

        def slowly(painted, original):
            time.sleep(FRAME_SECONDS)
            return decorate(painted, original) if decorate is not None else painted

        return slowly

    monkeypatch.setattr(worker, "clip_decorate", decorate_slowly)


def _request(port: int, method: str, path: str, body: bytes = b"", headers: dict | None = None, timeout=60):
    status, _, data = request(port, method, path, body, headers, timeout)
    return status, json.loads(data or b"null")


def _upload(port: int, name: str, data: bytes) -> tuple[int, dict]:
    status, _, answer = upload(port, name, data)
    return status, json.loads(answer or b"null")


def _done(port: int, photo: str) -> int:
    return _request(port, "GET", f"/api/photos/{photo}/clip/progress")[1]["done"]


def _start_making(port: int, photo: str) -> socket.socket:
    """A client that asks for the photo's clip (automatic subject) and waits."""
    client = socket.create_connection(("127.0.0.1", port), timeout=10)
    client.sendall(
        f"POST /api/photos/{photo}/clip HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
        "Content-Type: application/json\r\nContent-Length: 2\r\n\r\n{}".encode()
    )
    return client


def _wait_for(done, seconds: float, message: str) -> None:
    deadline = time.monotonic() + seconds
    while not done():
        assert time.monotonic() < deadline, message
        time.sleep(0.02)


def _wait_idle(state, seconds: float = 60) -> None:
    deadline = time.monotonic() + seconds
    while (state.clip_pool._running or state.pool._running) and time.monotonic() < deadline:
        time.sleep(0.05)


def _long_clip(port: int, frames: int = 40) -> str:
    status, opened = _upload(port, "walk.gif", clip_bytes(walking(frames)[0], "gif", fps=10.0))
    assert status == 200, opened
    return opened["photo"]


def test_a_client_that_leaves_mid_clip_stops_the_making_at_the_next_frame(live_server, slow_frames, capfd):
    port, state = live_server()
    photo = _long_clip(port, frames=20)
    client = _start_making(port, photo)
    _wait_for(lambda: _done(port, photo) >= 3, 60, "the making did not start")
    client.close()  # the page left
    left = time.monotonic()
    at_leaving = _done(port, photo)
    _wait_for(lambda: not state.clip_pool._running, 30, "the clip's worker was not freed")
    freed = time.monotonic() - left
    # The frame under way when the client left was the last one made.
    assert _done(port, photo) <= at_leaving + 1 < 20
    assert freed < 4 * FRAME_SECONDS + 3  # a frame here is FRAME_SECONDS and a few ms of work
    # The half-written clip is gone: the server's folder holds the upload only.
    _wait_for(lambda: [p.suffix for p in state.tmp.iterdir()] == [".gif"], 10, "a half-written clip was left")
    # The worker is free: the next making runs (and runs to its end).
    status, made = _request(port, "POST", f"/api/photos/{photo}/clip", b"{}", {"Content-Type": "application/json"})
    assert status == 200 and made["frames"] == 20, made
    assert "jeanscv serve:" not in capfd.readouterr().err  # a client leaving is no error


def test_six_abandoned_clips_do_not_hold_up_a_photo(live_server, slow_frames):
    port, state = live_server(workers=1)
    photo = _long_clip(port)
    clients = [_start_making(port, photo) for _ in range(6)]
    _wait_for(lambda: _done(port, photo) >= 1, 60, "no making started")
    for client in clients:
        client.close()
    at_leaving = _done(port, photo)
    began = time.monotonic()
    status, answer = _upload(port, "still.png", png_bytes(walking(1)[0][0], compress_level=1))
    took = time.monotonic() - began
    assert status == 200 and answer["kind"] == "photo", answer
    assert took < 8, f"the photo waited {took:.1f} s behind abandoned clips"
    # Nothing more was made for them: the running one stopped at its next frame, the
    # waiting ones never began (each would have started again from frame 0).
    _wait_for(lambda: not state.clip_pool._running, 30, "the clips' worker was not freed")
    time.sleep(3 * FRAME_SECONDS)  # time for a waiting making to have begun, were one left
    assert not state.clip_pool._running and not state.clip_pool._waiting
    assert _done(port, photo) <= at_leaving + 1 < 40


def test_a_client_that_waits_longer_than_the_body_timeout_gets_its_clip(live_server, slow_frames):
    """The server listens for the client leaving on the finished request's connection:
    waiting for the clip longer than the Guard's limit for a stalled body is no stall."""
    port, _ = live_server(body_timeout=0.5)
    photo = _long_clip(port, frames=10)  # about 2.5 s
    status, made = _request(port, "POST", f"/api/photos/{photo}/clip", b"{}", {"Content-Type": "application/json"})
    assert status == 200 and made["frames"] == 10, made


# ------------------------------------------------------------------ the page (Chromium)

CHROMIUM = "/usr/bin/chromium"


def _portrait_gif(frames: int) -> tuple[bytes, list]:
    """A 240x320 (portrait) GIF of the textured animal walking: ``(bytes, true masks)``."""
    from testkit import synthetic_clips as sc

    sprite = sc.texture_sprite(120, seed=3)
    ground = sc.background(240, 320, seed=5)
    made = list(sc.clip(sprite, ground, sc.Motion((100.0, 170.0), (16.0, 6.0), 2.0, 0.05, frames=frames)))
    return clip_bytes([p for p, _, _ in made], "gif", fps=10.0), [m for _, m, _ in made]


def test_the_page_shows_each_frame_and_scrolls_to_the_clip_made(slow_frames):
    """Issue 49: "Make the clip" says which frame is being made from the first moment
    ("frame 1 of 5", then 2, 3... on the bar and beside it) and, once made, the clip
    plays in view (it was made beside or below the frame, often out of sight)."""
    import os
    from pathlib import Path

    if not Path(CHROMIUM).is_file() or not _playwright():
        if os.environ.get("CI"):
            pytest.fail(f"{CHROMIUM} and playwright are needed in CI")
        pytest.skip("needs Debian's chromium and playwright")
    from playwright.sync_api import sync_playwright
    from test_serve_browser import _drop_file, _serving

    data, _ = _portrait_gif(5)
    with _serving({"warm": False}) as (url, _), sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"], headless=True)
        try:
            page = browser.new_page(viewport={"width": 1024, "height": 640})
            problems = []
            page.on("console", lambda message: message.type == "error" and problems.append(message.text))
            page.on("pageerror", lambda error: problems.append(str(error)))
            page.problems = problems
            page.goto(url + "/")
            page.wait_for_selector("#garment option", state="attached")
            _drop_file(page, data, "walk.gif", "image/gif")
            # Everything the page says of the making, with when, and whether the clip was shown yet.
            page.evaluate(
                """() => {
                    window.said = [];
                    const note = () => window.said.push({
                        at: performance.now(), text: document.getElementById('status').textContent,
                        bar: document.getElementById('clip-progress').value,
                        made: !!document.getElementById('clip-image').getAttribute('src') });
                    new MutationObserver(note).observe(document.getElementById('status'),
                        { childList: true, characterData: true, subtree: true });
                }"""
            )
            began = page.evaluate("() => performance.now()")
            page.click("#make-clip")
            page.wait_for_function(
                """() => { const img = document.getElementById('clip-image');
                           return !img.hidden && img.complete && img.naturalWidth > 0; }""",
                timeout=90_000,
            )
            said = page.evaluate("() => window.said")
            making = [s for s in said if s["text"].startswith("Making the clip: frame") and not s["made"]]
            assert making and making[0]["at"] - began < 1000, said  # from the first second
            assert making[0]["text"] == "Making the clip: frame 1 of 5…", said
            frames = {int(s["text"].split()[4]) for s in making}
            assert {1, 2, 3} <= frames, said  # frame by frame, before the clip is there
            assert any(s["bar"] >= 2 for s in making), said
            # The clip made is in view (scrolled there: the page is taller than the window).
            page.wait_for_function(
                """() => { const r = document.getElementById('clip-image').getBoundingClientRect();
                           return r.height > 0 && r.top >= -1 && r.bottom <= window.innerHeight + 1; }""",
                timeout=10_000,
            )
            assert page.locator("#clip-progress").is_hidden() and page.locator("#clip-count").is_hidden()
            assert page.locator("#status").text_content() == "walk.jeans.gif: 5 frames."
            assert problems == []
        finally:
            browser.close()


def _playwright() -> bool:
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return False
    return True
