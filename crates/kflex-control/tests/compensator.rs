//! The compensator (Eq. 3–5) on simple plants, its limits and faults, and
//! on kflex's plant with a perfect estimator: how much it and Eq. 5's
//! backlash term take off the paper's input's error and loop width.

use kflex_control::{
    BacklashTerm, Compensator, CompensatorConfig, ControlError, Fault, OpenLoopScenario,
    RunMetrics, Trace,
};
use kflex_model::{Command, Plant, PlantConfig};
use proptest::prelude::*;

const DT: f64 = 0.01;

fn compensator(config: CompensatorConfig) -> Compensator {
    Compensator::new(config).unwrap()
}

/// A PID without the backlash term, the derivative, the integral's clamp or
/// a binding rate limit: the textbook loop, for the simple plants.
fn plain(kp: f64, ki_per_s: f64) -> CompensatorConfig {
    CompensatorConfig {
        kp,
        ki_per_s,
        kd_s: 0.0,
        backlash_term: BacklashTerm::Off,
        integral_limit_deg: None,
        rate_limit_deg_per_s: 1e5,
        ..CompensatorConfig::default()
    }
}

/// A first-order plant `τ y' = u − y + offset` (exact discretisation).
struct FirstOrder {
    y: f64,
    tau_s: f64,
    offset_deg: f64,
}

impl FirstOrder {
    fn step(&mut self, u: f64, dt: f64) -> f64 {
        let a = (-dt / self.tau_s).exp();
        self.y = a * self.y + (1.0 - a) * (u + self.offset_deg);
        self.y
    }
}

/// Runs `comp` on `plant` towards a constant θ_d; the plant's outputs.
fn run_first_order(
    comp: &mut Compensator,
    plant: &mut FirstOrder,
    theta_d: f64,
    ticks: usize,
) -> Vec<f64> {
    (0..ticks)
        .map(|_| {
            let out = comp.step(theta_d, Some(plant.y), DT);
            assert!(out.fault.is_none());
            plant.step(out.theta_c_deg, DT)
        })
        .collect()
}

#[test]
fn p_only_converges_on_a_first_order_plant() {
    let mut plant = FirstOrder {
        y: 0.0,
        tau_s: 0.1,
        offset_deg: 0.0,
    };
    let mut comp = compensator(plain(0.8, 0.0));
    let y = run_first_order(&mut comp, &mut plant, 30.0, 300);
    // θ_c = θ_d + K_p e feeds θ_d forward: no offset, so the loop settles on θ_d
    assert!((y[299] - 30.0).abs() < 1e-3, "{}", y[299]);
    // and it is faster than the plant alone (τ = 0.1 s: 63 % after 10 ticks)
    let mut alone = FirstOrder {
        y: 0.0,
        tau_s: 0.1,
        offset_deg: 0.0,
    };
    let open: Vec<f64> = (0..10).map(|_| alone.step(30.0, DT)).collect();
    assert!(y[9] > open[9] + 3.0, "{} vs {}", y[9], open[9]);
    // monotone, no overshoot for this gain
    assert!(y.windows(2).all(|w| w[1] >= w[0] - 1e-12));
    assert!(y.iter().all(|&v| v <= 30.0 + 1e-9));
}

#[test]
fn the_integral_removes_a_constant_offset() {
    let run = |ki| {
        let mut plant = FirstOrder {
            y: 0.0,
            tau_s: 0.1,
            offset_deg: -5.0,
        };
        let mut comp = compensator(plain(0.5, ki));
        run_first_order(&mut comp, &mut plant, 20.0, 1000)[999]
    };
    // P alone leaves e = offset / (1 + K_p) = 5 / 1.5
    let p_only = run(0.0);
    assert!((20.0 - p_only - 5.0 / 1.5).abs() < 1e-6, "{p_only}");
    let pi = run(5.0);
    assert!((20.0 - pi).abs() < 1e-3, "{pi}");
}

