//! The fusion filters on synthetic sensors over the kflex plant
//! (`common/fusion_scenario.rs`; `examples/fusion_table.rs` prints the table),
//! and their handling of rates, bad input and covariance.

mod common;

use common::fusion_scenario::{Scenario, fused, rmse, simulate, table_row};
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, EstimateError, FilterRate, Fusion, KalmanParams, Measurements,
    PaperKalman, SensorUse,
};
use proptest::prelude::*;

const KBJAE: usize = 0;
const IBJAE: usize = 1;
const AS_RUN: usize = 2;
const AS_WRITTEN: usize = 3;
const ADAPTIVE: usize = 4;

fn case(sheath_deg: f64, distal_occlusion: bool, confidence: bool) -> [f64; 5] {
    table_row(Scenario {
        sheath_deg,
        distal_occlusion,
        confidence,
        seed: 7,
    })
}

#[test]
fn adaptive_filter_is_never_worse_than_the_better_sensor_plus_half_a_degree() {
    for sheath_deg in [0.0, 270.0] {
        let r = case(sheath_deg, false, false);
        let better = r[KBJAE].min(r[IBJAE]);
        assert!(
            r[ADAPTIVE] <= better + 0.5,
            "sheath {sheath_deg}: adaptive {:.2} against the better sensor {better:.2} ({r:?})",
            r[ADAPTIVE]
        );
    }
}

#[test]
fn at_a_bent_sheath_the_adaptive_filter_learns_kbjaes_bias_from_the_camera() {
    // KBJAE, trained straight, misses the bent sheath's hysteresis; the
    // paper's filter averages it in, the adaptive one calibrates it away
    let r = case(270.0, false, false);
    assert!(r[KBJAE] > 3.0 * r[IBJAE], "{r:?}");
    assert!(r[AS_RUN] > 3.0 * r[ADAPTIVE], "{r:?}");
}

#[test]
fn under_distal_occlusion_at_a_bent_sheath_the_adaptive_filter_is_best() {
    for confidence in [false, true] {
        let r = case(270.0, true, confidence);
        for other in [KBJAE, IBJAE, AS_RUN, AS_WRITTEN] {
            assert!(r[ADAPTIVE] < r[other], "confidence {confidence}: {r:?}");
        }
    }
}

#[test]
fn under_distal_occlusion_at_a_straight_sheath_the_camera_needs_its_confidence() {
    // with IBJAE's own per-frame uncertainty the adaptive filter keeps most of
    // the hidden-tip frames out; without it, 60 % of frames that read the
    // joint a third as bent pull KBJAE's bias with them (BELOW GOAL: the
    // issue asks for the best of the three; CALIBRATION of this lives in the
    // crate docs, "Fusion")
    let given = case(0.0, true, true);
    assert!(given[ADAPTIVE] < given[AS_RUN], "{given:?}");
    assert!(given[ADAPTIVE] < given[IBJAE] / 4.0, "{given:?}");
    // frames that report themselves too uncertain are rejected: within
    // 0.5 deg of the better sensor (measured 1.34 against KBJAE's 1.27; the
    // goal of best of the three is not met)
    assert!(given[ADAPTIVE] < given[KBJAE] + 0.5, "{given:?}");
    let keep_all = kflex_estimate::AdaptiveParams {
        max_ibjae_sigma_deg: 1e9,
        ..Default::default()
    };
    let run = simulate(Scenario {
        sheath_deg: 0.0,
        distal_occlusion: true,
        confidence: true,
        seed: 1,
    });
    let mut all = kflex_estimate::AdaptiveKalman::new(keep_all).unwrap();
    let mut rejecting = kflex_estimate::AdaptiveKalman::new(Default::default()).unwrap();
    assert!(
        rmse(&run, &fused(&run, &mut rejecting)) < rmse(&run, &fused(&run, &mut all)),
        "rejecting unsure frames must help"
    );
    let blind = case(0.0, true, false);
    assert!(
        blind[ADAPTIVE] < 13.0,
        "no worse than measured (10.4): {blind:?}"
    );
    assert!(
        blind[ADAPTIVE] > blind[KBJAE],
        "if this fails the gap closed: {blind:?}"
    );
}

#[test]
fn the_paper_filter_stepped_as_written_lags_the_one_stepped_as_run() {
    // DESIGN.md, "Kalman rate": stepped every 0.1 s the constant-velocity
    // filter lags the 1 rad/s input by several degrees
    let r = case(0.0, false, false);
    assert!(r[AS_WRITTEN] > 3.0 * r[AS_RUN], "{r:?}");
}

