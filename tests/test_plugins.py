"""Plugin discovery through entry points, with the example distribution in tests/plugin_example.

The example is "installed" into a temporary folder the way pip lays out a wheel (the
package plus a ``*.dist-info`` with ``METADATA`` and ``entry_points.txt``, written from
the example's own pyproject), which is fast and needs no network or build backend;
one test checks that a real ``pip install --target`` gives the same entry points.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jeanscv import plugins
from jeanscv.errors import JeansError
from jeanscv.fitting.garments import GARMENTS
from jeanscv.plugins import get_garment

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

EXAMPLE = Path(__file__).resolve().parent / "plugin_example"
ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "jeanscv_plugin_example"

#: A second, deliberately broken distribution: each entry point fails differently.
BROKEN_MODULE = """
import numpy as np

def raises(image, **options):
    raise RuntimeError("model file missing")

def wrong_shape(image, **options):
    return np.ones((3, 3), bool)

def not_a_mask(image, **options):
    return np.full(image.shape[:2], "x")

def gives_nan(image, **options):
    return np.full(image.shape[:2], np.nan)

def half(image, **options):
    class Result:  # Segmentation-like: has .mask
        mask = np.zeros(image.shape[:2], np.uint8)
    Result.mask[:, : image.shape[1] // 2] = 255
    return Result()

NOT_CALLABLE = 3

def not_a_garment():
    return "jeans"
"""
BROKEN_ENTRY_POINTS = {
    "jeanscv.garments": {
        "missing_module": "jeanscv_no_such_module:thing",
        "not_a_garment": "broken_jeans_plugin:not_a_garment",
        "jeans": f"{PACKAGE}:cape",  # a built-in's name: the built-in wins
    },
    "jeanscv.silhouettes": {
        "raises": "broken_jeans_plugin:raises",
        "wrong_shape": "broken_jeans_plugin:wrong_shape",
        "not_a_mask": "broken_jeans_plugin:not_a_mask",
        "gives_nan": "broken_jeans_plugin:gives_nan",
        "half": "broken_jeans_plugin:half",
        "not_callable": "broken_jeans_plugin:NOT_CALLABLE",
        "grabcut": "broken_jeans_plugin:half",  # a built-in's name
    },
}


def write_distribution(site: Path, name: str, version: str, entry_points: dict[str, dict[str, str]]) -> None:
    """A ``*.dist-info`` as pip writes it: ``importlib.metadata`` finds it on ``sys.path``."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(
        "".join(
            f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) + "\n"
            for group, eps in entry_points.items()
        )
    )


def install_example(site: Path) -> None:
    """The example distribution, laid out as an installed wheel, from its own pyproject."""
    project = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    shutil.copytree(EXAMPLE / PACKAGE, site / PACKAGE, ignore=shutil.ignore_patterns("__pycache__"))
    write_distribution(site, project["name"], project["version"], project["entry-points"])


@pytest.fixture
def site(tmp_path, monkeypatch):
    """A temporary site folder on ``sys.path`` holding the example plugin; forgotten afterwards."""
    folder = tmp_path / "site"
    install_example(folder)
    monkeypatch.syspath_prepend(str(folder))
    plugins.refresh()
    yield folder
    for module in (PACKAGE, "broken_jeans_plugin"):
        sys.modules.pop(module, None)
    monkeypatch.undo()
    plugins.refresh()


def dark_square_image() -> np.ndarray:
    """64x64 white RGB with a black 20 x 40 (w x h) block at x 20..40, y 10..50."""
    image = np.full((64, 64, 3), 255, np.uint8)
    image[10:50, 20:40] = 0
    return image


def test_without_plugins_only_the_builtins_are_offered():
    plugins.refresh()
    assert list(plugins.available_garments()) == list(GARMENTS)
    assert list(plugins.available_silhouette_methods()) == ["auto", "alpha", "threshold", "grabcut"]


