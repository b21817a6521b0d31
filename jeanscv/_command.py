"""The ``jeanscv`` command's package, ``jeanscv_cli``, made importable, and the ``-j``
workers' initializer.

The command lives in the ``jeanscv_cli`` package (the repository's ``cli/`` folder,
installed under that name). From a source checkout that is not installed, the folder
is loaded under the same name when this module is imported, so ``python -m jeanscv``
works there too (also in the worker processes of ``-j``, which import this module
again to unpickle :func:`worker_init`).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path


def load_cli_package() -> None:
    """Make ``jeanscv_cli`` importable, from the installed package or from ``../cli``."""
    if importlib.util.find_spec("jeanscv_cli") is not None:
        return
    folder = Path(__file__).resolve().parent.parent / "cli"
    spec = importlib.util.spec_from_file_location(
        "jeanscv_cli", folder / "__init__.py", submodule_search_locations=[str(folder)]
    )
    if spec is None or spec.loader is None:
        raise SystemExit("jeanscv: the command-line package jeanscv_cli is not installed")
    module = importlib.util.module_from_spec(spec)
    sys.modules["jeanscv_cli"] = module
    spec.loader.exec_module(module)


load_cli_package()


def worker_init(threads: int, parent: int | None = None) -> None:
    """Initializer of the ``-j`` worker processes.

    It lives here, not in ``jeanscv_cli``, because unpickling it imports this module,
    which makes ``jeanscv_cli`` importable in a worker of an uninstalled checkout
    before any of its objects arrive (spawn does not re-run a package's __main__).
    """
    from jeanscv_cli.worker import init_worker

    init_worker(threads, parent)
