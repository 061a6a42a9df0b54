//! The working region of the default camera and what its 48×48 silhouettes
//! resolve: for each translation d of the range, how many adjacent 1° bends
//! give identical silhouettes, and what share of the silhouette's pixels the
//! bend and gripper make.
//!
//! `cargo run --release -p kflex-model --example working_region [θ0 θ1 d0 d1]`
//! (default: `Roi::WORKING_POSES`). With `SHOW` set in the environment it
//! also prints the bends whose silhouette equals the previous degree's.

use kflex_model::{Camera, Instrument, Mask, Part, PoseRange, Rasterizer, Roi};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let poses = match args.as_slice() {
        [t0, t1, d0, d1] => PoseRange {
            theta_deg: [*t0, *t1],
            translation_mm: [*d0, *d1],
        },
        [] => Roi::WORKING_POSES,
        _ => return Err("usage: working_region [θ0 θ1 d0 d1]".into()),
    };
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let roi = Roi::for_workspace(&camera, &instrument, &poses, Roi::WORKING_MARGIN_PX)?;
    println!(
        "poses θ {:?} deg, d {:?} mm: region {}×{} px at ({}, {}) of {}×{}",
        poses.theta_deg,
        poses.translation_mm,
        roi.width,
        roi.height,
        roi.x0,
        roi.y0,
        camera.intrinsics.width,
        camera.intrinsics.height
    );
    let small = camera.with_intrinsics(roi.intrinsics(&camera.intrinsics, 48, 48)?);
    let mut raster = Rasterizer::new();
    let (mut a, mut b) = (Mask::new(48, 48)?, Mask::new(48, 48)?);
    let mut distal = Mask::new(48, 48)?;
    println!(
        "| d (mm) | identical adjacent 1° pairs | bend + gripper share of the 48×48 silhouette (mean, min) |"
    );
    println!("|---|---|---|");
    let [d0, d1] = poses.translation_mm;
    let steps = ((d1 - d0) / 5.0).ceil().max(0.0) as usize;
    for i in 0..=steps {
        let d = (d0 + 5.0 * i as f64).min(d1);
        let [t0, t1] = poses.theta_deg;
        let n = (t1 - t0).round() as i64;
        let (mut identical, mut shares) = (0, Vec::new());
        for j in 0..=n {
            let theta = t0 + j as f64;
            let mut shape = instrument.shape(theta, d)?;
            a.clear();
            raster.silhouette(&small, &shape, &mut a)?;
            if j > 0 && a == b {
                identical += 1;
                if std::env::var_os("SHOW").is_some() {
                    eprint!("{theta} ");
                }
            }
            std::mem::swap(&mut a, &mut b);
            shape.bodies.retain(|c| c.part != Part::Shaft);
            distal.clear();
            raster.silhouette(&small, &shape, &mut distal)?;
            let both = distal
                .data()
                .iter()
                .zip(b.data())
                .filter(|(x, y)| **x == 1 && **y == 1)
                .count();
            shares.push(both as f64 / b.count().max(1) as f64);
        }
        let mean = shares.iter().sum::<f64>() / shares.len() as f64;
        let min = shares.iter().copied().fold(f64::INFINITY, f64::min);
        println!(
            "| {d:.0} | {identical} | {:.0} %, {:.0} % |",
            100.0 * mean,
            100.0 * min
        );
    }
    Ok(())
}
