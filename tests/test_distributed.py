"""Dask runner: same outputs as one process, per-input failures, the CLI's output names;
and the command's ``--dask``: a local run's lines, resume, summary, exit status and report,
on a cluster, also with a worker killed mid-batch or the command interrupted.

The cluster tests start a real ``LocalCluster`` on the loopback interface with two
worker *processes* (one thread each), so inputs really cross process boundaries; they
are skipped when ``dask[distributed]`` is not installed.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from PIL import Image
from test_cli_batch import assert_interrupted

from jeanscv import __version__
from jeanscv.api import apply_jeans
from jeanscv.errors import JeansError
from jeanscv.io.write import encode_image, output_extension
from jeanscv.run.distributed import output_paths, run_on_dask
from jeanscv_cli.cluster import MADE_MEANWHILE
from testkit.synthetic import silhouette_zoo

SHAPES = ["person", "dog", "bottle"]
ITERATIONS = 10


def test_output_names_follow_the_cli(tmp_path):
    out = tmp_path / "out"
    names = ["a/dog.png", "b/dog.svg", "cat.JPG", "shot.dng", "pic.webp", "scan.tiff", "dog.png", "a/dog.png", "x.bmp"]
    got = [(str(p), pic.name, rep.name) for p, pic, rep in output_paths(names, out)]
    assert got == [
        ("a/dog.png", "dog.jeans.png", "dog.jeans.json"),
        ("b/dog.svg", "dog.svg.jeans.png", "dog.svg.jeans.json"),  # would share dog.jeans.png
        ("cat.JPG", "cat.jeans.jpg", "cat.jeans.json"),
        ("shot.dng", "shot.jeans.jpg", "shot.jeans.json"),  # RAW is developed to JPEG
        ("pic.webp", "pic.jeans.webp", "pic.jeans.json"),
        ("scan.tiff", "scan.jeans.tiff", "scan.jeans.json"),
        ("dog.png", "dog.png.jeans.png", "dog.png.jeans.json"),  # another folder's dog.png
        ("x.bmp", "x.jeans.png", "x.jeans.json"),  # a/dog.png named twice is one input
    ]
    assert all(pic.parent == out for _, pic, _ in output_paths(names, out))
    assert output_extension("drawing.svgz") == ".png"


def test_missing_dask_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # makes `import distributed` fail
    with pytest.raises(JeansError, match=r"^running on Dask needs dask\[distributed\]: install jeanscv\[dask\]$"):
        run_on_dask([], tmp_path)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> list[Path]:
    """Three 256x256 silhouette PNGs (black shape on white) and one file that is not an image."""
    folder = tmp_path_factory.mktemp("inputs")
    paths = []
    for name, alpha in silhouette_zoo(SHAPES).items():
        path = folder / f"{name}.png"
        Image.fromarray(np.round((1.0 - alpha) * 255).astype(np.uint8)).save(path)
        paths.append(path)
    bad = folder / "broken.png"
    bad.write_bytes(b"this is not a PNG")
    return [*paths, bad]


@pytest.fixture(scope="module")
def client():
    distributed = pytest.importorskip("distributed")
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as dask_client,
    ):
        yield dask_client


@pytest.fixture
def address(client) -> str:
    """The test cluster's scheduler, with both workers up (a test may have killed one)."""
    client.wait_for_workers(2, timeout=60)
    assert all(worker.startswith("tcp://127.0.0.1:") for worker in client.nthreads())
    return client.scheduler.address


