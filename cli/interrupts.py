"""What an interrupt does while the command starts: end at once, quietly (see
:func:`exit_at_once_on_interrupt`), until the command takes its signals over
(:func:`usual_interrupts`). Imports nothing heavy: the entry point uses it first."""

from __future__ import annotations

import os
import signal


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


def usual_interrupts() -> None:
    """Ctrl-C raises KeyboardInterrupt and SIGTERM is the default again (the command's
    own handling, from here on), where :func:`exit_at_once_on_interrupt` changed them."""
    try:
        if getattr(signal.getsignal(signal.SIGINT), "__qualname__", "").startswith("exit_at_once_on_interrupt"):
            signal.signal(signal.SIGINT, signal.default_int_handler)
        if getattr(signal.getsignal(signal.SIGTERM), "__qualname__", "").startswith("exit_at_once_on_interrupt"):
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
    except ValueError:
        pass
