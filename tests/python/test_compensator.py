"""The compensator from Python: the loop it closes on a toy plant written
here, its limits, its faults (a bad input holds the command, never raises),
its configuration's errors, and a whole run equal to stepping."""

from __future__ import annotations

import math

import kflex
import numpy as np
import pytest

DT = 0.01


def p_only(kp: float) -> kflex.CompensatorConfig:
    return kflex.CompensatorConfig(kp=kp, ki_per_s=0.0, kd_s=0.0, backlash_term="off")


def close_loop(comp: kflex.Compensator, theta_d: float, bias_deg: float, ticks: int) -> float:
    """A first-order joint that settles `bias_deg` below its command, with a
    perfect estimator; returns the final tracking error."""
    theta_a = 0.0
    for _ in range(ticks):
        out = comp.step(theta_d, theta_a, DT)
        assert out.fault is None
        theta_a += 0.2 * (out.theta_c_deg - bias_deg - theta_a)
    return theta_d - theta_a


@pytest.mark.parametrize("kp", [0.5, 1.0, 3.0])
def test_p_only_leaves_the_error_bias_over_one_plus_kp(kp: float) -> None:
    # at rest: e = bias - kp e, so e = bias / (1 + kp)
    error = close_loop(kflex.Compensator(p_only(kp)), 20.0, 4.0, 2000)
    assert error == pytest.approx(4.0 / (1.0 + kp), abs=1e-6)


def test_the_integral_removes_the_offset() -> None:
    config = kflex.CompensatorConfig(kp=0.5, ki_per_s=5.0, kd_s=0.0, backlash_term="off")
    assert abs(close_loop(kflex.Compensator(config), 20.0, 4.0, 3000)) < 1e-3
    # the P-only loop does not: the integral is what closed the gap
    assert close_loop(kflex.Compensator(p_only(0.5)), 20.0, 4.0, 3000) > 2.0


def test_commands_stay_inside_the_joint_and_rate_limits() -> None:
    config = kflex.CompensatorConfig(
        kp=5.0, theta_c_min_deg=-10.0, theta_c_max_deg=30.0, rate_limit_deg_per_s=50.0
    )
    comp = kflex.Compensator(config)
    rng = np.random.default_rng(0)
    theta_d = 40.0 * np.sin(np.arange(1500) * 0.005) + 10.0
    theta_hat = theta_d + rng.normal(0.0, 2.0, theta_d.size)
    out = comp.run(theta_d, theta_hat, DT)
    c = out["theta_c_deg"]
    assert c.min() >= -10.0 and c.max() <= 30.0
    assert np.all(np.abs(np.diff(c)) <= 50.0 * DT + 1e-12)
    # the limits did bind: θ_d alone goes to 50 deg
    assert out["limited"].any() and c.max() == 30.0
    # a target far above the limit: clamped, and reported as limited
    comp.reset()
    for _ in range(200):
        step = comp.step(29.0, 0.0, DT)
    assert step.theta_c_deg == 30.0 and step.limited


def test_a_nan_estimate_is_a_fault_that_holds_the_command() -> None:
    comp = kflex.Compensator()
    for _ in range(20):
        last = comp.step(10.0, 8.0, DT)
    held = comp.step(10.0, float("nan"), DT)
    assert held.fault is not None and held.fault.kind == "non_finite_estimate"
    assert math.isnan(held.fault.details["value"])
    assert "theta_hat_deg" in held.fault.message
    assert held.theta_c_deg == last.theta_c_deg == comp.theta_c_deg
    # θ_d that is not finite, and a bad tick length, also hold it
    assert comp.step(float("inf"), 8.0, DT).fault.kind == "non_finite_desired"
    bad_dt = comp.step(10.0, 8.0, 0.0).fault
    assert bad_dt.kind == "invalid_dt"
    assert (bad_dt.details["value"], bad_dt.details["min"], bad_dt.details["max"]) == (0.0, 0.0, 1.0)
    assert comp.theta_c_deg == last.theta_c_deg
    # a good estimate again: no fault
    assert comp.step(10.0, 8.0, DT).fault is None


