"""The ``jeanscv`` command's entry point: its signals first, then its imports.

A Ctrl-C in the tenth of a second that the command's imports take printed a traceback of
the import it stopped; this module imports nothing heavy before it says what an
interrupt does then.
"""

from __future__ import annotations

import sys

from .interrupts import exit_at_once_on_interrupt


def main() -> None:
    """``jeanscv ARGS``: the console script and ``python -m jeanscv``."""
    exit_at_once_on_interrupt(0 if sys.argv[1:2] == ["serve"] else 130)
    from .main import main as command

    command()
