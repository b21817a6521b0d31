"""Tests for jeanscv.paint.compositing and jeanscv.paint.denim: painting jeans on photos and the paper's figures.

The synthetic photo is a grey ellipse (a left-to-right gradient) on a plain light
background, with its exact mask; the jeans are the template scaled onto it so the
waistband and hems stick out of the ellipse, where clipping must stop the paint.
"""

from __future__ import annotations

import time
import tracemalloc

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from jeanscv.errors import JeansError
from jeanscv.fitting.garments import JEANS
from jeanscv.paint.compositing import FLAT_BLUE, composite_jeans, polygon_coverage_patch, render_silhouette_figure

H, W = 300, 400
CENTRE, AXES = (200.0, 150.0), (170.0, 85.0)
SCALE = 1.5  # template px -> image px: the jeans are 109 px wide, 198 px tall


def shoelace(v: np.ndarray) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


def jeans_vertices(scale: float = SCALE, centre: tuple[float, float] = (200.0, 150.0)) -> np.ndarray:
    t = JEANS.template
    return (t - t.mean(axis=0)) * scale + np.asarray(centre)


def photo(channels: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``(H, W, channels) uint8`` photo and its ``(H, W) bool`` ellipse mask."""
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    mask = ((xx - CENTRE[0]) / AXES[0]) ** 2 + ((yy - CENTRE[1]) / AXES[1]) ** 2 <= 1.0
    image = np.full((H, W, channels), 225, np.uint8)
    gradient = np.round(60 + 100 * xx / W).astype(np.uint8)
    for c in range(3):
        image[..., c] = np.where(mask, gradient, 225)
    if channels == 4:
        image[..., 3] = 255
    return image, mask


def changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.any(a != b, axis=2)


def luminance(image: np.ndarray) -> np.ndarray:
    return image[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114])


def full_coverage(vertices: np.ndarray) -> np.ndarray:
    return polygon_coverage_patch(vertices, H, W)


# ----------------------------------------------------------------------------- shape


@pytest.mark.parametrize("channels", [3, 4])
def test_output_matches_input_shape_and_dtype(channels: int) -> None:
    image, mask = photo(channels)
    out = composite_jeans(image, jeans_vertices(), mask=mask)
    assert out.shape == (H, W, channels) and out.dtype == np.uint8
    assert out is not image and np.array_equal(image, photo(channels)[0])  # input untouched
    if channels == 4:
        assert np.all(out[..., 3] == 255)  # opaque stays opaque


def test_pixels_outside_the_polygon_box_are_byte_identical() -> None:
    image, mask = photo()
    v = jeans_vertices()
    out = composite_jeans(image, v, mask=mask, clip=False)
    x0, y0 = np.floor(v.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(v.max(axis=0)).astype(int) + 2
    outside = np.ones((H, W), bool)
    outside[y0:y1, x0:x1] = False
    assert np.array_equal(out[outside], image[outside])
    # Inside the box too, only pixels the polygon touches change.
    assert not np.any(changed(out, image) & (full_coverage(v) == 0))


# ----------------------------------------------------------------------------- clipping


def test_clip_keeps_the_paint_on_the_object() -> None:
    image, mask = photo()
    v = jeans_vertices()
    cover = full_coverage(v)
    assert (cover * ~mask).sum() > 1000  # the legs really do stick out
    diff = changed(composite_jeans(image, v, mask=mask, clip=True), image)
    on_object = (diff & mask).sum() / diff.sum()
    assert on_object >= 0.95
    # Distance of every pixel to the object; the soft mask edge may reach 1 px out.
    off = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 5)
    assert off[diff].max() <= 2.0
    assert (diff & (off > 2.0)).sum() == 0
    # ... and it still covers the polygon on the object.
    assert diff[(cover == 1) & mask].mean() > 0.99


def test_without_clip_the_whole_polygon_is_painted() -> None:
    image, mask = photo()
    v = jeans_vertices()
    cover = full_coverage(v)
    diff = changed(composite_jeans(image, v, mask=mask, clip=False), image)
    outside_full = (cover == 1) & ~mask
    assert outside_full.sum() > 1000
    assert diff[outside_full].mean() > 0.99


def test_rgba_alpha_becomes_coverage_on_transparent_pixels() -> None:
    image = np.zeros((H, W, 4), np.uint8)  # fully transparent
    v = jeans_vertices()
    cover = full_coverage(v)
    # No mask given: clip uses the image's alpha, so nothing is painted.
    assert np.array_equal(composite_jeans(image, v), image)
    out = composite_jeans(image, v, style="flat", clip=False)
    np.testing.assert_array_equal(out[..., 3], np.rint(cover * 255).astype(np.uint8))
    inside = cover * 255 > 0.5  # alpha of at least one level
    assert np.all(out[inside][:, :3] == FLAT_BLUE)  # straight alpha: the colour is pure


def test_rgba_over_half_transparent_photo() -> None:
    image = np.zeros((4, 4, 4), np.uint8)
    image[..., 0] = 200
    image[..., 3] = 128  # alpha 0.502
    # A jeans-shaped polygon (8 vertices) covering pixel column 1 by half, rows 0..3 fully.
    v = np.array([[0.0, 4], [0, 0], [1.5, 0], [1.5, 4], [1.5, 4], [1.5, 4], [0, 4], [0, 4]])
    out = composite_jeans(image, v, style="flat", clip=False)
    a, below = 0.5, 128 / 255
    over = a + below * (1 - a)
    assert out[2, 1, 3] == round(over * 255)  # 192
    assert tuple(out[2, 1, :3]) == (round(200 * below * (1 - a) / over), 0, round(255 * a / over))
    assert tuple(out[2, 0]) == (0, 0, 255, 255)
    assert np.array_equal(out[:, 2:], image[:, 2:])


# ----------------------------------------------------------------------------- flat style


def test_flat_style_is_the_papers_blue_inside() -> None:
    image, mask = photo()
    v = jeans_vertices()
    cover = full_coverage(v)
    out = composite_jeans(image, v, mask=mask, style="flat", clip=False)
    assert (cover == 1).sum() > 10000
    assert np.all(out[cover == 1] == FLAT_BLUE)
    clipped = composite_jeans(image, v, mask=mask, style="flat", clip=True)
    interior = (cover == 1) & (cv2.erode(mask.astype(np.uint8), np.ones((3, 3))) > 0)
    assert np.all(clipped[interior] == FLAT_BLUE)


def test_flat_coverage_area_matches_the_shoelace_area() -> None:
    black = np.zeros((H, W, 3), np.uint8)
    # A rotated, non-axis-aligned fit with fractional vertices.
    angle = np.deg2rad(17)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    v = (jeans_vertices(1.2) - [200, 150]) @ rot.T + [203.3, 151.7]
    out = composite_jeans(black, v, style="flat", clip=False)
    assert out[..., :2].max() == 0
    painted_area = out[..., 2].astype(np.float64).sum() / 255.0
    assert painted_area == pytest.approx(shoelace(v), rel=0.005)
    # The coverage itself is exact to float precision.
    assert full_coverage(v).sum(dtype=np.float64) == pytest.approx(shoelace(v), rel=1e-5)


def test_polygon_partly_off_the_image_paints_the_visible_part() -> None:
    black = np.zeros((50, 60, 3), np.uint8)
    # An 'n'-shaped jeans from x = -10 to 20, y = 5 to 45 with a notch 0..4 wide at x in [3, 7].
    v = np.array([[-10, 45], [-10, 5], [20, 5], [20, 45], [7, 45], [7, 25], [3, 25], [3, 45]], float)
    out = composite_jeans(black, v, style="flat", clip=False)
    visible = 20 * 40 - 4 * 20  # x in [0, 20] x y in [5, 45] minus the notch
    assert (out[..., 2] == 255).sum() == visible
    assert out[..., 2].sum() == 255 * visible


# ----------------------------------------------------------------------------- denim


def denim_interior(mask: np.ndarray, v: np.ndarray, inset: int = 6) -> np.ndarray:
    """Pixels well inside both the jeans and the object."""
    inside = ((full_coverage(v) == 1) & mask).astype(np.uint8)
    return cv2.erode(inside, np.ones((2 * inset + 1, 2 * inset + 1), np.uint8)) > 0


def test_denim_is_indigo_blue() -> None:
    image, mask = photo()
    v = jeans_vertices()
    out = composite_jeans(image, v, mask=mask)
    region = denim_interior(mask, v)
    r, g, b = out[region].astype(np.float64).mean(axis=0)
    assert b > r + 40 and b > g + 20
    hue = cv2.cvtColor(np.uint8([[[round(r), round(g), round(b)]]]), cv2.COLOR_RGB2HSV_FULL)[0, 0, 0]
    hue_degrees = int(hue) * 360 / 256
    assert 205 <= hue_degrees <= 235  # indigo, not cyan or violet


def test_denim_has_a_diagonal_twill() -> None:
    image, mask = photo()
    v = jeans_vertices()
    out = composite_jeans(image, v, mask=mask)
    region = denim_interior(mask, v)
    lum = luminance(out)
    assert lum[region].std() > 8.0
    # Remove shading; the weave is the fine detail left.
    detail = lum - cv2.GaussianBlur(lum, (0, 0), 3)
    # For pixel (y, x): its up-right neighbour (y - 1, x + 1) lies along a right-hand
    # twill ridge ("/"), its down-right neighbour (y + 1, x + 1) across it.
    centre, up_right, down_right = detail[1:-1, :-1], detail[:-2, 1:], detail[2:, 1:]
    valid = region[1:-1, :-1] & region[:-2, 1:] & region[2:, 1:]
    corr_rising = np.corrcoef(centre[valid], up_right[valid])[0, 1]
    corr_falling = np.corrcoef(centre[valid], down_right[valid])[0, 1]
    assert corr_rising > corr_falling + 0.3


def test_denim_has_dark_seams_with_golden_stitching() -> None:
    image, mask = photo()
    v = jeans_vertices()
    out = composite_jeans(image, v, mask=mask).astype(np.int64)
    unit = 72.4 * SCALE
    # Outer left seam (edge 0) is the line x = v[0, 0]; stay clear of waistband and hem.
    x_seam = v[0, 0]
    rows = slice(int(v[1, 1] + 0.3 * unit), int(v[1, 1] + 0.9 * unit))
    groove = out[rows, int(x_seam) : int(x_seam + 0.01 * unit) + 1]
    panel = out[rows, int(x_seam + 0.15 * unit) : int(x_seam + 0.25 * unit)]
    assert luminance(groove).mean() < 0.8 * luminance(panel).mean()
    beside = out[rows, int(x_seam) : int(x_seam + 0.05 * unit)]
    golden = beside[..., 0] > beside[..., 2] + 25
    assert golden.any(axis=1).mean() > 0.5  # dashes: most rows cross a stitch
    panel_golden = panel[..., 0] > panel[..., 2] + 25
    assert panel_golden.mean() < 0.01


def test_denim_is_shaded_by_the_photo() -> None:
    image, mask = photo()
    v = jeans_vertices()
    dark_side = image.copy()
    dark_side[:, :200] = (dark_side[:, :200] * 0.5).astype(np.uint8)
    region = denim_interior(mask, v)
    left, right = region.copy(), region.copy()
    left[:, 190:] = False
    right[:, :210] = False
    lum = luminance(composite_jeans(dark_side, v, mask=mask))
    lum_even = luminance(composite_jeans(image, v, mask=mask))
    # Halving the object's left half darkens the jeans there relative to the right.
    ratio_dark = lum[left].mean() / lum[right].mean()
    ratio_even = lum_even[left].mean() / lum_even[right].mean()
    assert ratio_dark < 0.8 * ratio_even


def test_denim_is_deterministic_per_seed() -> None:
    image, mask = photo()
    v = jeans_vertices()
    a = composite_jeans(image, v, mask=mask, seed=3)
    b = composite_jeans(image, v, mask=mask, seed=3)
    c = composite_jeans(image, v, mask=mask, seed=4)
    assert np.array_equal(a, b)
    assert changed(a, c).sum() > 1000


def test_details_scale_with_the_garment() -> None:
    """The same jeans at twice the resolution look the same, not twice as fine."""
    small_img, small_mask = photo()
    big_img = cv2.resize(small_img, (2 * W, 2 * H), interpolation=cv2.INTER_NEAREST)
    big_mask = cv2.resize(small_mask.astype(np.uint8), (2 * W, 2 * H), interpolation=cv2.INTER_NEAREST) > 0
    v = jeans_vertices()
    small = composite_jeans(small_img, v, mask=small_mask, clip=False)
    big = composite_jeans(big_img, 2 * v, mask=big_mask, clip=False)
    down = cv2.resize(big, (W, H), interpolation=cv2.INTER_AREA)
    region = denim_interior(small_mask | True, v, inset=3)
    # Per-pixel noise differs, but the seams, waistband and stitches sit in the same
    # places: blurred, the two images agree closely.
    blur_small = cv2.GaussianBlur(luminance(small), (0, 0), 2.0)
    blur_big = cv2.GaussianBlur(luminance(down), (0, 0), 2.0)
    assert np.corrcoef(blur_small[region], blur_big[region])[0, 1] > 0.8


def test_large_photo_costs_only_the_jeans_box() -> None:
    """A 6000 x 4000 photo: correct, and its memory scales with the jeans, not the photo."""
    big = np.full((4000, 6000, 3), 90, np.uint8)
    v = jeans_vertices(scale=8.0, centre=(3000.0, 2000.0))  # 580 x 1055 px jeans
    x0, y0 = np.floor(v.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(v.max(axis=0)).astype(int) + 2
    box_pixels = (x1 - x0) * (y1 - y0)
    tracemalloc.start()
    start = time.perf_counter()
    out = composite_jeans(big, v)
    seconds = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"6000x4000 composite: {seconds:.2f} s, peak {peak / 2**20:.0f} MiB (box {box_pixels / 1e6:.2f} MP)")
    for outside in (out[:y0], out[y1:], out[y0:y1, :x0], out[y0:y1, x1:]):
        assert (outside == 90).all()
    centre = out[1900:2100, 2800:2860].reshape(-1, 3).mean(axis=0)
    assert centre[2] > centre[0] + 40
    # The output copy, plus a bounded number of float planes over the box only.
    assert peak < big.nbytes + 80 * box_pixels


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "image, vertices, kwargs, message",
    [
        (np.zeros((10, 10, 3), np.float32), None, {}, "uint8"),
        (np.zeros((10, 10), np.uint8), None, {}, "H x W x 3"),
        (np.zeros((10, 10, 3), np.uint8), np.zeros((7, 2)), {}, "shape (8, 2)"),
        (np.zeros((10, 10, 3), np.uint8), np.full((8, 2), np.nan), {}, "not finite"),
        (np.zeros((10, 10, 3), np.uint8), np.full((8, 2), 1e12), {}, "too far"),
        (np.zeros((10, 10, 3), np.uint8), None, {"mask": np.ones((9, 10), bool)}, "mask shape"),
        (np.zeros((10, 10, 3), np.uint8), None, {"style": "acid-wash"}, "unknown style"),
    ],
)
def test_bad_input_raises_jeans_error(image, vertices, kwargs, message) -> None:
    if vertices is None:
        vertices = jeans_vertices(0.05, (5.0, 5.0))
    with pytest.raises(JeansError, match=message.replace("(", r"\(").replace(")", r"\)")):
        composite_jeans(image, vertices, **kwargs)


def test_polygon_off_the_image_changes_nothing() -> None:
    image, mask = photo()
    out = composite_jeans(image, jeans_vertices(centre=(-500.0, -500.0)), mask=mask)
    assert np.array_equal(out, image)


# ----------------------------------------------------------------------------- figures


def test_silhouette_figure_exact_colours() -> None:
    sil = np.zeros((6, 8), np.float32)
    sil[1:5, 0:3] = 1.0
    sil[0, 0] = 0.5
    # An 'n': x in [4, 7.5] x y in [1, 5] minus the notch x in [5, 6] x y in [3, 5].
    v = np.array([[4, 5], [4, 1], [7.5, 1], [7.5, 5], [6, 5], [6, 3], [5, 3], [5, 5]], float)
    fig = render_silhouette_figure(sil, v)
    assert fig.shape == (6, 8, 3) and fig.dtype == np.uint8
    white, black, blue = (255, 255, 255), (0, 0, 0), (0, 0, 255)
    assert tuple(fig[0, 7]) == white
    assert tuple(fig[2, 1]) == black
    assert tuple(fig[0, 0]) == (128, 128, 128)  # half coverage, rounded half to even
    for r, c in [(1, 4), (1, 5), (1, 6), (2, 5), (4, 4), (4, 6)]:
        assert tuple(fig[r, c]) == blue
    assert tuple(fig[3, 5]) == white  # the notch between the legs
    assert tuple(fig[2, 7]) == (128, 128, 255)  # half-covered column over white
    # Blue over black silhouette stays blue; with no jeans, only the silhouette.
    sil[1:5, 4:7] = 1.0
    assert tuple(render_silhouette_figure(sil, v)[1, 4]) == blue
    bare = render_silhouette_figure(sil, None)
    assert tuple(bare[1, 4]) == black and tuple(bare[0, 7]) == white


def test_silhouette_figure_rejects_bad_input() -> None:
    with pytest.raises(JeansError, match="H x W"):
        render_silhouette_figure(np.zeros((4, 4, 3)), None)
    with pytest.raises(JeansError, match="shape"):
        render_silhouette_figure(np.zeros((4, 4)), np.zeros((3, 2)))


@settings(max_examples=40, deadline=None)
@given(
    vertices=arrays(np.float64, (8, 2), elements=st.floats(-40, 120, allow_nan=False)),
    channels=st.sampled_from([3, 4]),
    style=st.sampled_from(["denim", "flat"]),
    clip=st.booleans(),
)
def test_any_polygon_composites_without_error(vertices, channels, style, clip) -> None:
    """Self-crossing, collapsed or off-image fits still composite, touching only their box."""
    image = np.full((60, 80, channels), 200, np.uint8)
    mask = np.zeros((60, 80), bool)
    mask[10:50, 10:70] = True
    out = composite_jeans(image, vertices, mask=mask, style=style, clip=clip)
    assert out.shape == image.shape and out.dtype == np.uint8
    x0, y0 = np.floor(vertices.min(axis=0)).astype(int) - 2
    x1, y1 = np.ceil(vertices.max(axis=0)).astype(int) + 2
    outside = np.ones((60, 80), bool)
    outside[max(y0, 0) : max(y1, 0), max(x0, 0) : max(x1, 0)] = False
    assert np.array_equal(out[outside], image[outside])


def test_large_garment_boxes_render_reduced_and_paint_in_strips(monkeypatch):
    """Boxes over DENIM_MAX_PIXELS take the bounded-memory path: same clip guarantees,
    denim colours, and strips that join without seams."""
    import jeanscv.paint.compositing as compositing

    rng = np.random.default_rng(3)
    image = (90 + 60 * rng.random((300, 400, 3))).astype(np.uint8)
    mask = np.zeros((300, 400), bool)
    mask[20:290, 40:330] = True
    waist = JEANS.template[list(JEANS.waist)].mean(axis=0)
    vertices = (JEANS.template - waist) * 2.0 + [200.0, 40.0]
    monkeypatch.setattr(compositing, "DENIM_MAX_PIXELS", 5_000)
    monkeypatch.setattr(compositing, "_STRIP_PIXELS", 400 * 37)  # many strips, odd height
    strips = compositing.composite_jeans(image, vertices, JEANS, mask)
    monkeypatch.setattr(compositing, "_STRIP_PIXELS", 1 << 24)  # one strip
    whole = compositing.composite_jeans(image, vertices, JEANS, mask)
    # Float sums over different strips may round a byte the other way, nothing more.
    assert np.abs(strips.astype(int) - whole.astype(int)).max() <= 1
    changed = np.any(strips != image, axis=-1)
    assert changed.sum() > 5_000
    assert (changed & mask).sum() / changed.sum() >= 0.95
    painted = strips[changed].astype(float)
    assert painted[:, 2].mean() > painted[:, 0].mean() + 15


@pytest.mark.parametrize("channels", [3, 4])
def test_denim_bytes_do_not_depend_on_the_work_windows(monkeypatch, channels: int) -> None:
    """The per-pixel work runs in windows around the painted pixels; how the box is cut
    into them (and so how far each strip's noise is drawn) must not change a byte."""
    import jeanscv.paint.denim as denim

    rng = np.random.default_rng(7)
    height, width = 700, 560  # a box of three noise strips
    image = (60 + 120 * rng.random((height, width, channels))).astype(np.uint8)
    if channels == 4:
        image[..., 3] = (255 * rng.random((height, width)) ** 0.2).astype(np.uint8)
    yy, xx = np.mgrid[0:height, 0:width] + 0.5
    # An object narrower than the jeans, with a hole between the legs, so windows
    # start, stop and split inside the box.
    mask = ((xx - 280) / 200) ** 2 + ((yy - 350) / 330) ** 2 <= 1.0
    mask &= ~((np.abs(xx - 280) < 40) & (yy > 420))
    vertices = jeans_vertices(scale=4.0, centre=(280.0, 350.0))
    reference = composite_jeans(image, vertices, mask=mask, seed=2)
    assert changed(reference, image).sum() > 50_000
    for rows, gap in ((4, 1), (8, 10_000), (256, 128)):
        monkeypatch.setattr(denim, "_WINDOW_ROWS", rows)
        monkeypatch.setattr(denim, "_WINDOW_GAP", gap)
        assert np.array_equal(composite_jeans(image, vertices, mask=mask, seed=2), reference)
