"""The server's front door (pure ASGI middleware): who may ask, how much they may send
and how slowly, and what a failure looks like.

* ``Host`` must name this server: an IP address, ``localhost``, this machine's name or
  the ``--host`` given, with the server's port. A DNS rebinding page reaches the server
  under its own domain name, and is refused (400).
* A request that another site's page sent is refused (403) before it does anything,
  whatever its method: an ``Origin`` other than the server's own, or ``Sec-Fetch-Site``
  ``cross-site`` or ``same-site``. The one exception is following a link to the page
  itself (a top-level navigation to ``/`` or its static files, which do nothing). What
  writes, computes or reads a folder's file is a ``POST`` (or is reached only by an
  unguessable id), so even a browser that sends no ``Sec-Fetch-Site`` sends the
  ``Origin`` that gives it away. No CORS headers are ever sent, so other sites cannot
  read answers either.
* A body over the upload cap is refused (413): at once from ``Content-Length``, else
  as soon as the streamed bytes pass the cap. A body that stalls for ``body_timeout``
  seconds is refused (408); one still arriving when the server stops, 503.
* Every failure is one JSON line ``{"error": reason}``; an unexpected error is answered
  500 and logged as one line (with its traceback under ``--debug``), never sent.
* Every answer carries a strict Content-Security-Policy (the page loads nothing from
  any other host) and ``nosniff``.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import socket
from collections.abc import Iterable

SECURITY_HEADERS = [
    (
        b"content-security-policy",
        b"default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; media-src 'self'; "
        b"connect-src 'self'; form-action 'self'; base-uri 'none'; frame-ancestors 'none'",
    ),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
    (b"cross-origin-resource-policy", b"same-origin"),
]


class TooLarge(Exception):
    """The streamed body passed the cap (the app answers 413)."""

    @staticmethod
    def reason(limit: int) -> str:
        size = f"{limit / (1 << 20):.0f} MB" if limit >= 1 << 20 else f"{limit / 1024:.0f} KB"
        return f"the file is larger than the server's upload limit ({size})"


class BodyRefused(Exception):
    """The body stalled, or the server began stopping while it arrived."""

    def __init__(self, status: int, reason: str):
        super().__init__(reason)
        self.status, self.reason = status, reason


def split_host(value: str) -> tuple[str, int | None]:
    """``name[:port]`` or ``[v6][:port]`` -> (lower-case name, port or None); ('', None) if malformed."""
    value = value.strip().lower()
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return "", None
        name, rest = value[1:end], value[end + 1 :]
        if rest and not rest.startswith(":"):
            return "", None
        port = rest[1:] if rest else None
    elif value.count(":") == 1:
        name, port = value.split(":")
    elif ":" in value:
        return "", None
    else:
        name, port = value, None
    if port is not None:
        if not port.isdigit() or not 0 < int(port) < 65536:
            return "", None
        return name, int(port)
    return name, None


def is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def is_loopback(host: str) -> bool:
    """Whether ``--host`` keeps the server on this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def own_names(bind_host: str) -> frozenset[str]:
    """Host names (besides IP addresses) that may reach this server."""
    names = {"localhost", bind_host.strip("[]").lower()}
    try:
        names.add(socket.gethostname().lower())
        names.add(socket.getfqdn().lower())
    except OSError:
        pass
    return frozenset(n for n in names if n)


