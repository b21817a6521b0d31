"""The fitter: Adam on normalised garment vertices, several starts in one batch."""

from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from ..device import resolve_backend
from ..errors import JeansError
from ..geometry import CANVAS_SIZE
from .adam import BatchAdam
from .garments import JEANS, Garment
from .objectives import blurred, make_descent, make_objective
from .posture import posture, tilt_degrees
from .presets import Preset, get_preset
from .terms import PAPER_TERMS, PAPER_WEIGHTS, STROKE_HALF_WIDTH, TERM_NAMES

# (scale, rotation in degrees) of the starts after the paper's own initialisation,
# around the waistband centre moved to the canvas centre. They cover small and large
# objects and bodies that are upright, lying or upside down.
DEFAULT_PLACEMENTS = (
    (0.6, 0.0),
    (0.8, 0.0),
    (0.45, 0.0),
    (0.6, 90.0),
    (0.6, -90.0),
    (0.6, 180.0),
    (0.6, 35.0),
    (0.6, -35.0),
    (0.35, 0.0),
    (0.45, 180.0),
    (0.8, 90.0),
    (0.8, -90.0),
)


@dataclass
class FitResult:
    """The outcome of one fit. Vertices are in canvas pixels, template order."""

    vertices: np.ndarray  # (N, 2)
    objective: float
    terms: dict[str, float]
    paper_terms: dict[str, float]
    paper_total: float
    preset: Preset
    garment: Garment
    iterations: int
    seed: int
    start_index: int
    start_objectives: list[float]  # final objective of each start optimised to the end
    start_ids: list[int]  # which starts those are (the others were pruned)
    num_starts: int
    history: np.ndarray  # (iterations, starts) objective of every start
    trajectory: np.ndarray  # (iterations + 1, N, 2) the winning start's vertices, canvas px
    seconds: float
    device: str
    extra: dict = field(default_factory=dict)
    vertices_image: np.ndarray | None = None  # (N, 2) input-image pixels, when a framing is known


def preset_placements(preset: Preset, starts: int | None = None) -> tuple[tuple[float, ...], ...]:
    """The ``(scale, degrees[, aspect])`` of starts 1.. of ``preset``: its placements (or
    :data:`DEFAULT_PLACEMENTS`), cut or cycled to ``starts`` starts in all (default
    ``preset.starts``). An upright plan's starts follow the preset's own ``starts - 1``
    and count in ``starts`` (``starts=1`` is the paper's single start either way)."""
    placements = preset.placements or DEFAULT_PLACEMENTS
    count = preset.starts
    if preset.upright and preset.upright.starts:
        placements = tuple(placements[k % len(placements)] for k in range(preset.starts - 1)) + preset.upright.starts
        count = len(placements) + 1
    count = max(1, count if starts is None else starts)
    return tuple(placements[k % len(placements)] for k in range(count - 1))


def initial_placements(
    garment: Garment,
    starts: int,
    seed: int = 0,
    placements: tuple[tuple[float, ...], ...] = DEFAULT_PLACEMENTS,
) -> np.ndarray:
    """``(starts, N, 2)`` initial vertices in canvas pixels.

    Start 0 is the template itself (the paper's initialisation); the others are the
    template scaled (x by ``scale * sqrt(aspect)``, y by ``scale / sqrt(aspect)``; aspect
    1 when left out) and rotated about its waistband centre, which is moved to the
    canvas centre, with a small seeded jitter.
    """
    template = np.asarray(garment.template, dtype=np.float64)
    waist = template[list(garment.waist)].mean(axis=0)
    rng = np.random.default_rng(seed)
    centre = np.array([CANVAS_SIZE / 2, CANVAS_SIZE / 2])
    out = [template]
    for k in range(1, starts):
        scale, degrees, *aspect = placements[(k - 1) % len(placements)]
        stretch = math.sqrt(aspect[0]) if aspect else 1.0
        angle = math.radians(degrees + rng.normal(0.0, 3.0))
        scale *= math.exp(rng.normal(0.0, 0.05))
        rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
        shaped = (template - waist) * [stretch, 1.0 / stretch]
        out.append(shaped @ rot.T * scale + centre + rng.normal(0.0, 2.0, size=2))
    return np.stack(out)


