"""The long fuzz run: every parser and entry point of ``tests/fuzzing.py``, many cases.

    nice -n 10 python bench/fuzz.py [--cases 100000] [--targets svg,image,...] [--seed 0]
                                    [--timeout 10] [--save DIR] [--minutes M]

Each target runs in its own child process (so a crash in a C decoder or a hang is caught,
counted and the run goes on past it); case ``i`` of a target is generated from
``random.Random(f"{seed}:{target}:{i}")`` alone, so every failure is reproducible from its
number (``--only TARGET:I`` reruns one case in this process, with the traceback). A case
still running after ``--timeout`` seconds is a hang: the child is killed and restarted
after it. Failing inputs are written to ``--save`` (default ``fuzz-failures/``).

Prints, per target and in total: cases tried, contract failures (an exception other than
a one-line JeansError, a warning, C output on stderr), hangs, crashes, the slowest case
and its seconds, the rate, and the peak resident memory of the child processes.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import random
import resource
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

# Share of the cases each target gets: the command line runs a whole (tiny) fit per case.
WEIGHTS = {
    "svg": 24,
    "path_data": 8,
    "image": 28,
    "mask": 8,
    "clicks": 10,
    "clicks_file": 4,
    "garment": 8,
    "captions": 8,
    "cli": 2,
}


#: Seconds a child may take for its imports and warm-up case before its first case.
WARM_UP_SECONDS = 120


def case_rng(seed: int, target: str, index: int) -> random.Random:
    return random.Random(f"{seed}:{target}:{index}")


def _child(name: str, seed: int, start: int, stop: int, current, queue) -> None:
    """Run cases ``start..stop`` of ``name``; report failures and, at the end, the figures."""
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    from fuzzing import TARGETS, violation

    import jeanscv._command  # noqa: F401  (jeanscv_cli importable from a checkout)

    target = TARGETS[name]
    current.value = -1  # warming up: the first case pays for the imports (torch, for the command line)
    violation(target, target.generate(random.Random("warm-up")))
    slowest = (0.0, -1)
    for index in range(start, stop):
        case = target.generate(case_rng(seed, name, index))
        current.value = index
        began = time.perf_counter()
        problem = violation(target, case)
        seconds = time.perf_counter() - began
        if seconds > slowest[0]:
            slowest = (seconds, index)
        if problem is not None:
            queue.put(("failure", index, problem))
    current.value = stop
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    queue.put(("done", slowest, rss))


def _save(folder: Path, name: str, seed: int, index: int, kind: str, problem: str) -> Path:
    """Write the failing input of case ``index`` (regenerated) and what went wrong."""
    from fuzzing import TARGETS

    case = TARGETS[name].generate(case_rng(seed, name, index))
    folder.mkdir(parents=True, exist_ok=True)
    stem = folder / f"{name}-{index}"
    if name in ("image", "mask"):
        path = stem.with_suffix(Path(case[0]).suffix)
        path.write_bytes(case[1])
    elif name in ("svg", "clicks", "clicks_file"):
        path = stem.with_suffix(".svg" if name == "svg" else ".json")
        path.write_bytes(case[0])
    elif name == "garment":
        path = stem.with_suffix(".toml")
        path.write_bytes(case)
    else:
        path = stem.with_suffix(".txt")
        path.write_text(repr(case) + "\n")
    with open(folder / "failures.jsonl", "a") as log:
        log.write(json.dumps({"target": name, "index": index, "kind": kind, "problem": problem, "file": str(path)}))
        log.write("\n")
    return path


def run_target(name: str, cases: int, seed: int, timeout: float, save: Path, deadline: float) -> dict:
    """Fuzz one target in child processes; returns its figures."""
    context = multiprocessing.get_context("fork")
    figures = {"cases": 0, "failures": 0, "hangs": 0, "crashes": 0, "slowest": (0.0, -1), "rss": 0, "seconds": 0.0}
    began = time.perf_counter()
    start = 0
    while start < cases and time.time() < deadline:
        current = context.Value("q", -1)
        queue = context.Queue()
        child = context.Process(target=_child, args=(name, seed, start, cases, current, queue), daemon=True)
        child.start()
        last, last_change = current.value, time.monotonic()
        finished = False
        while True:
            while not queue.empty():
                message = queue.get()
                if message[0] == "failure":
                    figures["failures"] += 1
                    path = _save(save, name, seed, message[1], "failure", message[2])
                    print(f"  {name} case {message[1]}: {message[2]}  ({path})", flush=True)
                else:
                    _, slowest, rss = message
                    figures["slowest"] = max(figures["slowest"], slowest)
                    figures["rss"] = max(figures["rss"], rss)
                    finished = True
            if finished:
                child.join()
                start = cases
                break
            index = current.value
            if index != last:
                last, last_change = index, time.monotonic()
            stuck = time.monotonic() - last_change
            if index == -1:
                stuck -= WARM_UP_SECONDS  # imports, not a case
            if not child.is_alive() and queue.empty():
                child.join()
                figures["crashes"] += 1
                path = _save(save, name, seed, index, "crash", f"child died, exit {child.exitcode}")
                print(f"  {name} case {index}: the process died (exit {child.exitcode})  ({path})", flush=True)
                if index < 0:  # died warming up: nothing to skip past
                    cases = start
                start = max(index + 1, start)
                break
            if stuck > timeout:
                child.kill()
                child.join()
                figures["hangs"] += 1
                figures["slowest"] = max(figures["slowest"], (stuck, index))
                path = _save(save, name, seed, index, "hang", f"still running after {timeout:g} s")
                print(f"  {name} case {index}: hang (over {timeout:g} s)  ({path})", flush=True)
                if index < 0:
                    cases = start
                start = max(index + 1, start)
                break
            if time.time() > deadline:
                child.kill()
                child.join()
                start = cases = index  # out of time: count what ran
                break
            time.sleep(0.05)
        figures["cases"] = start
    figures["seconds"] = time.perf_counter() - began
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    figures["rss"] = max(figures["rss"], children)
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=100_000, help="cases over all targets (by WEIGHTS)")
    parser.add_argument("--targets", default=",".join(WEIGHTS))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds before a case is a hang")
    parser.add_argument("--save", type=Path, default=Path("fuzz-failures"))
    parser.add_argument("--minutes", type=float, default=0, help="stop after this long (0: no limit)")
    parser.add_argument("--only", help="TARGET:INDEX: run one case here, with its traceback")
    args = parser.parse_args()

    if args.only:
        from fuzzing import TARGETS

        import jeanscv._command  # noqa: F401

        name, index = args.only.split(":")
        case = TARGETS[name].generate(case_rng(args.seed, name, int(index)))
        print(repr(case)[:2000])
        TARGETS[name].run(case)
        print("kept the contract")
        return

    names = args.targets.split(",")
    total_weight = sum(WEIGHTS[n] for n in names)
    deadline = time.time() + args.minutes * 60 if args.minutes else float("inf")
    print(f"fuzzing {', '.join(names)}: {args.cases} cases, seed {args.seed}, hang after {args.timeout:g} s")
    totals = {"cases": 0, "failures": 0, "hangs": 0, "crashes": 0, "slowest": (0.0, ""), "rss": 0, "seconds": 0.0}
    rows = []
    for name in names:
        cases = max(1, round(args.cases * WEIGHTS[name] / total_weight))
        figures = run_target(name, cases, args.seed, args.timeout, args.save, deadline)
        rows.append((name, figures))
        for key in ("cases", "failures", "hangs", "crashes", "seconds"):
            totals[key] += figures[key]
        totals["rss"] = max(totals["rss"], figures["rss"])
        if figures["slowest"][0] > totals["slowest"][0]:
            totals["slowest"] = (figures["slowest"][0], f"{name}:{figures['slowest'][1]}")
        seconds, index = figures["slowest"]
        print(
            f"{name:12s} {figures['cases']:7d} cases {figures['failures']:4d} failures {figures['hangs']:3d} hangs "
            f"{figures['crashes']:3d} crashes  slowest {seconds:6.2f} s (case {index})  "
            f"{figures['cases'] / max(figures['seconds'], 1e-9):7.1f} cases/s  peak {figures['rss'] / 2**20:6.0f} MiB",
            flush=True,
        )
    seconds, where = totals["slowest"]
    print(
        f"total: {totals['cases']} cases in {totals['seconds'] / 60:.1f} min "
        f"({totals['cases'] / max(totals['seconds'], 1e-9):.0f} cases/s), {totals['failures']} failures, "
        f"{totals['hangs']} hangs, {totals['crashes']} crashes; slowest case {where} {seconds:.2f} s; "
        f"peak memory of a fuzzing process {totals['rss'] / 2**20:.0f} MiB"
    )


if __name__ == "__main__":
    main()