class Guard:
    """Wraps the app: Host and cross-site checks, the body cap and time limit, one error
    format, the security headers.

    ``pages``: paths of the static page a link from another site may open;
    ``stopping``: an object whose ``stopped`` says the server is stopping (its pool).
    """

    def __init__(
        self,
        app,
        *,
        names: Iterable[str],
        port: int | None,
        max_body: int,
        pages: frozenset[str] = frozenset(),
        stopping=None,
        body_timeout: float = 30.0,
        debug: bool = False,
    ):
        self.app = app
        self.names = frozenset(names)
        self.port = port
        self.max_body = max_body
        self.pages = pages
        self.stopping = stopping
        self.body_timeout = body_timeout
        self.debug = debug

    def host_allowed(self, host: str) -> bool:
        name, port = split_host(host)
        if not name:
            return False
        if self.port and port is not None and port != self.port:
            return False
        return is_ip(name) or name in self.names

    def cross_site(self, scope, headers: dict[str, str], host: str) -> str:
        """Why another site's page sent this request ('' if it did not)."""
        navigation = scope["method"] == "GET" and scope["path"] in self.pages
        navigation = navigation and headers.get("sec-fetch-mode", "navigate") == "navigate"
        origin = headers.get("origin")
        if origin is not None and origin != f"{scope.get('scheme', 'http')}://{host}" and not navigation:
            return "Origin"
        if headers.get("sec-fetch-site") in ("cross-site", "same-site") and not navigation:
            return "Sec-Fetch-Site"
        return ""

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        host = headers.get("host", "")
        if not self.host_allowed(host):
            return await _refuse(send, 400, "this server answers only to its own address (Host refused)")
        which = self.cross_site(scope, headers, host)
        if which:
            return await _refuse(send, 403, f"requests from other sites are refused ({which})")
        length = headers.get("content-length")
        if length is not None:
            if not length.isdigit():
                return await _refuse(send, 400, "bad Content-Length")
            if int(length) > self.max_body:
                return await _refuse(send, 413, self._too_large())
        received = 0
        started = False

        async def counted_receive():
            nonlocal received
            message = await self._receive(receive)
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_body:
                    raise TooLarge()
            return message

        async def headed_send(message):
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                message = {**message, "headers": list(message.get("headers", [])) + SECURITY_HEADERS}
            await send(message)

        try:
            await self.app(scope, counted_receive, headed_send)
        except TooLarge:
            if not started:
                await _refuse(send, 413, self._too_large())
        except BodyRefused as exc:
            if not started:
                await _refuse(send, exc.status, exc.reason)
        except Exception as exc:  # noqa: BLE001 - a bug: one line on the terminal, never a traceback to the client
            log_unexpected(exc, f"{scope['method']} {scope['path'][:80]}", self.debug)
            if not started:
                await _refuse(send, 500, UNEXPECTED)

    async def _receive(self, receive):
        """The next body message; BodyRefused when it stalls or the server stops."""
        waited = 0.0
        pending = asyncio.ensure_future(receive())
        try:
            while True:
                done, _ = await asyncio.wait({pending}, timeout=0.25)
                if done:
                    return pending.result()
                waited += 0.25
                if self.stopping is not None and self.stopping.stopped:
                    raise BodyRefused(503, "the server is stopping")
                if waited >= self.body_timeout:
                    raise BodyRefused(408, f"the upload stalled for {self.body_timeout:g} s")
        finally:
            if not pending.done():
                pending.cancel()

    def _too_large(self) -> str:
        return TooLarge.reason(self.max_body)


#: What a client is told of an unexpected error (the terminal gets the one line).
UNEXPECTED = "unexpected error (the server's terminal says more)"


_console = None


def keep_console() -> None:
    """Keep a copy of the terminal's file descriptor 2 for the server's own lines.

    While a photo is decoded, the decoders' own complaints are silenced by pointing
    descriptor 2 at /dev/null for the whole process (``jeanscv.io.image``); a line the
    server printed then (its "stopped" on a Ctrl-C during an upload) was lost."""
    import os
    import sys

    global _console
    try:
        _console = os.fdopen(os.dup(sys.stderr.fileno()), "w", encoding="utf-8", errors="replace", buffering=1)
    except (OSError, ValueError, AttributeError):  # no real descriptor 2 (embedded): sys.stderr then
        _console = None


def console():
    """Where the server's own lines go: the kept terminal (:func:`keep_console`), else
    ``sys.stderr``."""
    import sys

    return _console or sys.stderr


def log_unexpected(exc: BaseException, where: str, debug: bool) -> None:
    """One line on the terminal for an error that is not a bad input (the command line's
    reason for it); the traceback too with ``--debug``. A client gets only :data:`UNEXPECTED`
    or the one-line reason."""
    import traceback

    from jeanscv.run.runner import failure_reason  # only when an error happens

    print(f"jeanscv serve: {where}: {failure_reason(exc)}", file=console(), flush=True)
    if debug:
        traceback.print_exception(exc, file=console())


async def _refuse(send, status: int, reason: str) -> None:
    body = json.dumps({"error": reason}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    try:
        await send({"type": "http.response.start", "status": status, "headers": headers + SECURITY_HEADERS})
        await send({"type": "http.response.body", "body": body})
    except (OSError, RuntimeError):  # the client has gone: nobody to tell
        pass
