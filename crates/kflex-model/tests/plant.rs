//! Behaviour of the whole plant: joint models agree, determinism, bad input.

use kflex_model::{
    AuroraNoise, BUILD_SHARE, Bounds, Command, HOMING_SHARE, JointModelKind, JointParams,
    ModelError, Plant, PlantConfig, PlantState, RangeError, Seating, SheathParams, TendonGeometry,
    Trajectory,
};
use proptest::prelude::*;

fn command(theta_c_deg: f64, translation_mm: f64) -> Command {
    Command {
        theta_c_deg,
        translation_mm,
    }
}

/// Steps `plant` for k = 1..=n with θ_c = theta(k) deg at translation 0, returns the last state.
fn ramp(plant: &mut Plant, n: u32, dt: f64, theta: impl Fn(f64) -> f64) -> PlantState {
    let mut last = *plant.state();
    for k in 1..=n {
        let command = Command {
            theta_c_deg: theta(f64::from(k)),
            translation_mm: 0.0,
        };
        last = plant.step(command, dt).unwrap();
    }
    last
}

fn drive(config: PlantConfig, seconds: f64, dt: f64) -> Vec<f64> {
    let mut plant = Plant::new(config).unwrap();
    let traj = Trajectory::paper().sampler().unwrap();
    let n = (seconds / dt) as usize;
    (0..n)
        .map(|k| {
            let theta = traj
                .sample(k as f64 * dt)
                .theta_d_deg
                .min(25.0 * (k as f64 * dt)); // gentle start
            plant
                .step(
                    Command {
                        theta_c_deg: theta,
                        translation_mm: 5.0,
                    },
                    dt,
                )
                .unwrap()
                .theta_a_deg
        })
        .collect()
}

#[cfg(feature = "multibody")]
#[test]
fn rapier_and_analytic_joints_agree_without_load() {
    let joint = JointParams {
        gravity_m_per_s2: [0.0; 3],
        tip_load_n: [0.0; 3],
        ..JointParams::default()
    };
    for sheath_deg in [0.0, 180.0] {
        let base = PlantConfig {
            joint,
            sheath_deg,
            ..PlantConfig::default()
        };
        let analytic = drive(base, 8.0, 0.02);
        let rapier = drive(
            PlantConfig {
                joint_model: JointModelKind::Rapier,
                ..base
            },
            8.0,
            0.02,
        );
        let worst = analytic
            .iter()
            .zip(&rapier)
            .map(|(a, r)| (a - r).abs())
            .fold(0.0, f64::max);
        let range = analytic.iter().cloned().fold(f64::MIN, f64::max);
        assert!(range > 10.0, "the joint should move: max {range}");
        assert!(
            worst < 0.1,
            "sheath {sheath_deg}: joint models differ by {worst} deg"
        );
    }
}

#[cfg(feature = "multibody")]
#[test]
fn rapier_gravity_and_tip_load_bend_the_joint_as_the_analytic_model_does() {
    // a heavy tool and a push on the tip: both models move the same way, by a similar amount
    let joint = JointParams {
        tool_mass_g: 30.0,
        tip_load_n: [-0.3, 0.0, 0.0],
        ..JointParams::default()
    };
    let unloaded = JointParams {
        gravity_m_per_s2: [0.0; 3],
        tip_load_n: [0.0; 3],
        ..joint
    };
    let settle = |joint: JointParams, model| {
        let mut plant = Plant::new(PlantConfig {
            joint,
            joint_model: model,
            ..PlantConfig::default()
        })
        .unwrap();
        ramp(&mut plant, 100, 0.02, |k| 0.3 * k).theta_a_deg
    };
    for model in [JointModelKind::Analytic, JointModelKind::Rapier] {
        let drop = settle(unloaded, model) - settle(joint, model);
        assert!(
            drop > 1.0,
            "{model:?}: loads should lower the bend, dropped {drop}"
        );
    }
    let a = settle(unloaded, JointModelKind::Analytic) - settle(joint, JointModelKind::Analytic);
    let r = settle(unloaded, JointModelKind::Rapier) - settle(joint, JointModelKind::Rapier);
    assert!((a - r).abs() < 0.25 * a, "analytic drop {a} vs rapier {r}");
}

