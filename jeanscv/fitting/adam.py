"""Adam over a batch of starts, in numpy: the fit's optimiser.

Its own module, below both the fitter and the numba kernels, because both use the same
update (:func:`adam_update`): the fitter's torch path calls it, the fast path's step loop
compiles this same source with numba.
"""

from __future__ import annotations

import numpy as np


def adam_update(params, grad, exp_avg, exp_avg_sq, beta1, beta2, step_size, bias2, eps) -> None:
    """One Adam update of ``params`` and its moments in place, in torch.optim.Adam's order
    of operations; ``step_size = lr / (1 - beta1^t)``, ``bias2 = 1 - beta2^t``. Plain array
    code: the fast backend's step loop compiles this same source with numba."""
    exp_avg *= beta1
    exp_avg += (1 - beta1) * grad
    exp_avg_sq *= beta2
    exp_avg_sq += (1 - beta2) * grad * grad
    denom = np.sqrt(exp_avg_sq / bias2) + eps
    params -= step_size * (exp_avg / denom)


class BatchAdam:
    """Adam (Kingma & Ba; torch.optim.Adam's defaults and update) over a batch of starts,
    in numpy: the fit's parameters are a few hundred numbers, and torch.optim would
    import torch._dynamo (1.6 s per process). The batch shrinks with its moments when
    starts are pruned."""

    def __init__(self, params: np.ndarray, lr: float, betas=(0.9, 0.999), eps: float = 1e-8) -> None:
        self.params, self.lr, self.betas, self.eps = np.array(params, dtype=np.float64), lr, betas, eps
        self.exp_avg = np.zeros_like(self.params)
        self.exp_avg_sq = np.zeros_like(self.params)
        self.steps = 0

    def corrections(self, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """``(step_size, bias2)`` of the next ``steps`` steps (:func:`adam_update`)."""
        beta1, beta2 = self.betas
        counts = range(self.steps + 1, self.steps + steps + 1)
        return np.array([self.lr / (1 - beta1**t) for t in counts]), np.array([1 - beta2**t for t in counts])

    def step(self, grad: np.ndarray) -> None:
        """One Adam update of ``params`` in place."""
        step_size, bias2 = self.corrections(1)
        self.steps += 1
        adam_update(self.params, grad, self.exp_avg, self.exp_avg_sq, *self.betas, step_size[0], bias2[0], self.eps)

    def keep(self, index: np.ndarray) -> None:
        """Shrink the batch to the starts in ``index``, moments included."""
        self.params = self.params[index]
        self.exp_avg = self.exp_avg[index]
        self.exp_avg_sq = self.exp_avg_sq[index]
