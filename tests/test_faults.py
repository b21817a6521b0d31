"""Faults around a batch: inputs that are not files or vanish, full disks, folders that turn
read-only, writers that die at any point. Each: one line per failed input naming it and the
reason, finished outputs intact, no temporary file left, exit status 1, and a second run
completes only what is missing.

Killed runs and two runs at once are in ``test_runs.py``.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import write_silhouette_png
from PIL import Image

from jeanscv.io import write as write_module
from jeanscv.io.write import atomic_write_bytes, remove_stale_temporaries

FAST = ("--iterations", "2", "--starts", "1", "-j", "1", "--backend", "torch")


def make_inputs(folder: Path, count: int = 3) -> list[Path]:
    """``a.png``, ``b.png``... : copies of one silhouette (so their outputs are the same size)."""
    folder.mkdir(parents=True, exist_ok=True)
    return [write_silhouette_png(folder / f"{chr(ord('a') + i)}.png") for i in range(count)]


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if p.name.endswith(".tmp"))


def assert_valid_outputs(folder: Path, names: list[str]) -> dict[str, bytes]:
    """Exactly ``names`` in ``folder`` (besides inputs), each a complete PNG; their bytes."""
    found = sorted(p.name for p in folder.iterdir() if ".jeans." in p.name)
    assert found == sorted(names)
    for name in names:
        with Image.open(folder / name) as image:
            image.load()  # a torn file fails here
            assert image.size == (256, 256)
    assert temporaries(folder) == []
    return {name: (folder / name).read_bytes() for name in names}


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("jeanscv: ")]


# ------------------------------------------------------------------ inputs


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_device_and_symlink_loop_inputs(tmp_path, run_cli):
    """A FIFO used to block the run forever; a symlink loop said 'file not found'."""
    folder = tmp_path / "in"
    good = make_inputs(folder, 1)[0]
    os.mkfifo(folder / "pipe.png")
    (folder / "deep").mkdir()
    os.mkfifo(folder / "deep" / "pipe.jpg")
    (folder / "loop.png").symlink_to("loop.png")
    named_fifo = tmp_path / "named.svg"
    os.mkfifo(named_fifo)
    devices = [d for d in ("/dev/zero",) if os.path.exists(d) and stat.S_ISCHR(os.stat(d).st_mode)]
    result = run_cli(folder, named_fifo, *devices, "-r", "-q", *FAST)
    assert result.exit_code == 1
    expected = [
        f"jeanscv: {folder / 'deep' / 'pipe.jpg'}: cannot read file: is a named pipe, not a regular file",
        f"jeanscv: {folder / 'loop.png'}: cannot read file: too many levels of symbolic links",
        f"jeanscv: {folder / 'pipe.png'}: cannot read file: is a named pipe, not a regular file",
        f"jeanscv: {named_fifo}: cannot read file: is a named pipe, not a regular file",
    ] + [f"jeanscv: {d}: cannot read file: is a character device, not a regular file" for d in devices]
    assert result.stderr.splitlines() == expected
    assert_valid_outputs(folder, [good.stem + ".jeans.png"])


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_fifo_as_clicks_file_mask_and_garment(tmp_path, run_cli):
    src = make_inputs(tmp_path, 1)[0]
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    fifo_png = tmp_path / "pipe.png"
    os.mkfifo(fifo_png)
    fifo_toml = tmp_path / "pipe.toml"
    os.mkfifo(fifo_toml)
    result = run_cli(src, "--clicks", fifo, "-q", *FAST)
    assert result.stderr.splitlines() == [
        f"jeanscv: {src}: clicks file pipe.json: cannot read the clicks file (is a named pipe, not a regular file)"
    ]
    result = run_cli(src, "--mask", fifo_png, "-q", *FAST)
    assert result.stderr.splitlines() == [
        f"jeanscv: {src}: cannot read mask {fifo_png}: cannot read file: is a named pipe, not a regular file"
    ]
    result = run_cli(src, "--garment", fifo_toml, "-q", *FAST)
    assert result.exit_code == 2
    assert "cannot read garment file: is a named pipe, not a regular file" in result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "pipe.json", "pipe.png", "pipe.toml"]


def test_input_that_disappears_before_it_is_read(tmp_path, run_cli, monkeypatch):
    import jeanscv_cli.worker as worker

    folder = tmp_path / "in"
    a, b, c = make_inputs(folder)
    real = worker.process

    def vanishing(job, options, *rest):
        if job.path.name == "b.png":
            job.path.unlink()  # after discovery, before decoding
        return real(job, options, *rest)

    monkeypatch.setattr(worker, "process", vanishing)
    result = run_cli(folder, "-q", *FAST)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {folder / 'b.png'}: file not found"]
    first = assert_valid_outputs(folder, ["a.jeans.png", "c.jeans.png"])

    monkeypatch.setattr(worker, "process", real)
    write_silhouette_png(b)  # the fault is removed: only b is made
    result = run_cli(folder, "-q", *FAST)
    assert result.exit_code == 0 and result.stderr == ""
    again = assert_valid_outputs(folder, ["a.jeans.png", "b.jeans.png", "c.jeans.png"])
    assert {k: again[k] for k in first} == first


def test_input_cut_short_while_it_is_read(tmp_path, run_cli, monkeypatch):
    """The file is truncated between reading its header and its pixels."""
    import numpy as np

    from jeanscv.io import image

    folder = tmp_path / "in"
    a, b = make_inputs(folder, 2)
    noise = np.random.default_rng(0).integers(0, 256, (256, 256, 3), dtype=np.uint8)
    Image.fromarray(noise).save(b)  # 190 KiB: far more than one buffered read
    real = image._tile_rawmode

    def truncate_then(img):
        if os.fstat(img.fp.fileno()).st_ino == b.stat().st_ino:
            os.truncate(b, 120)
        return real(img)

    monkeypatch.setattr(image, "_tile_rawmode", truncate_then)
    result = run_cli(folder, "-q", *FAST)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {b}: truncated or corrupt image"]
    assert_valid_outputs(folder, ["a.jeans.png"])


# ------------------------------------------------------------------ outputs


def _fail_after(count: int, error: int, monkeypatch) -> None:
    """Make every output write after the first ``count`` fail with ``error`` (at its
    fsync, after the data went to the temporary file: the worst moment)."""
    real = os.fsync
    done = []

    def fsync(fd):
        if stat.S_ISREG(os.fstat(fd).st_mode):
            if len(done) >= count:
                raise OSError(error, os.strerror(error))
            done.append(fd)
        return real(fd)

    monkeypatch.setattr(write_module.os, "fsync", fsync)


@pytest.mark.parametrize(
    ("error", "reason"),
    [
        (errno.ENOSPC, "no space left on device"),
        (errno.EROFS, "read-only file system"),
        (errno.EIO, "input/output error"),
    ],
)
def test_write_fault_mid_batch_then_resume(tmp_path, run_cli, monkeypatch, error, reason):
    """The disk fills up (or the folder turns read-only, or the disk fails) after the first output."""
    folder = tmp_path / "in"
    make_inputs(folder)
    out = tmp_path / "out"
    with monkeypatch.context() as patch:
        _fail_after(1, error, patch)
        result = run_cli(folder, "-o", out, "-q", *FAST)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {folder / 'b.png'}: cannot write output: {reason}",
        f"jeanscv: {folder / 'c.png'}: cannot write output: {reason}",
    ]
    first = assert_valid_outputs(out, ["a.jeans.png"])
    result = run_cli(folder, "-o", out, *FAST)
    assert result.exit_code == 0
    assert result.stderr.splitlines()[-1].startswith("2 ok, 0 failed, 1 skipped in ")
    again = assert_valid_outputs(out, ["a.jeans.png", "b.jeans.png", "c.jeans.png"])
    assert again["a.jeans.png"] == first["a.jeans.png"]


def test_permission_denied_mid_batch_then_resume(tmp_path, run_cli, monkeypatch):
    """The output folder stops accepting new files after the first output (chmod for a
    normal user; refused creation, which works as root too)."""
    folder = tmp_path / "in"
    make_inputs(folder)
    out = tmp_path / "out"
    real_open = os.open
    made = []

    def guarded_open(path, flags, *args, **kwargs):
        if Path(path).parent == out and flags & os.O_CREAT:
            if made:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            made.append(path)
        return real_open(path, flags, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(os, "open", guarded_open)
        result = run_cli(folder, "-o", out, "-q", *FAST)
    assert result.exit_code == 1
    assert error_lines(result.stderr) == [
        f"jeanscv: {folder / n}: cannot write output: permission denied" for n in ("b.png", "c.png")
    ]
    first = assert_valid_outputs(out, ["a.jeans.png"])
    assert run_cli(folder, "-o", out, "-q", *FAST).exit_code == 0
    assert (
        assert_valid_outputs(out, ["a.jeans.png", "b.jeans.png", "c.jeans.png"])["a.jeans.png"] == first["a.jeans.png"]
    )


def _mount_tmpfs(where: Path, size: str) -> bool:
    if not (sys.platform.startswith("linux") and shutil.which("mount")):
        return False
    where.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)], capture_output=True)
    except OSError:
        return False
    return done.returncode == 0


def _fill(folder: Path, leave: int) -> None:
    """Fill the file system of ``folder`` up to ``leave`` bytes free."""
    free = os.statvfs(folder).f_bavail * os.statvfs(folder).f_frsize
    with open(folder / "filler", "wb") as filler:
        filler.write(b"\0" * max(0, free - leave))


def test_real_full_disk_and_read_only_remount(tmp_path, run_cli):
    """On a real small tmpfs (where this process may mount one): the disk fills up after
    the first output; then the folder is remounted read-only; each fault removed, a run
    completes what is missing."""
    mnt = tmp_path / "mnt"
    if not _mount_tmpfs(mnt, "2m"):
        pytest.skip("cannot mount a tmpfs here (needs root and mount rights)")
    try:
        folder = tmp_path / "in"
        make_inputs(folder)
        out = mnt / "out"
        # Leave room for the first output only (the three are the same size).
        assert run_cli(folder / "a.png", "-o", out, "-q", *FAST).exit_code == 0
        pages = -(-(out / "a.jeans.png").stat().st_size // 4096)
        (out / "a.jeans.png").unlink()
        _fill(mnt, pages * 4096 + 4095)
        result = run_cli(folder, "-o", out, "-q", *FAST)
        assert result.exit_code == 1
        lines = result.stderr.splitlines()
        assert lines == [
            f"jeanscv: {folder / 'b.png'}: cannot write output: no space left on device",
            f"jeanscv: {folder / 'c.png'}: cannot write output: no space left on device",
        ]
        first = assert_valid_outputs(out, ["a.jeans.png"])
        (mnt / "filler").unlink()
        subprocess.run(["mount", "-o", "remount,ro", str(mnt)], check=True)
        result = run_cli(folder, "-o", out, "-q", *FAST)
        assert result.exit_code == 1
        assert error_lines(result.stderr) == [
            f"jeanscv: {folder / n}: cannot write output: read-only file system" for n in ("b.png", "c.png")
        ]
        subprocess.run(["mount", "-o", "remount,rw", str(mnt)], check=True)
        assert run_cli(folder, "-o", out, "-q", *FAST).exit_code == 0
        again = assert_valid_outputs(out, ["a.jeans.png", "b.jeans.png", "c.jeans.png"])
        assert again["a.jeans.png"] == first["a.jeans.png"]
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


# ------------------------------------------------------------- power loss


class PowerLoss(BaseException):
    """Nothing runs after it: not even the writer's clean-up."""


