"""What the ``-j`` workers' fork server loads once, before it forks them (Linux).

Spawned workers each start a fresh interpreter and import the library, numba and the
kernels themselves (about 1.5 s of CPU each before their first file). A fork server
(:mod:`multiprocessing.forkserver`) imports this module once, while the command is
still finding its files, and forks each worker from that state. ``jeanscv_cli.pool``
names it as the server's preload; importing it does the work.

The kernels are loaded only when they are cached: with an empty cache each worker
compiles them as before (and a run's second compiling process helps, see
:mod:`jeanscv.fitting._fast.ahead`), so the server's workers are not held back half a minute.
Whatever fails here is left to the workers, which import and load what they need anyway.
"""

from __future__ import annotations

import gc


def _preload() -> None:
    try:
        from .. import _command  # noqa: F401  (makes jeanscv_cli importable in a checkout that is not installed)

        _load()
    except Exception:  # noqa: BLE001 - a worker imports and loads for itself what is missing here
        pass
    # Everything loaded so far lives as long as the workers: no collection needs to
    # traverse it again, in the server or in a worker (and a worker's collections then do
    # not touch, and so copy, the pages it shares with the server).
    gc.freeze()


def _load() -> None:
    """Import what every worker imports for its first file, and load the kernels."""
    import cv2

    import jeanscv_cli.worker  # noqa: F401

    from .. import pipeline  # noqa: F401
    from ..fitting import _fast
    from ..io import image, write  # noqa: F401
    from ..subject.scene import prepare_lab_tables

    # The server must hold no OpenCV worker threads when it forks: a child does not
    # inherit them, and with OpenCV 5.1 a child that then lowers its thread count (every
    # worker does, ``init_worker``) waits for them for ever. Building the Lab tables
    # starts OpenCV's pool, so the server keeps to one thread; each worker sets its own
    # share of the cores.
    cv2.setNumThreads(1)
    prepare_lab_tables(wait=True)  # built once here, not in every worker (no thread is left running)
    if _fast.kernels_cached():
        _fast.load_kernels()


_preload()
