//! Tendon-sheath transmission of the antagonistic tendon pair: each tendon a
//! chain of elements with distributed friction and Bouc–Wen pre-sliding.

use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result, finite};
use crate::hysteresis::{BoucWen, BoucWenParams};
use crate::range::Bounds;

/// Parameters of the tendon-sheath transmission. Forces in N, lengths in mm,
/// angles in degrees. Every parameter is a physical quantity of one tendon
/// and its sheath; the two tendons are alike (the transmission is symmetric).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SheathParams {
    /// Friction coefficient `μ` between tendon and sheath liner (dimensionless).
    pub friction_coefficient: f64,
    /// Wrap angle the tendons have in every sheath configuration (routing
    /// through the instrument's body, pulleys and guides), deg. The sheath's
    /// own bend adds to it.
    pub route_wrap_deg: f64,
    /// Pretension `T₀` of each tendon at rest, N.
    pub pretension_n: f64,
    /// Axial stiffness `EA/L` of one tendon over the sheath's length, N/mm.
    pub tendon_stiffness_n_per_mm: f64,
    /// Axial stiffness of one tendon from the sheath's distal end to its
    /// anchor in the joint, N/mm.
    pub distal_stiffness_n_per_mm: f64,
    /// Half-width of the drive's backlash, mm of differential stroke (the
    /// plant passes the command through it before the motors).
    pub drive_backlash_mm: f64,
    /// Travel over which the drive's tooth flanks take up the load once they
    /// meet, mm of stroke (their contact compliance): the backlash's corners
    /// are rounded over about `2ε` instead of being sharp. 0 is an ideal play.
    pub backlash_engagement_mm: f64,
    /// Pre-sliding displacement `δ` of the tendon in its sheath, mm: the
    /// relative motion over which friction builds up to its sliding value
    /// (Dahl's law; about 95 % after `3δ`). From 0.01 µm (tens of µm for
    /// steel against a liner or coil).
    pub presliding_mm: f64,
    /// Number `N` of friction elements along each tendon.
    pub elements: u32,
    /// Change of each tendon's path through the sheath per radian of the
    /// sheath's bend, mm/rad, the same for both tendons: positive where
    /// bending lengthens the path (a closed-coil sheath, whose neutral axis
    /// moves to the inside of the bend while the tendon stays near the
    /// centre), negative where the tendon takes the inside of its lumen (the
    /// radial clearance). It tightens or slackens both tendons alike, so it
    /// moves no zero: a common-mode effect, not an offset.
    pub sheath_path_mm_per_rad: f64,
}

impl SheathParams {
    // the ranges `validate` checks, named so that a draw around a valid
    // configuration (`PlantConfig::perturbed`) can be held inside them
    pub(crate) const FRICTION_COEFFICIENT: Bounds = Bounds::closed(0.0, 1.0);
    pub(crate) const ROUTE_WRAP_DEG: Bounds = Bounds::closed(0.0, 3600.0);
    pub(crate) const PRETENSION_N: Bounds = Bounds::open_closed(0.0, 1e3);
    /// From 0.001 N/mm (a steel tendon of 0.3 mm is 10.5 N/mm over 1.3 m; an
    /// UHMWPE one about 5), which the tests run at the paper's four sheath
    /// angles.
    pub(crate) const TENDON_STIFFNESS: Bounds = Bounds::closed_open(1e-3, 1e6);
    pub(crate) const DISTAL_STIFFNESS: Bounds = Bounds::open(0.0, 1e7);
    pub(crate) const BACKLASH_MM: Bounds = Bounds::closed(0.0, 10.0);
    /// From 0.01 µm, which the tests run at the paper's four sheath angles:
    /// at 1 nm a tendon solve on the joint's search for its balance fails at
    /// 270 deg (an element reversing within nanometres; 3 nm runs).
    pub(crate) const PRESLIDING_MM: Bounds = Bounds::closed(1e-5, 10.0);
    pub(crate) const PATH_MM_PER_RAD: Bounds = Bounds::closed(-1.0, 1.0);

    /// Checks every parameter against its physical range.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range, in
    /// declaration order: `friction_coefficient` outside `[0, 1]`,
    /// `route_wrap_deg` outside `[0, 3600]` deg, `pretension_n` outside
    /// `(0, 1000]` N, `tendon_stiffness_n_per_mm` outside `[0.001, 1e6)` N/mm,
    /// `distal_stiffness_n_per_mm` outside `(0, 1e7)` N/mm,
    /// `drive_backlash_mm` or `backlash_engagement_mm` outside `[0, 10]` mm, `presliding_mm` outside
    /// `[1e-5, 10]` mm, `elements` outside `[1, 200]`,
    /// `sheath_path_mm_per_rad` outside `[−1, 1]` mm/rad (NaN is out of every
    /// range); then `route_wrap_deg` above [`SheathParams::max_wrap_deg`].
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Self::FRICTION_COEFFICIENT.check("friction_coefficient", self.friction_coefficient)?;
        Self::ROUTE_WRAP_DEG.check("route_wrap_deg", self.route_wrap_deg)?;
        Self::PRETENSION_N.check("pretension_n", self.pretension_n)?;
        Self::TENDON_STIFFNESS
            .check("tendon_stiffness_n_per_mm", self.tendon_stiffness_n_per_mm)?;
        Self::DISTAL_STIFFNESS
            .check("distal_stiffness_n_per_mm", self.distal_stiffness_n_per_mm)?;
        Self::BACKLASH_MM.check("drive_backlash_mm", self.drive_backlash_mm)?;
        Self::BACKLASH_MM.check("backlash_engagement_mm", self.backlash_engagement_mm)?;
        Self::PRESLIDING_MM.check("presliding_mm", self.presliding_mm)?;
        Bounds::closed(1.0, 200.0).check("elements", f64::from(self.elements))?;
        Self::PATH_MM_PER_RAD.check("sheath_path_mm_per_rad", self.sheath_path_mm_per_rad)?;
        Bounds::closed(0.0, self.max_wrap_deg()).check("route_wrap_deg", self.route_wrap_deg)?;
        Ok(())
    }

    /// The largest total wrap the elements resolve, deg: `μ dΦ ≤ 1` rad per
    /// element (beyond it one element would stand for a capstan ratio above
    /// e, and its balance loses accuracy). More elements allow more wrap.
    #[must_use]
    pub fn max_wrap_deg(&self) -> f64 {
        if self.friction_coefficient > 0.0 {
            (f64::from(self.elements) / self.friction_coefficient).to_degrees()
        } else {
            f64::INFINITY
        }
    }

    /// The largest sheath bend these parameters take, deg: 3600, or less
    /// where [`SheathParams::max_wrap_deg`] is the limit.
    #[must_use]
    pub fn max_sheath_deg(&self) -> f64 {
        (self.max_wrap_deg() - self.route_wrap_deg).clamp(0.0, 3600.0)
    }
}