/// The paper's input through kflex's plant (nominal, analytic joint, no
/// measurement noise) at `sheath_deg`, with the protocol of
/// [`OpenLoopScenario::run`] (pre-roll, then five periods at 100 Hz), and
/// `comp` between θ_d and the plant fed a perfect estimate: θ̂ = θ_a, the
/// plant's true angle after the previous tick. `None`: no compensation.
fn paper_run(sheath_deg: f64, mut comp: Option<Compensator>) -> (Trace, Vec<f64>) {
    let scenario = OpenLoopScenario::default();
    let mut plant = Plant::new(PlantConfig {
        sheath_deg,
        noise: None,
        ..PlantConfig::default()
    })
    .unwrap();
    let sampler = scenario.trajectory.sampler().unwrap();
    let dt = scenario.dt_s;
    let mut tick = |theta_d: f64, plant: &mut Plant| {
        let theta_c = match comp.as_mut() {
            Some(c) => {
                let out = c.step(theta_d, Some(plant.state().theta_a_deg), dt);
                assert!(out.fault.is_none(), "{:?}", out.fault);
                out.theta_c_deg
            }
            None => theta_d,
        };
        let command = Command {
            theta_c_deg: theta_c,
            translation_mm: scenario.translation_mm,
        };
        (theta_c, plant.step(command, dt).unwrap())
    };
    // the pre-roll of OpenLoopScenario::run: raised cosine to θ_d(0), then hold
    let start = sampler.sample(0.0).theta_d_deg;
    let ramp_ticks = (scenario.pre_roll_s / dt).round() as usize;
    for k in 1..=2 * ramp_ticks {
        let u = (k as f64 / ramp_ticks as f64).min(1.0);
        tick(
            start * 0.5 * (1.0 - (std::f64::consts::PI * u).cos()),
            &mut plant,
        );
    }
    let n = (scenario.periods * scenario.period_s / dt).round() as usize;
    let mut commands = Vec::with_capacity(n);
    let mut trace = Trace::default();
    for k in 0..n {
        let t = (k + 1) as f64 * dt;
        let s = sampler.sample(t);
        let (theta_c, state) = tick(s.theta_d_deg, &mut plant);
        commands.push(theta_c);
        trace.time_s.push(t);
        trace.theta_d_deg.push(s.theta_d_deg);
        trace.theta_d_rate_deg_per_s.push(s.theta_d_rate_deg_per_s);
        trace.theta_a_deg.push(state.theta_a_deg);
        trace.theta_a_measured_deg.push(state.theta_a_measured_deg);
    }
    (trace, commands)
}

#[test]
fn without_compensation_the_runner_is_the_open_loop_scenario() {
    let (trace, commands) = paper_run(90.0, None);
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 90.0,
        noise: None,
        ..PlantConfig::default()
    })
    .unwrap();
    let reference = OpenLoopScenario::default().run(&mut plant).unwrap();
    assert_eq!(trace, reference);
    assert_eq!(commands, trace.theta_d_deg);
}

/// Metrics of a run; the loop width on the true angle (no noise here).
fn metrics(trace: &Trace) -> RunMetrics {
    assert_eq!(trace.theta_a_deg, trace.theta_a_measured_deg);
    trace.metrics().unwrap()
}

