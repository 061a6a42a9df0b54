//! Tendon-sheath transmission of the antagonistic tendon pair (lumped, quasi-static).

use serde::{Deserialize, Serialize};

use crate::error::{Result, finite};
use crate::hysteresis::Play;
use crate::range::Bounds;

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
    /// Stiffness `k_d` of the distal run of the pair (sheath end to joint), N/mm.
    pub distal_stiffness_n_per_mm: f64,
}

impl SheathParams {
    /// Checks every parameter against its physical range.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range, in
    /// declaration order: `friction_coefficient` outside `[0, 2]`,
    /// `route_wrap_deg` outside `[0, 3600]` deg, `pretension_n` outside
    /// `(0, 1e4)` N, `tendon_stiffness_n_per_mm` outside `(0, 1e6)` N/mm,
    /// `coulomb_friction_n` outside `[0, 1e4]` N, `drive_backlash_mm` outside
    /// `[0, 100]` mm, `sheath_coupling_mm_per_rad` outside `[-10, 10]` mm/rad,
    /// `distal_stiffness_n_per_mm` outside `(0, 1e7)` N/mm (NaN is out of
    /// every range).
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.0, 2.0).check("friction_coefficient", self.friction_coefficient)?;
        Bounds::closed(0.0, 3600.0).check("route_wrap_deg", self.route_wrap_deg)?;
        Bounds::open(0.0, 1e4).check("pretension_n", self.pretension_n)?;
        Bounds::open(0.0, 1e6)
            .check("tendon_stiffness_n_per_mm", self.tendon_stiffness_n_per_mm)?;
        Bounds::closed(0.0, 1e4).check("coulomb_friction_n", self.coulomb_friction_n)?;
        Bounds::closed(0.0, 100.0).check("drive_backlash_mm", self.drive_backlash_mm)?;
        Bounds::closed(-10.0, 10.0).check(
            "sheath_coupling_mm_per_rad",
            self.sheath_coupling_mm_per_rad,
        )?;
        Bounds::open(0.0, 1e7)
            .check("distal_stiffness_n_per_mm", self.distal_stiffness_n_per_mm)?;
        Ok(())
    }
}

