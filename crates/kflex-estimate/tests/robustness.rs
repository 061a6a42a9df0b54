//! The robustness matrix (issue 9), asserted: per condition, every case's IoU
//! in the working region and on the bend and gripper alone. Goals: 0.90 and
//! 0.85. Where a condition does not reach them, the bound asserted is what it
//! reaches (measured, rounded down), marked BELOW GOAL, so a regression still
//! fails. `examples/robustness_table.rs` prints the table.

mod matrix;

use kflex_estimate::{EstimateError, SegmentParams, Segmenter};
use kflex_model::Background;
use matrix::{Bench, Condition, Tissue, cases};

/// `(condition, least ROI IoU, least distal IoU)`.
// Measured over the working range (d = 8, 20, 35 mm), each case in the
// region IBJAE reads at its pose (`WorkingRegions::full`). The far poses
// (d = 35 mm) are the weak ones: the steel is dark there, its light falling
// with distance, against brighter tissue; the near ones meet the goals.
// A case where the segmentation finds no instrument scores 0.
const BOUNDS: [(Condition, f64, f64); 12] = [
    (Condition::Baseline, 0.83, 0.72), // BELOW GOAL: 0.836 / 0.723 (larynx, 35 mm; median 0.957 / 0.940)
    (Condition::Gain(0.4), 0.46, 0.23), // BELOW GOAL: 0.463 / 0.238
    (Condition::Gain(1.6), 0.38, 0.24), // BELOW GOAL: 0.385 / 0.244
    (Condition::Noise(0.1), 0.65, 0.46), // BELOW GOAL: 0.660 / 0.462
    (Condition::Blur(3.0), 0.67, 0.45), // BELOW GOAL: 0.676 / 0.454
    (Condition::Tint(0.25), 0.44, 0.22), // BELOW GOAL: 0.449 / 0.226
    (Condition::Specular, 0.82, 0.68), // BELOW GOAL: 0.823 / 0.687
    (Condition::Tissue(Tissue::Grey), 0.0, 0.0), // BELOW GOAL: 6 of 45 found empty (median 0.569 / 0.413)
    (Condition::Tissue(Tissue::Pale), 0.47, 0.24), // BELOW GOAL: 0.472 / 0.249
    (Condition::Tissue(Tissue::White), 0.02, 0.0), // BELOW GOAL: 0.021 / 0.000 (median 0.750 / 0.715)
    (Condition::Tissue(Tissue::BlueGreen), 0.53, 0.32), // BELOW GOAL: 0.540 / 0.327
    (Condition::Tissue(Tissue::Yellow), 0.51, 0.28), // BELOW GOAL: 0.514 / 0.289
];

/// Frames of the matrix the segmentation calls empty, at most: grey tissue
/// (BELOW GOAL: 6 of 45 measured; goal 0).
const MOST_MISSED_GREY: usize = 6;

/// Frames without the instrument that the segmentation calls instrument, at
/// most, of the 36 tried (BELOW GOAL: 2 measured, wet colon folds in the
/// region of (0°, 10 mm); goal 0).
const MOST_FALSE_FOUND: usize = 2;

#[test]
fn every_case_of_every_condition_meets_its_bound() {
    let mut bench = Bench::default();
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let mut failures = Vec::new();
    for (condition, roi_min, distal_min) in BOUNDS {
        for case in cases() {
            match bench.score(&mut segmenter, case, condition) {
                Ok(s) => {
                    if s.roi < roi_min || s.distal.is_some_and(|d| d < distal_min) {
                        failures.push(format!("{}: {case:?}: {s:?}", condition.name()));
                    }
                }
                Err(EstimateError::NoInstrument { .. }) if roi_min == 0.0 => {}
                Err(e) => failures.push(format!("{}: {case:?}: {e}", condition.name())),
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Frames without the instrument give no instrument, on every background and
/// repainted tissue colour, but for the few measured; the same frames with it
/// do not.
#[test]
fn no_instrument_only_when_there_is_none() {
    let mut bench = Bench::default();
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let roi = bench.roi;
    let mut false_found = Vec::new();
    for background in Background::ALL {
        for tissue in [
            None,
            Some(Tissue::Pale),
            Some(Tissue::BlueGreen),
            Some(Tissue::Yellow),
            Some(Tissue::Grey),
            Some(Tissue::White),
        ] {
            for seed in 0..2 {
                let f = bench.empty_frame(background, tissue, seed);
                if let Ok(s) = segmenter.segment(&f.rgb, f.width, f.height, roi) {
                    false_found.push(format!(
                        "{background:?} {tissue:?} seed {seed}: {} px",
                        s.full.count()
                    ));
                }
            }
        }
    }
    assert!(false_found.len() <= MOST_FALSE_FOUND, "{false_found:#?}");
    let mut missed_grey = 0;
    for case in cases() {
        assert!(
            bench
                .score(&mut segmenter, case, Condition::Baseline)
                .is_ok(),
            "{case:?}"
        );
        missed_grey += usize::from(
            bench
                .score(&mut segmenter, case, Condition::Tissue(Tissue::Grey))
                .is_err(),
        );
    }
    assert!(missed_grey <= MOST_MISSED_GREY, "{missed_grey}");
}
