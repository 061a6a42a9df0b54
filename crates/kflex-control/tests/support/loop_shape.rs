//! Measures of the plant's loop shared by `tests/plant_fidelity.rs` (which
//! holds the plant to them) and `examples/fit_calibration.rs` (which fits
//! and prints them): the transition after a reversal, and the mirrored
//! input.
#![allow(dead_code)] // each user takes what it needs

use kflex_control::OpenLoopScenario;
use kflex_model::{Command, Plant, PlantConfig, Sine, Trajectory};

/// The paper's input reflected through θ = 0: −(25 sin t + 25) deg.
pub fn mirrored() -> OpenLoopScenario {
    OpenLoopScenario {
        trajectory: Trajectory::Sine(Sine {
            phase_rad: std::f64::consts::PI,
            offset_deg: -25.0,
            ..Sine::PAPER
        }),
        ..OpenLoopScenario::default()
    }
}

/// Slope dθ_a/dθ_d along the falling branch after the command's top
/// reversal, as (command travelled since the reversal, slope), on the third
/// period of the paper's input at 100 Hz through the plant `config`.
///
/// # Errors
/// The plant's.
pub fn falling_branch_slopes(config: PlantConfig) -> kflex_model::Result<Vec<(f64, f64)>> {
    let mut plant = Plant::new(config)?;
    let dt = 0.01;
    let sampler = Trajectory::paper().sampler()?;
    let ticks = (3.0 / 0.159 / dt) as usize;
    let (mut d, mut a) = (Vec::with_capacity(ticks), Vec::with_capacity(ticks));
    for k in 0..ticks {
        let s = sampler.sample(k as f64 * dt);
        let command = Command {
            theta_c_deg: s.theta_d_deg,
            translation_mm: 10.0,
        };
        let state = plant.step(command, dt)?;
        d.push(s.theta_d_deg);
        a.push(state.theta_a_deg);
    }
    let top = (ticks / 3..ticks)
        .max_by(|&i, &j| d[i].total_cmp(&d[j]))
        .unwrap_or(ticks / 3);
    let mut out = Vec::new();
    let mut i = top;
    while i + 1 < ticks && d[i + 1] < d[i] {
        out.push((d[top] - d[i + 1], (a[i] - a[i + 1]) / (d[i] - d[i + 1])));
        i += 1;
    }
    Ok(out)
}

/// The sliding value of the slope: its mean over the branch's last 15 deg.
pub fn sliding_slope(slopes: &[(f64, f64)]) -> f64 {
    let tail: Vec<f64> = slopes.iter().filter(|s| s.0 > 35.0).map(|s| s.1).collect();
    tail.iter().sum::<f64>() / tail.len() as f64
}

/// The command travelled before the slope first reaches `share` of
/// `sliding`; `None` if it never does.
pub fn reach(slopes: &[(f64, f64)], share: f64, sliding: f64) -> Option<f64> {
    slopes.iter().find(|s| s.1 >= share * sliding).map(|s| s.0)
}
