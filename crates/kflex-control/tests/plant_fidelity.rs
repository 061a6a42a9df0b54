//! The plant behaves as a tendon-sheath transmission does, measured on the
//! shipped defaults with the paper's input (no noise, no spread): a
//! symmetric sheath, loops with rounded transitions, and metrics that grow
//! with the bend the way Table IX's do; and, over perturbed repeats, a
//! run-to-run spread of the order of the paper's.

#[path = "support/loop_shape.rs"]
mod loop_shape;

use kflex_control::{GridRow, OpenLoopGrid};
use kflex_model::PlantConfig;
use loop_shape::{falling_branch_slopes, mirrored, reach, sliding_slope};

fn nominal() -> OpenLoopGrid {
    OpenLoopGrid {
        repeats: 1,
        spread: 0.0,
        noise: None,
        ..OpenLoopGrid::default()
    }
}

fn run(grid: OpenLoopGrid) -> Vec<GridRow> {
    grid.run().unwrap()
}

#[test]
fn a_mirrored_command_gives_a_mirrored_response_without_gravity() {
    let mut plant = PlantConfig::default();
    plant.joint.gravity_m_per_s2 = [0.0; 3];
    let positive = run(OpenLoopGrid { plant, ..nominal() });
    let reflected = run(OpenLoopGrid {
        plant,
        scenario: mirrored(),
        ..nominal()
    });
    for (p, m) in positive.iter().zip(&reflected) {
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(
            rel(m.rmse_deg.mean, p.rmse_deg.mean) < 0.03,
            "sheath {}: RMSE {} mirrored vs {}",
            p.sheath_deg,
            m.rmse_deg.mean,
            p.rmse_deg.mean
        );
        assert!(
            rel(m.max_hysteresis_deg.mean, p.max_hysteresis_deg.mean) < 0.03,
            "sheath {}: loop width {} mirrored vs {}",
            p.sheath_deg,
            m.max_hysteresis_deg.mean,
            p.max_hysteresis_deg.mean
        );
    }
    // and gravity, the one modelled cause of asymmetry, does break it
    let with_gravity = {
        let mut p = plant;
        p.joint.gravity_m_per_s2 = [-9.81, 0.0, 0.0];
        p.joint.tool_mass_g = 20.0;
        p
    };
    let up = run(OpenLoopGrid {
        plant: with_gravity,
        sheaths_deg: vec![90.0],
        ..nominal()
    });
    let down = run(OpenLoopGrid {
        plant: with_gravity,
        sheaths_deg: vec![90.0],
        scenario: mirrored(),
        ..nominal()
    });
    assert!((up[0].rmse_deg.mean - down[0].rmse_deg.mean).abs() > 0.05);
}

#[test]
fn rmse_grows_with_the_bend_and_the_loop_width_saturates() {
    // The goals: RMSE growing at every 15 deg from 0 to 270, the loop width
    // growing up to 180 deg and staying within 10 % of its largest beyond.
    // Measured (CALIBRATION.md): the RMSE grows at every step; the width
    // grows at every step up to 180 deg (by 0.28 % at the least, from 165 to
    // 180 deg; 31 % in all, far less than the paper's 9.2 to 18.3 deg), then
    // stays within 8.0 % of its largest out to 270 deg. The plants shipped
    // before the last refit of 2026-11-29 dipped by 2.3 % and 4 % on the way.
    let sheaths: Vec<f64> = (0..=18).map(|k| 15.0 * f64::from(k)).collect();
    let rows = run(OpenLoopGrid {
        sheaths_deg: sheaths,
        ..nominal()
    });
    let rmse: Vec<f64> = rows.iter().map(|r| r.rmse_deg.mean).collect();
    for (k, w) in rmse.windows(2).enumerate() {
        assert!(
            w[1] > w[0],
            "RMSE did not grow from {} deg to {} deg: {rmse:?}",
            15 * k,
            15 * (k + 1)
        );
    }
    let widths: Vec<f64> = rows.iter().map(|r| r.max_hysteresis_deg.mean).collect();
    let (peak, largest) =
        widths.iter().copied().enumerate().fold(
            (0, 0.0),
            |best, (k, w)| if w > best.1 { (k, w) } else { best },
        );
    // the loop widens with the bend first ...
    assert!(
        (3..=12).contains(&peak),
        "widest loop at {} deg: {widths:?}",
        15 * peak
    );
    assert!(largest > 1.1 * widths[0], "{widths:?}");
    // ... at every 15 deg up to 180 deg, each step by more than 0.1 %
    // (the fit holds each to 0.2 %) ...
    for (k, w) in widths.windows(2).enumerate().take(12) {
        assert!(
            w[1] > 1.001 * w[0],
            "loop width did not grow from {} deg ({}) to {} deg ({}): {widths:?}",
            15 * k,
            w[0],
            15 * (k + 1),
            w[1]
        );
    }
    // ... and then saturates rather than collapsing: from its peak on (the
    // goal asks it beyond 180 deg) within 10 % of its largest
    for (k, w) in widths.iter().enumerate().skip(peak) {
        assert!(
            *w >= 0.9 * largest,
            "loop width {w} at {} deg is more than 10 % below its largest {largest}",
            15 * k
        );
    }
}

