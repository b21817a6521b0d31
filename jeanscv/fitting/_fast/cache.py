"""Where the compiled kernels are kept: a per-user cache, never the installed package.

numba's own choice (``cache=True``) is ``__pycache__`` beside the kernels' source, which
for ``pip install .`` is inside site-packages: files pip does not know, which outlive
``pip uninstall`` and leave a ``jeanscv`` folder without ``__init__.py`` that Python then
takes for a namespace package (every later ``jeanscv`` command failed to import). So the
kernels are given a cache of their own (:mod:`.jit`) in this folder::

    ROOT/kernels/VERSION-HASH/

``HASH`` is a digest of the kernels' source files, so two versions or two edits never
share stale machine code (numba's own freshness check is per file and misses a change in
a file a kernel calls into), and two installs of the same source share it. ``ROOT`` is,
in order: ``$JEANSCV_CACHE_DIR``; ``$NUMBA_CACHE_DIR/jeanscv`` (where a user pointed
numba's caches); the per-user cache (``~/.cache/jeanscv`` on Linux, or
``$XDG_CACHE_HOME/jeanscv``); and, where none can be written (a service account without
a home), a private folder under the temporary directory, which ``JEANSCV_CACHE_DIR`` is
then set to so that the processes a run starts use the same one.

Decided without importing numba (the command line asks before it loads anything).
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import stat
import sys
import tempfile
from pathlib import Path

KERNELS = Path(__file__).resolve().parent
"""The folder of the kernels' source files (``objective.py``, ``raster.py``)."""

#: The sources whose machine code the cache holds: every file here, and the two a kernel
#: compiles in from the fitting package (Adam's update, the upright plan's constants).
_SOURCES = ("adam.py", "terms.py")


def _writable(folder: Path) -> bool:
    """numba's own test of a cache folder: create it, then a temporary file in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    return True


@functools.lru_cache(maxsize=4)
def source_key(kernels: Path = KERNELS) -> str:
    """``VERSION-HASH``: jeanscv's version and a digest of the kernels' source files."""
    from ... import __version__

    digest = hashlib.sha256()
    for path in sorted(kernels.glob("*.py")) + [kernels.parent / name for name in _SOURCES]:
        digest.update(path.name.encode() + b"\0")
        try:
            digest.update(path.read_bytes())
        except OSError:  # a test's stand-in folder holds only some of them
            pass
    return f"{__version__}-{digest.hexdigest()[:16]}"


def _user_cache_root() -> Path:
    """The per-user cache folder of jeanscv (the platform's convention)."""
    if sys.platform.startswith("linux") or (os.name == "posix" and sys.platform != "darwin"):
        return Path(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")) / "jeanscv"
    if sys.platform == "darwin":
        return Path(os.path.expanduser("~/Library/Caches")) / "jeanscv"
    local = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~/AppData/Local")
    return Path(local) / "jeanscv" / "Cache"


def _private_temporary_root() -> Path:
    """A cache root only this user can write (compiled code is loaded from it): reused
    across runs when it is this user's own 0700 folder, else a fresh one per process."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    root = Path(tempfile.gettempdir()) / f"jeanscv-cache-{uid}"
    try:
        root.mkdir(mode=0o700, exist_ok=True)
        info = os.lstat(root)
        if stat.S_ISDIR(info.st_mode) and info.st_uid == uid and not info.st_mode & 0o022:
            return root
    except OSError:
        pass
    return Path(tempfile.mkdtemp(prefix="jeanscv-cache-"))


def cache_root() -> Path:
    """The folder that holds jeanscv's caches (see the module's docstring), without
    creating it."""
    if os.environ.get("JEANSCV_CACHE_DIR"):
        return Path(os.environ["JEANSCV_CACHE_DIR"])
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / "jeanscv"
    return _user_cache_root()


def kernel_cache_dir(kernels: Path = KERNELS) -> Path:
    """The folder the kernels of ``kernels`` are cached in, created if need be.

    When the usual place cannot be written, this sets ``JEANSCV_CACHE_DIR`` to a private
    temporary folder, so the kernels still compile and are shared with the processes
    this one starts, and returns the folder under it.
    """
    folder = cache_root() / "kernels" / source_key(kernels)
    if _writable(folder):
        return folder
    root = _private_temporary_root()
    os.environ["JEANSCV_CACHE_DIR"] = str(root)
    folder = root / "kernels" / source_key(kernels)
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def clear_kernel_cache() -> tuple[Path, int, int]:
    """Remove every version's compiled kernels; ``(folder, files, bytes)`` removed.

    The next fit compiles them again (about 25 s on two free cores, once)."""
    folder = cache_root() / "kernels"
    files = size = 0
    if folder.is_dir():
        for path in folder.rglob("*"):
            if path.is_file() and not path.is_symlink():
                files += 1
                size += path.stat().st_size
        shutil.rmtree(folder)
    return folder, files, size
