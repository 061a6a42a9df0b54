//! How fast D^I is made: pairs per second with one thread and with every
//! core, then where one query's time goes (its stages timed one by one on
//! one thread, as `ImagePairsConfig::generate` runs them).
//!
//! `cargo run --release -p kflex-control --example dataset_speed [PAIRS]`
//! (PAIRS: 4000 by default)

use std::time::Instant;

use kflex_control::{ImagePairsConfig, KinematicDatasetConfig};
use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{
    Background, BuildTolerances, Camera, FrameParams, Instrument, Mask, Rasterizer, Roi,
    SceneRenderer, Tissue, WorkingRegions,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let pairs: usize = std::env::args().nth(1).map_or(Ok(4000), |a| a.parse())?;
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let config = ImagePairsConfig {
        pairs,
        ..ImagePairsConfig::default()
    };
    println!(
        "D^I, {pairs} pairs ({} frames), default settings:",
        pairs / 2
    );
    for threads in [1, cores] {
        let t = Instant::now();
        let p = config.generate(threads)?;
        let s = t.elapsed().as_secs_f64();
        println!(
            "  {threads} thread(s): {:.2} s, {:.0} pairs/s ({} segmentation failures redrawn)",
            s,
            pairs as f64 / s,
            p.card.stats["segmentation_failures_redrawn"]
        );
    }
    let t = Instant::now();
    let db = config.database(cores)?;
    println!(
        "database: {} silhouettes in {:.2} s",
        db.theta_deg.len(),
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let k = KinematicDatasetConfig::default().generate(cores)?;
    println!(
        "D^k: {} sets x {} samples in {:.2} s ({cores} threads)",
        k.sets.len(),
        k.sets[0].theta_d_deg.len(),
        t.elapsed().as_secs_f64()
    );
    stages(pairs / 2)
}

/// One query's stages, each timed over `n` queries on this thread.
fn stages(n: usize) -> Result<(), Box<dyn std::error::Error>> {
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let regions = WorkingRegions::full(&camera)?;
    let tol = BuildTolerances::default();
    // one renderer per background, as the generator keeps them
    let mut renderers: std::collections::HashMap<(usize, u64), SceneRenderer> = Default::default();
    let mut segmenter = Segmenter::new(SegmentParams::default())?;
    let mut raster = Rasterizer::new();
    let mut mask = Mask::new(48, 48)?;
    let mut times = [0.0f64; 5];
    let mut area = 0u64;
    let golden = 0.618_033_988_75;
    for i in 0..n {
        let u = (i as f64 * golden).fract();
        let v = (i as f64 * golden * golden).fract();
        let (theta, d) = (-90.0 + 180.0 * u, 8.0 + 32.0 * v);
        let roi = regions.at(theta, d)?.roi;
        area += roi.area();
        let t = Instant::now();
        let built = tol.instrument(&instrument, i as u64)?;
        let cam = tol.camera(&camera, i as u64)?;
        let shape = built.shape(theta, d)?;
        times[0] += t.elapsed().as_secs_f64();
        let (kind, bg_seed) = ((i / 32) % 3, (i / 96) as u64 % 8);
        let renderer = renderers.entry((kind, bg_seed)).or_default();
        let params = FrameParams {
            background: Background::ALL[kind],
            tissue: Tissue::Organ,
            seed: bg_seed,
            frame: i as u64,
            blur_px: if i % 3 == 0 { 1.0 } else { 0.0 },
            ..FrameParams::default()
        };
        let t = Instant::now();
        let frame = renderer.render_window(&cam, &shape, &params, roi)?;
        times[1] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let _ = segmenter.segment(
            &frame.rgb,
            roi.width,
            roi.height,
            Roi::whole(roi.width, roi.height),
        );
        times[2] += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let small = camera.with_intrinsics(roi.intrinsics(&camera.intrinsics, 48, 48)?);
        for _ in 0..2 {
            mask.clear();
            raster.silhouette(
                &small,
                &instrument.shape(theta.round(), d.round())?,
                &mut mask,
            )?;
        }
        times[3] += t.elapsed().as_secs_f64();
        // the same frame with the nominal camera kept from frame to frame
        let t = Instant::now();
        renderer.render_window(&camera, &shape, &params, roi)?;
        times[4] += t.elapsed().as_secs_f64();
    }
    let per = |s: f64| 1e3 * s / n as f64;
    println!(
        "one query's stages, one thread, {n} queries (mean region {:.0} px; each background synthesised once):",
        area as f64 / n as f64
    );
    println!(
        "  as-built instrument and camera drawn, shape: {:.3} ms",
        per(times[0])
    );
    println!(
        "  frame of the region (as-built camera):      {:.3} ms",
        per(times[1])
    );
    println!(
        "  segmentation:                               {:.3} ms",
        per(times[2])
    );
    println!(
        "  two nominal 48x48 silhouettes:              {:.3} ms",
        per(times[3])
    );
    println!(
        "  (the same frame, camera kept between frames: {:.3} ms)",
        per(times[4])
    );
    Ok(())
}
