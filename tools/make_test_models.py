#!/usr/bin/env python3
"""Small ONNX models for kflex's Rust tests of ONNX Runtime, and their outputs.

Until the trained models land (issue 10), the Rust side is tested on models
built here with the `onnx` package, with weights from a fixed seed:

* `kbjae_test.onnx`: KBJAE's contract (input `theta_and_rate` [N, 2] in deg
  and deg/s, output `theta_error` [N, 1] in deg), Table II's shape at a small
  width: input scaling baked in, 2 -> 16 -> 16 -> 1 with LeakyReLU(0.01).
  Beside it `kbjae_test.card.json` (its SHA-256, as a real model card has)
  and `kbjae_test.expected.json`: inputs and numpy's float64 outputs.
* `kbjae_backlash_test.onnx`: KBJAE's contract with the error a trained
  KBJAE learns on a backlash-like plant, written down instead of learnt:
  `theta_error = -(BACKLASH_DEG / 2) * clip(rate / RATE_SCALE, -1, 1)` (the
  joint lags the command by half the loop's width, behind on the way up and
  ahead on the way down). The closed-loop tests use it to check what the
  compensator does with a KBJAE without a trained model.
* `renamed_test.onnx`: the same network with its input named `x`, for the
  name check.
* `scnn_test.onnx`: the SCNN's contract (input `silhouette` [N, 1, 48, 48],
  1 for instrument and 0 for background; output `embedding` [N, 256] in
  (0, 1)) with a small body: Conv 5x5 (2 filters, padding 2), ReLU, 8x8
  average pooling, a fully connected layer to 256 and a sigmoid. Beside it
  `scnn_test.expected.json`: four masks and numpy's float64 embeddings.

With `--paper-size DIR` it writes instead, for timing only (random weights,
not committed): `scnn_table1.onnx`, Table I's network padded for 48x48
(Conv 5x5/32, then 3x3 convs of 64, 128, 256, 256, each followed by ReLU and
MaxPool(3, 2, ceil) so 48 -> 24 -> 12 -> 6 -> 3 -> 1, then two
fully connected layers of 256 with sigmoids), and `kbjae_table2.onnx`,
Table II's 2 -> 200 -> 200 -> 200 -> 1 with LeakyReLU.

Usage:
    .venv/bin/python tools/make_test_models.py            # write the files
    .venv/bin/python tools/make_test_models.py --out DIR  # other folder
    .venv/bin/python tools/make_test_models.py --paper-size DIR

Requires numpy and onnx.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

DEFAULT_OUT = Path(__file__).resolve().parent.parent / "crates" / "kflex-estimate" / "tests" / "data"
WIDTH = 16
SLOPE = 0.01
# the input scaling a training script would bake in: deg -> about unit range
OFFSET = np.array([25.0, 0.0])
SCALE = np.array([1 / 25.0, 1 / 25.0])


def weights(seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    sizes = [(2, WIDTH), (WIDTH, WIDTH), (WIDTH, 1)]
    out = []
    for fan_in, fan_out in sizes:
        out.append(rng.normal(0.0, np.sqrt(2.0 / fan_in), (fan_in, fan_out)).astype(np.float32))
        out.append(rng.normal(0.0, 0.1, fan_out).astype(np.float32))
    return out


def reference(x: np.ndarray, w: list[np.ndarray]) -> np.ndarray:
    """The network in float64."""
    h = (x - OFFSET) * SCALE
    for i in range(0, len(w), 2):
        h = h @ w[i].astype(np.float64) + w[i + 1].astype(np.float64)
        if i + 2 < len(w):
            h = np.where(h > 0, h, SLOPE * h)
    return h


def finish(nodes, name, inputs, outputs, inits) -> onnx.ModelProto:
    """A checked opset-17 model of `nodes`; inputs and outputs as (name, dims), float32."""
    graph = helper.make_graph(
        nodes,
        name,
        [helper.make_tensor_value_info(n, TensorProto.FLOAT, dims) for n, dims in inputs],
        [helper.make_tensor_value_info(n, TensorProto.FLOAT, dims) for n, dims in outputs],
        inits,
    )
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="kflex tools")
    m.ir_version = 8
    onnx.checker.check_model(m)
    return m


def model(input_name: str, w: list[np.ndarray]) -> onnx.ModelProto:
    inits = [
        numpy_helper.from_array(OFFSET.astype(np.float32), "offset"),
        numpy_helper.from_array(SCALE.astype(np.float32), "scale"),
    ]
    nodes = [
        helper.make_node("Sub", [input_name, "offset"], ["centred"]),
        helper.make_node("Mul", ["centred", "scale"], ["h0"]),
    ]
    h = "h0"
    for layer in range(3):
        wn, bn = f"w{layer}", f"b{layer}"
        inits += [numpy_helper.from_array(w[2 * layer], wn), numpy_helper.from_array(w[2 * layer + 1], bn)]
        out = "theta_error" if layer == 2 else f"z{layer}"
        nodes.append(helper.make_node("Gemm", [h, wn, bn], [out]))
        if layer < 2:
            nodes.append(helper.make_node("LeakyRelu", [out], [f"a{layer}"], alpha=SLOPE))
            h = f"a{layer}"
    m = finish(nodes, "kbjae_test", [(input_name, ["batch", 2])], [("theta_error", ["batch", 1])], inits)
    return m


# the backlash-like model: half its width is the lag, reached from this rate on
BACKLASH_DEG = 10.0
RATE_SCALE = 2.0


def backlash_model() -> onnx.ModelProto:
    """`kbjae_backlash_test.onnx` (see the module docs)."""
    inits = [
        numpy_helper.from_array(np.array([[0.0], [1.0 / RATE_SCALE]], dtype=np.float32), "pick_rate"),
        numpy_helper.from_array(np.array([-1.0], dtype=np.float32).reshape(()), "lo"),
        numpy_helper.from_array(np.array([1.0], dtype=np.float32).reshape(()), "hi"),
        numpy_helper.from_array(np.array([-BACKLASH_DEG / 2.0], dtype=np.float32), "half_width"),
    ]
    nodes = [
        helper.make_node("MatMul", ["theta_and_rate", "pick_rate"], ["scaled_rate"]),
        helper.make_node("Clip", ["scaled_rate", "lo", "hi"], ["direction"]),
        helper.make_node("Mul", ["direction", "half_width"], ["theta_error"]),
    ]
    return finish(nodes, "kbjae_backlash_test", [("theta_and_rate", ["batch", 2])],
                  [("theta_error", ["batch", 1])], inits)


def inputs() -> np.ndarray:
    rng = np.random.default_rng(1)
    theta = rng.uniform(-10.0, 60.0, 32)
    rate = rng.uniform(-40.0, 40.0, 32)
    return np.stack([theta, rate], axis=1)


def scnn_weights(seed: int = 2) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        rng.normal(0.0, 0.3, (2, 1, 5, 5)).astype(np.float32),
        rng.normal(0.0, 0.1, 2).astype(np.float32),
        rng.normal(0.0, 0.5, (72, 256)).astype(np.float32),
        rng.normal(0.0, 0.1, 256).astype(np.float32),
    ]


def scnn_reference(masks: np.ndarray, w: list[np.ndarray]) -> np.ndarray:
    """The SCNN test network in float64: masks [N, 48, 48] -> [N, 256]."""
    k, kb, fc, fb = (a.astype(np.float64) for a in w)
    n = len(masks)
    padded = np.pad(masks.astype(np.float64), ((0, 0), (2, 2), (2, 2)))
    conv = np.zeros((n, 2, 48, 48))
    for c in range(2):
        for dy in range(5):
            for dx in range(5):
                conv[:, c] += k[c, 0, dy, dx] * padded[:, dy:dy + 48, dx:dx + 48]
        conv[:, c] += kb[c]
    act = np.maximum(conv, 0.0)
    pooled = act.reshape(n, 2, 6, 8, 6, 8).mean(axis=(3, 5))
    z = pooled.reshape(n, 72) @ fc + fb
    return 1.0 / (1.0 + np.exp(-z))


def scnn_model(w: list[np.ndarray]) -> onnx.ModelProto:
    inits = [numpy_helper.from_array(a, n) for a, n in zip(w, ["k", "kb", "fc", "fb"])]
    nodes = [
        helper.make_node("Conv", ["silhouette", "k", "kb"], ["c"], kernel_shape=[5, 5], pads=[2, 2, 2, 2]),
        helper.make_node("Relu", ["c"], ["r"]),
        helper.make_node("AveragePool", ["r"], ["p"], kernel_shape=[8, 8], strides=[8, 8]),
        helper.make_node("Flatten", ["p"], ["f"], axis=1),
        helper.make_node("Gemm", ["f", "fc", "fb"], ["z"]),
        helper.make_node("Sigmoid", ["z"], ["embedding"]),
    ]
    m = finish(nodes, "scnn_test", [("silhouette", ["batch", 1, 48, 48])], [("embedding", ["batch", 256])], inits)
    return m


def scnn_masks() -> np.ndarray:
    """Four 48x48 silhouettes: a bar bent by different angles, and an empty one."""
    yy, xx = np.mgrid[0:48, 0:48]
    masks = []
    for bend in (0.0, 0.4, 0.9):
        centre = 24 + bend * (yy - 24) ** 2 / 24
        masks.append((np.abs(xx - centre) < 4) & (yy > 6))
    masks.append(np.zeros((48, 48), dtype=bool))
    return np.array(masks, dtype=np.uint8)


def write(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    w = weights()
    for name, input_name in (("kbjae_test", "theta_and_rate"), ("renamed_test", "x")):
        data = model(input_name, w).SerializeToString()
        path = out / f"{name}.onnx"
        tmp = path.with_suffix(".tmp")
        tmp.write_bytes(data)
        tmp.replace(path)
        if name == "kbjae_test":
            card = {"model": path.name, "sha256": hashlib.sha256(data).hexdigest(),
                    "made_by": "tools/make_test_models.py (random weights, seed 0; a test model)"}
            (out / f"{name}.card.json").write_text(json.dumps(card, indent=2) + "\n")
    data = backlash_model().SerializeToString()
    path = out / "kbjae_backlash_test.onnx"
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    x = inputs()
    expected = {"inputs": x.tolist(), "theta_error": reference(x, w)[:, 0].tolist()}
    (out / "kbjae_test.expected.json").write_text(json.dumps(expected, indent=1) + "\n")
    sw = scnn_weights()
    data = scnn_model(sw).SerializeToString()
    path = out / "scnn_test.onnx"
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    masks = scnn_masks()
    expected = {
        "masks": ["".join(str(v) for v in m.ravel()) for m in masks],
        "embedding": scnn_reference(masks, sw).tolist(),
    }
    (out / "scnn_test.expected.json").write_text(json.dumps(expected) + "\n")


def paper_size_models(out: Path) -> None:
    """Table I's SCNN and Table II's MLP with random weights, for timing."""
    rng = np.random.default_rng(3)
    out.mkdir(parents=True, exist_ok=True)
    inits, nodes = [], []
    h, c_in = "silhouette", 1
    for i, (k, c) in enumerate([(5, 32), (3, 64), (3, 128), (3, 256), (3, 256)]):
        w = rng.normal(0.0, np.sqrt(2.0 / (k * k * c_in)), (c, c_in, k, k)).astype(np.float32)
        inits += [numpy_helper.from_array(w, f"cw{i}"), numpy_helper.from_array(np.zeros(c, np.float32), f"cb{i}")]
        pad = k // 2
        nodes += [
            helper.make_node("Conv", [h, f"cw{i}", f"cb{i}"], [f"c{i}"], kernel_shape=[k, k], pads=[pad] * 4),
            helper.make_node("Relu", [f"c{i}"], [f"r{i}"]),
            helper.make_node("MaxPool", [f"r{i}"], [f"p{i}"], kernel_shape=[3, 3], strides=[2, 2], ceil_mode=1),
        ]
        h, c_in = f"p{i}", c
    nodes.append(helper.make_node("Flatten", [h], ["flat"], axis=1))
    for i, (a, b) in enumerate([(256, 256), (256, 256)]):
        inits += [numpy_helper.from_array(rng.normal(0.0, np.sqrt(1.0 / a), (a, b)).astype(np.float32), f"fw{i}"),
                  numpy_helper.from_array(np.zeros(b, np.float32), f"fb{i}")]
        out_name = "embedding" if i == 1 else f"s{i}"
        nodes += [helper.make_node("Gemm", ["flat" if i == 0 else "s0", f"fw{i}", f"fb{i}"], [f"z{i}"]),
                  helper.make_node("Sigmoid", [f"z{i}"], [out_name])]
    m = finish(nodes, "scnn_table1", [("silhouette", ["batch", 1, 48, 48])], [("embedding", ["batch", 256])], inits)
    (out / "scnn_table1.onnx").write_bytes(m.SerializeToString())
    w = []
    for a, b in [(2, 200), (200, 200), (200, 200), (200, 1)]:
        w += [rng.normal(0.0, np.sqrt(2.0 / a), (a, b)).astype(np.float32), np.zeros(b, np.float32)]
    inits = [numpy_helper.from_array(OFFSET.astype(np.float32), "offset"),
             numpy_helper.from_array(SCALE.astype(np.float32), "scale")]
    nodes = [helper.make_node("Sub", ["theta_and_rate", "offset"], ["c"]), helper.make_node("Mul", ["c", "scale"], ["h0"])]
    h = "h0"
    for i in range(4):
        inits += [numpy_helper.from_array(w[2 * i], f"w{i}"), numpy_helper.from_array(w[2 * i + 1], f"b{i}")]
        z = "theta_error" if i == 3 else f"z{i}"
        nodes.append(helper.make_node("Gemm", [h, f"w{i}", f"b{i}"], [z]))
        if i < 3:
            nodes.append(helper.make_node("LeakyRelu", [z], [f"a{i}"], alpha=SLOPE))
            h = f"a{i}"
    m = finish(nodes, "kbjae_table2", [("theta_and_rate", ["batch", 2])], [("theta_error", ["batch", 1])], inits)
    (out / "kbjae_table2.onnx").write_bytes(m.SerializeToString())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    ap.add_argument("--paper-size", type=Path, help="write the paper-size timing models here instead")
    args = ap.parse_args()
    if args.paper_size is not None:
        paper_size_models(args.paper_size)
        print(f"wrote the paper-size timing models to {args.paper_size}")
        return 0
    write(args.out)
    print(f"wrote the test models to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
