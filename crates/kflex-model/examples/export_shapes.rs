//! Writes, as JSON, the K-FLEX instrument's bodies in the default camera's
//! frame for a sweep of poses, with the camera's intrinsics and its working
//! region: the geometry `tools/tinyrenderer_compare.py` hands to PyBullet's
//! TinyRenderer so that both renderers draw the same capsule chain.
//!
//! `cargo run --release -p kflex-model --example export_shapes [--pose θ d] [out.json]`
//! (stdout without a file). The poses are [`poses`]: the bend θ from −60° to
//! 60° in 0.37° steps at d = 10 mm, the sweep `render_rates` times; with
//! `--pose`, that one pose alone (θ deg, d mm).
//!
//! The default camera has a wide-angle lens (division-model barrel
//! distortion, `camera.lens`); the JSON carries only its pinhole intrinsics,
//! so a pinhole renderer sees the same bodies slightly elsewhere near the
//! image's edges.

use kflex_model::{Camera, Ends, Instrument, Roi};
use nalgebra::Point3;
use serde_json::json;

/// The sweep of poses (θ deg, d mm); `render_rates.rs` holds the same.
fn poses() -> Vec<(f64, f64)> {
    (0..)
        .map(|i| -60.0 + 0.37 * f64::from(i))
        .take_while(|theta| *theta <= 60.0)
        .map(|theta| (theta, 10.0))
        .collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let sweep = match args.iter().position(|a| a == "--pose") {
        Some(i) if i + 2 < args.len() => {
            let pose: Vec<String> = args.drain(i..i + 3).skip(1).collect();
            vec![(pose[0].parse()?, pose[1].parse()?)]
        }
        Some(_) => return Err("usage: export_shapes [--pose θ d] [out.json]".into()),
        None => poses(),
    };
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let roi = Roi::paper(&camera)?;
    let small = roi.intrinsics(&camera.intrinsics, 48, 48)?;
    let to_camera = |p: [f64; 3]| {
        let q = camera.camera_from_overtube * Point3::from(p);
        [q.x, q.y, q.z]
    };
    let mut frames = Vec::new();
    for (theta, d) in sweep {
        let shape = instrument.shape(theta, d)?;
        let bodies: Vec<_> = shape
            .bodies
            .iter()
            .map(|b| {
                json!({
                    "a_mm": to_camera(b.a_mm),
                    "b_mm": to_camera(b.b_mm),
                    "radius_mm": b.radius_mm,
                    "round": b.ends == Ends::Round,
                })
            })
            .collect();
        frames.push(json!({ "theta_deg": theta, "d_mm": d, "bodies": bodies }));
    }
    let doc = json!({
        "frame": "camera: x right, y down, z forward, mm",
        "lens": "the default camera's lens distorts (barrel); these intrinsics are its pinhole part",
        "intrinsics": camera.intrinsics,
        "roi": roi,
        "roi_intrinsics_48": small,
        "poses": frames,
    });
    let text = serde_json::to_string(&doc)?;
    match args.first() {
        Some(path) => std::fs::write(path, text)?,
        None => println!("{text}"),
    }
    Ok(())
}