#[test]
fn after_a_reversal_the_slope_rises_continuously_over_several_degrees() {
    // at 0 deg the sheath adds little friction and the drive's backlash shapes
    // the reversal: its flanks' engagement rounds the corner there
    for sheath_deg in [0.0, 90.0, 180.0, 270.0] {
        let slopes = falling_branch_slopes(PlantConfig {
            sheath_deg,
            ..PlantConfig::default()
        })
        .unwrap();
        // the sliding value: the mean slope over the last 15 deg of the branch
        let sliding = sliding_slope(&slopes);
        assert!(
            sliding > 0.2,
            "sheath {sheath_deg}: sliding slope {sliding}"
        );
        let reach = |share: f64| reach(&slopes, share, sliding).unwrap();
        let (p10, p90) = (reach(0.1), reach(0.9));
        assert!(
            p90 - p10 >= 3.0,
            "sheath {sheath_deg}: 10 % → 90 % of the sliding slope over {:.2} deg of command",
            p90 - p10
        );
        // no step on the way from 10 % to 90 %: between neighbouring samples
        // (≈ 0.1–0.25 deg of command) the slope changes by a small part of its
        // sliding value. The one kink left is where the slack antagonist
        // tendon comes taut again (a tendon cannot push): at 90 deg the slope
        // steps there by 23 % of its sliding value (CALIBRATION.md).
        for w in slopes.windows(2).filter(|w| w[1].0 >= p10 && w[1].0 <= p90) {
            assert!(
                (w[1].1 - w[0].1).abs() < 0.25 * sliding,
                "sheath {sheath_deg}: slope jumped from {:.3} to {:.3} at {:.2} deg (sliding {sliding:.3})",
                w[0].1,
                w[1].1,
                w[1].0
            );
        }
    }
}

#[test]
fn the_default_element_count_is_converged_to_2_percent() {
    let at = |elements: u32| {
        let mut plant = PlantConfig::default();
        plant.sheath.elements = elements;
        run(OpenLoopGrid {
            plant,
            sheaths_deg: vec![0.0, 90.0, 180.0, 270.0],
            ..nominal()
        })
    };
    let default = at(PlantConfig::default().sheath.elements);
    let fine = at(4 * PlantConfig::default().sheath.elements);
    for (d, f) in default.iter().zip(&fine) {
        for (a, b) in [
            (d.rmse_deg.mean, f.rmse_deg.mean),
            (d.max_hysteresis_deg.mean, f.max_hysteresis_deg.mean),
        ] {
            assert!(
                (a / b - 1.0).abs() < 0.02,
                "sheath {}: {a} with the default elements vs {b} with four times as many",
                d.sheath_deg
            );
        }
    }
}

#[test]
fn the_loop_does_not_depend_on_the_rate() {
    // quasi-static tendons and Dahl friction driven by displacement, no
    // viscous term: the loop is the same at a third of the paper's rate
    // and at six times it (CALIBRATION.md, "With the rate"; the differences
    // are where a 10 ms tick samples the loop: at 1 Hz a tick moves the
    // command by up to 1.6 deg, and the widths of nearby fits move by up to
    // 2 %)
    use kflex_control::OpenLoopScenario;
    use kflex_model::{Sine, Trajectory};
    let at = |frequency_hz: f64| {
        let mut plant = PlantConfig::default();
        plant.joint.gravity_m_per_s2 = [0.0; 3];
        run(OpenLoopGrid {
            plant,
            scenario: OpenLoopScenario {
                trajectory: Trajectory::Sine(Sine {
                    frequency_hz,
                    ..Sine::PAPER
                }),
                period_s: 1.0 / frequency_hz,
                ..OpenLoopScenario::default()
            },
            ..nominal()
        })
    };
    let paper = at(0.159);
    for f in [0.05, 1.0] {
        for (r, p) in at(f).iter().zip(&paper) {
            let (w, wp) = (r.max_hysteresis_deg.mean, p.max_hysteresis_deg.mean);
            assert!(
                (w / wp - 1.0).abs() < 0.03,
                "sheath {}: loop width {w} at {f} Hz vs {wp} at 0.159 Hz",
                r.sheath_deg
            );
        }
    }
}

#[test]
fn the_run_to_run_spread_is_within_a_factor_of_3_of_the_papers() {
    // Table IX's ± ("None"), standard deviations of its three repeats
    const RMSE_STD: [f64; 4] = [2.2, 1.9, 3.7, 1.2];
    const WIDTH_STD: [f64; 4] = [0.7, 0.7, 0.3, 1.5];
    let rows = run(OpenLoopGrid {
        repeats: 30,
        ..OpenLoopGrid::default()
    });
    for (i, row) in rows.iter().enumerate() {
        for (what, ours, paper) in [
            ("RMSE", row.rmse_deg.std, RMSE_STD[i]),
            ("loop width", row.max_hysteresis_deg.std, WIDTH_STD[i]),
        ] {
            assert!(
                ours >= paper / 3.0 && ours <= 3.0 * paper,
                "sheath {}: {what} std {ours:.2} against the paper's {paper}",
                row.sheath_deg
            );
        }
    }
}
