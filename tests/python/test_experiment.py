"""The paper's experiments from Python (``ExperimentGrid``,
``run_experiment``): scenario files, the records against the returned time
series, estimators from a models directory, and bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import kflex
import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = REPO_ROOT / "assets" / "scenarios"
KBJAE_TEST_MODEL = REPO_ROOT / "crates" / "kflex-estimate" / "tests" / "data" / "kbjae_test.onnx"


def small(estimators: list[str], kind: str = "compensation", table: str = "IX") -> kflex.ExperimentGrid:
    """One case at 90 deg, two repeats of one period."""
    grid = kflex.ExperimentGrid(
        cases=[{"table": table, "kind": kind, "sheath_deg": 90.0, "occlusion": "0%"}],
        estimators=estimators,
        repeats=2,
        seed=11,
    )
    scenario = grid.scenario
    scenario["motion"]["periods"] = 1.0
    grid.scenario = scenario
    return grid


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def test_the_scenario_files_are_the_papers_grid():
    assert kflex.ExperimentGrid.load(SCENARIOS / "paper.toml") == kflex.ExperimentGrid.paper()
    quick = kflex.ExperimentGrid.paper().quick()
    assert len(quick.cases) == 12 and quick.repeats == 1
    assert quick.scenario["motion"]["periods"] == 1.0


def test_records_agree_with_the_time_series_they_come_from():
    out = kflex.run_experiment(small(["none"]), jobs=1)
    (record,) = out["records"]
    assert (record["kind"], record["table"], record["estimator"]) == ("compensation", "IX", "none")
    assert record["seeds"] == [11, 12]
    assert record["max_hysteresis_deg"] > 0.0
    runs = out["runs"]
    assert sorted(r["seed"] for r in runs) == [11, 12]
    per_run = []
    for run in runs:
        n = len(run["time_s"])
        for key in ("theta_d_deg", "theta_c_deg", "theta_a_deg", "theta_a_measured_deg"):
            assert run[key].dtype == np.float64 and run[key].shape == (n,)
        # the uncompensated plant: the command is the master's, no estimate
        np.testing.assert_array_equal(run["theta_c_deg"], run["theta_d_deg"])
        assert run["estimates"] == {}
        per_run.append(rmse(run["theta_a_measured_deg"], run["theta_d_deg"]))
    assert record["rmse_deg"] == pytest.approx(np.mean(per_run), rel=1e-12)
    assert record["rmse_std_deg"] == pytest.approx(np.std(per_run, ddof=1), rel=1e-9)
    # the same on two threads
    assert kflex.run_experiment(small(["none"]), jobs=2, time_series=False) == {"records": out["records"]}


def test_estimators_load_from_a_models_directory(tmp_path):
    shutil.copy(KBJAE_TEST_MODEL, tmp_path / "kbjae.onnx")
    card = KBJAE_TEST_MODEL.with_name("kbjae_test.card.json")
    shutil.copy(card, tmp_path / "kbjae.card.json")
    out = kflex.run_experiment(small(["kbjae"], kind="estimation", table="VI"), models=tmp_path, jobs=1)
    (record,) = out["records"]
    assert record["kind"] == "estimation" and record["max_hysteresis_deg"] is None
    per_run = []
    for run in out["runs"]:
        est = run["estimates"]["kbjae"]
        assert est.shape == run["theta_a_deg"].shape
        ok = ~np.isnan(est)
        per_run.append(rmse(est[ok], run["theta_a_deg"][ok]))
    assert record["rmse_deg"] == pytest.approx(np.mean(per_run), rel=1e-12)


def test_bad_input_is_a_clear_error(tmp_path):
    with pytest.raises(RuntimeError, match="kbjae.onnx"):
        kflex.run_experiment(small(["kbjae"]), models=tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text("repeats = 2\nrepaets = 3\n")
    with pytest.raises(ValueError, match=r"(?s)bad\.toml.*unknown field `repaets`") as e:
        kflex.run_experiment(bad)
    assert "line 2" in str(e.value)
    # a value out of range is named with the line that sets it, when the
    # file runs; loaded, the grid can still be completed in Python
    bad.write_text('repeats = 1\n[[cases]]\ntable = "IX"\nkind = "compensation"\n'
                   'sheath_deg = 90.0\nocclusion = "0%"\n[scenario.motion]\nperiods = -1.0\n')
    with pytest.raises(kflex.RangeError, match=r"bad\.toml, line 8: periods = -1") as e:
        kflex.run_experiment(bad)
    assert (e.value.name, e.value.value) == ("periods", -1.0)
    assert kflex.ExperimentGrid.load(bad).repeats == 1
    with pytest.raises(OSError):
        kflex.ExperimentGrid.load(tmp_path / "missing.toml")
    with pytest.raises(TypeError, match="ExperimentGrid"):
        kflex.run_experiment(42)
    with pytest.raises(ValueError):
        kflex.ExperimentGrid(estimators=["kalman"])
    grid = small(["none"])
    grid.repeats = 0
    with pytest.raises(kflex.RangeError, match="repeats"):
        kflex.run_experiment(grid)


def test_ctrl_c_stops_a_running_grid_with_keyboard_interrupt():
    import os
    import signal
    import threading
    import time

    # 3,000 uncompensated runs: 16 s on two cores when not stopped
    grid = kflex.ExperimentGrid(
        cases=[
            {"table": "IX", "kind": "compensation", "sheath_deg": s, "occlusion": "0%"}
            for s in (0.0, 90.0, 180.0, 270.0)
        ],
        estimators=["none"],
        repeats=750,
    )
    # Python's own Ctrl-C handler: a process started in the background by a
    # shell without job control (as `make test &` is) inherits SIGINT
    # ignored, and Python then installs no handler
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            kflex.run_experiment(grid, time_series=False)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    # the runs in progress finish (a few ms each), nothing after them starts
    assert time.monotonic() - start < 5.0


def test_the_runs_mcap_logs_hold_what_the_records_say(tmp_path: Path):
    import json

    from mcap.reader import make_reader

    logs_dir = tmp_path / "logs"
    out = kflex.run_experiment(small(["none"]), mcap_dir=logs_dir, time_series=False)
    (record,) = out["records"]
    logs = sorted(logs_dir.glob("*.mcap"))
    assert [p.name for p in logs] == ["IX_90deg_0pct_none_seed11.mcap", "IX_90deg_0pct_none_seed12.mcap"]
    rmses = []
    for path, seed in zip(logs, record["seeds"]):
        with path.open("rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            assert {c.topic for c in summary.channels.values()} == {"/kflex/joint_states"}
            states = [json.loads(m.data) for _, _, m in reader.iter_messages()]
            (meta,) = list(reader.iter_metadata())
        assert meta.metadata["seed"] == str(seed)
        # one period of 10 ms ticks, no estimate on the uncompensated plant
        assert len(states) == 629
        assert all(s["theta_hat_deg"] is None for s in states)
        measured = np.array([s["theta_a_measured_deg"] for s in states])
        desired = np.array([s["theta_d_deg"] for s in states])
        rmses.append(rmse(measured, desired))
    # the record's RMSE ± std is over these two logs
    assert record["rmse_deg"] == pytest.approx(np.mean(rmses), rel=1e-9)
    assert record["rmse_std_deg"] == pytest.approx(np.std(rmses, ddof=1), rel=1e-9)
    # a directory that cannot be made is an OSError before any run
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    with pytest.raises(OSError, match="a-file"):
        kflex.run_experiment(small(["none"]), mcap_dir=blocker / "logs")


def test_records_carry_the_papers_figures_as_results_json_does():
    out = kflex.run_experiment(small(["none"]), time_series=False)
    (record,) = out["records"]
    # Table IX, sheath 90 deg, uncompensated: the paper's 9.95 ± 1.9 and 15.1 ± 0.7
    assert (record["paper_rmse_deg"], record["paper_rmse_std_deg"]) == (9.95, 1.9)
    assert (record["paper_max_hysteresis_deg"], record["paper_max_hysteresis_std_deg"]) == (15.1, 0.7)
    assert record["repeats"] == 2 and record["periods"] == 1.0 and record["dt_s"] == 0.01
    assert record["backgrounds"] == ["colon", "stomach"]
    # a case the paper did not measure has None
    grid = small(["none"])
    grid.cases = [{"table": "IX", "kind": "compensation", "sheath_deg": 45.0, "occlusion": "0%"}]
    (record,) = kflex.run_experiment(grid, time_series=False)["records"]
    assert record["paper_rmse_deg"] is None and record["paper_max_hysteresis_deg"] is None
