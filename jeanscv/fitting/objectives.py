"""The fit's objective, evaluated by the chosen backend: numpy in, numpy out; and the
exact polygon and stroke coverage that the rule checks and the compositor need, and the
blurred targets of the fit's coarse-to-fine schedule (:func:`blurred`).

``fast`` is the numba kernel (:mod:`jeanscv.fitting._fast`), ``torch`` the differentiable
reference (:mod:`jeanscv.fitting.loss`, autograd), which also runs on CUDA. Both take
vertices in pixels of the target's canvas and return the weighted total per
candidate, its gradient with respect to those vertices, and every term. Both work in
float64 (on CUDA too) and agree to rounding, so a fit takes the same path either way.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from ..device import fast_available
from .garments import Garment
from .terms import TERM_NAMES, check_inter_pairs

#: ``(pixels (B, N, 2), target (C, C), stroke half width, need_grad)`` ->
#: ``(totals (B,), d totals / d pixels (B, N, 2) or None, {term: (B,)})``.
ObjectiveFunction = Callable[[np.ndarray, np.ndarray, float, bool], tuple[np.ndarray, np.ndarray | None, dict]]
#: ``(optimizer (adam.BatchAdam), target (C, C), steps, stroke half width)`` -> ``(totals
#: (k, B), normalised params after each step (k, B, N, 2))``; ``k < steps``: at step ``k``
#: every start diverged.
DescentFunction = Callable[[object, np.ndarray, int, float], tuple[np.ndarray, np.ndarray]]


def make_objective(
    backend: str, garment: Garment, inter_pairs: str, weights: dict[str, float], device: str = "cpu"
) -> ObjectiveFunction:
    """The weighted objective of ``garment`` with ``inter_pairs`` and ``weights``."""
    check_inter_pairs(inter_pairs)
    if backend == "fast":
        from ._fast import Objective

        kernel = Objective(garment, inter_pairs, weights)

        def fast(pixels, target, half_width, need_grad=True):
            totals, grad, terms = kernel(pixels, target, half_width, need_grad)
            return totals, grad if need_grad else None, {name: terms[:, i] for i, name in enumerate(TERM_NAMES)}

        return fast
    return _torch_objective(garment, inter_pairs, weights, device)


def make_descent(
    backend: str, garment: Garment, inter_pairs: str, weights: dict[str, float], device: str = "cpu"
) -> DescentFunction:
    """The fit's Adam steps on one target: for ``fast`` one numba call runs them all
    (:meth:`jeanscv.fitting._fast.Objective.descend`), else a Python loop over the objective
    does the same step by step."""
    if backend == "fast":
        check_inter_pairs(inter_pairs)
        from ._fast import Objective

        return Objective(garment, inter_pairs, weights).descend
    return functools.partial(descend_by_steps, make_objective(backend, garment, inter_pairs, weights, device))


def descend_by_steps(
    evaluate: ObjectiveFunction, optimizer, target: np.ndarray, steps: int, half_width: float
) -> tuple[np.ndarray, np.ndarray]:
    """:data:`DescentFunction` as a Python loop: ``evaluate`` at the optimizer's params,
    then its Adam step, ``steps`` times."""
    size = target.shape[-1]
    totals, path = [], []
    for _ in range(steps):
        total, grad, _ = evaluate(optimizer.params * size, target, half_width)
        finite = np.isfinite(total)
        if not finite.any():
            break
        # Diverged starts must not poison the others: drop their gradient.
        grad = np.where(finite[:, None, None], grad * size, 0.0)
        if not np.isfinite(grad).all():
            grad = np.nan_to_num(grad, nan=0.0, posinf=0.0, neginf=0.0)
        optimizer.step(grad)
        totals.append(total)
        path.append(optimizer.params.copy())
    shape = optimizer.params.shape
    return np.reshape(totals, (len(totals), shape[0])), np.reshape(path, (len(path), *shape))


def _torch_objective(garment: Garment, inter_pairs: str, weights: dict[str, float], device: str) -> ObjectiveFunction:
    import torch

    from .loss import jalgorithm_terms, weighted_total

    # float64 on every device. On CUDA a step is a few hundred tiny kernels, bound by
    # launches more than arithmetic: a default fit took 2.35 s in float64 and 1.94 s in
    # float32 on an H200 (runs minutes apart; the CPU's figures were 15 % slower in the
    # float64 run). float32's rounding led fits to other minima than the CPU's
    # (objectives up to 9 % apart on the synthetic zoo); float64 gives the CPU's fit.
    dtype = torch.float64
    targets: dict[int, tuple[np.ndarray, torch.Tensor]] = {}

    def on_device(target: np.ndarray) -> torch.Tensor:
        # The fit passes a handful of targets (one per blur and canvas): convert each once.
        if id(target) not in targets or targets[id(target)][0] is not target:
            targets[id(target)] = (target, torch.as_tensor(target, dtype=dtype, device=device))
        return targets[id(target)][1]

    def evaluate(pixels, target, half_width, need_grad=True):
        points = torch.as_tensor(np.asarray(pixels), dtype=dtype, device=device)
        with torch.set_grad_enabled(need_grad):
            points.requires_grad_(need_grad)
            terms = jalgorithm_terms(points, on_device(target), garment, inter_pairs, half_width)
            total = weighted_total(terms, weights)
            grad = None
            if need_grad:
                # Diverged starts must not poison the others: drop their gradient.
                finite = torch.where(torch.isfinite(total), total, torch.zeros_like(total))
                (grad,) = torch.autograd.grad(finite.sum(), points)
                grad = grad.double().cpu().numpy()
        as_numpy = {name: value.detach().double().cpu().numpy() for name, value in terms.items()}
        return total.detach().double().cpu().numpy(), grad, as_numpy

    return evaluate


def gaussian_kernel(sigma: float) -> np.ndarray:
    """kornia's normalised 1-D Gaussian of ``2 * ceil(3 sigma) + 1`` taps."""
    radius = int(math.ceil(3 * sigma))
    taps = np.exp(-(np.arange(-radius, radius + 1, dtype=np.float64) ** 2) / (2 * sigma**2))
    return taps / taps.sum()


