"""The fast path against the torch reference on whole fits: the 30 silhouettes of
bench/presets_report.py (both presets) and 30 random creatures of
bench/unseen_shapes.py (default preset).

    python -m bench.backend_agreement [--creatures 30] [--first-seed 1000]

Per fit: the same start chosen, the same posture, the same six rule checks, and how
far apart the vertices and objectives end. Prints one row per fit and a summary.
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.presets_report import load_shapes
from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.garments import JEANS
from jeanscv.fitting.posture import posture
from testkit.synthetic import random_creature


def compare(silhouette: np.ndarray, preset: str) -> dict:
    fast, reference = (fit(silhouette, preset, backend=b) for b in ("fast", "torch"))
    return {
        "start": fast.start_index == reference.start_index,
        "posture": posture(fast.vertices, JEANS) == posture(reference.vertices, JEANS),
        "checks": rule_report(fast.vertices, silhouette).checks == rule_report(reference.vertices, silhouette).checks,
        "vertices_px": float(np.abs(fast.vertices - reference.vertices).max()),
        "objective_rel": abs(fast.objective - reference.objective) / max(abs(reference.objective), 1e-12),
        "first_steps": float(np.nanmax(np.abs(fast.history[:5] - reference.history[:5]))),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--creatures", type=int, default=30)
    parser.add_argument("--first-seed", type=int, default=1000)
    args = parser.parse_args()
    cases = [(name, s, preset) for name, s in load_shapes().items() for preset in ("default", "paper")]
    cases += [
        (f"creature:{seed}", random_creature(seed), "default")
        for seed in range(args.first_seed, args.first_seed + args.creatures)
    ]
    print("| shape | preset | same start | same posture | same checks | max vertex gap px | objective gap (rel) |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for name, silhouette, preset in cases:
        row = compare(silhouette, preset)
        rows.append((preset, row))
        print(
            f"| {name} | {preset} | {row['start']} | {row['posture']} | {row['checks']} | {row['vertices_px']:.2g} "
            f"| {row['objective_rel']:.2g} |",
            flush=True,
        )
    for preset in ("default", "paper"):
        mine = [r for p, r in rows if p == preset]
        gaps = np.array([r["vertices_px"] for r in mine])
        print(
            f"\n{preset}: {len(mine)} fits; same start {sum(r['start'] for r in mine)}, same posture "
            f"{sum(r['posture'] for r in mine)}, same checks {sum(r['checks'] for r in mine)}; vertex gap "
            f"median {np.median(gaps):.2g} px, max {gaps.max():.2g} px; objectives within "
            f"{max(r['objective_rel'] for r in mine):.2g} (rel); first 5 steps within "
            f"{max(r['first_steps'] for r in mine):.2g}"
        )


if __name__ == "__main__":
    main()
