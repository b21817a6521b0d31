"""The ``jeanscv`` command on folders: discovery, mirrored outputs, resume, reports,
worker processes and interruption."""

from __future__ import annotations

import json
import os
import platform
import queue
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, write_silhouette_png, write_silhouette_svg
from PIL import Image

FAST = ("--iterations", "3", "--starts", "1")


def assert_interrupted(process, lines: list[str], code: int, timeout: float) -> None:
    """A batch stopped by a signal ends as the command promises: exit ``code``, no
    traceback, the resume line, a summary that counts the skipped inputs. ``lines``: its
    standard error read so far, to which the rest is added."""
    _, rest = process.communicate(timeout=timeout)
    lines += rest.splitlines()
    assert process.returncode == code, lines
    assert "Traceback" not in rest
    assert "jeanscv: interrupted: finished outputs are kept; run again to resume" in lines
    assert lines[-1].split(" in ")[0].endswith("skipped")


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _tree(root: Path, corrupt: bool = True) -> None:
    """root/a.png, root/sub/b.png, root/sub/deeper/c.svg, a text file, a jeanscv output,
    a hidden file and (optionally) a corrupt JPEG in root/sub."""
    (root / "sub" / "deeper").mkdir(parents=True)
    write_silhouette_png(root / "a.png", "person")
    write_silhouette_png(root / "sub" / "b.png", "dog")
    write_silhouette_svg(root / "sub" / "deeper" / "c.svg")
    (root / "notes.txt").write_text("not an image\n")
    write_silhouette_png(root / "sub" / "old.jeans.png", "person")  # a previous output: never an input
    (root / ".hidden.png").write_bytes(b"junk")
    if corrupt:
        noise = np.random.default_rng(0).integers(0, 255, (64, 64, 3), dtype=np.uint8)
        Image.fromarray(noise).save(root / "sub" / "full.jpg")
        (root / "sub" / "corrupt.jpg").write_bytes((root / "sub" / "full.jpg").read_bytes()[:300])
        (root / "sub" / "full.jpg").unlink()


