//! The robustness matrix (issue 9), asserted: per condition, every case's IoU
//! in the working region and on the bend and gripper alone. Goals: 0.90 and
//! 0.85. Where a condition does not reach them, the bound asserted is what it
//! reaches (measured, rounded down), marked BELOW GOAL, so a regression still
//! fails. `examples/robustness_table.rs` prints the table.

mod matrix;

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::Background;
use matrix::{Bench, Condition, Tissue, cases};

/// `(condition, least ROI IoU, least distal IoU)`.
// Measured on camera v2's frames over the organ backgrounds (smooth-noise
// folds, tissue lit with the instrument's falloff). The realistic tissue
// exposed cases the striped backgrounds hid: grey tissue at (60°, 10 mm)
// and the larynx under gain 1.6 (pale tissue clipping beside a bright
// shaft) fail outright. The tissue colour now starts from the region's
// border, which fixed the same pose under gain 0.4 and blue-green tissue.
const BOUNDS: [(Condition, f64, f64); 12] = [
    (Condition::Baseline, 0.90, 0.85),                  // 0.980 / 0.930
    (Condition::Gain(0.4), 0.88, 0.60),                 // BELOW GOAL: 0.890 / 0.601
    (Condition::Gain(1.6), 0.06, 0.04), // BELOW GOAL: 0.068 / 0.050 (larynx; median 0.957 / 0.934)
    (Condition::Noise(0.1), 0.90, 0.83), // BELOW GOAL (distal): 0.943 / 0.833
    (Condition::Blur(3.0), 0.90, 0.78), // BELOW GOAL (distal): 0.932 / 0.782
    (Condition::Tint(0.25), 0.90, 0.74), // BELOW GOAL (distal): 0.945 / 0.749
    (Condition::Specular, 0.90, 0.85),  // 0.921 / 0.851
    (Condition::Tissue(Tissue::Grey), 0.015, 0.0), // BELOW GOAL: 0.020 / 0.000 (median 0.679 / 0.643)
    (Condition::Tissue(Tissue::Pale), 0.85, 0.59), // BELOW GOAL: 0.882 / 0.599
    (Condition::Tissue(Tissue::White), 0.55, 0.05), // BELOW GOAL: 0.557 / 0.051 (median 0.885 / 0.858)
    (Condition::Tissue(Tissue::BlueGreen), 0.90, 0.85), // 0.981 / 0.933
    (Condition::Tissue(Tissue::Yellow), 0.90, 0.85), // 0.976 / 0.905
];

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
                Err(e) => failures.push(format!("{}: {case:?}: {e}", condition.name())),
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Frames without the instrument give no instrument, on every background and
/// repainted tissue colour; the same frames with it do not.
#[test]
fn no_instrument_only_when_there_is_none() {
    let mut bench = Bench::default();
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let roi = bench.roi;
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
                let got = segmenter.segment(&f.rgb, f.width, f.height, roi);
                assert!(
                    got.is_err(),
                    "{background:?} {tissue:?} seed {seed}: {} px called instrument",
                    got.map(|s| s.full.count()).unwrap_or(0)
                );
            }
        }
    }
    for case in cases() {
        for condition in [Condition::Baseline, Condition::Tissue(Tissue::Grey)] {
            assert!(
                bench.score(&mut segmenter, case, condition).is_ok(),
                "{case:?} {}",
                condition.name()
            );
        }
    }
}