/// The stateful transmission for one sheath configuration.
///
/// The motors set the proximal differential stroke `q` of the pair (mm). On its
/// way to the joint the motion passes the drive's backlash (a [`Play`] of
/// half-width `drive_backlash_mm`, giving `q_b`), then the tendons, which stretch
/// (differential stiffness `k`, N/mm) and rub on the sheath.
///
/// **Elastic force.** With `δ = q_b − p` (`p`: the joint's distal differential
/// stroke), the pair pulls with `E(δ) = kδ` while both tendons are taut
/// (`|kδ| ≤ 2T₀`, pretension `T₀`) and `sign(δ)(T₀ + k|δ|/2)` once one is slack:
/// a tendon cannot push, and only the other one (stiffness `k/2`) still pulls.
///
/// **Capstan law.** A tendon sliding over a total wrap `Φ` with friction
/// coefficient `μ` carries `T_p = T_d e^{±μΦ}`. With distal tensions
/// `T₀ ± F/2` (`F = T_a − T_b`), the sum of both tendons' friction while the
/// pair slides is `±(2T₀ sinh μΦ) + F (cosh μΦ − 1)`, so on the two sliding branches
/// ```text
/// F cosh(μΦ) = E ∓ H,      H = 2T₀ sinh(μΦ) + F_c
/// ```
/// (`F_c`: load-independent Coulomb friction of guides and seals). `Φ` is the
/// sheath configuration plus the wrap the tendons already have inside the
/// instrument (`route_wrap_deg`). `H` is the hysteresis, `cosh μΦ` the lost
/// motion (the tendons' effective stiffness falls as friction grows); both
/// grow with the bend by the mechanism, not a table.
///
/// **Shaft coupling.** The tendons share the instrument's shaft, at a lateral
/// offset from its neutral axis. Bending the sheath by `Φ_sheath` lengthens one
/// tendon's path and shortens the other's, shifting the differential stroke at
/// the joint by `−c Φ_sheath` (`c = sheath_coupling_mm_per_rad`: the offset
/// projected on the sheath's bending plane; its sign says which way the
/// sheath is bent relative to the joint). The joint's zero moves with the
/// sheath — an error a kinematic model trained on a straight sheath cannot know.
///
/// **Stick.** The friction acts on the tendons inside the sheath, so the pair
/// is two springs: the long run through the sheath (`k`, with the slack law
/// above) and the short run from the sheath's end through the joint
/// (`k_d = distal_stiffness_n_per_mm`). The friction holds the node between
/// them: it stays put while the mobilised friction `E(q_b − c − s) − F cosh μΦ`
/// lies within `±H`, and slides along a branch where it reaches the bound.
/// The node `s` is therefore a play between the two branch positions (exact
/// Coulomb stick). Stuck, the joint still feels the distal run's stiffness
/// `k_d`: stuck tendons lock the joint rather than leaving it free. Sliding,
/// `F = k_d (s − p)` with `F cosh μΦ = E ∓ H` — the capstan branches above,
/// with the two runs in series.
///
/// Assumptions, stated so they can be revisited: the friction capacity is
/// that of the pretensioned pair (a slack tendon changes the elastic law, not
/// `H`); the distal run stays taut; the common-mode path change of Eq. 1 is
/// absorbed by the tendons' compliance; the transmission is quasi-static
/// (tendon and motor inertia neglected; the paper's test input is 0.159 Hz).
#[derive(Debug, Clone, PartialEq)]
pub struct TendonSheath {
    params: SheathParams,
    sheath_deg: f64,
    /// `H = 2T₀ sinh(μΦ) + F_c`, N.
    friction_n: f64,
    /// `cosh(μΦ)` and `sinh(μΦ)`.
    lost_motion: f64,
    sinh: f64,
    /// `c Φ_sheath`: stroke the shaft coupling takes from the joint, mm.
    coupling_mm: f64,
    play: Play,
    /// Differential position of the node between the sheath run and the distal run, mm.
    node_mm: f64,
    /// Joint's distal stroke at the last commit, mm.
    p_committed: f64,
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
    /// `dF/dp`, N/mm (< 0).
    pub slope_n_per_mm: f64,
    /// `T_a + T_b`, N: `max(2T₀, |F|)`.
    pub tension_sum_n: f64,
    /// Node position for this stroke, mm.
    node_mm: f64,
}

