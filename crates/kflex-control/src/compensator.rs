//! The hysteresis compensator of the paper (Eq. 3–5): a PID on the
//! estimated joint angle plus a backlash term, with what a real controller
//! needs around it (saturation, anti-windup, rate limit, faults, watchdog).
//! Everything about it, kflex's reading of Eq. 5 included, is on
//! [`Compensator`].

use kflex_model::{Bounds, RangeError};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::error::Result;

/// The longest tick the compensator steps, s: a longer one holds the
/// command ([`Fault::InvalidDt`]).
pub const MAX_STEP_S: f64 = 1.0;

/// The compensator's gains and limits. Angles in degrees, times in seconds.
///
/// The defaults are tuned on kflex's plant (analytic joint, 100 Hz, a
/// perfect estimator) for the paper's input, 25 sin(t) + 25 deg: see
/// `tests/compensator.rs`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompensatorConfig {
    /// Proportional gain `K_p` of Eq. 4, deg/deg, in `[0, 100]` (default 0.6).
    pub kp: f64,
    /// Integral gain `K_i` of Eq. 4, 1/s, in `[0, 1e4]` (default 10).
    pub ki_per_s: f64,
    /// Derivative gain `K_d` of Eq. 4, s, in `[0, 100]` (default 0.005).
    pub kd_s: f64,
    /// Time constant of the derivative's low-pass filter, s, in `[0, 10]`
    /// (0: unfiltered; default 0.02).
    pub derivative_filter_s: f64,
    /// Which reading of Eq. 5's backlash term G is applied (default
    /// [`BacklashTerm::PidCorrection`]; [`BacklashTerm::Off`] for the plain
    /// PID of Eq. 3–4).
    pub backlash_term: BacklashTerm,
    /// How far θ_d must come back from its extreme before the command counts
    /// as having changed direction, deg, in `[0, 10]` (default 0: any step
    /// back; raise it for a noisy master).
    pub direction_deadband_deg: f64,
    /// Lower joint limit for θ_c, deg, in `[-180, 180]` (default −120: the
    /// kflex joint's hard stops, `JointParams::max_theta_deg`; at a 270 deg
    /// sheath the paper's 50 deg peak needs commands past 90 deg).
    pub theta_c_min_deg: f64,
    /// Upper joint limit for θ_c, deg, in `(theta_c_min_deg, 180]` (default 120).
    pub theta_c_max_deg: f64,
    /// Clamp on the integral term `K_i ∫ e dt`, deg, in `(0, 1e3]`; `None`
    /// for no clamp (default `Some(60)`: at a 270 deg sheath the paper's
    /// input needs about 50 deg of correction). With
    /// [`BacklashTerm::PidCorrection`] the integral restarts at each reversal,
    /// so this bounds the integral over one branch.
    pub integral_limit_deg: Option<f64>,
    /// Conditional integration: no integration while the output is limited
    /// (joint limit or rate limit) and the error pushes it further out
    /// (default true).
    pub freeze_integral_when_saturated: bool,
    /// Largest rate of change of θ_c, deg/s, in `(0, 1e5]` (default 200; the
    /// paper's input moves at most 25 deg/s).
    pub rate_limit_deg_per_s: f64,
    /// Age of the last estimate past which the watchdog trips, s, in
    /// `(0, 60]` (default 0.25: seven frames of a 30 Hz camera).
    pub watchdog_timeout_s: f64,
}

impl Default for CompensatorConfig {
    fn default() -> Self {
        Self {
            kp: 0.6,
            ki_per_s: 10.0,
            kd_s: 0.005,
            derivative_filter_s: 0.02,
            backlash_term: BacklashTerm::PidCorrection,
            direction_deadband_deg: 0.0,
            theta_c_min_deg: -120.0,
            theta_c_max_deg: 120.0,
            integral_limit_deg: Some(60.0),
            freeze_integral_when_saturated: true,
            rate_limit_deg_per_s: 200.0,
            watchdog_timeout_s: 0.25,
        }
    }
}

