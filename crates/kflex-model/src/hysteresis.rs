//! Rate-independent hysteresis operators: Bouc–Wen and backlash (play).

use serde::{Deserialize, Serialize};

use crate::error::{Result, finite};
use crate::range::Bounds;

/// Parameters of the Bouc–Wen model.
///
/// The hysteretic state `z` obeys, per input increment `dx`,
/// ```text
/// dz = A dx − β |dx| |z|^(n−1) z − γ dx |z|^n
/// ```
/// and the operator's output is `α x + (1 − α) z`. For `β + γ > 0` and
/// `β ≥ |γ|`, `|z|` never exceeds `(A / (β + γ))^(1/n)` once inside that bound.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoucWenParams {
    /// `A`: initial slope `dz/dx` at `z = 0`.
    pub a: f64,
    /// `β`: shape of the loop on loading.
    pub beta: f64,
    /// `γ`: shape of the loop on unloading.
    pub gamma: f64,
    /// `n ≥ 1`: sharpness of the transition to saturation.
    pub n: f64,
    /// `α ∈ [0, 1]`: share of the output that is linear in the input.
    pub alpha: f64,
}

impl BoucWenParams {
    /// A normalised element whose `z` saturates at ±1 after about `3 δ` of travel:
    /// `A = 1/δ`, `β = γ = 1/(2δ)`, `n = 1`, `α = 0`. `δ` is the pre-sliding length.
    #[must_use]
    pub fn normalised(presliding: f64) -> Self {
        Self {
            a: 1.0 / presliding,
            beta: 0.5 / presliding,
            gamma: 0.5 / presliding,
            n: 1.0,
            alpha: 0.0,
        }
    }

    /// Checks the parameters: `A > 0`, `β + γ > 0`, `β ≥ |γ|`, `1 ≤ n ≤ 10`, `0 ≤ α ≤ 1`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter out of its range,
    /// in the order above (`bouc_wen.a`, `bouc_wen.beta + bouc_wen.gamma`,
    /// `bouc_wen.beta` (whose lower bound is |γ|), `bouc_wen.n`, `bouc_wen.alpha`); a
    /// NaN or infinite parameter is out of range.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Bounds::open(0.0, f64::INFINITY).check("bouc_wen.a", self.a)?;
        Bounds::open(0.0, f64::INFINITY)
            .check("bouc_wen.beta + bouc_wen.gamma", self.beta + self.gamma)?;
        Bounds::closed_open(self.gamma.abs(), f64::INFINITY).check("bouc_wen.beta", self.beta)?;
        Bounds::closed(1.0, 10.0).check("bouc_wen.n", self.n)?;
        Bounds::closed(0.0, 1.0).check("bouc_wen.alpha", self.alpha)?;
        Ok(())
    }

    /// The bound `(A / (β + γ))^(1/n)` on `|z|`.
    #[must_use]
    pub fn z_bound(&self) -> f64 {
        (self.a / (self.beta + self.gamma)).powf(1.0 / self.n)
    }
}

/// Bouc–Wen hysteresis operator with state, integrated in the input increment.
///
/// For `n = 1` each monotone increment is integrated exactly (the ODE in `x`
/// is piecewise linear in `z`); for other `n`, with classic RK4 sub-steps no
/// longer than [`BoucWen::MAX_SUBSTEP_FRACTION`] of the saturation length
/// `z_bound / A`. An increment longer than 40 saturation lengths ends on the
/// bound `±z_bound` (to below half an ulp, for every valid parameter set), so
/// one call costs at most 10⁴ sub-steps however far the input moves.
///
/// Both are driven by the *increment* of their input, not by time, so their
/// output depends only on the path the input took: sampling the same path at
/// a coarser or finer tick gives the same result (to the integrator's
/// tolerance for Bouc–Wen, exactly for play).
#[derive(Debug, Clone, PartialEq)]
pub struct BoucWen {
    params: BoucWenParams,
    x: f64,
    z: f64,
    max_substep: f64,
}

impl BoucWen {
    /// Sub-step length as a fraction of `z_bound / A` (the input travel to saturate).
    /// Short, because `|z|^n` is not smooth at `z = 0` for non-integer `n` and RK4
    /// loses order where `z` crosses zero.
    pub const MAX_SUBSTEP_FRACTION: f64 = 0.004;

