//! Kalman fusion of the two joint-angle estimators (LBHJAE, the paper's
//! Section II-C, Eq. 6–12): KBJAE's angle from the command and IBJAE's angle
//! from the camera, as two sensors of one joint.
//!
//! Two filters share one interface, [`Fusion`]:
//!
//! * [`PaperKalman`] — the paper's filter as published: a constant-velocity
//!   model `x = [θ, θ']`, `F = [[1, Δt], [0, 1]]`, `Q = G Gᵀ σ_a²` with
//!   `G = [Δt²/2, Δt]ᵀ`, both sensors measuring θ with the same `σ_z`, and
//!   `x₀ = 0`, `P₀ = 0`. Each step predicts, then updates with KBJAE, then
//!   with IBJAE; a missing measurement skips its update. Its model `Δt` is
//!   kept apart from the loop's tick, and both readings of its rate are
//!   available ([`FilterRate`]).
//! * [`AdaptiveKalman`] — beyond the paper (its own future work): the model
//!   runs on the loop's real tick, each sensor's noise is estimated from its
//!   innovations, KBJAE's slowly varying bias is a state the camera
//!   calibrates, and a chi-square gate rejects camera measurements that
//!   disagree with the prediction (distal occlusion).
//!
//! Angles in degrees, rates in deg/s, times in seconds. A missing
//! measurement is `None`; a NaN or infinite one, a tick `dt_s ≤ 0` or a
//! non-finite tick is an error, and the filter is left as it was.

mod adaptive;
mod paper;

pub use adaptive::{AdaptiveKalman, AdaptiveParams};
pub use paper::{FilterRate, KalmanParams, PaperKalman};

use kflex_model::Bounds;
use serde::{Deserialize, Serialize};

use crate::error::Result;

/// The two sensors' readings for one tick, deg; `None` where a sensor has no
/// measurement this tick (no camera frame, no instrument found).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Measurements {
    /// KBJAE's angle `θ_d + θ̃` (sensor 1), deg.
    pub kbjae_deg: Option<f64>,
    /// IBJAE's angle from the camera (sensor 2), deg.
    pub ibjae_deg: Option<f64>,
    /// IBJAE's own uncertainty of this angle, deg, where it gives one (from
    /// the distance to its nearest database silhouette: a frame whose
    /// silhouette matches nothing well, as under distal occlusion, is less
    /// certain). [`AdaptiveKalman`] uses it as a lower bound on the
    /// camera's noise; [`PaperKalman`] ignores it (the paper's `σ_z` is fixed).
    pub ibjae_sigma_deg: Option<f64>,
    /// Whether IBJAE's angle takes part of the instrument as hidden
    /// (`IbjaeReading::occluded`): [`AdaptiveKalman`] rejects such a reading
    /// (the camera is its absolute reference, and an occluder's bias would
    /// become KBJAE's); [`PaperKalman`] takes it as any other.
    #[serde(default)]
    pub ibjae_occluded: bool,
}

/// What a filter step did with one sensor's measurement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub enum SensorUse {
    /// The measurement updated the estimate.
    Used,
    /// There was no measurement this tick.
    Missing,
    /// The filter did not step this tick (the paper's filter "as written"
    /// steps only every model `Δt`): the estimate is held.
    Held,
    /// Rejected by the chi-square gate: its normalised innovation squared
    /// `ν²/S` was above the gate.
    Gated {
        /// `ν²/S` of the rejected measurement.
        nis: f64,
    },
}

/// The fused estimate after one tick (LBHJAE's θ̂).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// Estimated joint angle θ̂, deg.
    pub theta_hat_deg: f64,
    /// Estimated joint rate θ̂', deg/s.
    pub theta_hat_rate_deg_per_s: f64,
    /// Covariance of `[θ̂, θ̂']`, deg², deg²/s, deg²/s².
    pub covariance: [[f64; 2]; 2],
    /// What became of KBJAE's measurement.
    pub kbjae: SensorUse,
    /// What became of IBJAE's measurement.
    pub ibjae: SensorUse,
}

impl Estimate {
    /// The estimate a filter's state gives: `θ` and `θ'` are the first two
    /// entries of `x`, their covariance the top-left 2×2 block of `p`.
    pub(crate) fn of_state<D: nalgebra::Dim, S, T>(
        x: &nalgebra::Matrix<f64, D, nalgebra::U1, S>,
        p: &nalgebra::Matrix<f64, D, D, T>,
        last: [SensorUse; 2],
    ) -> Self
    where
        S: nalgebra::RawStorage<f64, D, nalgebra::U1>,
        T: nalgebra::RawStorage<f64, D, D>,
    {
        Self {
            theta_hat_deg: x[0],
            theta_hat_rate_deg_per_s: x[1],
            covariance: [[p[(0, 0)], p[(0, 1)]], [p[(1, 0)], p[(1, 1)]]],
            kbjae: last[0],
            ibjae: last[1],
        }
    }
}

/// A joint-angle fusion filter stepped once per control tick.
pub trait Fusion {
    /// Advances the filter by one tick of `dt_s` seconds with this tick's
    /// measurements and returns the estimate.
    ///
    /// # Errors
    /// [`crate::EstimateError::Model`] with a non-finite or out-of-range
    /// value (`dt_s` must lie in `(0, 3600]` s; measurements must be finite
    /// when present). The filter is then unchanged.
    fn step(&mut self, dt_s: f64, measurements: Measurements) -> Result<Estimate>;

    /// The current estimate without stepping (the prior before the first step).
    fn estimate(&self) -> Estimate;

    /// Back to the initial state.
    fn reset(&mut self);
}

/// Checks one tick's inputs before a filter changes anything.
pub(crate) fn check_inputs(dt_s: f64, m: &Measurements) -> Result<()> {
    kflex_model::finite("dt_s", dt_s)?;
    Bounds::open_closed(0.0, 3600.0).check("dt_s", dt_s)?;
    // within ±1e6 deg: larger readings would overflow the covariance's
    // arithmetic to infinities, and no joint bends that far
    if let Some(z) = m.kbjae_deg {
        kflex_model::finite("kbjae_deg", z)?;
        Bounds::closed(-1e6, 1e6).check("kbjae_deg", z)?;
    }
    if let Some(z) = m.ibjae_deg {
        kflex_model::finite("ibjae_deg", z)?;
        Bounds::closed(-1e6, 1e6).check("ibjae_deg", z)?;
    }
    if let Some(s) = m.ibjae_sigma_deg {
        Bounds::closed(0.0, 1e6).check("ibjae_sigma_deg", s)?;
    }
    Ok(())
}
