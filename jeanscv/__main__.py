"""``python -m jeanscv``: the ``jeanscv`` command (:mod:`jeanscv_cli`, made importable
from a source checkout too by :mod:`jeanscv._command`)."""

from __future__ import annotations

from . import _command  # noqa: F401  (registers jeanscv_cli from ../cli where it is not installed)

if __name__ == "__main__":
    from jeanscv_cli._entry import main

    main()