#[test]
fn eq5_narrows_the_loop() {
    let config = |backlash_term| CompensatorConfig {
        backlash_term,
        ..CompensatorConfig::default()
    };
    println!("perfect estimator (θ̂ = θ_a), paper input, nominal plant, 100 Hz, default gains:");
    println!("sheath  compensation              RMSE deg  loop width deg  error p-p deg");
    for sheath in [0.0, 270.0] {
        let none = metrics(&paper_run(sheath, None).0);
        let mut rows = vec![("none", none)];
        for (name, g) in [
            ("PID (G off)", BacklashTerm::Off),
            ("PID + G (Eq. 5)", BacklashTerm::PidCorrection),
            ("PID + G (total)", BacklashTerm::TotalCorrection),
        ] {
            rows.push((
                name,
                metrics(&paper_run(sheath, Some(compensator(config(g)))).0),
            ));
        }
        for (name, m) in &rows {
            println!(
                "{sheath:>6}  {name:<22}  {:>8.2}  {:>14.2}  {:>13.2}",
                m.rmse_deg, m.max_hysteresis_deg, m.error_peak_to_peak_deg
            );
        }
        let (pid, eq5) = (rows[1].1, rows[2].1);
        // the default compensator (Eq. 3–5) against none: the issue's check
        // at 0 deg, and a cut at 270 deg too
        if sheath == 0.0 {
            assert!(eq5.rmse_deg <= 0.6 * none.rmse_deg, "{eq5:?} vs {none:?}");
        }
        assert!(eq5.rmse_deg < none.rmse_deg, "{eq5:?} vs {none:?}");
        // Eq. 5's G narrows the loop the PID leaves, and costs no accuracy
        assert!(
            eq5.max_hysteresis_deg < 0.95 * pid.max_hysteresis_deg,
            "{eq5:?} vs {pid:?}"
        );
        assert!(eq5.rmse_deg <= pid.rmse_deg, "{eq5:?} vs {pid:?}");
    }
}

#[test]
fn eq5_terms_stay_bounded_over_many_periods() {
    // a gain loss makes the corrections at the two turning points differ;
    // taken literally G and the integral would drift apart by ~160 deg a period
    let mut comp = compensator(CompensatorConfig {
        integral_limit_deg: None,
        ..CompensatorConfig::default()
    });
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 270.0,
        noise: None,
        ..PlantConfig::default()
    })
    .unwrap();
    let mut reversals = 0;
    let mut largest = 0.0f64;
    for k in 0..20_000 {
        let t = f64::from(k) * DT;
        let theta_d = 25.0 * t.sin() + 25.0;
        let out = comp.step(theta_d, Some(plant.state().theta_a_deg), DT);
        reversals += usize::from(out.reversed);
        largest = largest
            .max(out.terms.g_deg.abs())
            .max(out.terms.i_deg.abs());
        let command = Command {
            theta_c_deg: out.theta_c_deg,
            translation_mm: 10.0,
        };
        plant.step(command, DT).unwrap();
    }
    // 200 s: 31 periods, 63 reversals
    assert!(reversals >= 60, "{reversals}");
    assert!(largest < 120.0, "{largest}");
}

/// A compensator ready for the stub tests: no rate limit to speak of.
fn free() -> CompensatorConfig {
    CompensatorConfig {
        rate_limit_deg_per_s: 1e5,
        ..CompensatorConfig::default()
    }
}

