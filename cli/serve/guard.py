"""The server's front door (pure ASGI middleware): who may ask, and how much they may send.

* ``Host`` must name this server: an IP address, ``localhost``, this machine's name or
  the ``--host`` given, with the server's port. A DNS rebinding page reaches the server
  under its own domain name, and is refused (400).
* A ``POST`` whose ``Origin`` (or ``Sec-Fetch-Site``) says another site sent it is
  refused (403). No CORS headers are ever sent, so other sites cannot read answers.
* A body over the upload cap is refused (413): at once from ``Content-Length``, else
  as soon as the streamed bytes pass the cap.
* Every answer carries a strict Content-Security-Policy (the page loads nothing from
  any other host) and ``nosniff``.
"""

from __future__ import annotations

import ipaddress
import json
import socket
from collections.abc import Iterable

SECURITY_HEADERS = [
    (
        b"content-security-policy",
        b"default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; "
        b"connect-src 'self'; form-action 'self'; base-uri 'none'; frame-ancestors 'none'",
    ),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
    (b"x-frame-options", b"DENY"),
    (b"cross-origin-resource-policy", b"same-origin"),
]
_UNSAFE_METHODS = frozenset({"POST", "PUT", "PATCH", "DELETE"})


class TooLarge(Exception):
    """The streamed body passed the cap (the app answers 413)."""

    @staticmethod
    def reason(limit: int) -> str:
        size = f"{limit / (1 << 20):.0f} MB" if limit >= 1 << 20 else f"{limit / 1024:.0f} KB"
        return f"the file is larger than the server's upload limit ({size})"


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
    """Wraps the app: Host and Origin checks, the body cap, the security headers."""

    def __init__(self, app, *, names: Iterable[str], port: int | None, max_body: int):
        self.app = app
        self.names = frozenset(names)
        self.port = port
        self.max_body = max_body

    def host_allowed(self, host: str) -> bool:
        name, port = split_host(host)
        if not name:
            return False
        if self.port and port is not None and port != self.port:
            return False
        return is_ip(name) or name in self.names

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        host = headers.get("host", "")
        if not self.host_allowed(host):
            return await _refuse(send, 400, "this server answers only to its own address (Host refused)")
        if scope["method"] in _UNSAFE_METHODS:
            origin = headers.get("origin")
            if origin is not None and origin != f"{scope.get('scheme', 'http')}://{host}":
                return await _refuse(send, 403, "requests from other sites are refused (Origin)")
            if headers.get("sec-fetch-site") == "cross-site":
                return await _refuse(send, 403, "requests from other sites are refused (Sec-Fetch-Site)")
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
            message = await receive()
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

    def _too_large(self) -> str:
        return TooLarge.reason(self.max_body)


async def _refuse(send, status: int, reason: str) -> None:
    body = json.dumps({"error": reason}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers + SECURITY_HEADERS})
    await send({"type": "http.response.body", "body": body})
