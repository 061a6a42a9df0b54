//! Tendon-sheath transmission of the antagonistic tendon pair (lumped, quasi-static).
//!
//! The motors set the proximal differential stroke `q` of the pair (mm). On its
//! way to the joint the motion passes the drive's backlash (a [`Play`] of
//! half-width `drive_backlash_mm`, giving `q_b`), then the tendons, which stretch
//! (differential stiffness `k`, N/mm) and rub on the sheath.
//!
//! **Elastic force.** With `δ = q_b − p` (`p`: the joint's distal differential
//! stroke), the pair pulls with `E(δ) = kδ` while both tendons are taut
//! (`|kδ| ≤ 2T₀`, pretension `T₀`) and `sign(δ)(T₀ + k|δ|/2)` once one is slack:
//! a tendon cannot push, and only the other one (stiffness `k/2`) still pulls.
//!
//! **Capstan law.** A tendon sliding over a total wrap `Φ` with friction
//! coefficient `μ` carries `T_p = T_d e^{±μΦ}`. With distal tensions
//! `T₀ ± F/2` (`F = T_a − T_b`), the sum of both tendons' friction while the
//! pair slides is `±(2T₀ sinh μΦ) + F (cosh μΦ − 1)`, so on the two sliding branches
//! ```text
//! F cosh(μΦ) = E ∓ H,      H = 2T₀ sinh(μΦ) + F_c
//! ```
//! (`F_c`: load-independent Coulomb friction of guides and seals). `Φ` is the
//! sheath configuration plus the wrap the tendons already have inside the
//! instrument (`route_wrap_deg`). `H` is the hysteresis, `cosh μΦ` the lost
//! motion (the tendons' effective stiffness falls as friction grows); both
//! grow with the bend by the mechanism, not a table.
//!
//! **Shaft coupling.** The tendons share the instrument's shaft, at a lateral
//! offset from its neutral axis. Bending the sheath by `Φ_sheath` lengthens one
//! tendon's path and shortens the other's, shifting the differential stroke at
//! the joint by `−c Φ_sheath` (`c = sheath_coupling_mm_per_rad`: the offset
//! projected on the sheath's bending plane; its sign says which way the
//! sheath is bent relative to the joint). The joint's zero moves with the
//! sheath — an error a kinematic model trained on a straight sheath cannot know.
//!
//! **Stick.** Between the branches the tendons stick in the sheath and the
//! distal force does not change: `G = F cosh μΦ` is a play of the elastic force,
//! `G ∈ [E − H, E + H]`. kflex smooths the corners with a Bouc–Wen friction
//! state `z` driven by `E` (`A = 1/H`, `β = γ = A/2`, `n = friction_sharpness`):
//! `G = E − H z`. Right after a reversal `dz/dE = 1/H` exactly while `z` keeps
//! its sign, so `dG = 0` (true stick, the joint holds still); past `z = 0`,
//! `dz/dE = (1 − |z|ⁿ)/H` and sliding sets in — gradually for `n = 1`, ever
//! more sharply (towards Coulomb's play) as `n` grows.
//! Hence `dF/dp ≤ 0` always: pulling the tendon back never bends the joint
//! further.
//!
//! Assumptions, stated so they can be revisited: the friction capacity is
//! that of the pretensioned pair (a slack tendon changes the elastic law, not
//! `H`); the common-mode path change of Eq. 1 is absorbed by the tendons'
//! compliance; the transmission is quasi-static (tendon and motor inertia
//! neglected; the paper's test input is 0.159 Hz).

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
    /// Half-width of the drive's backlash (motor coupling), mm of tendon stroke.
    pub drive_backlash_mm: f64,
    /// Shaft coupling `c`: differential path change per radian of sheath bend, mm/rad.
    pub sheath_coupling_mm_per_rad: f64,
    /// Bouc–Wen exponent `n` of the friction's stick-to-slide transition (1: smooth; large: sharp).
    pub friction_sharpness: f64,
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
        closed_range("drive_backlash_mm", self.drive_backlash_mm, 0.0, 100.0)?;
        closed_range(
            "sheath_coupling_mm_per_rad",
            self.sheath_coupling_mm_per_rad,
            -10.0,
            10.0,
        )?;
        closed_range("friction_sharpness", self.friction_sharpness, 1.0, 10.0)?;
        Ok(())
    }
}

/// Friction below this (N) counts as none: no hysteresis state is kept.
const NO_FRICTION_N: f64 = 1e-9;

