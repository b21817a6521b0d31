"""The ``jeanscv`` command's entry point: its signals first, then its imports.

A Ctrl-C in the tenth of a second that the command's imports take printed a traceback of
the import it stopped; this module imports nothing heavy before it says what an
interrupt does then.
"""

from __future__ import annotations

import os
import signal
import sys


def exit_at_once_on_interrupt(interrupted: int) -> None:
    """Until the command takes over its signals, Ctrl-C ends the process at once with
    status ``interrupted`` and SIGTERM with 143, saying nothing.

    Nothing has been written that early. Without this, Ctrl-C while the command starts
    up printed click's "Aborted!" and exited 1, or a traceback of the import it stopped.
    """

    def end(signum, frame) -> None:
        os._exit(interrupted if signum == signal.SIGINT else 128 + signal.SIGTERM)

    try:
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, end)
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, end)
    except ValueError:  # not the main thread: leave signals alone
        pass


def main() -> None:
    """``jeanscv ARGS``: the console script and ``python -m jeanscv``."""
    exit_at_once_on_interrupt(0 if sys.argv[1:2] == ["serve"] else 130)
    from .main import main as command

    command()