/// Built without the rapier joint, a configuration that asks for it is refused by name.
#[cfg(not(feature = "multibody"))]
#[test]
fn the_rapier_joint_needs_the_multibody_feature() {
    let err = Plant::new(PlantConfig {
        joint_model: JointModelKind::Rapier,
        ..PlantConfig::default()
    })
    .unwrap_err();
    assert_eq!(
        err,
        ModelError::FeatureDisabled {
            what: "joint_model = rapier",
            feature: "multibody",
        }
    );
    assert!(err.to_string().contains("\"multibody\""), "{err}");
}

#[test]
fn same_seed_same_run_other_seed_other_noise() {
    let config = PlantConfig {
        noise: Some(AuroraNoise::default()),
        seed: 5,
        ..PlantConfig::default()
    };
    let run = |config: PlantConfig| {
        let mut plant = Plant::new(config).unwrap();
        (0..200)
            .map(|k| {
                plant
                    .step(
                        Command {
                            theta_c_deg: f64::from(k) * 0.2,
                            translation_mm: 1.0,
                        },
                        0.01,
                    )
                    .unwrap()
            })
            .collect::<Vec<_>>()
    };
    let (a, b, c) = (
        run(config),
        run(config),
        run(PlantConfig { seed: 6, ..config }),
    );
    assert_eq!(a, b);
    assert!(
        a.iter()
            .zip(&c)
            .any(|(x, y)| x.theta_a_measured_deg != y.theta_a_measured_deg)
    );
    // noise touches the measurement only
    assert!(
        a.iter()
            .zip(&c)
            .all(|(x, y)| x.theta_a_deg == y.theta_a_deg)
    );
    // reset gives the same run again
    let mut plant = Plant::new(config).unwrap();
    plant
        .step(
            Command {
                theta_c_deg: 40.0,
                translation_mm: 1.0,
            },
            0.01,
        )
        .unwrap();
    plant.reset().unwrap();
    let first = plant
        .step(
            Command {
                theta_c_deg: 0.0,
                translation_mm: 1.0,
            },
            0.01,
        )
        .unwrap();
    assert_eq!(first, a[0]);
}

#[test]
fn hysteresis_grows_with_the_sheath_bend() {
    // the error at the same command on the way up grows with the bend (the mechanism, not a table)
    let lag = |sheath_deg| {
        let d = drive(
            PlantConfig {
                sheath_deg,
                ..PlantConfig::default()
            },
            4.0,
            0.01,
        );
        let traj = Trajectory::paper().sampler().unwrap();
        traj.sample(1.5).theta_d_deg - d[150]
    };
    let lags: Vec<f64> = [0.0, 90.0, 180.0, 270.0].into_iter().map(lag).collect();
    assert!(lags.windows(2).all(|w| w[1] > w[0]), "{lags:?}");
}