/// θ̂ RMSE of the adaptive filter on a noiseless sine seen by both sensors
/// (KBJAE 3 deg high), stepped at `hz`.
fn adaptive_on_a_sine(hz: f64) -> f64 {
    let mut kf = AdaptiveKalman::new(AdaptiveParams::default()).unwrap();
    let dt = 1.0 / hz;
    let n = (20.0 * hz) as usize;
    let mut sum = 0.0;
    let mut count = 0;
    for k in 0..n {
        let t = k as f64 * dt;
        let truth = 25.0 * t.sin() + 25.0;
        // the camera at 30 Hz whatever the tick
        let frame = (t * 30.0).floor() != ((t - dt) * 30.0).floor();
        let e = kf
            .step(
                dt,
                Measurements {
                    kbjae_deg: Some(truth + 3.0),
                    ibjae_deg: frame.then_some(truth),
                    ibjae_sigma_deg: None,
                    ibjae_occluded: false,
                },
            )
            .unwrap();
        if t > 5.0 {
            sum += (e.theta_hat_deg - truth).powi(2);
            count += 1;
        }
    }
    (sum / f64::from(count)).sqrt()
}

#[test]
fn the_adaptive_filter_is_the_same_at_any_tick_rate() {
    let slow = adaptive_on_a_sine(100.0);
    let fast = adaptive_on_a_sine(1000.0);
    assert!(slow < 0.5 && fast < 0.5, "{slow} {fast}");
    assert!((slow - fast).abs() < 0.1, "100 Hz {slow}, 1 kHz {fast}");
}

#[test]
fn a_constant_kbjae_offset_becomes_its_bias() {
    let mut kf = AdaptiveKalman::new(AdaptiveParams::default()).unwrap();
    for _ in 0..2000 {
        kf.step(
            0.01,
            Measurements {
                kbjae_deg: Some(27.0),
                ibjae_deg: Some(20.0),
                ibjae_sigma_deg: None,
                ibjae_occluded: false,
            },
        )
        .unwrap();
    }
    assert!(
        (kf.kbjae_bias_deg() - 7.0).abs() < 0.05,
        "{}",
        kf.kbjae_bias_deg()
    );
    // the camera lost for 2 s: KBJAE carries on with the bias it had, which
    // relaxes toward 0 over bias_time_s (5 s) at most (KBJAE's own updates
    // keep some of it in the bias rather than the angle)
    let mut e = kf.estimate();
    for _ in 0..200 {
        e = kf
            .step(
                0.01,
                Measurements {
                    kbjae_deg: Some(27.0),
                    ..Default::default()
                },
            )
            .unwrap();
    }
    assert_eq!(e.ibjae, SensorUse::Missing);
    let kept = 7.0 * (-2.0f64 / 5.0).exp();
    let b = kf.kbjae_bias_deg();
    assert!(b > kept - 0.05 && b < 7.0 * (-1.0f64 / 5.0).exp(), "{b}");
    assert!(
        (e.theta_hat_deg + b - 27.0).abs() < 0.05,
        "{}",
        e.theta_hat_deg
    );
}

/// A camera reading that reports itself too uncertain (IBJAE's silhouette
/// check under tape) does not start the adaptive filter: fed from the first
/// tick with a camera 30 deg off that says so, the filter rejects it every
/// tick and follows KBJAE. (Started from the camera, it took KBJAE's
/// disagreement for KBJAE's bias, and the camera's readings were then
/// consistent with its state.)
#[test]
fn an_unsure_camera_does_not_start_the_filter() {
    let params = AdaptiveParams::default();
    let unsure = params.max_ibjae_sigma_deg + 1.0;
    let mut kf = AdaptiveKalman::new(params).unwrap();
    for k in 0..300 {
        let theta = 20.0 + 10.0 * (f64::from(k) * 0.01).sin();
        let e = kf
            .step(
                0.01,
                Measurements {
                    kbjae_deg: Some(theta),
                    // biased by the tape, and saying so
                    ibjae_deg: Some(theta + 30.0),
                    ibjae_sigma_deg: Some(unsure),
                    ibjae_occluded: false,
                },
            )
            .unwrap();
        assert!(
            matches!(e.ibjae, SensorUse::Gated { .. }),
            "tick {k}: {e:?}"
        );
        assert!((e.theta_hat_deg - theta).abs() < 1.0, "tick {k}: {e:?}");
    }
    assert!(kf.kbjae_bias_deg().abs() < 0.5, "{}", kf.kbjae_bias_deg());
    // a sure camera reading starts it as before
    let mut kf = AdaptiveKalman::new(params).unwrap();
    let e = kf
        .step(
            0.01,
            Measurements {
                kbjae_deg: Some(20.0),
                ibjae_deg: Some(25.0),
                ibjae_sigma_deg: Some(1.0),
                ibjae_occluded: false,
            },
        )
        .unwrap();
    assert!((e.theta_hat_deg - 25.0).abs() < 1.0, "{e:?}");
}