impl TendonSheath {
    /// A transmission through a sheath bent by `sheath_deg` (`[0, 3600]` deg), at rest with zero stroke.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter of `params` out of
    /// its range ([`SheathParams::validate`]), or `sheath_deg`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn new(params: SheathParams, sheath_deg: f64) -> Result<Self> {
        params.validate()?;
        let mut out = Self {
            params,
            sheath_deg: 0.0,
            friction_n: 0.0,
            lost_motion: 1.0,
            sinh: 0.0,
            coupling_mm: 0.0,
            play: Play::new(params.drive_backlash_mm, 0.0)?,
            node_mm: 0.0,
            p_committed: 0.0,
        };
        out.set_sheath_deg(sheath_deg)?;
        out.reset(0.0);
        Ok(out)
    }

    /// Changes the sheath configuration (total bend, deg). The tendons stay where
    /// they are in the sheath (the node holds), so the distal force does not jump;
    /// the next tick slides them onto the new friction band if they lie outside it.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `sheath_deg` when it is outside
    /// `[0, 3600]` deg (NaN included); the transmission is then unchanged.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        Bounds::closed(0.0, 3600.0).check("sheath_deg", sheath_deg)?;
        let p = &self.params;
        let mu_phi = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians();
        self.sheath_deg = sheath_deg;
        self.friction_n = 2.0 * p.pretension_n * mu_phi.sinh() + p.coulomb_friction_n;
        self.lost_motion = mu_phi.cosh();
        self.sinh = mu_phi.sinh();
        self.coupling_mm = p.sheath_coupling_mm_per_rad * sheath_deg.to_radians();
        Ok(())
    }

    /// Sheath bend, deg.
    #[must_use]
    pub fn sheath_deg(&self) -> f64 {
        self.sheath_deg
    }

    /// Parameters.
    #[must_use]
    pub fn params(&self) -> &SheathParams {
        &self.params
    }

    /// Friction `H` of the pair at this bend, N.
    #[must_use]
    pub fn friction_n(&self) -> f64 {
        self.friction_n
    }

    /// Resets: motors at stroke `q`, joint straight, no friction mobilised.
    pub fn reset(&mut self, q_mm: f64) {
        self.play.reset(q_mm);
        self.p_committed = 0.0;
        self.node_mm = self.branch_node(0.0, 0.0);
    }

    /// Moves the motors' differential stroke to `q` (mm). The tendons in the
    /// sheath move when the joint's answer is known: [`TendonSheath::commit`].
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `q_mm` (named `play.x`,
    /// the input of the drive's backlash); nothing moves then.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn advance(&mut self, q_mm: f64) -> Result<()> {
        self.play.advance(q_mm)?;
        Ok(())
    }

    /// Mobilised friction as a fraction of `H` at the committed state, in `[−1, 1]`
    /// (+1: sliding as when tendon `a` is pulled in; 0 with no friction).
    #[must_use]
    pub fn friction_state(&self) -> f64 {
        self.mobilised(self.node_mm, self.p_committed)
    }

    /// Stroke after the drive's backlash, mm.
    #[must_use]
    pub fn stroke_after_backlash_mm(&self) -> f64 {
        self.play.output()
    }

    /// Elastic differential force of the sheath run `E(δ)` (N) and `dE/dδ`, with slack.
    fn elastic(&self, delta: f64) -> (f64, f64) {
        let k = self.params.tendon_stiffness_n_per_mm;
        let t0 = self.params.pretension_n;
        if (k * delta).abs() <= 2.0 * t0 {
            (k * delta, k)
        } else {
            (delta.signum() * (t0 + 0.5 * k * delta.abs()), 0.5 * k)
        }
    }

    /// Node position on the branch where the mobilised friction is `f` (N), for
    /// joint stroke `p`: the root of `E(q_b − c − s) − cosh·k_d (s − p) = f`,
    /// a decreasing piecewise-linear function of `s`, solved piece by piece.
    fn branch_node(&self, f: f64, p: f64) -> f64 {
        let k = self.params.tendon_stiffness_n_per_mm;
        let t0 = self.params.pretension_n;
        let ckd = self.lost_motion * self.params.distal_stiffness_n_per_mm;
        let q = self.play.output() - self.coupling_mm;
        // taut: k (q − s) − ckd (s − p) = f
        let s = (k * q + ckd * p - f) / (k + ckd);
        if (k * (q - s)).abs() <= 2.0 * t0 {
            return s;
        }
        // slack (one tendon carries): sign·T₀ + (k/2)(q − s) − ckd (s − p) = f
        let sign = (q - s).signum();
        (sign * t0 + 0.5 * k * q + ckd * p - f) / (0.5 * k + ckd)
    }

    /// Mobilised friction fraction at node `s` and joint stroke `p`.
    fn mobilised(&self, s: f64, p: f64) -> f64 {
        if self.friction_n <= 0.0 {
            return 0.0;
        }
        let e = self.elastic(self.play.output() - self.coupling_mm - s).0;
        let f = self.lost_motion * self.params.distal_stiffness_n_per_mm * (s - p);
        ((e - f) / self.friction_n).clamp(-1.0, 1.0)
    }

    /// The tendons at the joint if its distal stroke were `p` (mm), without committing it.
    #[must_use]
    pub fn distal(&self, p_mm: f64) -> Distal {
        let kd = self.params.distal_stiffness_n_per_mm;
        let h = self.friction_n;
        // branch positions: friction fully mobilised one way (+H: tendons pulled in) or the other
        let s_pull = self.branch_node(h, p_mm);
        let s_release = self.branch_node(-h, p_mm);
        let (node, sliding) = if self.node_mm < s_pull {
            (s_pull, true)
        } else if self.node_mm > s_release {
            (s_release, true)
        } else {
            (self.node_mm, false)
        };
        let force = kd * (node - p_mm);
        let slope = if sliding {
            // series of the distal run and the sheath run (seen through cosh μΦ)
            let q = self.play.output() - self.coupling_mm - node;
            let de = self.elastic(q).1;
            -kd * de / (de + self.lost_motion * kd)
        } else {
            -kd
        };
        Distal {
            force_n: force,
            slope_n_per_mm: slope,
            tension_sum_n: (2.0 * self.params.pretension_n).max(force.abs()),
            node_mm: node,
        }
    }

    /// Differential distal force `F = T_a − T_b` (N) if the joint's distal stroke were `p` (mm).
    #[must_use]
    pub fn distal_force_n(&self, p_mm: f64) -> f64 {
        self.distal(p_mm).force_n
    }

    /// Records that the joint settled at distal stroke `p` (mm): the tendons move there.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] naming `distal stroke` for a NaN or infinite
    /// `p_mm`; nothing moves then.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn commit(&mut self, p_mm: f64) -> Result<()> {
        finite("distal stroke", p_mm)?;
        self.node_mm = self.distal(p_mm).node_mm;
        self.p_committed = p_mm;
        Ok(())
    }

    /// Stiffness of the taut pair, N/mm: an upper bound of `−dF/dp`.
    #[must_use]
    pub fn taut_stiffness_n_per_mm(&self) -> f64 {
        self.params
            .distal_stiffness_n_per_mm
            .max(self.params.tendon_stiffness_n_per_mm)
    }

    /// Tensions at both ends for distal differential force `force_n`: distal
    /// `T_a = max(T₀ + F/2, F, 0)`, `T_b = T_a − F`; proximal
    /// `T_a (cosh μΦ + z sinh μΦ)` and `T_b (cosh μΦ − z sinh μΦ)`, which is the
    /// capstan law `e^{±μΦ}` when sliding (`z = ±1`) and, in between, keeps
    /// `T_a,p − T_b,p = F cosh μΦ + 2T₀ z sinh μΦ` consistent with the force balance.
    #[must_use]
    pub fn tensions(&self, force_n: f64) -> TendonTensions {
        let t0 = self.params.pretension_n;
        let a = (t0 + 0.5 * force_n).max(force_n).max(0.0);
        let b = a - force_n;
        let z = self.friction_state();
        TendonTensions {
            a_distal_n: a,
            b_distal_n: b,
            a_proximal_n: a * (self.lost_motion + z * self.sinh),
            b_proximal_n: b * (self.lost_motion - z * self.sinh),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::{ModelError, expect_range};

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
            distal_stiffness_n_per_mm: 600.0,
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
                p_top > 0.0 && last < p_top - 0.5 * p_top,
                "sheath {sheath_deg}: the joint must come back (top {p_top}, end {last})"
            );
        }
    }

    #[test]
    fn sliding_branches_follow_the_capstan_closed_form() {
        // joint held at p = 0, tendons pulled until they slide: the two runs in series with
        // F cosh μΦ = E − H on the sheath run, i.e. F = (q − H/k) / (cosh μΦ / k + 1/k_d) (taut)
        // low friction and high pretension: the tendons slide and both stay taut
        let p = SheathParams {
            pretension_n: 50.0,
            friction_coefficient: 0.05,
            ..params()
        };
        let sheath_deg = 200.0;
        let x = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians();
        let h = 2.0 * p.pretension_n * x.sinh() + p.coulomb_friction_n;
        let (k, kd) = (p.tendon_stiffness_n_per_mm, p.distal_stiffness_n_per_mm);
        let mut t = TendonSheath::new(p, sheath_deg).unwrap();
        let q = 2.0;
        for step in 1..=100 {
            t.advance(q * f64::from(step) / 100.0).unwrap();
            t.commit(0.0).unwrap();
        }
        let f = t.distal_force_n(0.0);
        assert!(f.abs() < 2.0 * p.pretension_n, "taut for this check: {f}");
        let expected = (q - h / k) / (x.cosh() / k + 1.0 / kd);
        assert!((f - expected).abs() < 1e-9, "{f} vs {expected}");
        assert!(
            (t.friction_state() - 1.0).abs() < 1e-9,
            "friction fully mobilised: {}",
            t.friction_state()
        );
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
        assert!(t.friction_state() > 0.999, "{}", t.friction_state());
        let tt = t.tensions(2.0);
        assert!(tt.b_distal_n > 0.0, "both taut at this force");
        let capstan = (p.friction_coefficient * (180.0 + p.route_wrap_deg).to_radians()).exp();
        // fully developed friction (z → 1) gives the capstan ratio e^{μΦ}
        let x = capstan.ln();
        assert!(
            (tt.a_proximal_n / tt.a_distal_n - (x.cosh() + t.friction_state() * x.sinh())).abs()
                < 1e-12
        );
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
        let mut last = t.distal_force_n(-2.0);
        let step = 1e-3;
        for k in 1..7000 {
            let f = t.distal_force_n(-2.0 + step * f64::from(k));
            assert!(f <= last + 1e-12, "F must not increase with p");
            // no jump: at most the stiffest slope (the distal run, when stuck) times the step
            assert!(
                (f - last).abs() <= p.distal_stiffness_n_per_mm * step * (1.0 + 1e-9),
                "jump: {last} -> {f}"
            );
            last = f;
        }
        let f = t.distal_force_n(0.0);
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
    fn reshaping_the_sheath_keeps_a_stuck_force_and_never_unloads_it() {
        // loaded to full sliding at 90 deg, then bent to 270 deg at rest: the force is held
        let p = params();
        let mut t = TendonSheath::new(p, 90.0).unwrap();
        for k in 1..=100 {
            t.advance(0.01 * f64::from(k)).unwrap();
            t.commit(0.0).unwrap();
        }
        let before = t.distal_force_n(0.0);
        t.set_sheath_deg(270.0).unwrap();
        assert!(
            (t.distal_force_n(0.0) - before).abs() < 1e-9,
            "{before} -> {}",
            t.distal_force_n(0.0)
        );
        // and turning the friction on from none starts from the current elastic force
        let none = SheathParams {
            friction_coefficient: 0.0,
            coulomb_friction_n: 0.0,
            ..p
        };
        let mut t = TendonSheath::new(none, 0.0).unwrap();
        t.advance(0.5).unwrap();
        t.commit(0.0).unwrap();
        let free = t.distal_force_n(0.0);
        let mut with = TendonSheath::new(
            SheathParams {
                friction_coefficient: 0.0,
                ..p
            },
            0.0,
        )
        .unwrap();
        with.advance(0.5).unwrap();
        with.commit(0.0).unwrap();
        assert!(with.distal_force_n(0.0) <= free + 1e-12);
    }

    #[test]
    fn proximal_tensions_balance_the_elastic_force() {
        // T_a,p − T_b,p = F cosh μΦ + 2T₀ z sinh μΦ at any z, not only when sliding
        let p = params();
        let mut t = TendonSheath::new(p, 180.0).unwrap();
        t.advance(0.05).unwrap();
        t.commit(0.0).unwrap();
        let z = t.friction_state();
        assert!(z > 0.05 && z < 0.95, "partly developed friction: {z}");
        let f = t.distal_force_n(0.0);
        let tt = t.tensions(f);
        let x = p.friction_coefficient * (180.0 + p.route_wrap_deg).to_radians();
        let expected = f * x.cosh() + 2.0 * p.pretension_n * z * x.sinh();
        assert!((tt.a_proximal_n - tt.b_proximal_n - expected).abs() < 1e-9);
    }

    #[test]
    fn commit_rejects_non_finite_strokes() {
        let none = SheathParams {
            friction_coefficient: 0.0,
            coulomb_friction_n: 0.0,
            ..params()
        };
        assert!(matches!(
            TendonSheath::new(none, 0.0).unwrap().commit(f64::NAN),
            Err(ModelError::NonFinite { name: "distal stroke", value }) if value.is_nan()
        ));
        assert!(matches!(
            TendonSheath::new(params(), 0.0).unwrap().commit(f64::INFINITY),
            Err(ModelError::NonFinite { name: "distal stroke", value }) if value == f64::INFINITY
        ));
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
        assert_eq!(
            expect_range(TendonSheath::new(p, 0.0), "friction_coefficient").value,
            -0.1
        );
        let e = expect_range(TendonSheath::new(params(), -10.0), "sheath_deg");
        assert_eq!((e.value, e.bounds.min, e.bounds.max), (-10.0, 0.0, 3600.0));
        assert!(
            expect_range(TendonSheath::new(params(), f64::NAN), "sheath_deg")
                .value
                .is_nan()
        );
        let p = SheathParams {
            tendon_stiffness_n_per_mm: 0.0,
            ..params()
        };
        let e = expect_range(TendonSheath::new(p, 0.0), "tendon_stiffness_n_per_mm");
        assert!(!e.bounds.min_inclusive && e.value == 0.0);
    }
}