    /// A new operator at `x = x0`, `z = 0`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter out of its range
    /// (see [`BoucWenParams::validate`]); [`ModelError::NonFinite`] for a NaN
    /// or infinite `x0`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn new(params: BoucWenParams, x0: f64) -> Result<Self> {
        params.validate()?;
        finite("bouc_wen.x0", x0)?;
        let max_substep = Self::MAX_SUBSTEP_FRACTION * params.z_bound() / params.a;
        Ok(Self {
            params,
            x: x0,
            z: 0.0,
            max_substep,
        })
    }

    /// Parameters.
    #[must_use]
    pub fn params(&self) -> &BoucWenParams {
        &self.params
    }

    /// Current hysteretic state `z`.
    #[must_use]
    pub fn z(&self) -> f64 {
        self.z
    }

    /// Last input.
    #[must_use]
    pub fn x(&self) -> f64 {
        self.x
    }

    /// Output `α x + (1 − α) z`.
    #[must_use]
    pub fn output(&self) -> f64 {
        self.params.alpha * self.x + (1.0 - self.params.alpha) * self.z
    }

    /// Resets to input `x0`, `z = 0`.
    pub fn reset(&mut self, x0: f64) {
        self.x = x0;
        self.z = 0.0;
    }

    /// Moves the input to `x` along a straight path and returns the new output.
    /// A non-finite `x` leaves the state unchanged and is an error.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `x`.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn advance(&mut self, x: f64) -> Result<f64> {
        finite("bouc_wen.x", x)?;
        self.z = self.peek(x);
        self.x = x;
        Ok(self.output())
    }

    /// The state `z` and its slope `dz/dx` after moving to `x` from the current
    /// state, without moving. The slope is the ODE's right-hand side at the new
    /// state (the derivative of the flow along the input); at `x` equal to the
    /// current input, the mean of the two one-sided slopes.
    pub(crate) fn trial(&self, x: f64) -> (f64, f64) {
        let dx = x - self.x;
        let z = self.peek(x);
        let slope = if dx > 0.0 {
            self.slope(z, 1.0)
        } else if dx < 0.0 {
            self.slope(z, -1.0)
        } else {
            0.5 * (self.slope(z, 1.0) + self.slope(z, -1.0))
        };
        (z, slope)
    }

    /// Sets input and state directly (a state reached by a history not replayed here).
    pub(crate) fn set_state(&mut self, x: f64, z: f64) {
        self.x = x;
        self.z = z;
    }

    /// The state `z` after moving to `x` from the current state (the current `z`
    /// for a non-finite `x`). Between finite inputs `dx` may still overflow to
    /// ±∞ (from −1e308 to 1e308): an infinite travel, which saturates.
    fn peek(&self, x: f64) -> f64 {
        let dx = x - self.x;
        if dx == 0.0 || !x.is_finite() {
            self.z
        } else if self.params.n == 1.0 {
            self.exact_n1(self.z, dx)
        } else {
            self.rk4(self.z, dx)
        }
    }

    /// `dz/dx` at state `z` for motion in direction `sign` (±1).
    fn slope(&self, z: f64, sign: f64) -> f64 {
        let p = &self.params;
        let zn = if p.n == 1.0 {
            z.abs()
        } else if p.n.fract() == 0.0 {
            z.abs().powi(p.n as i32)
        } else {
            z.abs().powf(p.n)
        };
        p.a - (p.beta * sign * z.signum() + p.gamma) * zn
    }

    /// Travel, in saturation lengths `L = z_bound / A`, after which `z` sits on
    /// its bound to within `e^{-39}` of it (below half an ulp), wherever in
    /// `[−z_bound, z_bound]` it started, for every valid parameter set.
    ///
    /// Why, and why the approach is monotone: with `u = sign(dx)·z` and the
    /// travelled distance `s = |dx|`, the ODE is autonomous,
    /// `du/ds = f(u) = A − (β sgn(u) + γ) |u|^n`. For `u < 0`,
    /// `f(u) = A + (β − γ)|u|^n ≥ A > 0` because `β ≥ |γ| ≥ γ`; for `u ≥ 0`,
    /// `f(u) = A − (β + γ) u^n` with `β + γ > 0` falls strictly from `A` through
    /// zero at `u* = z_bound`. So `u*` is the one equilibrium, `f > 0` below it
    /// and `f < 0` above it, and a solution of a scalar autonomous ODE cannot
    /// cross an equilibrium: `u` moves monotonically onto `u*` from either
    /// side, whatever the sign of `γ` (γ < 0 only speeds up the `u < 0` leg).
    /// How long it takes: from `u ≥ −u*` to `0` takes at most `L` (as
    /// `f ≥ A`); from `0` to `u*(1 − ε)`, writing `w = u/u*`,
    /// `s/L = ∫ dw/(1 − wⁿ) ≤ ∫ dw/(1 − w) = ln(1/ε)` since `wⁿ ≤ w` for
    /// `n ≥ 1`. Hence after `40 L`, `ε ≤ e^{-39} ≈ 1e-17`.
    ///
    /// This is a property of the ODE. The RK4 sub-steps are sized for the
    /// loading leg; where γ is close to −β the unloading leg is up to
    /// `2β/(β + γ)` times `A` steep, and RK4 may then step past the bound
    /// before settling back onto it.
    const SATURATED_AFTER: f64 = 40.0;

    /// RK4 in sub-steps of at most `max_substep`. The work is bounded
    /// independently of `|dx|`: beyond [`Self::SATURATED_AFTER`] saturation
    /// lengths the answer is the bound itself, so at most
    /// `SATURATED_AFTER / MAX_SUBSTEP_FRACTION` (10⁴) sub-steps are taken, and
    /// fewer once `z` has settled, i.e. once a sub-step leaves it unchanged:
    /// every further sub-step would then repeat that same step, so stopping
    /// there gives bit-for-bit the result of taking them all.
    fn rk4(&self, mut z: f64, dx: f64) -> f64 {
        let sign = dx.signum();
        let bound = self.params.z_bound();
        if dx.abs() * self.params.a > Self::SATURATED_AFTER * bound {
            // settled onto the bound (see SATURATED_AFTER): monotone for every valid γ
            return sign * bound;
        }
        let steps = (dx.abs() / self.max_substep).ceil().max(1.0);
        let h = dx / steps;
        for _ in 0..steps as u64 {
            let k1 = self.slope(z, sign);
            let k2 = self.slope(z + 0.5 * h * k1, sign);
            let k3 = self.slope(z + 0.5 * h * k2, sign);
            let k4 = self.slope(z + h * k3, sign);
            let next = z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            if next == z {
                break;
            }
            z = next;
        }
        z
    }

    /// Exact solution for `n = 1`. With `u = sign(dx)·z` and the travelled
    /// distance `s = |dx|`, the ODE is `du/ds = A − c u` with `c = β + γ` for
    /// `u ≥ 0` and `c = β − γ` for `u < 0`: an exponential approach on each side
    /// of `u = 0`, joined where `u` crosses zero.
    fn exact_n1(&self, z: f64, dx: f64) -> f64 {
        let p = &self.params;
        let sign = dx.signum();
        let mut s = dx.abs();
        let mut u = sign * z;
        if p.gamma == 0.0 {
            // both sides of u = 0 share c = β (Dahl's law): one exponential
            let u_inf = p.a / p.beta;
            return sign * (u_inf + (u - u_inf) * (-p.beta * s).exp());
        }
        if u < 0.0 {
            let c = p.beta - p.gamma; // ≥ 0 by validation
            // distance travelled until u reaches 0
            let s0 = if c < 1e-12 * p.a {
                -u / p.a
            } else {
                ((p.a - c * u) / p.a).ln() / c
            };
            if s <= s0 {
                u = if c < 1e-12 * p.a {
                    u + p.a * s
                } else {
                    p.a / c + (u - p.a / c) * (-c * s).exp()
                };
                return sign * u.min(0.0);
            }
            s -= s0;
            u = 0.0;
        }
        let c = p.beta + p.gamma;
        let u_inf = p.a / c;
        u = u_inf + (u - u_inf) * (-c * s).exp();
        sign * u
    }
}

