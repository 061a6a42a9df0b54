//! Open-loop experiments: the paper's test input through the uncompensated
//! plant, at several sheath configurations, repeated with recorded seeds.

use kflex_model::{
    AuroraNoise, Bounds, Command, JointModelKind, Plant, PlantConfig, Trajectory, TrajectorySampler,
};
use serde::{Deserialize, Serialize};

use crate::error::{ControlError, Result};
use crate::metrics::{self, MeanStd};

/// The most repeats a grid runs (the open-loop grid's and the scenario grid's).
pub const MAX_REPEATS: u32 = 1000;

/// One open-loop run's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OpenLoopScenario {
    /// The command θ_d(t).
    pub trajectory: Trajectory,
    /// Evaluated duration in periods of the trajectory (for the paper's sine: 5).
    pub periods: f64,
    /// Period of the trajectory, s, used with `periods` (the paper's: 1/0.159).
    pub period_s: f64,
    /// Control tick, s.
    pub dt_s: f64,
    /// Ramp from rest to θ_d(0), s (then held as long again before evaluation).
    pub pre_roll_s: f64,
    /// Constant translation command during the run, mm.
    pub translation_mm: f64,
}

impl Default for OpenLoopScenario {
    fn default() -> Self {
        Self {
            trajectory: Trajectory::paper(),
            periods: 5.0,
            period_s: 1.0 / 0.159,
            dt_s: 0.01,
            pre_roll_s: 2.0,
            translation_mm: 10.0,
        }
    }
}

/// A recorded run: one row per evaluated tick.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Trace {
    /// Time since the start of evaluation, s.
    pub time_s: Vec<f64>,
    /// θ_d, deg.
    pub theta_d_deg: Vec<f64>,
    /// dθ_d/dt, deg/s.
    pub theta_d_rate_deg_per_s: Vec<f64>,
    /// True θ_a, deg.
    pub theta_a_deg: Vec<f64>,
    /// Measured θ_a, deg.
    pub theta_a_measured_deg: Vec<f64>,
}

/// Metrics of one run, deg.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RunMetrics {
    /// RMSE of measured θ_a against θ_d.
    pub rmse_deg: f64,
    /// Loop width ("maximum hysteresis size", see [`loop_width`](crate::loop_width)).
    pub max_hysteresis_deg: f64,
    /// max e − min e.
    pub error_peak_to_peak_deg: f64,
    /// max θ_d − max θ_a.
    pub peak_loss_deg: f64,
}

impl Trace {
    /// Metrics of this trace, on the measured angle.
    ///
    /// # Errors
    /// As [`rmse`](crate::rmse) and [`loop_width`](crate::loop_width):
    /// [`ControlError::NotEnoughData`] for an empty trace, series of unequal
    /// lengths, or a trace without rising and falling samples at a common
    /// command angle; [`ControlError::NonFiniteSample`] for a NaN or infinite
    /// sample (indexed into `theta_d_deg` followed by the other series).
    pub fn metrics(&self) -> Result<RunMetrics> {
        Ok(RunMetrics {
            rmse_deg: metrics::rmse(&self.theta_d_deg, &self.theta_a_measured_deg)?,
            max_hysteresis_deg: metrics::loop_width(
                &self.theta_d_deg,
                &self.theta_d_rate_deg_per_s,
                &self.theta_a_measured_deg,
            )?,
            error_peak_to_peak_deg: metrics::error_peak_to_peak(
                &self.theta_d_deg,
                &self.theta_a_measured_deg,
            )?,
            peak_loss_deg: metrics::peak_loss(&self.theta_d_deg, &self.theta_a_measured_deg)?,
        })
    }
}

