//! The paper's estimators in the closed loop, on the small test models of
//! `kflex-estimate` (random weights: the mechanics, not the accuracy).
#![cfg(feature = "estimators")]

use std::path::{Path, PathBuf};

use kflex_control::{
    AngleEstimator, ClosedLoopScenario, IbjaeAlone, OpenLoopScenario, Result as ControlResult,
};
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, Fusion, Ibjae, Kbjae, Lbhjae, Scnn, SegmentParams,
    build_band_database,
};
use kflex_model::{Camera, Instrument, Plant, PlantConfig, PoseRange, Roi, WorkingBand};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../kflex-estimate/tests/data")
        .join(name)
}

/// IBJAE on the paper's band (θ 0–50° at d = 10 mm, the paper's region),
/// its database from the nominal instrument and camera.
fn ibjae() -> Ibjae {
    let camera = Camera::default();
    let band = WorkingBand {
        poses: PoseRange {
            theta_deg: [0.0, 50.0],
            translation_mm: [10.0, 10.0],
        },
        roi: Roi::paper(&camera).unwrap(),
    };
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let db =
        build_band_database(&mut scnn, &camera, &Instrument::kflex(), &band, 1.0, 1.0).unwrap();
    Ibjae::new(scnn, SegmentParams::default(), vec![db]).unwrap()
}

fn plant() -> Plant {
    Plant::new(PlantConfig {
        noise: None,
        ..PlantConfig::default()
    })
    .unwrap()
}

/// Half a period of the paper's input after a short pre-roll, estimation only.
fn scenario() -> ClosedLoopScenario {
    ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 0.5,
            pre_roll_s: 0.5,
            ..OpenLoopScenario::default()
        },
        compensator: None,
        ..ClosedLoopScenario::default()
    }
}

fn run(estimator: &mut dyn AngleEstimator) -> ControlResult<kflex_control::ClosedLoopTrace> {
    scenario().run(&mut plant(), estimator, 4)
}

#[test]
fn kbjae_estimates_every_tick_without_frames() {
    let mut kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let out = run(&mut kbjae).unwrap();
    assert_eq!(out.frames.captured, 0);
    assert!(
        out.theta_hat_deg
            .iter()
            .all(|h| h.is_some_and(f64::is_finite))
    );
}

#[test]
fn ibjae_reads_the_window_of_its_band_and_holds_between_frames() {
    let mut ibjae = IbjaeAlone::new(ibjae());
    let out = run(&mut ibjae).unwrap();
    assert!(out.frames.delivered > 50, "{:?}", out.frames);
    let hats: Vec<f64> = out.theta_hat_deg.iter().map(|h| h.unwrap()).collect();
    // held between frames: it changes at most once per frame
    let changes = hats.windows(2).filter(|w| w[0] != w[1]).count();
    assert!(changes <= out.frames.delivered, "{changes}");
    assert!(changes > 5, "{changes}");
    // the as-built robot against the nominal database, read by a random
    // SCNN: near, not exact
    let e = out.estimation_rmse_deg().unwrap();
    assert!(e < 10.0, "IBJAE RMSE {e} deg");
}

#[test]
fn lbhjae_closes_the_loop() {
    let kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
    let mut lbhjae = Lbhjae::new(kbjae, ibjae(), fusion);
    let compensated = ClosedLoopScenario {
        compensator: Some(Default::default()),
        ..scenario()
    };
    let out = compensated.run(&mut plant(), &mut lbhjae, 4).unwrap();
    assert_eq!(out.fault_ticks, 0);
    assert!(out.frames.delivered > 50, "{:?}", out.frames);
    assert!(out.theta_c_deg.iter().all(|c| c.is_finite()));
    assert!(
        out.theta_hat_deg
            .iter()
            .all(|h| h.is_some_and(f64::is_finite))
    );
}