/// How the tendons sit in their sheaths at rest: the history a real
/// instrument brings to an experiment (how it was last tensioned and moved).
///
/// `friction_a` and `friction_b` are the friction state `z ∈ [−1, 1]` of
/// every element of tendon `a` and `b` (+1: last slid toward the motor, as
/// after tensioning); the tensions along each tendon then follow the capstan
/// balance of that state, with the mean stretch of the tendon unchanged, so
/// the motors and the joint stay where they are. `backlash ∈ [−1, 1]` is
/// where the drive was homed inside its backlash (±1: against one flank).
/// The drive is zeroed with the joint straight, and the joint is straight
/// for every motor position inside the play, so the motor's zero lands
/// anywhere in it; unlike the friction states, which the first stroke
/// wipes out, that offset of the motor's zero lasts all run (−1: every
/// command lands one half-width further along). All zero is the idealised
/// rest state: uniform pretension, no friction mobilised, the drive homed
/// at the middle of its play.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Seating {
    /// Friction state of tendon `a`'s elements, `[−1, 1]`.
    pub friction_a: f64,
    /// Friction state of tendon `b`'s elements, `[−1, 1]`.
    pub friction_b: f64,
    /// Where the drive was homed inside its backlash, `[−1, 1]` of its
    /// half-width (used by [`crate::Plant`], which owns the drive).
    pub backlash: f64,
}

impl Seating {
    /// Checks that every field lies in `[−1, 1]`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `seating.friction_a`,
    /// `seating.friction_b` or `seating.backlash`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(-1.0, 1.0).check("seating.friction_a", self.friction_a)?;
        Bounds::closed(-1.0, 1.0).check("seating.friction_b", self.friction_b)?;
        Bounds::closed(-1.0, 1.0).check("seating.backlash", self.backlash)?;
        Ok(())
    }
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

/// The tendons at the joint for given positions of their distal ends.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distal {
    /// Tension of tendon `a` at its anchor, N.
    pub tension_a_n: f64,
    /// Tension of tendon `b` at its anchor, N.
    pub tension_b_n: f64,
    /// `−dT_a/dw_a`, N/mm (≥ 0): how much tension tendon `a` loses per mm its
    /// anchor is pulled in, with the friction along the sheath answering.
    pub stiffness_a_n_per_mm: f64,
    /// `−dT_b/dw_b`, N/mm (≥ 0).
    pub stiffness_b_n_per_mm: f64,
}

impl Distal {
    /// Differential force `F = T_a − T_b`, N.
    #[must_use]
    pub fn force_n(&self) -> f64 {
        self.tension_a_n - self.tension_b_n
    }

    /// `T_a + T_b`, N.
    #[must_use]
    pub fn tension_sum_n(&self) -> f64 {
        self.tension_a_n + self.tension_b_n
    }
}

/// Below slack a tendon segment keeps `SLACK_STIFFNESS` of its stiffness so
/// the equations stay regular; the force this leaves (µN for mm of slack) is
/// far below anything measured.
const SLACK_STIFFNESS: f64 = 1e-9;

/// Stretch of a segment of stiffness `k` carrying tension `t` (the inverse of
/// `T = T₀ + k·stretch`; a tendon cannot push), and `d stretch/dT`.
fn stretch(t0: f64, k: f64, t: f64) -> (f64, f64) {
    if t >= 0.0 {
        ((t - t0) / k, 1.0 / k)
    } else {
        let ks = k * SLACK_STIFFNESS;
        (t / ks - t0 / k, 1.0 / ks)
    }
}

/// Iterations of a tendon's own solve before it is declared not converged.
const MAX_ITERATIONS: usize = 100;
/// A tendon is solved when its proximal end is within this of the motor, mm.
pub(crate) const POSITION_TOL_MM: f64 = 1e-10;

/// A solved trial state is reused for anchor positions this close to where
/// it was solved, mm (the joint's last Newton step is below 1e-10 rad).
const SOLVED_REUSE_MM: f64 = 1e-9;

/// One tendon through its sheath: `N` friction elements between the motor
/// (position `m`) and the distal run to the anchor (position `w`).
#[derive(Debug, Clone, PartialEq)]
struct Tendon {
    /// Committed position and friction state of each element, distal element
    /// last (a Bouc–Wen operator driven by the element's position).
    nodes: Vec<BoucWen>,
    /// Trial positions, mm (pull-in toward the motor positive), and the
    /// friction states they give.
    u: Vec<f64>,
    z: Vec<f64>,
    /// Anchor position and `−dT/dw` of the last solve that landed on the
    /// motor (within [`POSITION_TOL_MM`]: a march, or the whole chain's
    /// solve); `None` when the trial state is not solved.
    solved: Option<(f64, f64)>,
    /// Trial and committed tension at the anchor, N.
    tension: f64,
    tension_committed: f64,
    /// Committed tension one commit earlier, N (for extrapolating the next guess).
    tension_before: f64,
    /// Trial and committed motor positions, mm.
    motor: f64,
    motor_committed: f64,
    /// Whether a solve since the last commit needed the whole chain: the
    /// next ones go to it first (a joint's search for its balance calls the
    /// solve tens of times a tick, and shooting near where it failed fails
    /// again: 50 N and 1000 N of pretension run 4.7× and 5.1× faster).
    steep: bool,
}

/// The constants of one solve, shared by both tendons.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Chain {
    t0: f64,
    /// Stiffness of one sheath segment `N·k`, and of the distal run.
    k_segment: f64,
    k_distal: f64,
    /// `μ dΦ`: the wrap of one element times the friction coefficient.
    mu_dphi: f64,
    /// Path lengthening of each tendon by the sheath's bend, mm.
    path_mm: f64,
}

/// A march along a tendon from its anchor to the motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct March {
    /// Where the proximal end lands minus where the motor is, mm.
    pub(crate) residual_mm: f64,
    /// Its derivatives by the anchor tension (mm/N, > 0) and by the anchor's position (> 0).
    pub(crate) by_tension: f64,
    pub(crate) by_anchor: f64,
}

impl Tendon {
    fn new(elements: usize, presliding_mm: f64, t0: f64) -> Result<Self> {
        let dahl = BoucWenParams {
            a: 1.0 / presliding_mm,
            beta: 1.0 / presliding_mm,
            gamma: 0.0,
            n: 1.0,
            alpha: 0.0,
        };
        let node = BoucWen::new(dahl, 0.0)?;
        Ok(Self {
            nodes: vec![node; elements],
            u: vec![0.0; elements],
            z: vec![0.0; elements],
            solved: None,
            tension: t0,
            tension_committed: t0,
            tension_before: t0,
            motor: 0.0,
            motor_committed: 0.0,
            steep: false,
        })
    }

    /// Rest with both ends at 0 and every element at friction state `z`: the
    /// tensions follow the element balances of `z`, scaled so the tendon's
    /// total stretch is what uniform `T₀` gives (uniform `T₀` for `z = 0`).
    fn seat(&mut self, chain: &Chain, z: f64) {
        let n = self.nodes.len();
        let ratio = element_ratio(chain.mu_dphi, z).0;
        // from the anchor: T_N = T_d, T_i = T_d ratio^(N−i); Σ (T_s − T₀)/k_s
        // equals the path the bent sheath added (motor at `path`, anchor at 0)
        let (mut weighted, mut r) = (1.0 / chain.k_distal, 1.0);
        for _ in 0..n {
            r *= ratio;
            weighted += r / chain.k_segment;
        }
        let plain = 1.0 / chain.k_distal + n as f64 / chain.k_segment;
        let t_d = (chain.t0 * plain + chain.path_mm) / weighted;
        let mut t = t_d;
        let mut u = (t - chain.t0) / chain.k_distal;
        for i in (0..n).rev() {
            self.u[i] = u;
            self.z[i] = z;
            self.nodes[i].set_state(u, z);
            t *= ratio;
            u += (t - chain.t0) / chain.k_segment;
        }
        self.tension = t_d;
        self.tension_committed = t_d;
        self.tension_before = t_d;
        self.motor = chain.path_mm;
        self.motor_committed = chain.path_mm;
        self.solved = None;
        self.steep = false;
    }