def blur_schedule(sigmas: tuple[float, ...], iterations: int) -> list[float]:
    """Sigma per iteration: equal slices for each sigma, then a final unblurred slice."""
    stages = list(sigmas) + [0.0]
    return [stages[min(i * len(stages) // max(iterations, 1), len(stages) - 1)] for i in range(iterations)]


def _area_downsampled(silhouette: np.ndarray, factor: int) -> np.ndarray:
    """``S`` averaged over ``factor x factor`` blocks (exact area coverage at the coarser grid)."""
    if factor == 1:
        return silhouette
    size = silhouette.shape[0] // factor
    return silhouette.reshape(size, factor, size, factor).mean(axis=(1, 3))


def _screen_factor(preset: Preset) -> int:
    """How much coarser than the canvas the screening iterations run."""
    if not preset.screen_canvas:
        return 1
    factor = CANVAS_SIZE // preset.screen_canvas
    if factor < 1 or factor * preset.screen_canvas != CANVAS_SIZE:
        raise JeansError(f"screen_canvas must divide {CANVAS_SIZE}, got {preset.screen_canvas}")
    return factor


def as_silhouette_array(silhouette) -> np.ndarray:
    """Validate ``S`` (array or tensor) and return it as a float64 ``(256, 256)`` array in [0, 1]."""
    if hasattr(silhouette, "detach"):
        silhouette = silhouette.detach().cpu().numpy()
    s = np.asarray(silhouette)
    if s.shape != (CANVAS_SIZE, CANVAS_SIZE):
        raise JeansError(f"silhouette must be {CANVAS_SIZE}x{CANVAS_SIZE}, got {tuple(s.shape)}")
    # Through float32 first, as the fit always took S: the same input, the same bits.
    s = s.astype(np.float32).astype(np.float64)
    if not np.isfinite(s).all():
        raise JeansError("silhouette has non-finite values")
    s = s.clip(0.0, 1.0)
    if s.sum() < 1.0:
        raise JeansError("silhouette is empty")
    return s


def _select(
    candidates: np.ndarray, totals: np.ndarray, silhouette: np.ndarray, garment: Garment, preset: Preset
) -> int:
    """Index of the winning start.

    ``objective``: the lowest objective. ``rules``: fewest failed rule checks first,
    then (with an upright plan) upright (tilt <= its ``max_tilt``) before tilted, then
    upright before lying before upside-down (:func:`posture`), then the lowest objective.
    """
    if preset.select == "objective":
        return int(np.argmin(totals))
    from .checks import rule_report

    def key(i: int) -> tuple:
        if not np.isfinite(totals[i]):
            return (math.inf,)
        failed = sum(not ok for ok in rule_report(candidates[i], silhouette, garment).checks.values())
        tilted = () if preset.upright is None else (tilt_degrees(candidates[i], garment) > preset.upright.max_tilt,)
        return (failed, *tilted, posture(candidates[i], garment), float(totals[i]))

    return min(range(len(totals)), key=key)


def _survivors(objectives: np.ndarray, postures: list[int], preset: Preset) -> np.ndarray:
    """Sorted indices of the ``preset.keep`` starts that go on after pruning.

    By objective; with ``select="rules"`` the best start of the most upright posture
    present is always among them, since the final choice prefers upright jeans and
    early objectives often favour upside-down ones.
    """
    order = list(np.argsort(objectives, kind="stable"))
    if preset.select == "rules":
        finite = [i for i in order if np.isfinite(objectives[i])]
        if finite:
            upright = min(finite, key=lambda i: postures[i])  # stable: the best of that posture
            order.remove(upright)
            order.insert(0, upright)
    return np.sort(np.asarray(order[: preset.keep], dtype=np.int64))


def _upright_survivors(
    objectives: np.ndarray, tilts: list[float], max_tilt: float, upright: int, tilted: int
) -> np.ndarray:
    """Sorted indices of the starts that go on under an upright plan: the ``upright`` best
    starts tilted at most ``max_tilt`` degrees and the ``tilted`` best others, by objective,
    topped up from the others (or the upright ones) when one kind runs short; diverged
    starts last."""
    order = [int(i) for i in np.argsort(np.nan_to_num(objectives, nan=math.inf), kind="stable")]
    upright_order = [i for i in order if tilts[i] <= max_tilt and np.isfinite(objectives[i])]
    tilted_order = [i for i in order if i not in upright_order]
    chosen = upright_order[:upright] + tilted_order[:tilted]
    chosen += [i for i in order if i not in chosen][: upright + tilted - len(chosen)]
    return np.sort(np.asarray(chosen, dtype=np.int64))


def _prunings(preset: Preset, iterations: int, num_starts: int) -> dict[int, tuple[int, int] | None]:
    """``{step: survivors}`` after which steps the batch shrinks: ``(upright, tilted)``
    counts under an upright plan, else None for the preset's ``keep``."""
    if preset.upright:
        return {
            int(iterations * fraction): (up, tilted)
            for fraction, up, tilted in preset.upright.prunings
            if up + tilted < num_starts
        }
    if preset.keep and preset.keep < num_starts:
        return {int(iterations * preset.prune_fraction): None}
    return {}


@contextmanager
def _torch_settings(threads: int | None, backend: str, device: str):
    """Torch's settings during a torch fit, restored after it (the fast backend does not
    touch torch):

    - ``threads`` threads (None: torch's own): the fit's tensors are small, and on a few
      cores thread hand-offs (in index_add above all) cost more than they save;
    - off the CPU, torch's deterministic algorithms: CUDA's index_add (the rasterizer's
      scatter and index_select's backward) sums in any order, so the same seed gave fits
      up to 0.8 px apart. Measured on an H100 (float32 then): 1.6 s a default fit instead
      of 1.1 s, and the same vertices every time (tests/test_cuda.py).
    """
    if backend != "torch":
        yield
        return
    import torch

    threads_before, deterministic_before = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    if threads:
        torch.set_num_threads(threads)
    if device != "cpu":
        torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.set_num_threads(threads_before)
        torch.use_deterministic_algorithms(deterministic_before)


def fit(
    silhouette,
    preset: str | Preset = "default",
    garment: Garment = JEANS,
    iterations: int = 100,
    seed: int = 0,
    starts: int | None = None,
    device: str = "cpu",
    threads: int | None = 1,
    posture: str = "upright",
    backend: str | None = None,
) -> FitResult:
    """Fit the garment to a 256x256 silhouette ``S`` (array or tensor) by gradient descent.

    All starts are optimised together as one batch with Adam on normalised
    coordinates; after ``preset.prune_fraction`` of the iterations only the
    ``preset.keep`` best go on (or those of its upright plan), and the winner is chosen
    by ``preset.select``. ``starts``: how many starts (default: the preset's, with its
    upright plan's; see :func:`preset_placements`). ``posture``: ``upright`` (the
    preset's upright plan, if it has one) or ``any`` (:meth:`Preset.with_posture`).
    ``threads``: torch threads during a torch fit (None leaves torch's setting).
    ``backend``: ``fast`` (numba, CPU) or ``torch``; None: :func:`jeanscv.device.resolve_backend`.
    """
    preset = (get_preset(preset) if isinstance(preset, str) else preset).with_posture(posture)
    backend = resolve_backend(backend, device)
    with _torch_settings(threads, backend, device):
        return _fit(silhouette, preset, garment, iterations, seed, starts, device, backend)


def _fit(
    silhouette,
    preset: Preset,
    garment: Garment,
    iterations: int,
    seed: int,
    starts: int | None,
    device: str,
    backend: str,
) -> FitResult:
    began = time.perf_counter()
    if iterations < 0:
        raise JeansError("iterations must be >= 0")
    placements = preset_placements(preset, starts)
    num_starts = len(placements) + 1
    s = as_silhouette_array(silhouette)

    init = initial_placements(garment, num_starts, seed, placements)
    optimizer = BatchAdam(init / CANVAS_SIZE, lr=preset.learning_rate)
    history = np.full((iterations, num_starts), np.nan)
    path = np.full((iterations + 1, num_starts, garment.num_vertices, 2), np.nan)
    path[0] = init
    active = np.arange(num_starts)  # which starts are still optimised
    prunings = _prunings(preset, iterations, num_starts)

    evaluate = make_objective(backend, garment, preset.inter_pairs, preset.weights, device)
    descend = make_descent(backend, garment, preset.inter_pairs, preset.weights, device)
    for step, stop, target in _stretches(s, preset, iterations, prunings, backend):
        totals, params = descend(optimizer, target, stop - step, _half_width(target))
        if len(totals) < stop - step:
            raise JeansError("the fit diverged (non-finite loss)")
        history[step:stop, active] = totals
        path[step + 1 : stop + 1, active] = params * CANVAS_SIZE
        if stop - 1 in prunings:
            # Successive halving: keep optimising only the most promising starts.
            order = _pruned(history[stop - 1, active], path[stop, active], prunings[stop - 1], preset, garment)
            optimizer.keep(order)
            active = active[order]

    final = optimizer.params * CANVAS_SIZE
    totals, _, terms = evaluate(final, s, _half_width(s), False)
    totals = np.where(np.isfinite(totals), totals, math.inf)
    best = _select(final, totals, s, garment, preset)
    vertices = final[best]
    if not np.isfinite(vertices).all() or not math.isfinite(float(totals[best])):
        raise JeansError("the fit diverged (non-finite vertices)")
    paper_objective = make_objective(backend, garment, "all", PAPER_WEIGHTS, device)
    paper_totals, _, paper = paper_objective(vertices[None], s, STROKE_HALF_WIDTH, False)
    paper_total = float(paper_totals[0])

    return FitResult(
        vertices=vertices,
        objective=float(totals[best]),
        terms={k: float(terms[k][best]) for k in TERM_NAMES},
        paper_terms={k: float(paper[k][0]) for k in PAPER_TERMS},
        paper_total=paper_total,
        preset=preset,
        garment=garment,
        iterations=iterations,
        seed=seed,
        start_index=int(active[best]),
        start_objectives=[float(v) for v in totals],
        start_ids=[int(i) for i in active],
        num_starts=num_starts,
        history=history,
        trajectory=path[:, active[best]],
        seconds=time.perf_counter() - began,
        device=str(device),
        extra={"backend": backend},
    )


def _half_width(target: np.ndarray) -> float:
    """The strokes' half width in pixels of ``target``'s canvas (a screening canvas is coarser)."""
    return STROKE_HALF_WIDTH * target.shape[-1] / CANVAS_SIZE


def _stretches(s: np.ndarray, preset: Preset, iterations: int, prunings: dict, backend: str):
    """``(step, stop, target)`` for each stretch of steps on one target, up to a pruning:
    the backend runs each at once. Targets are ``s`` blurred by the preset's schedule and,
    until the first pruning, on its coarser screening canvas; each is made once."""
    prune_step = min(prunings, default=-1)  # the screening canvas serves until the first
    screen_factor = _screen_factor(preset) if prune_step >= 0 else 1
    sigma_per_iteration = blur_schedule(preset.blur_sigmas, iterations)

    def target_key(step: int) -> tuple[float, int]:
        # Screening runs on a coarser canvas: which starts are promising shows there
        # at a fraction of the cost, and the normalised vertices carry over as they are.
        return sigma_per_iteration[step], screen_factor if step <= prune_step else 1

    target_cache: dict[tuple[float, int], np.ndarray] = {}
    step = 0
    while step < iterations:
        key = target_key(step)
        stop = step + 1
        while stop < iterations and stop - 1 not in prunings and target_key(stop) == key:
            stop += 1
        if key not in target_cache:
            sigma, factor = key
            target_cache[key] = _area_downsampled(blurred(s, sigma, backend), factor)
        yield step, stop, target_cache[key]
        step = stop


def _pruned(
    objectives: np.ndarray, vertices: np.ndarray, survivors: tuple[int, int] | None, preset: Preset, garment: Garment
) -> np.ndarray:
    """Sorted indices of the active starts that go on after a pruning, from their
    objectives and canvas ``vertices`` at it (:func:`_upright_survivors` under an upright
    plan, with its ``survivors`` counts; else :func:`_survivors`)."""
    if preset.upright:
        tilts = [tilt_degrees(v, garment) for v in vertices]
        return _upright_survivors(objectives, tilts, preset.upright.max_tilt, *survivors)
    postures = [posture(v, garment) for v in vertices]
    return _survivors(objectives, postures, preset)
