"""The CUDA path (``device="cuda"``): the torch rasterizer, the paper's terms and the fit
on the GPU, each against the same code on the CPU.

Skipped where CUDA is not available (CI has no GPU). On a GPU machine:
``python -m pytest tests/test_cuda.py``; ``python -m bench.cuda_speed`` prints its speed.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from conftest import write_silhouette_png

from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.garments import JEANS
from jeanscv.fitting.loss import jalgorithm_terms
from jeanscv.fitting.render import polygon_coverage, stroke_coverage
from testkit.synthetic import silhouette_zoo

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")

F64 = torch.float64
SHAPES = ("person", "dog", "spider", "kangaroo", "tree")
#: Shapes whose fit does not sit on a flat ridge: the spider's moves by pixels, and its
#: objective by 1 %, with the order of a sum (between the CPU's two backends too).
FIT_SHAPES = ("person", "dog", "kangaroo", "tree", "bird")


@pytest.fixture(scope="module")
def zoo() -> dict[str, np.ndarray]:
    return silhouette_zoo(list(dict.fromkeys(SHAPES + FIT_SHAPES)))


def _candidates(count: int, seed: int) -> np.ndarray:
    """``count`` jittered, scaled and shifted templates ``(count, 8, 2)`` in canvas pixels."""
    rng = np.random.default_rng(seed)
    scale = rng.uniform(0.6, 1.3, (count, 1, 1))
    shift = rng.uniform(-40, 40, (count, 1, 2))
    centre = JEANS.template.mean(axis=0)
    return (JEANS.template - centre) * scale + centre + shift + rng.normal(0, 4, (count, 8, 2))


def test_polygon_coverage_on_cuda_equals_cpu() -> None:
    vertices = torch.as_tensor(_candidates(16, seed=0), dtype=F64)
    on_cpu = polygon_coverage(vertices, 256, 256)
    on_gpu = polygon_coverage(vertices.cuda(), 256, 256)
    assert on_gpu.device.type == "cuda"
    torch.testing.assert_close(on_gpu.cpu(), on_cpu, rtol=0, atol=1e-12)


def test_stroke_coverage_on_cuda_equals_cpu() -> None:
    rng = np.random.default_rng(1)
    start, end = (torch.as_tensor(rng.uniform(-10, 266, (32, 2)), dtype=F64) for _ in range(2))
    on_cpu = stroke_coverage(start, end, 256, 256)
    on_gpu = stroke_coverage(start.cuda(), end.cuda(), 256, 256)
    torch.testing.assert_close(on_gpu.cpu(), on_cpu, rtol=0, atol=1e-12)


@pytest.mark.parametrize("inter_pairs", ["all", "non_adjacent"])
def test_terms_and_gradients_on_cuda_equal_cpu_in_float64(zoo, inter_pairs: str) -> None:
    for name in SHAPES:
        silhouette = torch.as_tensor(zoo[name], dtype=F64)
        results = {}
        for device in ("cpu", "cuda"):
            points = torch.as_tensor(_candidates(6, seed=2), dtype=F64, device=device).requires_grad_()
            terms = jalgorithm_terms(points, silhouette.to(device), JEANS, inter_pairs)
            (grad,) = torch.autograd.grad(sum(t.sum() for t in terms.values()), points)
            results[device] = ({k: v.detach().cpu() for k, v in terms.items()}, grad.cpu())
        (cpu_terms, cpu_grad), (gpu_terms, gpu_grad) = results["cpu"], results["cuda"]
        for key in cpu_terms:
            torch.testing.assert_close(gpu_terms[key], cpu_terms[key], rtol=1e-9, atol=1e-12, msg=f"{name} {key}")
        torch.testing.assert_close(gpu_grad, cpu_grad, rtol=1e-8, atol=1e-10, msg=name)


def test_terms_gradcheck_on_cuda() -> None:
    size = 24
    yy, xx = np.mgrid[0:size, 0:size] + 0.5
    silhouette = torch.as_tensor(1.0 / (1.0 + np.exp(np.hypot(xx - 12, (yy - 13) / 1.3) - 8)), device="cuda")
    # The template shrunk onto the small canvas, nudged off the pixel grid (coverage has kinks there).
    vertices = (JEANS.template - 128) * 0.08 + 12 + 0.137
    x = torch.as_tensor(vertices[None], dtype=F64, device="cuda").requires_grad_()
    for term in ("center", "coverage", "rigid", "open", "closed", "inter", "inside"):
        term_of = lambda v, t=term: jalgorithm_terms(v, silhouette, stroke_half_width=0.5)[t]  # noqa: E731
        # CUDA's index_add sums in any order: the same backward differs in the last bits.
        assert torch.autograd.gradcheck(term_of, (x,), nondet_tol=1e-12)


def _jeans_iou(first: np.ndarray, second: np.ndarray) -> float:
    masks = [polygon_coverage(torch.as_tensor(v)[None], 256, 256)[0].numpy() > 0.5 for v in (first, second)]
    return float((masks[0] & masks[1]).sum() / (masks[0] | masks[1]).sum())


@pytest.mark.parametrize("name", FIT_SHAPES)
def test_default_fit_on_cuda_equals_the_cpu_fits(zoo, name: str) -> None:
    """CUDA fits in float64 with deterministic sums: the same fit as the CPU's torch and
    fast ones, and the four rules pass. Sums run in another order on each, so the
    vertices may differ in their last digits, and a little more after 100 steps."""
    on_gpu = fit(zoo[name], device="cuda")
    assert on_gpu.device == "cuda" and on_gpu.extra["backend"] == "torch"
    for backend in ("torch", "fast"):
        on_cpu = fit(zoo[name], backend=backend)
        assert on_gpu.objective == pytest.approx(on_cpu.objective, rel=1e-3, abs=1e-6), backend
        assert _jeans_iou(on_gpu.vertices, on_cpu.vertices) >= 0.97, backend
    report = rule_report(on_gpu.vertices, zoo[name])
    assert report.passed, report.to_json()


def test_same_seed_gives_identical_fits_on_cuda(zoo) -> None:
    first = fit(zoo["dog"], device="cuda")
    second = fit(zoo["dog"], device="cuda")
    assert np.array_equal(first.vertices, second.vertices)


def test_command_line_device_cuda_writes_the_jeans_and_says_so(tmp_path, run_cli) -> None:
    src = write_silhouette_png(tmp_path / "person.png")
    result = run_cli(src, "--device", "cuda", "--json", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    report = json.loads((tmp_path / "out" / "person.jeans.json").read_text())
    assert report["device"].startswith("cuda"), report
    assert (tmp_path / "out" / "person.jeans.png").stat().st_size > 0
