"""A small torch executor for TensorFlow.js graph models (``model.json`` + ``.bin``).

The model JSON holds a TensorFlow ``GraphDef`` as JSON (``modelTopology``) and a
``weightsManifest`` that lays every ``Const`` out, in order, in the ``.bin`` file; a weight
may be stored quantized (``float16``, or ``uint8``/``uint16`` with a scale and minimum) and
is read back as float32 here.

:class:`GraphExecutor` keeps TensorFlow's semantics exactly (tensors are logically NHWC, as
in the graph) and builds the graph once into a list of closures: nodes whose inputs are all
constants are folded at build time, weights are converted to torch's layouts once, and a
call only runs the closures. A graph's ``Transpose`` nodes become ``permute`` views, so
they cost nothing; convolutions see NHWC data as a channels-last NCHW view.

Ops (:data:`OPS`): Conv2D, _FusedConv2D and (Fused)DepthwiseConv2dNative (VALID/SAME
padding, fused BiasAdd then Relu/Relu6/LeakyRelu), MaxPool (VALID/SAME), Add/AddV2, Sub,
Mul, Relu, Relu6, LeakyRelu, Sigmoid, Mean, ConcatV2, Reshape, Transpose, Pad, PadV2,
SplitV, ResizeBilinear (both TF corner conventions), Identity, and, for constant folding
only, SparseToDense and Cast.
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

Tensor = torch.Tensor

_DTYPES = {"float32": np.float32, "int32": np.int32, "bool": np.bool_}
_QUANT = {"float16": np.float16, "uint8": np.uint8, "uint16": np.uint16}


def read_weights(model: dict[str, Any], bin_bytes: bytes) -> dict[str, np.ndarray]:
    """Every weight of ``model``'s manifest, by name, dequantized (float weights as float32)."""
    weights: dict[str, np.ndarray] = {}
    offset = 0
    for group in model["weightsManifest"]:
        for spec in group["weights"]:
            shape = [int(d) for d in spec["shape"]]
            count = math.prod(shape)
            quant = spec.get("quantization")
            stored = np.dtype(_QUANT[quant["dtype"]] if quant else _DTYPES[spec["dtype"]])
            size = count * stored.itemsize
            if offset + size > len(bin_bytes):
                raise ValueError(f"weights file too short for {spec['name']}")
            raw = np.frombuffer(bin_bytes, stored, count, offset).reshape(shape)
            offset += size
            if quant and quant["dtype"] != "float16":
                # affine quantization: value = q * scale + min
                raw = raw.astype(np.float32) * quant["scale"] + quant["min"]
            weights[spec["name"]] = raw.astype(_DTYPES[spec["dtype"]])
    return weights


def _attr(node: dict[str, Any], key: str, default: Any = None) -> Any:
    """One attribute of a GraphDef node, decoded (bytes as str, lists as lists of int)."""
    value = node.get("attr", {}).get(key)
    if value is None:
        return default
    if "s" in value:
        return base64.b64decode(value["s"]).decode()
    if "list" in value:
        items = value["list"]
        if "i" in items:
            return [int(i) for i in items["i"]]
        if "s" in items:
            return [base64.b64decode(s).decode() for s in items["s"]]
        return []
    if "f" in value:
        return float(value["f"])
    if "i" in value:
        return int(value["i"])
    if "b" in value:
        return bool(value["b"])
    return value


