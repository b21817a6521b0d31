"""The server's memory: entries under random ids, bounded in bytes, and the bounded pool
the heavy work runs in."""

from __future__ import annotations

import asyncio
import secrets
import threading
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any


def new_id() -> str:
    """A random id of 128 bits: unguessable, and never derived from what a client sent."""
    return secrets.token_urlsafe(16)


class Store:
    """Entries under random ids, least recently used dropped first past ``max_bytes``.

    ``put`` takes the entry's size in bytes; the newest entry is kept even when it
    alone is over the cap (the page is working on it). Thread-safe.
    """

    def __init__(self, max_bytes: int):
        self.max_bytes = max_bytes
        self._entries: OrderedDict[str, tuple[Any, int]] = OrderedDict()
        self._lock = threading.Lock()

    def put(self, value: Any, nbytes: int) -> str:
        key = new_id()
        with self._lock:
            self._entries[key] = (value, int(nbytes))
            self._evict(keep=key)
        return key

    def resize(self, key: str, nbytes: int) -> None:
        """Record that an entry grew (a click session, a cached download)."""
        with self._lock:
            if key in self._entries:
                self._entries[key] = (self._entries[key][0], int(nbytes))
                self._evict(keep=key)

    def get(self, key: str) -> Any | None:
        with self._lock:
            found = self._entries.get(key)
            if found is None:
                return None
            self._entries.move_to_end(key)
            return found[0]

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def nbytes(self) -> int:
        with self._lock:
            return sum(size for _, size in self._entries.values())

    def _evict(self, keep: str) -> None:
        total = sum(size for _, size in self._entries.values())
        for key in list(self._entries):
            if total <= self.max_bytes:
                break
            if key == keep:
                continue
            total -= self._entries.pop(key)[1]


class Busy(Exception):
    """Every worker is busy and the queue is full: answered 503 with Retry-After."""


class Pool:
    """Threads for the fits and segmentations, with a bounded queue.

    At most ``workers`` jobs run and ``queue`` wait; one more is refused at once with
    :class:`Busy` (the client is told to retry) instead of waiting without end.
    """

    def __init__(self, workers: int, queue: int):
        self.workers = workers
        self.limit = workers + queue
        self._executor = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="jeanscv-serve")
        self._pending = 0
        self._lock = threading.Lock()

    async def run(self, function: Callable, *args) -> Any:
        """``function(*args)`` in a worker thread; :class:`Busy` when the queue is full.

        The slot is freed when the job ends, not when the request does: a client that
        goes away does not free room for more work than the pool can hold.
        """
        return await asyncio.wrap_future(self._submit(function, *args))

    def submit_background(self, function: Callable, *args) -> bool:
        """Run ``function`` when a worker is free, if the queue has room; False if not."""
        try:
            self._submit(function, *args)
        except Busy:
            return False
        return True

    def _submit(self, function: Callable, *args):
        with self._lock:
            if self._pending >= self.limit:
                raise Busy()
            self._pending += 1

        def done(_future) -> None:
            with self._lock:
                self._pending -= 1

        try:
            future = self._executor.submit(function, *args)
        except RuntimeError:  # shutting down
            done(None)
            raise Busy() from None
        future.add_done_callback(done)
        return future

    def shutdown(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)
