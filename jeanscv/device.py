"""Where a fit runs: the device (``cpu``, ``cuda``) and, on the CPU, the backend
(``fast``: the numba kernels of :mod:`jeanscv._fast`; ``torch``: the reference).

Cheap to import: it looks for numba and for an NVIDIA driver without importing numba or
torch, and imports torch only to ask about CUDA where a driver is installed.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

from .errors import JeansError

#: ``--device`` values: ``auto`` is CUDA where available, else the CPU.
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
    """``auto`` -> ``cuda`` when available else ``cpu``; asking for missing cuda is an error.

    ``cpu`` needs no torch, and ``auto`` imports torch (about a second) only where an
    NVIDIA driver is installed.
    """
    if device == "cpu":
        return device
    if device == "auto" and not _nvidia_driver():
        return "cpu"
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise JeansError("--device cuda was requested but CUDA is not available")
    if device not in ("cpu",) and not device.startswith("cuda"):
        raise JeansError(f"unknown device {device!r} (use auto, cpu or cuda)")
    return device


def _nvidia_driver() -> bool:
    """Whether an NVIDIA kernel driver is loaded (CUDA cannot be available without one)."""
    return Path("/proc/driver/nvidia/version").exists() or Path("/dev/nvidiactl").exists() or os.name == "nt"
