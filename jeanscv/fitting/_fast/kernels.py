"""The kernels of ``objective.py`` and ``raster.py`` as the package calls them: set to load
their cached machine code without numba's refresh of its registries.

Before numba loads a function from its disk cache it refreshes the target context
(``Cache.load_overload``): it imports and installs every registry of implementations
numba has (strings, dicts, lists, random numbers, linear algebra, which imports
``scipy.linalg`` to check for BLAS), about half a second of a fresh process, five times
what loading our four kernels costs. None of it is used by code that is already
compiled; a kernel that is not in the cache is compiled, and numba's compiler refreshes
the registries itself before compiling (``compiler.compile_extra``). So the kernels'
caches here load without the refresh (the machine code, and so every output, is the
same). Where numba's internals are not as expected, the kernels keep numba's own cache.
"""

from __future__ import annotations

from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher
from numba.core.runtime import rtsys

from . import objective as _objective_module
from . import raster as _raster_module


class _CacheWithoutRefresh(FunctionCache):
    """numba's function cache, less the registry refresh before a load."""

    def load_overload(self, sig, target_context):
        rtsys.initialize(target_context)  # the runtime's symbols, which compiled code may call
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)


def _load_without_refresh() -> None:
    if not all(hasattr(FunctionCache, name) for name in ("_load_overload", "_guard_against_spurious_io_errors")):
        return
    for module in (_objective_module, _raster_module):
        for kernel in vars(module).values():
            if isinstance(kernel, Dispatcher) and type(getattr(kernel, "_cache", None)) is FunctionCache:
                kernel._cache = _CacheWithoutRefresh(kernel.py_func)


_load_without_refresh()

descend = _objective_module.descend
objective = _objective_module.objective
polygon_coverage_rows = _raster_module.polygon_coverage_rows
stroke_maps = _raster_module.stroke_maps
