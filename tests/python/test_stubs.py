"""The hand-written stubs (crates/kflex-py/python/kflex/_kflex.pyi) stay true.

Every name the module exports is stubbed, and each parameter class's stub
lists exactly the fields its Rust type has (its serde form, as to_dict
gives it): a field added or renamed in Rust fails here until the stub says so.
"""

from __future__ import annotations

import ast
from pathlib import Path

import kflex
import pytest

STUB = Path(__file__).resolve().parents[2] / "crates" / "kflex-py" / "python" / "kflex" / "_kflex.pyi"


def stub_classes() -> dict[str, ast.ClassDef]:
    tree = ast.parse(STUB.read_text())
    return {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}


def stub_fields(node: ast.ClassDef) -> set[str]:
    return {s.target.id for s in node.body if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name)}


SAMPLES = {
    "SheathParams": lambda: kflex.SheathParams(),
    "JointParams": lambda: kflex.JointParams(),
    "Seating": lambda: kflex.Seating(),
    "TranslationParams": lambda: kflex.TranslationParams(),
    "AuroraNoise": lambda: kflex.AuroraNoise(),
    "Command": lambda: kflex.Command(theta_c_deg=0.0, translation_mm=0.0),
    "PlantState": lambda: kflex.Plant().state,
    "TendonGeometry": lambda: kflex.TendonGeometry(),
    "PlantConfig": lambda: kflex.PlantConfig(),
    "Sine": lambda: kflex.Sine.paper(),
    "OpenLoopScenario": lambda: kflex.OpenLoopScenario(),
    "Intrinsics": lambda: kflex.Intrinsics.default(),
    "Lens": lambda: kflex.Lens(),
    "Roi": lambda: kflex.Roi.whole(1, 1),
    "PoseRange": lambda: kflex.PoseRange.full(),
    "Banding": lambda: kflex.Banding(),
    "WorkingBand": lambda: kflex.WorkingRegions.full(kflex.Camera()).bands[0],
    "InstrumentParams": lambda: kflex.InstrumentParams(),
    "BuildTolerances": lambda: kflex.BuildTolerances(),
    "Occlusion": lambda: kflex.Occlusion(fraction=0.1, position=0.5),
    "FrameParams": lambda: kflex.FrameParams(),
    "SegmentParams": lambda: kflex.SegmentParams(),
    "KinematicSetSpec": lambda: kflex.KinematicSetSpec(amplitude_deg=35.0, frequency_hz=0.159, train=True),
    "KinematicDatasetConfig": lambda: kflex.KinematicDatasetConfig(),
    "ImagePairsConfig": lambda: kflex.ImagePairsConfig(),
    "KalmanParams": lambda: kflex.KalmanParams(),
    "AdaptiveParams": lambda: kflex.AdaptiveParams(),
    "CompensatorConfig": lambda: kflex.CompensatorConfig(),
    "ClosedLoopScenario": lambda: kflex.ClosedLoopScenario(),
    "ExperimentGrid": lambda: kflex.ExperimentGrid(),
}


def test_every_export_is_stubbed():
    tree = ast.parse(STUB.read_text())
    stubbed = set(stub_classes()) | {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert set(kflex.__all__) <= stubbed
    assert set(kflex.__all__) == {n for n in dir(kflex._kflex) if not n.startswith("_")}


@pytest.mark.parametrize("name", sorted(SAMPLES))
def test_stub_fields_are_the_rust_fields(name):
    assert stub_fields(stub_classes()[name]) == set(SAMPLES[name]().to_dict()), name
