"""The README's two commands in one environment, as a new user runs them: ``pip install .``
and a run, then ``pip install -e .`` over it, then ``jeanscv`` again from another folder.

A run used to compile the fit kernels into the installed package (numba's ``__pycache__``
beside the source); pip's uninstall before the editable install did not know those files,
so ``site-packages/jeanscv`` stayed behind without ``__init__.py`` and Python took it for a
namespace package: every later ``jeanscv`` failed to import. pytest's own path (the
repository root first) hides such a break, so these tests run the installed command from
a folder outside the repository.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CAT = ROOT / "sample_images" / "cat.jpg"
#: What ``pip install .`` builds from: the project's metadata and its two packages.
SOURCE = ("pyproject.toml", "README.md", "jeanscv", "cli")


def _outside_env() -> dict[str, str]:
    """The environment less anything that would put the repository on the path."""
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "PYTHONSTARTUP")}
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as a user's shell: Python writes bytecode where it may
    return env


def _run(command: list, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    done = subprocess.run(command, cwd=cwd, env=_outside_env(), capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, f"{command}\n{done.stdout}\n{done.stderr}"
    return done


def test_the_installed_command_runs_from_outside_the_repository(tmp_path, compiled_kernels):
    """The suite's own environment, seen as a user sees it: no repository on the path."""
    command = Path(sys.executable).parent / "jeanscv"
    if not command.exists():
        if os.environ.get("CI"):
            pytest.fail(f"{command} is missing: the README's install makes it")
        pytest.skip("jeanscv is not installed in this environment")
    version = _run([str(command), "--version"], tmp_path)
    from jeanscv import __version__

    assert version.stdout.strip() == f"jeanscv {__version__}"
    _run([str(command), str(CAT), "-o", "out", "-q", "--iterations", "5"], tmp_path)
    assert (tmp_path / "out" / "cat.jeans.jpg").stat().st_size > 10_000


def _dependencies_only(site_packages: Path, folder: Path) -> Path:
    """A folder of links to everything installed beside jeanscv, less jeanscv itself: the
    new environment reaches the dependencies through it without reinstalling gigabytes,
    and pip there does not see the running suite's own jeanscv."""
    folder.mkdir()
    for entry in site_packages.iterdir():
        lowered = entry.name.lower()
        if lowered.startswith(("jeanscv", "__editable__", "_jeanscv")) or lowered.endswith(".pth"):
            continue
        (folder / entry.name).symlink_to(entry)
    return folder


def _files_outside_record(site_packages: Path) -> list[str]:
    """Files under site-packages' jeanscv folders that pip's RECORD does not list."""
    (dist_info,) = site_packages.glob("jeanscv-*.dist-info")
    recorded = {line.split(",")[0] for line in (dist_info / "RECORD").read_text().splitlines()}
    found = []
    for package in ("jeanscv", "jeanscv_cli"):
        for path in (site_packages / package).rglob("*"):
            name = path.relative_to(site_packages).as_posix()
            if path.is_file() and name not in recorded:
                found.append(name)
    return sorted(found)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the venv layout below is Linux's")
def test_readme_commands_one_after_the_other_leave_a_working_jeanscv(tmp_path, compiled_kernels):
    source = tmp_path / "source"
    source.mkdir()
    for name in SOURCE:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        else:
            shutil.copy2(ROOT / name, source / name)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site_packages = Path(
        subprocess.run(
            [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    )
    links = _dependencies_only(Path(sysconfig.get_paths()["purelib"]), tmp_path / "dependencies")
    (site_packages / "dependencies.pth").write_text(f"{links}\n")
    pip = [sys.executable, "-m", "pip", "--python", str(python), "--disable-pip-version-check", "-q"]
    jeanscv = str(venv / "bin" / "jeanscv")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()

    _run([*pip, "install", "--no-deps", str(source)], elsewhere)
    _run([jeanscv, str(CAT), "-o", "first", "-q", "--iterations", "5"], elsewhere)
    assert (elsewhere / "first" / "cat.jeans.jpg").is_file()
    assert _files_outside_record(site_packages) == []  # nothing written into the installation

    _run([*pip, "install", "--no-deps", "-e", str(source)], elsewhere)
    assert not (site_packages / "jeanscv").exists()
    from jeanscv import __version__

    assert _run([jeanscv, "--version"], elsewhere).stdout.strip() == f"jeanscv {__version__}"
    _run([jeanscv, str(CAT), "-o", "second", "-q", "--iterations", "5"], elsewhere)
    assert (elsewhere / "second" / "cat.jeans.jpg").is_file()

    _run([*pip, "uninstall", "-y", "jeanscv"], elsewhere)
    assert not [path.name for path in site_packages.iterdir() if path.name.lower().startswith("jeanscv")]
