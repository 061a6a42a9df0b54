//! What one closed-loop run of the paper's length costs, to size the grid
//! of Tables V–X (issue 12's goal: the full grid within 90 s on two cores).
//!
//! `cargo run --release -p kflex-control --example closed_loop_speed`
//!
//! Three runs of the paper's input (pre-roll, five periods, 100 Hz ticks,
//! a 30 Hz camera) at sheath 0 with the compensator: an estimator that asks
//! for no frames (KBJAE's case: plant and compensator only); one that asks
//! for the frames' timing only (the stand-in `NoisyTruth`); and one that asks
//! for the pixels of the paper's working region and segments each frame
//! into its 48×48 silhouette (IBJAE's case up to its network: the SCNN's
//! own time, about 0.75 ms a frame on paper-size random weights, comes on
//! top; `tools/estimation_bench.sh`). It prints each run's wall time and,
//! from them, an estimate of the grid's.

use std::time::Instant;

use kflex_control::{
    AngleEstimator, ClosedLoopScenario, EstimatorTick, FrameRequest, NoisyTruth, Result,
};
use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{Camera, Command, Plant, PlantConfig, Roi};

/// Asks for no frames; its estimate is the command (KBJAE's shape of work).
struct CommandOnly;

impl AngleEstimator for CommandOnly {
    fn frame_request(&self, _command: Command) -> FrameRequest {
        FrameRequest::None
    }
    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        Ok(Some(tick.command.theta_c_deg))
    }
    fn reset(&mut self) {}
}

/// Asks for the paper's working region and segments every frame; its
/// estimate is the truth at capture (the retrieval is not timed here).
struct Segmenting {
    roi: Roi,
    segmenter: Segmenter,
    frames: usize,
    last: Option<f64>,
}

impl AngleEstimator for Segmenting {
    fn frame_request(&self, _command: Command) -> FrameRequest {
        FrameRequest::Pixels(self.roi)
    }
    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        if let Some(frame) = tick.frame
            && let Some(image) = frame.image
        {
            let whole = Roi::whole(image.width, image.height);
            // a frame without the instrument is no estimate, as IBJAE's
            if self
                .segmenter
                .segment(&image.rgb, image.width, image.height, whole)
                .is_ok()
            {
                self.last = Some(frame.truth_theta_a_deg);
            }
            self.frames += 1;
        }
        Ok(self.last)
    }
    fn reset(&mut self) {
        self.last = None;
        self.frames = 0;
    }
}

fn timed(name: &str, estimator: &mut dyn AngleEstimator) -> Result<f64> {
    let scenario = ClosedLoopScenario::default();
    let mut plant = Plant::new(PlantConfig::default())?;
    let start = Instant::now();
    let trace = scenario.run(&mut plant, estimator, 2020)?;
    let s = start.elapsed().as_secs_f64();
    println!(
        "{name:<34} {s:>7.3} s   {} ticks, {} frames captured, RMSE {:.2} deg",
        trace.trace.time_s.len(),
        trace.frames.captured,
        trace.trace.metrics()?.rmse_deg
    );
    Ok(s)
}

fn main() -> std::result::Result<(), Box<dyn std::error::Error>> {
    let roi = Roi::paper(&Camera::default())?;
    println!("one closed-loop run of the paper's input (sheath 0, compensator on):");
    let none = timed("no frames (KBJAE's case)", &mut CommandOnly)?;
    let timing = timed(
        "frame timing only (NoisyTruth)",
        &mut NoisyTruth::new(1.0, 1)?,
    )?;
    let mut seg = Segmenting {
        roi,
        segmenter: Segmenter::new(SegmentParams::default())?,
        frames: 0,
        last: None,
    };
    let pixels = timed("region rendered and segmented", &mut seg)?;
    let per_frame_ms = 1e3 * (pixels - timing) / seg.frames.max(1) as f64;
    println!(
        "a frame of the {}×{} region, rendered and segmented: {per_frame_ms:.2} ms",
        roi.width, roi.height
    );
    // the paper's grid: 11 estimation and 11 compensation cases, 3 repeats.
    // An estimation case's estimators share one run: the region rendered
    // once a frame, the SCNN run three times (IBJAE, LBHJAE, LBHJAE
    // adaptive). In compensation, ibjae, lbhjae and lbhjae-adaptive each
    // have their own run with one SCNN call a frame; none and kbjae take
    // no frames.
    let scnn_s = 0.75e-3 * seg.frames as f64;
    let estimation = 11.0 * 3.0 * (pixels + 3.0 * scnn_s);
    let compensation = 11.0 * 3.0 * (3.0 * (pixels + scnn_s) + 2.0 * none);
    let total = estimation + compensation;
    println!(
        "the paper's grid, estimated (the SCNN at 0.75 ms a frame): estimation {estimation:.0} s, \
         compensation {compensation:.0} s; {total:.0} s on one core, {:.0} s on two (goal 90 s)",
        total / 2.0
    );
    Ok(())
}
