"""Shared test set-up: the CLI package importable from a source checkout, and CLI fixtures.

The repository root is on ``sys.path`` (pytest's ``pythonpath``, pyproject.toml), so the
tests import ``jeanscv`` from a plain checkout and their data from ``testkit``.

After ``pip install -e .`` the CLI is the package ``jeanscv_cli``; in a plain
checkout ``jeanscv/_command.py`` loads the ``cli/`` folder under that name.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import signal
import threading
import time
from collections import OrderedDict
from pathlib import Path

# numpy's OpenBLAS on one thread, as the command and the server run it
# (jeanscv_cli.main.one_blas_thread), set before numpy loads it: on two threads the
# saliency's few-hundred-node solve took 30-100 ms instead of 4-30, and its threads'
# spinning took the core the GrabCut threads, the browser and the workers wait for.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

# A suite started from a background job (`nohup ... &`, or `&` in a script) begins with
# Ctrl-C ignored, and every process the tests start inherits that: the tests that send
# one (a command interrupted as it starts, a batch stopped half way) then saw it ignored
# ("not stopped", status 0). Ctrl-C is what it is on a terminal; its children inherit
# the default.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "silhouettes"
#: The paper's seven silhouettes in SHARED (NAME.png, NAME.svg).
PAPER_SHAPES = ("person", "vitruvian", "dog", "horse", "tripod", "balldragon", "extra_0")

if importlib.util.find_spec("jeanscv_cli") is None:
    import jeanscv._command  # noqa: F401  (registers jeanscv_cli from ./cli)

# A person-like polygon in a 256x256 viewBox: the SVG used when shared/ is absent.
_PERSON_SVG = """<svg xmlns="http://www.w3.org/2000/svg" width="256" height="256" viewBox="0 0 256 256">
<path d="M113 20 L143 20 L143 50 L160 60 L158 130 L150 130 L152 232 L134 232 L128 140 L122 232
L104 232 L106 130 L98 130 L96 60 L113 50 Z" fill="#000"/></svg>
"""


def pytest_sessionfinish(session, exitstatus) -> None:
    """Let the servers' worker threads and the kernels' warm-up finish what they were
    left with before the interpreter ends: a daemon thread still inside OpenCV or numba
    then aborts the process ("terminate called without an active exception", status
    134) after every test passed, as `jeanscv serve` would without its os._exit (see
    jeanscv_cli.serve.run). A stopped server's threads end with their job."""
    deadline = time.monotonic() + 60
    for thread in threading.enumerate():
        if thread.daemon and thread.name.startswith(("jeanscv-serve-", "jeanscv-warm-up")):
            thread.join(timeout=max(0.0, deadline - time.monotonic()))


@pytest.fixture(autouse=True, scope="session")
def _single_torch_thread():
    """One torch thread for every test: on the 2-core CI box torch's parallel
    index_add/scatter run ~30x slower than serial ones under load, and the tests
    check numbers, not threading (the fitter sets its own thread count anyway)."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="session")
def compiled_kernels():
    """The numba kernels compiled into the on-disk cache before a test that gives a
    subprocess a deadline, or checks that a fresh process loads them from there: in a fresh
    clone the first fit compiles them (half a minute, more with two workers compiling at
    once), which would eat the deadline and make the test depend on what the cache holds.
    Subprocesses share the cache (same environment)."""
    from jeanscv.device import fast_available

    if fast_available():
        from jeanscv.fitting import _fast

        _fast.load_kernels()


class _RealPhotoHypotheses:
    """Per real photo, one :class:`~jeanscv.subject.photo.SharedHypotheses` for its two
    users, ``test_real_photos`` (auto) and ``test_real_clicks`` (click sessions): auto's
    hypotheses, 90% of either's time on a photo, are cut once between them (the same
    results: ``test_clicks.py`` checks), and dropped once both have them (~7 MB each)."""

    def __init__(self) -> None:
        self._held: dict[str, object] = {}

    def take(self, stem: str):
        """The photo's shared hypotheses: made for its first user, handed over to its second."""
        from jeanscv.subject.photo import SharedHypotheses

        if stem in self._held:
            return self._held.pop(stem)
        shared = self._held[stem] = SharedHypotheses()
        return shared


@pytest.fixture(scope="session")
def real_photo_hypotheses() -> _RealPhotoHypotheses:
    """``real_photo_hypotheses.take(stem)``: see :class:`_RealPhotoHypotheses`."""
    return _RealPhotoHypotheses()


class _CutOnce:
    """auto's hypotheses (:meth:`~jeanscv.subject.photo.PreparedScene.of`) of each working
    copy cut once for every test that asks for ``cut_once``: the same few photos (the dog
    and its owner, the clicks figure) were cut afresh by some 80 tests, a second a cut,
    though a cut gives the same scene every time (``test_clicks.py`` checks sharing gives
    the same results). The latest few are kept (~7 MB each); a copy that differs from the
    one held, pixel for pixel, is cut anew."""

    KEEP = 8

    def __init__(self) -> None:
        self._lock = threading.Lock()  # the server's threads: a second caller waits for the cut
        self._held: OrderedDict[tuple, object] = OrderedDict()

    def of(self, cut, rgb: np.ndarray):
        """The prepared scene of ``rgb``: held, or ``cut(rgb)`` now."""
        key = (rgb.shape, rgb.dtype.str, hashlib.blake2b(np.ascontiguousarray(rgb).data, digest_size=16).digest())
        with self._lock:
            held = self._held.get(key)
            if held is None or not np.array_equal(held.rgb, rgb):
                held = self._held[key] = cut(rgb)
            self._held.move_to_end(key)
            while len(self._held) > self.KEEP:
                self._held.popitem(last=False)
            return held


