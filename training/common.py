"""What both training scripts share: device, seeds, ONNX export and its
check against torch, model cards, library versions.

The scripts run in the training environment (``make training-venv``:
``training/.venv`` with torch, onnx, onnxscript, onnxruntime), where the
``kflex`` module the project's ``.venv`` builds is importable too (a ``.pth``
file points at ``crates/kflex-py/python``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import random
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import torch
from kflex.npz import sha256, write_atomically

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO_ROOT / "assets" / "models"


def parser(doc: str | None, model: str) -> argparse.ArgumentParser:
    """The options both scripts take; each adds its own."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--smoke", action="store_true", help="tiny data, a few steps (under a minute)")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"folder of {model}.onnx and its card")
    p.add_argument("--data", type=Path, help="the data set as .npz (kflex.npz.save); generated if left out")
    p.add_argument("--data-seed", type=int, default=2020, help="seed of the generated data set")
    p.add_argument("--seed", type=int, default=0, help="seed of the initialisation, batches and noise")
    p.add_argument("--max-steps", type=int, help="stop after this many steps")
    p.add_argument("--batch", type=int, default=200)
    p.add_argument("--device", default="auto", help="auto (the GPU where torch finds one), cpu, cuda")
    return p


def finish(args: argparse.Namespace, epochs: int, smoke_steps: int) -> argparse.Namespace:
    """Fills the defaults that depend on ``--smoke``: ``epochs`` (1 in a
    smoke run) and ``max_steps`` (``smoke_steps`` in a smoke run)."""
    if args.epochs is None:
        args.epochs = 1 if args.smoke else epochs
    if args.max_steps is None and args.smoke:
        args.max_steps = smoke_steps
    return args


def pick_device(name: str) -> torch.device:
    """``"auto"``: the GPU where torch sees one, else the CPU; or the device named."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def seed_everything(seed: int) -> torch.Generator:
    """Seeds Python's, numpy's and torch's generators; returns a torch generator on the CPU."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)
    return torch.Generator().manual_seed(seed)


def versions() -> dict[str, str]:
    """The versions of what made a model."""
    out = {"python": platform.python_version(), "torch": torch.__version__}
    for name in ("onnx", "onnxscript", "onnxruntime", "numpy"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    try:
        import kflex

        out["kflex"] = kflex.__version__
    except ImportError:
        out["kflex"] = "not installed"
    return out


def card_path(onnx_path: Path) -> Path:
    """``NAME.card.json`` beside ``NAME.onnx`` (where kflex-estimate's loader reads it)."""
    return onnx_path.with_name(onnx_path.stem + ".card.json")


def export_onnx(
    model: torch.nn.Module,
    example: torch.Tensor,
    path: Path,
    input_name: str,
    output_name: str,
) -> Path:
    """Exports ``model`` (in eval mode, on the CPU) to one ONNX file with a
    dynamic batch axis, the input and output named as kflex-estimate expects,
    and checks the graph with onnx's checker."""
    import onnx

    model = model.eval().cpu()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.onnx")
    batch = torch.export.Dim("batch", min=1)
    program = torch.onnx.export(
        model,
        (example.cpu(),),
        input_names=[input_name],
        output_names=[output_name],
        dynamic_shapes=({0: batch},),
        external_data=False,
        dynamo=True,
    )
    program.save(str(tmp), external_data=False)
    onnx.checker.check_model(str(tmp), full_check=True)
    os.replace(tmp, path)
    return path


def onnx_diff(path: Path, model: torch.nn.Module, x: torch.Tensor) -> dict[str, float]:
    """How far onnxruntime's output for ``x`` (CPU) is from the torch
    model's own (eval mode, CPU): the largest absolute difference, the
    largest relative to ``max(1, |torch|)``, and whether they are equal
    within 1e-4 (``numpy.allclose`` with rtol = atol = 1e-4: float32 sums
    taken in another order differ in the last places of the intermediate
    sums' magnitude, not the output's: KBJAE's smoke model, inputs up to
    100 through three 200-wide layers, differed by 3.2e-5 deg at outputs
    near 1.7 deg on 2026-11-29, after the plant's refit changed its data;
    1e-4 deg is four orders below KBJAE's accuracy)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    (name,) = [i.name for i in session.get_inputs()]
    got = session.run(None, {name: x.cpu().numpy().astype(np.float32)})[0]
    with torch.no_grad():
        want = model.eval().cpu()(x.cpu()).numpy()
    diff = np.abs(got - want)
    return {
        "max_abs_diff_vs_torch": float(np.max(diff)),
        "max_rel_diff_vs_torch": float(np.max(diff / np.maximum(1.0, np.abs(want)))),
        "equal_within_1e-4": bool(np.allclose(got, want, rtol=1e-4, atol=1e-4)),
        "probe_inputs": len(x),
        "runtime": "onnxruntime CPUExecutionProvider",
    }


def write_card(onnx_path: Path, card: Mapping[str, Any]) -> Path:
    """Writes the model card beside the ONNX file, with the file's SHA-256,
    name and size added (the loader checks ``sha256``)."""
    full = dict(card)
    full.update(file=onnx_path.name, bytes=onnx_path.stat().st_size, sha256=sha256(onnx_path))
    path = card_path(onnx_path)
    text = json.dumps(full, indent=2, sort_keys=True) + "\n"
    write_atomically(path, lambda f: f.write(text.encode()))
    return path


def rmse(error: np.ndarray) -> float:
    """Root mean square of ``error``."""
    return float(np.sqrt(np.mean(np.square(error)))) if len(error) else float("nan")
