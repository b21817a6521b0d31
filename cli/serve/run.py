"""Start the server: listen first, warn when it is reachable from other machines, open
the page, and stop at once on Ctrl-C or SIGTERM.

Stopping never waits for a photo being worked on: the server answers every waiting and
running request ("the server is stopping"), removes its temporary files and any output
half-written in a folder, and the command then ends the process with ``os._exit``.
Worker threads may be inside OpenCV or numba at that moment; the interpreter's usual
tear-down would wait for them, or (for a daemon thread inside OpenCV) abort the
process with "terminate called without an active exception".
"""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import socket
import threading
import webbrowser
from pathlib import Path

from .guard import is_loopback

#: Longest the request head may take to arrive, from the connection or the last answer (slow clients).
HEAD_SECONDS = 10.0
#: Most connections open at once; more are answered 503 by uvicorn.
MAX_CONNECTIONS = 64


def _say(message: str) -> None:
    from .guard import console

    print(f"jeanscv serve: {message}", file=console(), flush=True)


def default_workers() -> int:
    """Photos worked on at once by default: one per core, at most 4, and at most one
    per 1.5 GB of memory (a 12-MP photo's segmentation and fit peak near 0.6 GB)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        memory = 4 << 30
    return max(1, min(cores, 4, int(memory // (1536 << 20))))


def listen(host: str, port: int) -> socket.socket | str:
    """A socket bound to ``host:port``, or the one-line reason it cannot be (before
    anything else starts: a busy port says so, and nothing is warmed up or printed)."""
    try:
        infos = socket.getaddrinfo(host.strip("[]"), port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError) as exc:
        return f"cannot listen on {host}: {getattr(exc, 'strerror', None) or 'not a name or address'}"
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn: a restart need not wait
        sock.bind(address)
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            return f"port {port} is in use (try --port 0 or another)"
        if exc.errno == errno.EACCES:
            return f"port {port} is reserved for the administrator (try --port 0 or one above 1023)"
        if exc.errno == errno.EADDRNOTAVAIL:
            return f"cannot listen on {host}: not an address of this machine"
        return f"cannot listen on {host}:{port} ({(exc.strerror or str(exc)).lower()})"
    sock.set_inheritable(True)
    return sock


def run_server(
    *,
    folder: Path | None,
    host: str,
    port: int,
    open_browser: bool,
    max_upload: int,
    max_pixels: int,
    store_bytes: int,
    workers: int,
    queue: int,
    job_seconds: float = 120.0,
    debug: bool = False,
) -> int:
    """Serve until Ctrl-C (0) or SIGTERM (143); 1 when it cannot listen. The caller
    should end the process soon after (see the module's docstring)."""
    from .guard import keep_console

    keep_console()  # before any photo is decoded (which silences descriptor 2 meanwhile)
    sock = listen(host, port)
    if isinstance(sock, str):
        _say(sock)
        return 1
    port = sock.getsockname()[1]
    import uvicorn

    from . import engine
    from .app import Config, create_app

    if not is_loopback(host):
        _say(
            f"WARNING: listening on {host}: other machines on the network can reach this page and "
            "upload files to it. Use the default (127.0.0.1) unless you mean that."
        )
    config = Config(
        host=host,
        port=port,
        folder=folder,
        max_upload=max_upload,
        max_pixels=max_pixels,
        store_bytes=store_bytes,
        workers=workers,
        queue=queue,
        job_seconds=job_seconds,
        backend=engine.default_backend(),
        debug=debug,
    )
    app = create_app(config)
    state = app.app.state.jeanscv
    shown = f"[{host}]" if ":" in host else host
    url = f"http://{'127.0.0.1' if host in ('0.0.0.0', '::') else shown}:{port}/"
    what = f"the photos of {folder}" if folder is not None else "a page to drop photos on"
    # From the line that says "Ctrl-C stops" on, a Ctrl-C or SIGTERM stops the server the
    # same way ("stopped", exit 0 or 143), even one that comes before uvicorn takes the
    # signals over (under load the first second after the line; it ended the process
    # without a word).
    early: list[int] = []
    on_main = threading.current_thread() is threading.main_thread()
    before = (
        {sig: signal.signal(sig, lambda sig, frame: early.append(sig)) for sig in (signal.SIGINT, signal.SIGTERM)}
        if on_main
        else {}
    )
    _say(f"{what} at {url} (Ctrl-C stops)")
    if engine.kernels_to_compile():
        _say(
            f"compiling the fit kernels for this installation, once (about {engine.COMPILE_SECONDS} s); the page says so"
        )
    if open_browser:
        opener = threading.Timer(1.0, webbrowser.open, (url,))
        opener.daemon = True
        opener.start()
    server = _server_class()(
        uvicorn.Config(
            app,
            host=host,
            port=port,
            log_level="error",  # the server's own lines say what matters; uvicorn's warnings are noise here
            access_log=False,
            timeout_graceful_shutdown=1,
            timeout_keep_alive=5,
            limit_concurrency=MAX_CONNECTIONS,
            server_header=False,
            lifespan="on",
            http=_protocol(),
        ),
        state,
        early,
    )
    try:
        if not early:
            server.run(sockets=[sock])
    except KeyboardInterrupt:  # a Ctrl-C before the server took the signals over
        pass
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
        state.close()
        sock.close()
    server.stopped_by = server.stopped_by or (early[0] if early else None)
    _say("stopped")
    return 128 + signal.SIGTERM if server.stopped_by == signal.SIGTERM else 0


def _server_class():
    import uvicorn

    class Server(uvicorn.Server):
        """uvicorn's server whose Ctrl-C and SIGTERM stop it at once: waiting and running
        requests are answered first, and the signal is not raised again afterwards."""

        def __init__(self, config, state, early: list[int]) -> None:
            super().__init__(config)
            self.state = state
            self.early = early  # signals that came before capture_signals
            self.stopped_by: int | None = None

        @contextlib.contextmanager
        def capture_signals(self):
            if threading.current_thread() is not threading.main_thread():
                yield
                return

            def handle(sig, frame) -> None:
                if self.stopped_by is None:
                    self.stopped_by = sig
                elif sig == signal.SIGINT:
                    self.force_exit = True
                self.should_exit = True

            previous = {sig: signal.signal(sig, handle) for sig in (signal.SIGINT, signal.SIGTERM)}
            if self.early:
                handle(self.early[0], None)
            try:
                yield
            finally:
                for sig, handler in previous.items():
                    signal.signal(sig, handler)

        async def shutdown(self, sockets=None) -> None:
            self.state.stop()  # every request waiting for a photo's job is answered now
            await super().shutdown(sockets)

    return Server


def _protocol():
    """uvicorn's h11 protocol with a deadline for each request head: a client that sends
    its headers a byte at a time (slow loris) is cut off after :data:`HEAD_SECONDS`."""
    try:
        import h11
        from uvicorn.protocols.http.h11_impl import H11Protocol
    except ImportError:  # pragma: no cover - uvicorn rearranged: its own protocol, without the deadline
        return "h11"

    class TimedH11Protocol(H11Protocol):
        _head_timer = None

        def _arm(self) -> None:
            self._disarm()
            self._head_timer = self.loop.call_later(HEAD_SECONDS, self._head_late)

        def _disarm(self) -> None:
            if self._head_timer is not None:
                self._head_timer.cancel()
                self._head_timer = None

        def _head_late(self) -> None:
            self._head_timer = None
            if self.conn.their_state is h11.IDLE and not self.transport.is_closing():
                self.transport.close()

        def connection_made(self, transport) -> None:
            super().connection_made(transport)
            self._arm()

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self.conn.their_state is not h11.IDLE:
                self._disarm()

        def on_response_complete(self) -> None:
            super().on_response_complete()
            if not self.transport.is_closing() and self.conn.their_state is h11.IDLE:
                self._arm()

        def connection_lost(self, exc) -> None:
            self._disarm()
            super().connection_lost(exc)

    return TimedH11Protocol
