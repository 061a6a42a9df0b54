//! What a threshold half way between the two colours reaches under optical
//! blur (issue 9's "blur ≤ 3 px" goal), were it to know both colours exactly
//! and see no noise: the renderer's exact instrument mask blurred by the
//! same Gaussian and cut at one half. (Not a bound on every segmentation: a
//! cut elsewhere could keep thin jaws whose peak falls under one half.) Scored as the
//! robustness matrix scores a segmentation, in the same regions.
//!
//! `cargo run --release -p kflex-estimate --example blur_bound`

#[path = "../tests/matrix/mod.rs"]
mod matrix;

use kflex_model::{Background, Mask};
use matrix::{Bench, Case, Condition, DS_MM, GOAL_DISTAL, GOAL_ROI, Score, THETAS_DEG};

/// `mask` (0/1) blurred by a Gaussian of `sigma` px and cut at one half.
fn blurred_cut(mask: &Mask, sigma: f64) -> Mask {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f64 = kernel.iter().sum();
    let src: Vec<f64> = mask.data().iter().map(|&v| f64::from(v)).collect();
    // one pass of the separable kernel, along rows (`step` 1, `len` w) or
    // columns (`step` w, `len` h), the edge pixel repeated past the ends
    let pass = |src: &[f64], step: usize, len: usize| -> Vec<f64> {
        (0..w * h)
            .map(|i| {
                let at = (i / step) % len; // position along the pass
                let base = i - at * step;
                kernel
                    .iter()
                    .enumerate()
                    .map(|(j, k)| {
                        let s = (at as isize + j as isize - r).clamp(0, len as isize - 1);
                        k * src[base + s as usize * step]
                    })
                    .sum::<f64>()
                    / norm
            })
            .collect()
    };
    let out = pass(&pass(&src, 1, w), w, h);
    let bits = out.iter().map(|&v| u8::from(v >= 0.5)).collect();
    Mask::from_raw(mask.width(), mask.height(), bits).expect("same size")
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut bench = Bench::default();
    println!(
        "| blur σ (px) | d (mm) | ROI IoU min | ROI IoU median | distal IoU min | distal IoU median | under a goal (of 5) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for sigma in [1.5, 3.0, 6.0] {
        for d_mm in DS_MM {
            let (mut rois, mut distals, mut under) = (Vec::new(), Vec::new(), 0);
            for theta_deg in THETAS_DEG {
                // the geometry alone: one background serves
                let case = Case {
                    background: Background::Colon,
                    theta_deg,
                    d_mm,
                };
                let (frame, parts) = bench.frame(case, Condition::Baseline);
                let roi = bench.roi_of(case);
                let found = blurred_cut(&frame.instrument, sigma).crop(roi)?;
                let truth = frame.instrument.crop(roi)?;
                let score = Score::of(&found, &truth, &parts.crop(roi));
                if !score.meets(GOAL_ROI, GOAL_DISTAL) {
                    under += 1;
                }
                rois.push(score.roi);
                distals.extend(score.distal);
            }
            let (rmin, rmed) = matrix::min_median(&mut rois).unwrap_or((f64::NAN, f64::NAN));
            let (dmin, dmed) = matrix::min_median(&mut distals).unwrap_or((f64::NAN, f64::NAN));
            println!(
                "| {sigma} | {d_mm} | {rmin:.3} | {rmed:.3} | {dmin:.3} | {dmed:.3} | {under} |"
            );
        }
    }
    Ok(())
}
