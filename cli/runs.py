"""Runs that meet other runs, and runs that were killed.

* Two ``jeanscv`` runs on the same folder: each input is claimed (an advisory lock on
  the input file) while its outputs are made, so the second run waits for that file
  and then skips it, instead of making it again or racing for its output.
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
import signal
import stat
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None


@contextlib.contextmanager
def claim(path: Path) -> Iterator[bool]:
    """Hold an exclusive lock on the input ``path`` inside ``with``; yields whether another
    run held it first (and this one waited for it to finish)."""
    if fcntl is None:
        yield False
        return
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError:
        yield False  # missing or unreadable: processing says why
        return
    try:
        waited = False
        try:
            if stat.S_ISREG(os.fstat(fd).st_mode):
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    waited = True
                    fcntl.flock(fd, fcntl.LOCK_EX)  # another run is making its outputs
        except OSError:
            waited = False  # a file system without locks: go on unclaimed
        yield waited
    finally:
        os.close(fd)  # releases the lock


def remove_leftovers(outputs: Iterable[Path]) -> int:
    """Remove the temporary files killed runs left beside any of ``outputs``; how many."""
    from jeanscv.io.write import remove_stale_temporaries

    by_folder: dict[Path, set[str]] = {}
    for path in outputs:
        by_folder.setdefault(path.parent, set()).add(path.name)
    return sum(len(remove_stale_temporaries(folder, names)) for folder, names in by_folder.items())


def stop_with_parent(interval: float = 1.0) -> None:
    """In a worker process: SIGTERM itself once its parent is gone.

    ProcessPoolExecutor's workers block reading their next file, and they hold the
    queue's write end themselves, so a parent killed with SIGKILL never wakes them: they
    would sleep forever, holding their memory. SIGTERM stops a worker the usual way (a
    file in progress removes its temporary file, see ``worker.init_worker``).
    """
    parent = os.getppid()

    def watch() -> None:
        event = threading.Event()
        while not event.wait(interval):
            if os.getppid() != parent:
                os.kill(os.getpid(), signal.SIGTERM)
                return

    threading.Thread(target=watch, name="jeanscv-parent-watch", daemon=True).start()
