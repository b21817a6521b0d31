"""The default preset on random creatures nobody drew by hand: how many pass all six
checks of the paper's four rules, which checks fail, and how many jeans hang upright.

    python -m bench.unseen_shapes [--count 40] [--first-seed 1000]
"""

from __future__ import annotations

import argparse
from collections import Counter

from jeanscv.fitting.checks import rule_report
from jeanscv.fitting.fitter import fit
from jeanscv.fitting.posture import posture_name, tilt_degrees
from testkit.synthetic import random_creature


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--count", type=int, default=40)
    parser.add_argument("--first-seed", type=int, default=1000)
    parser.add_argument("--preset", default="default")
    args = parser.parse_args()
    failures: Counter[str] = Counter()
    passed = upright = 0
    for seed in range(args.first_seed, args.first_seed + args.count):
        silhouette = random_creature(seed)
        result = fit(silhouette, args.preset)
        report = rule_report(result.vertices, silhouette)
        posture = posture_name(tilt_degrees(result.vertices, result.garment))
        passed += report.passed
        upright += posture == "upright"
        failed = [name for name, ok in report.checks.items() if not ok]
        failures.update(failed)
        print(f"seed {seed}: {'pass' if report.passed else 'FAIL ' + ', '.join(failed)}, {posture}", flush=True)
    print(
        f"\n{args.preset}: {passed}/{args.count} random creatures pass all six checks, {upright} upright; "
        f"failures by check: {dict(failures)}"
    )


if __name__ == "__main__":
    main()