/// A camera reading that takes part of the instrument as hidden is no
/// absolute reference for the adaptive filter: rejected (it neither starts
/// the filter nor teaches KBJAE a bias), however sure it says it is; the
/// paper's filter takes it as any reading.
#[test]
fn the_adaptive_filter_rejects_readings_with_a_hidden_part() {
    let m = |theta: f64, occluded: bool| Measurements {
        kbjae_deg: Some(theta),
        // an occluder's bias, said with a small uncertainty
        ibjae_deg: Some(theta + 6.0),
        ibjae_sigma_deg: Some(1.0),
        ibjae_occluded: occluded,
    };
    let mut adaptive = AdaptiveKalman::new(AdaptiveParams::default()).unwrap();
    let mut paper = PaperKalman::new(KalmanParams::default()).unwrap();
    let mut paper_unflagged = paper.clone();
    let (mut taken, mut seen) = (adaptive.clone(), 0.0);
    for k in 0..300 {
        let theta = 20.0 + 10.0 * (f64::from(k) * 0.01).sin();
        let e = adaptive.step(0.01, m(theta, true)).unwrap();
        assert!(
            matches!(e.ibjae, SensorUse::Gated { .. }),
            "tick {k}: {e:?}"
        );
        assert!((e.theta_hat_deg - theta).abs() < 1.0, "tick {k}: {e:?}");
        // unflagged, the same readings set the angle
        let t = taken.step(0.01, m(theta, false)).unwrap();
        seen = t.theta_hat_deg - theta;
        // the paper's filter takes the flag for nothing
        let p = paper.step(0.01, m(theta, true)).unwrap();
        assert_eq!(p, paper_unflagged.step(0.01, m(theta, false)).unwrap());
    }
    assert!(
        adaptive.kbjae_bias_deg().abs() < 0.5,
        "{}",
        adaptive.kbjae_bias_deg()
    );
    assert!((seen - 6.0).abs() < 1.0, "unflagged: {seen}");
}

/// A stretch of readings IBJAE flags as unexplained (tape) makes the camera
/// trusted less, not more: once the tape is gone the estimate follows the
/// camera's scatter no more than a fresh filter's does. (Counted with their
/// flag's 45 deg, they scaled every later reading's uncertainty down to a
/// tenth.)
#[test]
fn flagged_readings_do_not_make_the_camera_trusted_more() {
    let params = AdaptiveParams::default();
    let step = |kf: &mut AdaptiveKalman, ibjae: Option<(f64, f64)>| {
        kf.step(
            0.01,
            Measurements {
                kbjae_deg: Some(20.0),
                ibjae_deg: ibjae.map(|r| r.0),
                ibjae_sigma_deg: ibjae.map(|r| r.1),
                ibjae_occluded: false,
            },
        )
        .unwrap()
    };
    let mut taped = AdaptiveKalman::new(params).unwrap();
    let mut fresh = AdaptiveKalman::new(params).unwrap();
    for k in 0..600 {
        // a sure start, then tape: 13 deg off, flagged
        let taped_reading = if k < 3 { (20.0, 1.0) } else { (33.0, 45.0) };
        step(&mut taped, Some(taped_reading));
        step(&mut fresh, (k < 3).then_some((20.0, 1.0)));
    }
    // the tape gone: clear readings that scatter 1 deg about the joint and
    // say so; the estimate scatters no more than a fresh filter's
    let scatter = |kf: &mut AdaptiveKalman| {
        let mut sum = 0.0;
        for k in 0..100 {
            let z = 20.0 + if k % 2 == 0 { 1.0 } else { -1.0 };
            let e = step(kf, Some((z, 1.0)));
            sum += (e.theta_hat_deg - 20.0).powi(2);
        }
        (sum / 100.0).sqrt()
    };
    let (t, f) = (scatter(&mut taped), scatter(&mut fresh));
    assert!(t <= f * 1.1, "after the tape {t:.3} deg, fresh {f:.3}");
}