def test_example_plugin_garment_is_discovered(site):
    garments = plugins.available_garments()
    assert list(garments) == ["jeans", "shorts", "skirt", "cape"]
    cape = garments["cape"]
    assert cape.num_vertices == 6 and cape.open_edges == (2, 5) and cape.waist == (2, 3)
    assert cape.extra == {"style": "plain", "colour": (128, 0, 32)}
    assert get_garment("cape").same_as(cape)
    assert "cape" not in GARMENTS  # plugins never edit the built-in table


def test_plugin_garment_fits_through_the_api(site):
    from jeanscv import api
    from testkit.synthetic import silhouette_zoo

    result = api.fit(silhouette_zoo(["person"])["person"], garment="cape", iterations=5, starts=2)
    assert result.garment.name == "cape" and result.vertices.shape == (6, 2)
    assert np.all(np.isfinite(result.vertices))


def test_example_silhouette_method(site):
    extract = plugins.get_silhouette_method("everything_dark")
    image = dark_square_image()
    mask = extract(image)
    assert mask.dtype == bool and mask.shape == (64, 64) and int(mask.sum()) == 800
    assert int(plugins.extract_mask("everything_dark", image, level=1).sum()) == 800
    assert int(plugins.extract_mask("everything_dark", image, level=0).sum()) == 0
    segmentation = plugins.segment_with("everything_dark", image)
    assert segmentation.method == "everything_dark" and segmentation.details["plugin"] == "everything_dark"
    assert np.array_equal(segmentation.mask, mask)
    # The contour is the mask's 0.5 iso-line: the block's pixel edges, each corner cut by
    # a half-pixel chamfer, so its area is 20 * 40 - 4 * 0.125.
    x, y = segmentation.contour[:, 0], segmentation.contour[:, 1]
    assert 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) == pytest.approx(799.5, abs=1e-9)


def test_lookups_are_cached_until_refresh(site, tmp_path):
    assert "late" not in plugins.available_garments()
    late = tmp_path / "late"
    write_distribution(late, "late-plugin", "1.0", {"jeanscv.garments": {"late": f"{PACKAGE}:cape"}})
    sys.path.insert(0, str(late))
    try:
        assert "late" not in plugins.available_garments()  # cached
        plugins.refresh()
        late_garment = plugins.available_garments()["late"]
        assert late_garment.name == "late" and late_garment.num_vertices == 6  # renamed to its entry point
    finally:
        sys.path.remove(str(late))
        plugins.refresh()


def test_broken_plugins_are_skipped_with_a_warning(site):
    (site / "broken_jeans_plugin.py").write_text(BROKEN_MODULE)
    write_distribution(site, "broken-plugin", "0.1", BROKEN_ENTRY_POINTS)
    plugins.refresh()
    with pytest.warns(plugins.PluginWarning) as caught:
        garments = plugins.available_garments()
        methods = plugins.available_silhouette_methods()
    messages = sorted(str(w.message) for w in caught)
    assert list(garments) == ["jeans", "shorts", "skirt", "cape"]
    assert garments["jeans"] is GARMENTS["jeans"]
    assert sorted(methods) == sorted(
        [
            "auto",
            "alpha",
            "threshold",
            "grabcut",
            "everything_dark",
            "raises",
            "wrong_shape",
            "not_a_mask",
            "gives_nan",
            "half",
        ]
    )
    expected = [
        "jeanscv: skipping garment plugin 'jeans' (broken-plugin 0.1): a built-in has that name",
        "jeanscv: skipping garment plugin 'missing_module' (broken-plugin 0.1): ModuleNotFoundError: No module named 'jeanscv_no_such_module'",
        "jeanscv: skipping garment plugin 'not_a_garment' (broken-plugin 0.1): TypeError: it gave str, not a jeanscv Garment",
        "jeanscv: skipping silhouette plugin 'grabcut' (broken-plugin 0.1): a built-in has that name",
        "jeanscv: skipping silhouette plugin 'not_callable' (broken-plugin 0.1): it gave int, not a callable",
    ]
    assert messages == expected

    image = dark_square_image()
    for name, reason in [
        ("raises", "silhouette method 'raises' failed: RuntimeError: model file missing"),
        ("wrong_shape", "silhouette method 'wrong_shape' gave a mask of shape (3, 3), not (64, 64)"),
        ("not_a_mask", "silhouette method 'not_a_mask' gave a <U1 mask, not a boolean or numeric one"),
        ("gives_nan", "silhouette method 'gives_nan' gave a mask with NaN or infinite values"),
        ("nope", "unknown silhouette method 'nope' (known: auto, alpha, threshold, grabcut, "),
    ]:
        with pytest.raises(JeansError) as info:
            plugins.extract_mask(name, image)
        assert str(info.value).startswith(reason), str(info.value)
    # A Segmentation-like result with a 0/255 uint8 .mask: the left half.
    assert int(plugins.extract_mask("half", image).sum()) == 64 * 32