    /// Marches from the anchor at `w` with tension `t` to the motor, writing
    /// the trial positions: element by element `T_prox = T_dist·ratio(z(u))`,
    /// segment by segment `u_prox = u_dist + stretch(T)`.
    fn march(&mut self, chain: &Chain, t: f64, w: f64) -> March {
        let (x, dx) = stretch(chain.t0, chain.k_distal, t);
        let (mut u, mut du_dt, mut du_dw) = (w + x, dx, 1.0);
        let (mut t, mut dt_dt, mut dt_dw) = (t, 1.0, 0.0);
        for i in (0..self.nodes.len()).rev() {
            self.u[i] = u;
            let (z, dz) = self.nodes[i].trial(u);
            self.z[i] = z;
            // a slack element presses on nothing: no friction
            let (ratio, dratio) = if t > 0.0 {
                element_ratio(chain.mu_dphi, z)
            } else {
                (1.0, 0.0)
            };
            let dt_du = t * dratio * dz;
            dt_dt = dt_dt * ratio + dt_du * du_dt;
            dt_dw = dt_dw * ratio + dt_du * du_dw;
            t *= ratio;
            let (x, dx) = stretch(chain.t0, chain.k_segment, t);
            u += x;
            du_dt += dx * dt_dt;
            du_dw += dx * dt_dw;
        }
        let residual_mm = u - self.motor;
        self.solved = (residual_mm.abs() <= POSITION_TOL_MM).then_some((w, du_dw / du_dt));
        March {
            residual_mm,
            by_tension: du_dt,
            by_anchor: du_dw,
        }
    }

    /// Solves the tendon with its anchor at `w`. Returns `−dT/dw` and whether
    /// it converged; the trial state holds the answer.
    ///
    /// First by shooting ([`Tendon::shoot`]): cheap, and exact wherever the
    /// tension can be resolved finely enough. Where the elements' friction is
    /// stiffer than the tendon between them (a high pretension over a short
    /// pre-sliding, a soft tendon) the march amplifies a change of the anchor
    /// tension element by element (by a factor of order `1 + T μdΦ ∂z/∂u /
    /// (N k)` each): at 50 N and 270 deg the proximal end moved by 7·10¹² mm
    /// per N of anchor tension, 0.05 mm per bit of it, and no `f64` tension
    /// lands it within [`POSITION_TOL_MM`]. Then the whole chain is solved at
    /// once ([`Tendon::solve_whole`]), which has no such amplification; if
    /// that fails where shooting has failed earlier in the tick, shooting is
    /// tried again.
    fn solve(&mut self, chain: &Chain, w: f64) -> (f64, bool) {
        if let Some((at, stiffness)) = self.solved {
            // already solved this close to w: the answer moves by less than the tolerance
            if (at - w).abs() <= SOLVED_REUSE_MM {
                return (stiffness, true);
            }
        }
        if !self.steep {
            if let (stiffness, true) = self.shoot(chain, w) {
                return (stiffness, true);
            }
            self.steep = true;
            return self.solve_whole(chain, w);
        }
        match self.solve_whole(chain, w) {
            (stiffness, true) => (stiffness, true),
            // where the whole chain does not converge, shooting still may
            (_, false) => self.shoot(chain, w),
        }
    }

    /// Shooting: the anchor tension for which the proximal end lands on the
    /// motor, a strictly increasing function of the tension, found by
    /// Newton's method kept inside a bracket. Returns `−dT/dw` and whether it
    /// converged (the trial state holds the answer then).
    fn shoot(&mut self, chain: &Chain, w: f64) -> (f64, bool) {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut t = self.tension;
        let mut last = f64::INFINITY;
        for _ in 0..MAX_ITERATIONS {
            let m = self.march(chain, t, w);
            if !(m.residual_mm.is_finite() && m.by_tension > 0.0) {
                return (0.0, false);
            }
            let r = m.residual_mm;
            if r.abs() <= POSITION_TOL_MM {
                self.tension = t;
                return (m.by_anchor / m.by_tension, true);
            }
            // collapsed to a few of the tension's ulps short of the motor:
            // the march is too steep for the arithmetic here
            if hi - lo <= 4.0 * f64::EPSILON * (1.0 + t.abs()) {
                return (0.0, false);
            }
            if r > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let bracketed = lo.is_finite() && hi.is_finite();
            let newton = t - r / m.by_tension;
            // Newton inside the bracket while it at least halves the residual;
            // bisection otherwise (a kink of the slack law or of a reversal)
            t = if newton > lo && newton < hi && (!bracketed || r.abs() < 0.5 * last) {
                newton
            } else if bracketed {
                0.5 * (lo + hi)
            } else {
                // no bracket on that side yet: step out by twice the Newton distance
                let reach = 2.0 * (newton - t).abs().max(chain.t0 * 1e-6);
                if r > 0.0 { t - reach } else { t + reach }
            };
            last = r.abs();
        }
        (0.0, false)
    }

    /// Newton's method on all `N` element balances at once, the positions
    /// `u_i` the unknowns, from the committed positions (a balanced state a
    /// tick away; the failed march's positions can be far off). Element `i`
    /// balances the segment on its proximal side against the one on its
    /// distal side (the distal run for the last element) through its
    /// friction:
    /// ```text
    /// R_i = T(u_{i−1} − u_i) − ratio(z_i(u_i)) T(u_i − u_{i+1}),  u_{−1} = m, u_N = w
    /// ```
    /// Each `T` rises with its stretch and each `z_i` with `u_i` (Dahl's
    /// `dz/du ≥ 0`), so `−∂R/∂u` is tridiagonal with a positive diagonal that
    /// dominates its negative neighbours: an M-matrix, solved by Thomas's
    /// algorithm without pivoting, whose conditioning does not grow with the
    /// friction's stiffness as the march's does. Each step is halved until
    /// `Σ R_i²` falls (the kinks of a reversal and of slack). Returns
    /// `−dT/dw` (from the same Jacobian) and whether it converged: a full
    /// step moving no element by more than [`POSITION_TOL_MM`], or, where no
    /// step descends, every balance holding to the arithmetic's resolution.
    fn solve_whole(&mut self, chain: &Chain, w: f64) -> (f64, bool) {
        let n = self.nodes.len();
        for (u, node) in self.u.iter_mut().zip(&self.nodes) {
            *u = node.x();
        }
        let mut sys = Balances::new(n);
        let mut merit = sys.evaluate(self, chain, &self.u, w);
        let mut trial = vec![0.0; n];
        for _ in 0..WHOLE_ITERATIONS {
            if !merit.is_finite() {
                break;
            }
            // −R into the step, then J Δ = −R
            for (d, r) in sys.step.iter_mut().zip(&sys.r) {
                *d = -r;
            }
            if !sys.solve_step() {
                break;
            }
            let largest = sys.step.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
            if largest <= POSITION_TOL_MM {
                // converged: the last step taken (it squares the residual)
                for (u, d) in self.u.iter_mut().zip(&sys.step) {
                    *u += d;
                }
                sys.evaluate(self, chain, &self.u, w);
                return self.accept(&mut sys, w);
            }
            let mut alpha = 1.0;
            let mut taken = false;
            for _ in 0..LINE_SEARCH_HALVINGS {
                for ((t, u), d) in trial.iter_mut().zip(&self.u).zip(&sys.step) {
                    *t = u + alpha * d;
                }
                let next = sys.evaluate(self, chain, &trial, w);
                if next < merit {
                    merit = next;
                    taken = true;
                    break;
                }
                alpha *= 0.5;
            }
            if taken {
                self.u.copy_from_slice(&trial);
                // the Jacobian at the new positions
                sys.evaluate(self, chain, &self.u, w);
                continue;
            }
            // no descent along Newton's step: none is left to find where
            // every balance holds to the arithmetic's resolution (the step
            // can stay above the tolerance where the Jacobian is badly
            // conditioned); otherwise the solve has failed
            sys.evaluate(self, chain, &self.u, w);
            if sys.resolved {
                return self.accept(&mut sys, w);
            }
            break;
        }
        self.solved = None;
        (0.0, false)
    }

