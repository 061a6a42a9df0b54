//! Fits the plant's free parameters to Table IX's uncompensated row.
//!
//! `cargo run --release -p kflex-control --example fit_calibration`
//!
//! Targets (paper, Table IX, "None"): RMSE 7.84 / 9.95 / 16.6 / 21.9 deg and
//! maximum hysteresis size 9.23 / 15.1 / 18.3 / 18.4 deg at sheath 0 / 90 /
//! 180 / 270 deg. The cost is the sum of squared relative errors of the eight
//! figures, each divided by its acceptance tolerance (±20 % RMSE, ±30 % width), on the nominal plant without noise or spread, one run each, with
//! the protocol of `kflex-cli run`. Free parameters, searched in log space
//! within plausible boxes (`BOX`) by a seeded random search, then by
//! Nelder–Mead from the three best and from the shipped defaults: friction coefficient μ, route wrap
//! Φ_route, Coulomb friction F_c, pretension T₀, contact stiffness k_φ,
//! tendon stiffness k, drive backlash and shaft coupling. The geometry
//! and masses keep their K-FLEX-scale defaults.
//! `fit_calibration [SAMPLES]` sets the random-search size (default 600). The script prints the fitted constants to paste into
//! `crates/kflex-model/src/calibration.rs` and the residual table for
//! `crates/kflex-model/CALIBRATION.md`.

use kflex_control::OpenLoopGrid;
use kflex_model::PlantConfig;

const SHEATHS: [f64; 4] = [0.0, 90.0, 180.0, 270.0];
const RMSE: [f64; 4] = [7.84, 9.95, 16.6, 21.9];
const WIDTH: [f64; 4] = [9.23, 15.1, 18.3, 18.4];
const NAMES: [&str; 8] = [
    "friction_coefficient",
    "route_wrap_deg",
    "coulomb_friction_n",
    "pretension_n",
    "contact_stiffness",
    "tendon_stiffness",
    "drive_backlash_mm",
    "sheath_coupling_mm_per_rad",
];
/// Search box (natural units) of each parameter: physically plausible for a K-FLEX-scale instrument.
const BOX: [(f64, f64); 8] = [
    (0.05, 1.0),  // friction coefficient
    (1.0, 360.0), // route wrap, deg
    (0.01, 10.0), // Coulomb friction, N
    (0.5, 30.0),  // pretension, N
    (1.0, 500.0), // contact stiffness, N·mm/rad
    (2.0, 200.0), // tendon stiffness, N/mm
    (0.001, 0.3), // drive backlash, mm
    (0.001, 1.0), // shaft coupling, mm/rad
];
/// Acceptance tolerances (relative): the cost is measured in units of them.
const RMSE_TOL: f64 = 0.20;
const WIDTH_TOL: f64 = 0.30;

fn config(x: &[f64]) -> PlantConfig {
    let mut c = PlantConfig::default();
    c.sheath.friction_coefficient = x[0].exp();
    c.sheath.route_wrap_deg = x[1].exp();
    c.sheath.coulomb_friction_n = x[2].exp();
    c.sheath.pretension_n = x[3].exp();
    c.joint.contact_stiffness_nmm_per_rad = x[4].exp();
    c.sheath.tendon_stiffness_n_per_mm = x[5].exp();
    c.sheath.drive_backlash_mm = x[6].exp();
    c.sheath.sheath_coupling_mm_per_rad = x[7].exp();
    c
}

fn evaluate(x: &[f64]) -> Option<Vec<(f64, f64)>> {
    let grid = OpenLoopGrid {
        plant: config(x),
        sheaths_deg: SHEATHS.to_vec(),
        repeats: 1,
        spread: 0.0,
        noise: None,
        ..OpenLoopGrid::default()
    };
    let rows = grid.run().ok()?;
    Some(
        rows.iter()
            .map(|r| (r.rmse_deg.mean, r.max_hysteresis_deg.mean))
            .collect(),
    )
}

fn cost(x: &[f64]) -> f64 {
    // the boxes are hard limits: a fit outside them is not a plausible instrument
    if x.iter()
        .zip(BOX)
        .any(|(v, (lo, hi))| *v < lo.ln() || *v > hi.ln())
    {
        return f64::INFINITY;
    }
    match evaluate(x) {
        Some(v) => v
            .iter()
            .enumerate()
            .map(|(i, (r, w))| {
                ((r - RMSE[i]) / (RMSE[i] * RMSE_TOL)).powi(2)
                    + ((w - WIDTH[i]) / (WIDTH[i] * WIDTH_TOL)).powi(2)
            })
            .sum(),
        None => f64::INFINITY,
    }
}

