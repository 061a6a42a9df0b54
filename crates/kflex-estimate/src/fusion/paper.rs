//! The paper's Kalman filter (Eq. 6–12), with both readings of its rate.

use kflex_model::Bounds;
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

use super::{Estimate, Fusion, Measurements, SensorUse, check_inputs};
use crate::error::Result;

/// When the paper's filter steps (`../shared/DESIGN.md`, "Kalman rate").
///
/// The paper gives the filter's model `Δt = 0.1` s and `σ_a = σ_z = 0.01`
/// but not how often it runs. Taken literally the filter steps every 0.1 s
/// ([`FilterRate::AsWritten`]); the authors' public follow-up code steps it
/// on every incoming command with the model `Δt` kept at 0.1 s
/// ([`FilterRate::AsRun`]). The model `Δt` is a tuning constant in both: it
/// sets how far the constant-velocity model extrapolates per step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterRate {
    /// Predict and update on every tick of the loop, with the model `Δt`
    /// (the default: it follows the paper's 1 rad/s input; stepped every
    /// 0.1 s the filter lags it by several degrees, see the crate docs).
    #[default]
    AsRun,
    /// Predict and update once every model `Δt` of loop time; between steps
    /// the estimate is held and the measurements are not used.
    AsWritten,
}

/// The least measurement noise a filter takes, deg: far below any sensor's,
/// and far above where its square (from about 1e-154 deg) underflows.
pub(crate) const MIN_SIGMA_Z_DEG: f64 = 1e-6;

/// Parameters of [`PaperKalman`]. Defaults are the paper's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KalmanParams {
    /// The model's time step `Δt` in `F` and `G`, s (paper: 0.1).
    pub model_dt_s: f64,
    /// Process noise `σ_a`, the standard deviation of the acceleration the
    /// model allows per step, deg/s² (paper: 0.01).
    pub sigma_a: f64,
    /// Measurement noise `σ_z` of KBJAE and IBJAE, deg (paper: 0.01 for
    /// both, which makes the fusion roughly their average).
    pub sigma_z_deg: [f64; 2],
    /// How often the filter steps.
    pub rate: FilterRate,
}

impl Default for KalmanParams {
    fn default() -> Self {
        Self {
            model_dt_s: 0.1,
            sigma_a: 0.01,
            sigma_z_deg: [0.01, 0.01],
            rate: FilterRate::AsRun,
        }
    }
}

impl KalmanParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`crate::EstimateError::OutOfRange`] naming `model_dt_s` outside
    /// `(0, 3600]` s, `sigma_a` outside `[0, 1e6]`, or `sigma_z_deg` outside
    /// `[1e-6, 1e6]` deg (a smaller `σ_z` squares to zero in `f64`, and the
    /// filter would divide zero by zero).
    pub fn validate(&self) -> Result<()> {
        Bounds::open_closed(0.0, 3600.0).check("model_dt_s", self.model_dt_s)?;
        Bounds::closed(0.0, 1e6).check("sigma_a", self.sigma_a)?;
        for s in self.sigma_z_deg {
            Bounds::closed(MIN_SIGMA_Z_DEG, 1e6).check("sigma_z_deg", s)?;
        }
        Ok(())
    }
}

