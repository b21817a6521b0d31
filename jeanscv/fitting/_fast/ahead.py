"""A second core compiles the kernels that a first run reaches last.

A first fit compiles the objective's kernels into numba's on-disk cache, one after another,
in the order the objective calls them (half a minute of one core). :func:`start` launches
one more process that compiles the later phases (:func:`objective._stroke_gradient`,
:func:`objective._overlap_sums`) and the compositing's rasterizers while the first run
compiles the earlier ones; each process finds the other's work in the cache when it gets
there (numba reads a kernel's index afresh before compiling it). The code compiled is the
same whichever process compiles it, so the outputs are the same bytes.

Only one such process runs per cache folder (a lock file there); a run that finds the
kernels cached starts none.

    python -m jeanscv.fitting._fast.ahead   # what start() runs
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from .cache import kernel_cache_dir

_LOCK = "ahead.lock"
_STALE_SECONDS = 600.0  # a lock older than this was left by a killed process


def start() -> bool:
    """Launch the compiling process unless one runs for this cache folder; True if launched."""
    lock = kernel_cache_dir() / _LOCK
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        if lock.exists() and time.time() - lock.stat().st_mtime > _STALE_SECONDS:
            lock.unlink(missing_ok=True)
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
    except OSError:  # held by another run, or the cache cannot be written: nothing to share
        return False
    package_root = str(Path(__file__).resolve().parents[3])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [package_root, os.environ.get("PYTHONPATH")]))}
    try:
        subprocess.Popen(
            [sys.executable, "-m", "jeanscv.fitting._fast.ahead"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            env=env,
            close_fds=True,
        )
    except OSError:
        lock.unlink(missing_ok=True)
        return False
    return True


def later_phases() -> list:
    """``(kernel, signature)`` of the objective's last phases as a fit of the jeans on a
    256-px canvas calls them (built from stand-in arguments of the same types)."""
    import numpy as np
    from numba import typeof

    from ..garments import JEANS
    from ..terms import STROKE_HALF_WIDTH
    from . import Objective, scratch
    from .objective import Bands, Crossings, _overlap_sums, _stroke_gradient
    from .raster import BAND_COLUMNS, OUTLINE_POINTS

    size, half_width, n, rows = 256, float(STROKE_HALF_WIDTH), JEANS.num_vertices, 8
    target = Objective(JEANS, "all", {"coverage": 1.0})._target(np.ones((size, size)), half_width)
    work = scratch(size, half_width, n)
    per_edge, per_row, square = np.empty(n, np.int64), np.empty((n, rows), np.int64), np.empty((n, n))
    bands = Bands(per_edge, per_row, per_edge, per_row, per_row, np.empty(n, np.bool_))
    crossings = Crossings(np.empty(16), np.empty(16, np.int64), np.empty(16))
    labels, union, outline = np.empty((2, n), np.bool_), np.zeros((2, 4)), np.empty((OUTLINE_POINTS, 2))
    vertices = np.ascontiguousarray(JEANS.template, dtype=np.float64)
    gradient = (vertices, target, work, -4.5, 260.5, 3, union, np.empty(2), np.empty(n), square, square, labels)
    gradient += (bands, outline, outline, np.empty((rows, BAND_COLUMNS + 1)), crossings, np.zeros((n, 2)))
    overlaps = (target, work, bands, labels, union, square, square)
    return [
        (kernel, tuple(typeof(argument) for argument in arguments))
        for kernel, arguments in ((_stroke_gradient, gradient), (_overlap_sums, overlaps))
    ]


def compile_later_phases() -> None:
    """Compile (without running) the objective's last phases, then the rasterizers that
    compositing calls."""
    from . import load_rasterizers

    for kernel, signature in later_phases():
        kernel.compile(signature)
    load_rasterizers()


if __name__ == "__main__":
    try:
        compile_later_phases()
    finally:
        (kernel_cache_dir() / _LOCK).unlink(missing_ok=True)
