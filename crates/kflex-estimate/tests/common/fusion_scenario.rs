//! Synthetic sensors on the kflex plant, for judging the fusion filters
//! (`tests/fusion.rs`, `examples/fusion_table.rs`).
//!
//! The truth is the plant's joint angle under the paper's input
//! (25 sin(2π 0.159 t) + 25 deg, after a 2 s ramp and 2 s hold, five periods
//! evaluated, 10 ms tick). The sensors stand in for the trained estimators
//! until they exist:
//! * KBJAE, trained on the straight sheath: the straight-sheath plant's angle
//!   for the same command, plus a smooth learning error (1.5 deg) and noise
//!   (0.7 deg), every tick. At a bent sheath it misses the extra hysteresis,
//!   as the paper's KBJAE does.
//! * IBJAE: the true angle plus noise (2.5 deg), at 33 Hz (every third tick).
//!   Under 40 % distal occlusion the tip is hidden: 60 % of frames read a
//!   silhouette bent about a third as much (0.3 θ + noise 4 deg), 20 % a
//!   wild neighbour anywhere in −20…70 deg, 20 % the right one. Each frame
//!   also carries IBJAE's own uncertainty as the retrieval distance would
//!   give it: 2.5 deg for a frame that matches, 12 deg for a hidden tip,
//!   25 deg for a wild match (used only where `Scenario::confidence`).

use kflex_model::{Command, Plant, PlantConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// One case of the comparison.
#[derive(Debug, Clone, Copy)]
pub struct Scenario {
    pub sheath_deg: f64,
    pub distal_occlusion: bool,
    /// Whether IBJAE reports its own uncertainty per frame.
    pub confidence: bool,
    pub seed: u64,
}

/// A simulated run: the truth and both sensors' readings, one per tick.
pub struct Run {
    pub dt_s: f64,
    /// First evaluated tick (after the ramp and hold).
    pub start: usize,
    pub truth: Vec<f64>,
    pub kbjae: Vec<Option<f64>>,
    pub ibjae: Vec<Option<f64>>,
    pub ibjae_sigma: Vec<Option<f64>>,
}

pub const DT_S: f64 = 0.01;
const FREQUENCY_HZ: f64 = 0.159;
const RAMP_S: f64 = 2.0;

pub fn simulate(s: Scenario) -> Run {
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: s.sheath_deg,
        noise: None,
        ..PlantConfig::default()
    })
    .expect("default plant");
    let mut straight = Plant::new(PlantConfig {
        sheath_deg: 0.0,
        noise: None,
        ..PlantConfig::default()
    })
    .expect("default plant");
    let mut rng = ChaCha8Rng::seed_from_u64(s.seed);
    let kb_noise = Normal::new(0.0, 0.7).unwrap();
    let ib_noise = Normal::new(0.0, 2.5).unwrap();
    let occluded_noise = Normal::new(0.0, 4.0).unwrap();
    let start = (2.0 * RAMP_S / DT_S).round() as usize;
    let ticks = start + (5.0 / FREQUENCY_HZ / DT_S).round() as usize;
    let mut run = Run {
        dt_s: DT_S,
        start,
        truth: Vec::with_capacity(ticks),
        kbjae: Vec::with_capacity(ticks),
        ibjae: Vec::with_capacity(ticks),
        ibjae_sigma: Vec::with_capacity(ticks),
    };
    for k in 0..ticks {
        let t = k as f64 * DT_S;
        let theta_d = if k < start {
            25.0 * (t / RAMP_S).min(1.0)
        } else {
            let te = t - 2.0 * RAMP_S;
            25.0 * (std::f64::consts::TAU * FREQUENCY_HZ * te).sin() + 25.0
        };
        let command = Command {
            theta_c_deg: theta_d,
            translation_mm: 10.0,
        };
        let truth = plant.step(command, DT_S).expect("plant step").theta_a_deg;
        let learned = straight
            .step(command, DT_S)
            .expect("plant step")
            .theta_a_deg;
        let kbjae = learned + 1.5 * (0.5 * t + 1.0).sin() + kb_noise.sample(&mut rng);
        let frame = (k % 3 == 0).then(|| {
            if !s.distal_occlusion {
                return (truth + ib_noise.sample(&mut rng), 2.5);
            }
            match rng.random_range(0..10) {
                0..=5 => (0.3 * truth + occluded_noise.sample(&mut rng), 12.0),
                6..=7 => (rng.random_range(-20.0..70.0), 25.0),
                _ => (truth + ib_noise.sample(&mut rng), 2.5),
            }
        });
        run.truth.push(truth);
        run.kbjae.push(Some(kbjae));
        run.ibjae.push(frame.map(|f| f.0));
        run.ibjae_sigma
            .push(frame.filter(|_| s.confidence).map(|f| f.1));
    }
    run
}

/// RMSE over the evaluated ticks of an estimate given per tick.
pub fn rmse(run: &Run, estimate: &[f64]) -> f64 {
    let n = run.truth.len() - run.start;
    let sum: f64 = run.truth[run.start..]
        .iter()
        .zip(&estimate[run.start..])
        .map(|(t, e)| (t - e) * (t - e))
        .sum();
    (sum / n as f64).sqrt()
}

/// A sensor on its own: its last reading held between readings.
pub fn held(readings: &[Option<f64>]) -> Vec<f64> {
    let mut last = 0.0;
    readings
        .iter()
        .map(|r| {
            if let Some(v) = r {
                last = *v;
            }
            last
        })
        .collect()
}

/// The filter's θ̂ at every tick of the run.
pub fn fused(run: &Run, filter: &mut dyn kflex_estimate::Fusion) -> Vec<f64> {
    (0..run.truth.len())
        .map(|k| {
            filter
                .step(
                    run.dt_s,
                    kflex_estimate::Measurements {
                        kbjae_deg: run.kbjae[k],
                        ibjae_deg: run.ibjae[k],
                        ibjae_sigma_deg: run.ibjae_sigma[k],
                        ibjae_occluded: false,
                    },
                )
                .expect("finite measurements")
                .theta_hat_deg
        })
        .collect()
}

/// RMSE of KBJAE alone, IBJAE alone, the paper's filter as run and as
/// written, and the adaptive filter, deg.
pub fn table_row(s: Scenario) -> [f64; 5] {
    use kflex_estimate::{AdaptiveKalman, FilterRate, KalmanParams, PaperKalman};
    let run = simulate(s);
    let mut as_run = PaperKalman::new(KalmanParams::default()).unwrap();
    let mut as_written = PaperKalman::new(KalmanParams {
        rate: FilterRate::AsWritten,
        ..KalmanParams::default()
    })
    .unwrap();
    let mut adaptive = AdaptiveKalman::new(Default::default()).unwrap();
    [
        rmse(&run, &held(&run.kbjae)),
        rmse(&run, &held(&run.ibjae)),
        rmse(&run, &fused(&run, &mut as_run)),
        rmse(&run, &fused(&run, &mut as_written)),
        rmse(&run, &fused(&run, &mut adaptive)),
    ]
}