    /// Takes the whole-chain solve's evaluated balances as the solution:
    /// the friction states, the anchor tension and `−dT/dw` there.
    fn accept(&mut self, sys: &mut Balances, w: f64) -> (f64, bool) {
        let stiffness = sys.anchor_stiffness();
        if !stiffness.is_finite() {
            self.solved = None;
            return (0.0, false);
        }
        self.z.copy_from_slice(&sys.z);
        self.tension = sys.anchor_tension;
        self.solved = Some((w, stiffness));
        (stiffness, true)
    }

    /// Tension of the first segment, at the motor (trial state; 0 when slack).
    fn proximal_tension(&self, chain: &Chain) -> f64 {
        (chain.t0 + chain.k_segment * (self.motor - self.u[0])).max(0.0)
    }

    fn commit(&mut self) {
        for ((node, &u), &z) in self.nodes.iter_mut().zip(&self.u).zip(&self.z) {
            node.set_state(u, z);
        }
        self.motor_committed = self.motor;
        self.tension_before = self.tension_committed;
        self.tension_committed = self.tension;
        self.steep = false;
    }

    fn discard(&mut self) {
        for ((u, z), node) in self.u.iter_mut().zip(&mut self.z).zip(&self.nodes) {
            *u = node.x();
            *z = node.z();
        }
        self.solved = None;
        self.motor = self.motor_committed;
        self.tension = self.tension_committed;
        self.steep = false;
    }

    fn mean_friction_state(&self) -> f64 {
        self.nodes.iter().map(BoucWen::z).sum::<f64>() / self.nodes.len() as f64
    }
}

/// Newton iterations of the whole-chain solve before it is declared not converged.
const WHOLE_ITERATIONS: usize = 100;
/// Halvings of a whole-chain Newton step before the step is given up.
const LINE_SEARCH_HALVINGS: usize = 40;
/// A balance within this many times what rounding alone leaves of it
/// holds ([`Balances::resolved`]).
const RESOLUTION_ULPS: f64 = 16.0;

/// Tension of a segment of stiffness `k` stretched by `x` beyond its length
/// at `T₀` (the inverse of [`stretch`]), and `dT/dx`.
fn tension(t0: f64, k: f64, x: f64) -> (f64, f64) {
    let t = t0 + k * x;
    if t >= 0.0 {
        (t, k)
    } else {
        let ks = k * SLACK_STIFFNESS;
        (ks * (x + t0 / k), ks)
    }
}

/// The element balances of one tendon, their tridiagonal Jacobian by the
/// positions, and scratch for its solve ([`Tendon::solve_whole`]).
struct Balances {
    r: Vec<f64>,
    /// `∂R_i/∂u_{i−1}`, `∂R_i/∂u_i`, `∂R_i/∂u_{i+1}`.
    lower: Vec<f64>,
    diag: Vec<f64>,
    upper: Vec<f64>,
    /// Friction states at the evaluated positions.
    z: Vec<f64>,
    /// Whether every balance holds to [`RESOLUTION_ULPS`] times what
    /// rounding alone leaves of it, at the evaluated positions.
    resolved: bool,
    /// The Newton step (the right-hand side before [`Balances::solve_step`]),
    /// and the elimination's scratch.
    step: Vec<f64>,
    scratch: Vec<f64>,
    /// Tension of the distal run and `∂T/∂u_{N−1}`, and the last element's
    /// ratio, at the evaluated positions.
    anchor_tension: f64,
    anchor_slope: f64,
    anchor_ratio: f64,
}

impl Balances {
    fn new(n: usize) -> Self {
        Self {
            r: vec![0.0; n],
            lower: vec![0.0; n],
            diag: vec![0.0; n],
            upper: vec![0.0; n],
            z: vec![0.0; n],
            resolved: false,
            step: vec![0.0; n],
            scratch: vec![0.0; n],
            anchor_tension: 0.0,
            anchor_slope: 0.0,
            anchor_ratio: 1.0,
        }
    }

    /// Evaluates the balances and their Jacobian with the elements at `u`
    /// (motor at `tendon.motor`, anchor at `w`); returns `Σ R_i²`.
    fn evaluate(&mut self, tendon: &Tendon, chain: &Chain, u: &[f64], w: f64) -> f64 {
        let n = u.len();
        let mut merit = 0.0;
        self.resolved = true;
        for i in (0..n).rev() {
            let last = i + 1 == n;
            let (previous, here) = (if i == 0 { tendon.motor } else { u[i - 1] }, u[i]);
            let next = if last { w } else { u[i + 1] };
            let k_next = if last {
                chain.k_distal
            } else {
                chain.k_segment
            };
            let (distal, distal_slope) = tension(chain.t0, k_next, here - next);
            let (proximal, proximal_slope) = tension(chain.t0, chain.k_segment, previous - here);
            let (z, dz) = tendon.nodes[i].trial(here);
            // a slack element presses on nothing: no friction
            let (ratio, dratio) = if distal > 0.0 {
                element_ratio(chain.mu_dphi, z)
            } else {
                (1.0, 0.0)
            };
            let r = proximal - ratio * distal;
            // what rounding alone leaves of the balance: an ulp of each
            // tension and of each position its stretch is the difference
            // of, times the segment's stiffness
            let rounding = f64::EPSILON
                * (proximal.abs()
                    + ratio * distal.abs()
                    + proximal_slope * (previous.abs() + here.abs())
                    + ratio * distal_slope * (here.abs() + next.abs()));
            self.resolved &= r.abs() <= RESOLUTION_ULPS * rounding;
            self.z[i] = z;
            self.r[i] = r;
            self.lower[i] = proximal_slope;
            self.diag[i] = -proximal_slope - dratio * dz * distal - ratio * distal_slope;
            self.upper[i] = ratio * distal_slope;
            if last {
                self.anchor_tension = distal;
                self.anchor_slope = distal_slope;
                self.anchor_ratio = ratio;
            }
            merit += r * r;
        }
        merit
    }