impl CompensatorConfig {
    /// Checks every field against its range (see each field).
    ///
    /// # Errors
    /// [`ControlError::OutOfRange`](crate::ControlError::OutOfRange) naming
    /// the first field out of its range (NaN included); `theta_c_max_deg` is
    /// named when it is not above `theta_c_min_deg`.
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.0, 100.0).check("kp", self.kp)?;
        Bounds::closed(0.0, 1e4).check("ki_per_s", self.ki_per_s)?;
        Bounds::closed(0.0, 100.0).check("kd_s", self.kd_s)?;
        Bounds::closed(0.0, 10.0).check("derivative_filter_s", self.derivative_filter_s)?;
        Bounds::closed(0.0, 10.0).check("direction_deadband_deg", self.direction_deadband_deg)?;
        Bounds::closed(-180.0, 180.0).check("theta_c_min_deg", self.theta_c_min_deg)?;
        Bounds::open_closed(self.theta_c_min_deg, 180.0)
            .check("theta_c_max_deg", self.theta_c_max_deg)?;
        if let Some(limit) = self.integral_limit_deg {
            Bounds::open_closed(0.0, 1e3).check("integral_limit_deg", limit)?;
        }
        Bounds::open_closed(0.0, 1e5).check("rate_limit_deg_per_s", self.rate_limit_deg_per_s)?;
        Bounds::open_closed(0.0, 60.0).check("watchdog_timeout_s", self.watchdog_timeout_s)?;
        Ok(())
    }
}

/// How Eq. 5's backlash term G is updated at a reversal of θ_d (see the
/// [`Compensator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BacklashTerm {
    /// No G: the PID of Eq. 3–4 alone.
    Off,
    /// `G_t = −f_{t−1}` with `f` the PID's correction P + I + D, as Eq. 5
    /// writes it: the correction built on the old branch is cancelled (the
    /// integral's share moved into G, so that the terms stay bounded).
    #[default]
    PidCorrection,
    /// `G_t = −(f + G)_{t−1}`: the whole correction of the tick before,
    /// G included, is reversed.
    TotalCorrection,
}

/// Why a tick held the last command instead of computing a new one.
///
/// Serialised (for logs) with its kind under `"fault"` and its fields beside
/// it, e.g. `{"fault": "watchdog", "age_s": 0.3, "timeout_s": 0.25}`.
#[derive(Debug, Clone, Copy, PartialEq, Error, Serialize)]
#[serde(tag = "fault", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Fault {
    /// θ_d was NaN or infinite.
    #[error("theta_d_deg is not finite ({value})")]
    NonFiniteDesired {
        /// The value given.
        value: f64,
    },
    /// The tick's `dt_s` was outside `(0, 1]` s (NaN included).
    #[error(transparent)]
    InvalidDt(RangeError),
    /// The estimate θ̂ was NaN or infinite; it is not used and does not
    /// count as an estimate for the watchdog.
    #[error("theta_hat_deg is not finite ({value})")]
    NonFiniteEstimate {
        /// The value given.
        value: f64,
    },
    /// No estimate for longer than the watchdog's timeout.
    #[error("no estimate for {age_s} s (watchdog timeout {timeout_s} s)")]
    Watchdog {
        /// Time since the last estimate (or since the reset), s.
        age_s: f64,
        /// The configured timeout, s.
        timeout_s: f64,
    },
}

/// The terms of Eq. 3–5 on one tick, deg. `p + i + d` is Eq. 4's `f`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Terms {
    /// `K_p e`.
    pub p_deg: f64,
    /// `K_i ∫ e dt` (after its clamp).
    pub i_deg: f64,
    /// `K_d e'` (filtered).
    pub d_deg: f64,
    /// Eq. 5's backlash term `G`.
    pub g_deg: f64,
}