@pytest.fixture(scope="session")
def _cuts() -> _CutOnce:
    return _CutOnce()


@pytest.fixture
def cut_once(request, _cuts, monkeypatch):
    """auto's hypotheses of a photo cut once for all the tests that use this fixture
    (:class:`_CutOnce`), unless the test is marked ``fresh_cuts``: its point is the
    cutting itself (how often, on which thread, how long it takes)."""
    if request.node.get_closest_marker("fresh_cuts"):
        return
    from jeanscv.subject.photo import PreparedScene

    cut = PreparedScene.of
    monkeypatch.setattr(PreparedScene, "of", staticmethod(lambda rgb: _cuts.of(cut, rgb)))


def float64_tensor(array):
    """``array`` as a float64 torch tensor."""
    import torch

    return torch.as_tensor(np.asarray(array, dtype=np.float64))


@pytest.fixture
def run_cli():
    """``run_cli(*args)`` -> click ``Result`` of ``jeanscv ARGS`` run in-process (stderr separate)."""
    from click.testing import CliRunner

    from jeanscv_cli.main import cli

    def run(*args):
        return CliRunner().invoke(cli, [str(a) for a in args], prog_name="jeanscv")

    return run


def write_silhouette_png(path: Path, name: str = "person") -> Path:
    """A 256x256 8-bit grey silhouette PNG (255 inside): a paper silhouette, else a synthetic one."""
    from PIL import Image

    if (SHARED / f"{name}.png").is_file():
        shutil.copyfile(SHARED / f"{name}.png", path)
    else:
        from testkit.synthetic import ZOO, silhouette_zoo

        key = name if name in ZOO else "person"
        alpha = silhouette_zoo([key])[key]
        Image.fromarray(np.round(alpha * 255).astype(np.uint8)).save(path)
    return path


def write_silhouette_svg(path: Path) -> Path:
    """An SVG silhouette in a 256x256 viewBox: the paper's dog, else a person polygon."""
    if (SHARED / "dog.svg").is_file():
        shutil.copyfile(SHARED / "dog.svg", path)
    else:
        path.write_text(_PERSON_SVG)
    return path


def blue_pixels(image: np.ndarray) -> int:
    """Pixels in the paper's jeans blue (0, 0, 255), allowing for anti-aliasing and JPEG."""
    rgb = np.asarray(image)[..., :3].astype(int)
    return int(np.sum((rgb[..., 2] > 200) & (rgb[..., 0] < 60) & (rgb[..., 1] < 60)))


def paper_silhouette(name: str, dtype=np.float32) -> np.ndarray:
    """The paper's ``NAME.png`` as an alpha in [0, 1]; skips the test when ../shared lacks it."""
    path = SHARED / f"{name}.png"
    if not path.is_file():
        pytest.skip(f"{path} not available")
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("L"), dtype=dtype) / 255.0


@pytest.fixture
def live_app():
    """``live_app(**config)`` -> ``(port, state)`` of a fresh ``jeanscv serve`` app on a
    real uvicorn server in a thread (the command's own HTTP protocol, a free loopback
    port, no warm-up); stopped after the test."""
    import socket
    import threading

    import uvicorn

    from jeanscv_cli.serve import run
    from jeanscv_cli.serve.app import Config, create_app

    servers = []

    def make(**overrides):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        app = create_app(Config(port=port, warm=False, **overrides))
        server = uvicorn.Server(
            uvicorn.Config(app, host="127.0.0.1", port=port, log_level="error", lifespan="on", http=run._protocol())
        )
        thread = threading.Thread(target=server.run, daemon=True)
        thread.start()
        servers.append((server, thread))
        deadline = time.monotonic() + 30
        while not server.started:
            assert time.monotonic() < deadline, "the server did not start"
            time.sleep(0.02)
        return port, app.app.state.jeanscv

    yield make
    for server, thread in servers:
        server.should_exit = True
        thread.join(timeout=10)


@pytest.fixture
def make_client():
    """``make_client(**config)`` -> a started test client of a fresh ``jeanscv serve``
    app on http://127.0.0.1:8000 (no warm-up; closed after the test)."""
    from starlette.testclient import TestClient

    from jeanscv_cli.serve.app import Config, create_app

    clients = []

    def make(**overrides):
        client = TestClient(create_app(Config(port=8000, warm=False, **overrides)), base_url="http://127.0.0.1:8000")
        client.__enter__()
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.__exit__(None, None, None)
    # The server leaves a running job to finish on its own (a click session made ahead
    # of the first click, a hover map): wait for it, so it takes no core from the next
    # test (a clip's time limit there passed early) and is not inside OpenCV when the
    # suite ends (see pytest_sessionfinish).
    deadline = time.monotonic() + 60
    for client in clients:
        pool = client.app.app.state.jeanscv.pool
        while pool._running and time.monotonic() < deadline:
            time.sleep(0.05)