/// The stateful transmission for one sheath configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct TendonSheath {
    params: SheathParams,
    sheath_deg: f64,
    /// `H = 2T₀ sinh(μΦ) + F_c`, N.
    friction_n: f64,
    /// `cosh(μΦ)`.
    lost_motion: f64,
    /// `e^{μΦ} − 1` and `1 − e^{−μΦ}`, for the individual tensions.
    e_pull: f64,
    e_release: f64,
    /// `c Φ_sheath`: stroke the shaft coupling takes from the joint, mm.
    coupling_mm: f64,
    play: Play,
    /// Bouc–Wen state driven by the elastic force `E`; `None` without friction.
    friction: Option<BoucWen>,
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

/// The tendons at the joint for one distal stroke.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distal {
    /// Differential force `F = T_a − T_b`, N.
    pub force_n: f64,
    /// `dF/dp`, N/mm (≤ 0).
    pub slope_n_per_mm: f64,
    /// `T_a + T_b`, N: `max(2T₀, |F|)`.
    pub tension_sum_n: f64,
}

impl TendonSheath {
    /// A transmission through a sheath bent by `sheath_deg` (any angle ≥ 0), at rest with zero stroke.
    pub fn new(params: SheathParams, sheath_deg: f64) -> Result<Self> {
        params.validate()?;
        let mut out = Self {
            params,
            sheath_deg: 0.0,
            friction_n: 0.0,
            lost_motion: 1.0,
            e_pull: 0.0,
            e_release: 0.0,
            coupling_mm: 0.0,
            play: Play::new(params.drive_backlash_mm, 0.0)?,
            friction: None,
        };
        out.set_sheath_deg(sheath_deg)?;
        Ok(out)
    }

    /// Changes the sheath configuration (total bend, deg), keeping the friction state.
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        closed_range("sheath_deg", sheath_deg, 0.0, 3600.0)?;
        let p = &self.params;
        let mu_phi = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians();
        let friction_n = 2.0 * p.pretension_n * mu_phi.sinh() + p.coulomb_friction_n;
        let friction = if friction_n > NO_FRICTION_N {
            let a = 1.0 / friction_n;
            let n = p.friction_sharpness;
            // 5 % sub-steps: the friction state to ~1e-6, at a tenth of the default cost
            let mut bw = BoucWen::new(
                BoucWenParams {
                    a,
                    beta: 0.5 * a,
                    gamma: 0.5 * a,
                    n,
                    alpha: 0.0,
                },
                0.0,
            )?
            .with_substep_fraction(0.05)?;
            if let Some(old) = &self.friction {
                bw.set_state(old.x(), old.z());
            }
            Some(bw)
        } else {
            None
        };
        self.sheath_deg = sheath_deg;
        self.friction_n = friction_n;
        self.friction = friction;
        self.lost_motion = mu_phi.cosh();
        self.e_pull = mu_phi.exp() - 1.0;
        self.e_release = 1.0 - (-mu_phi).exp();
        self.coupling_mm = p.sheath_coupling_mm_per_rad * sheath_deg.to_radians();
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

    /// Friction `H` of the pair at this bend, N.
    pub fn friction_n(&self) -> f64 {
        self.friction_n
    }

    /// Resets backlash and friction: tendons at rest at stroke `q`, no load.
    pub fn reset(&mut self, q: f64) {
        self.play.reset(q);
        if let Some(bw) = &mut self.friction {
            bw.reset(0.0);
        }
    }

    /// Moves the motors' differential stroke to `q` (mm). The friction state
    /// moves when the joint's answer is known: [`TendonSheath::commit`].
    pub fn advance(&mut self, q: f64) -> Result<()> {
        self.play.advance(q)?;
        Ok(())
    }

    /// Friction state `z ∈ [−1, 1]` (+1: sliding as when tendon `a` is pulled in).
    pub fn z(&self) -> f64 {
        self.friction.as_ref().map_or(0.0, BoucWen::z)
    }

    /// Stroke after the drive's backlash, mm.
    pub fn stroke_after_backlash(&self) -> f64 {
        self.play.output()
    }

    /// Elastic differential force of the pair `E(δ)` (N) and `dE/dδ`, with slack.
    fn elastic(&self, delta: f64) -> (f64, f64) {
        let k = self.params.tendon_stiffness_n_per_mm;
        let t0 = self.params.pretension_n;
        if (k * delta).abs() <= 2.0 * t0 {
            (k * delta, k)
        } else {
            (delta.signum() * (t0 + 0.5 * k * delta.abs()), 0.5 * k)
        }
    }

    /// The tendons at the joint if its distal stroke were `p` (mm), without committing it.
    pub fn distal(&self, p: f64) -> Distal {
        let (e, de) = self.elastic(self.play.output() - self.coupling_mm - p);
        let (g, dg_de) = match &self.friction {
            Some(bw) => {
                let z = bw.peek(e);
                // dz/dE in the direction of travel, for Newton slopes
                let dz_de = bw.slope(z, (e - bw.x()).signum());
                (
                    e - self.friction_n * z,
                    (1.0 - self.friction_n * dz_de).clamp(0.0, 1.0),
                )
            }
            None => (e, 1.0),
        };
        let force = g / self.lost_motion;
        Distal {
            force_n: force,
            slope_n_per_mm: -de * dg_de / self.lost_motion,
            tension_sum_n: (2.0 * self.params.pretension_n).max(force.abs()),
        }
    }