#[test]
fn bad_commands_are_typed_errors_and_change_nothing() {
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    plant
        .step(
            Command {
                theta_c_deg: 20.0,
                translation_mm: 3.0,
            },
            0.01,
        )
        .unwrap();
    let before = *plant.state();
    // each bad command, the error it must give (variant, quantity, value)
    let cases: [(Command, f64, &str, &str, f64); 7] = [
        (
            command(f64::NAN, 3.0),
            0.01,
            "NonFinite",
            "theta_c_deg",
            f64::NAN,
        ),
        (
            command(f64::INFINITY, 3.0),
            0.01,
            "NonFinite",
            "theta_c_deg",
            f64::INFINITY,
        ),
        (
            command(200.0, 3.0),
            0.01,
            "OutOfWorkspace",
            "theta_c_deg",
            200.0,
        ),
        (
            command(10.0, -1.0),
            0.01,
            "OutOfWorkspace",
            "translation_mm",
            -1.0,
        ),
        (command(10.0, 3.0), 0.0, "OutOfRange", "dt_s", 0.0),
        (command(10.0, 3.0), -0.01, "OutOfRange", "dt_s", -0.01),
        (command(10.0, 3.0), f64::NAN, "OutOfRange", "dt_s", f64::NAN),
    ];
    let same = |a: f64, b: f64| a == b || (a.is_nan() && b.is_nan());
    for (command, dt, variant, name, value) in cases {
        let err = plant.step(command, dt).unwrap_err();
        let ok = match (&err, variant) {
            (ModelError::NonFinite { name: n, value: v }, "NonFinite") => {
                *n == name && same(*v, value)
            }
            (ModelError::OutOfWorkspace(e), "OutOfWorkspace")
            | (ModelError::OutOfRange(e), "OutOfRange") => e.name == name && same(e.value, value),
            _ => false,
        };
        assert!(
            ok,
            "{command:?} dt={dt}: expected {variant} of {name} = {value}, got {err:?}"
        );
        assert_eq!(
            *plant.state(),
            before,
            "{command:?} dt={dt} changed the state"
        );
    }
    let err = plant
        .step(
            Command {
                theta_c_deg: 200.0,
                translation_mm: 3.0,
            },
            0.01,
        )
        .unwrap_err();
    assert_eq!(
        err,
        ModelError::OutOfWorkspace(RangeError {
            name: "theta_c_deg",
            value: 200.0,
            bounds: Bounds::closed(-120.0, 120.0),
        })
    );
    assert!(err.to_string().contains("[-120, 120]"), "{err}");
    // and it carries on normally afterwards
    assert!(
        plant
            .step(
                Command {
                    theta_c_deg: 21.0,
                    translation_mm: 3.0
                },
                0.01
            )
            .is_ok()
    );
}

#[test]
fn meaningless_parameters_are_rejected_by_name() {
    let cases: Vec<(PlantConfig, &str)> = vec![
        (
            PlantConfig {
                sheath: SheathParams {
                    friction_coefficient: -0.1,
                    ..SheathParams::default()
                },
                ..PlantConfig::default()
            },
            "friction_coefficient",
        ),
        (
            PlantConfig {
                sheath_deg: -90.0,
                ..PlantConfig::default()
            },
            "sheath_deg",
        ),
        (
            PlantConfig {
                joint: JointParams {
                    link_mass_g: 0.0,
                    ..JointParams::default()
                },
                ..PlantConfig::default()
            },
            "link_mass_g",
        ),
        (
            PlantConfig {
                joint: JointParams {
                    contact_stiffness_nmm_per_rad: f64::NAN,
                    ..JointParams::default()
                },
                ..PlantConfig::default()
            },
            "contact_stiffness",
        ),
        (
            PlantConfig {
                geometry: kflex_model::TendonGeometry {
                    n_segments: 0,
                    ..Default::default()
                },
                ..PlantConfig::default()
            },
            "n_segments",
        ),
        (
            PlantConfig {
                noise: Some(AuroraNoise {
                    theta_std_deg: -1.0,
                    translation_std_mm: 0.1,
                }),
                ..PlantConfig::default()
            },
            "theta_std_deg",
        ),
    ];
    for (config, name) in cases {
        let err = Plant::new(config).unwrap_err().to_string();
        assert!(err.contains(name), "expected {name} in: {err}");
    }
}

#[test]
fn translation_follows_within_its_speed_limit() {
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let s = plant
        .step(
            Command {
                theta_c_deg: 0.0,
                translation_mm: 30.0,
            },
            0.1,
        )
        .unwrap();
    assert!(
        (s.translation_mm - 2.0).abs() < 1e-12,
        "20 mm/s for 0.1 s: {}",
        s.translation_mm
    );
    for _ in 0..20 {
        plant
            .step(
                Command {
                    theta_c_deg: 0.0,
                    translation_mm: 30.0,
                },
                0.1,
            )
            .unwrap();
    }
    assert_eq!(plant.state().translation_mm, 30.0);
}

