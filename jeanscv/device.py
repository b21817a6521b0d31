"""Where a fit runs: the device (``cpu``, ``cuda``) and, on the CPU, the backend
(``fast``: the numba kernels of :mod:`jeanscv.fitting._fast`; ``torch``: the reference).

Cheap to import: it looks for numba without importing it, and imports torch only to ask
about CUDA when CUDA is asked for.
"""

from __future__ import annotations

import importlib.util
import os

from .errors import JeansError

#: ``--device`` values: ``auto`` is the CPU, where a fit is fastest (:func:`resolve_device`).
DEVICES = ("auto", "cpu", "cuda")
#: Fitting backends on the CPU (``auto`` on the command line: :func:`resolve_backend` chooses).
BACKENDS = ("fast", "torch")


def fast_available() -> bool:
    """Whether numba can be imported (checked without importing it)."""
    return importlib.util.find_spec("numba") is not None


def resolve_backend(requested: str | None = None, device: str = "cpu") -> str:
    """The fitting backend: ``requested``, else ``$JEANSCV_BACKEND``, else ``fast``
    when numba is installed; always ``torch`` off the CPU."""
    choice = requested or os.environ.get("JEANSCV_BACKEND") or ("fast" if fast_available() else "torch")
    if choice not in BACKENDS:
        raise JeansError(f"unknown backend {choice!r} (use {' or '.join(BACKENDS)})")
    if device != "cpu":
        return "torch"
    if choice == "fast" and not fast_available():
        raise JeansError("the fast backend needs numba (pip install numba)")
    return choice


def resolve_device(device: str) -> str:
    """``auto`` -> ``cpu``; ``cuda`` (or ``cuda:N``) where CUDA is available; asking for
    missing CUDA is an error.

    ``auto`` is the CPU because there a fit is fastest: measured on an H200 beside its
    host's CPU (``python -m bench.cuda_speed``), a default fit took 0.18 s on the CPU's
    fast path, 1.15 s with torch on the CPU and 2.35 s on the GPU, whose kernels are too
    small for it (a 256x256 canvas, a few hundred launches a step). ``cpu`` and ``auto``
    need no torch.
    """
    if device in ("cpu", "auto"):
        return "cpu"
    if not device.startswith("cuda"):
        raise JeansError(f"unknown device {device!r} (use auto, cpu or cuda)")
    import torch

    if not torch.cuda.is_available():
        raise JeansError("--device cuda was requested but CUDA is not available")
    return device