def test_cluster_outputs_equal_one_process(client, inputs, tmp_path):
    out, report = tmp_path / "out", tmp_path / "report.jsonl"
    records = run_on_dask([*inputs, inputs[0]], out, client=client, report=report, iterations=ITERATIONS)

    assert [r["status"] for r in records] == ["ok", "ok", "ok", "failed"]  # the repeat is one input
    assert records[3]["input"] == str(inputs[3])
    assert records[3]["error"] == "not an image file (or an unsupported image format)"
    assert records[3]["output"] == "" and not (out / "broken.jeans.png").exists()
    assert len({r["worker"] for r in records}) >= 1 and all(r["worker"].startswith("tcp://") for r in records)
    lines = [json.loads(line) for line in report.read_text().splitlines()]
    assert lines == records

    for path, record in zip(inputs[:3], records):
        single = apply_jeans(path, iterations=ITERATIONS)
        picture, sidecar = out / f"{path.stem}.jeans.png", out / f"{path.stem}.jeans.json"
        assert record["output"] == str(picture) and record["report"] == str(sidecar)
        assert picture.read_bytes() == encode_image(single.image, "PNG", quality=95)
        on_cluster = json.loads(sidecar.read_text())
        expected = single.report(str(path), str(picture))
        assert np.array_equal(on_cluster["vertices_canvas"], expected["vertices_canvas"])
        on_cluster.pop("seconds"), expected.pop("seconds")
        assert on_cluster == json.loads(json.dumps(expected))
        assert record["objective"] == float(single.fit.objective)


def test_resumed_run_skips_finished_inputs_and_options_are_checked(client, inputs, tmp_path):
    out = tmp_path / "out"
    first = run_on_dask(inputs[2:3], out, client=client, iterations=ITERATIONS, garment="skirt")
    assert first[0]["status"] == "ok" and first[0]["garment"] == "skirt"
    written = (out / "bottle.jeans.png").stat().st_mtime_ns
    again = run_on_dask(inputs[2:3], out, client=client, overwrite=False, iterations=ITERATIONS)
    assert again[0]["status"] == "skipped" and again[0]["error"] == "its outputs exist already"
    assert (out / "bottle.jeans.png").stat().st_mtime_ns == written
    with pytest.raises(JeansError, match="^bad apply_jeans option: got an unexpected keyword argument 'iteratons'$"):
        run_on_dask(inputs[:1], out, client=client, iteratons=5)
    with pytest.raises(JeansError, match="^unknown garment 'kilt'"):
        run_on_dask(inputs[:1], out, client=client, garment="kilt")


def test_run_on_dask_connects_to_an_address(address, inputs, tmp_path):
    records = run_on_dask(inputs[:1], tmp_path, client=address, iterations=ITERATIONS)
    assert records[0]["status"] == "ok" and records[0]["worker"].startswith("tcp://127.0.0.1:")
    with pytest.raises(
        JeansError, match=r"^cannot reach the Dask scheduler at tcp://127\.0\.0\.1:1: connection refused$"
    ):
        run_on_dask(inputs[:1], tmp_path, client="tcp://127.0.0.1:1")


# -------------------------------------------------------------- jeanscv --dask


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _folder(root: Path, count: int) -> Path:
    """``count`` silhouettes below ``root`` (every third in a subfolder) and a broken file."""
    shapes = silhouette_zoo(SHAPES)
    for i in range(count):
        name = SHAPES[i % len(SHAPES)]
        path = root / ("sub" if i % 3 == 2 else "") / f"{name}{i:02d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        Image.fromarray(np.round((1.0 - shapes[name]) * 255).astype(np.uint8)).save(path)
    (root / "broken.png").write_bytes(b"this is not a PNG")
    return root


def _lines(result) -> list[str]:
    """stderr's lines without their counters, timings and the first line's workers."""
    lines = [re.sub(r"^\[\d+/\d+\] | \(\d+\.\d s\)$| in \d+\.\d s$", "", line) for line in result.stderr.splitlines()]
    return [re.sub(r", \d+ workers? \([^)]*\)|, the Dask cluster at \S+ \([^)]*\)", "", line) for line in lines]


def _records(path: Path) -> list[dict]:
    timed = ("seconds", "fit_seconds")
    return [{k: v for k, v in json.loads(line).items() if k not in timed} for line in path.read_text().splitlines()]


def _no_temporaries(folder: Path) -> None:
    """Only finished outputs: no temporary file (``.NAME.XXXX.tmp``, hidden) anywhere."""
    assert [p for p in folder.rglob(".*")] == []
    for path in folder.rglob("*.jeans.png"):
        with Image.open(path) as im:
            im.load()  # decodes completely


