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


def test_the_adaptive_filter_rejects_a_reading_with_a_hidden_part() -> None:
    flagged, plain = kflex.AdaptiveKalman(), kflex.AdaptiveKalman()
    for _ in range(50):
        a = flagged.step(0.01, kbjae_deg=20.0, ibjae_deg=26.0, ibjae_sigma_deg=1.0, ibjae_occluded=True)
        b = plain.step(0.01, kbjae_deg=20.0, ibjae_deg=26.0, ibjae_sigma_deg=1.0)
    assert a.ibjae == "gated" and abs(a.theta_hat_deg - 20.0) < 0.5, a
    assert b.ibjae == "used" and abs(b.theta_hat_deg - 26.0) < 1.0, b
