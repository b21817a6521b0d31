"""The ``jeanscv serve`` command: its help stays light, it warns when reachable from other
machines, and Ctrl-C stops it cleanly."""

from __future__ import annotations

import http.client
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from test_cli import _env

pytest.importorskip("uvicorn")


def free_port() -> int:
    """A port free on 127.0.0.1 just now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_serve_help_does_not_import_the_server_or_the_library():
    script = (
        "import sys\n"
        "import jeanscv.__main__\n"
        "from jeanscv_cli.main import main\n"
        "sys.argv = ['jeanscv', 'serve', '--help']\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    code = exc.code\n"
        "print('MODULES', code, *sorted({name.split('.')[0] for name in sys.modules}), file=sys.stderr)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=_env(), timeout=60)
    modules = done.stderr.split("MODULES ")[-1].split()
    assert modules[0] == "0", done.stderr[-2000:]
    assert not set(modules) & {"starlette", "uvicorn", "numpy", "cv2", "torch", "PIL"}
    assert done.stdout.startswith("Usage: jeanscv serve [OPTIONS] [FOLDER]") and "127.0.0.1" in done.stdout


def test_main_help_mentions_serve():
    done = subprocess.run([sys.executable, "-m", "jeanscv", "--help"], capture_output=True, text=True, env=_env())
    assert "jeanscv serve [FOLDER]" in done.stdout


def test_serve_rejects_a_missing_folder(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "jeanscv", "serve", str(tmp_path / "nope")], capture_output=True, text=True, env=_env()
    )
    assert done.returncode == 2 and "does not exist" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize(("host", "warned"), [("0.0.0.0", True), ("192.168.1.20", True), ("127.0.0.1", False)])
def test_warning_when_not_on_loopback(monkeypatch, capsys, host, warned):
    import uvicorn

    from jeanscv_cli.serve import run
    from jeanscv_cli.serve.run import run_server

    seen = {}
    monkeypatch.setattr(uvicorn.Server, "run", lambda self, sockets=None: seen.update(host=self.config.host))
    listen = run.listen
    monkeypatch.setattr(run, "listen", lambda host, port: listen("127.0.0.1", 0))  # any host can be bound
    folders = set(Path(tempfile.gettempdir()).glob("jeanscv-serve-*"))
    code = run_server(
        folder=None,
        host=host,
        port=8123,
        open_browser=False,
        max_upload=1 << 20,
        max_pixels=10**6,
        store_bytes=64 << 20,
        workers=1,
        queue=1,
    )
    assert code == 0 and seen["host"] == host
    assert ("WARNING: listening on" in capsys.readouterr().err) is warned
    assert set(Path(tempfile.gettempdir()).glob("jeanscv-serve-*")) == folders  # made only by a started server


def start_server(tmp_path: Path, *args: str) -> tuple[subprocess.Popen, int]:
    """A ``jeanscv serve`` process on a free port, answering; its temporary files under ``tmp_path``."""
    port = free_port()
    server = subprocess.Popen(
        [sys.executable, "-m", "jeanscv", "serve", "--port", str(port), *args],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env={**_env(), "TMPDIR": str(tmp_path)},
    )
    deadline = time.monotonic() + 60
    while True:
        try:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            connection.request("GET", "/api/options")
            assert connection.getresponse().status == 200
            connection.close()
            return server, port
        except OSError:
            if time.monotonic() > deadline or server.poll() is not None:
                server.kill()
                raise AssertionError(f"the server did not start: {server.communicate()[1][-2000:]}") from None
            time.sleep(0.05)


def test_ctrl_c_stops_the_server_cleanly(tmp_path):
    server, port = start_server(tmp_path)
    try:
        server.send_signal(signal.SIGINT)
        code = server.wait(timeout=30)
        err = server.stderr.read()
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    assert code == 0, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    lines = err.splitlines()
    assert lines[0] == f"jeanscv serve: a page to drop photos on at http://127.0.0.1:{port}/ (Ctrl-C stops)"
    assert lines[-1] == "jeanscv serve: stopped"