#[test]
fn missing_measurements_skip_their_update() {
    let mut kf = PaperKalman::new(KalmanParams::default()).unwrap();
    let e = kf.step(0.01, Measurements::default()).unwrap();
    assert_eq!((e.kbjae, e.ibjae), (SensorUse::Missing, SensorUse::Missing));
    assert_eq!(e.theta_hat_deg, 0.0);
    let mut ad = AdaptiveKalman::new(AdaptiveParams::default()).unwrap();
    let e = ad.step(0.01, Measurements::default()).unwrap();
    assert_eq!(e.theta_hat_deg, 0.0);
    let e = ad
        .step(
            0.01,
            Measurements {
                kbjae_deg: Some(12.0),
                ..Default::default()
            },
        )
        .unwrap();
    assert_eq!((e.kbjae, e.ibjae), (SensorUse::Used, SensorUse::Missing));
    assert!(
        (e.theta_hat_deg - 12.0).abs() < 1e-9,
        "starts at the first measurement"
    );
}

/// Every rejected input leaves the filter exactly as it was.
fn rejects_unchanged(filter: &mut dyn Fusion) {
    for _ in 0..50 {
        filter
            .step(
                0.01,
                Measurements {
                    kbjae_deg: Some(10.0),
                    ibjae_deg: Some(11.0),
                    ibjae_sigma_deg: Some(2.0),
                    ibjae_occluded: false,
                },
            )
            .unwrap();
    }
    let before = filter.estimate();
    let good = Measurements {
        kbjae_deg: Some(10.0),
        ..Default::default()
    };
    let bad: [(f64, Measurements, &str); 9] = [
        (f64::NAN, good, "dt_s"),
        (0.0, good, "dt_s"),
        (-0.01, good, "dt_s"),
        (f64::INFINITY, good, "dt_s"),
        (
            0.01,
            Measurements {
                kbjae_deg: Some(f64::NAN),
                ..good
            },
            "kbjae_deg",
        ),
        (
            0.01,
            Measurements {
                ibjae_deg: Some(f64::NEG_INFINITY),
                ..good
            },
            "ibjae_deg",
        ),
        (
            0.01,
            Measurements {
                ibjae_sigma_deg: Some(-1.0),
                ..good
            },
            "ibjae_sigma_deg",
        ),
        // finite, but far enough to overflow the filter's arithmetic
        (
            0.01,
            Measurements {
                kbjae_deg: Some(f64::MAX),
                ..good
            },
            "kbjae_deg",
        ),
        (
            0.01,
            Measurements {
                ibjae_deg: Some(-1e300),
                ..good
            },
            "ibjae_deg",
        ),
    ];
    for (dt, m, name) in bad {
        let err = filter.step(dt, m).expect_err(name);
        let named = match &err {
            EstimateError::Model(kflex_model::ModelError::NonFinite { name: n, .. }) => *n,
            e => e.range().map_or("", |r| r.name),
        };
        assert_eq!(named, name, "{err}");
        assert_eq!(filter.estimate(), before, "{name} changed the filter");
    }
}