#[test]
fn joint_range_covers_over_and_undershoot() {
    // commands beyond the paper's 0–50 deg working range are accepted and followed
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let mut low = 0.0f64;
    for k in 0..300 {
        low = plant
            .step(
                Command {
                    theta_c_deg: -0.3 * f64::from(k),
                    translation_mm: 0.0,
                },
                0.01,
            )
            .unwrap()
            .theta_a_deg;
    }
    assert!(low < -45.0, "{low}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]
    #[test]
    fn state_stays_finite_and_in_range(
        commands in prop::collection::vec((-120.0f64..120.0, 0.0f64..40.0, 1e-4f64..0.5), 1..80),
        sheath_deg in 0.0f64..400.0,
        homing in -1.0f64..=1.0,
    ) {
        // a drive homed off the middle of its play strokes past the stop's
        // stroke by up to its half-width, all run
        let seating = Seating { backlash: homing, ..Seating::default() };
        let mut plant = Plant::new(PlantConfig { sheath_deg, seating, ..PlantConfig::default() }).unwrap();
        for (theta_deg, translation_mm, dt) in commands {
            let s = plant.step(Command { theta_c_deg: theta_deg, translation_mm }, dt).unwrap();
            for v in [s.theta_a_deg, s.translation_mm, s.differential_force_n, s.tensions.a_distal_n, s.tensions.b_distal_n,
                      s.tensions.a_proximal_n, s.tensions.b_proximal_n, s.friction_state] {
                prop_assert!(v.is_finite());
            }
            prop_assert!(s.theta_a_deg.abs() <= 120.0 + 1e-9);
            prop_assert!(s.tensions.a_distal_n >= 0.0 && s.tensions.b_distal_n >= 0.0);
            prop_assert!(s.friction_state.abs() <= 1.0 + 1e-12);
        }
    }
}

/// Output swing and dead zone of one cycle of the paper's input after one warm-up cycle:
/// (θ_a max − θ_a min, command travel after the top reversal before θ_a has fallen 0.5 deg).
fn swing_and_dead_zone(sheath_deg: f64) -> (f64, f64) {
    let mut plant = Plant::new(PlantConfig {
        sheath_deg,
        ..PlantConfig::default()
    })
    .unwrap();
    let traj = Trajectory::Sine(kflex_model::Sine {
        phase_rad: -std::f64::consts::FRAC_PI_2,
        ..kflex_model::Sine::PAPER
    })
    .sampler()
    .unwrap();
    let dt = 0.005;
    let period = 1.0 / 0.159;
    let n = (2.0 * period / dt) as usize;
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let s = traj.sample(k as f64 * dt);
        out.push((
            s.theta_d_deg,
            plant
                .step(
                    Command {
                        theta_c_deg: s.theta_d_deg,
                        translation_mm: 0.0,
                    },
                    dt,
                )
                .unwrap()
                .theta_a_deg,
        ));
    }
    let second = &out[n / 2..];
    let hi = second.iter().map(|p| p.1).fold(f64::MIN, f64::max);
    let lo = second.iter().map(|p| p.1).fold(f64::MAX, f64::min);
    // top reversal of the command in the second cycle: its maximum
    let top = (0..second.len())
        .max_by(|&a, &b| second[a].0.total_cmp(&second[b].0))
        .unwrap();
    let theta_at_top = second[top].1.max(
        second[top..]
            .iter()
            .take(50)
            .map(|p| p.1)
            .fold(f64::MIN, f64::max),
    );
    let moved = second[top..]
        .iter()
        .position(|p| p.1 < theta_at_top - 0.5)
        .unwrap();
    (hi - lo, second[top].0 - second[top + moved].0)
}