#[test]
fn g_changes_only_when_theta_d_reverses_and_cancels_the_last_correction() {
    let mut comp = compensator(free());
    // rising, the joint 2 deg behind: the PID builds a positive correction
    let mut last = comp.step(0.0, Some(0.0), DT);
    for k in 1..=100 {
        let theta_d = 0.2 * f64::from(k);
        let out = comp.step(theta_d, Some(theta_d - 2.0), DT);
        assert!(!out.reversed && out.terms.g_deg == 0.0, "tick {k}: {out:?}");
        last = out;
    }
    let f_before = last.terms.f_deg();
    assert!(f_before > 2.0, "{f_before}");
    // θ_d turns back: G = −f_{t−1}'s P + D, the integral restarts (moved into G)
    let turn = comp.step(19.9, Some(18.5), DT);
    assert!(turn.reversed);
    assert_eq!(turn.terms.g_deg, -(last.terms.p_deg + last.terms.d_deg));
    assert!(turn.terms.g_deg < 0.0);
    // the total correction is Eq. 5's: f_t − f_{t−1} with the integral run on
    let literal_f = turn.terms.p_deg + turn.terms.d_deg + last.terms.i_deg + turn.terms.i_deg;
    let correction = turn.theta_c_deg - 19.9;
    assert!(
        (correction - (literal_f - f_before)).abs() < 1e-9,
        "{correction}"
    );
    // held while θ_d keeps falling, even as f changes
    let mut theta_d = 19.9;
    for _ in 0..50 {
        theta_d -= 0.2;
        let out = comp.step(theta_d, Some(theta_d + 1.0), DT);
        assert!(!out.reversed);
        assert_eq!(out.terms.g_deg, turn.terms.g_deg);
        last = out;
    }
    // a hold of θ_d is no reversal; rising again is
    assert!(!comp.step(theta_d, Some(theta_d + 1.0), DT).reversed);
    let back = comp.step(theta_d + 0.1, Some(theta_d + 0.5), DT);
    assert!(back.reversed);
    assert_ne!(back.terms.g_deg, turn.terms.g_deg);
    assert!(last.terms.f_deg() < 0.0);
    // the falling correction was negative, so G is positive now
    assert!(back.terms.g_deg > 0.0, "{back:?}");
}

#[test]
fn the_deadband_and_the_readings_of_eq5() {
    let run = |config: CompensatorConfig, back_deg: f64| {
        let mut comp = compensator(config);
        let mut last = comp.step(0.0, Some(0.0), DT);
        for k in 1..=100 {
            let theta_d = 0.2 * f64::from(k);
            last = comp.step(theta_d, Some(theta_d - 2.0), DT);
        }
        (last, comp.step(20.0 - back_deg, Some(18.0), DT))
    };
    let deadband = CompensatorConfig {
        direction_deadband_deg: 1.0,
        ..free()
    };
    assert!(!run(deadband, 0.5).1.reversed);
    assert!(run(deadband, 1.5).1.reversed);
    // G off: reversals are seen, G stays 0
    let off = CompensatorConfig {
        backlash_term: BacklashTerm::Off,
        ..free()
    };
    let (_, turn) = run(off, 0.5);
    assert!(turn.reversed && turn.terms.g_deg == 0.0);
    // the other reading: the whole correction, G included, reversed
    let total = CompensatorConfig {
        backlash_term: BacklashTerm::TotalCorrection,
        ..free()
    };
    let (last, turn) = run(total, 0.5);
    assert_eq!(turn.terms.g_deg, -(last.terms.f_deg() + last.terms.g_deg));
}

/// Ticks, after θ_d drops from an unreachable 40 deg (held 3 s against an
/// upper joint limit of 30 deg) to 10 deg, until θ_c leaves that limit.
fn ticks_to_leave_the_limit(config: CompensatorConfig) -> usize {
    let config = CompensatorConfig {
        theta_c_min_deg: -30.0,
        theta_c_max_deg: 30.0,
        rate_limit_deg_per_s: 1e5,
        ..config
    };
    let mut comp = compensator(config);
    let mut plant = FirstOrder {
        y: 0.0,
        tau_s: 0.05,
        offset_deg: 0.0,
    };
    for _ in 0..300 {
        let out = comp.step(40.0, Some(plant.y), DT);
        plant.step(out.theta_c_deg, DT);
    }
    assert_eq!(comp.theta_c_deg(), 30.0);
    (1..=2000)
        .find(|_| {
            let out = comp.step(10.0, Some(plant.y), DT);
            plant.step(out.theta_c_deg, DT);
            out.theta_c_deg < 30.0
        })
        .unwrap_or(usize::MAX)
}

