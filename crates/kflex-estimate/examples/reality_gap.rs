//! The reality gap, measured with the plainest retrieval: the nearest raw
//! 48×48 silhouette of the nominal (CAD) instrument and camera, for frames
//! of the simulated robot (an as-built instrument and camera, drawn per
//! frame from `BuildTolerances`), unoccluded, θ ∈ [0°, 50°] at d = 10 mm
//! (the paper's operating range), over a database every 0.5°.
//!
//! `cargo run --release -p kflex-estimate --example reality_gap [FRAMES [SCALE]]`
//! (SCALE multiplies every default tolerance; 1 by default)
//! (`tools/reality_gap.sh`). Prints the RMSE with the frame's exact mask
//! (perfect segmentation) and with kflex's segmentation, beside the same
//! with no gap (nominal frames). `KFLEX_SEGMENT_PARAMS='{"field": value}'` measures
//! other segmentation thresholds, as in `robustness_table`.

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{
    BuildTolerances, Camera, FrameParams, Instrument, Mask, Rasterizer, Roi, SceneRenderer,
};

const SIDE: u32 = 48;

fn distance(a: &Mask, b: &Mask) -> usize {
    a.data()
        .iter()
        .zip(b.data())
        .filter(|(x, y)| x != y)
        .count()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let frames: usize = std::env::args().nth(1).map_or(Ok(500), |a| a.parse())?;
    // every tolerance scaled by this (1: the defaults)
    let scale: f64 = std::env::args().nth(2).map_or(Ok(1.0), |a| a.parse())?;
    let d = BuildTolerances::default();
    let tolerances = BuildTolerances {
        link_length: d.link_length * scale,
        link_radius: d.link_radius * scale,
        curvature: d.curvature * scale,
        camera_rotation_deg: d.camera_rotation_deg * scale,
        camera_offset_mm: d.camera_offset_mm * scale,
        focal: d.focal * scale,
        principal_px: d.principal_px * scale,
        division: d.division * scale,
    };
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let roi = Roi::paper(&camera)?;
    let small = camera.with_intrinsics(roi.intrinsics(&camera.intrinsics, SIDE, SIDE)?);
    // the database: nominal silhouettes every 0.5° over [−5°, 55°]
    let mut raster = Rasterizer::new();
    let database: Vec<(f64, Mask)> = (0..=120)
        .map(|i| {
            let theta = -5.0 + 0.5 * f64::from(i);
            let mut m = Mask::new(SIDE, SIDE).expect("48×48");
            raster.silhouette(&small, &instrument.shape(theta, 10.0)?, &mut m)?;
            Ok((theta, m))
        })
        .collect::<Result<_, kflex_model::ModelError>>()?;
    let nearest = |q: &Mask| {
        database
            .iter()
            .min_by_key(|(_, m)| distance(m, q))
            .map_or(f64::NAN, |(t, _)| *t)
    };
    let mut renderer = SceneRenderer::new();
    let mut segmenter = Segmenter::new(match std::env::var("KFLEX_SEGMENT_PARAMS") {
        Ok(j) => serde_json::from_str(&j)?,
        Err(_) => SegmentParams::default(),
    })?;
    // squared errors: [exact mask, segmented] × [no gap, as built]; segmentation failures counted
    let mut sq = [[0.0f64; 2]; 2];
    let mut counted = [[0usize; 2]; 2];
    let mut failed = [0usize; 2];
    for i in 0..frames {
        // a low-discrepancy sweep of [0°, 50°]
        let theta = 50.0 * ((i as f64 * 0.618_033_988_75) % 1.0);
        for (g, gap) in [BuildTolerances::NONE, tolerances].iter().enumerate() {
            let seed = i as u64;
            let built = gap.instrument(&instrument, seed)?;
            let cam = gap.camera(&camera, seed)?;
            let params = FrameParams {
                seed,
                frame: seed,
                ..FrameParams::default()
            };
            let frame = renderer.render_window(&cam, &built.shape(theta, 10.0)?, &params, roi)?;
            let exact = frame.instrument.vote(SIDE, SIDE)?;
            let e = nearest(&exact) - theta;
            sq[0][g] += e * e;
            counted[0][g] += 1;
            let whole = Roi {
                x0: 0,
                y0: 0,
                width: roi.width,
                height: roi.height,
            };
            match segmenter.segment(&frame.rgb, roi.width, roi.height, whole) {
                Ok(seg) => {
                    let e = nearest(&seg.small) - theta;
                    sq[1][g] += e * e;
                    counted[1][g] += 1;
                }
                Err(_) => failed[g] += 1,
            }
        }
    }
    let rmse = |m: usize, g: usize| (sq[m][g] / counted[m][g].max(1) as f64).sqrt();
    println!(
        "raw-pixel nearest neighbour, nominal database (0.5° steps), {frames} frames, θ in [0°, 50°], d = 10 mm, unoccluded, tolerances ×{scale}"
    );
    println!(
        "| frames from | exact mask RMSE (deg) | segmented RMSE (deg) | segmentation failures |"
    );
    println!("|---|---|---|---|");
    for (g, name) in [
        "the nominal model (no gap)",
        "as-built instrument and camera",
    ]
    .iter()
    .enumerate()
    {
        println!(
            "| {name} | {:.2} | {:.2} | {} |",
            rmse(0, g),
            rmse(1, g),
            failed[g]
        );
    }
    Ok(())
}
