"""The closed loop from Python (``ClosedLoopScenario.run``): compensation on
a stand-in estimator and on KBJAE's test model, the camera's frames, bad
input, and the run's MCAP log read back with the ``mcap`` package."""

from __future__ import annotations

import json
from pathlib import Path

import kflex
import numpy as np
import pytest
from mcap.reader import make_reader

REPO_ROOT = Path(__file__).resolve().parents[2]
KBJAE_TEST_MODEL = REPO_ROOT / "crates" / "kflex-estimate" / "tests" / "data" / "kbjae_test.onnx"


def short(**fields) -> kflex.ClosedLoopScenario:
    """Two periods of the paper's input after a one-second pre-roll."""
    scenario = kflex.ClosedLoopScenario(**fields)
    motion = scenario.motion
    motion.update(periods=2.0, pre_roll_s=1.0)
    scenario.motion = motion
    return scenario


def plant() -> kflex.Plant:
    return kflex.Plant(kflex.PlantConfig(noise=None))


def test_compensation_on_a_stand_in_cuts_the_rmse() -> None:
    closed = short(camera={"rate_hz": 30.0, "latency_s": 0.05, "drop_probability": 0.1})
    open_loop = short(compensator=None)
    compensated = closed.run(plant(), kflex.NoisyTruth(1.0, seed=3), seed=11)
    uncompensated = open_loop.run(plant(), kflex.NoisyTruth(1.0, seed=3), seed=11)
    n = len(compensated)
    assert n == len(uncompensated) > 1000
    for column in ("time_s", "theta_d_deg", "theta_c_deg", "theta_a_deg", "theta_a_measured_deg", "theta_hat_deg"):
        values = getattr(compensated, column)
        assert values.dtype == np.float64 and values.shape == (n,), column
    # without a compensator the command is the input
    np.testing.assert_array_equal(uncompensated.theta_c_deg, uncompensated.theta_d_deg)
    r_open = uncompensated.metrics()["rmse_deg"]
    r_closed = compensated.metrics()["rmse_deg"]
    assert r_closed < 0.6 * r_open, (r_closed, r_open)
    assert compensated.fault_ticks == 0
    frames = compensated.frames
    assert set(frames) == {"captured", "dropped", "delivered", "stale"}
    assert 0 < frames["dropped"] < frames["captured"]
    assert compensated.estimation_rmse_deg() < 3.0
    # the stand-in camera tells its reading and noise on the ticks a frame reached it
    details = compensated.details
    read = np.isfinite(details["ibjae_deg"])
    assert 0 < read.sum() <= frames["delivered"]
    np.testing.assert_array_equal(details["ibjae_deg"][read], compensated.theta_hat_deg[read])
    assert np.all(details["ibjae_sigma_deg"][read] == 1.0)
    assert np.isnan(details["ibjae_sigma_deg"][~read]).all() and np.isnan(details["kbjae_deg"]).all()


def test_kbjae_closes_the_loop_without_frames() -> None:
    kbjae = kflex.Kbjae.load(KBJAE_TEST_MODEL)
    trace = short(compensator=None).run(plant(), kbjae, seed=1)
    assert trace.frames["captured"] == 0
    assert np.all(np.isfinite(trace.theta_hat_deg))


def test_bad_input_is_refused() -> None:
    with pytest.raises(TypeError, match="NoisyTruth, Kbjae or Lbhjae"):
        short().run(plant(), "an estimator")
    with pytest.raises(kflex.RangeError) as e:
        short(camera={"rate_hz": 0.0}).run(plant(), kflex.NoisyTruth(1.0))
    assert e.value.name == "camera.rate_hz"
    with pytest.raises(kflex.RangeError):
        kflex.NoisyTruth(-1.0)
    with pytest.raises(TypeError, match="fps"):
        kflex.ClosedLoopScenario(camera={"fps": 30})


def test_the_mcap_log_holds_every_tick(tmp_path: Path) -> None:
    scenario = short()
    path = tmp_path / "run.mcap"
    trace = scenario.run(plant(), kflex.NoisyTruth(0.5, seed=2), seed=17, mcap_path=path)
    with path.open("rb") as f:
        reader = make_reader(f)
        messages = list(reader.iter_messages(topics=["/kflex/joint_states"]))
        (meta,) = list(reader.iter_metadata())
    assert len(messages) == len(trace)
    schema, channel, _ = messages[0]
    assert (schema.name, schema.encoding, channel.message_encoding) == ("kflex.JointState", "jsonschema", "json")
    properties = json.loads(schema.data)["properties"]
    required = set(json.loads(schema.data)["required"])
    for _, _, m in messages:
        assert required <= set(json.loads(m.data)) <= set(properties)
    states = [json.loads(m.data) for _, _, m in messages]
    for column in ("time_s", "theta_d_deg", "theta_c_deg", "theta_a_deg"):
        np.testing.assert_array_equal([s[column] for s in states], getattr(trace, column), err_msg=column)
    hat = np.array([np.nan if s["theta_hat_deg"] is None else s["theta_hat_deg"] for s in states])
    np.testing.assert_array_equal(hat, trace.theta_hat_deg)
    assert [m.log_time for _, _, m in messages] == [round(t * 1e9) for t in trace.time_s]
    assert meta.name == "kflex.run" and meta.metadata["seed"] == "17"
    assert kflex.ClosedLoopScenario.from_dict(json.loads(meta.metadata["scenario"])) == scenario
    # a log that cannot be written is an OSError naming it, and leaves nothing
    missing = tmp_path / "no" / "run.mcap"
    with pytest.raises(OSError, match="no"):
        scenario.run(plant(), kflex.NoisyTruth(0.5), mcap_path=missing)
    assert not missing.exists()