#[test]
fn anti_windup_lets_the_output_leave_the_limit_promptly() {
    let base = CompensatorConfig {
        kp: 0.6,
        ki_per_s: 10.0,
        ..CompensatorConfig::default()
    };
    let neither = ticks_to_leave_the_limit(CompensatorConfig {
        integral_limit_deg: None,
        freeze_integral_when_saturated: false,
        ..base
    });
    let clamp = ticks_to_leave_the_limit(CompensatorConfig {
        integral_limit_deg: Some(5.0),
        freeze_integral_when_saturated: false,
        ..base
    });
    let freeze = ticks_to_leave_the_limit(CompensatorConfig {
        integral_limit_deg: None,
        ..base
    });
    let default = ticks_to_leave_the_limit(base);
    // without either, 3 s of a 10 deg error wound the integral to ~300 deg
    assert!(neither > 100, "{neither}");
    for (name, ticks) in [("clamp", clamp), ("freeze", freeze), ("default", default)] {
        assert!(ticks <= 3, "{name}: {ticks} (without: {neither})");
    }
}

#[test]
fn the_rate_limit_holds_exactly_and_binds() {
    let rate = 50.0;
    let mut comp = compensator(CompensatorConfig {
        rate_limit_deg_per_s: rate,
        ..CompensatorConfig::default()
    });
    let mut last = comp.theta_c_deg();
    let mut bound = 0;
    for k in 0..2000u32 {
        // θ_d jumps between ±60 deg every 0.2 s; dt varies
        let dt = [0.01, 0.002, 0.013][k as usize % 3];
        let theta_d = if (k / 20) % 2 == 0 { 60.0 } else { -60.0 };
        let out = comp.step(theta_d, Some(0.5 * last), dt);
        let moved = (out.theta_c_deg - last).abs();
        assert!(
            moved <= rate * dt * (1.0 + 1e-12),
            "tick {k}: {moved} > {}",
            rate * dt
        );
        bound += usize::from(moved >= rate * dt * (1.0 - 1e-9));
        last = out.theta_c_deg;
    }
    assert!(bound > 500, "{bound}");
}

#[test]
fn a_non_finite_estimate_holds_the_command_and_is_reported() {
    let mut comp = compensator(free());
    let mut out = comp.step(0.0, Some(0.0), DT);
    for k in 1..=50 {
        out = comp.step(f64::from(k), Some(f64::from(k) - 3.0), DT);
    }
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let held = comp.step(51.0, Some(bad), DT);
        assert_eq!(held.theta_c_deg, out.theta_c_deg);
        assert!(
            matches!(held.fault, Some(Fault::NonFiniteEstimate { value }) if value.to_bits() == bad.to_bits()),
            "{held:?}"
        );
    }
    // the next finite estimate resumes
    let resumed = comp.step(51.0, Some(48.0), DT);
    assert!(resumed.fault.is_none());
    assert!(resumed.theta_c_deg > out.theta_c_deg);
}

#[test]
fn a_bad_theta_d_or_dt_holds_and_leaves_the_state_untouched() {
    let mut comp = compensator(free());
    for k in 0..30 {
        comp.step(f64::from(k), Some(f64::from(k) - 1.0), DT);
    }
    let mut twin = comp.clone();
    let held = comp.theta_c_deg();
    for (theta_d, dt) in [
        (f64::NAN, DT),
        (f64::INFINITY, DT),
        (40.0, 0.0),
        (40.0, -0.01),
        (40.0, f64::NAN),
        (40.0, 5.0),
    ] {
        let out = comp.step(theta_d, Some(20.0), dt);
        assert_eq!(out.theta_c_deg, held, "{theta_d} {dt}");
        match out.fault {
            Some(Fault::NonFiniteDesired { value }) => assert!(!value.is_finite()),
            Some(Fault::InvalidDt(range)) => {
                assert_eq!(range.name, "dt_s");
                assert!(!range.bounds.contains(dt) && range.bounds.contains(DT));
            }
            other => panic!("{theta_d} {dt}: {other:?}"),
        }
    }
    // the bad ticks changed nothing: the same next ticks as a twin that never saw them
    for k in 30..60 {
        let (a, b) = (f64::from(k), f64::from(k) - 1.0);
        assert_eq!(comp.step(a, Some(b), DT), twin.step(a, Some(b), DT));
    }
}

