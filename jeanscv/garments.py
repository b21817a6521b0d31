"""Garment templates: the polygon the fitter deforms, and which edges are open.

A garment is data. Vertices are in canvas pixels (x right, y down) on the 256 canvas;
edge ``i`` runs from vertex ``i`` to vertex ``(i + 1) % n``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np


@dataclass(frozen=True)
class Garment:
    """A closed polygon template with open/closed edge labels.

    ``open_edges`` are indices of edges the body passes through (waistband, leg
    openings); every other edge is closed (a seam the body should not cross).
    ``waist`` names the two vertices whose midpoint is the waistband centre.
    """

    name: str
    template: np.ndarray  # (n, 2) canvas pixels
    open_edges: tuple[int, ...]
    waist: tuple[int, int]
    description: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def num_vertices(self) -> int:
        return int(self.template.shape[0])

    @property
    def edges(self) -> np.ndarray:
        """``(n, 2)`` vertex indices of each edge, in order."""
        n = self.num_vertices
        return np.stack([np.arange(n), (np.arange(n) + 1) % n], axis=1)

    @property
    def closed_edges(self) -> tuple[int, ...]:
        return tuple(i for i in range(self.num_vertices) if i not in self.open_edges)

    def edge_pairs(self, adjacent: bool = True) -> np.ndarray:
        """``(P, 2)`` edge-index pairs for ``L_inter``; ``adjacent=False`` drops pairs sharing a vertex."""
        n = self.num_vertices
        pairs = [
            (a, b)
            for a, b in combinations(range(n), 2)
            if adjacent or (b - a) % n not in (1, n - 1)
        ]
        return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


JEANS = Garment(
    name="jeans",
    # The paper's prototypical jeans: 0 outer bottom-left, 1 waist left, 2 waist right,
    # 3 outer bottom-right, 4 inner bottom-right, 5 crotch right, 6 crotch left,
    # 7 inner bottom-left.
    template=np.array(
        [
            [86.6217, 202.201],
            [86.6217, 70.2886],
            [159.059, 70.2886],
            [159.059, 202.201],
            [133.897, 202.201],
            [128.559, 105.364],
            [117.884, 105.364],
            [111.784, 202.201],
        ]
    ),
    # Edge i joins vertex i and i+1: 1 is the waistband (1-2), 3 the right leg
    # opening (3-4), 7 the left leg opening (7-0).
    open_edges=(1, 3, 7),
    waist=(1, 2),
    description="The paper's prototypical jeans (8 vertices).",
)

GARMENTS: dict[str, Garment] = {JEANS.name: JEANS}


def get_garment(name: str) -> Garment:
    """Look up a built-in garment by name."""
    from .errors import JeansError

    try:
        return GARMENTS[name]
    except KeyError:
        raise JeansError(f"unknown garment {name!r} (known: {', '.join(sorted(GARMENTS))})") from None
