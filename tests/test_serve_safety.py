"""``jeanscv serve`` under attack and at exit: each failure that issue 28 listed, as a test.

In-process tests use Starlette's test client; the exits are tested on a real
``jeanscv serve`` process; the queue's rules on :class:`~jeanscv_cli.serve.store.Pool`
itself; slow clients on a real uvicorn server in a thread.
"""

from __future__ import annotations

import asyncio
import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from test_cli import _env
from test_serve import BASE, png_bytes, scene, upload
from test_serve_cli import start_server

pytest.importorskip("starlette")

from jeanscv_cli.serve.app import client_text  # noqa: E402
from jeanscv_cli.serve.store import Busy, Pool, Stopping, TooSlow  # noqa: E402


@pytest.fixture
def folder(tmp_path):
    photos = tmp_path / "photos"
    photos.mkdir()
    Image.fromarray(scene().image).save(photos / "pets.png")
    return photos


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# ------------------------------------------------------------- 1. other sites


@pytest.mark.usefixtures("cut_once")  # the dog and its owner cut once (conftest.py)
def test_nothing_another_site_sends_does_anything(make_client, folder):
    client = make_client(folder=folder)
    before = listing(folder)
    cross = {"sec-fetch-site": "cross-site", "sec-fetch-mode": "no-cors", "sec-fetch-dest": "image"}
    # The <img> of another site's page: a GET, which never writes, and is refused anyway.
    assert client.get("/api/folder/0/thumb", headers=cross).status_code == 403
    assert client.get("/api/folder/0/thumb").status_code == 405  # making a thumbnail is a POST
    for headers in (
        {"origin": "http://evil.example"},
        {"origin": "null"},  # a sandboxed frame or a redirect
        {"sec-fetch-site": "cross-site"},
        {"sec-fetch-site": "same-site"},  # another port of this host, or a sibling subdomain
    ):
        for path in ("/api/folder/0/thumb", "/api/folder/0/open"):
            answer = client.post(path, headers=headers)
            assert answer.status_code == 403 and "other sites" in answer.json()["error"], (path, headers)
        assert client.get("/api/folder", headers=headers).status_code == 403, headers
        assert client.get("/api/options", headers=headers).status_code == 403, headers
    assert listing(folder) == before  # nothing was made
    # Following a link from another site to the page itself is fine: it does nothing.
    navigate = {"sec-fetch-site": "cross-site", "sec-fetch-mode": "navigate", "origin": "http://evil.example"}
    assert client.get("/", headers=navigate).status_code == 200
    # ...but its script is not for other sites' pages to include.
    assert client.get("/static/app.js", headers=cross).status_code == 403
    # The page itself (same origin) makes the thumbnail.
    made = client.post("/api/folder/0/thumb", headers={"origin": BASE, "sec-fetch-site": "same-origin"})
    assert made.status_code == 200 and "pets.jeans.png" in listing(folder)


# ------------------------------------------------------------- 2. symbolic links


