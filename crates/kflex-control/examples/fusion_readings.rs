//! Writes what LBHJAE's fusion is given, tick by tick, over recorded runs:
//! for studying fusion filters offline on the trained estimators' real
//! readings (the closed loop's own frames, tape and bent sheaths included).
//! It replays each log's frames through the models' `lbhjae-adaptive`
//! (`ClosedLoopScenario::replay_with_details`), so the readings are those of
//! the models given, whichever models recorded the log.
//!
//! ```text
//! kflex-cli run --scenario assets/scenarios/table_vii.toml --estimators lbhjae-adaptive \
//!     --mcap --mcap-frames --no-plots --out runs/vii
//! cargo run --release -p kflex-control --features estimators,mcap --example fusion_readings -- \
//!     MODELS_DIR OUT.csv runs/vii/runs/*.mcap
//! ```
//!
//! One CSV row per evaluated tick: the log's file name, the time (s), the
//! true angle, KBJAE's reading, IBJAE's reading where a frame was read
//! (angle, its own uncertainty, whether part of the instrument was taken as
//! hidden, the bends consistent with the visible part, the silhouette's
//! IoU; empty where none), and the adaptive filter's estimate. Angles in
//! deg. (A run's own readings are also in its log's joint states and in
//! `kflex.run_experiment`'s `details`, without replaying.)

use std::io::Write;
use std::path::PathBuf;

use kflex_control::{ClosedLoopScenario, EstimatorKind, ModelDir, read_mcap};
use kflex_model::Camera;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [models, out, logs @ ..] = args.as_slice() else {
        return Err("usage: fusion_readings MODELS_DIR OUT.csv LOG.mcap…".into());
    };
    let models = ModelDir::new(models);
    let camera = Camera::default();
    let mut csv = std::io::BufWriter::new(std::fs::File::create(out)?);
    writeln!(
        csv,
        "log,time_s,theta_a_deg,kbjae_deg,ibjae_deg,ibjae_sigma_deg,ibjae_occluded,\
         consistent_lo_deg,consistent_hi_deg,silhouette_iou,adaptive_deg"
    )?;
    for path in logs {
        let log = read_mcap(path)?;
        let scenario: ClosedLoopScenario = log
            .scenario
            .clone()
            .ok_or("a log without its scenario (record it with `kflex-cli run --mcap`)")?;
        let mut lbhjae = models.make(EstimatorKind::LbhjaeAdaptive, &camera)?;
        let ticks = log.replay_ticks(scenario.motion.translation_mm);
        let (estimates, details) =
            scenario.replay_with_details(lbhjae.as_mut(), &ticks, &log.frames)?;
        let name = path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
        for ((s, d), e) in log.states.iter().zip(&details).zip(&estimates) {
            writeln!(
                csv,
                "{name},{:.4},{:.4},{},{},{},{},{},{},{},{}",
                s.time_s,
                s.theta_a_deg,
                opt(d.kbjae_deg),
                opt(d.ibjae_deg),
                opt(d.ibjae_sigma_deg),
                d.ibjae_occluded
                    .filter(|_| d.ibjae_deg.is_some())
                    .map_or(String::new(), |o| u8::from(o).to_string()),
                opt(d.ibjae_consistent_deg.map(|c| c[0])),
                opt(d.ibjae_consistent_deg.map(|c| c[1])),
                opt(d.ibjae_silhouette_iou),
                opt(*e),
            )?;
        }
        eprintln!("{name}: {} ticks", log.states.len());
    }
    csv.flush()?;
    Ok(())
}