impl Terms {
    /// Eq. 4's `f = p + i + d`.
    #[must_use]
    pub fn f_deg(&self) -> f64 {
        self.p_deg + self.i_deg + self.d_deg
    }
}

/// One tick's result (serialisable, for logs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CompensatorOutput {
    /// The command θ_c to send, deg: always finite and within the joint limits.
    pub theta_c_deg: f64,
    /// Why this tick held the last command, if it did.
    pub fault: Option<Fault>,
    /// The terms of Eq. 3–5 (held from the last estimate between estimates).
    pub terms: Terms,
    /// Whether the joint limits or the rate limit changed the target `θ_d + f + G`.
    pub limited: bool,
    /// Time since the last finite estimate (or since the reset), s.
    pub estimate_age_s: f64,
    /// Whether this tick's θ_d reversed the command's direction (G updated).
    pub reversed: bool,
}

/// The hysteresis compensator of Eq. 3–5: a PID on the estimated joint
/// angle plus a backlash term, with saturation, anti-windup, a rate limit,
/// faults and a watchdog around it.
///
/// # The equations
///
/// ```text
/// θ_c = θ_d + f(e, e') + G                                  (Eq. 3)
/// f   = K_p e + K_d e' + K_i ∫ e dt,   e = θ_d − θ̂           (Eq. 4)
/// G_t = −f_{t−1}, updated only when the command changes direction   (Eq. 5)
/// ```
///
/// `θ_d` is the master's desired angle, `θ̂` the estimate (LBHJAE, or any
/// estimator), `θ_c` the command sent to the plant.
///
/// # kflex's reading of Eq. 5
///
/// * **The command whose direction counts is θ_d**, the master's input (the
///   paper's "input command"), not θ_c: θ_c carries the feedback and its
///   noise, and would reverse on every wiggle of the estimate. The
///   direction is the sign of θ_d's motion; it reverses when θ_d has come
///   back more than [`CompensatorConfig::direction_deadband_deg`] from its
///   extreme since the last reversal (0: any step back). The first motion
///   after a reset sets the direction without counting as a reversal.
/// * **G is a held term, replaced at each reversal**: on the tick `t` where
///   the direction reverses, `G_t = −f_{t−1}`, minus the PID correction of
///   the tick before (P + I + D, before saturation, without G itself); on
///   every other tick `G_t = G_{t−1}`. It starts at 0
///   ([`BacklashTerm::PidCorrection`], the default).
/// * **Its effect.** The integral runs on through the reversal, so the
///   total correction after it is `f_t + G_t = f_t − f_{t_r−1}`: the
///   correction the PID had built on the old branch is dropped at once and
///   the correction restarts from zero, instead of being unwound by the
///   integral while the joint crosses the transmission's dead band. On a
///   backlash of half-width `b` the rising branch needs `+b`, the falling
///   one `−b`: G takes the first half of that `2b` swing as a step, the PID
///   the rest. The loop narrows at every sheath angle (measured in
///   `tests/compensator.rs`, `eq5_narrows_the_loop`).
/// * **Bounded terms.** Taken literally, G and the integral grow apart
///   without bound whenever the corrections at the two turning points do not
///   cancel (a gain loss: on kflex's plant at a 270 deg sheath G fell by
///   about 160 deg per period and the integral rose as much), and an
///   integral clamp then pins the integral and ruins tracking. kflex keeps
///   the same θ_c with bounded terms: at a reversal the integral's value is
///   moved into G, `I ← 0` and `G ← −f_{t−1} + I_{t−1} = −(P + D)_{t−1}`.
///   So [`Terms::i_deg`] is the integral since the last reversal, and
///   `f + G` is exactly Eq. 3–5's (the integral clamp, where it binds,
///   bounds the integral over one branch).
/// * **Another reading**, [`BacklashTerm::TotalCorrection`]: `G_t = −(f +
///   G)_{t−1}`, the whole correction reversed, so the correction jumps at a
///   reversal to what it was at the previous turning point. Bounded too,
///   but on kflex's plant it tracks worse than the PID alone, even at a
///   0 deg sheath; kept for comparison.
///
/// # Multirate: estimates need not come every tick
///
/// [`Compensator::step`] runs every control tick; the estimate may be
/// missing (`None`: a camera frame dropped or late). The PID is evaluated
/// only when an estimate arrives, over the time since the previous one; in
/// between, its correction `f` is held while θ_d and G are followed every
/// tick. So a missing estimate is ordinary operation, reported through
/// [`CompensatorOutput::estimate_age_s`]; only when the age passes
/// [`CompensatorConfig::watchdog_timeout_s`] does it become a fault
/// ([`Fault::Watchdog`]).
///
/// # Derivative
///
/// On the error, as Eq. 4 writes it (`e' = θ_d' − θ̂'`; θ_d comes from a
/// smooth master, so the derivative kick of a setpoint step is not a concern
/// here), differenced between estimates and low-passed with a first-order
/// filter of time constant [`CompensatorConfig::derivative_filter_s`]
/// (backward Euler), which keeps the estimate's noise from being amplified
/// by `1/dt`. The filter restarts (at zero) after a reset or a watchdog trip.
///
/// # Around the equations
///
/// In order, every tick: the target `θ_d + f + G` is clamped to the joint
/// limits, then moved from the last command by at most
/// `rate_limit_deg_per_s · dt`; since the last command lies inside the
/// limits, so does the result. The integral term `K_i ∫ e dt` is clamped to
/// `±integral_limit_deg`, and (with `freeze_integral_when_saturated`) does
/// not integrate while the output is limited and the error pushes it further
/// out (conditional integration). A tick with a non-finite θ_d, a `dt_s`
/// outside `(0, 1]` s or a non-finite estimate, and every tick while the
/// watchdog has tripped, holds the last command and reports a [`Fault`].
/// An invalid θ_d or `dt_s` leaves the compensator's state as it was; a
/// non-finite estimate is dropped (it does not reset the watchdog) while
/// time and θ_d's direction move on. `step` neither allocates nor panics
/// and never returns a non-finite command.
///
/// # Examples
///
/// ```
/// use kflex_control::{Compensator, CompensatorConfig};
/// let mut comp = Compensator::new(CompensatorConfig::default())?;
/// // the joint lags: θ̂ below θ_d, so the command goes above θ_d
/// let mut out = comp.step(10.0, Some(8.0), 0.01);
/// for _ in 0..100 {
///     out = comp.step(10.0, Some(8.0), 0.01);
/// }
/// assert!(out.fault.is_none() && out.theta_c_deg > 10.0);
/// // a NaN estimate is a fault: the command is held
/// let held = comp.step(10.0, Some(f64::NAN), 0.01);
/// assert!(held.fault.is_some());
/// assert_eq!(held.theta_c_deg, out.theta_c_deg);
/// # Ok::<(), kflex_control::ControlError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Compensator {
    config: CompensatorConfig,
    state: State,
}

