//! Fits the plant's free parameters to Table IX's uncompensated row, then
//! checks the fit by leaving each sheath angle out.
//!
//! `make fit` runs `cargo run --release -p kflex-control --example
//! fit_calibration`, the fit that gave the shipped values.
//!
//! Targets (paper, Table IX, "None"): RMSE 7.84 / 9.95 / 16.6 / 21.9 deg and
//! maximum hysteresis size (read as the loop width) 9.23 / 15.1 / 18.3 /
//! 18.4 deg at sheath 0 / 90 / 180 / 270 deg. The cost is the sum of squared
//! relative errors, each divided by its acceptance tolerance (±20 % RMSE and
//! ±30 % width at 0–180 deg, ±25 % and ±40 % at 270 deg), on the nominal
//! plant without noise or spread, one run each, with the protocol of
//! `kflex-cli run`. Penalties keep the fit to the goals first (see
//! `cost`): each figure within 95 % of its tolerance, the loop width beyond
//! 180 deg within 8 % of its largest, the loop width growing up to 180 deg
//! (at every 15 deg, each step at least 0.2 % wider than the one before;
//! `KFLEX_FIT_GROWTH_STEP=90` reads it at the paper's sheath angles alone,
//! as the fits before 2026-11-29's last did), and the slope after a
//! reversal rising over at least 3.3 deg of command. These goals use no paper figure, so the
//! leave-one-out fits keep them too: without the growth goal the straight
//! sheath's width was predicted 52 % too wide, with it 32 % (35 % with
//! μ's range to 0.6).
//!
//! Five free parameters (`free()`), each a physical quantity searched in log
//! space inside its plausible range (written beside it): by default the
//! shipped five (μ, path change, backlash, contact stiffness, pretension);
//! `KFLEX_FIT_FREE=mu,k,pretension,backlash,kphi` (short names
//! of `CANDIDATES`, at most five) fits another choice, the others keeping
//! their default values; `KFLEX_FIT_SET=kphi=5,path=0.01` sets candidates by
//! hand first (for a fit, `eval` and `loops` alike). Then a seeded random
//! search, then Nelder–Mead from the best samples and from the shipped
//! defaults. Every other parameter keeps its value from the instrument's
//! dimensions or the literature (CALIBRATION.md gives the sources).
//!
//! Usage: `fit_calibration [SAMPLES] [--no-loo]` (SAMPLES: random-search size,
//! default 120; 0 starts Nelder–Mead from the shipped values alone, after
//! `KFLEX_FIT_SET`); `fit_calibration eval` prints the tables for the shipped
//! defaults only, the shipped protocol's figures and the run-to-run spread
//! among them (`KFLEX_FIT_SPREAD_SEEDS=2020,5000,…`: the spread over 30
//! repeats from each base seed); `KFLEX_FIT_PROTOCOL=1` makes the full fit
//! keep the shipped protocol's figures within 90 % of their tolerances and
//! the spread at 0 and 180 deg too (`protocol_cost`; several times slower;
//! from the shipped values it walks back to a plant whose width dips, so the
//! shipped fit leaves it off and the tests check those goals instead); `fit_calibration spread` what each source of run-to-run
//! spread does alone (about a minute); `fit_calibration loops FILE` writes the nominal plant's
//! traces for `tools/plot_loops.py`. It prints the fitted constants for
//! `crates/kflex-model/src/calibration.rs`, the residual table, the three
//! readings of the maximum hysteresis, and the leave-one-sheath-out table
//! for `crates/kflex-model/CALIBRATION.md`.

#[path = "../tests/support/loop_shape.rs"]
mod loop_shape;

use kflex_control::{GridRow, MeanStd, OpenLoopGrid};
use kflex_model::PlantConfig;

const SHEATHS: [f64; 4] = [0.0, 90.0, 180.0, 270.0];
const RMSE: [f64; 4] = [7.84, 9.95, 16.6, 21.9];
const WIDTH: [f64; 4] = [9.23, 15.1, 18.3, 18.4];
/// Acceptance tolerances (relative) per sheath angle: the cost is measured in units of them.
const RMSE_TOL: [f64; 4] = [0.20, 0.20, 0.20, 0.25];
const WIDTH_TOL: [f64; 4] = [0.30, 0.30, 0.30, 0.40];
/// The paper's ± over its three repeats (Table IX, "None").
const RMSE_STD: [f64; 4] = [2.2, 1.9, 3.7, 1.2];
const WIDTH_STD: [f64; 4] = [0.7, 0.7, 0.3, 1.5];

