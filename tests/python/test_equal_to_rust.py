"""The module gives exactly what the Rust crates give for the same inputs.

The reference is ``crates/kflex-py/examples/golden.rs``, which calls the
crates directly (see ``conftest.golden``); nothing here is a stored figure,
so a change to the plant's calibration changes both sides alike. Equality
is exact: the same Rust code runs on the same bits.
"""

from __future__ import annotations

import kflex
import numpy as np


def flat(tree: dict, prefix: str = "") -> dict[str, float]:
    out = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flat(v, key + "."))
        else:
            out[key] = v
    return out


def test_perturbed_config_equals_rust(golden):
    nominal = kflex.PlantConfig(sheath_deg=90.0, noise=kflex.AuroraNoise(), seed=7)
    assert nominal.perturbed(3, 0.15).to_dict() == golden["plant"]["config"]


def test_plant_run_equals_rust_step_by_step(golden):
    g = golden["plant"]
    config = kflex.PlantConfig.from_dict(g["config"])
    plant = kflex.Plant(config)
    commands = np.array(g["commands_deg"])
    run = plant.run(commands, g["translation_mm"], g["dt_s"])
    rows = [flat(s) for s in g["states"]]
    assert set(run) == set(rows[0])
    for key, column in run.items():
        assert column.dtype == np.float64
        np.testing.assert_array_equal(column, [r[key] for r in rows], err_msg=key)
    # and one tick at a time, from a fresh plant
    plant = kflex.Plant(config)
    for theta, row in zip(commands[:50], rows[:50]):
        state = plant.step(float(theta), g["translation_mm"], g["dt_s"])
        assert flat(state.to_dict()) == row


def test_open_loop_scenario_equals_rust(golden):
    plant = kflex.Plant(kflex.PlantConfig(sheath_deg=180.0))
    trace = kflex.OpenLoopScenario(periods=1.0).run(plant)
    g = golden["scenario"]
    for key, values in g["trace"].items():
        np.testing.assert_array_equal(getattr(trace, key), values, err_msg=key)
    assert trace.metrics() == g["metrics"]


def test_kinematics_equal_rust(golden):
    g = golden["kinematics"]
    geometry = kflex.TendonGeometry()
    theta = np.array(g["theta_rad"])
    for name in ["delta_l_a_mm", "delta_l_b_mm", "differential_stroke_mm", "common_mode_mm"]:
        np.testing.assert_array_equal(getattr(geometry, name)(theta), g[name], err_msg=name)
    inverse = geometry.theta_rad_from_delta_l_a(np.array(g["delta_l_a_mm"]), 1.6)
    np.testing.assert_array_equal(inverse, g["theta_rad_from_delta_l_a"])


def test_trajectory_equals_rust(golden):
    g = golden["trajectory"]
    trajectory = kflex.Trajectory(kind="band_limited", min_deg=-20.0, max_deg=60.0, cutoff_hz=1.5, components=8, seed=5)
    theta, rate = trajectory.sample(np.array(g["t_s"]))
    np.testing.assert_array_equal(theta, g["theta_d_deg"])
    np.testing.assert_array_equal(rate, g["theta_d_rate_deg_per_s"])


def test_regions_equal_rust(golden):
    camera = kflex.Camera()
    g = golden["camera"]
    assert kflex.Roi.paper(camera).to_dict() == g["roi_paper"]
    bands = kflex.WorkingRegions.full(camera).bands
    assert [b.to_dict() for b in bands] == g["bands"]


def test_frame_silhouette_and_segmentation_equal_rust(golden):
    g = golden["camera"]
    h, w = g["frame"]["height"], g["frame"]["width"]
    camera = kflex.Camera()
    shape = kflex.Instrument.kflex().shape(30.0, 12.0)
    params = kflex.FrameParams(seed=4, frame=2, occlusion=kflex.Occlusion(fraction=0.3, position=1.0))
    frame = kflex.SceneRenderer().render(camera, shape, params)
    np.testing.assert_array_equal(frame.rgb, golden.bytes("frame.rgb", (h, w, 3)))
    np.testing.assert_array_equal(frame.instrument, golden.bytes("frame.instrument", (h, w)) != 0)
    np.testing.assert_array_equal(frame.occluder, golden.bytes("frame.occluder", (h, w)) != 0)

    roi = kflex.Roi.paper(camera)
    silhouette = kflex.Rasterizer().silhouette_window(camera, shape, roi)
    expected = golden.bytes("silhouette.mask", (roi.height, roi.width)) != 0
    np.testing.assert_array_equal(silhouette, expected)

    seg = kflex.Segmenter().segment(frame.rgb, roi)
    np.testing.assert_array_equal(seg.small, np.array(g["segmentation_small"]).reshape(48, 48) != 0)
    grey = np.full((64, 64, 3), 128, dtype=np.uint8)
    assert g["segmentation_grey"] is None
    assert kflex.Segmenter().segment(grey, kflex.Roi.whole(64, 64)) is None


def test_as_built_camera_and_instrument_equal_rust(golden):
    g = golden["camera"]
    tolerances = kflex.BuildTolerances()
    built = tolerances.camera(kflex.Camera(), 9)
    assert built.camera_from_overtube == g["built_camera_from_overtube"]
    assert built.intrinsics.to_dict() == g["built_intrinsics"]
    assert built.lens.to_dict() == g["built_lens"]
    tip = tolerances.instrument(kflex.Instrument.kflex(), 9).shape(20.0, 15.0).tip_mm
    assert tip == g["built_tip_mm"]