def test_the_watchdog_trips_without_estimates_and_clears_on_the_next() -> None:
    comp = kflex.Compensator(kflex.CompensatorConfig(watchdog_timeout_s=0.05))
    comp.step(5.0, 5.0, DT)
    kinds = [comp.step(5.0, None, DT).fault for _ in range(10)]
    assert kinds[:4] == [None] * 4  # missing estimates are ordinary until the timeout
    trip = kinds[-1]
    assert trip.kind == "watchdog"
    assert trip.details["timeout_s"] == 0.05 and trip.details["age_s"] > 0.05
    assert comp.step(5.0, 5.0, DT).fault is None


def test_config_errors_name_the_field() -> None:
    with pytest.raises(kflex.RangeError) as e:
        kflex.Compensator(kflex.CompensatorConfig(kp=-1.0))
    assert e.value.name == "kp" and e.value.value == -1.0
    with pytest.raises(kflex.RangeError) as e:
        kflex.CompensatorConfig(theta_c_min_deg=10.0, theta_c_max_deg=5.0).validate()
    assert e.value.name == "theta_c_max_deg"
    with pytest.raises(TypeError, match="kq"):
        kflex.CompensatorConfig(kq=1.0)
    with pytest.raises(ValueError, match="bogus"):
        kflex.CompensatorConfig(backlash_term="bogus")
    config = kflex.CompensatorConfig(integral_limit_deg=None)
    assert config.integral_limit_deg is None
    assert kflex.Compensator(config).config == config
    assert kflex.CompensatorConfig().backlash_term == "pid_correction"


def test_a_run_equals_stepping_with_missing_and_bad_estimates() -> None:
    rng = np.random.default_rng(5)
    n = 300
    theta_d = 25.0 * np.sin(np.arange(n) * 0.03) + 25.0
    theta_hat = theta_d - 3.0 + rng.normal(0.0, 0.5, n)
    has = rng.random(n) < 0.4
    theta_hat[17] = np.nan  # given as an estimate: a fault
    has[17] = True
    theta_d[40] = np.nan
    whole = kflex.Compensator().run(theta_d, theta_hat, DT, has_estimate=has)
    comp = kflex.Compensator()
    for k in range(n):
        o = comp.step(float(theta_d[k]), float(theta_hat[k]) if has[k] else None, DT)
        assert o.theta_c_deg == whole["theta_c_deg"][k]
        assert o.terms.g_deg == whole["g_deg"][k]
        assert o.terms.f_deg() == pytest.approx(whole["p_deg"][k] + whole["i_deg"][k] + whole["d_deg"][k])
        assert o.limited == whole["limited"][k] and o.reversed == whole["reversed"][k]
        assert (o.fault.kind if o.fault else "") == whole["fault"][k]
    assert whole["fault"][17] == "non_finite_estimate"
    assert whole["fault"][40] == "non_finite_desired"
    assert whole["reversed"].any()
    # no estimates at all: θ_c follows θ_d until the watchdog trips
    blind = kflex.Compensator().run(np.full(50, 5.0), None, DT)
    assert blind["fault"][0] == "" and blind["fault"][-1] == "watchdog"


def test_run_refuses_mismatched_and_masked_inputs() -> None:
    comp = kflex.Compensator()
    with pytest.raises(TypeError, match=r"\(5,\)"):
        comp.run(np.zeros(5), np.zeros(4), DT)
    with pytest.raises(TypeError, match="has_estimate"):
        comp.run(np.zeros(5), np.zeros(5), DT, has_estimate=np.ones(4, bool))
    with pytest.raises(TypeError, match="has_estimate"):
        comp.run(np.zeros(5), np.zeros(5), DT, has_estimate=np.ones(5))
    with pytest.raises(TypeError, match="masked"):
        comp.run(np.zeros(3), np.ma.masked_invalid([1.0, np.nan, 2.0]), DT)
    assert comp.theta_c_deg == 0.0  # nothing ran


def test_reset_gives_a_new_compensators_output() -> None:
    comp = kflex.Compensator()
    for k in range(50):
        comp.step(10.0 + k, 5.0, DT)
    comp.reset()
    fresh = kflex.Compensator()
    a, b = comp.step(3.0, 1.0, DT), fresh.step(3.0, 1.0, DT)
    assert (a.theta_c_deg, a.estimate_age_s, a.terms.i_deg) == (b.theta_c_deg, b.estimate_age_s, b.terms.i_deg)
