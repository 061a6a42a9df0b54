//! Writes what LBHJAE's fusion is given, tick by tick, over recorded runs:
//! for studying fusion filters offline on the trained estimators' real
//! readings (the closed loop's own frames, tape and bent sheaths included).
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
//! hidden, the angles consistent with the visible part, the silhouette's
//! IoU; empty where none), and the adaptive filter's estimate (the
//! `lbhjae-adaptive` of the models' directory, replayed). Angles in deg.

use std::io::Write;
use std::path::PathBuf;

use kflex_control::{
    AngleEstimator, CameraFrame, ClosedLoopScenario, EstimatorTick, FrameRequest, read_mcap,
};
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, DEFAULT_MIN_SILHOUETTE_IOU, Ibjae, Kbjae, Lbhjae,
    LbhjaeEstimate, RgbView, Scnn, SegmentParams, load_databases,
};
use kflex_model::{Camera, Command, Instrument};

/// The frame's pixels where its window holds the one LBHJAE needs.
fn view<'a>(
    f: &CameraFrame<'a>,
    needed: Option<kflex_model::Roi>,
) -> kflex_control::Result<Option<RgbView<'a>>> {
    let (Some(image), Some(window)) = (f.image, f.window) else {
        return Ok(None);
    };
    if !needed.is_some_and(|n| window.holds(&n)) {
        return Ok(None);
    }
    Ok(Some(RgbView::window(
        &image.rgb,
        window,
        3 * image.width as usize,
    )?))
}

/// LBHJAE as the grid runs it, keeping each tick's readings.
struct Recording {
    lbhjae: Lbhjae,
    rows: Vec<LbhjaeEstimate>,
}

impl AngleEstimator for Recording {
    fn frame_request(&self, command: Command) -> FrameRequest {
        self.lbhjae
            .frame_window(command.translation_mm)
            .map_or(FrameRequest::None, FrameRequest::Pixels)
    }

    fn step(&mut self, tick: &EstimatorTick<'_>) -> kflex_control::Result<Option<f64>> {
        let needed = self.lbhjae.frame_window(tick.command.translation_mm);
        let frame = match &tick.frame {
            Some(f) => view(f, needed)?,
            None => None,
        };
        let e = self.lbhjae.step_with_rate(
            tick.command,
            tick.theta_d_rate_deg_per_s,
            tick.dt_s,
            frame.as_ref(),
        )?;
        self.rows.push(e);
        Ok(Some(e.fused.theta_hat_deg))
    }

    fn reset(&mut self) {
        self.lbhjae.reset();
        self.rows.clear();
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    let [models, out, logs @ ..] = args.as_slice() else {
        return Err("usage: fusion_readings MODELS_DIR OUT.csv LOG.mcap…".into());
    };
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
        let ibjae = Ibjae::new(
            Scnn::load(&models.join("scnn.onnx"), 1)?,
            SegmentParams::default(),
            load_databases(&models.join("db"), &camera)?,
        )?
        .with_silhouette_check(
            &camera,
            &Instrument::kflex(),
            DEFAULT_MIN_SILHOUETTE_IOU,
        )?;
        let lbhjae = Lbhjae::new(
            Kbjae::load(&models.join("kbjae.onnx"))?,
            ibjae,
            Box::new(AdaptiveKalman::new(AdaptiveParams::default())?),
        );
        let mut rec = Recording {
            lbhjae,
            rows: Vec::new(),
        };
        let ticks = log.replay_ticks(scenario.motion.translation_mm);
        scenario.replay(&mut rec, &ticks, &log.frames)?;
        // the replay steps through the pre-roll first: its rows come before the evaluated ones
        let rows = &rec.rows[rec.rows.len() - log.states.len()..];
        let name = path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        for (s, e) in log.states.iter().zip(rows) {
            let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.4}"));
            let r = e.ibjae.as_ref();
            writeln!(
                csv,
                "{name},{:.4},{:.4},{:.4},{},{},{},{},{},{},{:.4}",
                s.time_s,
                s.theta_a_deg,
                e.kbjae_deg,
                opt(r.map(|r| r.theta_deg)),
                opt(r.map(|r| r.sigma_deg)),
                r.map_or(String::new(), |r| u8::from(r.occluded).to_string()),
                opt(r.and_then(|r| r.consistent_deg).map(|c| c[0])),
                opt(r.and_then(|r| r.consistent_deg).map(|c| c[1])),
                opt(r.and_then(|r| r.silhouette_iou)),
                e.fused.theta_hat_deg,
            )?;
        }
        eprintln!("{name}: {} ticks", log.states.len());
    }
    csv.flush()?;
    Ok(())
}