#[test]
fn lost_motion_and_dead_zone_grow_with_the_bend() {
    let results: Vec<(f64, f64)> = [0.0, 90.0, 180.0, 270.0]
        .into_iter()
        .map(swing_and_dead_zone)
        .collect();
    for w in results.windows(2) {
        assert!(
            w[1].0 < w[0].0,
            "output swing should shrink (lost motion grows): {results:?}"
        );
        assert!(
            w[1].1 > w[0].1,
            "dead zone after reversal should grow: {results:?}"
        );
    }
    // the straight sheath still has a dead zone (drive backlash) but follows most of the 50 deg
    assert!(results[0].0 > 30.0 && results[0].1 > 1.0, "{results:?}");
}

#[test]
fn sheath_friction_develops_and_reverses_with_the_motion() {
    // the friction state follows the direction of travel (guards the plant's commit of it)
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 180.0,
        ..PlantConfig::default()
    })
    .unwrap();
    let z_up = ramp(&mut plant, 300, 0.01, |k| 0.15 * k).friction_state;
    let z_down = ramp(&mut plant, 300, 0.01, |k| 45.0 - 0.15 * k).friction_state;
    assert!(z_up > 0.5 && z_down < -0.5, "z up {z_up}, down {z_down}");
}

#[test]
fn joint_follows_its_path_under_compressive_tip_loads() {
    // (review) with a tip load pushing back, the balance has several roots; the
    // joint must move continuously to the one it reaches, never jump to another.
    // Loads stay below buckling: a larger axial push makes the joint snap
    // through, which is physics, not a solver fault. A lagging joint has
    // slackened one tendon (the motors paid out Eq. 1's common mode for the
    // commanded angle, and the bent sheath shortens the tendons' paths), and
    // with one tendon holding about 1 N of axial push already snaps it through.
    for (sheath_deg, load) in [
        (90.0, [-0.5, 0.0, -0.5]),
        (180.0, [-1.0, 0.0, -0.6]),
        (270.0, [0.5, 0.0, -0.5]),
    ] {
        let joint = JointParams {
            tip_load_n: load,
            ..JointParams::default()
        };
        let mut plant = Plant::new(PlantConfig {
            sheath_deg,
            joint,
            ..PlantConfig::default()
        })
        .unwrap();
        let mut last = 0.0f64;
        for k in 0..1300 {
            let theta_c_deg = 50.0 * (std::f64::consts::TAU * f64::from(k) / 629.0).sin();
            let s = plant
                .step(
                    Command {
                        theta_c_deg,
                        translation_mm: 0.0,
                    },
                    0.01,
                )
                .unwrap_or_else(|e| panic!("sheath {sheath_deg}, load {load:?}, tick {k}: {e}"));
            // tick 0 settles under the load from the unloaded reset pose; from then on, continuity
            assert!(
                k == 0 || (s.theta_a_deg - last).abs() < 5.0 || s.theta_a_deg.abs() >= 119.999,
                "sheath {sheath_deg}, load {load:?}: tick {k} jumped {last:.2} -> {:.2}",
                s.theta_a_deg
            );
            last = s.theta_a_deg;
        }
    }
}

/// The parameters `perturbed` draws: name, where it lives, and its share of
/// the spread (the set-up's 1, the build's `BUILD_SHARE`).
type Get = fn(&PlantConfig) -> f64;
const SPREAD: [(&str, Get, f64); 10] = [
    ("μ", |c| c.sheath.friction_coefficient, 1.0),
    ("route wrap", |c| c.sheath.route_wrap_deg, 1.0),
    ("pretension", |c| c.sheath.pretension_n, 1.0),
    ("pre-sliding", |c| c.sheath.presliding_mm, 1.0),
    (
        "tendon stiffness",
        |c| c.sheath.tendon_stiffness_n_per_mm,
        BUILD_SHARE,
    ),
    (
        "distal stiffness",
        |c| c.sheath.distal_stiffness_n_per_mm,
        BUILD_SHARE,
    ),
    ("backlash", |c| c.sheath.drive_backlash_mm, BUILD_SHARE),
    (
        "engagement",
        |c| c.sheath.backlash_engagement_mm,
        BUILD_SHARE,
    ),
    (
        "path change",
        |c| c.sheath.sheath_path_mm_per_rad,
        BUILD_SHARE,
    ),
    (
        "contact stiffness",
        |c| c.joint.contact_stiffness_nmm_per_rad,
        BUILD_SHARE,
    ),
];

