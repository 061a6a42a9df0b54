//! Tendon-sheath transmission of the antagonistic tendon pair (lumped, quasi-static).
//!
//! The motors set the proximal differential stroke `q` of the pair (mm). On its
//! way to the joint the motion passes
//!
//! 1. the drive's backlash: a [`Play`] of half-width `drive_backlash_mm`;
//! 2. the sheath: Coulomb friction between tendon and sheath, whose direction
//!    follows the tendon's sliding through a normalised [`BoucWen`] state
//!    `z ∈ [−1, 1]` (pre-sliding length `presliding_mm`);
//! 3. the tendons' elasticity: differential stiffness `k` (N/mm).
//!
//! **Capstan law.** A tendon sliding over a curve of total wrap angle `Φ` with
//! friction coefficient `μ` carries `T_p = T_d e^{±μΦ}` (proximal vs distal
//! tension; `+` when it is pulled in, `−` when it is paid out). The friction on
//! each tendon is therefore `T_d (e^{μΦ} − 1)` when pulled and `T_d (1 − e^{−μΦ})`
//! when released. With distal tensions `T_a = T₀ + F/2`, `T_b = T₀ − F/2`
//! (pretension `T₀`, differential force `F`), summing both tendons' friction and
//! solving the force balance `F = k (q_b − p) − friction − F_c z` for `F` gives
//! ```text
//!       k (q_b − p) − (2 T₀ sinh(μΦ) + F_c) z
//! F = ─────────────────────────────────────────
//!            1 + (cosh(μΦ) − 1) |z|
//! ```
//! where `p` is the distal differential stroke (set by the joint angle) and
//! `Φ = Φ_sheath + Φ_route`: the sheath configuration plus the wrap the tendons
//! already have in the instrument's own routing. The numerator's second term
//! is the hysteresis (its sign flips with the direction of sliding); the
//! denominator is the lost motion (the tendon's effective stiffness falls as
//! the sheath bends). Both grow with `Φ` by the mechanism, not a table.
//!
//! **Slack.** A tendon cannot push. The elastic differential force of the pair
//! is `E(δ) = kδ` while both tendons are taut (`|kδ| ≤ 2T₀`, `δ = q_b − p`) and
//! `sign(δ)(T₀ + k|δ|/2)` once one goes slack (only one tendon, of stiffness
//! `k/2`, still pulls). At the joint, the tensions are `T_a = max(T₀ + F/2, F, 0)`
//! and `T_b = T_a − F`; the friction is computed from those tensions, so the
//! balance is piecewise linear in `F` and solved regime by regime (the map
//! `F ↦ F + friction(F)` is increasing, so exactly one regime is consistent).
//! In the taut regime this is the closed form above.
//!
//! Assumptions, stated so they can be revisited: the common-mode path change of
//! Eq. 1 is absorbed by the tendons' compliance, and the transmission is
//! quasi-static (inertia of tendons and motors neglected; the paper's test
//! input is 0.159 Hz).

use serde::{Deserialize, Serialize};

use crate::error::{Result, closed_range, open_range};
use crate::hysteresis::{BoucWen, BoucWenParams, Play};

/// Parameters of the tendon-sheath transmission. Forces in N, lengths in mm, angles in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SheathParams {
    /// Friction coefficient `μ` between tendon and sheath (dimensionless).
    pub friction_coefficient: f64,
    /// Wrap angle the tendons already have inside the instrument (routing, guides), deg.
    pub route_wrap_deg: f64,
    /// Pretension `T₀` of each tendon, N.
    pub pretension_n: f64,
    /// Differential stiffness `k` of the tendon pair over its whole length, N/mm.
    pub tendon_stiffness_n_per_mm: f64,
    /// Load-independent Coulomb friction `F_c` (seals, guides, joint), N.
    pub coulomb_friction_n: f64,
    /// Pre-sliding length of the friction (travel over which it reverses), mm.
    pub presliding_mm: f64,
    /// Half-width of the drive's backlash (motor coupling), mm of tendon stroke.
    pub drive_backlash_mm: f64,
}

impl Default for SheathParams {
    /// Defaults fitted to Table IX's uncompensated row (see the crate docs for the fit).
    fn default() -> Self {
        crate::calibration::FITTED_SHEATH
    }
}

impl SheathParams {
    /// Checks every parameter against its physical range.
    pub fn validate(&self) -> Result<()> {
        closed_range("friction_coefficient", self.friction_coefficient, 0.0, 2.0)?;
        closed_range("route_wrap_deg", self.route_wrap_deg, 0.0, 3600.0)?;
        open_range("pretension_n", self.pretension_n, 0.0, 1e4)?;
        open_range(
            "tendon_stiffness_n_per_mm",
            self.tendon_stiffness_n_per_mm,
            0.0,
            1e6,
        )?;
        closed_range("coulomb_friction_n", self.coulomb_friction_n, 0.0, 1e4)?;
        open_range("presliding_mm", self.presliding_mm, 0.0, 100.0)?;
        closed_range("drive_backlash_mm", self.drive_backlash_mm, 0.0, 100.0)?;
        Ok(())
    }
}