#[test]
fn the_watchdog_trips_after_the_timeout_and_clears_when_estimates_return() {
    // a dt and a timeout exact in binary: the trip tick is exact
    let dt = 1.0 / 64.0;
    let mut comp = compensator(CompensatorConfig {
        watchdog_timeout_s: 0.25,
        ..free()
    });
    for k in 0..20 {
        assert!(
            comp.step(f64::from(k), Some(f64::from(k)), dt)
                .fault
                .is_none()
        );
    }
    // estimates stop: 16 ticks (0.25 s) are fine, θ_c follows θ_d
    let mut theta_d = 20.0;
    for k in 1..=16 {
        theta_d += 1.0;
        let out = comp.step(theta_d, None, dt);
        assert!(out.fault.is_none(), "tick {k}: {out:?}");
        assert_eq!(out.estimate_age_s, f64::from(k) * dt);
    }
    let held = comp.theta_c_deg();
    for k in 17..=40 {
        theta_d += 1.0;
        let out = comp.step(theta_d, None, dt);
        assert_eq!(out.theta_c_deg, held);
        match out.fault {
            Some(Fault::Watchdog { age_s, timeout_s }) => {
                assert_eq!((age_s, timeout_s), (f64::from(k) * dt, 0.25));
            }
            other => panic!("tick {k}: {other:?}"),
        }
    }
    // an estimate clears it; the command moves again and stays clear between estimates
    let back = comp.step(theta_d, Some(theta_d - 1.0), dt);
    assert!(back.fault.is_none() && back.estimate_age_s == 0.0);
    assert!(back.theta_c_deg > held);
    assert!(comp.step(theta_d, None, dt).fault.is_none());
    // and it counts from a reset too
    comp.reset();
    let faults = (0..20)
        .filter(|_| comp.step(0.0, None, dt).fault.is_some())
        .count();
    assert_eq!(faults, 4);
}