#[test]
fn a_perturbed_config_reports_the_value_as_given() {
    // the check runs before the spread is drawn: μ = −0.2 is reported as −0.2,
    // not as the scaled −0.2029… a perturbed copy would have
    let mut config = PlantConfig::default();
    config.sheath.friction_coefficient = -0.2;
    let err = config.perturbed(7, 0.15).unwrap_err();
    let range = err.range().expect("a range error");
    assert_eq!((range.name, range.value), ("friction_coefficient", -0.2));
    // each of these physical parameters is spread, and the seating is drawn
    let nominal = PlantConfig::default();
    let p = nominal.perturbed(7, 0.15).unwrap();
    for (name, get, _) in SPREAD {
        let (a, b) = (get(&p), get(&nominal));
        assert!(a != b && (a / b - 1.0).abs() <= 0.5, "{name}: {a} vs {b}");
    }
    assert!(p.seating != nominal.seating && p.seating.validate().is_ok());
    // no spread: the nominal plant at rest
    assert_eq!(nominal.perturbed(7, 0.0).unwrap(), nominal);
    Plant::new(p).unwrap();
}

#[test]
fn a_sheath_angle_the_config_accepts_every_repeat_accepts() {
    // the element chain resolves μ (Φ₀ + Φ_s) ≤ elements rad: 10 elements at
    // μ = 0.3 take 1,910 deg in all, so the nominal accepts a 1,500 deg
    // sheath; a repeat that drew μ up to 1.5 times would refuse it with a
    // bound of its own, so a draw past the limit is held at it
    let mut config = PlantConfig {
        sheath_deg: 1500.0,
        ..PlantConfig::default()
    };
    config.sheath.elements = 10;
    config.sheath.friction_coefficient = 0.3;
    Plant::new(config).unwrap();
    let mut held = 0;
    for seed in 0..40 {
        let p = config.perturbed(seed, 0.5).unwrap();
        // (the route wrap is drawn too)
        let limit =
            f64::from(p.sheath.elements) / (p.sheath.route_wrap_deg + p.sheath_deg).to_radians();
        assert!(p.sheath.friction_coefficient <= limit, "seed {seed}");
        held += usize::from(p.sheath.friction_coefficient > 0.999 * limit);
        Plant::new(p).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
    }
    assert!(
        held > 0,
        "no draw reached the limit: the test shows nothing"
    );
    // past the limit the configuration itself is refused, with its own
    // bound, by its own check (before the translation stage's, which comes
    // later in the order)
    let mut past = PlantConfig {
        sheath_deg: 1950.0,
        ..config
    };
    past.translation.max_mm = f64::NAN;
    let err = past.validate().unwrap_err();
    let range = err.range().expect("a range error");
    assert_eq!((range.name, range.value), ("sheath_deg", 1950.0));
    assert_eq!(range.bounds.max, config.sheath.max_sheath_deg());
    assert!(range.bounds.max > 1890.0 && range.bounds.max < 1950.0);
}

#[test]
fn every_drawn_value_stays_in_its_range() {
    // values near the top of their ranges, drawn up to 1.5 times: each draw
    // is held inside what `validate` allows
    let mut config = PlantConfig::default();
    config.sheath.pretension_n = 900.0;
    config.sheath.sheath_path_mm_per_rad = -0.9;
    config.sheath.tendon_stiffness_n_per_mm = 9e5;
    config.sheath.distal_stiffness_n_per_mm = 9e6;
    config.sheath.drive_backlash_mm = 9.0;
    config.joint.contact_stiffness_nmm_per_rad = 9e5;
    config.validate().unwrap();
    let mut held = 0;
    for seed in 0..40 {
        let p = config.perturbed(seed, 0.5).unwrap();
        p.validate().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        held += usize::from(p.sheath.pretension_n == 1e3);
    }
    assert!(held > 0, "no draw reached the top: the test shows nothing");
}

