"""The fusion filters from Python: the same numbers as the Rust filters
(whose golden test holds them to filterpy), a whole run in one call equal to
stepping, missing measurements as None or NaN, and errors that leave the
filter unchanged."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import kflex
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools" / "golden"))
import kalman_golden


def test_the_paper_filter_equals_filterpy_from_python() -> None:
    case = kalman_golden.cases()[0]
    expected = kalman_golden.run(case)
    kf = kflex.PaperKalman(
        kflex.KalmanParams(
            model_dt_s=case.model_dt,
            sigma_a=case.sigma_a,
            sigma_z_deg=list(case.sigma_z),
        )
    )
    z1, z2 = expected[:, 1], expected[:, 2]
    out = kf.run(case.tick_s, z1, z2)
    np.testing.assert_allclose(
        out["theta_hat_deg"], expected[:, 3], rtol=1e-9, atol=1e-12
    )
    np.testing.assert_allclose(
        out["theta_hat_rate_deg_per_s"], expected[:, 4], rtol=1e-9, atol=1e-12
    )
    np.testing.assert_allclose(
        out["theta_var_deg2"], expected[:, 5], rtol=1e-9, atol=1e-15
    )
    assert (out["ibjae_used"] == ~np.isnan(z2)).all()


def test_a_run_equals_stepping_tick_by_tick() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(400) * 0.01
    z1 = 25 * np.sin(t) + 25 + rng.normal(0, 1, t.size)
    z2 = np.where(
        np.arange(t.size) % 3 == 0,
        25 * np.sin(t) + 25 + rng.normal(0, 2, t.size),
        np.nan,
    )
    z2[150] = 90.0  # an outlier the gate should refuse
    whole = kflex.AdaptiveKalman().run(0.01, z1, z2)
    kf = kflex.AdaptiveKalman()
    for k in range(t.size):
        e = kf.step(0.01, z1[k], None if math.isnan(z2[k]) else float(z2[k]))
        assert e.theta_hat_deg == whole["theta_hat_deg"][k]
        assert (e.ibjae == "gated") == whole["ibjae_gated"][k]
    assert whole["ibjae_gated"][150]
    assert e.covariance.shape == (2, 2) and e.covariance[0, 1] == e.covariance[1, 0]


def test_bad_input_raises_and_changes_nothing() -> None:
    kf = kflex.AdaptiveKalman()
    kf.step(0.01, 10.0, 11.0)
    before = kf.estimate().theta_hat_deg
    with pytest.raises(ValueError, match="kbjae_deg"):
        kf.step(0.01, float("inf"))
    with pytest.raises(kflex.RangeError) as e:
        kf.step(-0.01, 10.0)
    assert e.value.name == "dt_s"
    assert kf.estimate().theta_hat_deg == before
    with pytest.raises(kflex.RangeError):
        kflex.PaperKalman(kflex.KalmanParams(model_dt_s=0.0))
    with pytest.raises(TypeError):
        kf.run(0.01, np.zeros((3, 2)))
    with pytest.raises(TypeError):
        kf.run(0.01, np.zeros(5), np.zeros(4))
    assert kflex.KalmanParams().rate == "as_run"


@pytest.mark.parametrize("make", [kflex.PaperKalman, kflex.AdaptiveKalman])
def test_a_rejected_run_changes_nothing(make) -> None:
    kf = make()
    kf.run(0.01, np.full(50, 10.0), np.full(50, 11.0))
    before = kf.estimate()
    # the bad tick comes last: the good ones before it must not stay applied
    with pytest.raises(ValueError, match="kbjae_deg"):
        kf.run(0.01, np.array([20.0, 20.0, np.inf]))
    after = kf.estimate()
    assert after.theta_hat_deg == before.theta_hat_deg
    np.testing.assert_array_equal(after.covariance, before.covariance)
    # and the filter goes on from there as if the bad run never came
    fresh = make()
    fresh.run(0.01, np.full(50, 10.0), np.full(50, 11.0))
    assert kf.step(0.01, 12.0).theta_hat_deg == fresh.step(0.01, 12.0).theta_hat_deg


def test_a_measurement_noise_too_small_to_square_is_refused() -> None:
    # 1e-200 squares to zero in f64: the filter would divide zero by zero
    with pytest.raises(kflex.RangeError) as e:
        kflex.PaperKalman(kflex.KalmanParams(sigma_z_deg=[1e-200, 0.01]))
    assert e.value.name == "sigma_z_deg"
    with pytest.raises(kflex.RangeError):
        kflex.AdaptiveKalman(kflex.AdaptiveParams(min_sigma_z_deg=1e-300))
    kf = kflex.PaperKalman(kflex.KalmanParams(sigma_z_deg=[1e-6, 1e-6]))
    e = kf.step(0.01, kbjae_deg=10.0, ibjae_deg=10.5, ibjae_sigma_deg=0.5)
    assert math.isfinite(e.theta_hat_deg) and np.isfinite(e.covariance).all()


def test_the_adaptive_filter_rejects_a_reading_with_a_hidden_part() -> None:
    flagged, plain = kflex.AdaptiveKalman(), kflex.AdaptiveKalman()
    for _ in range(50):
        a = flagged.step(0.01, kbjae_deg=20.0, ibjae_deg=26.0, ibjae_sigma_deg=1.0, ibjae_occluded=True)
        b = plain.step(0.01, kbjae_deg=20.0, ibjae_deg=26.0, ibjae_sigma_deg=1.0)
    assert a.ibjae == "gated" and abs(a.theta_hat_deg - 20.0) < 0.5, a
    assert b.ibjae == "used" and abs(b.theta_hat_deg - 26.0) < 1.0, b


def test_a_run_names_each_readings_use_as_a_step_does_and_takes_hidden_parts() -> None:
    # the adaptive filter rejects a reading with a hidden part: given as a
    # series, as run_experiment's details log it, it is gated as a step gates it
    rng = np.random.default_rng(5)
    n = 300
    t = np.arange(n) * 0.01
    z1 = 25 * np.sin(t) + 25 + rng.normal(0, 1, n)
    z2 = np.where(np.arange(n) % 3 == 0, 25 * np.sin(t) + 25, np.nan)
    sigma = np.full(n, 1.0)
    hidden = np.zeros(n, dtype=bool)
    hidden[90:120] = True
    whole = kflex.AdaptiveKalman().run(0.01, z1, z2, sigma, hidden)
    kf = kflex.AdaptiveKalman()
    for k in range(n):
        e = kf.step(
            0.01,
            z1[k],
            None if math.isnan(z2[k]) else float(z2[k]),
            float(sigma[k]),
            bool(hidden[k]),
        )
        assert whole["theta_hat_deg"][k] == e.theta_hat_deg
        assert whole["kbjae_use"][k] == e.kbjae
        assert whole["ibjae_use"][k] == e.ibjae, k
        np.testing.assert_array_equal(whole["theta_hat_covariance"][k], e.covariance)
        if e.ibjae_nis is None:
            assert math.isnan(whole["ibjae_nis"][k])
        else:
            assert whole["ibjae_nis"][k] == e.ibjae_nis
    read = ~np.isnan(z2)
    assert (whole["ibjae_use"][read & hidden] != "used").all()
    assert (whole["ibjae_use"][read & ~hidden] == "used").mean() > 0.9
    assert (whole["ibjae_use"][~read] == "missing").all()
    assert (whole["ibjae_used"] == (whole["ibjae_use"] == "used")).all()
    # without the flags every reading is taken as unhidden
    plain = kflex.AdaptiveKalman().run(0.01, z1, z2, sigma)
    assert (plain["ibjae_use"][read & hidden] == "used").all()
    with pytest.raises(TypeError, match="ibjae_occluded"):
        kflex.AdaptiveKalman().run(0.01, z1, z2, sigma, hidden[:10])
