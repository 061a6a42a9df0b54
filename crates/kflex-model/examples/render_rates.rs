//! kflex's rendering rates on one thread, for the side-by-side table of
//! `tools/tinyrenderer_compare.py`: 48×48 silhouettes of the working region,
//! full 640×480 shaded frames, and the working region of a frame alone, the
//! pose changing every call (the sweep of `export_shapes.rs`).
//!
//! `cargo run --release -p kflex-model --example render_rates [seconds] [what]`
//! (default 2 s per rate; `what`, one of `silhouette_48`, `frame_640x480`,
//! `roi_window`, times that one alone, e.g. under a profiler). Prints one
//! line per rate, `kflex <what> <per_second>`.

use std::time::{Duration, Instant};

use kflex_model::{
    Camera, FrameParams, Instrument, InstrumentShape, Mask, Rasterizer, Roi, SceneRenderer,
};

/// The sweep of poses (θ deg, d mm); `export_shapes.rs` holds the same.
fn poses() -> Vec<(f64, f64)> {
    (0..)
        .map(|i| -60.0 + 0.37 * f64::from(i))
        .take_while(|theta| *theta <= 60.0)
        .map(|theta| (theta, 10.0))
        .collect()
}

/// Calls `f` on the shapes in turn, round and round, for at least `span`;
/// returns calls per second (0 without shapes).
fn rate(
    shapes: &[InstrumentShape],
    span: Duration,
    mut f: impl FnMut(&InstrumentShape) -> Result<(), kflex_model::ModelError>,
) -> Result<f64, kflex_model::ModelError> {
    let start = Instant::now();
    let mut calls = 0_u64;
    for shape in shapes.iter().cycle() {
        f(shape)?;
        calls += 1;
        let elapsed = start.elapsed();
        if elapsed >= span {
            return Ok(calls as f64 / elapsed.as_secs_f64());
        }
    }
    Ok(0.0) // no shapes
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seconds: f64 = match std::env::args().nth(1) {
        Some(s) => s.parse()?,
        None => 2.0,
    };
    let span = Duration::from_secs_f64(seconds);
    let only = std::env::args().nth(2);
    let wanted = |what: &str| only.as_deref().is_none_or(|o| o == what);
    if let Some(o) = only.as_deref()
        && !["silhouette_48", "frame_640x480", "roi_window"].contains(&o)
    {
        return Err(
            format!("unknown rate {o:?}: silhouette_48, frame_640x480 or roi_window").into(),
        );
    }
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let roi = Roi::paper(&camera)?;
    let small = camera.with_intrinsics(roi.intrinsics(&camera.intrinsics, 48, 48)?);
    let shapes = poses()
        .into_iter()
        .map(|(theta, d)| instrument.shape(theta, d))
        .collect::<Result<Vec<_>, _>>()?;

    if wanted("silhouette_48") {
        let mut raster = Rasterizer::new();
        let mut mask = Mask::new(48, 48)?;
        let per_s = rate(&shapes, span, |shape| {
            mask.clear();
            raster.silhouette(&small, shape, &mut mask)
        })?;
        println!("kflex silhouette_48 {per_s:.1}");
    }

    let params = FrameParams::default();
    let mut renderer = SceneRenderer::new();
    if wanted("frame_640x480") {
        let per_s = rate(&shapes, span, |shape| {
            renderer.render(&camera, shape, &params).map(|_| ())
        })?;
        println!("kflex frame_640x480 {per_s:.1}");
    }

    if wanted("roi_window") {
        let per_s = rate(&shapes, span, |shape| {
            renderer
                .render_window(&camera, shape, &params, roi)
                .map(|_| ())
        })?;
        println!("kflex roi_window {per_s:.1}");
    }
    Ok(())
}