/// Everything that moves; `State::default()` is the state after a reset.
#[derive(Debug, Clone, Copy, Default)]
struct State {
    /// The last command sent (the last safe command), deg.
    theta_c_deg: f64,
    /// P, I, D as of the last estimate, and G.
    terms: Terms,
    /// The error at the last estimate, for the derivative; `None` restarts it.
    last_error_deg: Option<f64>,
    /// The filtered derivative of the error, deg/s.
    error_rate_deg_per_s: f64,
    /// Time since the last finite estimate, s.
    estimate_age_s: f64,
    /// Whether the watchdog has tripped (cleared by the next estimate).
    tripped: bool,
    /// Direction of θ_d: +1, −1, or 0 before the first motion.
    direction: i8,
    /// θ_d's extreme since the last reversal (or θ_d at the first tick).
    extreme_deg: Option<f64>,
    /// Whether the last tick's output was limited, and which way the target
    /// lay beyond it (sign of target − command).
    limited_push: f64,
}

impl Compensator {
    /// A compensator at rest: last command 0 deg (clamped into the limits),
    /// no correction, G = 0, no estimate yet (the watchdog counts from here).
    ///
    /// # Errors
    /// As [`CompensatorConfig::validate`].
    pub fn new(config: CompensatorConfig) -> Result<Self> {
        config.validate()?;
        let mut c = Self {
            config,
            state: State::default(),
        };
        c.reset();
        Ok(c)
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &CompensatorConfig {
        &self.config
    }

    /// The last command returned (the one a fault holds), deg.
    #[must_use]
    pub fn theta_c_deg(&self) -> f64 {
        self.state.theta_c_deg
    }

    /// Back to the state [`Compensator::new`] gives.
    pub fn reset(&mut self) {
        self.state = State {
            theta_c_deg: 0.0f64.clamp(self.config.theta_c_min_deg, self.config.theta_c_max_deg),
            ..State::default()
        };
    }

    /// One control tick: θ_d and the estimate θ̂ (`None` when none arrived
    /// this tick), deg, and the tick's length `dt_s`, s. Returns the command
    /// θ_c of Eq. 3 with its terms. Never panics, never allocates, never
    /// returns a non-finite command; an invalid input holds the last
    /// command and is reported in [`CompensatorOutput::fault`] (see the
    /// [`Compensator`]).
    pub fn step(
        &mut self,
        theta_d_deg: f64,
        theta_hat_deg: Option<f64>,
        dt_s: f64,
    ) -> CompensatorOutput {
        if !theta_d_deg.is_finite() {
            return self.hold(Fault::NonFiniteDesired { value: theta_d_deg }, false);
        }
        if let Err(e) = Bounds::open_closed(0.0, MAX_STEP_S).check("dt_s", dt_s) {
            return self.hold(Fault::InvalidDt(e), false);
        }
        let c = self.config;
        let s = &mut self.state;
        s.estimate_age_s += dt_s;
        // Eq. 5: on a reversal of θ_d, G_t = −f_{t−1}
        let reversed = s.track_direction(theta_d_deg, c.direction_deadband_deg);
        if reversed {
            s.terms.g_deg = match c.backlash_term {
                BacklashTerm::Off => 0.0,
                // −f_{t−1}, with the integral moved into G (see `Compensator`'s docs)
                BacklashTerm::PidCorrection => {
                    let g = -(s.terms.p_deg + s.terms.d_deg);
                    s.terms.i_deg = 0.0;
                    g
                }
                BacklashTerm::TotalCorrection => -(s.terms.f_deg() + s.terms.g_deg),
            };
            if !s.terms.g_deg.is_finite() {
                s.terms.g_deg = 0.0;
            }
        }
        match theta_hat_deg.filter(|v| v.is_finite()) {
            Some(theta_hat) => {
                // the time this estimate's update spans: since the last one,
                // or this tick after a reset or a trip
                let span_s = if s.last_error_deg.is_some() {
                    s.estimate_age_s
                } else {
                    dt_s
                };
                s.update_pid(&c, theta_d_deg - theta_hat, span_s);
                s.estimate_age_s = 0.0;
                s.tripped = false;
            }
            None => {
                if s.tripped || s.estimate_age_s > c.watchdog_timeout_s {
                    // the PID restarts its derivative when estimates return
                    s.tripped = true;
                    s.last_error_deg = None;
                    s.error_rate_deg_per_s = 0.0;
                }
                let fault = match theta_hat_deg {
                    Some(value) => Some(Fault::NonFiniteEstimate { value }),
                    None if s.tripped => Some(Fault::Watchdog {
                        age_s: s.estimate_age_s,
                        timeout_s: c.watchdog_timeout_s,
                    }),
                    None => None,
                };
                if let Some(fault) = fault {
                    return self.hold(fault, reversed);
                }
            }
        }
        // Eq. 3, then the joint limits, then the rate limit
        let target = theta_d_deg + s.terms.f_deg() + s.terms.g_deg;
        let limited_target = if target.is_finite() {
            target.clamp(c.theta_c_min_deg, c.theta_c_max_deg)
        } else {
            // only with absurd gains and errors; hold rather than pass it on
            s.theta_c_deg
        };
        let step = c.rate_limit_deg_per_s * dt_s;
        let theta_c = limited_target.clamp(s.theta_c_deg - step, s.theta_c_deg + step);
        let limited = theta_c != target;
        s.limited_push = if limited && target.is_finite() {
            (target - theta_c).signum()
        } else {
            0.0
        };
        s.theta_c_deg = theta_c;
        CompensatorOutput {
            theta_c_deg: theta_c,
            fault: None,
            terms: s.terms,
            limited,
            estimate_age_s: s.estimate_age_s,
            reversed,
        }
    }

    /// The output of a tick that holds the last command.
    fn hold(&self, fault: Fault, reversed: bool) -> CompensatorOutput {
        CompensatorOutput {
            theta_c_deg: self.state.theta_c_deg,
            fault: Some(fault),
            terms: self.state.terms,
            limited: false,
            estimate_age_s: self.state.estimate_age_s,
            reversed,
        }
    }
}

impl State {
    /// Follows θ_d's direction; true on a reversal (see `Compensator`'s docs).
    fn track_direction(&mut self, theta_d_deg: f64, deadband_deg: f64) -> bool {
        let Some(extreme) = self.extreme_deg else {
            self.extreme_deg = Some(theta_d_deg);
            return false;
        };
        let moved = theta_d_deg - extreme;
        match self.direction {
            0 => {
                if moved.abs() > deadband_deg {
                    self.direction = if moved > 0.0 { 1 } else { -1 };
                    self.extreme_deg = Some(theta_d_deg);
                }
                false
            }
            d => {
                let along = f64::from(d) * moved;
                if along > 0.0 {
                    self.extreme_deg = Some(theta_d_deg);
                    false
                } else if -along > deadband_deg {
                    self.direction = -d;
                    self.extreme_deg = Some(theta_d_deg);
                    true
                } else {
                    false
                }
            }
        }
    }

