"""The ``jeanscv`` command on single inputs: outputs, sidecars, extras, options, exit codes."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, blue_pixels, write_silhouette_png, write_silhouette_svg
from PIL import Image

FAST = ("--iterations", "4", "--starts", "1")
pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)
REPORT_KEYS = {
    "input",
    "output",
    "preset",
    "iterations",
    "seed",
    "canvas_size",
    "vertices_canvas",
    "vertices_image",
    "canvas_to_image",
    "paper_terms",
    "paper_total",
    "objective",
    "weights",
    "seconds",
}
PAPER_TERMS = {"center", "coverage", "rigid", "open", "closed", "inter", "inside"}


def _env() -> dict:
    """Environment for ``python -m jeanscv`` in a source checkout (harmless when installed)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def _load_report(path: Path) -> dict:
    return json.loads(path.read_text())


def _check_report(report: dict, input_name: str, output_name: str, iterations: int = 4) -> None:
    assert REPORT_KEYS <= set(report)
    assert report["input"] == input_name and report["output"] == output_name
    assert report["preset"] == "default" and report["iterations"] == iterations and report["seed"] == 0
    assert report["canvas_size"] == 256
    canvas = np.array(report["vertices_canvas"])
    image = np.array(report["vertices_image"])
    affine = np.array(report["canvas_to_image"])
    assert canvas.shape == (8, 2) and image.shape == (8, 2) and affine.shape == (2, 3)
    assert set(report["paper_terms"]) == PAPER_TERMS
    assert set(report["weights"]) == PAPER_TERMS | {"upright"}
    # Both vertex lists are rounded to 6 significant digits.
    np.testing.assert_allclose(canvas @ affine[:, :2].T + affine[:, 2], image, rtol=2e-5, atol=1e-3)
    assert np.isfinite(report["paper_total"]) and np.isfinite(report["objective"])