/// The stateful transmission for one sheath configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct TendonSheath {
    params: SheathParams,
    sheath_deg: f64,
    /// `2 T₀ sinh(μΦ) + F_c`, N.
    friction_amplitude: f64,
    /// `cosh(μΦ) − 1`.
    lost_motion: f64,
    /// `e^{μΦ} − 1` and `1 − e^{−μΦ}`, for the individual tensions.
    e_pull: f64,
    e_release: f64,
    play: Play,
    friction: BoucWen,
}

/// Tensions in the two tendons, N.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TendonTensions {
    /// Tendon `a`, at the joint (distal end).
    pub a_distal_n: f64,
    /// Tendon `b`, at the joint.
    pub b_distal_n: f64,
    /// Tendon `a`, at the motor (proximal end).
    pub a_proximal_n: f64,
    /// Tendon `b`, at the motor.
    pub b_proximal_n: f64,
}

impl TendonSheath {
    /// A transmission through a sheath bent by `sheath_deg` (any angle ≥ 0), at rest with zero stroke.
    pub fn new(params: SheathParams, sheath_deg: f64) -> Result<Self> {
        params.validate()?;
        let play = Play::new(params.drive_backlash_mm, 0.0)?;
        let friction = BoucWen::new(BoucWenParams::normalised(params.presliding_mm), 0.0)?;
        let mut out = Self {
            params,
            sheath_deg: 0.0,
            friction_amplitude: 0.0,
            lost_motion: 0.0,
            e_pull: 0.0,
            e_release: 0.0,
            play,
            friction,
        };
        out.set_sheath_deg(sheath_deg)?;
        Ok(out)
    }

    /// Changes the sheath configuration (total bend, deg) keeping the friction state.
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        closed_range("sheath_deg", sheath_deg, 0.0, 3600.0)?;
        let p = &self.params;
        let mu_phi = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians();
        self.sheath_deg = sheath_deg;
        self.friction_amplitude = 2.0 * p.pretension_n * mu_phi.sinh() + p.coulomb_friction_n;
        self.lost_motion = mu_phi.cosh() - 1.0;
        self.e_pull = mu_phi.exp() - 1.0;
        self.e_release = 1.0 - (-mu_phi).exp();
        Ok(())
    }

    /// Sheath bend, deg.
    pub fn sheath_deg(&self) -> f64 {
        self.sheath_deg
    }

    /// Parameters.
    pub fn params(&self) -> &SheathParams {
        &self.params
    }

    /// Resets the friction and backlash state (tendons at rest at stroke `q`).
    pub fn reset(&mut self, q: f64) {
        self.play.reset(q);
        self.friction.reset(q);
    }

    /// Moves the motors' differential stroke to `q` (mm) and updates the friction state.
    pub fn advance(&mut self, q: f64) -> Result<()> {
        let q_b = self.play.advance(q)?;
        self.friction.advance(q_b)?;
        Ok(())
    }

    /// Friction direction state `z ∈ [−1, 1]` (+1: sliding as when tendon `a` is pulled in).
    pub fn z(&self) -> f64 {
        self.friction.z()
    }

    /// Stroke after the drive's backlash, mm.
    pub fn stroke_after_backlash(&self) -> f64 {
        self.play.output()
    }

    /// Elastic differential force of the pair `E(δ)` (N) and its slope, with slack.
    fn elastic(&self, delta: f64) -> (f64, f64) {
        let k = self.params.tendon_stiffness_n_per_mm;
        let t0 = self.params.pretension_n;
        if (k * delta).abs() <= 2.0 * t0 {
            (k * delta, k)
        } else {
            (delta.signum() * (t0 + 0.5 * k * delta.abs()), 0.5 * k)
        }
    }

    /// The joint-side state of the tendons when the joint's distal stroke is `p` (mm).
    pub fn distal(&self, p: f64) -> Distal {
        let z = self.friction.z();
        let (zp, zn) = (z.max(0.0), (-z).max(0.0));
        let (e, de) = self.elastic(self.play.output() - p);
        let rhs = e - self.params.coulomb_friction_n * z;
        let t0 = self.params.pretension_n;
        // friction = c_a T_a + c_b T_b: coefficient of each tendon's tension
        let c_a = zp * self.e_pull - zn * self.e_release;
        let c_b = zp * self.e_release - zn * self.e_pull;
        // taut: T_a = T0 + F/2, T_b = T0 − F/2
        let taut_den = 1.0 + 0.5 * (c_a - c_b);
        let force = (rhs - t0 * (c_a + c_b)) / taut_den;
        let (force, den) = if force.abs() <= 2.0 * t0 {
            (force, taut_den)
        } else if force > 0.0 {
            // b slack: T_a = F, T_b = 0
            let den = 1.0 + c_a;
            (rhs / den, den)
        } else {
            // a slack: T_a = 0, T_b = −F
            let den = 1.0 - c_b;
            (rhs / den, den)
        };
        Distal {
            force_n: force,
            slope_n_per_mm: -de / den,
            tension_sum_n: (2.0 * t0).max(force.abs()),
        }
    }

    /// Differential distal force `F = T_a − T_b` (N) when the joint's distal stroke is `p` (mm).
    pub fn distal_force(&self, p: f64) -> f64 {
        self.distal(p).force_n
    }

    /// Stiffness of the taut pair as seen from the joint, `−dF/dp` at rest (N/mm), an upper bound.
    pub fn taut_stiffness(&self) -> f64 {
        self.params.tendon_stiffness_n_per_mm
    }

    /// Tensions at both ends for distal differential force `force_n`.
    pub fn tensions(&self, force_n: f64) -> TendonTensions {
        let t0 = self.params.pretension_n;
        let a = (t0 + 0.5 * force_n).max(force_n).max(0.0);
        let b = a - force_n;
        let z = self.friction.z();
        let (zp, zn) = (z.max(0.0), (-z).max(0.0));
        TendonTensions {
            a_distal_n: a,
            b_distal_n: b,
            a_proximal_n: a * (1.0 + self.e_pull * zp - self.e_release * zn),
            b_proximal_n: b * (1.0 + self.e_pull * zn - self.e_release * zp),
        }
    }
}

