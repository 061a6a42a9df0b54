//! `kflex-cli replay LOG.mcap`: runs estimators again over a recorded run
//! (its commands and camera frames, `run --scenario … --mcap --mcap-frames`,
//! or a log from elsewhere whose channels follow the documented schemas)
//! and prints their RMSE against the log's true angle, and what became of
//! the camera's frames: how many IBJAE read an angle from, how many of those
//! with a hidden part, and how many the fusion used or gated.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use kflex_control::{
    ClosedLoopScenario, EstimatorKind, ModelDir, ReadingUse, TickDetails, estimation_rmse_deg,
    read_mcap,
};
use kflex_model::Camera;

use crate::grid::estimator;

#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The run's MCAP log.
    log: PathBuf,
    /// The estimators to replay, comma separated (kbjae, ibjae, lbhjae,
    /// lbhjae-adaptive).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "kbjae,ibjae,lbhjae,lbhjae-adaptive"
    )]
    estimators: Vec<String>,
    /// The trained models' directory (kbjae.onnx, scnn.onnx, db/).
    #[arg(long, value_name = "DIR", default_value = kflex_control::MODELS_DIR)]
    models: PathBuf,
}

/// The camera's readings of a run, as the table prints them: frames IBJAE
/// read an angle from, of those how many took part of the instrument as
/// hidden, and for a fused estimator what the filter did with them (used,
/// gated); `-` where the estimator has no camera (`camera`) or no filter
/// (`fused`).
fn readings(details: &[TickDetails], camera: bool, fused: bool) -> String {
    let count = |f: &dyn Fn(&TickDetails) -> bool| details.iter().filter(|d| f(d)).count();
    let dash = || "-".to_string();
    let (read, hidden) = if camera {
        (
            count(&|d| d.ibjae_deg.is_some()).to_string(),
            count(&|d| d.ibjae_occluded == Some(true)).to_string(),
        )
    } else {
        (dash(), dash())
    };
    let (used, gated) = if fused {
        (
            count(&|d| d.ibjae_use == Some(ReadingUse::Used)).to_string(),
            count(&|d| d.ibjae_use == Some(ReadingUse::Gated)).to_string(),
        )
    } else {
        (dash(), dash())
    };
    format!("{read:>11} {hidden:>6} {used:>6} {gated:>6}")
}

/// Whether an estimator of `kind` reads frames, and whether it fuses.
fn has_camera_and_filter(kind: EstimatorKind) -> (bool, bool) {
    let fused = matches!(kind, EstimatorKind::Lbhjae | EstimatorKind::LbhjaeAdaptive);
    (fused || kind == EstimatorKind::Ibjae, fused)
}

/// RMSE of `estimate` against `truth` over the ticks that have an
/// estimate, and how many those are.
fn scored(truth: &[f64], estimate: &[Option<f64>]) -> Option<(f64, usize)> {
    let ticks = estimate.iter().flatten().count();
    estimation_rmse_deg(truth, estimate)
        .ok()
        .map(|r| (r, ticks))
}

pub fn replay(args: &ReplayArgs) -> Result<()> {
    let kinds = args
        .estimators
        .iter()
        .map(|n| estimator(n))
        .collect::<Result<Vec<_>>>()?;
    if kinds.contains(&EstimatorKind::None) {
        bail!("--estimators: \"none\" estimates nothing to replay");
    }
    let log = read_mcap(&args.log)?;
    // a log from elsewhere: the default scenario at the log's own tick, no
    // pre-roll, no compensator
    let scenario = match &log.scenario {
        Some(s) => s.clone(),
        None => {
            let mut s = ClosedLoopScenario {
                compensator: None,
                ..ClosedLoopScenario::default()
            };
            let t = &log.states;
            if t.len() > 1 {
                s.motion.dt_s = (t[t.len() - 1].time_s - t[0].time_s) / (t.len() - 1) as f64;
            }
            s.motion.pre_roll_s = 0.0;
            s
        }
    };
    let ticks = log.replay_ticks(scenario.motion.translation_mm);
    let truth: Vec<f64> = log.states.iter().map(|s| s.theta_a_deg).collect();
    let models = ModelDir::new(&args.models);
    let camera = Camera::default();
    crate::grid::check_models(&models, &kinds, &camera, "")?;
    outln!(
        "kflex replay — {} ({} ticks of {} s, {} frames{}{})",
        args.log.display(),
        log.states.len(),
        kflex_model::Num(scenario.motion.dt_s),
        log.frames.len(),
        log.seed.map_or(String::new(), |s| format!(", seed {s}")),
        if log.scenario.is_some() {
            ""
        } else {
            ", no scenario in the log: no pre-roll"
        },
    );
    if log.frames.is_empty() {
        outln!(
            "note: the log holds no camera frames (record them with `run --mcap --mcap-frames`): \
             camera-based estimators see none"
        );
    }
    outln!(
        "\n{:>16} | {:>13} {:>7} | {:>11} {:>6} {:>6} {:>6}",
        "estimator",
        "RMSE (deg)",
        "ticks",
        "frames read",
        "hidden",
        "used",
        "gated"
    );
    let logged: Vec<Option<f64>> = log.states.iter().map(|s| s.theta_hat_deg).collect();
    if let Some((r, n)) = scored(&truth, &logged) {
        // the logged estimator's own, as far as its log tells ("?" for a
        // log without the details: one from an older kflex or from elsewhere)
        let details: Vec<TickDetails> = log.states.iter().map(|s| s.details).collect();
        let fused = details.iter().any(|d| d.ibjae_use.is_some());
        let camera = fused || details.iter().any(|d| d.ibjae_deg.is_some());
        let camera_use = if details.iter().all(|d| *d == TickDetails::default()) {
            format!("{:>11} {:>6} {:>6} {:>6}", "?", "?", "?", "?")
        } else {
            readings(&details, camera, fused)
        };
        outln!("{:>16} | {r:>13.3} {n:>7} | {camera_use}", "as logged");
    }
    // camera-based estimators that read no angle from any of the frames
    let mut unread = Vec::new();
    for kind in kinds {
        let mut estimator = models.make(kind, &camera)?;
        let (estimate, details) = scenario
            .replay_with_details(estimator.as_mut(), &ticks, &log.frames)
            .with_context(|| format!("replaying {}", kind.name()))?;
        let (camera, fused) = has_camera_and_filter(kind);
        let camera_use = readings(&details, camera, fused);
        if camera && !log.frames.is_empty() && details.iter().all(|d| d.ibjae_deg.is_none()) {
            unread.push(kind.name());
        }
        match scored(&truth, &estimate) {
            Some((r, n)) => outln!("{:>16} | {r:>13.3} {n:>7} | {camera_use}", kind.name()),
            None => outln!(
                "{:>16} | {:>13} {:>7} | {camera_use}",
                kind.name(),
                "no estimate",
                0
            ),
        }
    }
    if !unread.is_empty() {
        outln!(
            "\nnote: {} read no angle from the log's {} frames. A frame is read where its \
             window holds the band the estimator reads and shows the instrument; a frame \
             without its {} record is taken as the camera's whole image, at its own size.",
            unread.join(", "),
            log.frames.len(),
            kflex_control::CAMERA_FRAMES_TOPIC
        );
    }
    Ok(())
}