impl OpenLoopScenario {
    /// Checks the settings and prepares the trajectory (before anything moves).
    pub(crate) fn validate(&self) -> Result<TrajectorySampler> {
        Bounds::open_closed(0.0, 1e4).check("periods", self.periods)?;
        Bounds::open_closed(0.0, 1e5).check("period_s", self.period_s)?;
        Bounds::open_closed(0.0, 10.0).check("dt_s", self.dt_s)?;
        Bounds::closed_open(0.0, 1e4).check("pre_roll_s", self.pre_roll_s)?;
        let ticks = self.periods * self.period_s / self.dt_s;
        Bounds::closed(1.0, 5e7).check("periods * period_s / dt_s", ticks)?;
        // the pre-roll ramps and holds, twice its length in ticks
        Bounds::closed(0.0, 5e7)
            .check("2 * pre_roll_s / dt_s", 2.0 * self.pre_roll_s / self.dt_s)?;
        Ok(self.trajectory.sampler()?)
    }

    /// The pre-roll's commands, one per tick: a raised cosine from `from_deg`
    /// (where the plant is) to `to_deg` (θ_d(0)) over `pre_roll_s`, then held
    /// as long again.
    pub(crate) fn pre_roll(&self, from_deg: f64, to_deg: f64) -> impl Iterator<Item = f64> {
        let ramp_ticks = (self.pre_roll_s / self.dt_s).round() as usize;
        (1..=2 * ramp_ticks).map(move |k| {
            let u = (k as f64 / ramp_ticks as f64).min(1.0);
            let w = 0.5 * (1.0 - (std::f64::consts::PI * u).cos());
            from_deg + (to_deg - from_deg) * w
        })
    }

    /// The number of evaluated ticks: `periods` periods of `dt_s`.
    pub(crate) fn evaluated_ticks(&self) -> usize {
        (self.periods * self.period_s / self.dt_s).round() as usize
    }

    /// Drives `plant` (from its current state) through the scenario and records the evaluated part.
    ///
    /// # Errors
    /// * [`ControlError::OutOfRange`] naming the first setting out of its
    ///   range, before the plant moves: `periods` outside `(0, 1e4]`,
    ///   `period_s` outside `(0, 1e5]` s, `dt_s` outside `(0, 10]` s,
    ///   `pre_roll_s` outside `[0, 1e4)` s, or `periods * period_s / dt_s`
    ///   (the evaluated ticks) outside `[1, 5e7]`;
    /// * [`ControlError::Model`] with the trajectory's error
    ///   ([`Trajectory::sampler`]), also before the plant moves;
    /// * [`ControlError::Model`] with the plant's error ([`Plant::step`]), e.g.
    ///   [`ModelError::OutOfWorkspace`] for a `translation_mm` or a θ_d outside
    ///   the workspace; the plant keeps the ticks it took before.
    ///
    /// [`ModelError::OutOfWorkspace`]: kflex_model::ModelError::OutOfWorkspace
    pub fn run(&self, plant: &mut Plant) -> Result<Trace> {
        let sampler = self.validate()?;
        let start = sampler.sample(0.0).theta_d_deg;
        let command = |theta_c_deg| Command {
            theta_c_deg,
            translation_mm: self.translation_mm,
        };
        for theta in self.pre_roll(plant.state().command.theta_c_deg, start) {
            plant.step(command(theta), self.dt_s)?;
        }
        let n = self.evaluated_ticks();
        let mut trace = Trace::default();
        for v in [
            &mut trace.time_s,
            &mut trace.theta_d_deg,
            &mut trace.theta_d_rate_deg_per_s,
            &mut trace.theta_a_deg,
            &mut trace.theta_a_measured_deg,
        ] {
            v.reserve(n);
        }
        for k in 0..n {
            // sample at the end of the tick, when the plant has answered it
            let t = (k + 1) as f64 * self.dt_s;
            let s = sampler.sample(t);
            let state = plant.step(command(s.theta_d_deg), self.dt_s)?;
            trace.time_s.push(t);
            trace.theta_d_deg.push(s.theta_d_deg);
            trace.theta_d_rate_deg_per_s.push(s.theta_d_rate_deg_per_s);
            trace.theta_a_deg.push(state.theta_a_deg);
            trace.theta_a_measured_deg.push(state.theta_a_measured_deg);
        }
        Ok(trace)
    }
}

