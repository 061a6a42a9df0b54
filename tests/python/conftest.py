"""Shared fixtures of the Python tests.

``golden``: the Rust crates' own outputs on fixed inputs, written by
``crates/kflex-py/examples/golden.rs`` (built and run once per session with
cargo, in the release profile that ``make py-module`` has already built the
dependencies in), for the tests that compare the module with Rust.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parent.parent.parent


class Golden:
    """The example's output directory: ``golden.json`` and raw buffers."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.data = json.loads((path / "golden.json").read_text())

    def __getitem__(self, key: str):
        return self.data[key]

    def bytes(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        return np.fromfile(self.path / name, dtype=np.uint8).reshape(shape)


@pytest.fixture(scope="session")
def golden(tmp_path_factory: pytest.TempPathFactory) -> Golden:
    out = tmp_path_factory.mktemp("golden")
    env = dict(os.environ, PYO3_PYTHON=sys.executable)
    cargo = os.environ.get("CARGO", "cargo")
    cmd = [cargo, "run", "--release", "--locked", "-q", "-p", "kflex-py", "--example", "golden", "--", str(out)]
    subprocess.run(cmd, cwd=REPO_ROOT, env=env, check=True)
    return Golden(out)
