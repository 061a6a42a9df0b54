"""The small ONNX test models (tools/make_test_models.py) are what they claim:
onnxruntime's outputs equal the float64 reference, the card records the file's
SHA-256, and regenerating gives the same reference values.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import sys
from pathlib import Path

import numpy as np
import onnxruntime as ort

REPO_ROOT = Path(__file__).resolve().parent.parent.parent
sys.path.insert(0, str(REPO_ROOT / "tools"))
mtm = importlib.import_module("make_test_models")
DATA = REPO_ROOT / "crates" / "kflex-estimate" / "tests" / "data"


def stored_expected():
    return json.loads((DATA / "kbjae_test.expected.json").read_text())


def test_onnxruntime_gives_the_reference_outputs() -> None:
    expected = stored_expected()
    session = ort.InferenceSession(str(DATA / "kbjae_test.onnx"), providers=["CPUExecutionProvider"])
    assert [i.name for i in session.get_inputs()] == ["theta_and_rate"]
    assert [o.name for o in session.get_outputs()] == ["theta_error"]
    x = np.array(expected["inputs"], dtype=np.float32)
    (out,) = session.run(None, {"theta_and_rate": x})
    assert out.shape == (len(x), 1)
    np.testing.assert_allclose(out[:, 0], expected["theta_error"], rtol=1e-5, atol=1e-5)


def test_the_card_records_the_files_sha256() -> None:
    card = json.loads((DATA / "kbjae_test.card.json").read_text())
    assert card["sha256"] == hashlib.sha256((DATA / "kbjae_test.onnx").read_bytes()).hexdigest()


def test_regenerating_gives_the_stored_reference(tmp_path) -> None:
    mtm.write(tmp_path)
    fresh = json.loads((tmp_path / "kbjae_test.expected.json").read_text())
    assert fresh == stored_expected()
    assert (tmp_path / "renamed_test.onnx").is_file()
    scnn = json.loads((tmp_path / "scnn_test.expected.json").read_text())
    assert scnn == json.loads((DATA / "scnn_test.expected.json").read_text())


def test_the_scnn_test_model_gives_the_reference_embeddings() -> None:
    expected = json.loads((DATA / "scnn_test.expected.json").read_text())
    masks = np.array([[int(c) for c in m] for m in expected["masks"]], dtype=np.float32).reshape(-1, 1, 48, 48)
    session = ort.InferenceSession(str(DATA / "scnn_test.onnx"), providers=["CPUExecutionProvider"])
    (out,) = session.run(None, {"silhouette": masks})
    assert out.shape == (len(masks), 256)
    np.testing.assert_allclose(out, expected["embedding"], rtol=1e-5, atol=1e-6)