#[test]
fn bad_input_is_an_error_that_changes_nothing() {
    rejects_unchanged(&mut PaperKalman::new(KalmanParams::default()).unwrap());
    rejects_unchanged(
        &mut PaperKalman::new(KalmanParams {
            rate: FilterRate::AsWritten,
            ..KalmanParams::default()
        })
        .unwrap(),
    );
    rejects_unchanged(&mut AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
}

#[test]
fn meaningless_parameters_are_refused_by_name() {
    let e = PaperKalman::new(KalmanParams {
        model_dt_s: 0.0,
        ..KalmanParams::default()
    })
    .unwrap_err();
    assert_eq!(e.range().unwrap().name, "model_dt_s");
    let e = PaperKalman::new(KalmanParams {
        sigma_z_deg: [0.01, f64::NAN],
        ..KalmanParams::default()
    })
    .unwrap_err();
    assert_eq!(e.range().unwrap().name, "sigma_z_deg");
    let e = AdaptiveKalman::new(AdaptiveParams {
        gate: -1.0,
        ..AdaptiveParams::default()
    })
    .unwrap_err();
    assert_eq!(e.range().unwrap().name, "gate");
}

fn measurement() -> impl Strategy<Value = Option<f64>> {
    prop_oneof![Just(None), (-90.0f64..90.0).prop_map(Some)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn covariance_stays_symmetric_and_positive_semidefinite(
        ticks in proptest::collection::vec(
            (1e-4f64..0.2, measurement(), measurement(), proptest::option::of(0.0f64..30.0)),
            1..300,
        ),
        as_written in any::<bool>(),
    ) {
        let rate = if as_written { FilterRate::AsWritten } else { FilterRate::AsRun };
        let mut filters: Vec<Box<dyn Fusion>> = vec![
            Box::new(PaperKalman::new(KalmanParams { rate, ..KalmanParams::default() }).unwrap()),
            Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap()),
        ];
        for (dt, z1, z2, sigma) in ticks {
            let m = Measurements { kbjae_deg: z1, ibjae_deg: z2, ibjae_sigma_deg: sigma, ibjae_occluded: false };
            for f in &mut filters {
                let e = f.step(dt, m).unwrap();
                let [[a, b], [c, d]] = e.covariance;
                prop_assert_eq!(b, c);
                prop_assert!(a >= -1e-9 && d >= -1e-9, "{:?}", e.covariance);
                prop_assert!(a * d - b * c >= -1e-9 * (1.0 + a * d), "{:?}", e.covariance);
                prop_assert!(e.theta_hat_deg.is_finite() && e.theta_hat_rate_deg_per_s.is_finite());
            }
        }
    }
}

/// Every parameter and every input at the ends of its accepted range, in a
/// mixed order: the estimate stays finite, for both filters. (A `σ_z` of
/// 1e-200 deg was once accepted: its square is zero in `f64`, and the
/// paper's filter returned NaN from its first update.)
#[test]
fn the_filters_stay_finite_at_the_ends_of_every_range() {
    let dts = [1e-9, 1e-3, 3600.0];
    let zs = [None, Some(0.0), Some(1e6), Some(-1e6)];
    let sigmas = [None, Some(0.0), Some(1e-300), Some(1e6)];
    let mut ticks = Vec::new();
    for &dt in &dts {
        for &kb in &zs {
            for &ib in &zs {
                for &sg in &sigmas {
                    ticks.push((dt, kb, ib, sg));
                }
            }
        }
    }
    // a fixed shuffle: each tick after one far from it
    let order: Vec<usize> = (0..ticks.len()).map(|i| (i * 37) % ticks.len()).collect();
    let check = |name: String, filter: &mut dyn Fusion| {
        for &k in &order {
            let (dt, kb, ib, sg) = ticks[k];
            let m = Measurements {
                kbjae_deg: kb,
                ibjae_deg: ib,
                ibjae_sigma_deg: sg,
                ibjae_occluded: false,
            };
            let e = filter.step(dt, m).unwrap();
            let finite = e.theta_hat_deg.is_finite()
                && e.theta_hat_rate_deg_per_s.is_finite()
                && e.covariance.iter().flatten().all(|c| c.is_finite());
            assert!(finite, "{name}: tick {dt} s {m:?} gave {e:?}");
        }
    };
    for sz in [1e-6, 1e6] {
        for sa in [0.0, 1e-300, 1e6] {
            for model_dt_s in [1e-300, 3600.0] {
                let p = KalmanParams {
                    sigma_z_deg: [sz, sz],
                    sigma_a: sa,
                    model_dt_s,
                    ..KalmanParams::default()
                };
                check(format!("{p:?}"), &mut PaperKalman::new(p).unwrap());
            }
        }
    }
    for sz in [1e-6, 1e3] {
        for accel in [1e-300, 1e9] {
            for bias in [0.0, 1e-300, 1e3] {
                let p = AdaptiveParams {
                    initial_sigma_z_deg: [sz, sz],
                    min_sigma_z_deg: sz,
                    accel_psd_deg2_per_s3: accel,
                    bias_sigma_deg: bias,
                    ..AdaptiveParams::default()
                };
                check(format!("{p:?}"), &mut AdaptiveKalman::new(p).unwrap());
            }
        }
    }
    // below the least σ_z: refused, not run
    let tiny = KalmanParams {
        sigma_z_deg: [1e-200, 0.01],
        ..KalmanParams::default()
    };
    assert!(matches!(
        PaperKalman::new(tiny),
        Err(EstimateError::OutOfRange(_))
    ));
    let tiny = AdaptiveParams {
        min_sigma_z_deg: 1e-300,
        ..AdaptiveParams::default()
    };
    assert!(matches!(
        AdaptiveKalman::new(tiny),
        Err(EstimateError::OutOfRange(_))
    ));
}