    /// Solves `J x = step` in place (Thomas's algorithm: `−J` is an
    /// M-matrix, so no pivoting); false if a pivot vanished.
    fn solve_step(&mut self) -> bool {
        let n = self.step.len();
        for i in 0..n {
            let (pivot, rhs) = if i == 0 {
                (self.diag[0], self.step[0])
            } else {
                (
                    self.diag[i] - self.lower[i] * self.scratch[i - 1],
                    self.step[i] - self.lower[i] * self.step[i - 1],
                )
            };
            if pivot == 0.0 || !pivot.is_finite() {
                return false;
            }
            self.scratch[i] = self.upper[i] / pivot;
            self.step[i] = rhs / pivot;
        }
        for i in (0..n.saturating_sub(1)).rev() {
            self.step[i] -= self.scratch[i] * self.step[i + 1];
        }
        self.step.iter().all(|d| d.is_finite())
    }

    /// `−dT/dw` of the anchor tension, the chain following the anchor:
    /// `J x = −∂R/∂w` (only the last balance holds `w`), then
    /// `dT/dw = T'(x_{N−1} − 1)`.
    fn anchor_stiffness(&mut self) -> f64 {
        let n = self.step.len();
        self.step.fill(0.0);
        self.step[n - 1] = -self.anchor_ratio * self.anchor_slope;
        if !self.solve_step() {
            return f64::NAN;
        }
        self.anchor_slope * (1.0 - self.step[n - 1])
    }
}

/// Proximal-to-distal tension ratio of one element with friction state `z`,
/// `(1 + μdΦ z/2)/(1 − μdΦ z/2)` (the element balance
/// `T_prox − T_dist = μ dΦ z (T_prox + T_dist)/2`; `e^{μdΦ z}` to third order),
/// and its derivative by `z`.
fn element_ratio(mu_dphi: f64, z: f64) -> (f64, f64) {
    let h = 0.5 * mu_dphi * z;
    let den = 1.0 - h;
    ((1.0 + h) / den, mu_dphi / (den * den))
}

/// The stateful transmission for one sheath configuration.
///
/// **Motors.** The controller turns the command θ_c into the paths of Eq. 1:
/// tendon `a` must be pulled in by `w_a(θ) = −ΔL_a(θ) = s(θ) − c(θ)` and
/// tendon `b` by `w_b(θ) = −s(θ) − c(θ)`, with `s` the differential stroke
/// and `c` the common mode (both paths lengthen as the joint bends). The
/// drive takes the command through its backlash first ([`crate::Backlash`] on
/// the differential stroke, half-width `drive_backlash_mm`, in [`crate::Plant`]),
/// giving θ_b, and the motors take tendon `a` to `m_a = s(θ_b) − c(θ_b)` and
/// `b` to `m_b = −s(θ_b) − c(θ_b)` ([`TendonSheath::advance`]), plus the path
/// the bent sheath adds (`sheath_path_mm_per_rad`). The controller computes
/// both modes at θ_c; the play sits after it, in the drive that moves the
/// pair, so the tendons receive the two modes of the angle the drive's
/// output stands for, θ_b: inside the dead zone after a reversal both hold
/// still (a common mode that kept moving there would have the pair take up
/// or pay out length through a drive that is not turning). When the joint lags
/// (θ_a < θ_b) the motors have paid out more common mode than the joint
/// takes up, and both tendons lose tension: a lagging joint is also a
/// slacker one.
///
/// **Tendons.** Each tendon runs through its sheath as a chain of `N`
/// elements (`elements`). The sheath's wrap — its configuration plus the
/// instrument's own routing, `Φ = Φ_sheath + Φ_route` — is spread evenly,
/// `dΦ = Φ/N` per element. Between the motor, the elements and the anchor in
/// the joint the tendon is elastic: `N` segments of stiffness `N·k` (`k = EA/L`
/// of the tendon in the sheath) and a distal run `k_d`, each carrying
/// `T = T₀ + k·(stretch)` and nothing once slack.
///
/// **Friction.** Element `i` presses on the sheath with the normal force of a
/// tendon under tension `T̄_i` wrapped by `dΦ` (the mean of the tensions on
/// its two sides), so the friction it can give is `μ dΦ T̄_i`, and it gives
/// the part `z_i` of it:
/// ```text
/// T_{i−1} − T_i = μ dΦ T̄_i z_i,      dz_i = (1/δ)(1 − z_i sign(du_i)) du_i
/// ```
/// `z_i` is a Bouc–Wen operator driven by the element's own displacement `u_i`
/// ([`BoucWen`] with `A = β = 1/δ`, `γ = 0`, `n = 1`: Dahl's law), so friction
/// builds up over a pre-sliding displacement of a few `δ` instead of jumping.
/// Sliding everywhere (`z = ±1`) the element balances chain to
/// `T_p/T_d = ((1 + μdΦ/2)/(1 − μdΦ/2))^N → e^{±μΦ}`: the capstan law emerges
/// along the chain, it is not applied as a lump. A slack tendon presses on
/// nothing and has no friction to give.
///
/// **What follows from it.** After a reversal of the motor the change of
/// tension enters at the proximal end and travels toward the joint as a front
/// of elements that slip the other way; until it arrives the joint feels
/// nothing (the dead zone), as it arrives the distal tension changes first
/// slowly, then at the sliding rate (the rounded transition), and the stroke
/// spent on turning the friction round is lost (lost motion). The dead zone
/// and the loop grow with `μΦ` and with the load, by the mechanism.
///
/// **Solving.** The transmission is quasi-static (tendon and motor inertia
/// are negligible at the paper's 0.159 Hz). For a given anchor position and
/// anchor tension, one march from the anchor to the motor gives every
/// element's position and tension in turn, each element's `z_i(u_i)`
/// integrated exactly from its committed state (so nothing drifts between
/// ticks). Where the march lands relative to the motor is strictly
/// increasing in the anchor tension, so a bracketed Newton iteration on that
/// one number solves the tendon (shooting). The march amplifies a change of
/// the anchor tension element by element, by a factor of order
/// `1 + T μdΦ ∂z/∂u/(N k)` each (the friction's pre-sliding stiffness
/// against the tendon's between elements); where that makes the landing
/// steeper than the arithmetic can resolve (at 50 N of pretension and
/// 270 deg, 7·10¹² mm per N over 20 elements), the tendon is solved as
/// a whole instead: Newton's method on all `N` element balances at once,
/// whose Jacobian is a tridiagonal M-matrix that does not amplify anything.
/// The joint sees the condensed result: the anchor tension and its
/// stiffness `−dT/dw`, carried along the march as derivatives (or solved
/// from the whole chain's Jacobian), which gives its own Newton step the
/// exact slope. Nothing moves until [`TendonSheath::commit`].
#[derive(Debug, Clone, PartialEq)]
pub struct TendonSheath {
    params: SheathParams,
    sheath_deg: f64,
    chain: Chain,
    a: Tendon,
    b: Tendon,
    /// Whether the last solve of both tendons converged.
    converged: bool,
}