/// A free parameter: its name, its plausible range, and where it lives in the config.
struct Free {
    /// Its name in `KFLEX_FIT_FREE`.
    short: &'static str,
    name: &'static str,
    range: (f64, f64),
    get: fn(&PlantConfig) -> f64,
    set: fn(&mut PlantConfig, f64),
}

const CANDIDATES: [Free; 9] = [
    Free {
        // steel tendon in a coil sheath: PTFE-lined 0.05–0.2, a lubricated
        // steel coil about 0.1–0.2, a dry steel coil as hard steel on hard
        // steel, kinetic 0.42 (mild steel 0.57): 0.05–0.6
        short: "mu",
        name: "sheath.friction_coefficient",
        range: (0.05, 0.6),
        get: |c| c.sheath.friction_coefficient,
        set: |c, v| c.sheath.friction_coefficient = v,
    },
    Free {
        // tendon (0.3 mm steel, 1.3 m: EA/L = 10.5 N/mm) in series with the coil
        // sheath's axial compliance: 2–15 N/mm
        short: "k",
        name: "sheath.tendon_stiffness_n_per_mm",
        range: (2.0, 15.0),
        get: |c| c.sheath.tendon_stiffness_n_per_mm,
        set: |c, v| c.sheath.tendon_stiffness_n_per_mm = v,
    },
    Free {
        // path shortening of a tendon that takes the inside of its lumen as the
        // sheath bends: the radial clearance, 0.001–0.3 mm per radian of bend
        // (stored negative: the path shortens)
        short: "path",
        name: "sheath.sheath_path_mm_per_rad (negated)",
        range: (0.001, 0.3),
        get: |c| (-c.sheath.sheath_path_mm_per_rad).max(0.001),
        set: |c, v| c.sheath.sheath_path_mm_per_rad = -v,
    },
    Free {
        // gear and capstan play of a small differential drive: 0.01–0.3 mm of stroke
        short: "backlash",
        name: "sheath.drive_backlash_mm",
        range: (0.01, 0.3),
        get: |c| c.sheath.drive_backlash_mm,
        set: |c, v| c.sheath.drive_backlash_mm = v,
    },
    Free {
        // bending stiffness of one rolling contact (springs, jacket): 5–300 N·mm/rad
        short: "kphi",
        name: "joint.contact_stiffness_nmm_per_rad",
        range: (5.0, 300.0),
        get: |c| c.joint.contact_stiffness_nmm_per_rad,
        set: |c, v| c.joint.contact_stiffness_nmm_per_rad = v,
    },
    Free {
        // tendons of 0.3 mm steel wire rope (breaking load about 60 N) are
        // pretensioned to 1–15 N in instruments of this size
        short: "pretension",
        name: "sheath.pretension_n",
        range: (1.0, 15.0),
        get: |c| c.sheath.pretension_n,
        set: |c, v| c.sheath.pretension_n = v,
    },
    Free {
        // pre-sliding displacement of steel on a polymer liner: 0.01–0.3 mm
        short: "presliding",
        name: "sheath.presliding_mm",
        range: (0.01, 0.3),
        get: |c| c.sheath.presliding_mm,
        set: |c, v| c.sheath.presliding_mm = v,
    },
    Free {
        // wrap the tendon sees with the sheath straight: the shaft's own
        // curvature in the endoscope's channel, the coil's waviness, the
        // drive's routing: 5–360 deg
        short: "wrap",
        name: "sheath.route_wrap_deg",
        range: (5.0, 360.0),
        get: |c| c.sheath.route_wrap_deg,
        set: |c, v| c.sheath.route_wrap_deg = v,
    },
    Free {
        // R − B of Eq. 1, the arm of the pretension's straightening moment: set
        // from the joint's geometry (1.8 mm), a candidate only to probe by hand
        // (KFLEX_FIT_SET=rminusb=0.3); 0.05–2.9 mm for R = 3
        short: "rminusb",
        name: "geometry.r_mm - geometry.b_mm",
        range: (0.05, 2.9),
        get: |c| c.geometry.r_mm - c.geometry.b_mm,
        set: |c, v| c.geometry.b_mm = c.geometry.r_mm - v,
    },
];

/// The plant every fit and table starts from: the shipped defaults, with the
/// values `KFLEX_FIT_SET=name=value,…` names (short names of `CANDIDATES`)
/// set first, to try a parameter by hand.
fn base() -> PlantConfig {
    let mut c = PlantConfig::default();
    let Ok(set) = std::env::var("KFLEX_FIT_SET") else {
        return c;
    };
    for item in set.split(',').filter(|s| !s.trim().is_empty()) {
        let parsed = item.split_once('=').and_then(|(n, v)| {
            let free = CANDIDATES.iter().find(|f| f.short == n.trim())?;
            Some((free, v.trim().parse::<f64>().ok()?))
        });
        let Some((free, v)) = parsed else {
            eprintln!(
                "KFLEX_FIT_SET: cannot read {item:?} (want name=value, a name of CANDIDATES)"
            );
            std::process::exit(2)
        };
        (free.set)(&mut c, v);
    }
    c
}

