"""The server's memory: entries under random ids, bounded in bytes, and the bounded pool
the heavy work runs in."""

from __future__ import annotations

import asyncio
import secrets
import threading
from collections import OrderedDict, deque
from collections.abc import Callable
from concurrent.futures import Future
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


class FolderCuts:
    """auto's hypotheses of the folder photos worked on last, by file name: one
    :class:`~jeanscv.subject.photo.SharedHypotheses` per photo for its thumbnail's
    output, the page's automatic result and click session, and the outputs its saved
    (or reverted) clicks make, so the photo is cut once instead of four or five times
    (a second on a 12-MP photo each). A file changed meanwhile gives another working
    copy, which is cut anew (they are compared pixel for pixel). The latest ``keep`` are
    held (about 7 MB each, whatever the photo's size). Thread-safe."""

    def __init__(self, keep: int = 4):
        self.keep = keep
        self._held: OrderedDict[str, Any] = OrderedDict()
        self._lock = threading.Lock()

    def of(self, name: str):
        """The hypotheses held for the folder photo ``name`` (empty at first)."""
        from jeanscv.subject.photo import SharedHypotheses

        with self._lock:
            shared = self._held.pop(name, None) or SharedHypotheses()
            self._held[name] = shared  # the most recently used last
            while len(self._held) > self.keep:
                self._held.popitem(last=False)
            return shared


class Busy(Exception):
    """The queue is full, or a request waited its longest: answered 503 with Retry-After."""


class Stopping(Exception):
    """The server is stopping: waiting and running requests are answered 503 at once."""


class TooSlow(Exception):
    """A job ran past the per-job time limit: the request is answered 504 (the thread
    runs on, its slot taken, until the job ends; its result is dropped)."""


class Pool:
    """Worker threads for the fits and segmentations, with a fair, bounded queue.

    * At most ``workers`` jobs run. A request's job waits its turn in arrival order
      (first in, first out); one that finds ``queue`` jobs already waiting, or that waits
      longer than ``max_wait`` seconds, is refused with :class:`Busy` (503 Retry-After).
    * Background jobs (a click session made ahead) run only on a worker that no
      request is waiting for, and at most ``background`` of them wait; the oldest is
      dropped for a newer one.
    * A request waits at most ``job_seconds`` for its running job (:class:`TooSlow`).
    * :meth:`stop` answers every waiting and running request with :class:`Stopping`
      at once. The threads are daemons: the server does not wait for a running job.

    The server has two: the photos' and the clips' (a clip's making runs for seconds to
    minutes, so photos never wait behind one); ``name`` names the threads.
    """

    def __init__(
        self,
        workers: int,
        queue: int,
        *,
        max_wait: float = 30.0,
        job_seconds: float = 120.0,
        background: int = 4,
        name: str = "jeanscv-serve",
    ):
        self.workers = workers
        self.queue = queue
        self.max_wait = max_wait
        self.job_seconds = job_seconds
        self.background_limit = background
        self._lock = threading.Condition()
        self._waiting: deque = deque()  # requests' jobs, in arrival order: (future, function, args, on_start)
        self._background: deque = deque()
        self._running = 0
        self._stopped = False
        self._stop_events: list = []  # (loop, asyncio.Event) of the loops that ran requests
        for index in range(workers):
            threading.Thread(target=self._work, name=f"{name}-{index}", daemon=True).start()

    @property
    def stopped(self) -> bool:
        return self._stopped

    def retry_after(self) -> int:
        """Seconds a refused client should wait before it asks again (1-30)."""
        with self._lock:
            return int(min(30, max(1, 2 * (len(self._waiting) + 1) // max(1, self.workers))))

    async def run(self, function: Callable, *args) -> Any:
        """``function(*args)`` in a worker thread, in arrival order; raises :class:`Busy`,
        :class:`TooSlow` or :class:`Stopping` as the class says."""
        loop = asyncio.get_running_loop()
        stop = self._stop_event(loop)
        future: Future = Future()
        started = asyncio.Event()
        with self._lock:
            if self._stopped:
                raise Stopping()
            if len(self._waiting) >= self.queue and self._running >= self.workers:
                raise Busy()
            self._waiting.append((future, function, args, lambda: loop.call_soon_threadsafe(started.set)))
            self._lock.notify()
        answer = asyncio.wrap_future(future, loop=loop)
        stopping = asyncio.ensure_future(stop.wait())
        taken = asyncio.ensure_future(started.wait())
        try:
            done, _ = await asyncio.wait(
                {answer, stopping, taken}, timeout=self.max_wait, return_when="FIRST_COMPLETED"
            )
            if stopping in done:
                raise Stopping()
            if not done and future.cancel():  # still waiting after max_wait: give its place up
                raise Busy()
            begun = loop.time()
            done, _ = await asyncio.wait({answer, stopping}, timeout=self.job_seconds, return_when="FIRST_COMPLETED")
            if answer in done:
                return answer.result()
            if stopping in done:
                raise Stopping()
            raise TooSlow(f"{loop.time() - begun:.0f} s")
        finally:
            for waiter in (stopping, taken, answer):
                if not waiter.done():
                    waiter.cancel()  # the job itself runs on if it started; its result is dropped

    def submit_background(self, function: Callable, *args) -> None:
        """Run ``function(*args)`` when a worker has nothing a request is waiting for."""
        with self._lock:
            if self._stopped:
                return
            if len(self._background) >= self.background_limit:
                self._background.popleft()
            self._background.append((Future(), function, args, None))
            self._lock.notify()

    def _work(self) -> None:
        while True:
            with self._lock:
                while not (self._stopped or self._waiting or self._background):
                    self._lock.wait()
                if self._stopped:
                    return
                future, function, args, on_start = (self._waiting or self._background).popleft()
                if not future.set_running_or_notify_cancel():
                    continue  # its request gave up waiting
                self._running += 1
            try:
                if on_start is not None:
                    on_start()
                result = function(*args)
            except BaseException as exc:  # noqa: BLE001 - handed to the waiting request
                future.set_exception(exc)
            else:
                future.set_result(result)
            finally:
                with self._lock:
                    self._running -= 1

    def _stop_event(self, loop) -> asyncio.Event:
        with self._lock:
            for known, event in self._stop_events:
                if known is loop:
                    return event
            event = asyncio.Event()
            if self._stopped:
                event.set()
            self._stop_events.append((loop, event))
            return event

    def stop(self) -> None:
        """Refuse new jobs, drop the waiting ones and answer every waiting or running
        request with :class:`Stopping`, now; running jobs are abandoned."""
        with self._lock:
            self._stopped = True
            dropped = list(self._waiting) + list(self._background)
            self._waiting.clear()
            self._background.clear()
            self._lock.notify_all()
            events = list(self._stop_events)
        for future, *_ in dropped:
            future.cancel()
        for loop, event in events:
            try:
                loop.call_soon_threadsafe(event.set)
            except RuntimeError:  # that loop is closed: nobody waits on it
                pass