impl TendonSheath {
    /// A transmission through a sheath bent by `sheath_deg` (`[0, 3600]` deg),
    /// at rest: zero stroke, uniform pretension, no friction mobilised.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter of `params` out of
    /// its range ([`SheathParams::validate`]), or `sheath_deg`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn new(params: SheathParams, sheath_deg: f64) -> Result<Self> {
        params.validate()?;
        Bounds::closed(0.0, params.max_sheath_deg()).check("sheath_deg", sheath_deg)?;
        let n = params.elements as usize;
        let mut out = Self {
            params,
            sheath_deg,
            chain: Chain {
                t0: params.pretension_n,
                k_segment: f64::from(params.elements) * params.tendon_stiffness_n_per_mm,
                k_distal: params.distal_stiffness_n_per_mm,
                mu_dphi: 0.0,
                path_mm: 0.0,
            },
            a: Tendon::new(n, params.presliding_mm, params.pretension_n)?,
            b: Tendon::new(n, params.presliding_mm, params.pretension_n)?,
            converged: true,
        };
        out.set_sheath_deg(sheath_deg)?;
        out.reset(&Seating::default())?;
        Ok(out)
    }

    /// Changes the sheath configuration (total bend, deg). The tendons stay where
    /// they are in the sheath, so the distal force does not jump; the next
    /// solve lets them slide onto the new friction if they must.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `sheath_deg` when it is outside
    /// `[0, 3600]` deg or above [`SheathParams::max_sheath_deg`] (NaN
    /// included); the transmission is then unchanged.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        let p = &self.params;
        Bounds::closed(0.0, p.max_sheath_deg()).check("sheath_deg", sheath_deg)?;
        self.sheath_deg = sheath_deg;
        self.a.solved = None;
        self.b.solved = None;
        self.chain.path_mm = p.sheath_path_mm_per_rad * sheath_deg.to_radians();
        self.chain.mu_dphi = p.friction_coefficient * (sheath_deg + p.route_wrap_deg).to_radians()
            / f64::from(p.elements);
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

    /// `e^{μΦ}`-like ratio of the proximal to the distal tension of a tendon
    /// sliding toward the motor over the whole wrap, as the element chain gives it.
    #[must_use]
    pub fn capstan_ratio(&self) -> f64 {
        element_ratio(self.chain.mu_dphi, 1.0)
            .0
            .powi(self.params.elements as i32)
    }

    /// Back to rest with the motors at zero stroke and the tendons seated as
    /// `seating` says (see [`Seating`]; `Seating::default()` for the idealised rest).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the field of `seating` out of `[−1, 1]`;
    /// the transmission is then unchanged.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn reset(&mut self, seating: &Seating) -> Result<()> {
        seating.validate()?;
        self.a.seat(&self.chain, seating.friction_a);
        self.b.seat(&self.chain, seating.friction_b);
        self.converged = true;
        Ok(())
    }

    /// Moves the motors to the differential stroke `differential_mm` and the
    /// common mode `common_mode_mm` (paid out on both tendons), mm, both after
    /// the drive's backlash. The tendons answer when the joint's position is known:
    /// [`TendonSheath::distal`], then [`TendonSheath::commit`] or
    /// [`TendonSheath::discard`].
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] naming `differential stroke` or `common-mode
    /// stroke` for a NaN or infinite input; nothing moves then.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn advance(&mut self, differential_mm: f64, common_mode_mm: f64) -> Result<()> {
        finite("differential stroke", differential_mm)?;
        finite("common-mode stroke", common_mode_mm)?;
        let s = differential_mm;
        self.a.motor = s - common_mode_mm + self.chain.path_mm;
        self.b.motor = -s - common_mode_mm + self.chain.path_mm;
        self.a.solved = None;
        self.b.solved = None;
        self.a.steep = false;
        self.b.steep = false;
        Ok(())
    }

    /// The tendons at the joint if their anchors were pulled in by `w_a_mm`
    /// and `w_b_mm` (`−ΔL_a(θ)`, `−ΔL_b(θ)` of Eq. 1), from the committed state
    /// and the motors' last [`advance`](TendonSheath::advance). Solves the
    /// trial state; nothing is committed.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] naming `w_a_mm` or `w_b_mm` for a NaN or
    /// infinite position (the trial state is then unchanged);
    /// [`ModelError::Diverged`] if the element balances did not converge.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    /// [`ModelError::Diverged`]: crate::ModelError::Diverged
    pub fn distal(&mut self, w_a_mm: f64, w_b_mm: f64) -> Result<Distal> {
        finite("w_a_mm", w_a_mm)?;
        finite("w_b_mm", w_b_mm)?;
        let d = self.solve(w_a_mm, w_b_mm);
        if self.converged {
            Ok(d)
        } else {
            Err(ModelError::Diverged {
                what: "tendon element balance",
            })
        }
    }

    /// [`TendonSheath::distal`] for positions the caller knows are finite;
    /// [`TendonSheath::converged`] tells whether the solve converged.
    pub(crate) fn solve(&mut self, w_a_mm: f64, w_b_mm: f64) -> Distal {
        let chain = self.chain;
        let (ka, ok_a) = self.a.solve(&chain, w_a_mm);
        let (kb, ok_b) = self.b.solve(&chain, w_b_mm);
        self.converged = ok_a && ok_b;
        // a slack tendon's regularised tension (at most µN below zero) reads as 0
        Distal {
            tension_a_n: self.a.tension.max(0.0),
            tension_b_n: self.b.tension.max(0.0),
            stiffness_a_n_per_mm: ka,
            stiffness_b_n_per_mm: kb,
        }
    }

    /// Anchor tensions `(T_a, T_b)` extrapolated from the last two commits, N:
    /// the next tick's first guess.
    pub(crate) fn extrapolated_tensions(&self) -> (f64, f64) {
        let next = |t: &Tendon| 2.0 * t.tension_committed - t.tension_before;
        (next(&self.a), next(&self.b))
    }

    /// Marches both tendons from their anchors at `w_a`, `w_b` with tensions
    /// `t_a`, `t_b` (the joint's coupled Newton step; see [`March`]). The
    /// trial state takes the tensions and the positions the march wrote.
    pub(crate) fn march(&mut self, t_a: f64, t_b: f64, w_a: f64, w_b: f64) -> (March, March) {
        let chain = self.chain;
        let ma = self.a.march(&chain, t_a, w_a);
        let mb = self.b.march(&chain, t_b, w_b);
        self.a.tension = t_a;
        self.b.tension = t_b;
        (ma, mb)
    }

    /// Whether the last solve converged.
    pub(crate) fn converged(&self) -> bool {
        self.converged
    }

    /// Records that the joint settled with the anchors at `w_a_mm`, `w_b_mm`:
    /// the tendons and their friction states move there.
    ///
    /// # Errors
    /// As [`TendonSheath::distal`]; nothing is committed then.
    pub fn commit(&mut self, w_a_mm: f64, w_b_mm: f64) -> Result<Distal> {
        let d = self.distal(w_a_mm, w_b_mm)?;
        self.a.commit();
        self.b.commit();
        Ok(d)
    }

    /// Forgets the trial state: back to the last commit (motors included).
    pub fn discard(&mut self) {
        self.a.discard();
        self.b.discard();
    }

    /// Mean friction state of the pair, `(z̄_a − z̄_b)/2 ∈ [−1, 1]`, committed:
    /// +1 when the whole pair slides as when tendon `a` is pulled in and `b`
    /// paid out, −1 the other way, 0 with no friction mobilised.
    #[must_use]
    pub fn friction_state(&self) -> f64 {
        0.5 * (self.a.mean_friction_state() - self.b.mean_friction_state())
    }

    /// Upper bound of the pair's differential stiffness at the joint,
    /// `−d(T_a − T_b)/dp` for anchors moving by `±p`: both distal runs, N/mm.
    #[must_use]
    pub fn taut_stiffness_n_per_mm(&self) -> f64 {
        2.0 * self.params.distal_stiffness_n_per_mm
    }

    /// Tensions at both ends of both tendons in the trial state (the committed
    /// one after [`TendonSheath::commit`]), for the anchors at `distal`.
    #[must_use]
    pub fn tensions(&self, distal: &Distal) -> TendonTensions {
        TendonTensions {
            a_distal_n: distal.tension_a_n,
            b_distal_n: distal.tension_b_n,
            a_proximal_n: self.a.proximal_tension(&self.chain),
            b_proximal_n: self.b.proximal_tension(&self.chain),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::expect_range;

    /// Moderate, explicit parameters: these tests are about the mechanism, not the calibration.
    fn params() -> SheathParams {
        SheathParams {
            friction_coefficient: 0.2,
            route_wrap_deg: 30.0,
            pretension_n: 5.0,
            tendon_stiffness_n_per_mm: 15.0,
            distal_stiffness_n_per_mm: 300.0,
            drive_backlash_mm: 0.0,
            backlash_engagement_mm: 0.0,
            presliding_mm: 0.01,
            elements: 20,
            sheath_path_mm_per_rad: 0.0,
        }
    }

    /// Quasi-static equilibrium with a linear spring joint on the differential
    /// stroke, `F = K p` (K = 5 N/mm), anchors at `±p` (no common mode).
    fn settle(t: &mut TendonSheath, q: f64) -> f64 {
        t.advance(q, 0.0).unwrap();
        let joint_k = 5.0;
        let mut p = 0.0;
        // p is found by Newton on F(p) − K p with the condensed stiffness
        for _ in 0..50 {
            let d = t.distal(p, -p).unwrap();
            let r = d.force_n() - joint_k * p;
            let slope = -(d.stiffness_a_n_per_mm + d.stiffness_b_n_per_mm) - joint_k;
            let step = -r / slope;
            p += step;
            if step.abs() < 1e-12 {
                break;
            }
        }
        t.commit(p, -p).unwrap();
        p
    }

    /// The largest element imbalance of tendon `a`'s trial state, N.
    fn largest_imbalance(t: &TendonSheath, w: f64) -> f64 {
        let mut sys = Balances::new(t.a.nodes.len());
        sys.evaluate(&t.a, &t.chain, &t.a.u, w);
        sys.r.iter().fold(0.0_f64, |m, r| m.max(r.abs()))
    }

    #[test]
    fn the_whole_chain_solve_finds_what_shooting_finds() {
        // where shooting resolves the tension, solving all the element
        // balances at once from the committed positions lands on the same
        // state: anchor tension, stiffness and every element's position
        let mut t = TendonSheath::new(params(), 180.0).unwrap();
        let chain = t.chain;
        for (k, q) in [0.2, 0.5, 0.35, 0.1, -0.2].into_iter().enumerate() {
            t.advance(q, 0.0).unwrap();
            let w = 0.3 * q;
            let (shot, ok) = t.a.shoot(&chain, w);
            assert!(ok, "shooting at {q}");
            let (tension, u) = (t.a.tension, t.a.u.clone());
            t.a.discard();
            t.a.motor = q;
            let (whole, ok) = t.a.solve_whole(&chain, w);
            assert!(ok, "whole chain at {q}");
            assert!(
                (t.a.tension - tension).abs() < 1e-7,
                "{} vs {tension}",
                t.a.tension
            );
            assert!((whole / shot - 1.0).abs() < 1e-6, "{whole} vs {shot}");
            for (x, y) in t.a.u.iter().zip(&u) {
                assert!((x - y).abs() < 1e-9, "step {k}: {x} vs {y}");
            }
            t.commit(w, -w).unwrap();
        }
    }

    /// 50 N over a pre-sliding of 1 µm at 270°: each element's friction
    /// about nine times stiffer than the tendon beside it.
    fn stiff_friction() -> TendonSheath {
        let p = SheathParams {
            pretension_n: 50.0,
            presliding_mm: 1e-3,
            ..params()
        };
        TendonSheath::new(p, 270.0).unwrap()
    }

    #[test]
    fn friction_stiffer_than_the_tendon_is_solved_by_the_whole_chain() {
        // 50 N over a pre-sliding of 1 µm: each element's friction is about
        // nine times stiffer than the tendon beside it, and the march
        // amplifies a change of the anchor tension ~10¹⁹ times over the chain,
        // so shooting cannot land the proximal end; the solve still does,
        // with every element balanced and the stiffness the tension's slope
        let mut t = stiff_friction();
        let chain = t.chain;
        let mut shooting_failed = 0;
        for k in (0..=40).chain((0..40).rev()) {
            let q = 0.02 * f64::from(k);
            t.advance(q, 0.0).unwrap();
            let w = 0.5 * q;
            let mut probe = t.a.clone();
            if !probe.shoot(&chain, w).1 {
                shooting_failed += 1;
            }
            let d = t.distal(w, -w).unwrap();
            let imbalance = largest_imbalance(&t, w);
            assert!(
                imbalance < 1e-6,
                "imbalance {imbalance} at {q}, tension {}",
                d.tension_a_n
            );
            // the proximal end on the motor: the first segment's stretch
            // carries the first element's proximal tension
            let h = 1e-7;
            let ahead = t.distal(w + h, -w).unwrap();
            let slope = (d.tension_a_n - ahead.tension_a_n) / h;
            assert!(
                (slope / d.stiffness_a_n_per_mm - 1.0).abs() < 1e-3,
                "at {q}: {slope} vs {}",
                d.stiffness_a_n_per_mm
            );
            t.commit(w, -w).unwrap();
        }
        assert!(
            shooting_failed > 10,
            "shooting failed {shooting_failed} times"
        );
    }

    #[test]
    fn going_straight_to_the_whole_chain_changes_no_answer() {
        // a tick's solves after one that needed the whole chain skip
        // shooting; the same solves each starting afresh give the same
        // tensions and stiffnesses, and the flag is down after a commit
        let mut t = stiff_friction();
        let mut fresh = t.clone();
        let mut went_steep = 0;
        for k in (0..=30).chain((0..30).rev()) {
            let q = 0.02 * f64::from(k);
            t.advance(q, 0.0).unwrap();
            fresh.advance(q, 0.0).unwrap();
            // a joint's search: several anchor positions in one tick
            for j in 0..5 {
                let w = 0.5 * q + 1e-3 * f64::from(j);
                let d = t.distal(w, -w).unwrap();
                went_steep += usize::from(t.a.steep);
                fresh.a.steep = false;
                fresh.b.steep = false;
                let e = fresh.distal(w, -w).unwrap();
                assert!(
                    (d.tension_a_n - e.tension_a_n).abs() < 1e-7,
                    "{d:?} vs {e:?}"
                );
                assert!(
                    (d.tension_b_n - e.tension_b_n).abs() < 1e-7,
                    "{d:?} vs {e:?}"
                );
                let rel = d.stiffness_a_n_per_mm / e.stiffness_a_n_per_mm - 1.0;
                assert!(rel.abs() < 1e-6, "{d:?} vs {e:?}");
            }
            let w = 0.5 * q;
            t.commit(w, -w).unwrap();
            fresh.commit(w, -w).unwrap();
            assert!(!t.a.steep && !t.b.steep);
        }
        assert!(went_steep > 20, "the shortcut was taken {went_steep} times");
    }

    #[test]
    fn frictionless_pair_is_two_springs_in_series() {
        let p = SheathParams {
            friction_coefficient: 0.0,
            ..params()
        };
        let mut t = TendonSheath::new(p, 270.0).unwrap();
        t.advance(0.3, 0.0).unwrap();
        let d = t.distal(0.1, -0.1).unwrap();
        let k = 1.0 / (1.0 / p.tendon_stiffness_n_per_mm + 1.0 / p.distal_stiffness_n_per_mm);
        assert!(
            (d.tension_a_n - (p.pretension_n + k * 0.2)).abs() < 1e-9,
            "{d:?}"
        );
        assert!(
            (d.tension_b_n - (p.pretension_n - k * 0.2)).abs() < 1e-9,
            "{d:?}"
        );
        assert!((d.stiffness_a_n_per_mm - k).abs() < 1e-6 * k);
    }

    #[test]
    fn sliding_tendon_follows_the_capstan_law() {
        // tendon a pulled far with its anchor held: every element slides, and the
        // ratio of proximal to distal tension is the chain's capstan ratio ≈ e^{μΦ}
        let p = SheathParams {
            pretension_n: 20.0,
            ..params()
        };
        let mut t = TendonSheath::new(p, 180.0).unwrap();
        for k in 1..=200 {
            t.advance(0.01 * f64::from(k), 0.0).unwrap();
            t.commit(0.0, 0.0).unwrap();
        }
        let d = t.distal(0.0, 0.0).unwrap();
        let tt = t.tensions(&d);
        let ratio = tt.a_proximal_n / tt.a_distal_n;
        assert!((ratio / t.capstan_ratio() - 1.0).abs() < 1e-3, "{ratio}");
        let x = p.friction_coefficient * (180.0 + p.route_wrap_deg).to_radians();
        assert!((t.capstan_ratio() / x.exp() - 1.0).abs() < 1e-3);
        assert!(t.friction_state() > 0.99, "{}", t.friction_state());
    }

    #[test]
    fn reversal_has_a_dead_zone_then_a_rounded_transition() {
        // loaded, then reversed: the joint holds while the front travels, then
        // moves back; the slope grows continuously (no jump from 0 to sliding)
        let mut t = TendonSheath::new(params(), 180.0).unwrap();
        let step = 0.002;
        let mut top = 0.0;
        for k in 0..=500 {
            top = settle(&mut t, step * f64::from(k));
        }
        let mut ps = vec![top];
        for k in 1..=500 {
            ps.push(settle(&mut t, 1.0 - step * f64::from(k)));
        }
        let slopes: Vec<f64> = ps.windows(2).map(|w| (w[0] - w[1]) / step).collect();
        let sliding = slopes[400..].iter().sum::<f64>() / 100.0;
        assert!(sliding > 0.0);
        assert!(slopes[0] < 0.05 * sliding, "dead zone: {}", slopes[0]);
        for w in slopes.windows(2).take(300) {
            assert!(
                w[1] - w[0] < 0.2 * sliding,
                "slope jumped from {} to {}",
                w[0],
                w[1]
            );
        }
        assert!(
            ps.windows(2).all(|w| w[1] <= w[0] + 1e-12),
            "never overshoots"
        );
    }

    #[test]
    fn hysteresis_grows_with_sheath_bend() {
        let gap = |sheath_deg: f64| {
            let mut t = TendonSheath::new(params(), sheath_deg).unwrap();
            let p: Vec<f64> = (0..=700)
                .map(|k| settle(&mut t, (std::f64::consts::TAU * f64::from(k) / 400.0).sin()))
                .collect();
            (0..=200)
                .map(|m| (p[500 + m] - p[500 - m]).abs())
                .fold(0.0, f64::max)
        };
        let gaps: Vec<f64> = [0.0, 90.0, 180.0, 270.0].iter().map(|&s| gap(s)).collect();
        for w in gaps.windows(2) {
            assert!(w[1] > w[0], "loop must grow with the bend: {gaps:?}");
        }
    }

    #[test]
    fn slack_tendon_has_no_friction() {
        // tendon b paid out far: slack along its length, so no friction and no tension
        let mut t = TendonSheath::new(params(), 270.0).unwrap();
        for k in 1..=100 {
            t.advance(0.0, 0.01 * f64::from(k)).unwrap();
            t.commit(0.0, 0.0).unwrap();
        }
        let d = t.distal(0.0, 0.0).unwrap();
        assert!(
            d.tension_a_n.abs() < 1e-6 && d.tension_b_n.abs() < 1e-6,
            "{d:?}"
        );
        let tt = t.tensions(&d);
        assert!(tt.a_proximal_n.abs() < 1e-6);
    }

    #[test]
    fn seating_keeps_the_ends_and_balances_every_element() {
        let mut t = TendonSheath::new(params(), 180.0).unwrap();
        let seating = Seating {
            friction_a: 0.8,
            friction_b: -0.5,
            backlash: 0.0,
        };
        t.reset(&seating).unwrap();
        t.advance(0.0, 0.0).unwrap();
        // solving from the seated state at the same ends moves nothing
        let before = t.a.u.clone();
        let d = t.distal(0.0, 0.0).unwrap();
        for (x, y) in before.iter().zip(&t.a.u) {
            assert!((x - y).abs() < 1e-9);
        }
        // tendon a last slid toward the motor: less tension at the joint than at the motor
        let tt = t.tensions(&d);
        assert!(
            tt.a_proximal_n > tt.a_distal_n && tt.b_proximal_n < tt.b_distal_n,
            "{tt:?}"
        );
        assert!(t.friction_state() > 0.6);
        assert!(
            expect_range(
                t.reset(&Seating {
                    backlash: 1.5,
                    ..seating
                }),
                "seating.backlash"
            )
            .value
                == 1.5
        );
    }

    #[test]
    fn discard_returns_to_the_commit() {
        let mut t = TendonSheath::new(params(), 90.0).unwrap();
        settle(&mut t, 0.4);
        let before = t.clone();
        t.advance(0.9, 0.1).unwrap();
        t.distal(0.3, -0.3).unwrap();
        t.discard();
        assert_eq!(t.a.u, before.a.u);
        assert_eq!(t.a.motor, before.a.motor);
    }

    #[test]
    fn rejects_non_finite_and_meaningless_inputs() {
        let mut t = TendonSheath::new(params(), 0.0).unwrap();
        assert!(matches!(
            t.distal(f64::NAN, 0.0),
            Err(ModelError::NonFinite { name: "w_a_mm", .. })
        ));
        assert!(matches!(
            t.commit(0.0, f64::INFINITY),
            Err(ModelError::NonFinite { name: "w_b_mm", .. })
        ));
        assert!(matches!(
            t.advance(f64::NAN, 0.0),
            Err(ModelError::NonFinite {
                name: "differential stroke",
                ..
            })
        ));
        let p = SheathParams {
            friction_coefficient: -0.1,
            ..params()
        };
        assert_eq!(
            expect_range(TendonSheath::new(p, 0.0), "friction_coefficient").value,
            -0.1
        );
        let e = expect_range(TendonSheath::new(params(), -10.0), "sheath_deg");
        assert_eq!((e.value, e.bounds.min, e.bounds.max), (-10.0, 0.0, 3600.0));
        let p = SheathParams {
            elements: 0,
            ..params()
        };
        expect_range(TendonSheath::new(p, 0.0), "elements");
    }
}