fn nelder_mead(f: impl Fn(&[f64]) -> f64, x0: &[f64], step: f64, iters: usize) -> (Vec<f64>, f64) {
    let n = x0.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = (0..=n)
        .map(|i| {
            let mut x = x0.to_vec();
            if i > 0 {
                x[i - 1] += step;
            }
            let fx = f(&x);
            (x, fx)
        })
        .collect();
    for _ in 0..iters {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let centroid: Vec<f64> = (0..n)
            .map(|j| simplex[..n].iter().map(|s| s.0[j]).sum::<f64>() / n as f64)
            .collect();
        let worst = simplex[n].clone();
        let along = |t: f64| -> Vec<f64> {
            (0..n)
                .map(|j| centroid[j] + t * (worst.0[j] - centroid[j]))
                .collect()
        };
        let xr = along(-1.0);
        let fr = f(&xr);
        if fr < simplex[0].1 {
            let xe = along(-2.0);
            let fe = f(&xe);
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (xr, fr);
        } else {
            let xc = along(0.5);
            let fc = f(&xc);
            if fc < worst.1 {
                simplex[n] = (xc, fc);
            } else {
                let best = simplex[0].0.clone();
                for s in simplex.iter_mut().skip(1) {
                    s.0 = (0..n).map(|j| best[j] + 0.5 * (s.0[j] - best[j])).collect();
                    s.1 = f(&s.0);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex.swap_remove(0)
}

/// A small deterministic generator (SplitMix64) so the search is reproducible without extra crates.
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

fn main() {
    let samples: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(600);
    let mut rng = 2020u64;
    let mut pool: Vec<(Vec<f64>, f64)> = (0..samples)
        .map(|_| {
            let x: Vec<f64> = BOX
                .iter()
                .map(|(lo, hi)| lo.ln() + uniform(&mut rng) * (hi.ln() - lo.ln()))
                .collect();
            let c = cost(&x);
            (x, c)
        })
        .collect();
    pool.sort_by(|a, b| a.1.total_cmp(&b.1));
    println!(
        "random search over {samples} samples: best cost {:.4}",
        pool[0].1
    );
    // Nelder–Mead from the three best samples and from the shipped defaults
    let d = PlantConfig::default();
    let shipped = vec![
        d.sheath.friction_coefficient.ln(),
        d.sheath.route_wrap_deg.ln(),
        d.sheath.coulomb_friction_n.ln(),
        d.sheath.pretension_n.ln(),
        d.joint.contact_stiffness_nmm_per_rad.ln(),
        d.sheath.tendon_stiffness_n_per_mm.ln(),
        d.sheath.drive_backlash_mm.ln(),
        d.sheath.sheath_coupling_mm_per_rad.ln(),
    ];
    let shipped_cost = cost(&shipped);
    println!("shipped defaults: cost {shipped_cost:.4}");
    let starts: Vec<(Vec<f64>, f64)> = pool
        .iter()
        .take(3)
        .cloned()
        .chain([(shipped, shipped_cost)])
        .collect();
    let mut best = (starts[0].0.clone(), starts[0].1);
    for (i, (x0, c0)) in starts.iter().enumerate() {
        let (mut x, mut c) = nelder_mead(cost, x0, 0.3, 300);
        for _ in 0..2 {
            let (x2, c2) = nelder_mead(cost, &x, 0.1, 200);
            if c2 < c {
                (x, c) = (x2, c2);
            }
        }
        println!("start {i}: {c0:.4} -> {c:.5}");
        if c < best.1 {
            best = (x, c);
        }
    }
    let (x, c) = best;
    println!("\nfitted (cost {c:.5}):");
    for (name, v) in NAMES.iter().zip(&x) {
        println!("  {name} = {:.4}", v.exp());
    }
    println!(
        "\n| sheath (deg) | RMSE paper | RMSE kflex | rel. | max. hysteresis paper | kflex | rel. |"
    );
    println!("|---|---|---|---|---|---|---|");
    if let Some(v) = evaluate(&x) {
        for (i, (r, w)) in v.iter().enumerate() {
            println!(
                "| {} | {:.2} | {:.2} | {:+.1}% | {:.2} | {:.2} | {:+.1}% |",
                SHEATHS[i],
                RMSE[i],
                r,
                100.0 * (r / RMSE[i] - 1.0),
                WIDTH[i],
                w,
                100.0 * (w / WIDTH[i] - 1.0)
            );
        }
    }
}