/// The parameters fitted: `KFLEX_FIT_FREE` (comma-separated short names of
/// `CANDIDATES`, at most five), or the shipped choice.
fn free() -> &'static [&'static Free] {
    static CHOSEN: std::sync::OnceLock<Vec<&'static Free>> = std::sync::OnceLock::new();
    CHOSEN.get_or_init(|| {
        let names = std::env::var("KFLEX_FIT_FREE")
            .unwrap_or_else(|_| "mu,path,backlash,kphi,pretension".to_string());
        let chosen: Vec<&'static Free> = names
            .split(',')
            .map(|n| {
                CANDIDATES
                    .iter()
                    .find(|c| c.short == n.trim())
                    .unwrap_or_else(|| {
                        let known: Vec<&str> = CANDIDATES.iter().map(|c| c.short).collect();
                        eprintln!(
                            "KFLEX_FIT_FREE: no parameter {n:?}; known: {}",
                            known.join(",")
                        );
                        std::process::exit(2)
                    })
            })
            .collect();
        if chosen.len() > 5 {
            eprintln!(
                "KFLEX_FIT_FREE: at most five free parameters, got {}",
                chosen.len()
            );
            std::process::exit(2);
        }
        chosen
    })
}

fn config(x: &[f64]) -> PlantConfig {
    let mut c = base();
    for (free, v) in free().iter().zip(x) {
        (free.set)(&mut c, v.exp());
    }
    c
}

fn evaluate(plant: PlantConfig, sheaths: &[f64]) -> Option<Vec<GridRow>> {
    let grid = OpenLoopGrid {
        plant,
        sheaths_deg: sheaths.to_vec(),
        repeats: 1,
        spread: 0.0,
        noise: None,
        ..OpenLoopGrid::default()
    };
    grid.run().ok()
}

/// Where the loop width's growth is read: at the paper's sheath angles
/// (0 ≤ 90 ≤ 180) with `KFLEX_FIT_GROWTH_STEP=90`, or by default at every
/// 15 deg up to 180 (the tests' grid), each step widening the loop by at
/// least [`GROWTH_MARGIN`].
fn growth_sheaths() -> &'static [f64] {
    static GRID: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    GRID.get_or_init(|| {
        // by default every 15 deg (the tests' grid)
        let step = std::env::var("KFLEX_FIT_GROWTH_STEP").map_or(Ok(15.0), |v| v.parse::<f64>());
        match step {
            // a whole fraction of 90 deg, so that the grid holds the paper's angles
            Ok(step) if step > 0.0 && step <= 90.0 && (90.0 / step).fract() == 0.0 => {
                let per_90 = (90.0 / step) as u32;
                (0..=2 * per_90)
                    .map(|k| 90.0 * f64::from(k) / f64::from(per_90))
                    .collect()
            }
            _ => {
                eprintln!("KFLEX_FIT_GROWTH_STEP: want 90 deg divided by a whole number");
                std::process::exit(2)
            }
        }
    })
}
/// The least relative growth per step of `growth_sheaths`, so that the
/// tests can ask for growth strictly (the shipped fit's least step is
/// 0.28 %, from 165 to 180 deg).
const GROWTH_MARGIN: f64 = 0.002;

/// Beyond 180 deg the width must stay within `SATURATION_FLOOR` of the
/// widest (goal: 10 %; the tests check every 15 deg).
const SATURATION_SHEATHS: [f64; 2] = [225.0, 270.0];
/// The shape goals, with a margin so that the 15 deg grid of the tests meets
/// them too: beyond 180 deg the width within 8 % of its largest (goal 10 %),
/// the transition over at least 3.3 deg of command (goal 3).
const SATURATION_FLOOR: f64 = 0.92;
const MIN_TRANSITION_DEG: f64 = 3.3;
/// Weight of a figure's excess over 95 % of its tolerance, and of a shape
/// goal's shortfall: large, so that the fit meets every goal it can before
/// it trades residuals.
const PENALTY: f64 = 100.0;

/// Every sheath angle a cost evaluation runs (the paper's four among them),
/// and the saturation's at 45 and 135 deg as before the growth grid was an
/// option, so that the shipped fit's evaluations are unchanged.
fn cost_sheaths() -> Vec<f64> {
    let mut all = growth_sheaths().to_vec();
    for s in [45.0, 135.0].iter().chain(&SATURATION_SHEATHS) {
        if !all.contains(s) {
            all.push(*s);
        }
    }
    all.sort_by(f64::total_cmp);
    all
}