def _wait_idle(client, seconds: float = 30) -> None:
    """Until no task runs on any worker (a cancelled one still runs to its end)."""
    deadline = time.monotonic() + seconds
    while sum(client.run(lambda dask_worker: len(dask_worker.state.all_running_tasks)).values()):
        assert time.monotonic() < deadline, "the workers are still busy"
        time.sleep(0.05)


def test_dask_run_is_a_local_run_resume_summary_status_and_report(address, run_cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _folder(tmp_path / "in", 5)
    common = ("in", "-r", "--json", "--iterations", str(ITERATIONS))
    local = run_cli(*common, "-o", "local", "--report", "local.jsonl", "-j", "1")
    remote = run_cli(*common, "-o", "remote", "--report", "remote.jsonl", "--dask", address)

    assert (local.exit_code, remote.exit_code) == (1, 1), remote.stderr  # broken.png failed
    assert "Traceback" not in remote.stderr
    first = f"jeanscv {__version__}: 6 inputs, the Dask cluster at {address} (2 workers, 2 threads), device cpu"
    assert remote.stderr.startswith(first)
    # The same lines (a cluster finishes in its own order), outputs named alike, the same summary.
    assert sorted(_lines(remote)) == sorted(line.replace("local", "remote") for line in _lines(local))
    assert _lines(remote)[-1] == "5 ok, 1 failed, 0 skipped"
    local_files = sorted(str(p.relative_to("local")) for p in Path("local").rglob("*") if p.is_file())
    assert local_files == sorted(str(p.relative_to("remote")) for p in Path("remote").rglob("*") if p.is_file())
    assert "sub/bottle02.jeans.png" in local_files and len(local_files) == 10
    for name in local_files:
        if name.endswith(".png"):
            assert (Path("remote") / name).read_bytes() == (Path("local") / name).read_bytes(), name
    # The report: the same lines in the same order (input order), paths as this run names them.
    report = _records(Path("remote.jsonl"))
    assert [r["input"] for r in report] == [r["input"] for r in _records(Path("local.jsonl"))]
    assert json.dumps(report).replace("remote", "local") == json.dumps(_records(Path("local.jsonl")))
    _no_temporaries(Path("remote"))

    # Resumed: what exists is skipped, nothing is made again; only the broken file fails again.
    made = {p: p.stat().st_mtime_ns for p in Path("remote").rglob("*.png")}
    again = run_cli(*common, "-o", "remote", "--report", "again.jsonl", "--dask", address)
    assert again.exit_code == 1 and _lines(again)[-1] == "0 ok, 1 failed, 5 skipped"
    assert {p: p.stat().st_mtime_ns for p in Path("remote").rglob("*.png")} == made
    assert [r["status"] for r in _records(Path("again.jsonl"))] == ["failed"] + ["skipped"] * 5
    # All done: exit status 0.
    good = sorted(str(p) for p in Path("in").rglob("*.png") if p.name != "broken.png")
    done = run_cli(*good, "-o", "remote2", "--iterations", str(ITERATIONS), "--dask", address, "-q")
    assert (done.exit_code, done.stderr) == (0, "")
    assert len(list(Path("remote2").glob("*.jeans.png"))) == 5


def test_dask_run_survives_a_worker_killed_mid_batch(client, address, run_cli, tmp_path):
    """One worker process killed (SIGKILL) while it runs a task: every input ends done or
    failed with its reason, each output complete, no temporary file left."""
    folder = _folder(tmp_path / "in", 10)
    out = tmp_path / "out"
    pids = client.run(os.getpid)
    victim, pid = sorted(pids.items())[0]
    killed = []

    def kill_while_busy() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not killed:
            if client.processing().get(victim) and any(out.rglob("*.jeans.png")):
                os.kill(pid, signal.SIGKILL)
                killed.append(victim)
            time.sleep(0.01)

    thread = threading.Thread(target=kill_while_busy, daemon=True)
    thread.start()
    result = run_cli(
        folder, "-r", "-o", out, "--report", tmp_path / "run.jsonl", "--iterations", "800", "--dask", address
    )
    thread.join()
    assert killed, "the batch ended before a worker could be killed"
    assert result.exit_code in (0, 1) and "Traceback" not in result.stderr, (result.exit_code, result.stderr)
    records = _records(tmp_path / "run.jsonl")
    assert len(records) == 11 and {r["status"] for r in records} <= {"ok", "failed", "skipped"}
    for record in records:
        if record["status"] == "skipped":  # the killed worker had written it: done, by its first try
            assert record["reason"] == MADE_MEANWHILE and Path(record["output"]).is_file(), record
        elif record["status"] == "failed":
            assert record["error"] and record["output"] == "", record
            assert record["input"].endswith("broken.png") or record["error"].startswith(
                "the task failed on the cluster: "
            )
        else:
            assert Path(record["output"]).is_file() and record["written"] == [record["output"]]
    assert [r["input"] for r in records if r["status"] == "failed"][:1] == [str(folder / "broken.png")]
    _no_temporaries(out)
    counts = {status: sum(r["status"] == status for r in records) for status in ("ok", "failed", "skipped")}
    assert _lines(result)[-1] == "{ok} ok, {failed} failed, {skipped} skipped".format(**counts)


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_dask_run_interrupted_keeps_finished_outputs_and_resumes(client, address, run_cli, tmp_path, sig, code):
    folder = _folder(tmp_path / "in", 30)
    process = subprocess.Popen(
        [sys.executable, "-m", "jeanscv", str(folder), "-r", "--iterations", "300", "--dask", address],
        stderr=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        text=True,
        env=_env(),
    )
    lines = []
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        lines.append(line.rstrip("\n"))
        if sum(line.startswith("[") for line in lines) == 2 or not line:
            break
    process.send_signal(sig)
    assert_interrupted(process, lines, code, timeout=60)
    _wait_idle(client)  # tasks running when it stopped end on their workers; queued ones were cancelled
    made = sorted(folder.rglob("*.jeans.png"))
    assert 2 <= len(made) < 30
    _no_temporaries(folder)
    resumed = run_cli(folder, "-r", "--iterations", "300", "--dask", address, "--report", tmp_path / "run.jsonl")
    assert resumed.exit_code == 1  # broken.png
    statuses = [r["status"] for r in _records(tmp_path / "run.jsonl")]
    assert statuses.count("skipped") >= len(made) and statuses.count("ok") == 30 - statuses.count("skipped")


def test_dask_unreachable_or_missing_is_one_line_and_status_2(run_cli, tmp_path, monkeypatch):
    import jeanscv.run.distributed as dist

    folder = _folder(tmp_path / "in", 2)
    expected = {
        "tcp://127.0.0.1:1": "jeanscv: cannot reach the Dask scheduler at tcp://127.0.0.1:1: connection refused",
        "nowhere": "jeanscv: not a Dask scheduler address: 'nowhere' (missing port number in address 'nowhere')",
    }
    for where, line in expected.items():
        result = run_cli(folder, "--dask", where, "--report", tmp_path / "run.jsonl")
        assert (result.exit_code, result.stderr.splitlines()) == (2, [line])

    # No answer at all (a host that drops the connection): given up after the timeout.
    def silent(address, timeout):
        raise TimeoutError("timed out")

    monkeypatch.setattr(dist.socket, "create_connection", silent)
    result = run_cli(folder, "--dask", "tcp://192.0.2.1:8786")
    assert result.exit_code == 2
    assert result.stderr == "jeanscv: cannot reach the Dask scheduler at tcp://192.0.2.1:8786: no answer within 10 s\n"
    monkeypatch.undo()
    # dask[distributed] not installed.
    monkeypatch.setitem(sys.modules, "distributed", None)  # makes `import distributed` fail
    result = run_cli(folder, "--dask", "tcp://127.0.0.1:8786")
    assert result.exit_code == 2
    assert result.stderr == "jeanscv: running on Dask needs dask[distributed]: install jeanscv[dask]\n"
    # -j is for local workers.
    result = run_cli(folder, "--dask", "tcp://127.0.0.1:8786", "-j", "2")
    assert result.exit_code == 2 and "with --dask the cluster's workers do the work" in result.stderr
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["broken.png", "dog01.png", "person00.png"]
