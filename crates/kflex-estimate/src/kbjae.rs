//! KBJAE: the kinematic-based joint angle estimator (the paper's Section
//! II-C-2): an MLP that predicts the hysteresis error `θ̃` from the command
//! and its rate, so `θ = θ_c + θ̃` (cargo feature `onnx`).

use std::path::Path;
use std::sync::Arc;

use kflex_model::{Bounds, ModelError};

use crate::error::Result;
use crate::onnx::{ModelPool, OnnxModel, Pooled, TensorSpec};

/// KBJAE's model input: `[batch, 2]` of (θ deg, θ' deg/s), `f32`; the
/// training script bakes its input scaling into the graph.
pub const KBJAE_INPUT: TensorSpec = TensorSpec {
    name: "theta_and_rate",
    shape: &[-1, 2],
};

/// KBJAE's model output: `[batch, 1]` of the predicted error `θ̃`, deg.
pub const KBJAE_OUTPUT: TensorSpec = TensorSpec {
    name: "theta_error",
    shape: &[-1, 1],
};

/// The rate of the command stream: a backward difference over each tick's
/// own `dt`, 0 on the first tick (no history), so irregular ticks give the
/// right rate. KBJAE was trained on `(θ_d, θ_d')` sampled from smooth
/// periodic signals; this is the derivative those samples stand for.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CommandRate {
    last_deg: Option<f64>,
}

impl CommandRate {
    /// A differentiator with no history.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The rate after a tick of `dt_s` that ends at `theta_deg`, deg/s.
    ///
    /// # Errors
    /// [`crate::EstimateError::Model`] for a non-finite angle, or `dt_s`
    /// outside `(0, 3600]` s; the history is then unchanged.
    pub fn step(&mut self, theta_deg: f64, dt_s: f64) -> Result<f64> {
        if !theta_deg.is_finite() {
            return Err(ModelError::NonFinite {
                name: "theta_c_deg",
                value: theta_deg,
            }
            .into());
        }
        Bounds::open_closed(0.0, 3600.0).check("dt_s", dt_s)?;
        let rate = self.last_deg.map_or(0.0, |last| (theta_deg - last) / dt_s);
        self.last_deg = Some(theta_deg);
        Ok(rate)
    }

    /// Forgets the history (the next tick's rate is 0).
    pub fn reset(&mut self) {
        self.last_deg = None;
    }
}

/// [`Kbjae::predict`]'s refusal in a step's words: the command is
/// `theta_c_deg`, and a rate the caller did not give (`differenced`) is the
/// commands' difference, not an argument called `rate_deg_per_s`.
fn as_step(e: crate::EstimateError, differenced: bool) -> crate::EstimateError {
    let rename = |name: &'static str| match name {
        "theta_deg" => "theta_c_deg",
        "rate_deg_per_s" if differenced => "the commands' rate (their difference over dt_s), deg/s",
        name => name,
    };
    match e {
        crate::EstimateError::OutOfRange(mut r) => {
            r.name = rename(r.name);
            crate::EstimateError::OutOfRange(r)
        }
        crate::EstimateError::Model(ModelError::NonFinite { name, value }) => {
            crate::EstimateError::Model(ModelError::NonFinite {
                name: rename(name),
                value,
            })
        }
        e => e,
    }
}

/// The largest command KBJAE takes, ± deg ([`Kbjae::predict`]).
pub const MAX_THETA_DEG: f64 = 1e6;
/// The largest command rate KBJAE takes, ± deg/s ([`Kbjae::predict`]).
pub const MAX_RATE_DEG_PER_S: f64 = 1e9;

/// KBJAE: `θ̂ = θ + θ̃(θ, θ')` with `θ̃` from the MLP (Table II).
///
/// Its input is the command **actually sent to the plant**, `θ_c`, not the
/// master's `θ_d`: the MLP learned how the joint lags the command its
/// motors receive (open loop, where `θ_c = θ_d`), and once the compensator
/// adds to the command, the joint follows `θ_c`, not `θ_d`.
#[derive(Debug)]
pub struct Kbjae {
    model: Pooled,
    rate: CommandRate,
}

