//! Prints the segmentation's robustness table (issue 9): for each condition,
//! the minimum and median IoU over the matrix of cases, in the working region
//! and on the bend and gripper alone, and the frames wrongly called empty.
//!
//! `cargo run --release -p kflex-estimate --example robustness_table`
//! (with `KFLEX_SEGMENT_PARAMS='{"field": value, …}'` it measures other
//! thresholds than the defaults; with `KFLEX_WORST=1` it also names each
//! condition's worst case, in the region and on the bend and gripper, for
//! `examples/segment_case.rs`, with `KFLEX_UNDER=1` every case under a goal;
//! `KFLEX_MATRIX_SEED=0,100,200` pools the cases over other backgrounds of
//! the same organs, their seeds moved by each offset; `KFLEX_ONLY=blur` keeps
//! the conditions whose name holds `blur`; `KFLEX_FINGERPRINT=1` prints a
//! hash of every mask found, to check that a change leaves them alike)

#[path = "../tests/matrix/mod.rs"]
mod matrix;

use kflex_estimate::{EstimateError, SegmentParams, Segmenter};
use kflex_model::Background;
use kflex_model::Tissue;
use matrix::{Bench, Condition, cases, min_median};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut bench = Bench::default();
    // other backgrounds of the same organs: `KFLEX_MATRIX_SEED=N` adds N to
    // their seeds; `N,M,…` pools the cases of each
    let offsets: Vec<u64> = match std::env::var("KFLEX_MATRIX_SEED") {
        Ok(list) => list
            .split(',')
            .map(|o| o.trim().parse())
            .collect::<Result<_, _>>()?,
        Err(_) => vec![0],
    };
    // thresholds to try: `KFLEX_SEGMENT_PARAMS='{"bright_ratio": 1.3}'`
    // overrides the defaults' fields it names
    let params = match std::env::var("KFLEX_SEGMENT_PARAMS") {
        Ok(json) => serde_json::from_str::<SegmentParams>(&json)?,
        Err(_) => SegmentParams::default(),
    };
    let mut segmenter = Segmenter::new(params)?;
    let cases = cases();
    // `KFLEX_FINGERPRINT=1`: a hash of every segmentation's masks (full and
    // 48×48; the tape's rows left out), printed at the end, to check that a
    // change leaves them alike
    let mut fingerprint = std::env::var_os("KFLEX_FINGERPRINT").map(|_| 0xcbf2_9ce4_8422_2325_u64);
    println!(
        "{} cases a condition (backgrounds {:?} × θ {:?} deg × d {:?} mm, background seed \
         offsets {offsets:?}), each in the working region of its pose (`WorkingRegions::full`)",
        cases.len() * offsets.len(),
        Background::ALL,
        matrix::THETAS_DEG,
        matrix::DS_MM,
    );
    println!();
    println!(
        "| condition | no instrument | ROI IoU min | ROI IoU median | distal IoU min | distal IoU median | under a goal |"
    );
    println!("|---|---|---|---|---|---|---|");
    let fmt = |v: Option<(f64, f64)>| match v {
        Some((min, median)) => (format!("{min:.3}"), format!("{median:.3}")),
        None => ("–".into(), "–".into()),
    };
    for (label, condition) in Condition::GOALS
        .iter()
        .map(|c| ("", *c))
        .chain(Condition::BEYOND.iter().map(|c| (" (past the goals)", *c)))
        .chain(
            Condition::TRAINING
                .iter()
                .map(|c| (" (IBJAE's training range)", *c)),
        )
        .chain(Condition::TAPE.iter().map(|c| (" (the paper's)", *c)))
    {
        // `KFLEX_ONLY=blur` keeps the conditions whose name holds it
        if let Ok(only) = std::env::var("KFLEX_ONLY")
            && !condition.name().contains(only.as_str())
        {
            continue;
        }
        let (mut roi, mut distal, mut missed, mut under) = (Vec::new(), Vec::new(), 0, 0);
        let (mut worst, mut worst_distal) = (None, None);
        for (&offset, &case) in offsets
            .iter()
            .flat_map(|o| cases.iter().map(move |c| (o, c)))
        {
            bench.seed_offset = offset;
            // the tape's rows came later: left out, so that the hash reads
            // as it did before them
            if let Some(h) = fingerprint
                .as_mut()
                .filter(|_| !matches!(condition, Condition::Tape(..)))
            {
                let (frame, _) = bench.frame(case, condition);
                let found =
                    segmenter.segment(&frame.rgb, frame.width, frame.height, bench.roi_of(case));
                let bytes: Vec<u8> = match &found {
                    Ok(s) => s
                        .full
                        .data()
                        .iter()
                        .chain(s.small.data())
                        .copied()
                        .collect(),
                    Err(e) => e.to_string().into_bytes(),
                };
                for b in bytes {
                    *h = (*h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
                }
            }
            match bench.score(&mut segmenter, case, condition) {
                Ok(s) => {
                    if worst.is_none_or(|(w, _, _)| s.roi < w) {
                        worst = Some((s.roi, offset, case));
                    }
                    if let Some(d) = s.distal
                        && worst_distal.is_none_or(|(w, _, _)| d < w)
                    {
                        worst_distal = Some((d, offset, case));
                    }
                    let short = !s.meets(matrix::GOAL_ROI, matrix::GOAL_DISTAL);
                    if short && std::env::var_os("KFLEX_UNDER").is_some() {
                        eprintln!(
                            "  under: {} offset {offset} {case:?} {s:?}",
                            condition.name()
                        );
                    }
                    under += usize::from(short);
                    roi.push(s.roi);
                    distal.extend(s.distal);
                }
                Err(EstimateError::NoInstrument { .. }) => {
                    if std::env::var_os("KFLEX_UNDER").is_some() {
                        eprintln!(
                            "  under: {} offset {offset} {case:?} no instrument",
                            condition.name()
                        );
                    }
                    missed += 1;
                    under += 1;
                    roi.push(0.0);
                    distal.push(0.0);
                }
                Err(e) => return Err(e.into()),
            }
        }
        let (rmin, rmed) = fmt(min_median(&mut roi));
        let (dmin, dmed) = fmt(min_median(&mut distal));
        let name = format!("{}{label}", condition.name());
        println!("| {name} | {missed} | {rmin} | {rmed} | {dmin} | {dmed} | {under} |");
        if std::env::var_os("KFLEX_WORST").is_some() {
            for (what, w) in [("ROI", worst), ("distal", worst_distal)] {
                if let Some((iou, offset, case)) = w {
                    eprintln!("  worst {what} {iou:.3}: seed offset {offset}, {case:?}");
                }
            }
        }
    }
    println!();
    let mut false_found = Vec::new();
    let tissues = Tissue::ALL;
    let mut total = 0;
    // the same backgrounds as the cases: each offset's
    for &offset in &offsets {
        bench.seed_offset = offset;
        for background in Background::ALL {
            for tissue in tissues {
                for seed in 0..3 {
                    total += 1;
                    let f = bench.empty_frame(background, tissue, seed);
                    if let Ok(seg) = segmenter.segment(&f.rgb, f.width, f.height, bench.roi) {
                        false_found.push(format!(
                            "{background:?} {tissue:?} seed {seed} offset {offset}: {} px",
                            seg.full.count()
                        ));
                    }
                }
            }
        }
    }
    if let Some(h) = fingerprint {
        println!("fingerprint of the masks: {h:016x}");
    }
    println!(
        "frames without the instrument called instrument: {} of {total} {:?}",
        false_found.len(),
        false_found
    );
    Ok(())
}
