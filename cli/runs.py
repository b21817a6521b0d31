"""Runs that meet other runs, and runs that were killed.

* Two ``jeanscv`` runs on the same folder: each input is claimed (an advisory lock on
  the input file) while its outputs are made. A run that finds a file claimed puts it
  off and goes on with the next (:class:`WorkQueue`), so the two runs work on different
  files; at the end it comes back to the files it put off, waits for the other run if it
  still holds them, and skips what it made, instead of making it again or racing for its
  output.
* A run killed with SIGKILL (or a power loss) leaves the temporary file it was writing;
  the next run on that output folder removes it (only unlocked ones: never those of a
  live run).
* A ``-j`` worker whose parent was killed stops instead of waiting forever for work.

Locks are released by the kernel when their holder dies, so a killed run never leaves
one behind. Where advisory locks do not exist (Windows) or the file system refuses them,
runs go on without them.
"""

from __future__ import annotations

import contextlib
import os
import select
import signal
import stat
import threading
from collections import deque
from collections.abc import Iterable, Iterator
from pathlib import Path

from .discover import is_own_output

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None


@contextlib.contextmanager
def claim(path: Path, wait: bool = True) -> Iterator[bool]:
    """Hold an exclusive lock on the input ``path`` inside ``with``; yields whether this run
    may make its outputs. Another run that holds it first is waited for, or, without
    ``wait``, yields False at once (and nothing is held)."""
    if fcntl is None:
        yield True
        return
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        yield True  # missing or unreadable: processing says why
        return
    try:
        ours = True
        try:
            if stat.S_ISREG(os.fstat(fd).st_mode):
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    if wait:
                        fcntl.flock(fd, fcntl.LOCK_EX)  # another run is making its outputs
                    else:
                        ours = False
        except OSError:
            ours = True  # a file system without locks: go on unclaimed
        yield ours
    finally:
        os.close(fd)  # releases the lock


class WorkQueue:
    """The order in which a run takes its jobs: ``jobs`` as they come (made lazily), then
    the jobs another run held when their turn came.

    :meth:`next` gives ``(job, wait)``: whether to wait for another run that holds the
    file's claim. First turns do not wait; a job whose outcome is ``busy`` is put off to
    the end (:meth:`finish`), where it waits. Two runs on one folder thus work on
    different files instead of queueing behind each other on the same ones.
    """

    def __init__(self, jobs: Iterable, progress, outcomes: dict):
        self._jobs = iter(jobs)
        self._first: deque[tuple[object, bool]] = deque()  # looked ahead at, or given back
        self._later: deque = deque()  # busy elsewhere when their turn came
        self.progress = progress
        self._outcomes = outcomes

    def look_ahead(self, count: int) -> int:
        """Make sure the next ``count`` jobs are known (fewer when the run has fewer); how many."""
        while len(self._first) < count:
            job = next(self._jobs, None)
            if job is None:
                break
            self._first.append((job, False))
        return len(self._first)

    def next(self) -> tuple | None:
        """The next ``(job, wait)``, or None when nothing is left to start."""
        if self._first:
            return self._first.popleft()
        job = next(self._jobs, None)
        if job is not None:
            return job, False
        if self._later:
            return self._later.popleft(), True
        return None

    def again(self, items: Iterable[tuple]) -> None:
        """Put unfinished ``(job, wait)`` items back at the front (a worker died under them)."""
        self._first.extendleft(reversed(list(items)))

    def finish(self, job, outcome) -> None:
        """Count and report ``job``'s outcome; a ``busy`` one is put off to the end."""
        if outcome.status == "busy":
            self._later.append(job)
            return
        self._outcomes[job.index] = outcome
        self.progress.finish(outcome)


def remove_leftovers(outputs: Iterable[Path]) -> int:
    """Remove the temporary files killed runs left beside any of ``outputs``; how many."""
    from jeanscv.io.write import remove_stale_temporaries

    by_folder: dict[Path, set[str]] = {}
    for path in outputs:
        by_folder.setdefault(path.parent, set()).add(path.name)
    return sum(len(remove_stale_temporaries(folder, names)) for folder, names in by_folder.items())


class _OutputNames:
    """Every jeanscv output's name (``NAME.jeans.EXT``), as a container of names."""

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and is_own_output(Path(name))


def remove_leftovers_in(folder: Path) -> int:
    """Remove the temporary files killed runs left for any jeanscv output in ``folder``;
    how many. One look at the folder, before this run writes there: a folder of 10,000
    outputs is not listed once for each."""
    from jeanscv.io.write import remove_stale_temporaries

    return len(remove_stale_temporaries(folder, _OutputNames()))


def stop_with_parent(parent: int | None = None, interval: float = 1.0) -> None:
    """In a worker process: SIGTERM itself once the run ``parent`` (default: its parent
    process) is gone.

    ProcessPoolExecutor's workers block reading their next file, and they hold the
    queue's write end themselves, so a parent killed with SIGKILL never wakes them: they
    would sleep forever, holding their memory. SIGTERM stops a worker the usual way (a
    file in progress removes its temporary file, see ``worker.init_worker``). A worker
    forked by the fork server is the server's child, and the server lives as long as its
    workers do, so the run's own process is watched: through a pidfd where there is one
    (no polling, no confusion with a later process of the same pid), else every
    ``interval`` seconds.
    """
    parent = os.getppid() if parent is None else parent
    try:
        handle = os.pidfd_open(parent)
    except (AttributeError, OSError):  # not Linux 5.3+, or gone already
        handle = None

    def watch() -> None:
        if handle is not None:
            select.select([handle], [], [])  # readable once the parent has exited
        else:
            event = threading.Event()
            while _running(parent) and not event.wait(interval):
                pass
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="jeanscv-parent-watch", daemon=True).start()


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists and has not exited (a zombie has)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True  # no /proc: it exists
