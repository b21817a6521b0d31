"""The ``-j`` worker processes: a pool of workers, and what happens when one dies.

On Linux the workers are forked from a fork server that has loaded the library and the
cached kernels once (:mod:`jeanscv.run._forkserver`), started as soon as the command line
says several inputs may come (:func:`start_early`), while the parent finds its files.
Elsewhere they are spawned, each a fresh interpreter. Each worker gets its share of the
cores (``worker.init_worker``). A worker that dies (killed, out of memory, a crash in a
C library) breaks the pool, and with it every file not yet finished; those run again
rather than fail (:func:`run_parallel`).

A fork server keeps the environment it started with: a process that runs the command
more than once (tests, an embedding program) gets workers with the environment of the
first run that started it.
"""

from __future__ import annotations

import contextlib
import os
import queue as queues
import signal
import sys
import threading
from collections.abc import Iterator

#: Files handed to the pool per worker ahead of their turn: enough that a worker does not
#: wait for the parent between small files on a busy machine, few enough that the first
#: file starts at once and a big folder is not all queued up front.
_AHEAD = 32


def run_parallel(queue, options, overwrite: bool, workers: int) -> None:
    """Process the jobs of ``queue`` (a :class:`runs.WorkQueue`) in ``workers``
    processes, each with its share of the cores.

    A worker that dies (killed, out of memory, a crash in a C library) breaks the pool, and
    every file not yet finished with it. Those run again in a fresh pool, and the files
    after them too; what a second broken pool leaves runs one file at a time, so that only
    a file that kills its worker every time fails (``worker process died``), not the files
    queued beside it.
    """
    from .runs import remove_leftovers

    def sweep(items) -> None:  # a dead worker could not remove its temporary file; its lock went with it
        remove_leftovers([path for job, _ in items for path in job.outputs.values()])

    left = _pool_round(queue, options, overwrite, workers)
    if left:
        sweep(left)
        queue.again(left)
        left = _pool_round(queue, options, overwrite, workers)
    if left:
        sweep(left)
        queue.again(left)
        _one_at_a_time(queue, options, overwrite)


def _context():
    """The workers' start method: the fork server on Linux, started if it is not running
    yet; spawn elsewhere (fork is not safe on macOS with its system libraries, and Windows
    has only spawn), and where the server cannot start (it listens on a Unix socket)."""
    import multiprocessing

    if sys.platform.startswith("linux") and "forkserver" in multiprocessing.get_all_start_methods():
        from multiprocessing import forkserver

        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["jeanscv.run._forkserver"])
        try:
            forkserver.ensure_running()
            return context
        except Exception:  # noqa: BLE001 - any reason it cannot start: spawned workers need none of it
            pass
    return multiprocessing.get_context("spawn")


def start_early() -> None:
    """Start the fork server now (where workers are forked), so that it loads the library
    and the kernels while the parent is still finding the files; the pool's first worker
    then forks at once instead of waiting for a fresh interpreter's imports. When no pool
    comes, the server stops with the parent."""
    _context()


