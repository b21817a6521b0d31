"""A short, deterministic fuzz run of every parser and entry point (``tests/fuzzing.py``),
the inputs the long run (``bench/fuzz.py``) found, and the checks of the harness itself.

The contract: a result, or ``JeansError`` with a one-line reason; no other exception, no
warning, nothing printed to file descriptor 2 by C code.
"""

from __future__ import annotations

import os
import random
import warnings
from pathlib import Path

import pytest
from fuzzing import TARGETS, Target, violation
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jeanscv.errors import JeansError

REGRESSIONS = Path(__file__).parent / "data" / "fuzz"

# Cases per target: a few seconds each on the 2-core CI machine.
EXAMPLES = {
    "svg": 80,
    "path_data": 80,
    "image": 150,
    "mask": 60,
    "clip": 40,
    "clicks": 50,
    "clicks_file": 40,
    "garment": 100,
    "captions": 50,
    "cli": 10,
}


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_fuzz_short_run(name: str) -> None:
    target = TARGETS[name]

    @settings(
        max_examples=EXAMPLES[name],
        derandomize=True,
        database=None,
        deadline=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.randoms(use_true_random=False, note_method_calls=False))
    def check(rng: random.Random) -> None:
        problem = violation(target, target.generate(rng))
        assert problem is None, problem

    check()


def test_every_target_is_fuzzed() -> None:
    assert sorted(EXAMPLES) == sorted(TARGETS)


def _regression_cases() -> list[Path]:
    return sorted(p for p in REGRESSIONS.glob("*/*") if p.is_file())


@pytest.mark.parametrize("path", _regression_cases(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_found_inputs_keep_the_contract(path: Path) -> None:
    """Each input the fuzzer once found breaking the contract, through its entry point
    (images also as a mask)."""
    data = path.read_bytes()
    if path.parent.name == "image":
        for name in ("image", "mask"):
            assert violation(TARGETS[name], (path.name, data)) is None
    elif path.parent.name == "svg":
        for canvas in (16, 256):
            assert violation(TARGETS["svg"], (data, canvas, 4)) is None
    else:
        raise AssertionError(f"no target for {path}")


def test_unknown_declared_encoding_is_one_line() -> None:
    from jeanscv.io.svg import read_svg_silhouette_from_bytes

    data = (REGRESSIONS / "svg" / "unknown_declared_encoding.svg").read_bytes()
    with pytest.raises(JeansError, match="^not an SVG file: unknown encoding: bogus$"):
        read_svg_silhouette_from_bytes(data)


def test_png_chunk_claiming_more_than_the_file_is_not_given_to_opencv(monkeypatch) -> None:
    """A 640-byte 16-bit PNG whose IDAT claims 1 GiB: OpenCV allocated the 1 GiB; Pillow
    decodes the bytes that are there, and OpenCV is not asked."""
    import cv2

    from jeanscv.io import image

    path = REGRESSIONS / "image" / "png16_idat_claims_1gib.png"
    assert not image._png_chunks_inside(path.read_bytes())

    def no_opencv(*args, **kwargs):
        raise AssertionError("cv2.imdecode was called")

    monkeypatch.setattr(cv2, "imdecode", no_opencv)
    loaded = image.load_image(path)
    assert loaded.pixels.shape == (24, 32, 3)


def test_png_chunks_inside() -> None:
    import io

    from PIL import Image

    from jeanscv.io.image import _png_chunks_inside

    buffer = io.BytesIO()
    Image.new("RGB", (8, 8)).save(buffer, "PNG")
    data = buffer.getvalue()
    assert _png_chunks_inside(data)
    assert not _png_chunks_inside(data[:-1])  # IEND's CRC cut short


def test_damaged_tiff_is_one_line_on_the_command_line(tmp_path, run_cli, capfd) -> None:
    """libtiff's own complaint and Pillow's warning used to follow the jeanscv line."""
    bad = tmp_path / "scan.tif"
    bad.write_bytes((REGRESSIONS / "image" / "lzw_strip_libtiff_prints.tif").read_bytes())
    warned = tmp_path / "exif.tif"
    warned.write_bytes((REGRESSIONS / "image" / "exif_ifd_past_end_warns.tif").read_bytes())
    result = run_cli(bad, warned, "-q", "--iterations", "1", "--starts", "1", "-j", "1")
    assert capfd.readouterr().err == ""
    assert result.stderr.splitlines() == [
        f"jeanscv: {bad}: truncated or corrupt image",
        f"jeanscv: {warned}: not an image file (or an unsupported image format)",
    ]
    assert result.exit_code == 1


# ------------------------------------------------------------- the harness itself


def _target(run) -> Target:
    return Target("probe", lambda rng: None, run)


def test_harness_reports_what_breaks_the_contract() -> None:
    def raises_key_error(case):
        raise KeyError("x")

    def two_lines(case):
        raise JeansError("first\nsecond")

    def prints(case):
        os.write(2, b"libfoo: bad thing\n")

    def warns(case):
        warnings.warn("careful", UserWarning, stacklevel=1)

    assert violation(_target(lambda case: 1), None) is None
    assert violation(_target(lambda case: (_ for _ in ()).throw(JeansError("one line"))), None) is None
    assert violation(_target(raises_key_error), None) == "KeyError: 'x'"
    assert violation(_target(two_lines), None).startswith("JeansError reason is not one short line")
    assert violation(_target(prints), None) == "wrote to stderr: 'libfoo: bad thing'"
    assert violation(_target(warns), None) == "warned UserWarning: careful"


def test_generators_are_deterministic() -> None:
    for target in TARGETS.values():
        assert repr(target.generate(random.Random(7))) == repr(target.generate(random.Random(7)))