def _files(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_folder_tree_is_mirrored_and_errors_listed(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _tree(tmp_path / "in")
    result = run_cli("in", "-r", "-o", "out", *FAST, "--json", "--report", "run.jsonl", "-j", "1")
    assert result.exit_code == 1
    assert "Traceback" not in result.stderr
    assert _files(tmp_path / "out") == [
        "a.jeans.json",
        "a.jeans.png",
        "sub/b.jeans.json",
        "sub/b.jeans.png",
        "sub/deeper/c.jeans.json",
        "sub/deeper/c.jeans.png",
    ]
    for name in ("a", "sub/b", "sub/deeper/c"):
        with Image.open(tmp_path / "out" / f"{name}.jeans.png") as im:
            assert im.size == (256, 256)
        report = json.loads((tmp_path / "out" / f"{name}.jeans.json").read_text())
        assert report["output"] == f"out/{name}.jeans.png"
    lines = result.stderr.splitlines()
    assert re.search(
        r": 4 inputs, 1 worker \(-j\), device cpu \((fast|torch)\), preset default, 3 iterations$", lines[0]
    )
    assert [line for line in lines if line.startswith("jeanscv: ")] == [
        "jeanscv: in/sub/corrupt.jpg: truncated or corrupt image"
    ]
    # Plain progress lines (not a terminal), in input order for a serial run.
    progress = [line for line in lines if line.startswith("[")]
    assert [line.split(" (")[0] for line in progress] == [
        "[1/4] in/a.png -> out/a.jeans.png",
        "[2/4] in/sub/b.png -> out/sub/b.jeans.png",
        "[4/4] in/sub/deeper/c.svg -> out/sub/deeper/c.jeans.png",
    ]
    assert lines[-1].startswith("3 ok, 1 failed, 1 skipped in ")
    records = [json.loads(line) for line in (tmp_path / "run.jsonl").read_text().splitlines()]
    by_input = {r["input"]: r for r in records}
    assert {k: r["status"] for k, r in by_input.items()} == {
        "in/notes.txt": "skipped",
        "in/a.png": "ok",
        "in/sub/b.png": "ok",
        "in/sub/corrupt.jpg": "failed",
        "in/sub/deeper/c.svg": "ok",
    }
    assert by_input["in/sub/corrupt.jpg"]["error"] == "truncated or corrupt image"
    ok = by_input["in/a.png"]
    assert ok["output"] == "out/a.jeans.png" and ok["kind"] == "silhouette" and ok["fit_seconds"] > 0
    assert ok["written"] == ["out/a.jeans.png", "out/a.jeans.json"]


def test_resume_skips_finished_outputs_and_overwrite_redoes_them(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _tree(tmp_path / "in", corrupt=False)
    assert run_cli("in", "-r", *FAST, "-q").exit_code == 0
    outputs = ["in/a.jeans.png", "in/sub/b.jeans.png", "in/sub/deeper/c.jeans.png"]
    assert all((tmp_path / p).is_file() for p in outputs)
    old = 1_000_000_000
    for p in outputs:
        os.utime(tmp_path / p, ns=(old, old))
    os.remove(tmp_path / outputs[1])  # as if interrupted before b was written

    again = run_cli("in", "-r", *FAST)
    assert again.exit_code == 0
    assert again.stderr.splitlines()[-1].startswith("1 ok, 0 failed, 3 skipped in ")  # a and c, notes.txt
    assert os.stat(tmp_path / outputs[0]).st_mtime_ns == old
    assert os.stat(tmp_path / outputs[2]).st_mtime_ns == old
    assert (tmp_path / outputs[1]).is_file()

    redo = run_cli("in", "-r", *FAST, "--overwrite", "-q")
    assert redo.exit_code == 0
    assert all(os.stat(tmp_path / p).st_mtime_ns > old for p in outputs)
    # The old output of a previous run stays untouched and is not an input.
    assert not (tmp_path / "in" / "sub" / "old.jeans.jeans.png").exists()


def test_folder_without_recursion_globs_and_name_clashes(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _tree(tmp_path / "in", corrupt=False)
    write_silhouette_svg(tmp_path / "in" / "a.svg")  # clashes with a.png: a.svg.jeans.png
    result = run_cli("in", "in/sub/*.png", *FAST, "-o", "out", "-q")
    assert result.exit_code == 0, result.stderr
    assert _files(tmp_path / "out") == ["a.jeans.png", "a.svg.jeans.png", "b.jeans.png"]


def test_a_clash_found_while_jobs_are_made_is_counted_in_order(tmp_path, run_cli, monkeypatch):
    """Output names are decided as the jobs are made, in order: x.svg would take
    x.svg.jeans.png, which x.svg.png (named first) already has. It fails in its place in
    the progress count, and the summary adds up."""
    monkeypatch.chdir(tmp_path)
    write_silhouette_png(tmp_path / "x.svg.png")
    write_silhouette_png(tmp_path / "x.png")
    write_silhouette_svg(tmp_path / "x.svg")
    result = run_cli("x.svg.png", "x.png", "x.svg", *FAST, "-j", "1")
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert ": 3 inputs, 1 worker (-j)" in lines[0]
    assert [line.split(" (")[0] for line in lines[1:-1]] == [
        "[1/3] x.svg.png -> x.svg.jeans.png",
        "[2/3] x.png -> x.jeans.png",
        "jeanscv: x.svg: its output x.svg.jeans.png would also be the output of x.svg.png",
    ]
    assert lines[-1].startswith("2 ok, 1 failed, 0 skipped in ")
    assert _files(tmp_path) == ["x.jeans.png", "x.png", "x.svg", "x.svg.jeans.png", "x.svg.png"]


@pytest.mark.usefixtures("compiled_kernels")
def test_python_m_jeanscv_with_worker_processes(tmp_path):
    _tree(tmp_path / "in", corrupt=True)
    done = subprocess.run(
        [sys.executable, "-m", "jeanscv", "in", "-r", "-j", "2", "-o", "out", *FAST],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=_env(),
        timeout=240,
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert _files(tmp_path / "out") == ["a.jeans.png", "sub/b.jeans.png", "sub/deeper/c.jeans.png"]
    lines = done.stderr.splitlines()
    assert "jeanscv: in/sub/corrupt.jpg: truncated or corrupt image" in lines
    assert sorted(line.split(" (")[0].split("] ")[1] for line in lines if line.startswith("[")) == [
        "in/a.png -> out/a.jeans.png",
        "in/sub/b.png -> out/sub/b.jeans.png",
        "in/sub/deeper/c.svg -> out/sub/deeper/c.jeans.png",
    ]
    assert lines[-1].startswith("3 ok, 1 failed, 1 skipped in ")


@pytest.mark.usefixtures("compiled_kernels")
@pytest.mark.parametrize(("sig", "code", "jobs"), [(signal.SIGINT, 130, "1"), (signal.SIGTERM, 143, "2")])
def test_interrupt_keeps_finished_outputs_and_no_partial_files(tmp_path, sig, code, jobs):
    # Enough files that the run cannot finish between its first result and the signal,
    # however late the signal comes (with 12 it once did, on a busy machine); the run
    # stops at the signal, so more files cost the test nothing.
    count = 48
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(count):
        write_silhouette_png(folder / f"s{i:02d}.png", "person")
    process = subprocess.Popen(
        [sys.executable, "-m", "jeanscv", str(folder), "-j", jobs, "--iterations", "60", "--starts", "2"],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env=_env(),
        start_new_session=jobs == "1",  # a parent with workers signals only itself, like `kill PID`
    )
    lines = []
    deadline = time.monotonic() + 180
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        lines.append(line.rstrip("\n"))
        if line.startswith(f"[1/{count}]") or not line:
            break
    if jobs == "1":
        os.killpg(process.pid, sig)  # Ctrl-C reaches the whole process group
    else:
        process.send_signal(sig)
    assert_interrupted(process, lines, code, timeout=120)
    outputs = sorted(folder.glob("*.jeans.png"))
    assert 1 <= len(outputs) < count
    assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []  # no temporary files
    for path in outputs:
        with Image.open(path) as im:
            assert im.size == (256, 256)
            assert np.asarray(im).shape == (256, 256, 3)  # decodes completely


def test_a_signal_during_a_pool_is_acted_on_where_the_loop_waits():
    """Ctrl-C or SIGTERM while the pool runs must not raise inside concurrent.futures: an
    exception there once left a future's lock held, and the process never exited. The
    handler only notes the signal; the loop raises it where it takes the next finished
    file, and after the last one."""
    from jeanscv_cli import pool

    class Stop(BaseException):
        pass

    def stop(signum, frame):
        raise Stop

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        finished = queue.SimpleQueue()
        with pool._signals_noted(finished):
            finished.put("a file")
            os.kill(os.getpid(), signal.SIGTERM)  # noted, not raised here
            time.sleep(0.01)
            assert pool._next_finished(finished) == "a file"
            with pytest.raises(Stop):
                pool._next_finished(finished)
            os.kill(os.getpid(), signal.SIGTERM)  # after the last file
            time.sleep(0.01)
            with pytest.raises(Stop):
                pool._act_on_noted(finished)
        assert signal.getsignal(signal.SIGTERM) is stop
    finally:
        signal.signal(signal.SIGTERM, previous)


# A worker's setup, run in a fresh interpreter: it changes process-wide settings.
_WORKER_SETUP = """
import os, sys
import numpy as np
from jeanscv_cli.worker import init_worker

def resident_mb():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20

def kept_after_free():
    block = np.ones(64 * 2**20, np.uint8)  # 64 MB, every page touched
    before = resident_mb()
    del block
    return before - resident_mb() < 8  # still resident after the free

default = kept_after_free()
init_worker(int(sys.argv[1]))
import cv2
print(default, kept_after_free(), cv2.getNumThreads(), "torch" in sys.modules)
"""


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc",
    reason="the heap setting is glibc's and /proc is Linux's",
)
def test_worker_setup_shares_cores_and_keeps_freed_memory():
    done = subprocess.run(
        [sys.executable, "-c", "import jeanscv._command\n" + _WORKER_SETUP, "1"],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    default, kept, cv2_threads, torch_loaded = done.stdout.split()
    # OpenCV gets the worker's share of the cores, not all of them; torch is not
    # loaded at all (a torch fit sets its own thread count, jeanscv.fitting.fitter.fit).
    assert (cv2_threads, torch_loaded) == ("1", "False")
    # By default a freed 64-MB array goes back to the system (and its pages are zeroed
    # again when the next photo needs them); a worker keeps it for the next file.
    assert (default, kept) == ("False", "True")


def test_several_inputs_without_j_get_one_worker_per_core_as_memory_allows(monkeypatch):
    from jeanscv_cli import main as cli_main

    monkeypatch.setattr(cli_main.os, "cpu_count", lambda: 8)
    monkeypatch.setattr(cli_main, "_available_memory", lambda: 64 << 30)
    assert cli_main._workers(None, 100) == (8, "one per core, 8 cores")
    assert cli_main._workers(None, 3) == (3, "one per core, 8 cores")
    assert cli_main._workers(None, 1) == (1, "one input")
    assert cli_main._workers(2, 100) == (2, "-j")
    monkeypatch.setattr(cli_main, "_available_memory", lambda: 3 << 30)
    assert cli_main._workers(None, 100) == (3, "8 cores, memory for 3")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers are forked from a fork server on Linux only")
def test_the_fork_server_loads_the_library_and_the_cached_kernels_once(compiled_kernels):
    """What every worker would import and load for its first file is loaded by the fork
    server before it forks them, and frozen out of the garbage collector's traversals."""
    code = (
        "import gc, sys\n"
        "import jeanscv.run._forkserver\n"
        "from jeanscv.fitting._fast import objective, raster\n"
        "loaded = [len(k.overloads) for k in (objective.objective, objective.descend, raster.polygon_coverage_rows)]\n"
        "print(all(loaded), 'jeanscv_cli.worker' in sys.modules, 'jeanscv.pipeline' in sys.modules,"
        " gc.get_freeze_count() > 0)\n"
    )
    assert _python(code) == ["True"] * 4


def _python(code: str) -> list[str]:
    """The words ``code`` prints, run in a fresh interpreter (which must exit cleanly)."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.split()


def test_a_batch_starts_its_workers_fork_server_before_listing_the_files(tmp_path, monkeypatch):
    """Several inputs with more than one worker: the fork server starts first; one input,
    or -j 1, starts none."""
    import jeanscv_cli.main as cli_main
    import jeanscv_cli.pool as pool

    started = []
    monkeypatch.setattr(pool, "start_early", lambda: started.append(True))
    (tmp_path / "in").mkdir()
    for arguments, jobs, expected in (
        ([str(tmp_path / "in")], 2, [True]),
        ([str(tmp_path / "a.png"), str(tmp_path / "b.png")], None, [True] if (os.cpu_count() or 1) > 1 else []),
        ([str(tmp_path / "*.png")], 2, [True]),
        ([str(tmp_path / "a.png")], 2, []),
        ([str(tmp_path / "in")], 1, []),
    ):
        started.clear()
        cli_main._start_workers_early(arguments, jobs)
        assert started == expected, (arguments, jobs)


def test_the_command_collects_young_garbage_less_often_and_restores_the_threshold(monkeypatch, run_cli):
    import gc

    import jeanscv_cli.main as cli_main

    seen = []
    monkeypatch.setattr(cli_main, "_main", lambda ctx, paths, **kw: seen.append(gc.get_threshold()) or 0)
    before = gc.get_threshold()
    assert run_cli("x.png").exit_code == 0
    assert seen == [(10_000, *before[1:])]
    assert gc.get_threshold() == before


def test_a_worker_forked_by_the_fork_server_can_set_its_threads():
    """The fork server starts no OpenCV worker threads: a forked worker lowering its
    thread count to one (as ``init_worker`` does with two workers on two cores) returns at
    once. With OpenCV 5.1 and the Lab tables built on its pool, every worker hung there."""
    code = (
        "import os, time, cv2\n"
        "import jeanscv.run._forkserver\n"
        "pid = os.fork()\n"
        "if pid == 0:\n"
        "    cv2.setNumThreads(1)\n"
        "    cv2.setNumThreads(3)\n"
        "    os._exit(0)\n"
        "for _ in range(6000):  # a minute\n"
        "    if os.waitpid(pid, os.WNOHANG)[0]:\n"
        "        print('returned')\n"
        "        break\n"
        "    time.sleep(0.01)\n"
        "else:\n"
        "    os.kill(pid, 9)\n"
        "    print('hung')\n"
    )
    assert _python(code) == ["returned"]