/// Row `r`'s RMSE and loop width against the paper's at sheath `SHEATHS[i]`:
/// relative errors in units of their tolerances.
fn in_tolerances(r: &GridRow, i: usize) -> [f64; 2] {
    [
        (r.rmse_deg.mean - RMSE[i]) / (RMSE[i] * RMSE_TOL[i]),
        (r.max_hysteresis_deg.mean - WIDTH[i]) / (WIDTH[i] * WIDTH_TOL[i]),
    ]
}

/// Cost over the sheath angles `which` (indices into `SHEATHS`): the sum of
/// squared relative errors in units of their tolerances, plus penalties
/// where a figure leaves 95 % of its tolerance or the loop misses a shape
/// goal (which uses no paper figure, so the leave-one-out fits keep it).
fn cost(x: &[f64], which: &[usize]) -> f64 {
    // the ranges are hard limits: a fit outside them is not a plausible instrument
    if x.iter()
        .zip(free())
        .any(|(v, f)| *v < f.range.0.ln() || *v > f.range.1.ln())
    {
        return f64::INFINITY;
    }
    let plant = config(x);
    let sheaths = cost_sheaths();
    let Some(rows) = evaluate(plant, &sheaths) else {
        return f64::INFINITY;
    };
    let row = |sheath: f64| {
        rows.iter()
            .zip(&sheaths)
            .find(|(_, s)| **s == sheath)
            .map(|(r, _)| r)
    };
    let mut c = 0.0;
    for &i in which {
        let Some(r) = row(SHEATHS[i]) else {
            return f64::INFINITY;
        };
        for q in in_tolerances(r, i) {
            c += q * q + PENALTY * (q.abs() - 0.95).max(0.0).powi(2);
        }
    }
    let widths: Vec<f64> = rows.iter().map(|r| r.max_hysteresis_deg.mean).collect();
    let widest = widths.iter().copied().fold(0.0, f64::max);
    for (w, s) in widths.iter().zip(&sheaths) {
        if *s >= 180.0 {
            c += PENALTY * (100.0 * (SATURATION_FLOOR - w / widest).max(0.0)).powi(2);
        }
    }
    // the loop widens with the bend up to 180 deg, at each step of the grid
    for pair in growth_sheaths().windows(2) {
        let [Some(lo), Some(hi)] =
            [pair[0], pair[1]].map(|s| row(s).map(|r| r.max_hysteresis_deg.mean))
        else {
            return f64::INFINITY;
        };
        c += PENALTY * (100.0 * (1.0 + GROWTH_MARGIN - hi / lo).max(0.0)).powi(2);
    }
    for sheath in SHEATHS {
        let Some(t) = transition_deg(plant, sheath) else {
            return f64::INFINITY;
        };
        c += PENALTY * (MIN_TRANSITION_DEG - t).max(0.0).powi(2);
    }
    c
}

