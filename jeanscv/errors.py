"""The exception types that jeanscv raises for bad input: :class:`JeansError` and its kinds."""

from __future__ import annotations


class JeansError(ValueError):
    """A user-facing failure: bad input, an empty silhouette, a diverged fit.

    The message is one line that names the reason (the CLI prefixes the file name),
    so it can be shown as ``jeanscv: FILE: reason`` without a traceback.
    """


class OptionError(JeansError):
    """An option that does not fit this input, such as a point outside the image: the
    CLI reports it as a usage error (exit status 2)."""


class NothingFound(JeansError):
    """Clicks or a box that found no object (a click on plain background, a box round
    nothing, negative clicks that leave nothing): an outcome to show the person, who
    clicks again, rather than a broken input."""