/// The uncompensated-plant grid of `kflex-cli run --estimator none`.
///
/// **Protocol.** The plant starts at rest, straight. The paper's input starts
/// at θ_d(0) = 25 deg, so a pre-roll first brings the command there with a
/// raised-cosine ramp of [`OpenLoopScenario::pre_roll_s`] and holds it for as
/// long again; then the input runs for `periods` periods, sampled every `dt_s`.
/// Metrics use only those periods and the *measured* angle (Aurora-like noise,
/// as in the paper's measurements).
///
/// **Repeats.** Each repeat draws a plant from the nominal one with a
/// parameter spread ([`kflex_model::PlantConfig::perturbed`]: the physical
/// parameter, the build's by a third as much as the set-up's, and the
/// tendons' seating with the drive's homing) and its own noise seed; both
/// seeds are recorded. The spread stands in for what changes between
/// repeated runs on a real robot (friction with lubrication and temperature,
/// re-tensioning, tendon seating, where the drive was zeroed). The default,
/// 15 %, gives a run-to-run spread of the RMSE and the loop width within a
/// factor of 3 of the paper's (its Table IX ± figures; see CALIBRATION.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OpenLoopGrid {
    /// Nominal plant (its `sheath_deg`, `noise` and `seed` are set per run).
    pub plant: PlantConfig,
    /// Scenario of every run.
    pub scenario: OpenLoopScenario,
    /// Sheath configurations, deg.
    pub sheaths_deg: Vec<f64>,
    /// Repeats per configuration.
    pub repeats: u32,
    /// Base seed; repeat `r` uses `seed + r` for both spread and noise.
    pub seed: u64,
    /// Relative parameter spread between repeats, `[0, 0.5]` (0 for identical
    /// plants at rest; the default 0.15).
    pub spread: f64,
    /// Measurement noise of every run; `None` for the true angle.
    pub noise: Option<AuroraNoise>,
}

impl Default for OpenLoopGrid {
    fn default() -> Self {
        Self {
            plant: PlantConfig::default(),
            scenario: OpenLoopScenario::default(),
            sheaths_deg: vec![0.0, 90.0, 180.0, 270.0],
            repeats: 3,
            seed: 2020,
            spread: 0.15,
            noise: Some(AuroraNoise::default()),
        }
    }
}

/// Mean ± std over the repeats of one configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridRow {
    /// Sheath bend, deg.
    pub sheath_deg: f64,
    /// Joint model that produced it.
    pub joint_model: JointModelKind,
    /// RMSE, deg.
    pub rmse_deg: MeanStd,
    /// Loop width, deg.
    pub max_hysteresis_deg: MeanStd,
    /// Error peak-to-peak, deg.
    pub error_peak_to_peak_deg: MeanStd,
    /// Peak loss, deg.
    pub peak_loss_deg: MeanStd,
    /// Per-repeat metrics, in seed order.
    pub runs: Vec<RunMetrics>,
    /// The seed of each repeat.
    pub seeds: Vec<u64>,
}

/// [`ControlError::SeedOverflow`] where repeat `r` of `repeats`, run on
/// `seed + r`, would wrap past the largest seed to 0.
pub(crate) fn check_seed(seed: u64, repeats: u32) -> Result<()> {
    let largest_base = u64::MAX - u64::from(repeats.saturating_sub(1));
    if seed > largest_base {
        return Err(ControlError::SeedOverflow {
            seed,
            repeats,
            largest_base,
        });
    }
    Ok(())
}

