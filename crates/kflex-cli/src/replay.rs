//! `kflex-cli replay LOG.mcap`: runs estimators again over a recorded run
//! (its commands and camera frames, `run --scenario … --mcap --mcap-frames`,
//! or a log from elsewhere whose channels follow the documented schemas)
//! and prints their RMSE against the log's true angle.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use kflex_control::{ClosedLoopScenario, EstimatorKind, ModelDir, estimation_rmse_deg, read_mcap};
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
    models
        .check(&kinds, &camera)
        .context("give the directory that holds the trained models with --models")?;
    println!(
        "kflex replay — {} ({} ticks of {} s, {} frames{}{})",
        args.log.display(),
        log.states.len(),
        scenario.motion.dt_s,
        log.frames.len(),
        log.seed.map_or(String::new(), |s| format!(", seed {s}")),
        if log.scenario.is_some() {
            ""
        } else {
            ", no scenario in the log: no pre-roll"
        },
    );
    if log.frames.is_empty() {
        println!(
            "note: the log holds no camera frames (record them with `run --mcap --mcap-frames`): \
             camera-based estimators see none"
        );
    }
    println!(
        "\n{:>16} | {:>13} {:>7}",
        "estimator", "RMSE (deg)", "ticks"
    );
    let logged: Vec<Option<f64>> = log.states.iter().map(|s| s.theta_hat_deg).collect();
    if let Some((r, n)) = scored(&truth, &logged) {
        println!("{:>16} | {r:>13.3} {n:>7}", "as logged");
    }
    for kind in kinds {
        let mut estimator = models.make(kind, &camera)?;
        let estimate = scenario
            .replay(estimator.as_mut(), &ticks, &log.frames)
            .with_context(|| format!("replaying {}", kind.name()))?;
        match scored(&truth, &estimate) {
            Some((r, n)) => println!("{:>16} | {r:>13.3} {n:>7}", kind.name()),
            None => println!("{:>16} | {:>13} {:>7}", kind.name(), "no estimate", 0),
        }
    }
    Ok(())
}
