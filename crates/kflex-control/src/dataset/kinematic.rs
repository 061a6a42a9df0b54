//! KBJAE's kinematic data set D^k (the paper's Section II-C-2, Table III).

use kflex_model::{AuroraNoise, Bounds, Command, Plant, PlantConfig, Trajectory};
use serde::{Deserialize, Serialize};

use super::{DatasetCard, parallel};
use crate::error::{ControlError, Result};

/// Version of [`KinematicDatasetConfig::generate`]'s output for a given
/// configuration (see [`DatasetCard::generator_version`]).
///
/// 2: the plants' spread by mechanism (the set-up's parameters more than
/// the build's) and one homing of the drive for the whole set.
pub const KINEMATIC_GENERATOR_VERSION: u32 = 2;

/// One periodic signal of D^k.
///
/// **Amplitude.** The paper's amplitudes (trained on 35–85, tested on
/// 30–80) are read as the signal's peak: each signal is a raised cosine
/// `θ_d(t) = (A/2)(1 − cos 2πft)` that sweeps `[0, A]` deg from the
/// straight joint, as its test input `25 sin(t) + 25` sweeps `[0, 50]`
/// (the [`Trajectory::PeriodicSet`] shape). So a signal of amplitude 50 at
/// the default frequency covers the test input's angles and rates exactly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicSetSpec {
    /// Peak of the signal `A`, deg: θ_d sweeps `[0, A]`.
    pub amplitude_deg: f64,
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Whether the set is for training (else held out for testing).
    pub train: bool,
}

/// How to make D^k: periodic signals through perturbed plants, straight
/// sheath, with the tracker's noise on the measured angle.
///
/// **Protocol.** Set `i` (in `sets` order) runs its own plant
/// ([`KinematicDatasetConfig::set_plant`]): the nominal `plant` drawn with
/// [`PlantConfig::perturbed`]`(seed + i, spread)` (its physical parameters
/// and the tendons' seating; friction and tension drift between signals),
/// but homed once for the whole set (set 0's homing: the drive is homed
/// when the robot is set up, not between signals), its measurement noise
/// `noise` with seed `seed + i`. A homing of its own per signal would put
/// an offset into each signal's θ̃ that no model of (θ, θ') can learn. The
/// plant starts at rest, straight, as the signal does (θ_d(0) = 0); it
/// runs `warmup_cycles` cycles unrecorded (the first loading from rest is
/// not a steady hysteresis loop), then records
/// `samples_per_set` ticks of `dt_s`: θ_d and its exact rate θ_d' at the end
/// of each tick, and θ_a, true and as measured. KBJAE learns
/// `θ̃ = θ_a(measured) − θ_d` (the paper's ground truth is the Aurora's).
///
/// **Defaults.** The paper's 12 signals: peaks 35, 45, …, 85 deg for
/// training and 30, 40, …, 80 deg held out, all at 0.159 Hz (its test
/// input's frequency, so rates scale with the amplitude: peak rates 15–43
/// deg/s); 50,000 samples each at 100 Hz (500 s, about 80 cycles); one
/// warm-up cycle; the straight sheath; a 15 % parameter spread (as
/// [`crate::OpenLoopGrid`]); the default [`AuroraNoise`] (0.2 deg);
/// translation 10 mm; seed 2020.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KinematicDatasetConfig {
    /// The signals, one set each.
    pub sets: Vec<KinematicSetSpec>,
    /// Recorded samples per set.
    pub samples_per_set: usize,
    /// Control tick, s.
    pub dt_s: f64,
    /// Cycles run before recording starts.
    pub warmup_cycles: u32,
    /// Nominal plant (its `noise` and `seed` are set per set; its
    /// `sheath_deg` is used as given: 0, straight, by default).
    pub plant: PlantConfig,
    /// Relative parameter spread between the sets' plants, `[0, 0.5]`.
    pub spread: f64,
    /// Measurement noise on θ_a; `None` measures the true angle.
    pub noise: Option<AuroraNoise>,
    /// Constant translation command, mm.
    pub translation_mm: f64,
    /// Base seed: set `i` uses `seed + i`.
    pub seed: u64,
}

impl Default for KinematicDatasetConfig {
    fn default() -> Self {
        let spec = |amplitude_deg, train| KinematicSetSpec {
            amplitude_deg,
            frequency_hz: 0.159,
            train,
        };
        let train = (0..6).map(|k| spec(35.0 + 10.0 * f64::from(k), true));
        let test = (0..6).map(|k| spec(30.0 + 10.0 * f64::from(k), false));
        Self {
            sets: train.chain(test).collect(),
            samples_per_set: 50_000,
            dt_s: 0.01,
            warmup_cycles: 1,
            plant: PlantConfig::default(),
            spread: 0.15,
            noise: Some(AuroraNoise::default()),
            translation_mm: 10.0,
            seed: 2020,
        }
    }
}