def test_svg_silhouette_end_to_end(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_silhouette_svg(tmp_path / "shape.svg")
    result = run_cli("shape.svg", *FAST, "--json", "-q")
    assert result.exit_code == 0, result.stderr
    assert result.stderr == ""
    with Image.open(tmp_path / "shape.jeans.png") as im:
        assert im.format == "PNG" and im.size == (256, 256)
        pixels = np.asarray(im.convert("RGB"))
    assert blue_pixels(pixels) > 500
    assert np.sum(pixels.sum(axis=-1) == 0) > 500  # the black silhouette shows around the jeans
    report = _load_report(tmp_path / "shape.jeans.json")
    _check_report(report, "shape.svg", "shape.jeans.png")
    assert report["kind"] == "silhouette"
    # A 256x256 viewBox maps 1:1 onto the canvas.
    np.testing.assert_allclose(report["canvas_to_image"], [[1, 0, 0], [0, 1, 0]])


def test_png_silhouette_end_to_end_and_deterministic(tmp_path, run_cli, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write_silhouette_png(tmp_path / "person.png")
    first = run_cli("person.png", *FAST, "--json", "-q")
    assert first.exit_code == 0, first.stderr
    image_bytes = (tmp_path / "person.jeans.png").read_bytes()
    text = (tmp_path / "person.jeans.json").read_text()
    with Image.open(tmp_path / "person.jeans.png") as im:
        assert im.size == (256, 256)
        assert blue_pixels(np.asarray(im.convert("RGB"))) > 500
    report = json.loads(text)
    _check_report(report, "person.png", "person.jeans.png")
    assert report["silhouette_method"] == "drawing"
    # Sorted keys, indent 2, newline at the end.
    assert text == json.dumps(report, sort_keys=True, indent=2) + "\n"

    again = run_cli("person.png", *FAST, "--json", "-q", "--overwrite")
    assert again.exit_code == 0, again.stderr
    second = _load_report(tmp_path / "person.jeans.json")
    assert second.pop("seconds") >= 0 and report.pop("seconds") >= 0
    assert second == report
    assert (tmp_path / "person.jeans.json").read_text().count("\n") == text.count("\n")
    assert (tmp_path / "person.jeans.png").read_bytes() == image_bytes


def test_photo_keeps_jpeg_format_and_size(tmp_path, run_cli):
    source = ROOT / "sample_images" / "cat.jpg"
    result = run_cli(source, *FAST, "-o", tmp_path, "--json", "-q")
    assert result.exit_code == 0, result.stderr
    out = tmp_path / "cat.jeans.jpg"
    with Image.open(out) as im, Image.open(source) as original:
        assert im.format == "JPEG" and im.size == original.size == (451, 300)
        changed = np.abs(np.asarray(im, int) - np.asarray(original, int)).sum(axis=-1) > 60
    report = _load_report(tmp_path / "cat.jeans.json")
    assert report["kind"] == "photo" and report["image_size"] == [451, 300]
    # The jeans were painted inside the fitted polygon's bounding box, nowhere far outside.
    xs, ys = np.array(report["vertices_image"]).T
    rows, cols = np.nonzero(changed)
    assert len(rows) > 200
    assert cols.min() >= xs.min() - 3 and cols.max() <= xs.max() + 3
    assert rows.min() >= ys.min() - 3 and rows.max() <= ys.max() + 3


def test_format_option_and_input_never_overwritten(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "person.png")
    before = src.read_bytes()
    result = run_cli(src, *FAST, "--format", "webp", "-q")
    assert result.exit_code == 0, result.stderr
    with Image.open(tmp_path / "person.jeans.webp") as im:
        assert im.format == "WEBP" and im.size == (256, 256)
    assert src.read_bytes() == before
    # An output named as an input is skipped, never read as an input nor overwritten.
    result = run_cli(tmp_path / "person.jeans.webp", *FAST)
    assert result.exit_code == 0
    assert "a jeanscv output" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["person.jeans.webp", "person.png"]


def test_svg_sidecar_matches_the_fit(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "person.png")
    result = run_cli(src, *FAST, "--json", "--svg", "-q")
    assert result.exit_code == 0, result.stderr
    root = ET.parse(tmp_path / "person.jeans.svg").getroot()
    ns = {"svg": "http://www.w3.org/2000/svg"}
    assert root.tag == "{http://www.w3.org/2000/svg}svg"
    assert (root.get("width"), root.get("height"), root.get("viewBox")) == ("256", "256", "0 0 256 256")
    polygon = root.find("svg:polygon", ns)
    points = np.array([[float(v) for v in p.split(",")] for p in polygon.get("points").split()])
    report = _load_report(tmp_path / "person.jeans.json")
    np.testing.assert_allclose(points, report["vertices_image"], rtol=1e-5)
    # The silhouette outline lies on the mask's edge: its bounding box is the drawing's.
    path = root.find("svg:path", ns).get("d")
    xy = np.array(
        [[float(v) for v in p.split(",")] for p in path.replace("M", " ").replace("L", " ").replace("Z", " ").split()]
    )
    with Image.open(src) as im:
        inside = np.asarray(im.convert("L")) >= 128
    rows, cols = np.nonzero(inside)
    assert abs(xy[:, 0].min() - cols.min()) <= 1 and abs(xy[:, 0].max() - (cols.max() + 1)) <= 1
    assert abs(xy[:, 1].min() - rows.min()) <= 1 and abs(xy[:, 1].max() - (rows.max() + 1)) <= 1


def test_gif_has_the_requested_frames(tmp_path, run_cli):
    from jeanscv.fitting.fitter import FitResult

    if "trajectory" not in FitResult.__dataclass_fields__:
        pytest.xfail("FitResult.trajectory is not in the library yet")
    src = write_silhouette_png(tmp_path / "person.png")
    result = run_cli(src, "--iterations", "8", "--starts", "1", "--gif", "--gif-frames", "5", "-q")
    assert result.exit_code == 0, result.stderr
    with Image.open(tmp_path / "person.jeans.gif") as im:
        assert im.format == "GIF" and im.n_frames == 5
        assert max(im.size) <= 320
        im.seek(4)
        last = np.asarray(im.convert("RGB"))
    assert blue_pixels(last) > 300
    # The progress bar along the bottom is full on the last frame.
    assert blue_pixels(last[-2:]) == 2 * last.shape[1]


def test_meme_captions_change_only_their_band(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "person.png")
    assert run_cli(src, *FAST, "-q", "-o", tmp_path / "plain").exit_code == 0
    result = run_cli(src, *FAST, "-q", "-o", tmp_path / "meme", "--top", "how would a person wear jeans")
    assert result.exit_code == 0, result.stderr
    plain = np.asarray(Image.open(tmp_path / "plain" / "person.jeans.png").convert("RGB"), int)
    meme = np.asarray(Image.open(tmp_path / "meme" / "person.jeans.png").convert("RGB"), int)
    changed = np.abs(meme - plain).sum(axis=-1) > 0
    rows = np.nonzero(changed.any(axis=1))[0]
    assert changed.sum() > 300
    assert rows.max() < 256 // 3  # the top caption stays in the top band
    # White letters with a black outline.
    assert np.sum((meme[changed] == 255).all(axis=-1)) > 100
    assert np.sum((meme[changed] == 0).all(axis=-1)) > 100


def test_side_by_side_doubles_the_width(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "person.png")
    assert run_cli(src, *FAST, "-q", "-o", tmp_path / "plain").exit_code == 0
    assert run_cli(src, *FAST, "-q", "-o", tmp_path / "both", "--side-by-side").exit_code == 0
    plain = np.asarray(Image.open(tmp_path / "plain" / "person.jeans.png").convert("RGB"))
    both = np.asarray(Image.open(tmp_path / "both" / "person.jeans.png").convert("RGB"))
    assert both.shape == (256, 512, 3)
    np.testing.assert_array_equal(both[:, 256:], plain)
    assert blue_pixels(both[:, :256]) == 0  # the original, without jeans
    original = np.asarray(Image.open(src).convert("L")).astype(int)
    assert np.abs(both[:, :256, 0].astype(int) - (255 - original)).max() <= 1


def test_mask_option_and_report(tmp_path, run_cli):
    rng = np.random.default_rng(0)
    photo = rng.integers(60, 200, size=(96, 128, 3), dtype=np.uint8)
    mask = np.zeros((96, 128), np.uint8)
    mask[20:80, 40:90] = 255
    Image.fromarray(photo).save(tmp_path / "noise.png")
    Image.fromarray(mask).save(tmp_path / "mask.png")
    result = run_cli(
        tmp_path / "noise.png",
        "--mask",
        tmp_path / "mask.png",
        *FAST,
        "--json",
        "--report",
        tmp_path / "run.jsonl",
        "--style",
        "flat",
        "-q",
    )
    assert result.exit_code == 0, result.stderr
    report = _load_report(tmp_path / "noise.jeans.json")
    assert report["kind"] == "photo" and report["silhouette_method"] == "mask"
    # Framing: a square of side ceil(60 / 0.9) = 67 centred on the 50x60 box at (40, 20).
    np.testing.assert_allclose(report["canvas_to_image"], [[67 / 256, 0, 31], [0, 67 / 256, 16]], atol=1e-5)
    lines = (tmp_path / "run.jsonl").read_text().splitlines()
    assert len(lines) == 1
    record = json.loads(lines[0])
    assert record["status"] == "ok" and record["error"] == ""
    assert record["input"] == str(tmp_path / "noise.png")
    assert record["output"] == str(tmp_path / "noise.jeans.png")
    assert set(record["paper_terms"]) == PAPER_TERMS
    assert record["paper_total"] == pytest.approx(report["paper_total"], rel=1e-5)


def test_usage_errors_exit_2(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "a.png")
    other = write_silhouette_png(tmp_path / "b.png")
    for args in (
        [],
        ["--preset", "nope", src],
        ["--garment", "ballgown.toml", src],
        ["--rect", "1,2,3", src],
        ["--iterations", "-1", src],
        ["--format", "bmp", src],
        ["--mask", src, src, other],
    ):
        result = run_cli(*args)
        assert result.exit_code == 2, (args, result.stderr)
        assert "Traceback" not in result.stderr and "Error:" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png"]


def test_rect_is_the_old_name_of_box(tmp_path, run_cli, monkeypatch):
    """``--rect X,Y,W,H`` is ``--box X,Y,X+W,Y+H`` with one line saying so; hidden from
    --help; like --box it needs exactly one input. The library's GrabCut ``rect`` stays."""
    import jeanscv_cli.main as cli_main
    from jeanscv.options import JeansOptions

    src = write_silhouette_png(tmp_path / "a.png")
    other = write_silhouette_png(tmp_path / "b.png")
    seen = []
    monkeypatch.setattr(cli_main, "_run_jobs", lambda pending, options, *rest: seen.append(options) or 0)
    result = run_cli(src, "--rect", "10,20,100,200")
    assert result.exit_code == 0, result.stderr
    assert (
        result.stderr.splitlines()[0] == "jeanscv: --rect X,Y,W,H is now --box X0,Y0,X1,Y1 (here --box 10,20,110,220)"
    )
    assert result.stderr.count("--rect") == 1
    assert seen[0].box == (10.0, 20.0, 110.0, 220.0) and seen[0].rect is None
    for args, message in (
        ((src, other, "--rect", "10,20,100,200"), "--box needs exactly one input image"),
        ((src, "--rect", "10,20,100,200", "--box", "1,2,30,40"), "--rect is the old name of --box"),
        ((src, "--rect", "10,20,1,200"), "at least 2 pixels apart"),
    ):
        result = run_cli(*args)
        assert result.exit_code == 2 and message in result.stderr, (args, result.stderr)
    assert "--rect" not in run_cli("--help").stdout
    assert JeansOptions(rect=(1, 2, 30, 40)).rect == (1, 2, 30, 40)  # API users keep GrabCut's box


def test_help_lists_every_option_in_one_section(run_cli):
    import click

    from jeanscv_cli.main import cli
    from jeanscv_cli.sections import SECTIONS, option_name

    ctx = click.Context(cli)
    shown = [option_name(p) for p in cli.get_params(ctx) if isinstance(p, click.Option) and not p.hidden]
    listed = [name for names in SECTIONS.values() for name in names]
    assert sorted(listed) == sorted(set(listed)), "an option is in two sections"
    assert sorted(listed) == sorted(shown)
    text = run_cli("--help").stdout
    titles = [line[:-1] for line in text.splitlines() if line.endswith(":") and not line.startswith(" ")]
    assert titles == list(SECTIONS)  # no "Options:" section of left-overs
    assert text.index("Inputs and outputs:") < text.index("  -o, --output-dir") < text.index("What to dress:")
    assert text.index("Limits and speed:") < text.index("  --dask ADDRESS") < text.index("Information:")
    # One column for the help texts of every section.
    rows = [re.match(r"  -\S.*?\s{2,}(\S)", line) for line in text.split("Examples:")[0].splitlines()]
    assert len([row for row in rows if row]) > 30 and len({row.start(1) for row in rows if row}) == 1


def test_device_cuda_without_gpu_is_a_usage_error(tmp_path, run_cli):
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    src = write_silhouette_png(tmp_path / "a.png")
    result = run_cli(src, "--device", "cuda")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == ["jeanscv: --device cuda was requested but CUDA is not available"]
    assert not (tmp_path / "a.jeans.png").exists()


def test_device_auto_fits_on_the_cpu_without_torch(tmp_path) -> None:
    """``auto`` is the CPU's fast path, also where CUDA exists (it is faster there), and
    choosing it imports no torch."""
    code = (
        "import sys; from jeanscv.device import resolve_device; print(resolve_device('auto'), 'torch' in sys.modules)"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.split() == ["cpu", "False"]


def test_unknown_device_is_a_usage_error(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "a.png")
    result = run_cli(src, "--device", "tpu")
    assert result.exit_code == 2 and "Traceback" not in result.stderr
    assert not (tmp_path / "a.jeans.png").exists()


def test_list_presets_and_garments(run_cli):
    presets = run_cli("--list-presets")
    assert presets.exit_code == 0
    assert [line.split(":")[0] for line in presets.stdout.splitlines()] == ["default (default)", "paper"]
    garments = run_cli("--list-garments")
    assert garments.exit_code == 0 and garments.stdout.startswith("jeans: ")


def test_clear_cache_removes_every_versions_kernels_and_nothing_else(tmp_path):
    """``--clear-cache`` empties jeanscv's kernel folder (every version's) in the per-user
    cache, imports neither numba nor torch, and says what it removed."""
    kernels = tmp_path / "cache" / "kernels"
    for key in ("0.0.9-0123456789abcdef", "0.1.0-fedcba9876543210"):
        (kernels / key).mkdir(parents=True)
        (kernels / key / "objective.descend-593.py311.nbi").write_bytes(b"x" * 1000)
    (tmp_path / "cache" / "other").write_text("kept")
    env = {**_env(), "JEANSCV_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "jeanscv", "--clear-cache"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout == f"removed the compiled fit kernels: 2 files, 0.0 MB, from {kernels}\n"
    assert not kernels.exists() and (tmp_path / "cache" / "other").read_text() == "kept"
    imported = {line.split("|")[-1].strip().split(".")[0] for line in done.stderr.splitlines()}
    assert not imported & {"torch", "numba", "cv2"}
    again = subprocess.run([sys.executable, "-m", "jeanscv", "--clear-cache"], capture_output=True, text=True, env=env)
    assert again.returncode == 0 and again.stdout == f"no compiled fit kernels to remove ({kernels})\n"


def test_version_and_help_do_not_import_heavy_modules():
    for flag in ("--version", "--help"):
        done = subprocess.run(
            [sys.executable, "-X", "importtime", "-m", "jeanscv", flag],
            capture_output=True,
            text=True,
            env=_env(),
            timeout=60,
        )
        assert done.returncode == 0, done.stderr[-2000:]
        imported = {line.split("|")[-1].strip().split(".")[0] for line in done.stderr.splitlines()}
        assert not imported & {"torch", "kornia", "cv2", "rawpy", "skimage", "numpy"}
    assert done.stdout.startswith("Usage: ") and "Examples:" in done.stdout
    version = subprocess.run(
        [sys.executable, "-m", "jeanscv", "--version"], capture_output=True, text=True, env=_env(), timeout=60
    )
    from jeanscv import __version__

    assert version.stdout == f"jeanscv {__version__}\n"


def test_a_photo_with_a_click_imports_only_what_it_needs(tmp_path, compiled_kernels):
    """A photo with a click and no detector (decode, segmentation, the click session, the
    fast fit, the denim) imports neither torch nor scipy's sparse routines (0.35 s of a
    fresh process). With the detector (the default) torch comes for it alone: a first
    click on a detected animal starts from its box."""
    photo = ROOT / "sample_images" / "cat.jpg"  # (195, 160) is on the cat; (300, 200) was background
    command = ["-m", "jeanscv", str(photo), "--point", "195,160", "--detector", "none", "-o", str(tmp_path)]
    done = subprocess.run(
        [sys.executable, "-X", "importtime", *command],
        capture_output=True,
        text=True,
        env=_env(),
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "cat.jeans.jpg").is_file()
    imported = {line.split("|")[-1].strip() for line in done.stderr.splitlines() if line.startswith("import time:")}
    heavy = {name for name in imported if name.split(".")[0] in {"torch", "kornia", "rawpy"}}
    heavy |= {name for name in imported if name.startswith(("scipy.sparse", "scipy.linalg"))}
    assert not heavy


def test_raw_gives_jpeg_and_rgba_png_keeps_alpha(tmp_path, run_cli):
    samples = ROOT / "sample_images"
    result = run_cli(samples / "coffee.dng", *FAST, "-o", tmp_path, "-v", "--style", "flat")
    assert result.exit_code == 0, result.stderr
    with Image.open(tmp_path / "coffee.jeans.jpg") as im:
        assert im.format == "JPEG" and im.size == (600, 400)  # the camera's full size by default
    assert "photo (silhouette: " in result.stderr and "device cpu" in result.stderr
    assert "terms: center=" in result.stderr
    result = run_cli(samples / "coffee.dng", *FAST, "-o", tmp_path / "half", "-q", "--raw-half-size")
    assert result.exit_code == 0, result.stderr
    with Image.open(tmp_path / "half" / "coffee.jeans.jpg") as im:
        assert im.size == (300, 200)
    # --raw-full-size, the old opt-in, is still accepted (full size is the default now).
    result = run_cli(samples / "coffee.dng", *FAST, "-o", tmp_path / "full", "-q", "--raw-full-size")
    assert result.exit_code == 0, result.stderr
    with Image.open(tmp_path / "full" / "coffee.jeans.jpg") as im:
        assert im.size == (600, 400)

    result = run_cli(samples / "horse_cutout.png", *FAST, "-o", tmp_path, "--kind", "photo", "--json", "-q")
    assert result.exit_code == 0, result.stderr
    out = np.asarray(Image.open(tmp_path / "horse_cutout.jeans.png"))
    original = np.asarray(Image.open(samples / "horse_cutout.png"))
    assert out.shape == original.shape == (328, 400, 4)
    report = _load_report(tmp_path / "horse_cutout.jeans.json")
    assert report["silhouette_method"] == "alpha"
    # Outside the jeans' bounding box (plus the 2 px margin) every byte, alpha included, is kept.
    xs, ys = np.array(report["vertices_image"]).T
    outside = np.ones(out.shape[:2], bool)
    outside[max(int(ys.min()) - 3, 0) : int(ys.max()) + 4, max(int(xs.min()) - 3, 0) : int(xs.max()) + 4] = False
    np.testing.assert_array_equal(out[outside], original[outside])
    assert np.sum(out[..., 3] == 0) > 10000  # the transparent background stays transparent


def test_progress_passes_on_a_note_unless_quiet():
    import io

    from jeanscv_cli.progress import Progress
    from jeanscv_cli.worker import Outcome

    done = Outcome(
        0, "in/a.png", "ok", "in/a.jeans.png", seconds=1.0, info={"note": "unsure which thing is the subject"}
    )
    for quiet, expected in ((False, "jeanscv: in/a.png: note: unsure which thing is the subject\n"), (True, "")):
        stream = io.StringIO()
        Progress(1, quiet=quiet, stream=stream, tty=True).finish(done)
        assert stream.getvalue().replace("\r\x1b[K[1/1] 100%", "") == expected


def test_progress_on_a_terminal_is_one_updating_line():
    import io

    from jeanscv_cli.progress import Progress
    from jeanscv_cli.worker import Outcome

    stream = io.StringIO()
    progress = Progress(2, stream=stream, tty=True)
    progress.start("in/a.png")
    assert stream.getvalue() == "\r\x1b[K[0/2] 0%  in/a.png"
    progress.finish(Outcome(0, "in/a.png", "ok", "in/a.jeans.png", seconds=1.0))
    progress.start("in/b.png")
    progress.finish(Outcome(1, "in/b.png", "failed", error="empty file"))
    summary = progress.summary()
    text = stream.getvalue()
    assert "[1/2] 50% ETA 0:0" in text and "\r\x1b[K[1/2] 50% ETA 0:00  in/b.png" in text
    # The error gets a line of its own; the status line is cleared before the summary.
    assert "\r\x1b[Kjeanscv: in/b.png: empty file\n" in text
    assert summary.startswith("1 ok, 1 failed, 0 skipped in ") and text.endswith("\r\x1b[K" + summary + "\n")


@pytest.mark.parametrize(
    ("args", "sig", "status"), [([], 2, 130), ([], 15, 143), (["serve"], 2, 0), (["serve"], 15, 143)]
)
def test_an_interrupt_while_the_command_starts_is_quiet(args, sig, status):
    """Ctrl-C or SIGTERM before the command takes its signals over (imports, option
    parsing): its status and nothing printed. It was click's "Aborted!" with status 1, or
    a traceback of the import it stopped. The signal comes where the command's option
    parsing would be, right after the entry point's first step."""
    script = (
        "import os, sys, time\n"
        "import jeanscv_cli.interrupts as entry\n"
        f"sys.argv = ['jeanscv', *{args!r}]\n"
        "entry.exit_at_once_on_interrupt(0 if sys.argv[1:2] == ['serve'] else 130)\n"
        f"os.kill(os.getpid(), {sig})\n"
        "time.sleep(10)\n"
        "print('not stopped')\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=_env(), timeout=60)
    assert (done.returncode, done.stdout, done.stderr) == (status, "", "")
