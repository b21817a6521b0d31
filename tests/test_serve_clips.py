"""``jeanscv serve`` and clips (cli/serve/clips.py): a GIF or a short video uploaded, its
first frame clicked, the clip made with the jeans following, played and downloaded; its
caps and refusals, through Starlette's test client."""

from __future__ import annotations

import io
import time

import numpy as np
import pytest
from PIL import Image
from test_serve import BASE, upload

from jeanscv.io.clip import clip_bytes
from testkit import synthetic_clips as sc

pytest.importorskip("starlette")

from jeanscv_cli.serve.clips import ClipCaps  # noqa: E402

WIDTH, HEIGHT = 192, 144


def walking(frames: int = 5) -> tuple[list, list]:
    """The textured animal walking right over gravel: ``(frames, true masks)``."""
    sprite = sc.texture_sprite(110, seed=3)
    ground = sc.background(WIDTH, HEIGHT, seed=5)
    made = list(sc.clip(sprite, ground, sc.Motion((70.0, 72.0), (24.0, 4.0), 2.0, 0.05, frames=frames)))
    return [p for p, _, _ in made], [m for _, m, _ in made]


def test_a_gif_is_clicked_on_its_first_frame_made_played_and_downloaded(make_client):
    client = make_client()
    frames, masks = walking()
    answer = upload(client, "walk.gif", clip_bytes(frames, "gif", fps=10.0))
    assert answer.status_code == 200, answer.text
    opened = answer.json()
    assert opened["clip"] == {"frames": 5, "seconds": 0.5, "format": "gif", "media": "image/gif"}
    assert (opened["width"], opened["height"]) == (WIDTH, HEIGHT)  # frame 0: clicks refer to it
    photo = opened["photo"]
    assert client.get(f"/api/photos/{photo}/clip/progress").json() == {"done": 0, "frames": 5}
    click = [list(sc.inner_point(masks[0]))]
    made = client.post(f"/api/photos/{photo}/clip", json={"objects": [{"positive": click, "negative": []}]})
    assert made.status_code == 200, made.text
    info = made.json()
    assert info["name"] == "walk.jeans.gif" and info["frames"] == 5 and info["frames_without_jeans"] == 0
    assert client.get(f"/api/photos/{photo}/clip/progress").json() == {"done": 5, "frames": 5}
    played = client.get(info["clip"])
    assert played.headers["content-type"] == "image/gif" and "content-disposition" not in played.headers
    with Image.open(io.BytesIO(played.content)) as gif:
        assert gif.n_frames == 5 and gif.size == (WIDTH, HEIGHT)
        for index, (pixels, mask) in enumerate(zip(frames, masks)):
            gif.seek(index)
            shown = np.asarray(gif.convert("RGB")).astype(int)
            changed = np.abs(shown - pixels).max(axis=-1) > 60
            assert changed[mask].mean() > 0.05 and changed[~mask].mean() < 0.01, index  # jeans on the animal
    saved = client.get(info["clip"] + "?download=1")
    assert saved.headers["content-disposition"] == 'attachment; filename="walk.jeans.gif"'
    assert saved.content == played.content
    # A photo is no clip.
    still = upload(client, "still.png", _png(frames[0])).json()
    assert "clip" not in still
    refused = client.post(f"/api/photos/{still['photo']}/clip", json={})
    assert refused.status_code == 422 and refused.json()["error"] == "still.png: not a clip"


def test_a_video_is_made_as_mp4(make_client):
    client = make_client()
    frames, _ = walking(frames=4)
    opened = upload(client, "walk.mov", clip_bytes(frames, "mp4", fps=10.0)).json()
    assert opened["clip"]["format"] == "mp4" and opened["clip"]["media"] == "video/mp4"
    info = client.post(f"/api/photos/{opened['photo']}/clip", json={}).json()  # automatic subject
    assert info["name"] == "walk.jeans.mp4" and info["frames"] == 4
    played = client.get(info["clip"])
    assert played.headers["content-type"] == "video/mp4" and played.content[4:8] == b"ftyp"