impl OpenLoopGrid {
    /// Runs every configuration and repeat. Deterministic in `seed`.
    ///
    /// # Errors
    /// Stops at the first failure:
    /// * [`ControlError::OutOfRange`] naming `repeats` when it is outside
    ///   `[1, 1000]` or `spread` outside `[0, 0.5]` (NaN included);
    ///   [`ControlError::SeedOverflow`] for a `seed` whose repeats would
    ///   pass the largest seed; [`ControlError::NotEnoughData`] for no
    ///   `sheaths_deg`;
    /// * [`ControlError::Model`] naming the first parameter of the nominal
    ///   plant out of its range ([`PlantConfig::perturbed`]), or of a run's plant
    ///   out of its range ([`Plant::new`]), e.g. a sheath angle outside
    ///   `[0, 3600]` deg or a noise level;
    /// * as [`OpenLoopScenario::run`] and [`Trace::metrics`] for each run.
    ///
    /// # Examples
    ///
    /// One short run (one period of the paper's input, one repeat) at a
    /// 180 deg sheath:
    ///
    /// ```
    /// use kflex_control::{OpenLoopGrid, OpenLoopScenario};
    /// let grid = OpenLoopGrid {
    ///     sheaths_deg: vec![180.0],
    ///     repeats: 1,
    ///     scenario: OpenLoopScenario { periods: 1.0, ..OpenLoopScenario::default() },
    ///     ..OpenLoopGrid::default()
    /// };
    /// let rows = grid.run()?;
    /// assert_eq!(rows.len(), 1);
    /// let row = &rows[0];
    /// assert_eq!(row.sheath_deg, 180.0);
    /// assert_eq!(row.seeds, [grid.seed]);
    /// // the uncompensated joint misses the command and lags it in a loop
    /// assert!(row.rmse_deg.mean > 0.0 && row.max_hysteresis_deg.mean > 0.0);
    /// assert_eq!(row.rmse_deg.std, 0.0); // a single repeat
    /// # Ok::<(), kflex_control::ControlError>(())
    /// ```
    pub fn run(&self) -> Result<Vec<GridRow>> {
        Bounds::closed(1.0, f64::from(MAX_REPEATS)).check("repeats", f64::from(self.repeats))?;
        check_seed(self.seed, self.repeats)?;
        Bounds::closed(0.0, 0.5).check("spread", self.spread)?;
        if self.sheaths_deg.is_empty() {
            return Err(ControlError::NotEnoughData {
                metric: "grid",
                needed: "at least one sheath configuration",
                got: 0,
            });
        }
        self.sheaths_deg
            .iter()
            .map(|&sheath_deg| self.run_one(sheath_deg))
            .collect()
    }

    fn run_one(&self, sheath_deg: f64) -> Result<GridRow> {
        let seeds: Vec<u64> = (0..u64::from(self.repeats))
            .map(|r| self.seed.wrapping_add(r))
            .collect();
        let mut runs = Vec::with_capacity(seeds.len());
        for &seed in &seeds {
            // the grid's sheath, noise and seed replace the plant's before
            // anything checks it: a value they replace is never at fault
            let mut base = self.plant;
            base.sheath_deg = sheath_deg;
            base.noise = self.noise;
            base.seed = seed;
            let config = base.perturbed(seed, self.spread)?;
            let mut plant = Plant::new(config)?;
            runs.push(self.scenario.run(&mut plant)?.metrics()?);
        }
        let pick = |f: fn(&RunMetrics) -> f64| MeanStd::of(&runs.iter().map(f).collect::<Vec<_>>());
        Ok(GridRow {
            sheath_deg,
            joint_model: self.plant.joint_model,
            rmse_deg: pick(|m| m.rmse_deg)?,
            max_hysteresis_deg: pick(|m| m.max_hysteresis_deg)?,
            error_peak_to_peak_deg: pick(|m| m.error_peak_to_peak_deg)?,
            peak_loss_deg: pick(|m| m.peak_loss_deg)?,
            runs,
            seeds,
        })
    }
}
