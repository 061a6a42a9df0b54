#!/usr/bin/env python3
"""Small ONNX models for kflex's Rust tests of ONNX Runtime, and their outputs.

Until the trained models land (issue 10), the Rust side is tested on models
built here with the `onnx` package, with weights from a fixed seed:

* `kbjae_test.onnx`: KBJAE's contract (input `theta_and_rate` [N, 2] in deg
  and deg/s, output `theta_error` [N, 1] in deg), Table II's shape at a small
  width: input scaling baked in, 2 -> 16 -> 16 -> 1 with LeakyReLU(0.01).
  Beside it `kbjae_test.card.json` (its SHA-256, as a real model card has)
  and `kbjae_test.expected.json`: inputs and numpy's float64 outputs.
* `renamed_test.onnx`: the same network with its input named `x`, for the
  name check.

Usage:
    .venv/bin/python tools/make_test_models.py            # write the files
    .venv/bin/python tools/make_test_models.py --out DIR  # other folder

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
    graph = helper.make_graph(
        nodes,
        "kbjae_test",
        [helper.make_tensor_value_info(input_name, TensorProto.FLOAT, ["batch", 2])],
        [helper.make_tensor_value_info("theta_error", TensorProto.FLOAT, ["batch", 1])],
        inits,
    )
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="kflex tools")
    m.ir_version = 8
    onnx.checker.check_model(m)
    return m


def inputs() -> np.ndarray:
    rng = np.random.default_rng(1)
    theta = rng.uniform(-10.0, 60.0, 32)
    rate = rng.uniform(-40.0, 40.0, 32)
    return np.stack([theta, rate], axis=1)


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
    x = inputs()
    expected = {"inputs": x.tolist(), "theta_error": reference(x, w)[:, 0].tolist()}
    (out / "kbjae_test.expected.json").write_text(json.dumps(expected, indent=1) + "\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args()
    write(args.out)
    print(f"wrote the test models to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