/// One signal's recording.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KinematicSet {
    /// The signal.
    pub spec: KinematicSetSpec,
    /// Seed of its plant's spread and noise.
    pub seed: u64,
    /// θ_d, deg.
    pub theta_d_deg: Vec<f64>,
    /// θ_d', deg/s (exact, from the signal).
    pub theta_d_rate_deg_per_s: Vec<f64>,
    /// True θ_a, deg.
    pub theta_a_deg: Vec<f64>,
    /// θ_a as the tracker measures it, deg.
    pub theta_a_measured_deg: Vec<f64>,
}

/// D^k: one recording per signal, and its card.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicDataset {
    /// The recordings, in the configuration's order.
    pub sets: Vec<KinematicSet>,
    /// What was made and how.
    pub card: DatasetCard<KinematicDatasetConfig>,
}

/// The most plant ticks a set runs, warm-up included (some three minutes
/// of one core at 3.3 µs a tick).
const MAX_TICKS_PER_SET: f64 = 5e7;

impl KinematicDatasetConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ControlError::OutOfRange`] naming the first setting out of its
    /// range: `sets.len()` outside `[1, 1000]`, a set's `amplitude_deg`
    /// outside `[0, 170]` or `frequency_hz` outside `(0, 100]`,
    /// `samples_per_set` outside `[1, 1e7]` or more than 5e7 samples in all,
    /// `dt_s` outside `(0, 10]`, more than 5e7 plant ticks in a set (its
    /// warm-up included),
    /// `warmup_cycles` above 1000, `spread` outside `[0, 0.5]`;
    /// [`ControlError::SeedOverflow`] for a `seed` whose sets (set `i` on
    /// `seed + i`) would pass the largest seed;
    /// [`ControlError::Model`] for the nominal plant's parameters.
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(1.0, 1000.0).check("sets.len()", self.sets.len() as f64)?;
        for s in &self.sets {
            Bounds::closed(0.0, 170.0).check("amplitude_deg", s.amplitude_deg)?;
            Bounds::open_closed(0.0, 100.0).check("frequency_hz", s.frequency_hz)?;
        }
        Bounds::closed(1.0, 1e7).check("samples_per_set", self.samples_per_set as f64)?;
        // each sample is three float64 values: 5e7 of them take 1.2 GB
        Bounds::closed(1.0, 5e7).check(
            "sets.len() * samples_per_set",
            self.sets.len() as f64 * self.samples_per_set as f64,
        )?;
        Bounds::open_closed(0.0, 10.0).check("dt_s", self.dt_s)?;
        Bounds::closed(0.0, 1000.0).check("warmup_cycles", f64::from(self.warmup_cycles))?;
        // the plant's ticks a set takes, warm-up included: a tiny `dt_s`
        // would otherwise run for ever (or overflow the count)
        for s in &self.sets {
            let warmup = f64::from(self.warmup_cycles) / s.frequency_hz / self.dt_s;
            Bounds::closed(1.0, MAX_TICKS_PER_SET).check(
                "ticks a set (warmup_cycles / frequency_hz / dt_s + samples_per_set)",
                warmup.round() + self.samples_per_set as f64,
            )?;
        }
        Bounds::closed(0.0, 0.5).check("spread", self.spread)?;
        // set i is made on seed + i: the last must not wrap to 0
        crate::experiment::check_seed(
            self.seed,
            u32::try_from(self.sets.len()).unwrap_or(u32::MAX),
        )?;
        self.plant.perturbed(self.seed, self.spread)?;
        Ok(())
    }

    /// Makes D^k, one set per worker thread at a time (`threads` 0: every
    /// core). Deterministic in the configuration, whatever `threads`.
    ///
    /// # Examples
    /// Two short sets:
    /// ```
    /// use kflex_control::{KinematicDatasetConfig, KinematicSetSpec};
    /// let spec = |amplitude_deg, train| KinematicSetSpec { amplitude_deg, frequency_hz: 0.5, train };
    /// let config = KinematicDatasetConfig {
    ///     sets: vec![spec(35.0, true), spec(30.0, false)],
    ///     samples_per_set: 500,
    ///     ..KinematicDatasetConfig::default()
    /// };
    /// let data = config.generate(0)?;
    /// assert_eq!(data.sets.len(), 2);
    /// let set = &data.sets[0];
    /// assert_eq!(set.theta_d_deg.len(), 500);
    /// assert!(set.theta_d_deg.iter().all(|&t| (0.0..=35.0).contains(&t)));
    /// assert_eq!(data.card.sizes["theta_d_deg"], [2, 500]);
    /// # Ok::<(), kflex_control::ControlError>(())
    /// ```
    ///
    /// # Errors
    /// As [`KinematicDatasetConfig::validate`], before any plant moves;
    /// [`ControlError::Model`] with a plant's error ([`Plant::new`],
    /// [`Plant::step`], e.g. a peak outside the workspace).
    pub fn generate(&self, threads: usize) -> Result<KinematicDataset> {
        self.validate()?;
        let sets = parallel(self.sets.len(), threads, || Ok(()), |i, _| self.record(i))?;
        let mut card = DatasetCard::new(
            "kinematic",
            "kflex_control::KinematicDatasetConfig::generate",
            KINEMATIC_GENERATOR_VERSION,
            self.seed,
            self.clone(),
        );
        let shape = vec![sets.len(), self.samples_per_set];
        for name in [
            "theta_d_deg",
            "theta_d_rate_deg_per_s",
            "theta_a_deg",
            "theta_a_measured_deg",
        ] {
            card.sizes.insert(name.to_owned(), shape.clone());
        }
        for name in ["amplitude_deg", "frequency_hz", "train", "seed"] {
            card.sizes.insert(name.to_owned(), vec![sets.len()]);
        }
        let all =
            |f: fn(&KinematicSet) -> &Vec<f64>| sets.iter().flat_map(move |s| f(s).iter().copied());
        card.range("theta_d_deg", all(|s| &s.theta_d_deg));
        card.range("theta_d_rate_deg_per_s", all(|s| &s.theta_d_rate_deg_per_s));
        card.range("theta_a_deg", all(|s| &s.theta_a_deg));
        card.range("theta_a_measured_deg", all(|s| &s.theta_a_measured_deg));
        let error = sets.iter().flat_map(|s| {
            s.theta_a_measured_deg
                .iter()
                .zip(&s.theta_d_deg)
                .map(|(a, d)| a - d)
        });
        card.range("theta_error_deg", error);
        let train = self.sets.iter().filter(|s| s.train).count();
        card.stats.insert("train_sets".to_owned(), train as f64);
        card.stats
            .insert("test_sets".to_owned(), (self.sets.len() - train) as f64);
        Ok(KinematicDataset { sets, card })
    }

    /// The plant set `i` records on: `plant` drawn with
    /// [`PlantConfig::perturbed`]`(seed + i, spread)`, homed as set 0's (the
    /// drive is homed once, when the robot is set up for the session), with
    /// the measurement noise `noise` seeded `seed + i`.
    ///
    /// # Errors
    /// As [`PlantConfig::perturbed`].
    pub fn set_plant(&self, i: usize) -> Result<PlantConfig> {
        let seed = self.seed.wrapping_add(i as u64);
        let mut config = self.plant.perturbed(seed, self.spread)?;
        config.seating.backlash = self
            .plant
            .perturbed(self.seed, self.spread)?
            .seating
            .backlash;
        config.noise = self.noise;
        config.seed = seed;
        Ok(config)
    }

    /// Records set `i`.
    fn record(&self, i: usize) -> Result<KinematicSet> {
        let spec = self
            .sets
            .get(i)
            .copied()
            .ok_or(ControlError::NotEnoughData {
                metric: "kinematic data set",
                needed: "a signal for each set",
                got: self.sets.len(),
            })?;
        let seed = self.seed.wrapping_add(i as u64);
        let mut plant = Plant::new(self.set_plant(i)?)?;
        let period_s = 1.0 / spec.frequency_hz;
        let warmup = (f64::from(self.warmup_cycles) * period_s / self.dt_s).round() as usize;
        let ticks = warmup + self.samples_per_set;
        let cycles = (ticks as f64 * self.dt_s / period_s).ceil() + 1.0;
        let sampler = Trajectory::PeriodicSet {
            legs: vec![(spec.amplitude_deg, spec.frequency_hz)],
            cycles_per_leg: cycles.min(1e6) as u32,
        }
        .sampler()?;
        let n = self.samples_per_set;
        let mut set = KinematicSet {
            spec,
            seed,
            theta_d_deg: Vec::with_capacity(n),
            theta_d_rate_deg_per_s: Vec::with_capacity(n),
            theta_a_deg: Vec::with_capacity(n),
            theta_a_measured_deg: Vec::with_capacity(n),
        };
        for k in 0..ticks {
            // sampled at the end of the tick, when the plant has answered it
            let s = sampler.sample((k + 1) as f64 * self.dt_s);
            let state = plant.step(
                Command {
                    theta_c_deg: s.theta_d_deg,
                    translation_mm: self.translation_mm,
                },
                self.dt_s,
            )?;
            if k >= warmup {
                set.theta_d_deg.push(s.theta_d_deg);
                set.theta_d_rate_deg_per_s.push(s.theta_d_rate_deg_per_s);
                set.theta_a_deg.push(state.theta_a_deg);
                set.theta_a_measured_deg.push(state.theta_a_measured_deg);
            }
        }
        Ok(set)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> KinematicDatasetConfig {
        KinematicDatasetConfig {
            samples_per_set: 300,
            sets: KinematicDatasetConfig::default().sets[..3].to_vec(),
            ..KinematicDatasetConfig::default()
        }
    }

    #[test]
    fn the_default_is_the_papers_twelve_signals() {
        let c = KinematicDatasetConfig::default();
        assert_eq!(c.sets.len(), 12);
        let peaks = |train| -> Vec<f64> {
            c.sets
                .iter()
                .filter(|s| s.train == train)
                .map(|s| s.amplitude_deg)
                .collect()
        };
        assert_eq!(peaks(true), [35.0, 45.0, 55.0, 65.0, 75.0, 85.0]);
        assert_eq!(peaks(false), [30.0, 40.0, 50.0, 60.0, 70.0, 80.0]);
        assert_eq!(c.samples_per_set, 50_000);
        assert_eq!(c.plant.sheath_deg, 0.0);
    }

    #[test]
    fn same_seed_same_data_whatever_the_threads_and_plants_differ_per_set() {
        let a = small().generate(1).unwrap();
        let b = small().generate(2).unwrap();
        assert_eq!(a.sets, b.sets);
        let c = KinematicDatasetConfig { seed: 1, ..small() }
            .generate(1)
            .unwrap();
        assert_ne!(a.sets[0].theta_a_deg, c.sets[0].theta_a_deg);
        assert_eq!(a.sets[0].seed, 2020);
        assert_eq!(a.sets[2].seed, 2022);
    }

    #[test]
    fn the_sets_drift_but_share_one_homing() {
        let c = small();
        let plants: Vec<PlantConfig> = (0..3).map(|i| c.set_plant(i).unwrap()).collect();
        let homing = plants[0].seating.backlash;
        assert!(homing != 0.0);
        for p in &plants[1..] {
            assert_eq!(p.seating.backlash, homing);
            assert_ne!(
                p.sheath.friction_coefficient,
                plants[0].sheath.friction_coefficient
            );
        }
        // each set's own draw would have homed it elsewhere
        assert_ne!(
            c.plant
                .perturbed(c.seed + 1, c.spread)
                .unwrap()
                .seating
                .backlash,
            homing
        );
    }

    #[test]
    fn the_joint_follows_the_signal_with_hysteresis_and_noise() {
        let data = small().generate(0).unwrap();
        let set = &data.sets[0];
        let peak = set.theta_d_deg.iter().copied().fold(0.0, f64::max);
        assert!(peak > 30.0 && peak <= 35.0 + 1e-9, "{peak}");
        let err: Vec<f64> = set
            .theta_a_deg
            .iter()
            .zip(&set.theta_d_deg)
            .map(|(a, d)| a - d)
            .collect();
        assert!(err.iter().any(|e| e.abs() > 1.0), "no hysteresis error");
        assert!(
            set.theta_a_deg
                .iter()
                .zip(&set.theta_a_measured_deg)
                .any(|(a, m)| a != m),
            "no measurement noise"
        );
        assert!(data.card.ranges["theta_error_deg"][0] < 0.0);
    }

    #[test]
    fn bad_settings_are_refused_before_any_plant_moves() {
        let bad = KinematicDatasetConfig {
            samples_per_set: 0,
            ..small()
        };
        assert_eq!(
            bad.generate(1).unwrap_err().range().unwrap().name,
            "samples_per_set"
        );
        let bad = KinematicDatasetConfig {
            sets: vec![],
            ..small()
        };
        assert_eq!(
            bad.validate().unwrap_err().range().unwrap().name,
            "sets.len()"
        );
        // a tick so short that the warm-up alone would take 10²⁰ ticks: it
        // once overflowed the count and made sets of no samples
        let bad = KinematicDatasetConfig {
            dt_s: 1e-20,
            ..small()
        };
        assert!(
            bad.generate(1)
                .unwrap_err()
                .range()
                .unwrap()
                .name
                .starts_with("ticks a set")
        );
        // set i runs on seed + i: three sets from the largest seed would wrap
        let bad = KinematicDatasetConfig {
            seed: u64::MAX - 1,
            ..small()
        };
        assert!(matches!(
            bad.validate(),
            Err(ControlError::SeedOverflow { repeats: 3, .. })
        ));
        // a peak the joint cannot reach
        let mut bad = small();
        bad.sets[0].amplitude_deg = 169.0;
        assert!(bad.generate(1).unwrap_err().range().is_some());
    }
}