@pytest.mark.usefixtures("cut_once")  # the dog and its owner cut once (conftest.py)
def test_folder_mode_never_follows_a_symbolic_link(make_client, folder, tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    secret = np.full((120, 160, 3), (250, 10, 200), np.uint8)
    Image.fromarray(secret).save(outside / "secret.png")
    (outside / "x.clicks.json").write_text(
        json.dumps({"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[400, 250]]}]})
    )
    (folder / "pets.jeans.png").symlink_to(outside / "secret.png")
    (folder / "pets.clicks.json").symlink_to(outside / "x.clicks.json")
    client = make_client(folder=folder)
    items = client.get("/api/folder").json()["items"]
    assert items == [
        {
            "item": 0,
            "name": "pets.png",
            "output": False,
            "clicks": False,
            "thumb": "/api/folder/0/thumb",
            "uncertain": None,
        }
    ]
    thumb = client.post("/api/folder/0/thumb")
    assert thumb.status_code == 422 and "symbolic link" in thumb.json()["error"]
    opened = client.post("/api/folder/0/open")
    assert opened.status_code == 200 and opened.json()["clicks"] is False and "saved_clicks" not in opened.json()
    photo = opened.json()["photo"]
    saved = client.post("/api/folder/0/clicks", json={"photo": photo, "objects": [{"positive": [[400, 250]]}]})
    assert saved.status_code == 422 and "symbolic link" in saved.json()["error"]
    # Nothing outside was read into an answer or written.
    assert (folder / "pets.jeans.png").readlink() == outside / "secret.png"
    assert np.array_equal(np.asarray(Image.open(outside / "secret.png")), secret)
    assert sorted(p.name for p in outside.iterdir()) == ["secret.png", "x.clicks.json"]


# ------------------------------------------------------------- 3. paths in errors, damaged outputs


@pytest.mark.usefixtures("cut_once")  # the dog and its owner cut once (conftest.py)
def test_a_damaged_output_is_made_again(make_client, folder):
    output = folder / "pets.jeans.png"
    output.write_bytes(b"not a picture at all")
    client = make_client(folder=folder)
    thumb = client.post("/api/folder/0/thumb")
    assert thumb.status_code == 200 and thumb.headers["content-type"] == "image/jpeg"
    with Image.open(output) as made:
        assert made.size == (800, 500)  # the command line's output, made again


@pytest.mark.usefixtures("cut_once")  # the dog and its owner cut once (conftest.py)
def test_no_absolute_path_in_an_error(make_client, folder, tmp_path):
    (folder / "pets.jeans.png").mkdir()  # an output that can never be written
    client = make_client(folder=folder)
    answer = client.post("/api/folder/0/thumb")
    assert answer.status_code == 422
    reason = answer.json()["error"]
    assert reason.startswith("pets.png: ") and str(tmp_path) not in reason and "/" not in reason, reason


@pytest.mark.parametrize(
    ("text", "shown"),
    [
        ("cannot identify image file '/abs/path/folder/cat.jeans.jpg'", "cannot identify image file 'cat.jeans.jpg'"),
        ("[Errno 13] Permission denied: '/home/me/x'", "[Errno 13] Permission denied: 'x'"),
        ("cannot write into /srv/photos/", "cannot write into (a folder)"),
        ("a 12 MB/s link, TIFF/JPEG, 1/2 of it", "a 12 MB/s link, TIFF/JPEG, 1/2 of it"),
        ("two\nlines", "two lines"),
    ],
)
def test_client_text(text, shown):
    assert client_text(text) == shown


# ------------------------------------------------------------- 4. bodies that broke the parsers


@pytest.mark.usefixtures("cut_once")  # the dog and its owner cut once (conftest.py)
def test_absurd_click_bodies_are_one_line_422(client_photo):
    client, photo = client_photo
    nested = b'{"objects": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    answer = client.post(f"/api/photos/{photo}/render", content=nested)
    assert answer.status_code == 422 and "not valid JSON" in answer.json()["error"]
    huge = b'{"objects": [{"positive": [[' + b"9" * 401 + b", 5]]}]}"
    answer = client.post(f"/api/photos/{photo}/render", content=huge)
    assert answer.status_code == 422 and "too large to be pixels" in answer.json()["error"]


@pytest.fixture
def client_photo(make_client):
    client = make_client()
    return client, upload(client, "two.png", png_bytes(scene().image)).json()["photo"]


def test_a_bug_is_500_and_one_line(make_client, monkeypatch, capfd):
    from jeanscv_cli.serve import engine

    client = make_client()
    monkeypatch.setattr(engine, "garments", lambda: 1 / 0)
    answer = client.get("/api/options")
    assert answer.status_code == 500 and answer.json() == {
        "error": "unexpected error (the server's terminal says more)"
    }
    logged = capfd.readouterr().err
    assert "ZeroDivisionError" in logged and "Traceback" not in logged


def test_a_huge_click_in_a_clicks_file_on_the_command_line(tmp_path, run_cli):
    photo = tmp_path / "pets.png"
    Image.fromarray(scene().image).save(photo)
    clicks = tmp_path / "c.json"
    clicks.write_text('{"format": "jeanscv-clicks", "version": 1, "objects": [{"positive": [[' + "1" * 401 + ", 5]]}]}")
    result = run_cli(photo, "--clicks", clicks, "-q")
    assert result.exit_code != 0 and "too large to be pixels" in result.stderr
    assert "unexpected" not in result.stderr and "Traceback" not in result.stderr


# ------------------------------------------------------------- 5-7. exits


def stop(server: subprocess.Popen, sig: int) -> tuple[int, float, str]:
    """Send ``sig``: (exit status, seconds until it exited, its stderr)."""
    began = time.monotonic()
    server.send_signal(sig)
    try:
        code = server.wait(timeout=30)
    except subprocess.TimeoutExpired:
        server.kill()
        code = server.wait()
    return code, time.monotonic() - began, server.stderr.read()


#: Starts in the loop below. With the two fixes it guards undone (the Lab-table thread a
#: daemon again, the command ending through the interpreter instead of ``os._exit``),
#: 35 of 40 such starts aborted (2026-11-27), so 10 miss it once in about 10^9 runs;
#: each start costs a fresh process's imports, so 30 only cost time.
STARTS = 10


def test_start_and_stop_10_times_without_an_abort(tmp_path):
    """Ctrl-C and SIGTERM alternately, each as soon as the page answers (the warm-up
    threads still running): always 0 or 143, never an abort, in under 2 s."""
    seen = []
    for round_ in range(STARTS):
        server, _ = start_server(tmp_path)
        sig = signal.SIGINT if round_ % 2 == 0 else signal.SIGTERM
        code, seconds, err = stop(server, sig)
        seen.append((code, round(seconds, 2), err.strip().splitlines()[-1:]))
    expected = [0 if round_ % 2 == 0 else 143 for round_ in range(STARTS)]
    assert [code for code, _, _ in seen] == expected, seen
    assert max(seconds for _, seconds, _ in seen) < 2.0, seen
    assert all(last == ["jeanscv serve: stopped"] for _, _, last in seen), seen
    assert not list(tmp_path.glob("jeanscv-serve-*"))


@cache
def big_photo() -> bytes:
    """A 12-MP photo: its segmentation takes a few seconds. Made once, as a level-1 PNG
    (1.2 s to encode, not 4.2; decoded as fast; 9.7 MB, not 7.7)."""
    image = Image.fromarray(scene().image).resize((4000, 3000))
    return png_bytes(np.asarray(image), compress_level=1)


def post_upload(port: int, data: bytes, answers: list, sent: threading.Event | None = None) -> None:
    """Upload ``data``; ``sent`` is set once the whole request is out; the answer is appended."""
    boundary = "jeanscvtest"
    body = (
        f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="big.png"\r\n\r\n'.encode()
        + data
        + f"\r\n--{boundary}--\r\n".encode()
    )
    try:
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
        connection.request("POST", "/api/photos", body, {"Content-Type": f"multipart/form-data; boundary={boundary}"})
        if sent is not None:
            sent.set()
        response = connection.getresponse()
        answers.append((response.status, response.read()))
    except OSError as exc:
        answers.append((0, str(exc).encode()))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_stops_within_2_s_while_a_photo_is_worked_on(tmp_path, sig):
    server, port = start_server(tmp_path)
    data = big_photo()
    answers: list = []
    sent = threading.Event()
    client = threading.Thread(target=post_upload, args=(port, data, answers, sent))
    client.start()
    assert sent.wait(30)
    time.sleep(0.6)  # the upload is in and being decoded or segmented (2-3 s in all for 12 MP here)
    code, seconds, err = stop(server, sig)
    client.join(timeout=30)
    assert code == (0 if sig == signal.SIGINT else 143), err
    assert seconds < 2.0, (seconds, err)
    assert "Traceback" not in err and "terminate called" not in err, err
    assert err.splitlines()[-1] == "jeanscv serve: stopped"
    assert answers and answers[0][0] in (0, 503), answers  # "the server is stopping", or cut off
    if answers[0][0] == 503:
        assert json.loads(answers[0][1]) == {"error": "the server is stopping"}
    assert not list(tmp_path.glob("jeanscv-serve-*"))  # its temporary folder is gone


def test_stops_within_2_s_during_a_slow_upload(tmp_path):
    server, port = start_server(tmp_path)
    with socket.create_connection(("127.0.0.1", port)) as slow:
        head = (
            "POST /api/photos HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 10000000\r\n"
            "Content-Type: multipart/form-data; boundary=b\r\n\r\n"
        )
        slow.sendall(head.encode() + b'--b\r\nContent-Disposition: form-data; name="file"; filename="a.png"\r\n\r\n')
        slow.sendall(b"x" * 100_000)
        time.sleep(0.5)
        code, seconds, err = stop(server, signal.SIGINT)
    assert code == 0 and seconds < 2.0, (code, seconds, err)
    assert "Traceback" not in err and err.splitlines()[-1] == "jeanscv serve: stopped"
    assert not list(tmp_path.glob("jeanscv-serve-*"))


def test_a_busy_port_is_one_line():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        began = time.monotonic()
        done = subprocess.run(
            [sys.executable, "-m", "jeanscv", "serve", "--port", str(port)],
            capture_output=True,
            text=True,
            env=_env(),
            timeout=60,
        )
    assert done.returncode == 1
    assert done.stderr == f"jeanscv serve: port {port} is in use (try --port 0 or another)\n"
    assert time.monotonic() - began < 10  # said before any warm-up


# ------------------------------------------------------------- 9. slow clients and load


@pytest.fixture
def live_server(monkeypatch, live_app):
    """``live_server(**config)`` -> port of a real uvicorn server in a thread, with the
    command's protocol (head deadline patched to 0.5 s)."""
    from jeanscv_cli.serve import run

    monkeypatch.setattr(run, "HEAD_SECONDS", 0.5)
    return lambda **overrides: live_app(**overrides)[0]


def closed_within(connection: socket.socket, seconds: float, trickle: bytes = b"") -> bool:
    """Whether the server closes ``connection`` within ``seconds`` while ``trickle`` is
    sent a byte every 0.1 s."""
    connection.settimeout(0.1)
    deadline = time.monotonic() + seconds
    sent = 0
    while time.monotonic() < deadline:
        try:
            if connection.recv(4096) == b"":
                return True
        except TimeoutError:
            pass
        except OSError:
            return True
        if sent < len(trickle):
            try:
                connection.sendall(trickle[sent : sent + 1])
            except OSError:
                return True
            sent += 1
    return False


def test_a_request_head_sent_a_byte_at_a_time_is_cut_off(live_server):
    port = live_server()
    with socket.create_connection(("127.0.0.1", port)) as loris:
        assert closed_within(loris, 3.0, trickle=b"GET /api/options HTTP/1.1\r\nHost: 127.0.0.1\r\nX-a: " + b"a" * 100)
    with socket.create_connection(("127.0.0.1", port)) as idle:
        assert closed_within(idle, 3.0)
    # A prompt client is answered as usual.
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    connection.request("GET", "/api/options")
    assert connection.getresponse().status == 200


def test_a_stalled_body_is_408(live_server):
    port = live_server(body_timeout=0.5)
    with socket.create_connection(("127.0.0.1", port), timeout=10) as stalled:
        stalled.sendall(
            b"POST /api/photos HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000\r\n"
            b"Content-Type: multipart/form-data; boundary=b\r\n\r\n--b\r\n"
        )
        answer = b""
        while b"\r\n\r\n" not in answer or not answer.rstrip().endswith(b"}"):  # the head, then the JSON body
            more = stalled.recv(4096)  # the two may come in separate reads
            if not more:
                break
            answer += more
    assert answer.startswith(b"HTTP/1.1 408") and b"stalled" in answer, answer


def test_the_queue_is_first_come_first_served():
    order = []

    async def main():
        pool = Pool(1, 16)
        release = threading.Event()
        pool.submit_background(release.wait)  # the worker is busy
        pool.submit_background(order.append, "background")
        requests = [asyncio.ensure_future(pool.run(order.append, index)) for index in range(8)]
        await asyncio.sleep(0.1)
        release.set()
        await asyncio.gather(*requests)
        await asyncio.sleep(0.1)
        pool.stop()

    asyncio.run(main())
    assert order == [0, 1, 2, 3, 4, 5, 6, 7, "background"]  # requests first, in arrival order


def test_the_queue_refuses_when_full_or_too_long():
    async def main():
        pool = Pool(1, 1, max_wait=0.3, job_seconds=0.3)
        release = threading.Event()
        running = asyncio.ensure_future(pool.run(release.wait))
        for _ in range(500):  # until the worker has taken it (a loaded machine may take a while)
            await asyncio.sleep(0.01)
            if pool._running == 1:
                break
        waiting = asyncio.ensure_future(pool.run(lambda: "late"))
        await asyncio.sleep(0.05)
        with pytest.raises(Busy):  # the one place in the queue is taken
            await pool.run(lambda: "refused")
        with pytest.raises(Busy):  # waited longer than max_wait
            await waiting
        with pytest.raises(TooSlow):  # its job ran past job_seconds
            await running
        release.set()
        await asyncio.sleep(0.05)
        assert await pool.run(lambda: "served") == "served"  # the worker is free again
        blocked = threading.Event()
        stuck = asyncio.ensure_future(pool.run(blocked.wait))
        queued = asyncio.ensure_future(pool.run(lambda: "never"))
        await asyncio.sleep(0.05)
        pool.stop()
        for request in (stuck, queued):
            with pytest.raises(Stopping):
                await request
        with pytest.raises(Stopping):
            await pool.run(lambda: "after")
        blocked.set()

    asyncio.run(main())


def test_default_workers_fit_the_machine(monkeypatch):
    from jeanscv_cli.serve.run import default_workers

    workers = default_workers()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert 1 <= workers <= min(4, cores)
