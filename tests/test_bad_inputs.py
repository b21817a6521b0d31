"""Bad inputs: each gives exactly one line ``jeanscv: FILE: reason``, no traceback, no
output, exit 1; in a batch the other files are still processed."""

from __future__ import annotations

import errno
import io
import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from conftest import write_silhouette_png
from PIL import Image

FAST = ("--iterations", "3", "--starts", "1")


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def _huge_png_header() -> bytes:
    """A PNG that claims 50000x50000 pixels (header and one tiny chunk of data only)."""
    ihdr = struct.pack(">IIBBBBB", 50000, 50000, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr)
            + _png_chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + _png_chunk(b"IEND", b""))


def _encoded(pixels: np.ndarray, fmt: str) -> bytes:
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, fmt)
    return buffer.getvalue()


def _photo() -> np.ndarray:
    rng = np.random.default_rng(1)
    return rng.integers(0, 255, size=(64, 64, 3), dtype=np.uint8)


_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE svg [
<!ENTITY lol "lol">
<!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
<!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
<!ENTITY lol9 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><title>&lol9;</title>
<path d="M10 10 L200 10 L200 200 Z"/></svg>
"""

# name -> (file bytes, expected words of the reason)
BAD_FILES = {
    "empty.png": (b"", "empty file"),
    "truncated.jpg": (_encoded(_photo(), "JPEG")[:300], "truncated or corrupt"),
    "truncated.png": (_encoded(_photo(), "PNG")[:200], "truncated or corrupt"),
    "text.jpg": (b"this is not a picture\n" * 20, "not an image file"),
    "huge.png": (_huge_png_header(), "over the --max-pixels limit"),
    "tiny.png": (_encoded(np.zeros((1, 1, 3), np.uint8), "PNG"), "too small"),
    "flat.png": (_encoded(np.full((64, 64, 3), 128, np.uint8), "PNG"), ""),  # reason: the library's
    "nopath.svg": (b'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256"><g/></svg>', "no filled path"),
    "zeroarea.svg": (b'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 256 256">'
                     b'<path d="M10 10 L100 100 L200 200 Z"/></svg>', "silhouette is empty"),
    "laughs.svg": (_LAUGHS.encode(), "entities"),
    "fake.nef": (b"II*\x00" + b"\x00" * 400, "not a readable RAW file"),
}


def _error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("jeanscv: ")]


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_bad_file_alone(tmp_path, run_cli, name):
    data, words = BAD_FILES[name]
    bad = tmp_path / name
    bad.write_bytes(data)
    result = run_cli(bad, *FAST, "-q", "--json")
    assert result.exit_code == 1
    assert "Traceback" not in result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    prefix = f"jeanscv: {bad}: "
    assert lines[0].startswith(prefix) and len(lines[0]) > len(prefix)
    assert words in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]


def test_missing_file_and_empty_folder(tmp_path, run_cli):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "notes.txt").write_text("hello")
    missing = tmp_path / "missing.png"
    result = run_cli(missing, tmp_path / "docs", tmp_path / "nothing*.png", *FAST, "-q")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [
        f"jeanscv: {missing}: file not found",
        f"jeanscv: {tmp_path / 'docs'}: no supported images found in this folder (use -r to search subfolders)",
        f"jeanscv: {tmp_path / 'nothing*.png'}: no files match this pattern",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["docs"]


def test_batch_goes_on_past_bad_files(tmp_path, run_cli):
    folder = tmp_path / "in"
    folder.mkdir()
    for name, (data, _) in BAD_FILES.items():
        (folder / name).write_bytes(data)
    write_silhouette_png(folder / "good.png")
    (folder / "readme.txt").write_text("not an image")
    result = run_cli(folder, *FAST, "-o", tmp_path / "out")
    assert result.exit_code == 1
    assert "Traceback" not in result.stderr
    errors = _error_lines(result.stderr)
    assert sorted(errors) == sorted(
        line for line in errors if any(line.startswith(f"jeanscv: {folder / n}: ") for n in BAD_FILES)
    )
    assert len(errors) == len(BAD_FILES)
    for name in BAD_FILES:
        assert sum(line.startswith(f"jeanscv: {folder / name}: ") for line in errors) == 1
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["good.jeans.png"]
    # 11 failed, the good one done, readme.txt skipped quietly.
    assert result.stderr.splitlines()[-1].startswith(f"1 ok, {len(BAD_FILES)} failed, 1 skipped in ")


def test_unwritable_output_folder(tmp_path, run_cli, monkeypatch):
    src = write_silhouette_png(tmp_path / "a.png")
    locked = tmp_path / "locked"
    locked.mkdir()
    if getattr(os, "geteuid", lambda: -1)() == 0:
        # root ignores permission bits: refuse file creation in that folder instead.
        real_open = os.open

        def guarded_open(path, flags, *args, **kwargs):
            if Path(path).parent == locked and flags & os.O_CREAT:
                raise PermissionError(errno.EACCES, "Permission denied", str(path))
            return real_open(path, flags, *args, **kwargs)

        monkeypatch.setattr(os, "open", guarded_open)
    else:
        locked.chmod(0o555)
    try:
        result = run_cli(src, *FAST, "-q", "-o", locked)
    finally:
        locked.chmod(0o755)
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {src}: cannot write output: permission denied"]
    assert list(locked.iterdir()) == []


def test_unexpected_exception_is_one_line(tmp_path, run_cli, monkeypatch):
    from jeanscv import api

    def boom(*args, **kwargs):
        raise RuntimeError("something\nbroke")

    monkeypatch.setattr(api, "apply_jeans", boom)
    src = write_silhouette_png(tmp_path / "a.png")
    result = run_cli(src, *FAST, "-q")
    assert result.exit_code == 1
    assert result.stderr.splitlines() == [f"jeanscv: {src}: unexpected error (RuntimeError: something broke)"]


def test_existing_output_skipped_then_overwritten(tmp_path, run_cli):
    src = write_silhouette_png(tmp_path / "a.png")
    out = tmp_path / "a.jeans.png"
    out.write_bytes(b"placeholder")
    result = run_cli(src, *FAST)
    assert result.exit_code == 0
    assert out.read_bytes() == b"placeholder"
    assert f"{src}: skipped (output exists; --overwrite redoes it)" in result.stderr
    assert result.stderr.splitlines()[-1].startswith("0 ok, 0 failed, 1 skipped in ")
    result = run_cli(src, *FAST, "--overwrite", "-q")
    assert result.exit_code == 0 and result.stderr == ""
    with Image.open(out) as im:
        assert im.size == (256, 256)
