"""The photo pipeline end to end: decode -> segment -> frame -> fit -> composite."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from jeanscv.api import apply_jeans, silhouette_from_drawing
from testkit.synthetic import silhouette_zoo

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
pytestmark = pytest.mark.usefixtures("cut_once")  # the same photos' hypotheses, cut once (conftest.py)


def synthetic_photo(height: int = 300, width: int = 400) -> tuple[np.ndarray, np.ndarray]:
    """A textured brown 'dog' on a textured green ground, and its mask."""
    rng = np.random.default_rng(5)
    shape = silhouette_zoo(["dog"])["dog"]
    mask = np.zeros((height, width), bool)
    small = np.asarray(Image.fromarray((shape * 255).astype(np.uint8)).resize((height, height))) >= 128
    mask[:, (width - height) // 2 : (width - height) // 2 + height] = small
    ground = np.stack(
        [
            60 + 20 * rng.random((height, width)),
            150 + 30 * rng.random((height, width)),
            50 + 20 * rng.random((height, width)),
        ],
        -1,
    )
    fur = np.stack(
        [
            150 + 30 * rng.random((height, width)),
            100 + 20 * rng.random((height, width)),
            60 + 20 * rng.random((height, width)),
        ],
        -1,
    )
    photo = np.where(mask[..., None], fur, ground).astype(np.uint8)
    return photo, mask


def jpeg_bytes(pixels: np.ndarray, orientation: int | None = None) -> bytes:
    image = Image.fromarray(pixels)
    exif = Image.Exif()
    if orientation is not None:
        exif[0x0112] = orientation
    buffer = io.BytesIO()
    image.save(buffer, "JPEG", quality=95, exif=exif.tobytes())
    return buffer.getvalue()


def test_composite_stays_on_the_object_and_looks_like_denim(tmp_path):
    photo, mask = synthetic_photo()
    result = apply_jeans(photo, iterations=40)
    assert result.kind == "photo" and result.image.shape == photo.shape
    changed = np.any(result.image != photo, axis=-1)
    assert changed.sum() > 0.1 * mask.sum()
    assert (changed & mask).sum() / changed.sum() >= 0.95
    painted = result.image[changed].astype(float)
    # Indigo on a brown object: the median, since golden stitching and seams (a large
    # share of small jeans) pull the mean towards red.
    assert np.median(painted[:, 2] - painted[:, 0]) > 25
    assert painted.mean(axis=-1).std() > 8  # textured, not one flat colour


def test_any_array_like_photo_is_taken_as_its_array():
    """A Pillow image (or anything numpy turns into a uint8 image) gives the same
    result as its array: only paths are opened as files."""
    photo, _ = synthetic_photo(120, 160)
    from_array = apply_jeans(photo, iterations=5)
    from_pillow = apply_jeans(Image.fromarray(photo), iterations=5)
    assert np.array_equal(from_pillow.image, from_array.image)
    assert np.array_equal(from_pillow.fit.vertices, from_array.fit.vertices)


def test_report_says_why_auto_took_its_subject():
    photo, mask = synthetic_photo()
    result = apply_jeans(photo, iterations=10, detector="none")  # classical finding's reasons
    subject = result.report()["subject"]
    details = result.silhouette.details
    keys = ("chosen", "reason", "consensus", "subject", "kind", "uncertain", "doubts")
    assert subject == {key: details[key] for key in keys}
    assert subject["chosen"] in subject["reason"] and subject["uncertain"] is False and subject["doubts"] == []
    assert subject["subject"] == "auto"
    assert subject["consensus"] == details["candidates"][subject["chosen"]]["consensus"] >= 0.5
    # A given mask is not a choice: nothing to explain.
    assert "subject" not in apply_jeans(photo, mask=mask, iterations=10).report()


def test_exif_orientation_6_gives_the_displayed_picture_with_jeans_in_place(tmp_path):
    photo, _ = synthetic_photo()
    upright = tmp_path / "upright.jpg"
    upright.write_bytes(jpeg_bytes(photo))
    # Orientation 6: the stored pixels are the displayed ones turned 90 degrees anticlockwise.
    stored = np.ascontiguousarray(np.rot90(photo, 1))
    turned = tmp_path / "turned.jpg"
    turned.write_bytes(jpeg_bytes(stored, orientation=6))

    # Fits run to convergence: after 40 steps two masks that differ by JPEG noise (IoU
    # 0.99) can still leave the jeans 10 px apart; after 100 they agree within 1-2 px.
    a = apply_jeans(upright, iterations=100)
    b = apply_jeans(turned, iterations=100)
    assert b.image.shape == photo.shape  # displayed size, not stored size
    jeans_a = np.asarray(a.report()["vertices_image"])
    jeans_b = np.asarray(b.report()["vertices_image"])
    assert np.abs(jeans_a - jeans_b).max() < 6.0  # same place, up to JPEG noise


def test_sample_raw_file_decodes_and_gets_jeans():
    result = apply_jeans(SAMPLES / "coffee.dng", iterations=30)
    assert result.source.is_raw and result.kind == "photo"
    assert result.image.shape == result.source.pixels.shape
    assert np.any(result.image != result.source.pixels)


def test_silhouette_drawings_are_told_from_photos():
    photo, mask = synthetic_photo()
    drawing = np.where(mask[..., None], 0, 255).astype(np.uint8).repeat(3, axis=-1)[..., :3]
    assert silhouette_from_drawing(photo) is None
    alpha = silhouette_from_drawing(drawing)
    assert alpha is not None and np.array_equal(alpha >= 0.5, mask)
    inverted = 255 - drawing
    assert np.array_equal(silhouette_from_drawing(inverted) >= 0.5, mask)
    cutout = np.dstack([photo, np.where(mask, 255, 0).astype(np.uint8)])
    assert silhouette_from_drawing(cutout) is None  # textured under its alpha: a photo


@pytest.mark.parametrize("name", ["cat.jpg", "horse_cutout.png", "rocket_exif6.jpg"])
def test_samples_keep_their_displayed_size(name):
    result = apply_jeans(SAMPLES / name, iterations=10)
    assert result.image.shape[:2] == result.source.pixels.shape[:2]
    assert result.image.shape[1::-1] == tuple(result.source.original_size)
