"""How the server says no, names a download and reads a JSON body: the one-line JSON
refusal (no path of this machine in it), the Content-Disposition of a download and a
request's JSON object. Shared by the HTTP layer (:mod:`.app`) and its clip and folder
endpoints (:mod:`.clips`, :mod:`.folder`)."""

from __future__ import annotations

import json
import re

from starlette.requests import Request
from starlette.responses import JSONResponse

from jeanscv.errors import JeansError, NothingFound


class Refused(Exception):
    """Answer the request with ``{"error": reason}`` and ``status`` (raised anywhere in a
    handler; the one way the server says no)."""

    def __init__(self, status: int, reason: str, headers: dict | None = None):
        super().__init__(reason)
        self.status, self.reason, self.headers = status, reason, headers


def error(status: int, reason: str, **headers) -> JSONResponse:
    return JSONResponse({"error": client_text(reason)}, status_code=status, headers=headers or None)


#: An absolute file path inside a message: shown to a client as its last part only.
_ABSOLUTE_PATH = re.compile(r"(?<![\w.:/])/(?:[^\s'\"/<>]+/)+([^\s'\"/<>]*)")


def client_text(reason: str) -> str:
    """A reason fit for a web client: one line, short, no absolute path of this machine."""
    text = " ".join(str(reason).split())
    return _ABSOLUTE_PATH.sub(lambda match: match.group(1) or "(a folder)", text)[:500]


def nothing_found(exc: Exception) -> bool:
    """Whether ``exc`` says that clicks found nothing (a click or a box on plain
    background, or negative clicks that leave nothing): an outcome the page shows, not
    a bad request."""
    return isinstance(exc, NothingFound)


def attachment(filename: str) -> str:
    """A Content-Disposition that saves the answer as ``filename`` (its ASCII letters)."""
    ascii_name = "".join(c if c.isascii() and c.isprintable() and c not in '"\\' else "_" for c in filename)
    return f'attachment; filename="{ascii_name}"'


async def json_object(request: Request) -> dict:
    """The request's JSON object body, else JeansError saying why."""
    body = await request.body()
    try:
        data = json.loads(body or b"{}")
    except (ValueError, UnicodeDecodeError, RecursionError):  # RecursionError: brackets nested 100,000 deep
        raise JeansError("the request body is not valid JSON") from None
    if not isinstance(data, dict):
        raise JeansError("expected a JSON object")
    return data


__all__ = ["Refused", "attachment", "client_text", "error", "json_object", "nothing_found"]
