"""The jalgorithm's loss: the paper's seven terms (its equations 2-10) in torch,
and our eighth, ``upright`` (weight 0 in the paper's objective).

All terms take vertices in canvas pixels ``(B, N, 2)`` and a silhouette ``S`` of
shape ``(256, 256)`` or ``(B, 256, 256)``; each term is returned separately as a
``(B,)`` tensor so that presets only choose weights. Coordinates inside the terms
are normalised (pixels / canvas size), as in the paper.

For speed, the maps ``J`` and ``R(e)`` are rendered only in a window around each
candidate polygon (its bounding box plus the stroke radius, inside the canvas);
silhouette sums outside the window are added back exactly, so the terms equal the
full-canvas ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from .garments import JEANS, Garment
from .render import StrokeBands, coverage_from_winding, polygon_edges, rasterize
from .terms import (
    PAPER_WEIGHTS,
    STROKE_HALF_WIDTH,
    TERM_NAMES,
    UPRIGHT_FREE_DEGREES,
    UPRIGHT_SATURATE_DEGREES,
    affine_residual_operator,
    check_inter_pairs,
)

_EPS = 1e-6


@dataclass(frozen=True)
class _GarmentTensors:
    """Index and operator tensors of a garment, built once per garment, dtype and device."""

    residual: Tensor  # (N, N) affine residual operator
    waist: Tensor  # (2,)
    open_edges: Tensor
    closed_edges: Tensor
    pairs: Tensor  # (P, 2)


_GARMENT_TENSORS: dict[tuple, tuple[Garment, _GarmentTensors]] = {}


def _garment_tensors(garment: Garment, inter_pairs: str, like: Tensor) -> _GarmentTensors:
    key = (id(garment), inter_pairs, like.dtype, str(like.device))
    cached = _GARMENT_TENSORS.get(key)
    if cached is not None and cached[0] is garment:
        return cached[1]
    device = like.device

    def index(values) -> Tensor:
        return torch.as_tensor(np.asarray(values, dtype=np.int64), device=device)

    tensors = _GarmentTensors(
        residual=like.new_tensor(affine_residual_operator(garment.template)),
        waist=index(garment.waist),
        open_edges=index(garment.open_edges),
        closed_edges=index(garment.closed_edges),
        pairs=index(garment.edge_pairs(adjacent=inter_pairs == "all")).reshape(-1, 2),
    )
    _GARMENT_TENSORS[key] = (garment, tensors)
    return tensors


@dataclass
class CanvasWindow:
    """Per-candidate crops of the canvas where the polygon and its strokes live."""

    origin: Tensor  # (B, 2) integer (x, y) offsets, as the vertices' dtype
    height: int
    width: int
    silhouette: Tensor  # (B, h, w) S inside the window
    outside_sum: Tensor  # (B,) sum of S outside the window


def canvas_window(vertices: Tensor, silhouette: Tensor, margin: float) -> CanvasWindow:
    """The smallest common window size holding every candidate (plus ``margin``).

    Args:
        vertices: ``(B, N, 2)`` canvas pixels.
        silhouette: ``(H, W)`` shared by all candidates, or ``(B, H, W)``.
    """
    batch = vertices.shape[0]
    size_y, size_x = silhouette.shape[-2:]
    with torch.no_grad():
        corners = torch.cat([vertices.amin(dim=1) - margin, vertices.amax(dim=1) + margin], dim=1)
        corners = corners.cpu().numpy().astype(np.float64)
    limits = np.array([size_x, size_y], dtype=np.float64)
    low = np.minimum(np.clip(np.floor(corners[:, :2]), 0, None), limits)
    high = np.maximum(np.minimum(np.ceil(corners[:, 2:]), limits), low)
    extent = np.maximum((high - low).max(axis=0), 1)
    width, height = int(extent[0]), int(extent[1])
    origin = np.minimum(low, limits - extent).astype(np.int64)
    # Plain slices: cheaper than a gather, and S carries no gradient.
    crop = torch.stack(
        [
            (silhouette if silhouette.dim() == 2 else silhouette[b])[
                origin[b, 1] : origin[b, 1] + height, origin[b, 0] : origin[b, 0] + width
            ]
            for b in range(batch)
        ]
    )
    total = silhouette.sum(dim=(-2, -1)).expand(batch)
    outside = total - crop.sum(dim=(-2, -1))
    origin = torch.as_tensor(origin, dtype=vertices.dtype, device=vertices.device)
    return CanvasWindow(origin, height, width, crop, outside)


@dataclass
class SharedPixels:
    """Per-edge stroke alphas on the canvas pixels that two or more strokes touch.

    Stroke terms are sums of per-stroke values except where strokes meet (the
    union clamps, the pair overlaps), so those few pixels are gathered into a small
    table instead of rendering every stroke on the full canvas.
    """

    alpha: Tensor  # (m, E) stroke alpha of every edge at each shared pixel
    candidate: Tensor  # (m,) which batch entry the pixel belongs to
    silhouette: Tensor  # (m,) S at the pixel


def _shared_pixels(
    alpha: Tensor, key: Tensor, silhouette_flat: Tensor, pixels: int, per_candidate: bool
) -> SharedPixels:
    """Collect pixels covered by >= 2 strokes.

    ``alpha``, ``key``: ``(B, E, cells)``; ``key = candidate * pixels + pixel``;
    ``silhouette_flat``: ``S`` flattened, shared (``pixels``) or per candidate.
    """
    batch, num_edges, cells_per_edge = alpha.shape
    flat_key = key.reshape(-1).cpu().numpy()
    touched = (alpha.detach() > 0).reshape(-1).cpu().numpy()
    # Band cells of one stroke are distinct pixels, so this counts strokes per pixel.
    counts = np.bincount(flat_key[touched], minlength=batch * pixels)
    unique_key = np.flatnonzero(counts >= 2)
    shared = np.flatnonzero(touched & (counts[flat_key] >= 2))
    slot = np.searchsorted(unique_key, flat_key[shared])
    edge = (shared // cells_per_edge) % num_edges
    s_key = unique_key if per_candidate else unique_key % pixels
    device = alpha.device
    shared_cell = torch.as_tensor(shared, device=device)
    unique_key = torch.as_tensor(unique_key, device=device)
    slot = torch.as_tensor(slot, device=device)
    edge = torch.as_tensor(edge, device=device)
    s_key = torch.as_tensor(s_key, device=device)
    values = alpha.reshape(-1).index_select(0, shared_cell)
    table = alpha.new_zeros(len(unique_key) * num_edges).index_add(0, slot * num_edges + edge, values)
    table = table.view(len(unique_key), num_edges)
    return SharedPixels(table, unique_key // pixels, silhouette_flat.index_select(0, s_key))


def _pair_terms(shared: SharedPixels, areas: Tensor, pairs: Tensor) -> Tensor:
    """``L_inter`` for ``(P, 2)`` edge pairs given per-edge stroke ``areas`` ``(B, E)``.

    ``sum R1 R2`` and the correction in
    ``sum min(R1 + R2, 1) = sum R1 + sum R2 - sum max(R1 + R2 - 1, 0)`` vanish
    where fewer than two strokes are present.
    """
    batch = areas.shape[0]
    if pairs.numel() == 0:
        return areas.new_zeros(batch)
    first = shared.alpha.index_select(1, pairs[:, 0])
    second = shared.alpha.index_select(1, pairs[:, 1])
    overlap = areas.new_zeros(batch, len(pairs)).index_add(0, shared.candidate, first * second)
    excess = areas.new_zeros(batch, len(pairs)).index_add(
        0, shared.candidate, torch.clamp(first + second - 1.0, min=0.0)
    )
    union = areas.index_select(1, pairs[:, 0]) + areas.index_select(1, pairs[:, 1]) - excess
    return (overlap / union.clamp(min=_EPS)).sum(dim=1)


def _union_on_body(shared: SharedPixels, areas: Tensor, on_body: Tensor, ids: Tensor) -> Tensor:
    """``sum R(E) S / sum R(E)`` for the union of the strokes of edges ``ids``.

    Strokes drawn together clamp at 1 where they overlap, so the union's sums are
    the per-stroke sums less the excess at shared pixels.
    """
    stacked = shared.alpha.index_select(1, ids).sum(dim=1)
    excess = stacked - torch.clamp(stacked, max=1.0)
    batch = areas.shape[0]
    excess_area = areas.new_zeros(batch).index_add(0, shared.candidate, excess)
    excess_on_body = areas.new_zeros(batch).index_add(0, shared.candidate, excess * shared.silhouette)
    union_area = areas.index_select(1, ids).sum(dim=1) - excess_area
    return (on_body.index_select(1, ids).sum(dim=1) - excess_on_body) / union_area.clamp(min=_EPS)


def upright_term(vertices: Tensor, garment: Garment = JEANS) -> Tensor:
    """How far the garment is from hanging upright, ``(B, N, 2)`` -> ``(B,)``.

    With ``d`` = hems midpoint - waist midpoint and ``w`` = the waist vector (see
    :attr:`Garment.hems`), ``c = (d_y / |d| + |w_x| / |w|) / 2`` is 1 for an upright
    garment (legs straight down the image, waistband level) and ``cos t`` for one turned
    by ``t``. The term is ``clamp(cos 20deg - c, 0, cos 20deg - cos 60deg)``: free within
    20 degrees of upright, a pull towards upright up to 60 degrees, and flat beyond, so
    that it ranks lying and upside-down starts equally and never drags them through a
    half turn (pixels or normalised coordinates give the same value).
    """
    free = float(np.cos(np.radians(UPRIGHT_FREE_DEGREES)))
    saturated = free - float(np.cos(np.radians(UPRIGHT_SATURATE_DEGREES)))
    waist_a, waist_b = vertices[:, garment.waist[0]], vertices[:, garment.waist[1]]
    hem_a, hem_b = vertices[:, garment.hems[0]], vertices[:, garment.hems[1]]
    down = (hem_a + hem_b - waist_a - waist_b) / 2
    across = waist_b - waist_a
    down_cos = down[:, 1] / down.norm(dim=-1).clamp(min=_EPS)
    level_cos = across[:, 0].abs() / across.norm(dim=-1).clamp(min=_EPS)
    return torch.clamp(free - (down_cos + level_cos) / 2, min=0.0, max=saturated)


def _fill_terms(fill: Tensor, s_win: Tensor, outside_sum: Tensor, s_total: Tensor) -> tuple[Tensor, Tensor]:
    """``coverage`` and ``inside`` ``(B,)`` from the polygons' fill ``(B, h, w)`` over the
    canvas window, the silhouette there ``s_win``, its mass outside the window and its
    total: (1/2 - the silhouette's uncovered share)^2, and the fill's share off it."""
    fill_area = fill.sum(dim=(-2, -1))
    uncovered = outside_sum + torch.clamp(s_win - fill, min=0).sum(dim=(-2, -1))
    coverage = (0.5 - uncovered / s_total.clamp(min=_EPS)) ** 2
    inside = torch.clamp(fill - s_win, min=0).sum(dim=(-2, -1)) / fill_area.clamp(min=_EPS)
    return coverage, inside


def _stroke_terms(
    bands: StrokeBands, batch: int, num_edges: int, silhouette: Tensor, indices: _GarmentTensors
) -> tuple[Tensor, Tensor, Tensor]:
    """``open``, ``closed`` and ``inter`` ``(B,)`` from the ``batch x num_edges`` edges'
    stroke bands over the silhouette ``(H, W)`` or ``(B, H, W)``."""
    pixels = silhouette.shape[-2] * silhouette.shape[-1]
    alpha = bands.alpha.reshape(batch, num_edges, -1)
    flat = bands.flat_index(silhouette.shape[-1]).reshape(batch, num_edges, -1)
    key = flat + torch.arange(batch, device=flat.device)[:, None, None] * pixels
    # A shared (H, W) silhouette is indexed by pixel, a per-candidate one by key.
    s_index = flat if silhouette.dim() == 2 else key
    silhouette_flat = silhouette.reshape(-1)
    s_cells = silhouette_flat.index_select(0, s_index.reshape(-1)).view(flat.shape)
    areas = alpha.sum(dim=-1)
    on_body = (alpha * s_cells).sum(dim=-1)
    shared = _shared_pixels(alpha, key, silhouette_flat, pixels, per_candidate=silhouette.dim() == 3)

    open_term = -_union_on_body(shared, areas, on_body, indices.open_edges)
    closed_term = _union_on_body(shared, areas, on_body, indices.closed_edges)
    inter = _pair_terms(shared, areas, indices.pairs)
    return open_term, closed_term, inter


def jalgorithm_terms(
    vertices: Tensor,
    silhouette: Tensor,
    garment: Garment = JEANS,
    inter_pairs: str = "all",
    stroke_half_width: float = STROKE_HALF_WIDTH,
) -> dict[str, Tensor]:
    """The paper's seven terms and ``upright``, unweighted, one value per candidate.

    Args:
        vertices: ``(B, N, 2)`` garment vertices in canvas pixels, template order.
        silhouette: ``(H, W)`` or ``(B, H, W)`` alpha ``S`` in [0, 1] (H = W = 256 in
            the paper; the normalisation uses W).
        garment: which edges are open, the waist pair and the rigid template.
        inter_pairs: ``"all"`` (the paper: every pair of edges) or ``"non_adjacent"``
            (pairs that share no vertex).
        stroke_half_width: half the width of the strokes ``R(e)`` in pixels of
            ``silhouette`` (the paper's 2.5 on its 256-px canvas).

    Returns:
        ``{name: (B,) tensor}`` for ``center, coverage, rigid, open, closed, inter,
        inside, upright`` (:func:`upright_term`).
    """
    check_inter_pairs(inter_pairs)
    batch = vertices.shape[0]
    silhouette = silhouette.to(vertices.dtype)
    scale = float(silhouette.shape[-1])
    normalised = vertices / scale

    indices = _garment_tensors(garment, inter_pairs, vertices)
    waist = normalised.index_select(1, indices.waist).mean(dim=1)
    center = ((waist - 0.5) ** 2).sum(dim=-1)

    rigid = (torch.einsum("ij,bjk->bik", indices.residual, normalised) ** 2).sum(dim=(-2, -1))

    window = canvas_window(vertices, silhouette, margin=1.0)
    local = vertices - window.origin[:, None, :]
    s_win = window.silhouette
    s_total = s_win.sum(dim=(-2, -1)) + window.outside_sum

    num_edges = vertices.shape[1]
    start, end = polygon_edges(vertices)
    winding, bands = rasterize(
        fill_edges=polygon_edges(local),
        fill_size=(window.height, window.width),
        strokes=(start.reshape(-1, 2), end.reshape(-1, 2)),
        canvas_size=tuple(silhouette.shape[-2:]),
        half_width=stroke_half_width,
    )
    coverage, inside = _fill_terms(coverage_from_winding(winding), s_win, window.outside_sum, s_total)
    open_term, closed_term, inter = _stroke_terms(bands, batch, num_edges, silhouette, indices)
    return {
        "center": center,
        "coverage": coverage,
        "rigid": rigid,
        "open": open_term,
        "closed": closed_term,
        "inter": inter,
        "inside": inside,
        "upright": upright_term(vertices, garment),
    }


def weighted_total(terms: dict[str, Tensor], weights: dict[str, float]) -> Tensor:
    """``sum_i k_i L_i`` over the named terms, ``(B,)``."""
    return sum(weights[name] * terms[name] for name in TERM_NAMES if weights.get(name, 0.0))


class JalgorithmLoss(torch.nn.Module):
    """The weighted jalgorithm loss as a module: ``(B, N, 2)`` pixels -> ``(B,)``.

    Args:
        silhouette: ``(H, W)`` alpha ``S`` (registered as a buffer).
        weights: term weights (default: the paper's).
        garment, inter_pairs: as in :func:`jalgorithm_terms`.
    """

    def __init__(
        self,
        silhouette: Tensor,
        weights: dict[str, float] | None = None,
        garment: Garment = JEANS,
        inter_pairs: str = "all",
    ) -> None:
        super().__init__()
        self.register_buffer("silhouette", torch.as_tensor(silhouette))
        self.weights = dict(PAPER_WEIGHTS if weights is None else weights)
        self.garment = garment
        self.inter_pairs = inter_pairs

    def forward(self, vertices: Tensor) -> Tensor:  # noqa: D102
        terms = jalgorithm_terms(vertices, self.silhouette, self.garment, self.inter_pairs)
        return weighted_total(terms, self.weights)