/// The paper's fusion filter (LBHJAE, Eq. 6–12): a constant-velocity model
/// on `[θ, θ']` updated in turn by KBJAE and IBJAE.
///
/// `F = [[1, Δt], [0, 1]]`, `Q = G Gᵀ σ_a²` with `G = [Δt²/2, Δt]ᵀ`,
/// `H = [1, 0]` and `R = σ_z²` for each sensor, `x₀ = 0`, `P₀ = 0`. Each step
/// predicts (`x = F x`, `P = F P Fᵀ + Q`), then updates with KBJAE, then with
/// IBJAE (`K = P Hᵀ / S`, `x += K ν`, and the covariance in Joseph form
/// `P = (I − K H) P (I − K H)ᵀ + K R Kᵀ`, as filterpy computes it); a
/// missing measurement skips its update. The tests hold it to filterpy's
/// `KalmanFilter` within 1e-9.
///
/// # Examples
/// ```
/// use kflex_estimate::{Fusion, Measurements, PaperKalman, KalmanParams};
/// let mut kf = PaperKalman::new(KalmanParams::default())?;
/// let m = Measurements { kbjae_deg: Some(10.0), ibjae_deg: Some(12.0), ..Default::default() };
/// let mut e = kf.step(0.01, m)?;
/// assert!(e.theta_hat_deg < 0.01); // P₀ = 0: the filter starts sure of x₀ = 0
/// for _ in 0..2000 {
///     e = kf.step(0.01, m)?;
/// }
/// assert!((e.theta_hat_deg - 11.0).abs() < 0.01); // equal σ_z: the average
/// # Ok::<(), kflex_estimate::EstimateError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct PaperKalman {
    params: KalmanParams,
    f: Matrix2<f64>,
    q: Matrix2<f64>,
    x: Vector2<f64>,
    p: Matrix2<f64>,
    /// Loop time since the last step ([`FilterRate::AsWritten`]), s.
    elapsed_s: f64,
    last: [SensorUse; 2],
}

impl PaperKalman {
    /// A filter at the paper's initial state `x₀ = 0`, `P₀ = 0`.
    ///
    /// # Errors
    /// As [`KalmanParams::validate`].
    pub fn new(params: KalmanParams) -> Result<Self> {
        params.validate()?;
        let dt = params.model_dt_s;
        let f = Matrix2::new(1.0, dt, 0.0, 1.0);
        let g = Vector2::new(0.5 * dt * dt, dt);
        let q = g * g.transpose() * (params.sigma_a * params.sigma_a);
        Ok(Self {
            params,
            f,
            q,
            x: Vector2::zeros(),
            p: Matrix2::zeros(),
            elapsed_s: 0.0,
            last: [SensorUse::Missing; 2],
        })
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &KalmanParams {
        &self.params
    }

    fn predict(&mut self) {
        self.x = self.f * self.x;
        self.p = self.f * self.p * self.f.transpose() + self.q;
    }

    fn update(&mut self, z: Option<f64>, sigma_z: f64) -> SensorUse {
        let Some(z) = z else {
            return SensorUse::Missing;
        };
        let r = sigma_z * sigma_z;
        let nu = z - self.x[0];
        let s = self.p[(0, 0)] + r;
        let k = self.p.column(0) / s;
        self.x += k * nu;
        let i_kh = Matrix2::identity() - Matrix2::new(k[0], 0.0, k[1], 0.0);
        self.p = i_kh * self.p * i_kh.transpose() + k * k.transpose() * r;
        // kept exactly symmetric (the Joseph form leaves rounding asymmetry)
        self.p = (self.p + self.p.transpose()) * 0.5;
        SensorUse::Used
    }
}

impl Fusion for PaperKalman {
    fn step(&mut self, dt_s: f64, m: Measurements) -> Result<Estimate> {
        check_inputs(dt_s, &m)?;
        let steps = match self.params.rate {
            FilterRate::AsRun => 1,
            FilterRate::AsWritten => {
                self.elapsed_s += dt_s;
                // a tick that lands within rounding of the period counts as reaching it
                let n = (self.elapsed_s / self.params.model_dt_s * (1.0 + 1e-9)).floor();
                self.elapsed_s = (self.elapsed_s - n * self.params.model_dt_s).max(0.0);
                n.min(1e6) as u32
            }
        };
        if steps == 0 {
            self.last = [SensorUse::Held; 2];
            return Ok(self.estimate());
        }
        for _ in 0..steps {
            self.predict();
        }
        let [s1, s2] = self.params.sigma_z_deg;
        self.last = [self.update(m.kbjae_deg, s1), self.update(m.ibjae_deg, s2)];
        Ok(self.estimate())
    }

    fn estimate(&self) -> Estimate {
        Estimate::of_state(&self.x, &self.p, self.last)
    }

    fn reset(&mut self) {
        self.x = Vector2::zeros();
        self.p = Matrix2::zeros();
        self.elapsed_s = 0.0;
        self.last = [SensorUse::Missing; 2];
    }
}