    /// Eq. 4 for an estimate whose error is `error_deg`, `span_s` after the last one.
    fn update_pid(&mut self, c: &CompensatorConfig, error_deg: f64, span_s: f64) {
        // derivative of the error, low-passed; zero on the first estimate
        if let Some(last) = self.last_error_deg {
            let raw = (error_deg - last) / span_s;
            let alpha = span_s / (c.derivative_filter_s + span_s);
            self.error_rate_deg_per_s += alpha * (raw - self.error_rate_deg_per_s);
        }
        self.last_error_deg = Some(error_deg);
        // integral, unless the output is limited and the error pushes further out
        let frozen = c.freeze_integral_when_saturated && self.limited_push * error_deg > 0.0;
        if !frozen {
            self.terms.i_deg += c.ki_per_s * error_deg * span_s;
        }
        if let Some(limit) = c.integral_limit_deg {
            self.terms.i_deg = self.terms.i_deg.clamp(-limit, limit);
        }
        self.terms.p_deg = c.kp * error_deg;
        self.terms.d_deg = c.kd_s * self.error_rate_deg_per_s;
        // a term that overflowed is dropped rather than carried on
        for t in [
            &mut self.terms.p_deg,
            &mut self.terms.i_deg,
            &mut self.terms.d_deg,
        ] {
            if !t.is_finite() {
                *t = 0.0;
            }
        }
        if !self.error_rate_deg_per_s.is_finite() {
            self.error_rate_deg_per_s = 0.0;
        }
    }
}
