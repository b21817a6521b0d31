"""Runs killed with SIGKILL (the parent, or one ``-j`` worker; a file that kills its worker
every time) and two runs at once on one folder, as real processes. Whenever the kill lands, the invariants hold: every output is
complete, no temporary file is left once the processes are gone, no process outlives its
run, and running again completes what is missing. (The speed of two runs at once is
measured by ``bench/two_runs.py``, not here.)
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import write_silhouette_png
from test_faults import assert_valid_outputs, temporaries

pytestmark = [
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; POSIX signals"),
    pytest.mark.usefixtures("compiled_kernels"),  # the kills land mid-batch, not mid-compile
]

# The fast backend (its kernels cached before the test, ``compiled_kernels``, and loaded
# once by the workers' fork server; torch's workers import torch each, 3.5 s of CPU apiece),
# with enough iterations (~0.5 s a file) that a kill usually lands mid-batch (the
# assertions hold wherever it lands).
SLOW = ("--iterations", "1000", "--starts", "1", "--backend", "fast", "-q")
COUNT = 5


def make_folder(tmp_path: Path) -> tuple[Path, Path, list[str]]:
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(COUNT):
        write_silhouette_png(folder / f"s{i}.png")
    return folder, tmp_path / "out", [f"s{i}.jeans.png" for i in range(COUNT)]


def jeanscv(*args) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "jeanscv", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        text=True,
    )


def wait_until(condition, timeout: float = 300.0) -> bool:
    """Poll ``condition`` until it holds; False after ``timeout`` (a generous bound, not a timing)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(0.05)
    return False


def children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def workers(pid: int) -> list[int]:
    """The ``-j`` workers of the run ``pid``: its spawned children, or its fork server's."""
    found = []
    for child in children(pid):
        try:
            command = (Path("/proc") / str(child) / "cmdline").read_text()
        except OSError:
            continue
        if "spawn_main" in command:
            found.append(child)
        elif "forkserver" in command:
            found += children(child)
    return found


