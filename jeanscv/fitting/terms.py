"""Names, weights and constants of the jalgorithm's objective, free of torch.

Shared by the torch reference (:mod:`jeanscv.fitting.loss`), the numba fast path
(:mod:`jeanscv.fitting._fast`), the presets and the rule checks, so that choosing weights or
checking rules does not import torch.
"""

from __future__ import annotations

import functools

import numpy as np

from ..errors import JeansError

PAPER_TERMS = ("center", "coverage", "rigid", "open", "closed", "inter", "inside")
TERM_NAMES = PAPER_TERMS + ("upright",)

#: The weights printed in the paper (its equation 1).
PAPER_WEIGHTS = {
    "center": 50.0,
    "coverage": 100.0,
    "rigid": 5.0,
    "open": 1.0,
    "closed": 1.0,
    "inter": 50.0,
    "inside": 1.0,
}

STROKE_HALF_WIDTH = 2.5
#: ``upright`` is 0 within this angle of upright and saturates beyond ``UPRIGHT_SATURATE``.
UPRIGHT_FREE_DEGREES = 20.0
UPRIGHT_SATURATE_DEGREES = 60.0
INTER_PAIRS = ("all", "non_adjacent")


def check_inter_pairs(inter_pairs: str) -> None:
    """Raise JeansError unless ``inter_pairs`` is one of :data:`INTER_PAIRS`."""
    if inter_pairs not in INTER_PAIRS:
        raise JeansError(f"unknown inter_pairs {inter_pairs!r} (use {' or '.join(INTER_PAIRS)})")


def affine_residual_operator(template: np.ndarray) -> np.ndarray:
    """``(N, N)`` matrix ``I - H`` whose product with ``X`` is ``X - T X̄`` (cached)."""
    return _affine_residual_operator(np.asarray(template, dtype=np.float64).tobytes(), len(template)).copy()


@functools.lru_cache(maxsize=32)
def _affine_residual_operator(template_bytes: bytes, count: int) -> np.ndarray:
    """``(N, N)`` matrix ``I - H`` whose product with ``X`` is ``X - T X̄``.

    ``T`` is the least-squares affine map of the template ``X̄`` onto ``X``; ``H`` is
    the hat matrix of the design ``[X̄, 1]``, constant for a given template.
    """
    template = np.frombuffer(template_bytes, dtype=np.float64).reshape(count, 2)
    design = np.hstack([template, np.ones((count, 1))])
    hat = design @ np.linalg.pinv(design)
    return np.eye(count) - hat