def blurred(silhouette: np.ndarray, sigma: float, backend: str = "fast") -> np.ndarray:
    """``S`` ``(C, C)`` float64 blurred by a Gaussian of ``sigma`` px, zeros outside the canvas.

    The torch path uses kornia (``kornia.filters.gaussian_blur2d``, ``2 * ceil(3 sigma) + 1``
    taps); the fast path, which imports neither torch nor kornia, its numpy twin (the same
    taps, separable), which agrees with it to 1e-14.
    """
    if sigma <= 0:
        return silhouette
    if backend == "torch":
        import kornia
        import torch

        size = 2 * int(math.ceil(3 * sigma)) + 1
        image = torch.as_tensor(silhouette)[None, None]
        return kornia.filters.gaussian_blur2d(image, (size, size), (sigma, sigma), border_type="constant")[0, 0].numpy()
    taps = gaussian_kernel(sigma)
    radius = len(taps) // 2
    padded = np.pad(silhouette, radius)
    rows = sum(w * padded[:, k : k + silhouette.shape[1]] for k, w in enumerate(taps))
    return sum(w * rows[k : k + silhouette.shape[0]] for k, w in enumerate(taps))


def polygon_coverage(vertices: np.ndarray, height: int, width: int) -> np.ndarray:
    """Exact coverage ``(height, width)`` of the closed polygon ``vertices`` ``(N, 2)``:
    the numba kernel when numba is installed (no torch import), else the torch
    rasterizer; the same exact area either way."""
    from . import _fast

    if fast_available():
        return _fast.polygon_coverage(vertices, height, width)
    import torch

    from .render import polygon_coverage as torch_coverage

    return torch_coverage(torch.as_tensor(np.asarray(vertices, np.float64)), height, width).numpy()


def stroke_coverage(start: np.ndarray, end: np.ndarray, height: int, width: int) -> np.ndarray:
    """``(M, height, width)`` alphas of the 5-px strokes of segments ``(M, 2)``, by the
    same backend as :func:`polygon_coverage`."""
    from . import _fast

    if fast_available():
        return _fast.stroke_coverage(start, end, height, width)
    import torch

    from .render import stroke_coverage as torch_strokes

    return torch_strokes(torch.as_tensor(start), torch.as_tensor(end), height, width).numpy()