def _new_pool(workers: int):
    from concurrent.futures import ProcessPoolExecutor

    from jeanscv._command import worker_init

    threads = max(1, (os.cpu_count() or 1) // workers)
    return ProcessPoolExecutor(
        max_workers=workers,
        mp_context=_context(),
        initializer=worker_init,
        initargs=(threads, os.getpid()),
    )


class _Signal:
    """A signal's note in a pool's queue of finished files (see :func:`_signals_noted`)."""

    def __init__(self, number: int, handler) -> None:
        self.number, self.handler = number, handler

    def act(self) -> None:
        """Do what the signal's own handler does (raise KeyboardInterrupt, say), here."""
        self.handler(self.number, None)


@contextlib.contextmanager
def _signals_noted(finished: queues.SimpleQueue) -> Iterator[None]:
    """While the pool runs, Ctrl-C and SIGTERM put a :class:`_Signal` in ``finished``
    instead of raising where the main thread happens to be.

    An exception raised by a signal handler can land inside concurrent.futures while it
    holds a future's lock (``wait()`` takes each future's lock in turn): the pool's
    manager thread then blocks on that lock for ever as it cancels the queued files,
    and the process never exits (seen once in some 160 interrupted runs). Noted here,
    the signal is acted on when the loop takes the note from the queue, with no lock
    held. ``SimpleQueue.put`` may be called from a signal handler (it is reentrant).
    Only Python-level handlers are replaced, and only in the main thread.
    """
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for number in (signal.SIGINT, signal.SIGTERM):
            handler = signal.getsignal(number)
            if callable(handler):
                previous[number] = handler
                signal.signal(number, lambda n, frame, h=handler: finished.put(_Signal(n, h)))
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _next_finished(finished: queues.SimpleQueue):
    """The next finished future; a signal noted meanwhile acts here."""
    item = finished.get()
    while isinstance(item, _Signal):
        item.act()  # raises, unless its handler only records the signal
        item = finished.get()
    return item


def _act_on_noted(finished: queues.SimpleQueue) -> None:
    """Act on a signal noted after the last file finished."""
    while True:
        try:
            item = finished.get_nowait()
        except queues.Empty:
            return
        if isinstance(item, _Signal):
            item.act()


def _pool_round(queue, options, overwrite: bool, workers: int) -> list:
    """Process the jobs of ``queue`` in a fresh pool, some ahead of the workers, so the
    first file starts while later ones are still being found; returns the ``(job, wait)``
    items a dying worker left unfinished (then nothing more is taken from ``queue``)."""
    from concurrent.futures.process import BrokenProcessPool

    from .worker import process_in_worker

    pool = _new_pool(workers)
    clean = False
    running: dict = {}  # future -> (job, wait)
    finished: queues.SimpleQueue = queues.SimpleQueue()  # futures as they finish (their done-callbacks)
    left: list = []
    try:
        with _signals_noted(finished):
            queue.progress.start(f"{workers} workers")
            while True:
                while not left and len(running) < _AHEAD * workers and (item := queue.next()) is not None:
                    future = pool.submit(process_in_worker, item[0], options, overwrite, item[1])
                    running[future] = item
                    future.add_done_callback(finished.put)
                if not running:
                    break
                future = _next_finished(finished)
                job, wait = item = running.pop(future)
                try:
                    outcome = future.result()
                except BrokenProcessPool:
                    left.append(item)
                    continue
                except Exception as exc:  # noqa: BLE001 - this file failed in its worker (unpicklable, say)
                    outcome = _died(job, exc)
                queue.finish(job, outcome)
            _act_on_noted(finished)
        clean = True
    finally:
        if clean:
            pool.shutdown(wait=True)
        else:
            _stop_pool(pool)
    return sorted(left, key=lambda item: item[0].index)


def _one_at_a_time(queue, options, overwrite: bool) -> None:
    """Process the jobs of ``queue`` one by one in a single worker: a file whose worker dies
    fails alone."""
    from concurrent.futures.process import BrokenProcessPool

    from .runs import remove_leftovers
    from .worker import process_in_worker

    pool = None
    finished: queues.SimpleQueue = queues.SimpleQueue()  # as in _pool_round
    try:
        with _signals_noted(finished):
            while (item := queue.next()) is not None:
                job, wait = item
                pool = pool or _new_pool(1)
                future = pool.submit(process_in_worker, job, options, overwrite, wait)
                future.add_done_callback(finished.put)
                _next_finished(finished)
                try:
                    outcome = future.result()
                except BrokenProcessPool as exc:
                    outcome = _died(job, exc)
                    pool.shutdown(wait=True)
                    pool = None
                    remove_leftovers(job.outputs.values())
                except Exception as exc:  # noqa: BLE001 - as in _pool_round
                    outcome = _died(job, exc)
                queue.finish(job, outcome)
            _act_on_noted(finished)
    except BaseException:
        if pool is not None:
            _stop_pool(pool)
            pool = None
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True)


def _died(job, exc: BaseException):
    """The outcome of a file whose worker died under it (or could not take it)."""
    from .worker import Outcome

    return Outcome(job.index, job.display, "failed", error=f"worker process died ({type(exc).__name__})")


def _stop_pool(pool) -> None:
    """Cancel queued files and stop the workers; a worker mid-file removes its temporary file."""
    processes = list(getattr(pool, "_processes", {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()  # SIGTERM: see worker.init_worker
    for process in processes:
        process.join(timeout=10)
        if process.is_alive():
            process.kill()
    if manager is not None:
        # The pool's manager thread closes its wake-up pipe as it ends; at the
        # interpreter's exit concurrent.futures writes to that pipe unless the thread has
        # ended, and a close between its check and its write printed a traceback
        # ("Bad file descriptor", Python 3.11). With the workers gone the thread ends at once.
        manager.join(timeout=10)
