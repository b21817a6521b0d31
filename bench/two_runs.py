"""Two ``jeanscv`` runs at once on the same folder and output folder, against one alone.

    nice -n 10 python bench/two_runs.py [--count 200] [--jobs 1] [--iterations 20] [--repeat 2]

Each input is claimed while its outputs are made (cli/runs.py); a run that finds a file
claimed puts it off to the end, so the two runs work on different files: together they
should finish no later than one run alone plus a small margin (start-up), make each output
once, and leave no temporary file.
Prints the wall times (one alone, then the pair, alternating ``--repeat`` times on fresh
output folders), how many outputs each run of the pair made, and the checks.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from big_folder import make_inputs  # noqa: E402


def start(folder: Path, out: Path, jobs: int, iterations: int) -> subprocess.Popen:
    args = [sys.executable, "-m", "jeanscv", str(folder), "-o", str(out), "-j", str(jobs)]
    args += ["--iterations", str(iterations), "--starts", "1"]
    return subprocess.Popen(args, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)


def made(stderr: str) -> int:
    match = re.search(r"^(\d+) ok, (\d+) failed, (\d+) skipped", stderr, re.MULTILINE)
    return int(match.group(1)) if match else -1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--iterations", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="jeanscv-two-") as tmp:
        folder = Path(tmp) / "in"
        make_inputs(folder, args.count)
        print(f"{args.count} inputs, -j {args.jobs} per run, {args.iterations} iterations")
        for round_ in range(args.repeat):
            out = Path(tmp) / f"alone{round_}"
            began = time.perf_counter()
            alone = start(folder, out, args.jobs, args.iterations)
            _, stderr = alone.communicate()
            one = time.perf_counter() - began
            out = Path(tmp) / f"pair{round_}"
            began = time.perf_counter()
            pair = [start(folder, out, args.jobs, args.iterations) for _ in range(2)]
            results = [run.communicate()[1] for run in pair]
            two = time.perf_counter() - began
            outputs = sorted(p.name for p in out.iterdir())
            temporaries = [name for name in outputs if name.endswith(".tmp")]
            counts = [made(r) for r in results]
            ok = (
                all(run.returncode == 0 for run in pair)
                and sum(counts) == args.count
                and len(outputs) == args.count
                and not temporaries
            )
            print(
                f"round {round_ + 1}: one run alone {one:6.1f} s; two at once {two:6.1f} s "
                f"({two / one:.2f}x, {two - one:+.1f} s); outputs made by each: {counts[0]} + {counts[1]}; "
                f"{len(outputs)} outputs, {len(temporaries)} temporary files -> {'ok' if ok else 'WRONG'}"
            )


if __name__ == "__main__":
    main()