/// Command travelled (deg) while the slope dθ_a/dθ_d of the falling branch
/// after the top reversal rises from 10 % to 90 % of its sliding value (the
/// mean over the branch's last 15 deg), third period, as the loop-shape test
/// in `tests/plant_fidelity.rs` measures it. `None` if the plant fails.
fn transition_deg(plant: PlantConfig, sheath_deg: f64) -> Option<f64> {
    let slopes = loop_shape::falling_branch_slopes(PlantConfig {
        sheath_deg,
        ..plant
    })
    .ok()?;
    let sliding = loop_shape::sliding_slope(&slopes);
    let reach = |share| loop_shape::reach(&slopes, share, sliding);
    Some(reach(0.9)? - reach(0.1)?)
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

/// With `KFLEX_FIT_PROTOCOL=1`, the full fit also keeps the goals that
/// `kflex-cli run`'s protocol reads (three perturbed repeats with noise):
/// its eight figures within 90 % of their tolerances, and the run-to-run
/// spread over 30 repeats at [`SPREAD_SHEATHS`]: the RMSE's std at least
/// the paper's / 2.7, the width's at most 2.7 times the paper's (the
/// directions this plant misses; the goal is a factor of 3 either way).
fn protocol_cost(plant: PlantConfig, which: &[usize]) -> f64 {
    let shipped = OpenLoopGrid {
        plant,
        sheaths_deg: SHEATHS.to_vec(),
        ..OpenLoopGrid::default()
    };
    let spread = OpenLoopGrid {
        plant,
        sheaths_deg: SPREAD_SHEATHS.to_vec(),
        repeats: 30,
        ..OpenLoopGrid::default()
    };
    let (Ok(rows), Ok(spreads)) = (shipped.run(), spread.run()) else {
        return f64::INFINITY;
    };
    let mut c = 0.0;
    for &i in which {
        let Some(r) = rows.get(i) else {
            return f64::INFINITY;
        };
        for q in in_tolerances(r, i) {
            c += PENALTY * (100.0 * (q.abs() - 0.9).max(0.0)).powi(2);
        }
    }
    for (r, sheath) in spreads.iter().zip(SPREAD_SHEATHS) {
        let Some(i) = SHEATHS.iter().position(|&s| s == sheath) else {
            return f64::INFINITY;
        };
        let rmse_ratio = r.rmse_deg.std / RMSE_STD[i];
        let width_ratio = r.max_hysteresis_deg.std / WIDTH_STD[i];
        c += PENALTY * (100.0 * (1.0 / 2.7 - rmse_ratio).max(0.0)).powi(2);
        c += PENALTY * (10.0 * (width_ratio - 2.7).max(0.0)).powi(2);
    }
    c
}

/// Where `protocol_cost` reads the run-to-run spread: 180 deg, whose paper
/// ± is the hardest pair (RMSE ± 3.7 beside width ± 0.3), and 0 deg, where
/// the RMSE's spread (paper ± 2.2) lies nearest its goal's edge (0.32–0.42
/// of it over four seed sets, 2026-11-29).
const SPREAD_SHEATHS: [f64; 2] = [0.0, 180.0];

/// Random search then Nelder–Mead, on the sheath angles `which`.
fn fit(which: &[usize], samples: usize, verbose: bool) -> (Vec<f64>, f64) {
    let protocol = verbose && std::env::var("KFLEX_FIT_PROTOCOL").is_ok_and(|v| v == "1");
    let f = |x: &[f64]| {
        let c = cost(x, which);
        if protocol && c.is_finite() {
            c + protocol_cost(config(x), which)
        } else {
            c
        }
    };
    let mut rng = 2020u64;
    let mut pool: Vec<(Vec<f64>, f64)> = (0..samples)
        .map(|_| {
            let x: Vec<f64> = free()
                .iter()
                .map(|p| p.range.0.ln() + uniform(&mut rng) * (p.range.1.ln() - p.range.0.ln()))
                .collect();
            let c = f(&x);
            (x, c)
        })
        .collect();
    pool.sort_by(|a, b| a.1.total_cmp(&b.1));
    let d = base();
    let shipped: Vec<f64> = free().iter().map(|p| (p.get)(&d).ln()).collect();
    let shipped_cost = f(&shipped);
    if verbose {
        // SAMPLES 0: Nelder–Mead from the shipped values (and `KFLEX_FIT_SET`'s) alone
        if let Some((_, best)) = pool.first() {
            println!("random search over {samples} samples: best cost {best:.4}");
        }
        println!("shipped defaults: cost {shipped_cost:.4}");
    }
    let starts: Vec<(Vec<f64>, f64)> = pool
        .iter()
        .take(2)
        .cloned()
        .chain([(shipped, shipped_cost)])
        .collect();
    let mut best = (starts[0].0.clone(), f64::INFINITY);
    for (i, (x0, c0)) in starts.iter().enumerate() {
        let (mut x, mut c) = nelder_mead(f, x0, 0.3, 150);
        let (x2, c2) = nelder_mead(f, &x, 0.1, 100);
        if c2 < c {
            (x, c) = (x2, c2);
        }
        if verbose {
            println!("start {i}: {c0:.4} -> {c:.5}");
        }
        if c < best.1 {
            best = (x, c);
        }
    }
    best
}

fn rel(v: f64, target: f64) -> String {
    format!("{:+.1} %", 100.0 * (v / target - 1.0))
}

fn print_tables(plant: PlantConfig) {
    let Some(rows) = evaluate(plant, &SHEATHS) else {
        println!("the plant failed to run");
        return;
    };
    println!(
        "\n| sheath (deg) | RMSE paper | RMSE kflex | rel. | loop width paper | kflex | rel. |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (i, r) in rows.iter().enumerate() {
        println!(
            "| {} | {:.2} | {:.2} | {} | {:.2} | {:.2} | {} |",
            SHEATHS[i],
            RMSE[i],
            r.rmse_deg.mean,
            rel(r.rmse_deg.mean, RMSE[i]),
            WIDTH[i],
            r.max_hysteresis_deg.mean,
            rel(r.max_hysteresis_deg.mean, WIDTH[i]),
        );
    }
    let every15: Vec<f64> = (0..=18).map(|k| 15.0 * f64::from(k)).collect();
    if let Some(rows) = evaluate(plant, &every15) {
        let list = |f: fn(&GridRow) -> f64| {
            rows.iter()
                .map(|r| format!("{:.2}", f(r)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!("\nEvery 15 deg from 0 to 270 deg:");
        println!("RMSE {}", list(|r| r.rmse_deg.mean));
        println!("loop width {}", list(|r| r.max_hysteresis_deg.mean));
    }
    let transitions: Vec<String> = SHEATHS
        .iter()
        .map(|&s| transition_deg(plant, s).map_or("failed".into(), |t| format!("{t:.2}")))
        .collect();
    println!(
        "\nAfter the top reversal the slope rises from 10 % to 90 % over {} deg of command (goal ≥ 3)",
        transitions.join(" / ")
    );
    print_rate_mirror_spread(plant);
    println!("\nThree readings of the maximum hysteresis (paper 9.23 / 15.1 / 18.3 / 18.4):");
    println!("| sheath (deg) | loop width | error peak-to-peak | peak loss |");
    println!("|---|---|---|---|");
    for (i, r) in rows.iter().enumerate() {
        println!(
            "| {} | {:.2} ({}) | {:.2} ({}) | {:.2} ({}) |",
            SHEATHS[i],
            r.max_hysteresis_deg.mean,
            rel(r.max_hysteresis_deg.mean, WIDTH[i]),
            r.error_peak_to_peak_deg.mean,
            rel(r.error_peak_to_peak_deg.mean, WIDTH[i]),
            r.peak_loss_deg.mean,
            rel(r.peak_loss_deg.mean, WIDTH[i]),
        );
    }
}

/// The loop width at four frequencies, the mirrored command's figures (both
/// with gravity off), the shipped protocol's figures and the spread over 30
/// perturbed repeats beside the paper's ±, for CALIBRATION.md.
fn print_rate_mirror_spread(plant: PlantConfig) {
    use kflex_control::OpenLoopScenario;
    use kflex_model::{Sine, Trajectory};
    let mut level = plant;
    level.joint.gravity_m_per_s2 = [0.0; 3];
    let nominal = |plant: PlantConfig, scenario: OpenLoopScenario| {
        OpenLoopGrid {
            plant,
            scenario,
            sheaths_deg: SHEATHS.to_vec(),
            repeats: 1,
            spread: 0.0,
            noise: None,
            ..OpenLoopGrid::default()
        }
        .run()
        .ok()
    };
    println!("\nLoop width (deg) with the rate, gravity off:");
    println!("| sheath (deg) | 0.05 Hz | 0.159 Hz | 0.5 Hz | 1 Hz |");
    println!("|---|---|---|---|---|");
    let by_rate: Vec<Option<Vec<GridRow>>> = [0.05, 0.159, 0.5, 1.0]
        .iter()
        .map(|&f| {
            let scenario = OpenLoopScenario {
                trajectory: Trajectory::Sine(Sine {
                    frequency_hz: f,
                    ..Sine::PAPER
                }),
                period_s: 1.0 / f,
                ..OpenLoopScenario::default()
            };
            nominal(level, scenario)
        })
        .collect();
    for (i, sheath) in SHEATHS.iter().enumerate() {
        let cells: Vec<String> = by_rate
            .iter()
            .map(|rows| {
                rows.as_ref().map_or("failed".into(), |r| {
                    format!("{:.2}", r[i].max_hysteresis_deg.mean)
                })
            })
            .collect();
        println!("| {sheath} | {} |", cells.join(" | "));
    }
    let mirrored = loop_shape::mirrored();
    if let (Some(p), Some(m)) = (
        nominal(level, OpenLoopScenario::default()),
        nominal(level, mirrored),
    ) {
        println!("\nThe mirrored command −(25 sin t + 25), gravity off:");
        println!(
            "| sheath (deg) | RMSE positive | RMSE mirrored | width positive | width mirrored |"
        );
        println!("|---|---|---|---|---|");
        for (i, (p, m)) in p.iter().zip(&m).enumerate() {
            println!(
                "| {} | {:.3} | {:.3} | {:.3} | {:.3} |",
                SHEATHS[i],
                p.rmse_deg.mean,
                m.rmse_deg.mean,
                p.max_hysteresis_deg.mean,
                m.max_hysteresis_deg.mean
            );
        }
    }
    if let Ok(rows) = (OpenLoopGrid {
        plant,
        ..OpenLoopGrid::default()
    })
    .run()
    {
        println!(
            "\nThe shipped protocol (kflex-cli run: three repeats, 15 % spread, noise, seeds 2020–2022):"
        );
        println!("| sheath (deg) | RMSE | rel. | tol. | loop width | rel. | tol. |");
        println!("|---|---|---|---|---|---|---|");
        for (i, r) in rows.iter().enumerate() {
            println!(
                "| {} | {:.2} ± {:.2} | {} | ±{:.0} % | {:.2} ± {:.2} | {} | ±{:.0} % |",
                SHEATHS[i],
                r.rmse_deg.mean,
                r.rmse_deg.std,
                rel(r.rmse_deg.mean, RMSE[i]),
                100.0 * RMSE_TOL[i],
                r.max_hysteresis_deg.mean,
                r.max_hysteresis_deg.std,
                rel(r.max_hysteresis_deg.mean, WIDTH[i]),
                100.0 * WIDTH_TOL[i]
            );
        }
    }
    // other sets of 30 seeds: `KFLEX_FIT_SPREAD_SEEDS=2020,5000,9000,123456`
    let seeds: Vec<u64> = std::env::var("KFLEX_FIT_SPREAD_SEEDS")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect())
        .unwrap_or_else(|| vec![2020]);
    for seed in seeds {
        let spread = OpenLoopGrid {
            plant,
            sheaths_deg: SHEATHS.to_vec(),
            repeats: 30,
            seed,
            ..OpenLoopGrid::default()
        };
        let Ok(rows) = spread.run() else {
            println!("\nthe spread's runs failed (seed {seed})");
            continue;
        };
        println!(
            "\nStandard deviation over 30 repeats (seeds {seed}–{}), {} % spread, with noise (goal: within 3x the paper's ±):",
            seed + 29,
            100.0 * spread.spread
        );
        println!(
            "| sheath (deg) | RMSE std kflex | paper ± | ratio | width std kflex | paper ± | ratio |"
        );
        println!("|---|---|---|---|---|---|---|");
        for (i, r) in rows.iter().enumerate() {
            println!(
                "| {} | {:.2} | {} | {:.2} | {:.2} | {} | {:.2} |",
                SHEATHS[i],
                r.rmse_deg.std,
                RMSE_STD[i],
                r.rmse_deg.std / RMSE_STD[i],
                r.max_hysteresis_deg.std,
                WIDTH_STD[i],
                r.max_hysteresis_deg.std / WIDTH_STD[i]
            );
        }
    }
}

/// What each source of run-to-run spread does alone: the RMSE's and the
/// loop width's standard deviation over 30 repeats, no noise, every
/// parameter at a 15 % spread (the build's too), the homing as
/// `perturbed` draws it (uniform over `±HOMING_SHARE` of the play), the
/// friction seating uniform in `[−1, 1]`, the sheath's angle ±15 deg.
fn print_spread_by_mechanism(plant: PlantConfig) {
    use rand::{Rng, SeedableRng};
    use rand_distr::{Distribution, Normal};
    type Spread = fn(&mut PlantConfig, f64, &mut rand_chacha::ChaCha8Rng);
    let sources: [(&str, Spread); 13] = [
        ("homing in the play", |c, _, r| {
            let h = kflex_model::HOMING_SHARE;
            c.seating.backlash = r.random_range(-h..=h);
        }),
        ("friction seating", |c, _, r| {
            c.seating.friction_a = r.random_range(-1.0..=1.0);
            c.seating.friction_b = r.random_range(-1.0..=1.0);
        }),
        ("backlash", |c, f, _| c.sheath.drive_backlash_mm *= f),
        ("backlash engagement", |c, f, _| {
            c.sheath.backlash_engagement_mm *= f
        }),
        ("μ", |c, f, _| c.sheath.friction_coefficient *= f),
        ("route wrap", |c, f, _| c.sheath.route_wrap_deg *= f),
        ("pretension", |c, f, _| c.sheath.pretension_n *= f),
        ("pre-sliding", |c, f, _| c.sheath.presliding_mm *= f),
        ("tendon stiffness", |c, f, _| {
            c.sheath.tendon_stiffness_n_per_mm *= f
        }),
        ("distal stiffness", |c, f, _| {
            c.sheath.distal_stiffness_n_per_mm *= f
        }),
        ("path change", |c, f, _| {
            c.sheath.sheath_path_mm_per_rad *= f
        }),
        ("contact stiffness", |c, f, _| {
            c.joint.contact_stiffness_nmm_per_rad *= f;
        }),
        ("the sheath's angle (±15 deg)", |c, f, _| {
            c.sheath_deg = (c.sheath_deg + 100.0 * (f - 1.0)).max(0.0);
        }),
    ];
    let Ok(normal) = Normal::new(0.0, 0.15) else {
        return;
    };
    println!("Each source of spread alone, 30 repeats, no noise: RMSE std / width std (deg)");
    println!("| alone | 0 deg | 90 deg | 180 deg | 270 deg |");
    println!("|---|---|---|---|---|");
    for (name, spread) in sources {
        let mut line = format!("| {name} |");
        for sheath_deg in SHEATHS {
            let (mut rmse, mut width) = (Vec::new(), Vec::new());
            for repeat in 0..30u64 {
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + repeat);
                let f = (1.0_f64 + normal.sample(&mut rng)).clamp(0.5, 1.5);
                let mut c = PlantConfig {
                    sheath_deg,
                    ..plant
                };
                spread(&mut c, f, &mut rng);
                let Some(rows) = evaluate(c, &[c.sheath_deg]) else {
                    println!("{name}: a run failed");
                    return;
                };
                rmse.push(rows[0].rmse_deg.mean);
                width.push(rows[0].max_hysteresis_deg.mean);
            }
            let (Ok(r), Ok(w)) = (MeanStd::of(&rmse), MeanStd::of(&width)) else {
                return;
            };
            line.push_str(&format!(" {:.2} / {:.2} |", r.std, w.std));
        }
        println!("{line}");
    }
}

/// The nominal plant's traces (protocol of `kflex-cli run`, true angle) as CSV:
/// `sheath_deg,time_s,theta_d_deg,theta_a_deg`, for `tools/plot_loops.py`.
fn write_loops(path: &str) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = String::from("sheath_deg,time_s,theta_d_deg,theta_a_deg\n");
    for sheath_deg in SHEATHS {
        let config = PlantConfig {
            sheath_deg,
            ..base()
        };
        let mut plant = kflex_model::Plant::new(config).map_err(std::io::Error::other)?;
        let trace = kflex_control::OpenLoopScenario::default()
            .run(&mut plant)
            .map_err(std::io::Error::other)?;
        for i in 0..trace.time_s.len() {
            out.push_str(&format!(
                "{sheath_deg},{:.4},{:.6},{:.6}\n",
                trace.time_s[i], trace.theta_d_deg[i], trace.theta_a_deg[i]
            ));
        }
    }
    let tmp = format!("{path}.tmp");
    let mut f = std::fs::File::create(&tmp)?;
    f.write_all(out.as_bytes())?;
    f.sync_all()?;
    std::fs::rename(&tmp, path)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("eval") {
        print_tables(base());
        return;
    }
    if args.first().map(String::as_str) == Some("spread") {
        print_spread_by_mechanism(base());
        return;
    }
    if args.first().map(String::as_str) == Some("loops") {
        let path = args.get(1).map_or("loops.csv", String::as_str);
        if let Err(e) = write_loops(path) {
            eprintln!("writing {path}: {e}");
            std::process::exit(1);
        }
        return;
    }
    let samples: usize = args.iter().find_map(|a| a.parse().ok()).unwrap_or(120);
    let loo = !args.iter().any(|a| a == "--no-loo");
    let all = [0, 1, 2, 3];
    let (x, c) = fit(&all, samples, true);
    println!("\nfitted (cost {c:.5}):");
    for (p, v) in free().iter().zip(&x) {
        let (lo, hi) = p.range;
        println!("  {} = {:.4}   (range {lo} – {hi})", p.name, v.exp());
    }
    print_tables(config(&x));
    if !loo {
        return;
    }
    println!(
        "\nLeave one sheath out: fit on three, predict the fourth (goal: within 1.5x the tolerances)"
    );
    println!(
        "| left out (deg) | RMSE paper | predicted | rel. | in 1.5x tol. | loop width paper | predicted | rel. | in 1.5x tol. |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for out in 0..4 {
        let which: Vec<usize> = all.iter().copied().filter(|&i| i != out).collect();
        let (x, _) = fit(&which, samples / 2, false);
        let Some(rows) = evaluate(config(&x), &[SHEATHS[out]]) else {
            println!("| {} | failed |", SHEATHS[out]);
            continue;
        };
        let r = &rows[0];
        let (er, ew) = (
            r.rmse_deg.mean / RMSE[out] - 1.0,
            r.max_hysteresis_deg.mean / WIDTH[out] - 1.0,
        );
        let ok = |e: f64, tol: f64| if e.abs() <= 1.5 * tol { "yes" } else { "no" };
        println!(
            "| {} | {:.2} | {:.2} | {:+.1} % | {} | {:.2} | {:.2} | {:+.1} % | {} |",
            SHEATHS[out],
            RMSE[out],
            r.rmse_deg.mean,
            100.0 * er,
            ok(er, RMSE_TOL[out]),
            WIDTH[out],
            r.max_hysteresis_deg.mean,
            100.0 * ew,
            ok(ew, WIDTH_TOL[out]),
        );
    }
}
