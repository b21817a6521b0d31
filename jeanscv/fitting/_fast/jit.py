"""``njit`` for the kernels: numba's disk cache, kept in :func:`.cache.kernel_cache_dir`.

numba's ``cache=True`` picks its folder when a kernel is defined, and its first choice,
``__pycache__`` beside the source, is inside site-packages for an installed jeanscv
(see :mod:`.cache` for what that broke). Here each kernel is defined without numba's
cache and given one whose only place is jeanscv's folder, so nothing is ever written
beside the source.

The cache also loads without numba's refresh of its registries. Before numba loads a
function from its disk cache it refreshes the target context (``Cache.load_overload``):
it imports and installs every registry of implementations numba has (strings, dicts,
lists, random numbers, linear algebra, which imports ``scipy.linalg`` to check for BLAS),
about half a second of a fresh process, five times what loading our kernels costs. None
of it is used by code that is already compiled; a kernel that is not in the cache is
compiled, and numba's compiler refreshes the registries itself before compiling
(``compiler.compile_extra``). So the machine code, and every output, is the same.
"""

from __future__ import annotations

import hashlib
import os

import numba
from numba.core.caching import FunctionCache
from numba.core.runtime import rtsys

from .cache import kernel_cache_dir


class _Locator:
    """A numba cache locator with one place: jeanscv's kernel folder. The source stamp
    is the file's content digest (as numba's own since 0.66), so two installs of the same
    source share the cache."""

    def __init__(self, py_func, py_file: str) -> None:
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = str(kernel_cache_dir())

    @classmethod
    def from_function(cls, py_func, py_file: str) -> _Locator | None:
        if not os.path.exists(py_file):
            return None
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()
        except OSError:
            return None
        return locator

    def ensure_cache_path(self) -> None:
        os.makedirs(self._cache_path, exist_ok=True)

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> bytes:
        with open(self._py_file, "rb") as source:
            return hashlib.sha256(source.read()).digest()

    def get_disambiguator(self) -> str:
        return str(self._lineno)


class _Impl(FunctionCache._impl_class):
    _locator_classes = [_Locator]


class KernelCache(FunctionCache):
    """numba's function cache in jeanscv's folder, loaded without the registry refresh."""

    _impl_class = _Impl

    def load_overload(self, sig, target_context):
        rtsys.initialize(target_context)  # the runtime's symbols, which compiled code may call
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)


def njit(function=None, **options):
    """``numba.njit(**options)`` with the disk cache of :class:`KernelCache`; used as
    ``@njit`` or ``@njit(...)``. The cache is always on: ``cache`` is not an option."""

    def define(py_func):
        kernel = numba.njit(**options)(py_func)
        kernel._cache = KernelCache(py_func)  # what Dispatcher.enable_caching sets
        return kernel

    return define(function) if function is not None else define