impl Kbjae {
    /// Loads KBJAE's ONNX model (see [`KBJAE_INPUT`], [`KBJAE_OUTPUT`]) for
    /// batch-1 latency on one thread.
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load(path: &Path) -> Result<Self> {
        Ok(Self {
            model: Pooled::alone(OnnxModel::load(path, KBJAE_INPUT, KBJAE_OUTPUT, 1)?),
            rate: CommandRate::new(),
        })
    }

    /// [`Kbjae::load`] through `pool` (see [`Scnn::load_pooled`](crate::Scnn::load_pooled)).
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load_pooled(path: &Path, pool: &Arc<ModelPool>) -> Result<Self> {
        Ok(Self {
            model: pool.load(path, KBJAE_INPUT, KBJAE_OUTPUT, 1)?,
            rate: CommandRate::new(),
        })
    }

    /// The model file's SHA-256.
    #[must_use]
    pub fn sha256(&self) -> &str {
        self.model.sha256()
    }

    /// One tick: the command `theta_c_deg` sent this tick, `dt_s` after the
    /// last; returns KBJAE's angle `θ_c + θ̃(θ_c, θ_c')`, deg.
    ///
    /// # Errors
    /// As [`CommandRate::step`]; as [`Kbjae::predict`], the angle named
    /// `theta_c_deg` and the rate differenced from the commands named as
    /// theirs (the estimator is unchanged after any of these).
    pub fn step(&mut self, theta_c_deg: f64, dt_s: f64) -> Result<f64> {
        self.advance(theta_c_deg, None, dt_s)
    }

    /// [`Kbjae::step`] for each command of `theta_c_deg`, each `dt_s` after
    /// the one before: KBJAE's angles, deg. All or nothing: on a refused
    /// command the error is returned and the estimator is as it was before
    /// the call.
    ///
    /// # Errors
    /// As [`Kbjae::step`], for the first command refused.
    pub fn run(&mut self, theta_c_deg: &[f64], dt_s: f64) -> Result<Vec<f64>> {
        let before = self.rate;
        let angles = theta_c_deg
            .iter()
            .map(|&t| self.step(t, dt_s))
            .collect::<Result<Vec<f64>>>();
        if angles.is_err() {
            self.rate = before;
        }
        angles
    }

    /// One tick with the rate given instead of taken from the commands'
    /// differences: the command `theta_c_deg` sent this tick and `rate_deg_per_s`,
    /// e.g. the master's θ_d' (the paper's input is the master's
    /// {θ_d, θ_d'}; in a compensated loop the compensator's corrections make
    /// θ_c' wiggle, and a memoryless model reads each wiggle as a reversal).
    /// The commands' history is kept as [`Kbjae::step`] keeps it, so the two
    /// may be mixed. Returns `θ_c + θ̃(θ_c, rate)`, deg.
    ///
    /// # Errors
    /// As [`Kbjae::step`], and [`crate::EstimateError::Model`] for a
    /// non-finite rate (the estimator is then unchanged).
    pub fn step_with_rate(
        &mut self,
        theta_c_deg: f64,
        rate_deg_per_s: f64,
        dt_s: f64,
    ) -> Result<f64> {
        self.advance(theta_c_deg, Some(rate_deg_per_s), dt_s)
    }

    /// [`Kbjae::step_with_rate`] where a rate is given, else [`Kbjae::step`]:
    /// the commands' history moves either way, and only once every check
    /// has passed and the model has answered.
    pub(crate) fn advance(
        &mut self,
        theta_c_deg: f64,
        rate_deg_per_s: Option<f64>,
        dt_s: f64,
    ) -> Result<f64> {
        let (angle, history) = self.answer(theta_c_deg, rate_deg_per_s, dt_s)?;
        self.rate = history;
        Ok(angle)
    }