def alive(pid: int) -> bool:
    """Running (a zombie waiting for a reaper counts as gone)."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def any_output(out: Path) -> bool:
    return out.is_dir() and any(".jeans." in p.name and not p.name.endswith(".tmp") for p in out.iterdir())


def finished_outputs(out: Path) -> list[str]:
    return sorted(p.name for p in out.iterdir() if ".jeans." in p.name and not p.name.startswith("."))


def resume(run_cli, folder: Path, out: Path, names: list[str], before: dict[str, bytes]) -> None:
    """Run again: exit 0, every output there and complete, the earlier ones untouched.
    (In this process: what a run finds on disk does not depend on which process runs it,
    and a fresh interpreter's imports were most of a subprocess's time.)"""
    done = run_cli(folder, "-o", out, *SLOW, "-j", "1")
    assert done.exit_code == 0, done.stderr
    again = assert_valid_outputs(out, names)
    assert {name: again[name] for name in before} == before


def test_sigkill_to_the_parent(tmp_path, run_cli):
    folder, out, names = make_folder(tmp_path)
    run = jeanscv(folder, "-o", out, "-j", "2", *SLOW)
    assert wait_until(lambda: any_output(out) or run.poll() is not None)
    processes = children(run.pid) + workers(run.pid)
    run.kill()
    run.wait()
    # The workers notice within a second or so, and stop; a file in progress leaves nothing.
    assert wait_until(lambda: not any(alive(pid) for pid in processes), timeout=120), "orphaned workers"
    before = assert_valid_outputs(out, finished_outputs(out))
    resume(run_cli, folder, out, names, before)


def test_sigkill_to_a_worker(tmp_path):
    """A worker killed mid-batch (the OOM killer, say) breaks the pool; the files it left
    unfinished run again in a fresh pool, so nothing fails and nothing is left behind."""
    folder, out, names = make_folder(tmp_path)
    run = jeanscv(folder, "-o", out, "-j", "2", *SLOW)
    assert wait_until(lambda: any_output(out) or run.poll() is not None)
    running = workers(run.pid)
    assert running
    os.kill(running[0], signal.SIGKILL)
    _, stderr = run.communicate(timeout=600)
    assert run.returncode == 0, stderr
    assert stderr == ""
    assert wait_until(lambda: not any(alive(pid) for pid in running), timeout=120)
    assert_valid_outputs(out, names)


def test_a_file_that_kills_its_worker_fails_alone(tmp_path):
    """A file whose decoding kills the worker every time (a crash in a C library, made
    here by a sitecustomize that SIGKILLs the worker loading crash.png): it fails with one
    line, and the files queued beside it are done."""
    folder, out, names = make_folder(tmp_path)
    write_silhouette_png(folder / "crash.png")
    hooks = tmp_path / "hooks"
    hooks.mkdir()
    (hooks / "sitecustomize.py").write_text(
        "import os, signal\n"
        "from pathlib import Path\n"
        "import jeanscv.io.image as image\n"
        "real = image.load_image\n"
        "def load_image(path, *args, **kwargs):\n"
        "    if Path(path).name == 'crash.png':\n"
        "        os.kill(os.getpid(), signal.SIGKILL)\n"
        "    return real(path, *args, **kwargs)\n"
        "image.load_image = load_image\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(hooks), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, "-m", "jeanscv", folder, "-o", out, "-j", "2", *SLOW],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )
    assert done.returncode == 1
    assert done.stderr.splitlines() == [f"jeanscv: {folder / 'crash.png'}: worker process died (BrokenProcessPool)"]
    assert_valid_outputs(out, names)


def test_two_runs_at_once_share_the_work(tmp_path):
    """Same folder, same output folder: each input is made by exactly one of the two."""
    folder, out, names = make_folder(tmp_path)
    first = jeanscv(folder, "-o", out, "-j", "1", *SLOW[:-1])
    second = jeanscv(folder, "-o", out, "-j", "1", *SLOW[:-1])
    results = [run.communicate(timeout=600) for run in (first, second)]
    assert (first.returncode, second.returncode) == (0, 0), results
    assert_valid_outputs(out, names)
    made = 0
    for _, stderr in results:
        assert "Traceback" not in stderr
        summary = re.search(r"^(\d+) ok, 0 failed, (\d+) skipped in ", stderr, re.MULTILINE)
        assert summary, stderr
        made += int(summary.group(1))
    assert made == COUNT  # no input made twice
    assert temporaries(tmp_path) == []


@pytest.mark.parametrize("jobs, other_makes_it", [("1", True), ("2", False)])
def test_a_file_another_run_holds_is_put_off_not_waited_for(tmp_path, jobs, other_makes_it):
    """The first file is held by another run (its claim taken here by the test): the run
    makes the other files meanwhile instead of waiting in line, then comes back to it and
    waits. What the other run made is skipped; what it did not make, this run makes."""
    fcntl = pytest.importorskip("fcntl")
    folder, out, names = make_folder(tmp_path)
    held = os.open(folder / "s0.png", os.O_RDONLY)
    try:
        fcntl.flock(held, fcntl.LOCK_EX)
        run = jeanscv(folder, "-o", out, "-j", jobs, *SLOW[:-1])
        assert wait_until(lambda: set(names[1:]) <= set(finished_outputs(out)) if out.is_dir() else False)
        assert run.poll() is None  # back at s0, waiting for the other run
        assert finished_outputs(out) == names[1:]
        if other_makes_it:
            (out / names[0]).write_bytes((out / names[1]).read_bytes())
    finally:
        os.close(held)
    _, stderr = run.communicate(timeout=600)
    assert run.returncode == 0, stderr
    assert_valid_outputs(out, names)
    if other_makes_it:
        assert f"[5/5] {folder / 's0.png'}: skipped (made by another jeanscv run meanwhile)" in stderr.splitlines()
        assert re.search(r"^4 ok, 0 failed, 1 skipped in ", stderr, re.MULTILINE), stderr
    else:
        assert re.search(r"^5 ok, 0 failed, 0 skipped in ", stderr, re.MULTILINE), stderr
    assert temporaries(tmp_path) == []


def test_work_queue_puts_busy_files_off_to_the_end():
    """The order a run takes its files in: as found, then those another run held (now
    waiting for it); files a dead worker left come first again; nothing is counted twice."""
    from types import SimpleNamespace

    from jeanscv_cli.runs import WorkQueue

    class Progress:
        def __init__(self):
            self.finished = []

        def finish(self, outcome):
            self.finished.append(outcome.input)

    def job(name: str, index: int):
        return SimpleNamespace(index=index, display=name)

    made = []
    jobs = (job(name, i) for i, name in enumerate("abcd"))  # a generator: taken as needed
    outcomes: dict = {}
    queue = WorkQueue(jobs, Progress(), outcomes)
    assert queue.look_ahead(2) == 2
    order = []
    while (item := queue.next()) is not None:
        current, wait = item
        order.append((current.display, wait))
        status = "busy" if current.display in "bc" and not wait else "ok"
        if current.display == "d" and not made:  # its worker died: handed back once
            made.append("d")
            queue.again([(current, wait)])
            continue
        queue.finish(current, SimpleNamespace(status=status, input=current.display))
    assert order == [("a", False), ("b", False), ("c", False), ("d", False), ("d", False), ("b", True), ("c", True)]
    assert queue.progress.finished == ["a", "d", "b", "c"]
    assert sorted(outcomes) == [0, 1, 2, 3]


def test_a_run_removes_temporaries_killed_runs_left_in_its_output_folder(tmp_path, run_cli):
    """Temporary files of any jeanscv output in a folder the run writes to are removed,
    also those of outputs that are already finished (a killed --overwrite run left them);
    another program's temporary file is left alone. (Both runs in this process: nothing
    is killed here, and what a run finds on disk does not depend on which process runs it.)"""
    folder, out, names = make_folder(tmp_path)
    done = run_cli(folder, "-o", out, *SLOW, "-j", "1")
    assert done.exit_code == 0, done.stderr
    before = assert_valid_outputs(out, names)
    (out / names[1]).unlink()
    for name in (names[0], names[1], "notes.txt"):
        (out / f".{name}.0badf00d.tmp").write_bytes(b"half of it")
    again = run_cli(folder, "-o", out, *SLOW, "-j", "1")
    assert again.exit_code == 0, again.stderr
    assert temporaries(out) == [".notes.txt.0badf00d.tmp"]
    (out / ".notes.txt.0badf00d.tmp").unlink()
    after = assert_valid_outputs(out, names)
    assert {name: after[name] for name in names if name != names[1]} == {
        name: before[name] for name in names if name != names[1]
    }
