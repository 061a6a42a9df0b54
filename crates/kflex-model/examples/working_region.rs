//! The working regions of the default camera and what their 48×48
//! silhouettes resolve: the bands and their regions, then for each
//! translation d (every `STEP` mm, default 2) and each part of the bend
//! range, how many adjacent 1° bends give identical silhouettes in the
//! pose's band, and what share of the silhouette's pixels the bend and
//! gripper make.
//!
//! `cargo run --release -p kflex-model --example working_region [θ0 θ1 d0 d1 [parts [growth]]]`
//! (default: `PoseRange::FULL`, `Banding::default()`). With `SHOW` set in
//! the environment it also prints the bends whose silhouette equals the
//! previous degree's.

use kflex_model::{
    Banding, Camera, Instrument, Mask, Part, PoseRange, Rasterizer, WorkingBand, WorkingRegions,
};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let mut banding = Banding::default();
    let poses = match args.as_slice() {
        [t0, t1, d0, d1, rest @ ..] if rest.len() <= 2 => {
            if let Some(p) = rest.first() {
                banding.theta_parts = *p as u32;
            }
            if let Some(g) = rest.get(1) {
                banding.growth = *g;
            }
            PoseRange {
                theta_deg: [*t0, *t1],
                translation_mm: [*d0, *d1],
            }
        }
        [] => PoseRange::FULL,
        _ => return Err("usage: working_region [θ0 θ1 d0 d1 [parts [growth]]]".into()),
    };
    let step: f64 = std::env::var("STEP").map_or(Ok(2.0), |s| s.parse())?;
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let regions = WorkingRegions::for_workspace(&camera, &instrument, &poses, &banding)?;
    println!(
        "poses θ {:?} deg, d {:?} mm, {banding:?}: {} bands of the {}×{} frame",
        poses.theta_deg,
        poses.translation_mm,
        regions.bands().len(),
        camera.intrinsics.width,
        camera.intrinsics.height
    );
    println!("| θ (deg) | d (mm) | region (px) | at |");
    println!("|---|---|---|---|");
    for b in regions.bands() {
        let ([t0, t1], [d0, d1], r) = (b.poses.theta_deg, b.poses.translation_mm, b.roi);
        println!(
            "| {t0:.0}…{t1:.0} | {d0:.0}–{d1:.0} | {}×{} | ({}, {}) |",
            r.width, r.height, r.x0, r.y0
        );
    }
    println!();
    println!(
        "| d (mm) | θ part (deg) | identical adjacent 1° pairs | bend + gripper share of the 48×48 silhouette (mean, min) |"
    );
    println!("|---|---|---|---|");
    let mut raster = Rasterizer::new();
    let (mut a, mut b) = (Mask::new(48, 48)?, Mask::new(48, 48)?);
    let mut distal = Mask::new(48, 48)?;
    let [d0, d1] = poses.translation_mm;
    let steps = ((d1 - d0) / step).ceil().max(0.0) as usize;
    // the parts of the bend range: the θ ranges of the bands, each once
    let mut parts: Vec<[f64; 2]> = regions.bands().iter().map(|b| b.poses.theta_deg).collect();
    parts.dedup();
    for i in 0..=steps {
        let d = (d0 + step * i as f64).min(d1);
        for &[t0, t1] in &parts {
            // the band of this part that an estimator reads at d
            let band: &WorkingBand = regions
                .bands()
                .iter()
                .rfind(|b| b.poses.theta_deg == [t0, t1] && b.poses.contains(t0, d))
                .ok_or("no band")?;
            let small = camera.with_intrinsics(band.roi.intrinsics(&camera.intrinsics, 48, 48)?);
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
                        eprint!("d {d} θ {theta}; ");
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
                "| {d:.0} | {t0:.0}…{t1:.0} | {identical} | {:.0} %, {:.0} % |",
                100.0 * mean,
                100.0 * min
            );
        }
    }
    Ok(())
}