    /// [`Kbjae::advance`]'s angle and the commands' history after it,
    /// without moving the history: a caller that can still fail after
    /// (LBHJAE's fusion) moves it with [`Kbjae::keep`] once it has not.
    pub(crate) fn answer(
        &mut self,
        theta_c_deg: f64,
        rate_deg_per_s: Option<f64>,
        dt_s: f64,
    ) -> Result<(f64, CommandRate)> {
        let mut history = self.rate;
        let difference = history.step(theta_c_deg, dt_s)?;
        let angle = self
            .predict(theta_c_deg, rate_deg_per_s.unwrap_or(difference))
            .map_err(|e| as_step(e, rate_deg_per_s.is_none()))?;
        Ok((angle, history))
    }

    /// Moves the commands' history to `history` ([`Kbjae::answer`]'s; LBHJAE
    /// keeps it, which needs the `index` feature).
    #[cfg_attr(not(feature = "index"), allow(dead_code))]
    pub(crate) fn keep(&mut self, history: CommandRate) {
        self.rate = history;
    }

    /// Checks one input of the network: a finite angle within
    /// ±[`MAX_THETA_DEG`], then a finite rate within ±[`MAX_RATE_DEG_PER_S`]
    /// (the angle first: a step's rate is the angles' difference, so a wild
    /// angle is the cause). The network runs in `f32`: a value past these
    /// bounds would reach it as infinity (and no joint bends or turns that
    /// far). Check a caller's `f64` values before rounding them to `f32`.
    ///
    /// # Errors
    /// [`crate::EstimateError::Model`] naming a value that is not finite,
    /// [`crate::EstimateError::OutOfRange`] one beyond its bound.
    pub fn check_input(theta_deg: f64, rate_deg_per_s: f64) -> Result<()> {
        for (name, value, max) in [
            ("theta_deg", theta_deg, MAX_THETA_DEG),
            ("rate_deg_per_s", rate_deg_per_s, MAX_RATE_DEG_PER_S),
        ] {
            kflex_model::finite(name, value)?;
            kflex_model::Bounds::closed(-max, max).check(name, value)?;
        }
        Ok(())
    }

    /// KBJAE's angle for a command and its rate, deg (no history kept).
    ///
    /// # Errors
    /// As [`Kbjae::check_input`]; [`crate::EstimateError::Onnx`] when the
    /// model fails or answers with a value that is not finite.
    pub fn predict(&mut self, theta_deg: f64, rate_deg_per_s: f64) -> Result<f64> {
        Self::check_input(theta_deg, rate_deg_per_s)?;
        let mut error = [0.0f32];
        self.model
            .run(&[theta_deg as f32, rate_deg_per_s as f32], 1, &mut error)?;
        Ok(theta_deg + f64::from(error[0]))
    }

    /// The predicted errors `θ̃` for many (θ, θ') pairs at once, deg
    /// (throughput: one model call).
    ///
    /// # Errors
    /// [`crate::EstimateError::Length`] when the slices differ in length;
    /// as [`Kbjae::check_input`] for each pair; [`crate::EstimateError::Onnx`]
    /// when the model fails or answers with a value that is not finite.
    pub fn errors(&mut self, theta_deg: &[f32], rate_deg_per_s: &[f32]) -> Result<Vec<f32>> {
        if theta_deg.len() != rate_deg_per_s.len() {
            return Err(crate::EstimateError::Length {
                what: "rates",
                expected: theta_deg.len(),
                got: rate_deg_per_s.len(),
            });
        }
        let mut input = Vec::with_capacity(2 * theta_deg.len());
        for (&t, &r) in theta_deg.iter().zip(rate_deg_per_s) {
            Self::check_input(f64::from(t), f64::from(r))?;
            input.extend([t, r]);
        }
        let mut out = vec![0.0f32; theta_deg.len()];
        self.model.run(&input, theta_deg.len(), &mut out)?;
        Ok(out)
    }

    /// Forgets the command history.
    pub fn reset(&mut self) {
        self.rate.reset();
    }
}