/// The tendons at the joint for one distal stroke.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distal {
    /// Differential force `T_a − T_b`, N.
    pub force_n: f64,
    /// `dF/dp`, N/mm (negative).
    pub slope_n_per_mm: f64,
    /// `T_a + T_b`, N: `max(2T₀, |F|)`.
    pub tension_sum_n: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quasi-static loop of the transmission against a linear spring joint
    /// `F = K p`: returns the half-gap between the loading and unloading
    /// branches at mid-stroke (mm of distal stroke).
    fn loop_half_gap(sheath_deg: f64) -> f64 {
        // explicit, moderate parameters: this tests the mechanism, not the calibration
        let params = SheathParams {
            friction_coefficient: 0.2,
            route_wrap_deg: 10.0,
            pretension_n: 5.0,
            tendon_stiffness_n_per_mm: 30.0,
            coulomb_friction_n: 1.0,
            presliding_mm: 0.04,
            drive_backlash_mm: 0.0,
        };
        let mut t = TendonSheath::new(params, sheath_deg).unwrap();
        let joint_k = 5.0; // N/mm
        let solve = |t: &TendonSheath| -> f64 {
            // F(p) = K p, F linear in p: closed form
            // F(p) = K p; F is piecewise linear in p, so two Newton steps solve it
            let mut p = 0.0;
            for _ in 0..4 {
                let d = t.distal(p);
                p -= (d.force_n - joint_k * p) / (d.slope_n_per_mm - joint_k);
            }
            p
        };
        // second cycle: rising from k = 300 (q = −1) to 500 (q = 1), falling to 700;
        // q(500 + m) = q(500 − m), so the two branches meet at equal stroke
        let mut p = vec![0.0; 701];
        for (k, slot) in p.iter_mut().enumerate() {
            let q = (std::f64::consts::TAU * k as f64 / 400.0).sin();
            t.advance(q).unwrap();
            *slot = solve(&t);
        }
        (0..=200)
            .map(|m| (p[500 + m] - p[500 - m]).abs())
            .fold(0.0, f64::max)
            / 2.0
    }

    #[test]
    fn hysteresis_grows_with_sheath_bend() {
        let gaps: Vec<f64> = [0.0, 90.0, 180.0, 270.0]
            .iter()
            .map(|&s| loop_half_gap(s))
            .collect();
        for w in gaps.windows(2) {
            assert!(w[1] > w[0], "loop width must grow with the bend: {gaps:?}");
        }
    }

    #[test]
    fn taut_force_matches_the_documented_closed_form() {
        // F = [k(q_b − p) − (2T₀ sinh μΦ + F_c) z] / (1 + (cosh μΦ − 1)|z|), fully sliding
        let p = SheathParams {
            pretension_n: 20.0,
            drive_backlash_mm: 0.0,
            presliding_mm: 0.01, // saturates within the 2 mm of travel below
            ..SheathParams::default()
        };
        let x = p.friction_coefficient * (200.0 + p.route_wrap_deg).to_radians();
        for (q, z_expected) in [(2.0, 1.0), (-2.0, -1.0)] {
            let mut t = TendonSheath::new(p, 200.0).unwrap();
            t.advance(q).unwrap();
            assert!((t.z() - z_expected).abs() < 1e-9);
            for dp in [-0.2, 0.0, 0.3] {
                let pp = q + dp;
                let expected = (p.tendon_stiffness_n_per_mm * (q - pp)
                    - (2.0 * p.pretension_n * x.sinh() + p.coulomb_friction_n) * t.z())
                    / (1.0 + (x.cosh() - 1.0) * t.z().abs());
                let d = t.distal(pp);
                assert!(
                    d.force_n.abs() <= 2.0 * p.pretension_n,
                    "must be taut for this check"
                );
                assert!(
                    (d.force_n - expected).abs() < 1e-9,
                    "q={q} p={pp}: {} vs {expected}",
                    d.force_n
                );
            }
        }
    }

    #[test]
    fn slack_regimes_never_flip_the_force() {
        // however large the friction, pulling harder never makes F smaller
        let p = SheathParams {
            friction_coefficient: 0.8,
            pretension_n: 1.0,
            ..SheathParams::default()
        };
        for z_dir in [1.0, -1.0] {
            let mut t = TendonSheath::new(p, 360.0).unwrap();
            t.advance(5.0 * z_dir).unwrap();
            let mut last = f64::INFINITY;
            for k in -400..400 {
                let f = t.distal_force(f64::from(k) * 0.05);
                assert!(
                    f.is_finite() && f <= last,
                    "F({}) = {f} after {last}",
                    f64::from(k) * 0.05
                );
                last = f;
            }
        }
    }

    #[test]
    fn frictionless_sheath_has_no_loop() {
        let params = SheathParams {
            friction_coefficient: 0.0,
            coulomb_friction_n: 0.0,
            drive_backlash_mm: 0.0,
            ..SheathParams::default()
        };
        let mut t = TendonSheath::new(params, 270.0).unwrap();
        t.advance(1.0).unwrap();
        let up = t.distal_force(0.3);
        t.advance(1.5).unwrap();
        t.advance(1.0).unwrap();
        assert!((t.distal_force(0.3) - up).abs() < 1e-12);
    }

    #[test]
    fn capstan_ratio_of_tensions() {
        // Fully sliding while tendon a is pulled: proximal/distal = e^{μΦ}.
        let p = SheathParams::default();
        let mut t = TendonSheath::new(p, 180.0).unwrap();
        t.advance(5.0).unwrap();
        assert!(t.z() > 0.999);
        let tt = t.tensions(2.0);
        assert!(tt.b_distal_n > 0.0, "both taut at this force");
        let expected = (p.friction_coefficient * (180.0 + p.route_wrap_deg).to_radians()).exp();
        assert!((tt.a_proximal_n / tt.a_distal_n - expected).abs() < 1e-2 * expected);
    }

    #[test]
    fn slack_tendon_carries_nothing_and_force_is_continuous() {
        let p = SheathParams {
            pretension_n: 2.0,
            ..SheathParams::default()
        };
        let mut t = TendonSheath::new(p, 90.0).unwrap();
        t.advance(3.0).unwrap();
        // sweep p: F is continuous (no jump at the slack boundaries) and decreasing
        let mut last = t.distal_force(-2.0);
        let mut k = -2.0;
        while k < 5.0 {
            k += 1e-3;
            let f = t.distal_force(k);
            assert!(f <= last + 1e-12, "F must decrease with p");
            assert!((f - last).abs() < 0.2, "jump at p = {k}: {last} -> {f}");
            last = f;
        }
        let pulled = t.distal(0.0);
        assert!(
            pulled.force_n > 2.0 * p.pretension_n,
            "should be past slack: {pulled:?}"
        );
        let tt = t.tensions(pulled.force_n);
        assert_eq!(tt.b_distal_n, 0.0);
        assert_eq!(pulled.tension_sum_n, pulled.force_n);
    }

    #[test]
    fn rejects_meaningless_parameters() {
        let p = SheathParams {
            friction_coefficient: -0.1,
            ..SheathParams::default()
        };
        let err = TendonSheath::new(p, 0.0).unwrap_err().to_string();
        assert!(
            err.contains("friction_coefficient") && err.contains("-0.1"),
            "{err}"
        );
        assert!(TendonSheath::new(SheathParams::default(), -10.0).is_err());
        assert!(TendonSheath::new(SheathParams::default(), f64::NAN).is_err());
        let p = SheathParams {
            tendon_stiffness_n_per_mm: 0.0,
            ..SheathParams::default()
        };
        assert!(TendonSheath::new(p, 0.0).is_err());
    }
}