def same_padding(size: int, kernel: int, stride: int) -> tuple[int, int]:
    """TF 'SAME' padding (before, after) of one axis: the extra pixel goes after."""
    out = -(-size // stride)
    total = max((out - 1) * stride + kernel - size, 0)
    return total // 2, total - total // 2


def _pad_for(x: Tensor, padding: str, kernel: tuple[int, int], stride: tuple[int, int]) -> tuple[int, int, int, int]:
    """F.pad widths (left, right, top, bottom) of an NCHW tensor for TF padding mode."""
    if padding == "VALID":
        return (0, 0, 0, 0)
    top, bottom = same_padding(x.shape[2], kernel[0], stride[0])
    left, right = same_padding(x.shape[3], kernel[1], stride[1])
    return (left, right, top, bottom)


def _activation(name: str, alpha: float) -> Callable[[Tensor], Tensor] | None:
    """The fused activation after a convolution (None for none)."""
    if name == "Relu":
        return torch.relu
    if name == "Relu6":
        return lambda x: torch.clamp(x, 0.0, 6.0)
    if name == "LeakyRelu":
        return lambda x: F.leaky_relu(x, alpha)
    if name == "Sigmoid":
        return torch.sigmoid
    raise NotImplementedError(f"fused activation {name}")


def _conv(node: dict[str, Any], consts: list[Tensor | None]) -> Callable[..., Tensor]:
    """Conv2D / _FusedConv2D / (Fused)DepthwiseConv2dNative on an NHWC input."""
    op = node["op"]
    if _attr(node, "data_format", "NHWC") != "NHWC" or any(d != 1 for d in _attr(node, "dilations", [1, 1, 1, 1])):
        raise NotImplementedError(f"{node['name']}: only NHWC, undilated convolutions")
    kernel = consts[1]
    if kernel is None:
        raise NotImplementedError(f"{node['name']}: a convolution's filter must be constant")
    kh, kw, cin, mult = kernel.shape
    depthwise = "Depthwise" in op
    if depthwise:  # TF HWCM, output channel c*M + m -> torch [C*M, 1, kh, kw], groups=C
        weight = kernel.permute(2, 3, 0, 1).reshape(cin * mult, 1, kh, kw)
        groups = cin
    else:  # TF HWIO -> torch OIHW
        weight = kernel.permute(3, 2, 0, 1)
        groups = 1
    weight = weight.contiguous(memory_format=torch.channels_last)
    fused = _attr(node, "fused_ops", []) if op.startswith(("_Fused", "Fused")) else []
    bias = None
    if fused and fused[0] == "BiasAdd":
        bias = consts[2]
        fused = fused[1:]
    elif fused:
        raise NotImplementedError(f"{node['name']}: fused ops {fused}")
    act = _activation(fused[0], _attr(node, "leakyrelu_alpha", 0.2)) if fused else None
    strides = _attr(node, "strides", [1, 1, 1, 1])
    stride = (strides[1], strides[2])
    padding = _attr(node, "padding")
    if padding not in ("SAME", "VALID"):
        raise NotImplementedError(f"{node['name']}: padding {padding}")

    def run(x: Tensor, *_: Tensor) -> Tensor:
        x = x.permute(0, 3, 1, 2)
        pad = _pad_for(x, padding, (kh, kw), stride)
        if pad[0] == pad[1] and pad[2] == pad[3]:  # symmetric: let the convolution pad
            y = F.conv2d(x, weight, bias, stride, (pad[2], pad[0]), 1, groups)
        else:
            y = F.conv2d(F.pad(x, pad), weight, bias, stride, 0, 1, groups)
        if act is not None:
            y = act(y)
        return y.permute(0, 2, 3, 1)

    return run


def _max_pool(node: dict[str, Any], consts: list[Tensor | None]) -> Callable[..., Tensor]:
    """MaxPool (NHWC): SAME pads with -inf, as TF ignores padded cells."""
    ksize, strides = _attr(node, "ksize"), _attr(node, "strides")
    kernel, stride = (ksize[1], ksize[2]), (strides[1], strides[2])
    padding = _attr(node, "padding")

    def run(x: Tensor) -> Tensor:
        x = x.permute(0, 3, 1, 2)
        pad = _pad_for(x, padding, kernel, stride)
        if any(pad):
            x = F.pad(x, pad, value=-math.inf)
        return F.max_pool2d(x, kernel, stride).permute(0, 2, 3, 1)

    return run


def _legacy_index(size_in: int, size_out: int) -> tuple[Tensor, Tensor, Tensor]:
    """TF ResizeBilinear without half-pixel centers or aligned corners: source
    coordinate ``out * in/out``; lower and upper indices and the upper weight."""
    src = torch.arange(size_out, dtype=torch.float64) * (size_in / size_out)
    lower = torch.floor(src).long().clamp(max=size_in - 1)
    upper = (lower + 1).clamp(max=size_in - 1)
    return lower, upper, (src - lower).float()


def resize_bilinear(x: Tensor, size: Sequence[int], align_corners: bool, half_pixel: bool) -> Tensor:
    """TF ResizeBilinear of an NHWC tensor to ``size`` (height, width)."""
    height, width = int(size[0]), int(size[1])
    if half_pixel or align_corners:
        # torch's conventions are TF's: align_corners=False is half-pixel centers
        y = F.interpolate(x.permute(0, 3, 1, 2), (height, width), mode="bilinear", align_corners=align_corners)
        return y.permute(0, 2, 3, 1)
    lo, hi, w = _legacy_index(x.shape[1], height)
    x = x[:, lo] + (x[:, hi] - x[:, lo]) * w.view(1, -1, 1, 1)
    lo, hi, w = _legacy_index(x.shape[2], width)
    return x[:, :, lo] + (x[:, :, hi] - x[:, :, lo]) * w.view(1, 1, -1, 1)


def _pad_widths(paddings: Tensor) -> list[int]:
    """TF paddings [[before, after], ...] (first axis first) -> F.pad's last-axis-first list."""
    widths: list[int] = []
    for before, after in reversed(paddings.tolist()):
        widths += [int(before), int(after)]
    return widths


def _sparse_to_dense(indices: Tensor, shape: Tensor, values: Tensor, default: Tensor) -> Tensor:
    """SparseToDense (constant folding only)."""
    out = torch.full([int(s) for s in shape.reshape(-1).tolist()], default.item(), dtype=values.dtype)
    # indices: a scalar, [N] (1-D output) or [N, rank]
    flat = indices.reshape(-1, indices.shape[-1]) if indices.dim() == 2 else indices.reshape(-1, 1)
    for k, index in enumerate(flat.tolist()):
        out[tuple(index)] = values.reshape(-1)[k if values.numel() > 1 else 0]
    return out


def _split(x: Tensor, sizes: Tensor, axis: Tensor) -> tuple[Tensor, ...]:
    """SplitV: one size may be -1 (the rest)."""
    dim = int(axis) % x.dim()
    parts = [int(s) for s in sizes.tolist()]
    if -1 in parts:
        parts[parts.index(-1)] = x.shape[dim] - (sum(parts) + 1)
    return tuple(torch.split(x, parts, dim))


def _simple(node: dict[str, Any]) -> Callable[..., Any]:
    """The ops whose attributes need no preparation."""
    op = node["op"]
    if op in ("Add", "AddV2"):
        return torch.add
    if op == "Sub":
        return torch.sub
    if op == "Mul":
        return torch.mul
    if op == "Relu":
        return torch.relu
    if op == "Relu6":
        return lambda x: torch.clamp(x, 0.0, 6.0)
    if op == "LeakyRelu":
        alpha = _attr(node, "alpha", 0.2)
        return lambda x: F.leaky_relu(x, alpha)
    if op == "Sigmoid":
        return torch.sigmoid
    if op == "Identity":
        return lambda x: x
    if op == "Transpose":
        return lambda x, perm: x.permute(*[int(p) for p in perm.tolist()])
    if op == "Reshape":
        return lambda x, shape: x.reshape([int(s) for s in shape.tolist()])
    if op == "ConcatV2":
        return lambda *xs: torch.cat(xs[:-1], int(xs[-1]) % xs[0].dim())
    if op == "Mean":
        keep = bool(_attr(node, "keep_dims", False))
        return lambda x, axes: x.mean(dim=[int(a) % x.dim() for a in axes.reshape(-1).tolist()], keepdim=keep)
    if op == "Pad":
        return lambda x, paddings: F.pad(x, _pad_widths(paddings))
    if op == "PadV2":
        return lambda x, paddings, value: F.pad(x, _pad_widths(paddings), value=float(value))
    if op == "SplitV":
        return _split
    if op == "ResizeBilinear":
        corners, half = bool(_attr(node, "align_corners", False)), bool(_attr(node, "half_pixel_centers", False))
        return lambda x, size: resize_bilinear(x, size.tolist(), corners, half)
    if op == "SparseToDense":
        return _sparse_to_dense
    if op == "Cast":
        dst = {"DT_FLOAT": torch.float32, "DT_INT32": torch.int32}[node["attr"]["DstT"]["type"]]
        return lambda x: x.to(dst)
    raise NotImplementedError(f"op {op} ({node['name']})")


#: The ops :class:`GraphExecutor` runs (those only for constant folding included).
OPS = (
    "Conv2D _FusedConv2D DepthwiseConv2dNative FusedDepthwiseConv2dNative MaxPool Add AddV2 Sub Mul Relu "
    "Relu6 LeakyRelu Sigmoid Identity Transpose Reshape ConcatV2 Mean Pad PadV2 SplitV ResizeBilinear "
    "SparseToDense Cast"
).split()


def _source(ref: str) -> tuple[str, int]:
    """A node input 'name:k' -> (name, output index); control inputs are '^name'."""
    name, _, index = ref.partition(":")
    return name, int(index or 0)


class GraphExecutor:
    """A tfjs graph model, pruned to ``outputs`` and built once into closures.

    Call it with the input tensors (in ``inputs`` order, float32, the graph's own layout);
    it returns the ``outputs`` tensors.
    """

    def __init__(self, model: dict[str, Any], weights: dict[str, np.ndarray], inputs: list[str], outputs: list[str]):
        nodes = {node["name"]: node for node in model["modelTopology"]["node"]}
        self.inputs, self.outputs = inputs, outputs
        order = self._order(nodes, outputs)
        slot: dict[tuple[str, int], int] = {}
        consts: dict[tuple[str, int], Tensor] = {}
        self.steps: list[tuple[Callable[..., Any], list[int], list[int]]] = []
        #: Slot -> a constant operand that a closure reads (not folded: its other inputs vary).
        self.bound: dict[int, Tensor] = {}
        for name in inputs:
            slot[(name, 0)] = len(slot)
        for name in order:
            node = nodes[name]
            refs = [_source(r) for r in node.get("input", []) if not r.startswith("^")]
            if node["op"] == "Const":
                consts[(name, 0)] = torch.from_numpy(np.array(weights[name]))
                continue
            if node["op"] == "Placeholder":
                if (name, 0) not in slot:
                    raise ValueError(f"graph input {name} not given")
                continue
            const_in = [consts.get(ref) for ref in refs]
            if node["op"] in ("Conv2D", "_FusedConv2D", "DepthwiseConv2dNative", "FusedDepthwiseConv2dNative"):
                fn, refs = _conv(node, const_in), refs[:1]
            elif node["op"] == "MaxPool":
                fn = _max_pool(node, const_in)
            else:
                fn = _simple(node)
            if all(c is not None for c in const_in):  # constant folding
                with torch.inference_mode():
                    result = fn(*const_in)
                for k, value in enumerate(result if isinstance(result, tuple) else (result,)):
                    consts[(name, k)] = value
                continue
            # A constant operand that the closure still needs travels with it.
            args: list[int] = []
            for ref, const in zip(refs, const_in):
                if const is not None and ref not in slot:
                    slot[ref] = len(slot)
                    self.bound[slot[ref]] = const
                args.append(slot[ref])
            outs = [len(slot) + k for k in range(self._arity(node))]
            for k, index in enumerate(outs):
                slot[(name, k)] = index
            self.steps.append((fn, args, outs))
        self.size = len(slot)
        self.result = [slot[_source(ref)] for ref in outputs]

    @staticmethod
    def _arity(node: dict[str, Any]) -> int:
        """How many outputs a node has."""
        return int(_attr(node, "num_split", 1)) if node["op"] == "SplitV" else 1

    @staticmethod
    def _order(nodes: dict[str, dict[str, Any]], outputs: list[str]) -> list[str]:
        """The nodes ``outputs`` need, each after its inputs (iterative depth-first)."""
        order: list[str] = []
        seen: set[str] = set()
        stack = [(_source(ref)[0], False) for ref in reversed(outputs)]
        while stack:
            name, done = stack.pop()
            if done:
                order.append(name)
                continue
            if name in seen:
                continue
            seen.add(name)
            stack.append((name, True))
            for ref in reversed(nodes[name].get("input", [])):
                source = _source(ref.lstrip("^"))[0]
                if source not in seen:
                    stack.append((source, False))
        return order

    def __call__(self, *inputs: Tensor) -> list[Tensor]:
        values: list[Any] = [None] * self.size
        values[: len(inputs)] = inputs
        for index, const in self.bound.items():
            values[index] = const
        for fn, args, outs in self.steps:
            result = fn(*[values[i] for i in args])
            if len(outs) == 1:
                values[outs[0]] = result
            else:
                for index, value in zip(outs, result):
                    values[index] = value
        return [values[i] for i in self.result]


def load_graph(json_path: Path, bin_path: Path, inputs: list[str], outputs: list[str]) -> GraphExecutor:
    """Read a tfjs graph model's files and build its executor."""
    model = json.loads(Path(json_path).read_text())
    weights = read_weights(model, Path(bin_path).read_bytes())
    return GraphExecutor(model, weights, inputs, outputs)
