"""The kernels of ``objective.py`` and ``raster.py`` as the package calls them.

Each is defined with :func:`.jit.njit`: its machine code is cached in jeanscv's per-user
folder (:func:`.cache.kernel_cache_dir`), never beside the installed source, and loaded
without numba's refresh of its registries.
"""

from __future__ import annotations

from . import objective as _objective_module
from . import raster as _raster_module

descend = _objective_module.descend
objective = _objective_module.objective
polygon_coverage_rows = _raster_module.polygon_coverage_rows
stroke_maps = _raster_module.stroke_maps