/// Backlash (play) operator of half-width `r`: the output stays put until the
/// input has moved `r` past it, then follows at distance `r`.
/// `y ← max(x − r, min(x + r, y))`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Play {
    half_width: f64,
    y: f64,
}

impl Play {
    /// A play operator of half-width `half_width ≥ 0`, output starting at `y0`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `play.half_width` when it is negative,
    /// NaN or infinite; [`ModelError::NonFinite`] for a NaN or infinite `y0`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn new(half_width: f64, y0: f64) -> Result<Self> {
        Bounds::closed(0.0, f64::MAX).check("play.half_width", half_width)?;
        finite("play.y0", y0)?;
        Ok(Self { half_width, y: y0 })
    }

    /// Half-width `r`.
    #[must_use]
    pub fn half_width(&self) -> f64 {
        self.half_width
    }

    /// Current output.
    #[must_use]
    pub fn output(&self) -> f64 {
        self.y
    }

    /// Resets the output to `y0`.
    pub fn reset(&mut self, y0: f64) {
        self.y = y0;
    }

    /// Moves the input to `x`, returns the output. Non-finite `x` is an error and changes nothing.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `x`.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn advance(&mut self, x: f64) -> Result<f64> {
        finite("play.x", x)?;
        self.y = (x - self.half_width).max((x + self.half_width).min(self.y));
        Ok(self.y)
    }
}