def test_caps_and_bad_clips_are_one_line(make_client, tmp_path):
    client = make_client(clip_caps=ClipCaps(frames=3, seconds=30.0, pixels=100 * 100))
    frames, _ = walking()
    answer = upload(client, "walk.gif", clip_bytes(frames, "gif", fps=10.0))
    assert answer.status_code == 422
    # The pixel cap is read from the header first.
    assert answer.json()["error"] == f"walk.gif: frames are {WIDTH}x{HEIGHT}, over the limit of 10,000 pixels a frame"
    client = make_client(clip_caps=ClipCaps(frames=3))
    answer = upload(client, "walk.gif", clip_bytes(frames, "gif", fps=10.0))
    assert answer.status_code == 422
    assert answer.json()["error"] == "walk.gif: clip has 5 frames, over the limit of 3 (this server's limit)"
    client = make_client(clip_caps=ClipCaps(seconds=0.3))
    error = upload(client, "walk.mp4", clip_bytes(frames, "mp4", fps=10.0)).json()["error"]
    assert error == "walk.mp4: clip lasts 0.5 s, over the limit of 0.3 s"
    broken = upload(client, "broken.mp4", b"\x00\x00\x00\x18ftypmp42" + bytes(200)).json()["error"]
    assert broken.startswith("broken.mp4: ") and "/" not in broken and "\n" not in broken
    assert list(client.app.app.state.jeanscv.tmp.iterdir()) == []  # nothing refused is kept


def test_making_a_clip_stops_at_the_time_limit(make_client):
    client = make_client()
    frames, _ = walking(frames=40)
    opened = upload(client, "long.gif", clip_bytes(frames, "gif", fps=10.0)).json()
    state = client.app.app.state.jeanscv
    state.config.job_seconds = state.clip_pool.job_seconds = 0.5  # the upload took its own time
    answer = client.post(f"/api/photos/{opened['photo']}/clip", json={})
    assert answer.status_code == 504
    assert answer.json()["error"] == "long.gif: took longer than the server's limit of 0.5 s"
    # The making itself stops at its next frame (the worker is free again), and keeps nothing.
    deadline = time.monotonic() + 60
    while state.clip_pool._running or len(list(state.tmp.iterdir())) > 1:
        assert time.monotonic() < deadline, "the making did not stop"
        time.sleep(0.1)
    assert client.get(f"/api/photos/{opened['photo']}/clip/progress").json()["done"] < 40
    assert [p.suffix for p in state.tmp.iterdir()] == [".gif"]  # the upload only


def test_a_clip_past_its_own_deadline_is_too_slow_as_the_pools_wait_says(make_client, tmp_path):
    """The making checks its own deadline after each frame. On a busy machine that deadline
    passes before the pool's wait for the job does (which starts when the server's loop
    hears the job began), so it must be the same answer, TooSlow (504), not a bad-input
    error (422), and keep nothing."""
    from jeanscv_cli.serve import engine
    from jeanscv_cli.serve.clips import make_clip
    from jeanscv_cli.serve.store import TooSlow

    client = make_client()
    frames, _ = walking(frames=3)
    opened = upload(client, "walk.gif", clip_bytes(frames, "gif", fps=10.0)).json()
    state = client.app.app.state.jeanscv
    photo = state.photos.get(opened["photo"])
    with pytest.raises(TooSlow):
        make_clip(photo, None, engine.RenderOptions(), None, ClipCaps(), 0.0, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_another_site_cannot_make_or_read_a_clip(make_client):
    client = make_client()
    frames, _ = walking(frames=3)
    opened = upload(client, "walk.gif", clip_bytes(frames, "gif", fps=10.0)).json()
    photo = opened["photo"]
    for headers in ({"origin": "http://evil.example"}, {"sec-fetch-site": "cross-site"}):
        assert client.post(f"/api/photos/{photo}/clip", json={}, headers=headers).status_code == 403
        assert client.get(f"/api/photos/{photo}/clip/progress", headers=headers).status_code == 403
    info = client.post(f"/api/photos/{photo}/clip", json={}, headers={"origin": BASE}).json()
    cross = {"sec-fetch-site": "cross-site", "sec-fetch-mode": "no-cors", "sec-fetch-dest": "image"}
    assert client.get(info["clip"], headers=cross).status_code == 403
    assert client.get(info["clip"]).status_code == 200
    assert client.get("/api/clips/not-a-clip").status_code == 404


def _png(pixels: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, "PNG")
    return buffer.getvalue()