def test_plugins_are_found_from_a_fresh_interpreter(site):
    code = (
        "import json, numpy as np\n"
        "from jeanscv.plugins import available_garments, get_silhouette_method\n"
        "image = np.full((64, 64, 3), 255, np.uint8); image[10:50, 20:40] = 0\n"
        "g = available_garments()['cape']\n"
        "print(json.dumps({'garments': list(available_garments()), 'vertices': g.num_vertices,\n"
        "                  'dark': int(get_silhouette_method('everything_dark')(image).sum())}))\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout) == {"garments": ["jeans", "shorts", "skirt", "cape"], "vertices": 6, "dark": 800}


@pytest.mark.skipif(importlib.util.find_spec("setuptools") is None, reason="building the example needs setuptools")
def test_pip_installs_the_example_with_the_same_entry_points(tmp_path):
    source = tmp_path / "src"
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("__pycache__", "build", "*.egg-info"))
    target = tmp_path / "target"
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--no-index",
            "--disable-pip-version-check",
            "--target",
            str(target),
            str(source),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    (installed,) = target.glob("jeanscv_plugin_example-0.1.0.dist-info")
    hand_made = tmp_path / "hand"
    install_example(hand_made)
    (ours,) = hand_made.glob("*.dist-info")
    parse = lambda text: sorted(line.replace(" ", "") for line in text.splitlines() if line.strip())  # noqa: E731
    assert parse((installed / "entry_points.txt").read_text()) == parse((ours / "entry_points.txt").read_text())
    assert (target / PACKAGE / "__init__.py").read_bytes() == (EXAMPLE / PACKAGE / "__init__.py").read_bytes()


@pytest.mark.usefixtures("compiled_kernels")
def test_the_cli_offers_and_uses_plugin_garments_and_extractors(site, tmp_path):
    """The installed example plugin from the command line, in a fresh process."""
    from PIL import Image

    photo = tmp_path / "square.png"
    image = np.full((160, 160, 3), 230, np.uint8)
    image[30:140, 50:110] = 20
    Image.fromarray(image).save(photo)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT), str(ROOT / "tests")])}

    def jeanscv(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "jeanscv", *args], env=env, capture_output=True, text=True, timeout=240
        )

    listed = jeanscv("--list-garments")
    assert listed.returncode == 0, listed.stderr
    assert "cape:" in listed.stdout
    out = tmp_path / "out"
    run = jeanscv(
        str(photo),
        "-o",
        str(out),
        "--kind",
        "photo",
        "--garment",
        "cape",
        "--silhouette",
        "everything_dark",
        "--iterations",
        "5",
        "--json",
    )
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "square.jeans.json").read_text())
    assert report["garment"] == "cape" and report["silhouette_method"] == "everything_dark"
    assert len(report["vertices_canvas"]) == 6