STEPS = ("write", "fsync", "replace", "folder fsync")


@pytest.mark.parametrize("step", STEPS)
def test_power_loss_at_every_step_leaves_old_or_new(tmp_path, monkeypatch, step):
    """The writer stops dead at each step: the target is the old file or the complete new
    one, never a mix; a leftover temporary file is removed by the next run's sweep."""
    target = tmp_path / "a.jeans.png"
    old, new = b"old output " * 100, b"new output " * 5000
    target.write_bytes(old)
    calls = []
    real = {"fsync": os.fsync, "replace": os.replace, "unlink": os.unlink}

    def fsync(fd):
        regular = stat.S_ISREG(os.fstat(fd).st_mode)
        calls.append("fsync" if regular else "folder fsync")
        if calls[-1] == step:
            raise PowerLoss
        real["fsync"](fd)

    def replace(src, dst):
        calls.append("replace")
        if step == "replace":
            raise PowerLoss
        real["replace"](src, dst)

    class Torn:
        """The temporary file's writer: half the data, then the power goes."""

        def __init__(self, f):
            self.f = f

        def __getattr__(self, name):
            return getattr(self.f, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, data):
            calls.append("write")
            if step == "write":
                self.f.write(data[: len(data) // 2])
                raise PowerLoss
            return self.f.write(data)

    real_fdopen = os.fdopen
    monkeypatch.setattr(write_module.os, "fsync", fsync)
    monkeypatch.setattr(write_module.os, "replace", replace)
    monkeypatch.setattr(write_module.os, "fdopen", lambda fd, mode: Torn(real_fdopen(fd, mode)))
    monkeypatch.setattr(write_module.os, "unlink", lambda path: None)  # no clean-up after a power loss
    with pytest.raises(PowerLoss):
        atomic_write_bytes(target, new)
    monkeypatch.undo()
    assert target.read_bytes() in (old, new)
    # The data is on disk before the rename, and the rename before the folder's fsync.
    assert calls == ["write", "fsync", "replace", "folder fsync"][: len(calls)]
    assert remove_stale_temporaries(tmp_path, {"a.jeans.png"}) == [] or temporaries(tmp_path) == []
    assert temporaries(tmp_path) == []


def test_sweep_removes_only_dead_writers_temporaries(tmp_path):
    import fcntl

    dead = tmp_path / ".a.jeans.png.0123abcd.tmp"
    dead.write_bytes(b"half")
    live = tmp_path / ".b.jeans.png.89abcdef.tmp"
    live.write_bytes(b"being written")
    other = tmp_path / ".notes.txt.0123abcd.tmp"
    other.write_bytes(b"someone else's")
    user = tmp_path / ".a.jeans.png.backup.tmp"
    user.write_bytes(b"not ours")
    holder = os.open(live, os.O_RDONLY)
    fcntl.flock(holder, fcntl.LOCK_EX)  # a live writer (another open file description)
    try:
        removed = remove_stale_temporaries(tmp_path, {"a.jeans.png", "b.jeans.png"})
    finally:
        os.close(holder)
    assert removed == [dead]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([live.name, other.name, user.name])


def test_a_run_removes_what_a_killed_run_left(tmp_path, run_cli):
    folder = tmp_path / "in"
    make_inputs(folder, 1)
    leftover = folder / ".a.jeans.png.deadbeef.tmp"
    leftover.write_bytes(b"\x89PNG half of it")
    assert run_cli(folder, "-q", *FAST).exit_code == 0
    assert_valid_outputs(folder, ["a.jeans.png"])


def test_big_folder_counts(tmp_path, run_cli):
    """400 inputs of every outcome: the summary adds up (speed: bench/big_folder.py)."""
    folder = tmp_path / "in"
    make_inputs(folder, 2)
    for i in range(300):
        (folder / f"bad{i:03d}.png").write_bytes(b"not a picture")
    for i in range(60):
        write_silhouette_png(folder / f"done{i:02d}.png")
        (folder / f"done{i:02d}.jeans.png").write_bytes(b"an earlier output")
    for i in range(40):
        (folder / f"notes{i:02d}.txt").write_text("x")
    result = run_cli(folder, *FAST)
    assert result.exit_code == 1
    assert len(error_lines(result.stderr)) == 300
    assert result.stderr.splitlines()[-1].startswith("2 ok, 300 failed, 100 skipped in ")


# ------------------------------------------------------- read-only install


def test_kernel_cache_of_a_read_only_install(tmp_path, monkeypatch):
    """Where the kernels are kept: the per-user cache (never beside the installed source),
    else (a service account without a home) a private temporary folder that
    JEANSCV_CACHE_DIR is set to, for the processes a run starts. 'Cannot be written' is made
    real for root too: a regular file where the folder should be."""
    from jeanscv.fitting._fast.cache import kernel_cache_dir, source_key

    kernels = tmp_path / "site-packages" / "jeanscv" / "fitting" / "_fast"
    kernels.mkdir(parents=True)
    key = source_key(kernels)
    # kernel_cache_dir sets JEANSCV_CACHE_DIR itself, below: put back after the test, or every
    # later fit of the suite, and every subprocess it starts, compiled the kernels afresh into
    # this test's empty folder (a minute of CI). setenv, unlike delenv of an unset variable,
    # is undone; "" counts as unset.
    monkeypatch.setenv("JEANSCV_CACHE_DIR", "")
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "home-cache"))
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    user = tmp_path / "home-cache" / "jeanscv" / "kernels" / key
    assert kernel_cache_dir(kernels) == user and user.is_dir()
    assert not (kernels / "__pycache__").exists()

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))  # where a user sent numba's caches
    assert kernel_cache_dir(kernels) == tmp_path / "numba" / "jeanscv" / "kernels" / key
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")

    (tmp_path / "nohome").write_bytes(b"")  # the home folder cannot be written
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "nohome"))
    private = tmp_path / "tmp" / f"jeanscv-cache-{os.getuid()}"
    assert kernel_cache_dir(kernels) == private / "kernels" / key
    assert os.environ["JEANSCV_CACHE_DIR"] == str(private)
    assert stat.S_IMODE(private.stat().st_mode) == 0o700
    assert kernel_cache_dir(kernels) == private / "kernels" / key  # the same on the next call


def test_private_cache_folder_is_not_taken_from_someone_else(tmp_path, monkeypatch):
    """A folder of that name another user could write is not trusted (code is loaded from it)."""
    from jeanscv.fitting._fast.cache import _private_temporary_root

    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    planted = tmp_path / f"jeanscv-cache-{os.getuid()}"
    planted.mkdir(mode=0o777)
    planted.chmod(0o777)
    root = _private_temporary_root()
    assert root != planted and root.parent == tmp_path and stat.S_IMODE(root.stat().st_mode) == 0o700
