//! The robustness matrix (issue 9), asserted: per condition, every case's IoU
//! in the working region and on the bend and gripper alone. Goals: 0.90 and
//! 0.85. Where a condition does not reach them, the bound asserted is what it
//! reaches (measured, rounded down), marked BELOW GOAL, so a regression still
//! fails. `examples/robustness_table.rs` prints the table.

mod matrix;

use kflex_estimate::{EstimateError, SegmentParams, Segmenter};
use kflex_model::Tissue;
use kflex_model::{Background, Mask};
use matrix::{Bench, Case, Condition, Parts, Score, cases};

/// `(condition, least ROI IoU, least distal IoU)`.
// Measured over the working range (d = 8, 20, 35 mm), each case in the
// region IBJAE reads at its pose (`WorkingRegions::full`), on frames encoded
// by the camera's response (BT.709), the threshold starting from the
// steel's base colour. The far poses (d = 35 mm) are the weak ones. A case where the
// segmentation finds no instrument scores 0. The tissue colours are rendered
// in the scene (`FrameParams::tissue`), so the steel reflects them.
const BOUNDS: [(Condition, f64, f64); 12] = [
    (Condition::Baseline, 0.90, 0.85),                  // 0.959 / 0.915
    (Condition::Gain(0.4), 0.90, 0.85),                 // 0.924 / 0.893
    (Condition::Gain(1.6), 0.90, 0.85),                 // 0.959 / 0.915
    (Condition::Noise(0.1), 0.90, 0.85),                // 0.911 / 0.856
    (Condition::Blur(3.0), 0.89, 0.82), // BELOW GOAL: 0.892 / 0.829 (median 0.947 / 0.925)
    (Condition::Tint(0.25), 0.90, 0.85), // 0.965 / 0.928
    (Condition::Specular, 0.90, 0.85),  // 0.939 / 0.900
    (Condition::Tissue(Tissue::Grey), 0.88, 0.85), // BELOW GOAL: 0.888 / 0.855 (median 0.972 / 0.966)
    (Condition::Tissue(Tissue::Pale), 0.90, 0.85), // 0.948 / 0.912
    (Condition::Tissue(Tissue::White), 0.89, 0.84), // BELOW GOAL: 0.894 / 0.845 (median 0.972 / 0.968)
    (Condition::Tissue(Tissue::BlueGreen), 0.90, 0.85), // 0.965 / 0.930
    (Condition::Tissue(Tissue::Yellow), 0.90, 0.85), // 0.962 / 0.924
];

/// The paper's tape (`Condition::TAPE`), at the goals: the visible rest of
/// the instrument, whole (measured 2026-11-29).
const TAPE_BOUNDS: [(Condition, f64, f64); 4] = [
    (Condition::TAPE[0], 0.90, 0.85), // 20 % middle: 0.947 / 0.899
    (Condition::TAPE[1], 0.90, 0.85), // 40 % middle: 0.924 / 0.872
    (Condition::TAPE[2], 0.90, 0.85), // 20 % distal: 0.956 / 0.913
    (Condition::TAPE[3], 0.90, 0.85), // 40 % distal: 0.956 / 0.915
];

/// Frames of the matrix the segmentation calls empty, at most, per tissue
/// colour (as measured, of 45; goal 0).
const MOST_MISSED: [(Tissue, usize); 3] =
    [(Tissue::Grey, 0), (Tissue::Pale, 0), (Tissue::White, 0)];