    /// Differential distal force `F = T_a − T_b` (N) if the joint's distal stroke were `p` (mm).
    pub fn distal_force(&self, p: f64) -> f64 {
        self.distal(p).force_n
    }

    /// Records that the joint settled at distal stroke `p` (mm): the friction state moves there.
    pub fn commit(&mut self, p: f64) -> Result<()> {
        let (e, _) = self.elastic(self.play.output() - self.coupling_mm - p);
        if let Some(bw) = &mut self.friction {
            bw.advance(e)?;
        }
        Ok(())
    }

    /// Stiffness of the taut pair, N/mm: an upper bound of `−dF/dp`.
    pub fn taut_stiffness(&self) -> f64 {
        self.params.tendon_stiffness_n_per_mm
    }

    /// Tensions at both ends for distal differential force `force_n`: distal
    /// `T_a = max(T₀ + F/2, F, 0)`, `T_b = T_a − F`; proximal by the capstan law
    /// in the current sliding direction.
    pub fn tensions(&self, force_n: f64) -> TendonTensions {
        let t0 = self.params.pretension_n;
        let a = (t0 + 0.5 * force_n).max(force_n).max(0.0);
        let b = a - force_n;
        let z = self.z();
        let (zp, zn) = (z.max(0.0), (-z).max(0.0));
        TendonTensions {
            a_distal_n: a,
            b_distal_n: b,
            a_proximal_n: a * (1.0 + self.e_pull * zp - self.e_release * zn),
            b_proximal_n: b * (1.0 + self.e_pull * zn - self.e_release * zp),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moderate, explicit parameters: these tests are about the mechanism, not the calibration.
    fn params() -> SheathParams {
        SheathParams {
            friction_coefficient: 0.2,
            route_wrap_deg: 10.0,
            pretension_n: 5.0,
            tendon_stiffness_n_per_mm: 30.0,
            coulomb_friction_n: 1.0,
            drive_backlash_mm: 0.0,
            sheath_coupling_mm_per_rad: 0.0,
            friction_sharpness: 1.0,
        }
    }

    /// Quasi-static equilibrium with a linear spring joint `F = K p` (K = 5 N/mm).
    fn settle(t: &mut TendonSheath, q: f64) -> f64 {
        t.advance(q).unwrap();
        let joint_k = 5.0;
        let residual = |p: f64| {
            let d = t.distal(p);
            (d.force_n - joint_k * p, d.slope_n_per_mm - joint_k)
        };
        let p = crate::numeric::root_decreasing(residual, -50.0, 50.0, 0.0, 1e-13);
        t.commit(p).unwrap();
        p
    }

    /// Half the largest gap between the loading and unloading branches at equal stroke, mm.
    fn loop_half_gap(sheath_deg: f64) -> f64 {
        let mut t = TendonSheath::new(params(), sheath_deg).unwrap();
        // second cycle: rising from k = 300 (q = −1) to 500 (q = 1), falling to 700
        let p: Vec<f64> = (0..=700)
            .map(|k| settle(&mut t, (std::f64::consts::TAU * f64::from(k) / 400.0).sin()))
            .collect();
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
    fn reversal_sticks_and_never_pushes_the_joint_further() {
        // after a reversal the output holds still (stick), then follows back; it never overshoots
        for sheath_deg in [0.0, 270.0, 540.0] {
            let mut t = TendonSheath::new(params(), sheath_deg).unwrap();
            let mut p_top = 0.0;
            for k in 0..=100 {
                p_top = settle(&mut t, 0.02 * f64::from(k));
            }
            let mut last = p_top;
            let mut stuck = 0;
            for k in 1..=200 {
                let p = settle(&mut t, 2.0 - 0.02 * f64::from(k));
                assert!(
                    p <= last + 1e-9,
                    "sheath {sheath_deg}: reversal pushed p from {last} to {p}"
                );
                if (p - p_top).abs() < 1e-9 {
                    stuck += 1;
                }
                last = p;
            }
            assert!(
                stuck >= 1,
                "sheath {sheath_deg}: no stick after the reversal"
            );
            assert!(
                last < p_top - 0.1,
                "sheath {sheath_deg}: the joint must come back"
            );
        }
    }

    #[test]
    fn sliding_branches_follow_the_capstan_closed_form() {
        // F cosh(μΦ) = E − H z always; far along a monotone loading z → 1: the lower branch E − H
        let p = params();
        let sheath_deg = 200.0;
        let x = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians();
        let h = 2.0 * p.pretension_n * x.sinh() + p.coulomb_friction_n;
        let mut t = TendonSheath::new(p, sheath_deg).unwrap();
        for k in 1..=500 {
            t.advance(0.01 * f64::from(k)).unwrap();
            t.commit(0.0).unwrap(); // joint held straight: E grows with the stroke
        }
        let e = p.pretension_n + 0.5 * p.tendon_stiffness_n_per_mm * 5.0; // slack branch at δ = 5 mm
        let d = t.distal(0.0);
        assert!((d.force_n * x.cosh() - (e - h * t.z())).abs() < 1e-9);
        assert!(t.z() > 0.999, "{}", t.z());
        assert!((d.force_n * x.cosh() - (e - h)).abs() < 1e-2 * h);
    }

    #[test]
    fn frictionless_sheath_has_no_loop() {
        let params = SheathParams {
            friction_coefficient: 0.0,
            coulomb_friction_n: 0.0,
            ..params()
        };
        assert!(loop_gap_with(params) < 1e-12);
    }

    fn loop_gap_with(params: SheathParams) -> f64 {
        let mut t = TendonSheath::new(params, 270.0).unwrap();
        let up = settle(&mut t, 0.5);
        settle(&mut t, 1.0);
        (settle(&mut t, 0.5) - up).abs()
    }

    #[test]
    fn capstan_ratio_of_tensions() {
        // fully sliding while tendon a is pulled: proximal/distal = e^{μΦ}
        let p = params();
        let mut t = TendonSheath::new(p, 180.0).unwrap();
        for k in 1..=100 {
            t.advance(0.05 * f64::from(k)).unwrap();
            t.commit(0.0).unwrap(); // joint held: the friction develops fully
        }
        assert!(t.z() > 0.999, "{}", t.z());
        let tt = t.tensions(2.0);
        assert!(tt.b_distal_n > 0.0, "both taut at this force");
        let capstan = (p.friction_coefficient * (180.0 + p.route_wrap_deg).to_radians()).exp();
        // fully developed friction (z → 1) gives the capstan ratio e^{μΦ}
        assert!((tt.a_proximal_n / tt.a_distal_n - (1.0 + (capstan - 1.0) * t.z())).abs() < 1e-12);
        assert!((tt.a_proximal_n / tt.a_distal_n - capstan).abs() < 1e-2 * capstan);
    }

    #[test]
    fn slack_tendon_carries_nothing_and_force_is_continuous_and_monotone() {
        let p = SheathParams {
            pretension_n: 2.0,
            ..params()
        };
        let mut t = TendonSheath::new(p, 90.0).unwrap();
        t.advance(3.0).unwrap();
        let mut last = t.distal_force(-2.0);
        for k in 1..7000 {
            let f = t.distal_force(-2.0 + 1e-3 * f64::from(k));
            assert!(f <= last + 1e-12, "F must not increase with p");
            assert!((f - last).abs() < 0.2, "jump: {last} -> {f}");
            last = f;
        }
        let f = t.distal_force(0.0);
        assert!(f > 2.0 * p.pretension_n, "should be past slack: {f}");
        let tt = t.tensions(f);
        assert_eq!(tt.b_distal_n, 0.0);
        assert_eq!(t.distal(0.0).tension_sum_n, f);
    }

    #[test]
    fn shaft_coupling_shifts_the_zero_with_the_sheath_only() {
        let coupled = SheathParams {
            sheath_coupling_mm_per_rad: 0.2,
            ..params()
        };
        let at = |params: SheathParams, sheath_deg: f64| {
            let mut t = TendonSheath::new(params, sheath_deg).unwrap();
            settle(&mut t, 0.5)
        };
        assert_eq!(
            at(coupled, 0.0),
            at(params(), 0.0),
            "no effect on a straight sheath"
        );
        let shift = at(params(), 180.0) - at(coupled, 180.0);
        assert!(
            shift > 0.05,
            "a bent sheath takes stroke from the joint: {shift}"
        );
    }

    #[test]
    fn rejects_meaningless_parameters() {
        let p = SheathParams {
            friction_coefficient: -0.1,
            ..params()
        };
        let err = TendonSheath::new(p, 0.0).unwrap_err().to_string();
        assert!(
            err.contains("friction_coefficient") && err.contains("-0.1"),
            "{err}"
        );
        assert!(TendonSheath::new(params(), -10.0).is_err());
        assert!(TendonSheath::new(params(), f64::NAN).is_err());
        let p = SheathParams {
            tendon_stiffness_n_per_mm: 0.0,
            ..params()
        };
        assert!(TendonSheath::new(p, 0.0).is_err());
    }
}
