"""Where numba keeps the compiled kernels, decided without importing numba.

numba (``cache=True``) tries, in order: ``$NUMBA_CACHE_DIR``, ``__pycache__`` beside the
kernels' source, then its per-user cache (``~/.cache/numba`` on Linux). An installation
that cannot be written (a read-only site-packages, another user's) falls through to the
per-user cache; when that cannot be written either (a service account without a home),
numba refuses to define the kernels at all, and every fit failed with an ImportError. Then
a private folder under the temporary directory is used (``NUMBA_CACHE_DIR`` is set to it).
"""

from __future__ import annotations

import hashlib
import os
import stat
import sys
import tempfile
from pathlib import Path

KERNELS = Path(__file__).resolve().parent
"""The folder of the kernels' source files (``objective.py``, ``raster.py``)."""


def _writable(folder: Path) -> bool:
    """numba's own test of a cache folder: create it, then a temporary file in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    return True


def _subpath(kernels: Path) -> str:
    """numba's name for a source folder's cache under a cache root (_CacheLocator)."""
    path = os.path.abspath(kernels)
    return f"{os.path.basename(path)}_{hashlib.sha1(path.encode()).hexdigest()}"


def _user_cache_root() -> Path:
    """numba's per-user cache root (numba.misc.appdirs.user_cache_dir("numba"))."""
    if sys.platform.startswith("linux") or (os.name == "posix" and sys.platform != "darwin"):
        return Path(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache")) / "numba"
    from numba.misc.appdirs import user_cache_dir  # macOS, Windows: ask numba

    return Path(user_cache_dir("numba", appauthor=False))


def _private_temporary_root() -> Path:
    """A cache root only this user can write (compiled code is loaded from it): reused
    across runs when it is this user's own 0700 folder, else a fresh one per process."""
    uid = os.getuid() if hasattr(os, "getuid") else 0
    root = Path(tempfile.gettempdir()) / f"jeanscv-numba-{uid}"
    try:
        root.mkdir(mode=0o700, exist_ok=True)
        info = os.lstat(root)
        if stat.S_ISDIR(info.st_mode) and info.st_uid == uid and not info.st_mode & 0o022:
            return root
    except OSError:
        pass
    return Path(tempfile.mkdtemp(prefix="jeanscv-numba-"))


def kernel_cache_dir(kernels: Path = KERNELS) -> Path:
    """The folder numba caches the kernels of ``kernels`` in, as numba will choose it.

    When none of numba's own places can be written, this sets ``NUMBA_CACHE_DIR`` (and
    numba's config, if numba is already imported) to a private temporary folder, so the
    kernels still compile, and returns that folder.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"]) / _subpath(kernels)
    beside = kernels / "__pycache__"
    if _writable(beside):
        return beside
    user = _user_cache_root() / _subpath(kernels)
    if _writable(user):
        return user
    root = _private_temporary_root()
    os.environ["NUMBA_CACHE_DIR"] = str(root)
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = str(root)
    return root / _subpath(kernels)
