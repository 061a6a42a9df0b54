//! Draws one case of the robustness matrix as a PNG to look at (and prints
//! its score as the matrix does): the region
//! of interest as rendered, the renderer's truth, and the segmentation
//! (green: found and true, red: found but tissue, blue: missed).
//!
//! `cargo run --release -p kflex-estimate --example segment_case -- CONDITION BACKGROUND THETA D OUT.png`
//! with CONDITION the index into the goal conditions (0 baseline … 11 yellow
//! tissue), then those past the goals (12–15) and the edges of IBJAE's
//! training ranges (16–19), then the paper's tape (20–23: 20 and 40 % over
//! the middle, then the distal part), in the order `tests/matrix` lists them;
//! BACKGROUND colon, stomach or larynx.

#[path = "../tests/matrix/mod.rs"]
mod matrix;

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::Background;
use matrix::{Bench, Case, Condition};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [condition, background, theta, d, out] = args.as_slice() else {
        return Err("usage: segment_case CONDITION BACKGROUND THETA D OUT.png".into());
    };
    let condition = *Condition::GOALS
        .iter()
        .chain(Condition::BEYOND.iter())
        .chain(Condition::TRAINING.iter())
        .chain(Condition::TAPE.iter())
        .nth(condition.parse()?)
        .ok_or("condition index out of range")?;
    let background: Background = background.parse()?;
    let case = Case {
        background,
        theta_deg: theta.parse()?,
        d_mm: d.parse()?,
    };
    let mut bench = Bench::default();
    // other backgrounds of the same organs: `KFLEX_MATRIX_SEED=N` adds N to their seeds
    if let Ok(offset) = std::env::var("KFLEX_MATRIX_SEED") {
        bench.seed_offset = offset.parse()?;
    }
    let (frame, parts) = bench.frame(case, condition);
    let roi = bench.roi_of(case);
    let truth = frame.instrument.crop(roi)?;
    // as in `robustness_table`: `KFLEX_SEGMENT_PARAMS` overrides the fields it names
    let params = match std::env::var("KFLEX_SEGMENT_PARAMS") {
        Ok(json) => serde_json::from_str::<SegmentParams>(&json)?,
        Err(_) => SegmentParams::default(),
    };
    let mut segmenter = Segmenter::new(params)?;
    let found = match segmenter.segment(&frame.rgb, frame.width, frame.height, roi) {
        Ok(s) => Some(s.full.clone()),
        Err(e) => {
            eprintln!("segmentation: {e}");
            None
        }
    };
    let (w, h) = (roi.width, roi.height);
    let mut img = image::RgbImage::new(2 * w, h);
    for y in 0..h {
        for x in 0..w {
            let i = 3 * ((roi.y0 + y) * frame.width + roi.x0 + x) as usize;
            img.put_pixel(
                x,
                y,
                image::Rgb([frame.rgb[i], frame.rgb[i + 1], frame.rgb[i + 2]]),
            );
            let t = truth.get(x, y);
            let f = found.as_ref().is_some_and(|m| m.get(x, y));
            let c = match (f, t) {
                (true, true) => [40, 200, 40],
                (true, false) => [230, 40, 40],
                (false, true) => [40, 80, 255],
                (false, false) => [0, 0, 0],
            };
            img.put_pixel(w + x, y, image::Rgb(c));
        }
    }
    // as the robustness matrix scores it: in the region, and on the bend and
    // gripper alone
    if let Some(m) = &found {
        let s = matrix::Score::of(m, &truth, &parts.crop(roi));
        let distal = s.distal.map_or("not scored".into(), |d| format!("{d:.3}"));
        println!(
            "IoU {:.3} in the region, {distal} on the bend and gripper",
            s.roi
        );
    }
    img.save(out)?;
    Ok(())
}
