"""Dask runner: same outputs as one process, per-input failures, the CLI's output names.

The cluster test starts a real ``LocalCluster`` with two worker *processes* (one
thread each), so inputs really cross process boundaries; it is skipped when
``dask[distributed]`` is not installed.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from jeanscv.api import apply_jeans
from jeanscv.errors import JeansError
from jeanscv.io.write import encode_image, output_extension
from jeanscv.run.distributed import output_paths, run_on_dask
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
        distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        distributed.Client(cluster) as dask_client,
    ):
        yield dask_client


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
