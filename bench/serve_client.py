"""What the ``jeanscv serve`` benches share: a fresh server in its own process on a free
loopback port, and a tiny HTTP client (the standard library's; loopback only)."""

from __future__ import annotations

import http.client
import json
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def request(
    port: int, method: str, path: str, body: bytes | None = None, headers: dict | None = None, timeout: float = 300
) -> tuple[int, dict, bytes]:
    """(status, headers, body) of one request to the server on loopback ``port``, on a
    new connection."""
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    try:
        connection.request(method, path, body=body, headers=headers or {})
        response = connection.getresponse()
        return response.status, dict(response.getheaders()), response.read()
    finally:
        connection.close()


def upload(port: int, name: str, data: bytes) -> tuple[int, dict, bytes]:
    """:func:`request` that uploads ``data`` as the photo or clip ``name`` (a form, as the
    page sends it)."""
    boundary = secrets.token_hex(12)
    body = (
        (
            f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="{name}"\r\n'
            "Content-Type: application/octet-stream\r\n\r\n"
        ).encode()
        + data
        + f"\r\n--{boundary}--\r\n".encode()
    )
    return request(port, "POST", "/api/photos", body, {"Content-Type": f"multipart/form-data; boundary={boundary}"})


class Server:
    """``python -m jeanscv serve`` on 127.0.0.1 in a child process; ``stop()`` sends Ctrl-C."""

    def __init__(self, *args: str):
        self.port = free_port()
        self.tmp = Path(tempfile.mkdtemp(prefix="jeanscv-bench-"))
        env = {**os.environ, "TMPDIR": str(self.tmp)}  # the server's temporary files land here
        self.stderr = open(self.tmp.parent / f"{self.tmp.name}.log", "w+")  # noqa: SIM115
        self.process = subprocess.Popen(
            [sys.executable, "-m", "jeanscv", "serve", "--port", str(self.port), *args],
            cwd=ROOT,
            env=env,
            stderr=self.stderr,
            stdout=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 120
        while True:
            try:
                status, _, _ = self.request("GET", "/api/options")
                if status == 200:
                    break
            except OSError:
                pass
            if self.process.poll() is not None or time.monotonic() > deadline:
                raise SystemExit(f"the server did not start: {self.log()}")
            time.sleep(0.1)

    def request(self, method: str, path: str, body: bytes | None = None, headers: dict | None = None):
        """(status, headers, body) of one request, on a new connection."""
        return request(self.port, method, path, body, headers)

    def upload(self, name: str, data: bytes):
        return upload(self.port, name, data)

    def render(self, photo: str, objects: list, options: dict | None = None):
        body = json.dumps({"objects": objects, "options": options or {}}).encode()
        return self.request("POST", f"/api/photos/{photo}/render", body, {"Content-Type": "application/json"})

    def memory(self) -> tuple[int, int]:
        """(resident, peak resident) bytes of the server process."""
        values = {}
        with open(f"/proc/{self.process.pid}/status") as status:
            for line in status:
                key, _, rest = line.partition(":")
                if key in ("VmRSS", "VmHWM"):
                    values[key] = int(rest.split()[0]) * 1024
        return values.get("VmRSS", 0), values.get("VmHWM", 0)

    def leftovers(self) -> list[str]:
        """Files the server left in its temporary folder."""
        return sorted(str(p.relative_to(self.tmp)) for p in self.tmp.rglob("*") if not p.is_dir())

    def log(self) -> str:
        self.stderr.flush()
        self.stderr.seek(0)
        return self.stderr.read()

    def remove(self) -> None:
        """Remove the bench's own temporary folder and log (after :meth:`stop`)."""
        import shutil

        self.stderr.close()
        shutil.rmtree(self.tmp, ignore_errors=True)
        Path(self.stderr.name).unlink(missing_ok=True)

    def stop(self) -> tuple[int, float]:
        """Ctrl-C; (exit status, seconds to stop)."""
        began = time.monotonic()
        self.process.send_signal(signal.SIGINT)
        try:
            code = self.process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            code = self.process.wait()
        return code, time.monotonic() - began