/// Mean θ_a over the last period of the paper's input on `config`'s plant.
fn mean_theta_last_period(config: PlantConfig) -> f64 {
    let dt = 0.01;
    let trace = drive(config, 3.0 / 0.159, dt);
    let period = (1.0 / 0.159 / dt) as usize;
    trace[trace.len() - period..].iter().sum::<f64>() / period as f64
}

#[test]
fn the_drive_is_homed_with_the_joint_straight_and_its_zero_stays_where_it_fell() {
    // seating.backlash places the motor's zero inside the drive's play: the
    // joint starts straight whatever it is, and the offset lasts all run
    let b = PlantConfig::default().sheath.drive_backlash_mm;
    let play_deg = TendonGeometry::default()
        .theta_rad_from_stroke(b)
        .unwrap()
        .to_degrees();
    let homed = |backlash: f64| PlantConfig {
        seating: Seating {
            backlash,
            ..Seating::default()
        },
        ..PlantConfig::default()
    };
    let start = |side: f64| {
        let mut plant = Plant::new(homed(side)).unwrap();
        plant.step(command(0.0, 0.0), 0.01).unwrap().theta_a_deg
    };
    // (where the tool's weight alone holds it: gravity is on)
    for side in [-1.0, 1.0] {
        assert!(
            (start(side) - start(0.0)).abs() < 1e-9,
            "{side}: starts at {}",
            start(side)
        );
    }
    // zero at the play's −1 end: every command lands one half-width further
    let (low, mid, high) = (
        mean_theta_last_period(homed(-1.0)),
        mean_theta_last_period(homed(0.0)),
        mean_theta_last_period(homed(1.0)),
    );
    for (shift, expected) in [(low - mid, play_deg), (mid - high, play_deg)] {
        assert!(
            shift > 0.7 * expected && shift < 1.1 * expected,
            "shift {shift:.2} deg for a half-width of {expected:.2} deg"
        );
    }
}

#[test]
fn a_repeat_spreads_the_set_up_more_than_the_build() {
    // each parameter's relative spread over many draws: the set-up's at the
    // full spread, the build's at BUILD_SHARE of it
    let nominal = PlantConfig::default();
    let drawn: Vec<PlantConfig> = (0..400)
        .map(|seed| nominal.perturbed(seed, 0.15).unwrap())
        .collect();
    for (name, get, share) in SPREAD {
        let rel: Vec<f64> = drawn.iter().map(|p| get(p) / get(&nominal) - 1.0).collect();
        let std = (rel.iter().map(|x| x * x).sum::<f64>() / rel.len() as f64).sqrt();
        assert!(
            (std / (0.15 * share) - 1.0).abs() < 0.15,
            "{name}: spread {std:.4}, expected {:.4}",
            0.15 * share
        );
    }
    // the drive homed over the middle of its play, uniformly
    let homing: Vec<f64> = drawn.iter().map(|p| p.seating.backlash).collect();
    let widest = homing.iter().fold(0.0f64, |m, h| m.max(h.abs()));
    assert!(
        widest <= HOMING_SHARE && widest > 0.95 * HOMING_SHARE,
        "{widest}"
    );
}

#[test]
fn a_reset_homes_the_drive_again() {
    // after a run, reset gives the plant a fresh one gives, homing included
    let config = PlantConfig {
        seating: Seating {
            backlash: -0.8,
            ..Seating::default()
        },
        ..PlantConfig::default()
    };
    let mut used = Plant::new(config).unwrap();
    ramp(&mut used, 300, 0.01, |k| 40.0 * (k / 100.0).sin().abs());
    used.reset().unwrap();
    let mut fresh = Plant::new(config).unwrap();
    for k in 1..=200 {
        let c = command(0.2 * f64::from(k), 0.0);
        assert_eq!(used.step(c, 0.01).unwrap(), fresh.step(c, 0.01).unwrap());
    }
}