#[test]
fn config_errors_name_the_field_and_unknown_fields_are_refused() {
    let range = |c: CompensatorConfig| match Compensator::new(c) {
        Err(e) => *e.range().expect("a range error"),
        Ok(_) => panic!("accepted {c:?}"),
    };
    let d = CompensatorConfig::default();
    assert_eq!(range(CompensatorConfig { kp: -1.0, ..d }).name, "kp");
    assert_eq!(
        range(CompensatorConfig {
            ki_per_s: f64::NAN,
            ..d
        })
        .name,
        "ki_per_s"
    );
    let r = range(CompensatorConfig {
        theta_c_max_deg: -120.0,
        ..d
    });
    assert_eq!((r.name, r.bounds.min), ("theta_c_max_deg", -120.0));
    let r = range(CompensatorConfig {
        integral_limit_deg: Some(0.0),
        ..d
    });
    assert_eq!(r.name, "integral_limit_deg");
    let r = range(CompensatorConfig {
        rate_limit_deg_per_s: 0.0,
        ..d
    });
    assert_eq!(r.name, "rate_limit_deg_per_s");
    let r = range(CompensatorConfig {
        watchdog_timeout_s: f64::INFINITY,
        ..d
    });
    assert_eq!(r.name, "watchdog_timeout_s");
    assert!(matches!(
        Compensator::new(CompensatorConfig { kd_s: 1e9, ..d }),
        Err(ControlError::OutOfRange(_))
    ));
    // serde: partial configs take the defaults; unknown fields are errors
    let c: CompensatorConfig = serde_json::from_str(
        r#"{"kp": 0.3, "backlash_term": "total_correction", "integral_limit_deg": null}"#,
    )
    .unwrap();
    assert_eq!(
        c,
        CompensatorConfig {
            kp: 0.3,
            backlash_term: BacklashTerm::TotalCorrection,
            integral_limit_deg: None,
            ..d
        }
    );
    let err = serde_json::from_str::<CompensatorConfig>(r#"{"k_p": 0.3}"#).unwrap_err();
    assert!(err.to_string().contains("k_p"), "{err}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Whatever comes in, θ_c is finite, inside the joint limits, and moves
    /// no faster than the rate limit.
    #[test]
    fn the_command_stays_finite_inside_the_limits(
        ticks in prop::collection::vec(
            (
                prop_oneof![4 => -500.0..500.0f64, 1 => Just(f64::NAN), 1 => Just(1e300)],
                prop_oneof![3 => (-200.0..200.0f64).prop_map(Some), 1 => Just(None), 1 => Just(Some(f64::INFINITY))],
                prop_oneof![4 => 1e-4..0.05f64, 1 => Just(0.0), 1 => Just(-1.0)],
            ),
            1..300,
        ),
        g in prop_oneof![Just(BacklashTerm::Off), Just(BacklashTerm::PidCorrection), Just(BacklashTerm::TotalCorrection)],
        kp in 0.0..100.0f64,
        ki in 0.0..1e4f64,
    ) {
        let config = CompensatorConfig {
            kp,
            ki_per_s: ki,
            backlash_term: g,
            theta_c_min_deg: -40.0,
            theta_c_max_deg: 70.0,
            ..CompensatorConfig::default()
        };
        let mut comp = compensator(config);
        let mut last = comp.theta_c_deg();
        for (theta_d, theta_hat, dt) in ticks {
            let out = comp.step(theta_d, theta_hat, dt);
            prop_assert!(out.theta_c_deg.is_finite());
            prop_assert!((-40.0..=70.0).contains(&out.theta_c_deg));
            if out.fault.is_none() {
                prop_assert!((out.theta_c_deg - last).abs() <= config.rate_limit_deg_per_s * dt * (1.0 + 1e-12));
            } else {
                prop_assert_eq!(out.theta_c_deg, last);
            }
            last = out.theta_c_deg;
        }
    }
}

#[test]
fn outputs_and_faults_serialise_for_logs() {
    // what an MCAP channel records per tick: the command, the terms and the fault by kind
    let dt = 1.0 / 64.0;
    let mut comp = compensator(CompensatorConfig {
        watchdog_timeout_s: 0.25,
        ..free()
    });
    let ok = comp.step(10.0, Some(8.0), dt);
    let v = serde_json::to_value(ok).unwrap();
    assert_eq!(v["theta_c_deg"], ok.theta_c_deg);
    assert_eq!(v["terms"]["p_deg"], ok.terms.p_deg);
    assert!(v["fault"].is_null());
    let tripped = (0..40)
        .map(|_| comp.step(10.0, None, dt))
        .find(|o| o.fault.is_some())
        .unwrap();
    let v = serde_json::to_value(tripped).unwrap();
    assert_eq!(v["fault"]["fault"], "watchdog");
    assert_eq!(v["fault"]["timeout_s"], 0.25);
    assert_eq!(v["fault"]["age_s"], tripped.estimate_age_s);
    // a bad dt names the quantity and its bounds; an infinite bound is null in JSON
    let bad = serde_json::to_value(comp.step(10.0, Some(9.0), -1.0)).unwrap();
    assert_eq!(bad["fault"]["fault"], "invalid_dt");
    assert_eq!(bad["fault"]["name"], "dt_s");
    assert_eq!(bad["fault"]["value"], -1.0);
    assert_eq!(bad["fault"]["bounds"]["min"], 0.0);
    assert_eq!(bad["fault"]["bounds"]["min_inclusive"], false);
    let nan = serde_json::to_value(comp.step(10.0, Some(f64::NAN), dt)).unwrap();
    assert_eq!(nan["fault"]["fault"], "non_finite_estimate");
    assert!(
        nan["fault"]["value"].is_null(),
        "NaN is null in JSON: {nan}"
    );
}
