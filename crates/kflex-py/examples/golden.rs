//! Reference outputs of the Rust crates for `tests/python/test_equal_to_rust.py`.
//!
//! Runs the crates themselves (not the Python module) on fixed inputs and
//! writes what they return: `DIR/golden.json` (numbers as JSON, which
//! round-trip exactly) and the rendered frame's buffers as raw bytes
//! (`frame.rgb`, `frame.instrument`, `frame.occluder`, `silhouette.mask`).
//! The Python tests run the same inputs through `kflex` and compare for
//! exact equality. Inputs the Python side cannot write down exactly
//! (commands, times, angles computed here) are written out too.
//!
//! `cargo run --release -p kflex-py --example golden -- DIR`

use std::error::Error;
use std::path::PathBuf;

use kflex_control::{ImagePairsConfig, KinematicDatasetConfig, OpenLoopScenario};
use kflex_estimate::{EstimateError, SegmentParams, Segmenter};
use kflex_model::{
    AuroraNoise, BuildTolerances, Camera, Command, FrameParams, Instrument, Mask, Occlusion, Plant,
    PlantConfig, Rasterizer, Roi, SceneRenderer, TendonGeometry, Trajectory, WorkingRegions,
};
use serde_json::{Value, json};

fn main() -> Result<(), Box<dyn Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: golden DIR")?);
    std::fs::create_dir_all(&dir)?;

    // the plant over an array of commands: a perturbed, noisy plant at 90 deg
    let nominal = PlantConfig {
        sheath_deg: 90.0,
        noise: Some(AuroraNoise::default()),
        seed: 7,
        ..PlantConfig::default()
    };
    let config = nominal.perturbed(3, 0.15)?;
    let commands: Vec<f64> = (0..400)
        .map(|k| 30.0 * (0.02 * f64::from(k)).sin() + 10.0)
        .collect();
    let mut plant = Plant::new(config)?;
    let mut states = Vec::new();
    for &theta_c_deg in &commands {
        let command = Command {
            theta_c_deg,
            translation_mm: 12.0,
        };
        states.push(plant.step(command, 0.01)?);
    }

    // the open-loop scenario: one period of the paper's input at 180 deg
    let scenario = OpenLoopScenario {
        periods: 1.0,
        ..OpenLoopScenario::default()
    };
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 180.0,
        ..PlantConfig::default()
    })?;
    let trace = scenario.run(&mut plant)?;
    let metrics = trace.metrics()?;

    // Eq. 1-2 and the inverse
    let geometry = TendonGeometry::default();
    let theta_rad: Vec<f64> = (0..61).map(|k| -1.5 + 0.05 * f64::from(k)).collect();
    let delta_l_a: Vec<f64> = theta_rad
        .iter()
        .map(|&t| geometry.delta_l_a_mm(t))
        .collect();
    let inverse = delta_l_a
        .iter()
        .map(|&dl| geometry.theta_rad_from_delta_l_a(dl, 1.6))
        .collect::<Result<Vec<f64>, _>>()?;

    // a band-limited trajectory
    let trajectory = Trajectory::BandLimited {
        min_deg: -20.0,
        max_deg: 60.0,
        cutoff_hz: 1.5,
        components: 8,
        seed: 5,
    };
    let sampler = trajectory.sampler()?;
    let t_s: Vec<f64> = (0..200).map(|k| 0.05 * f64::from(k)).collect();
    let samples: Vec<_> = t_s.iter().map(|&t| sampler.sample(t)).collect();

    // camera, regions, a taped frame, its silhouette and its segmentation
    let camera = Camera::default();
    let roi = Roi::paper(&camera)?;
    let regions = WorkingRegions::full(&camera)?;
    let shape = Instrument::kflex().shape(30.0, 12.0)?;
    let params = FrameParams {
        seed: 4,
        frame: 2,
        occlusion: Some(Occlusion::new(0.3, 1.0)),
        ..FrameParams::default()
    };
    let frame = SceneRenderer::new().render(&camera, &shape, &params)?;
    std::fs::write(dir.join("frame.rgb"), &frame.rgb)?;
    std::fs::write(dir.join("frame.instrument"), frame.instrument.data())?;
    std::fs::write(dir.join("frame.occluder"), frame.occluder.data())?;
    let mut silhouette = Mask::new(roi.width, roi.height)?;
    Rasterizer::new().silhouette_window(&camera, &shape, roi, &mut silhouette)?;
    std::fs::write(dir.join("silhouette.mask"), silhouette.data())?;
    let mut segmenter = Segmenter::new(SegmentParams::default())?;
    let small = segmenter
        .segment(&frame.rgb, frame.width, frame.height, roi)?
        .small
        .data()
        .to_vec();
    let grey = vec![128u8; 64 * 64 * 3];
    let empty = match segmenter.segment(&grey, 64, 64, Roi::whole(64, 64)) {
        Err(EstimateError::NoInstrument { .. }) => Value::Null,
        Ok(s) => json!(s.small.data()),
        Err(e) => return Err(e.into()),
    };

    // the as-built camera and instrument
    let tolerances = BuildTolerances::default();
    let built_camera = tolerances.camera(&camera, 9)?;
    let m = built_camera.camera_from_overtube.to_homogeneous();
    let built_tip = tolerances
        .instrument(&Instrument::kflex(), 9)?
        .shape(20.0, 15.0)?
        .tip_mm;

    // the training data sets, small
    let kinematic_config = KinematicDatasetConfig {
        sets: KinematicDatasetConfig::default().sets[4..8].to_vec(),
        samples_per_set: 200,
        ..KinematicDatasetConfig::default()
    };
    let kinematic = kinematic_config.generate(1)?;
    let pairs_config = ImagePairsConfig {
        pairs: 8,
        block: 2,
        seed: 11,
        ..ImagePairsConfig::default()
    };
    let pairs = pairs_config.generate(1)?;

    let golden = json!({
        "datasets": {
            "kinematic": {
                "config": kinematic_config,
                "sets": kinematic.sets,
                "card": kinematic.card,
            },
            "pairs": {
                "config": pairs_config,
                "x_b": pairs.x_b,
                "x_r": pairs.x_r,
                "s": pairs.s,
                "hard": pairs.hard,
                "band": pairs.band,
                "theta_b_deg": pairs.theta_b_deg,
                "translation_b_mm": pairs.translation_b_mm,
                "theta_r_deg": pairs.theta_r_deg,
                "translation_r_mm": pairs.translation_r_mm,
                "card": pairs.card,
            },
        },
        "plant": {
            "config": config,
            "commands_deg": commands,
            "translation_mm": 12.0,
            "dt_s": 0.01,
            "states": states,
        },
        "scenario": {"trace": trace, "metrics": metrics},
        "kinematics": {
            "theta_rad": theta_rad,
            "delta_l_a_mm": delta_l_a,
            "delta_l_b_mm": theta_rad.iter().map(|&t| geometry.delta_l_b_mm(t)).collect::<Vec<_>>(),
            "differential_stroke_mm": theta_rad.iter().map(|&t| geometry.differential_stroke_mm(t)).collect::<Vec<_>>(),
            "common_mode_mm": theta_rad.iter().map(|&t| geometry.common_mode_mm(t)).collect::<Vec<_>>(),
            "theta_rad_from_delta_l_a": inverse,
        },
        "trajectory": {
            "t_s": t_s,
            "theta_d_deg": samples.iter().map(|s| s.theta_d_deg).collect::<Vec<_>>(),
            "theta_d_rate_deg_per_s": samples.iter().map(|s| s.theta_d_rate_deg_per_s).collect::<Vec<_>>(),
        },
        "camera": {
            "roi_paper": roi,
            "bands": regions.bands(),
            "frame": {"width": frame.width, "height": frame.height},
            "segmentation_small": small,
            "segmentation_grey": empty,
            "built_camera_from_overtube": (0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "built_intrinsics": built_camera.intrinsics,
            "built_lens": built_camera.lens,
            "built_tip_mm": built_tip,
        },
    });
    std::fs::write(dir.join("golden.json"), serde_json::to_string(&golden)?)?;
    Ok(())
}