/// A gear backlash whose flanks take up the load over a short travel: the
/// output stays put until the input has crossed the gap, then the flanks
/// engage over the travel `ε` (`dy/dx` rising from 0 to 1 as `1 − e^{−s/ε}`),
/// and the output follows at the half-width `r`. With `ε = 0` it is the
/// ideal [`Play`]; either way the lost motion after a reversal tends to `2r`.
/// Rate-independent and exact for any increment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backlash {
    half_width: f64,
    engagement: f64,
    x: f64,
    y: f64,
}

impl Backlash {
    /// Half-width `r ≥ 0`, engagement travel `ε ≥ 0`; input and output at 0.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `backlash.half_width` or
    /// `backlash.engagement` when negative, NaN or infinite.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn new(half_width: f64, engagement: f64) -> Result<Self> {
        Bounds::closed(0.0, f64::MAX).check("backlash.half_width", half_width)?;
        Bounds::closed(0.0, f64::MAX).check("backlash.engagement", engagement)?;
        Ok(Self {
            half_width,
            engagement,
            x: 0.0,
            y: 0.0,
        })
    }

    /// Current output.
    #[must_use]
    pub fn output(&self) -> f64 {
        self.y
    }

    /// Input at `x0`, output at `x0 + offset` (`offset` clamped into the gap `[−r, r]`).
    pub fn reset(&mut self, x0: f64, offset: f64) {
        self.x = x0;
        self.y = x0 + offset.clamp(-self.half_width, self.half_width);
    }

    /// Moves the input to `x`, returns the output. Non-finite `x` is an error and changes nothing.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `x`.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn advance(&mut self, x: f64) -> Result<f64> {
        finite("backlash.x", x)?;
        let dx = x - self.x;
        if dx == 0.0 {
            return Ok(self.y);
        }
        let (r, eps) = (self.half_width, self.engagement);
        let sign = dx.signum();
        // gap in the direction of motion, and the travel left
        let mut gap = sign * (self.x - self.y);
        let mut travel = dx.abs();
        let knee = r - eps;
        if gap < knee {
            let free = (knee - gap).min(travel);
            gap += free;
            travel -= free;
        }
        if travel > 0.0 {
            // engaged: d(gap)/dx = (r − gap)/ε
            gap = if eps > 0.0 {
                r - (r - gap) * (-travel / eps).exp()
            } else {
                r
            };
        }
        self.x = x;
        self.y = x - sign * gap.min(r);
        Ok(self.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ModelError;
    use proptest::prelude::*;

    fn sine_path(amp: f64, samples_per_period: usize, periods: usize) -> Vec<f64> {
        (0..=samples_per_period * periods)
            .map(|k| amp * (std::f64::consts::TAU * k as f64 / samples_per_period as f64).sin())
            .collect()
    }

    fn params_set() -> Vec<BoucWenParams> {
        vec![
            BoucWenParams {
                a: 1.0,
                beta: 0.5,
                gamma: 0.5,
                n: 1.0,
                alpha: 0.0,
            },
            BoucWenParams {
                a: 1.0,
                beta: 0.7,
                gamma: 0.3,
                n: 2.0,
                alpha: 0.2,
            },
            BoucWenParams {
                a: 2.0,
                beta: 1.2,
                gamma: -0.4,
                n: 1.5,
                alpha: 0.0,
            },
            BoucWenParams {
                a: 3.0,
                beta: 1.0,
                gamma: 0.0,
                n: 1.0,
                alpha: 0.5,
            },
        ]
    }

    #[test]
    fn rejects_bad_parameters() {
        use crate::error::expect_range;
        for (bad, name) in [
            (
                BoucWenParams {
                    a: -1.0,
                    ..BoucWenParams::normalised(1.0)
                },
                "bouc_wen.a",
            ),
            (
                BoucWenParams {
                    beta: 0.1,
                    gamma: 0.5,
                    ..BoucWenParams::normalised(1.0)
                },
                "bouc_wen.beta",
            ),
            (
                BoucWenParams {
                    n: 0.5,
                    ..BoucWenParams::normalised(1.0)
                },
                "bouc_wen.n",
            ),
            (
                BoucWenParams {
                    alpha: 1.5,
                    ..BoucWenParams::normalised(1.0)
                },
                "bouc_wen.alpha",
            ),
            (
                BoucWenParams {
                    a: f64::NAN,
                    ..BoucWenParams::normalised(1.0)
                },
                "bouc_wen.a",
            ),
        ] {
            expect_range(BoucWen::new(bad, 0.0), name);
        }
        let e = expect_range(
            BoucWen::new(
                BoucWenParams {
                    beta: 0.1,
                    gamma: 0.5,
                    ..BoucWenParams::normalised(1.0)
                },
                0.0,
            ),
            "bouc_wen.beta",
        );
        assert_eq!((e.value, e.bounds.min), (0.1, 0.5));
        let e = expect_range(Play::new(-1.0, 0.0), "play.half_width");
        assert_eq!(e.value, -1.0);
        // the message names the bound in scientific notation, not 309 digits
        let msg = Play::new(-1.0, 0.0).unwrap_err().to_string();
        assert!(msg.ends_with("[0, 1.7976931348623157e308]"), "{msg}");
        // and so does the message for a half-width too large for a float
        assert_eq!(
            Play::new(f64::INFINITY, 0.0).unwrap_err().to_string(),
            "play.half_width = inf is out of range: must be in [0, 1.7976931348623157e308]"
        );
    }

    #[test]
    fn non_finite_input_changes_nothing() {
        let mut bw = BoucWen::new(BoucWenParams::normalised(0.1), 0.0).unwrap();
        bw.advance(0.05).unwrap();
        let before = bw.clone();
        assert!(matches!(
            bw.advance(f64::NAN),
            Err(ModelError::NonFinite { value, .. }) if value.is_nan()
        ));
        assert_eq!(bw, before);
    }

    #[test]
    fn exact_n1_matches_rk4() {
        // The closed form must agree with fine RK4 of the same ODE, including
        // the reversal leg that starts from negative u.
        for p in [
            params_set()[0],
            params_set()[3],
            BoucWenParams {
                a: 1.0,
                beta: 0.9,
                gamma: 0.1,
                n: 1.0,
                alpha: 0.0,
            },
        ] {
            let exact = BoucWen::new(p, 0.0).unwrap();
            // a much finer RK4 than the operator's own, so the kink of the
            // slope at z = 0 costs less than the tolerance
            let fine = BoucWen {
                max_substep: 1e-5,
                ..exact.clone()
            };
            for (z0, dx) in [
                (0.0, 0.7),
                (0.8, -0.3),
                (-0.9, 2.0),
                (0.3, -5.0),
                (-0.2, 0.01),
            ] {
                let ze = exact.exact_n1(z0, dx);
                let zr = fine.rk4(z0, dx);
                assert!(
                    (ze - zr).abs() < 1e-10,
                    "{p:?} z0={z0} dx={dx}: {ze} vs {zr}"
                );
            }
        }
    }

    /// A = 1, β = 1, γ = −0.5, n = 2.5: γ < 0 and n ≠ 1, integrated by RK4.
    fn negative_gamma() -> BoucWenParams {
        BoucWenParams {
            a: 1.0,
            beta: 1.0,
            gamma: -0.5,
            n: 2.5,
            alpha: 0.0,
        }
    }

    #[test]
    fn huge_increment_with_negative_gamma_lands_on_the_bound() {
        // used to take RK4 sub-steps in proportion to |dx|: hours for 1e9
        let p = negative_gamma();
        let bound = p.z_bound();
        let mut bw = BoucWen::new(p, 0.0).unwrap();
        assert!((bw.advance(1e9).unwrap() - bound).abs() < 1e-9);
        assert!((bw.advance(-1e9).unwrap() + bound).abs() < 1e-9);
        assert!((bw.advance(1e4).unwrap() - bound).abs() < 1e-9);
    }

    #[test]
    fn an_increment_that_overflows_still_saturates() {
        // x − x_prev = 2e308 overflows to ∞ though both inputs are finite
        for p in [negative_gamma(), params_set()[0]] {
            let mut bw = BoucWen::new(p, -1e308).unwrap();
            bw.advance(1e308).unwrap();
            assert_eq!(bw.z(), p.z_bound(), "{p:?}");
            bw.advance(-1e308).unwrap();
            assert_eq!(bw.z(), -p.z_bound(), "{p:?}");
        }
    }

    #[test]
    fn saturation_shortcut_agrees_with_integration() {
        // From the far bound, 40 saturation lengths integrated in short legs
        // (each integrated, none long enough for the shortcut) end on the
        // bound, as the shortcut for one long leg says, also for γ < 0.
        for p in [
            negative_gamma(),
            params_set()[1],
            params_set()[2],
            BoucWenParams {
                a: 0.5,
                beta: 1.0,
                gamma: -0.6,
                n: 1.5,
                alpha: 0.0,
            },
            BoucWenParams {
                a: 2.0,
                beta: 0.3,
                gamma: -0.2,
                n: 10.0,
                alpha: 0.0,
            },
        ] {
            let bound = p.z_bound();
            let length = bound / p.a;
            let mut legs = BoucWen::new(p, 0.0).unwrap();
            legs.advance(-41.0 * length).unwrap();
            assert_eq!(legs.z(), -bound, "{p:?}: the shortcut lands on the bound");
            let mut prev = legs.z();
            for k in 1..=40 {
                legs.advance(-41.0 * length + f64::from(k) * length)
                    .unwrap();
                assert!(legs.z() >= prev, "{p:?}: monotone approach");
                prev = legs.z();
            }
            assert!(
                (legs.z() - bound).abs() <= 1e-12 * bound,
                "{p:?}: {} vs {bound}",
                legs.z()
            );
        }
    }

    #[test]
    fn rk4_stops_early_only_where_that_changes_nothing() {
        // the operator's RK4 (which stops once a sub-step leaves z unchanged)
        // against the same sub-steps all taken
        let p = negative_gamma();
        let bw = BoucWen::new(p, 0.0).unwrap();
        let bound = p.z_bound();
        let length = bound / p.a;
        for (z0, dx) in [
            (0.0, 0.3 * length),
            (-bound, 2.0 * length),
            (0.5 * bound, -5.0 * length),
            (-0.9 * bound, 39.9 * length),
            (0.2 * bound, -30.0 * length),
        ] {
            let sign = dx.signum();
            let steps = (dx.abs() / bw.max_substep).ceil();
            let h = dx / steps;
            let mut z = z0;
            for _ in 0..steps as u64 {
                let k1 = bw.slope(z, sign);
                let k2 = bw.slope(z + 0.5 * h * k1, sign);
                let k3 = bw.slope(z + 0.5 * h * k2, sign);
                let k4 = bw.slope(z + h * k3, sign);
                z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            }
            assert_eq!(bw.rk4(z0, dx).to_bits(), z.to_bits(), "z0={z0} dx={dx}");
        }
    }

    #[test]
    fn loops_close_under_periodic_input() {
        for p in params_set() {
            let mut bw = BoucWen::new(p, 0.0).unwrap();
            let path = sine_path(3.0, 200, 6);
            let mut outs = Vec::new();
            for &x in &path {
                outs.push(bw.advance(x).unwrap());
            }
            // after the first cycle's transient, successive cycles coincide
            let (c4, c5) = (&outs[800..1000], &outs[1000..1200]);
            let worst = c4
                .iter()
                .zip(c5)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{p:?}: cycles differ by {worst}");
            // and the loop has area: rising and falling outputs differ at x = 0
            assert!(
                (outs[1000] - outs[1100]).abs() > 0.05,
                "{p:?}: no hysteresis"
            );
        }
    }

    #[test]
    fn play_has_the_right_width() {
        let mut play = Play::new(0.5, 0.0).unwrap();
        assert_eq!(play.advance(0.4).unwrap(), 0.0); // inside the gap
        assert_eq!(play.advance(2.0).unwrap(), 1.5); // dragged
        assert_eq!(play.advance(1.2).unwrap(), 1.5); // reversal: dead zone of 2r
        assert_eq!(play.advance(0.0).unwrap(), 0.5);
    }

    proptest! {
        #[test]
        fn z_stays_within_bound(idx in 0usize..4, xs in prop::collection::vec(-20.0f64..20.0, 1..200)) {
            let p = params_set()[idx];
            let mut bw = BoucWen::new(p, 0.0).unwrap();
            for x in xs {
                bw.advance(x).unwrap();
                prop_assert!(bw.z().abs() <= p.z_bound() * (1.0 + 1e-9), "{} > {}", bw.z(), p.z_bound());
            }
        }

        #[test]
        fn rate_independent(idx in 0usize..4, amp in 0.1f64..5.0, fine in 2usize..9) {
            // The same path sampled at 100 and at 100·fine points per period (turning
            // points on samples) ends in the same state.
            let p = params_set()[idx];
            let mut coarse = BoucWen::new(p, 0.0).unwrap();
            let mut dense = BoucWen::new(p, 0.0).unwrap();
            for x in sine_path(amp, 100, 2) { coarse.advance(x).unwrap(); }
            for x in sine_path(amp, 100 * fine, 2) { dense.advance(x).unwrap(); }
            prop_assert!((coarse.z() - dense.z()).abs() < 1e-7, "{} vs {}", coarse.z(), dense.z());
        }

        #[test]
        fn play_output_within_half_width(xs in prop::collection::vec(-10.0f64..10.0, 1..100), r in 0.0f64..2.0) {
            let mut play = Play::new(r, 0.0).unwrap();
            for x in xs {
                let y = play.advance(x).unwrap();
                prop_assert!((x - y).abs() <= r + 1e-12);
            }
        }
    }

    #[test]
    fn backlash_is_the_play_without_engagement_and_rounds_it_with() {
        let path: Vec<f64> = sine_path(2.0, 400, 3);
        let mut play = Play::new(0.5, 0.0).unwrap();
        let mut sharp = Backlash::new(0.5, 0.0).unwrap();
        for &x in &path {
            assert!((play.advance(x).unwrap() - sharp.advance(x).unwrap()).abs() < 1e-12);
        }
        // with engagement: same lost motion far from a reversal, a smooth slope near it
        let mut round = Backlash::new(0.5, 0.1).unwrap();
        let mut play = Play::new(0.5, 0.0).unwrap();
        let (mut last_y, mut last_x, mut last_slope) = (0.0, 0.0, 0.0f64);
        for k in 0..=2000 {
            let x = 0.002 * f64::from(k);
            let y = round.advance(x).unwrap();
            let p = play.advance(x).unwrap();
            assert!(
                y >= p - 1e-12,
                "the flanks meet before the ideal play would: never behind it"
            );
            if k > 0 {
                let slope = (y - last_y) / (x - last_x);
                assert!((0.0..=1.0 + 1e-9).contains(&slope));
                assert!(
                    slope - last_slope < 0.05,
                    "no step in the slope at {x}: {last_slope} -> {slope}"
                );
                last_slope = slope;
            }
            (last_y, last_x) = (y, x);
        }
        assert!(
            (last_y - (last_x - 0.5)).abs() < 1e-6,
            "follows at r once engaged"
        );
        assert!(matches!(
            round.advance(f64::NAN),
            Err(ModelError::NonFinite { .. })
        ));
        assert!(Backlash::new(-1.0, 0.0).is_err() && Backlash::new(1.0, f64::NAN).is_err());
    }
}