#[test]
fn every_case_of_every_condition_meets_its_bound() {
    let mut bench = Bench::default();
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let mut failures = Vec::new();
    // and the edges of IBJAE's training ranges, at the goals, and the
    // paper's tape
    let training = Condition::TRAINING.map(|c| (c, matrix::GOAL_ROI, matrix::GOAL_DISTAL));
    for (condition, roi_min, distal_min) in BOUNDS.into_iter().chain(training).chain(TAPE_BOUNDS) {
        for case in cases() {
            match bench.score(&mut segmenter, case, condition) {
                Ok(s) => {
                    if !s.meets(roi_min, distal_min) {
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
/// repainted tissue colour; the same frames with it do not.
#[test]
fn no_instrument_only_when_there_is_none() {
    let mut bench = Bench::default();
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let roi = bench.roi;
    let mut false_found = Vec::new();
    for background in Background::ALL {
        for tissue in Tissue::ALL {
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
    // none of the 36 (one, a wet colon fold in the region of (0°, 10 mm),
    // before overexposed tissue was clipped by the sensor)
    assert!(false_found.is_empty(), "{false_found:#?}");
    for case in cases() {
        assert!(
            bench
                .score(&mut segmenter, case, Condition::Baseline)
                .is_ok(),
            "{case:?}"
        );
    }
    for (tissue, most) in MOST_MISSED {
        let missed = cases()
            .into_iter()
            .filter(|&case| {
                bench
                    .score(&mut segmenter, case, Condition::Tissue(tissue))
                    .is_err()
            })
            .count();
        assert!(missed <= most, "{tissue:?}: {missed}");
    }
}

/// Cases under a goal (ROI IoU 0.90 or distal 0.85, or no instrument found),
/// at most, per condition in [`BOUNDS`]'s order then
/// [`Condition::TRAINING`]'s, of the 45 on other backgrounds of the same
/// organs (`Bench::seed_offset`): the bounds above were tuned on one
/// background per organ, and these keep the segmentation from being tuned
/// to it. As measured; goal 0 for each.
const MOST_UNDER_GOAL: [(u64, [usize; 16]); 3] = [
    (100, [0, 0, 0, 2, 5, 0, 0, 5, 0, 4, 0, 0, 0, 0, 0, 0]),
    (200, [0, 0, 0, 1, 4, 0, 0, 6, 0, 3, 0, 0, 0, 0, 0, 0]),
    (300, [0, 0, 1, 1, 4, 0, 0, 2, 0, 2, 0, 0, 0, 0, 0, 0]),
];

fn under_goal_on_other_backgrounds(offset: u64) {
    let (_, most) = MOST_UNDER_GOAL
        .iter()
        .find(|(o, _)| *o == offset)
        .expect("a measured offset");
    let mut bench = Bench::default();
    bench.seed_offset = offset;
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let mut failures = Vec::new();
    let conditions: Vec<&Condition> = BOUNDS
        .iter()
        .map(|b| &b.0)
        .chain(&Condition::TRAINING)
        .collect();
    assert_eq!(conditions.len(), most.len(), "a count for every condition");
    for (condition, &most) in conditions.into_iter().zip(most) {
        let under = cases()
            .into_iter()
            .filter(
                |&case| match bench.score(&mut segmenter, case, *condition) {
                    Ok(s) => !s.meets(matrix::GOAL_ROI, matrix::GOAL_DISTAL),
                    Err(EstimateError::NoInstrument { .. }) => true,
                    Err(e) => panic!("{}: {case:?}: {e}", condition.name()),
                },
            )
            .count();
        if under > most {
            failures.push(format!(
                "{}: {under} under a goal (at most {most})",
                condition.name()
            ));
        }
    }
    assert!(failures.is_empty(), "offset {offset}: {failures:#?}");
}

#[test]
fn few_cases_fall_short_on_other_backgrounds_100() {
    under_goal_on_other_backgrounds(100);
}

#[test]
fn few_cases_fall_short_on_other_backgrounds_200() {
    under_goal_on_other_backgrounds(200);
}

#[test]
fn few_cases_fall_short_on_other_backgrounds_300() {
    under_goal_on_other_backgrounds(300);
}

/// The distal score leaves the shaft out, its taped part too: a taped shaft
/// pixel taken for instrument is the shaft's fault (it lowers the region's
/// IoU), not the bend's; a taped pixel of the bend taken for instrument
/// still lowers the bend's. Before the shaft's taped pixels were known, the
/// first case read 0.667 on the bend.
#[test]
fn a_taped_shaft_pixel_found_does_not_count_against_the_bend() {
    let (w, h) = (40u32, 20u32);
    let mask = |keep: &dyn Fn(u32) -> bool| {
        let data = (0..w * h).map(|i| u8::from(keep(i % w))).collect();
        Mask::from_raw(w, h, data).unwrap()
    };
    // columns 0–9 visible shaft, 10–19 taped shaft, 20–39 the bend (400 px)
    let truth = mask(&|x| !(10..20).contains(&x));
    let parts = Parts {
        distal: mask(&|x| x >= 20),
        shaft: mask(&|x| x < 20),
    };
    // everything found, the taped shaft included
    let s = Score::of(&mask(&|_| true), &truth, &parts);
    assert_eq!(s.distal, Some(1.0), "{s:?}");
    assert!((s.roi - 0.75).abs() < 1e-12, "{s:?}");
    // the bend's last five columns taped, and found all the same
    let truth = mask(&|x| x < 10 || (20..35).contains(&x));
    let parts = Parts {
        distal: mask(&|x| (20..35).contains(&x)),
        shaft: mask(&|x| x < 20),
    };
    let s = Score::of(&mask(&|x| !(10..20).contains(&x)), &truth, &parts);
    assert_eq!(s.distal, Some(0.75), "{s:?}");
}

/// A taped frame's parts: every visible pixel of the instrument is in one
/// of them, a taped pixel is never in the bend's, and the tapes over the
/// middle put some of the shaft's taped pixels in the shaft's part (before,
/// the shaft was read off the visible pixels alone).
#[test]
fn the_shaft_part_holds_its_taped_pixels() {
    let mut bench = Bench::default();
    let case = Case {
        background: Background::Colon,
        theta_deg: 30.0,
        d_mm: 20.0,
    };
    for condition in Condition::TAPE {
        let (frame, parts) = bench.frame(case, condition);
        let mut taped_shaft = 0;
        let pixels = frame
            .occluder
            .data()
            .iter()
            .zip(frame.instrument.data())
            .zip(parts.distal.data().iter().zip(parts.shaft.data()));
        for ((&taped, &visible), (&distal, &shaft)) in pixels {
            let (visible, distal, shaft) = (visible != 0, distal != 0, shaft != 0);
            assert!(!(distal && shaft), "{condition:?}: a pixel in both parts");
            assert_eq!(visible, visible && (distal || shaft), "{condition:?}");
            assert!(taped == 0 || !distal, "{condition:?}: a taped bend pixel");
            taped_shaft += usize::from(taped != 0 && shaft);
        }
        if matches!(condition, Condition::Tape(_, at) if at == 0.5) {
            assert!(taped_shaft > 0, "{condition:?}: no taped shaft pixel");
        }
    }
}
