//! Mechanics of the continuum bending joint: the shape of the link chain, the
//! loads on it, and the quasi-static analytic solver.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::kinematics::TendonGeometry;
use crate::range::Bounds;
#[cfg(feature = "multibody")]
use crate::transmission::Distal;
use crate::transmission::TendonSheath;

/// Which joint model the plant uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointModelKind {
    /// Quasi-static closed-form balance with equal contact angles (fast).
    #[default]
    Analytic,
    /// A rapier3d multibody chain, integrated to rest every tick (cargo
    /// feature `multibody`).
    ///
    /// `2n` links hang from a fixed base (the overtube exit) by revolute joints
    /// about `+y`. Each contact carries the backbone's elasticity as rapier's
    /// implicit joint spring (`k_φ`), the tendon moment `τ_j` of
    /// [`JointParams`] as an internal torque pair on the two bodies it joins,
    /// gravity on the links' and the tool's masses, and the tip load as a force at
    /// the tool tip. The tendon force depends on where the joint is (through the
    /// distal stroke `p = Σ d_t sin φ_j`), so it is recomputed every internal step.
    ///
    /// Quasi-static use: every plant tick integrates the chain until it is at rest.
    /// Real links weigh a fraction of a gram, which would make the dynamics
    /// needlessly stiff; an armature (rotor-like inertia on each joint, no weight)
    /// and joint damping slow them to a critically damped settle of a few tens of
    /// milliseconds. They change how the chain gets to rest, not where it rests.
    ///
    /// rapier works in `f32` with glam types; this module converts at the boundary
    /// and works in metres, kilograms and newtons inside.
    Rapier,
}

/// Mechanical parameters of the bending joint and the distal tool. SI-ish units as named.
///
/// The joint is `2n` rolling links (two per segment, as Eq. 1's `2n` contact
/// angles), each bending by `φ_j` about the instrument's `+y` axis, so positive
/// θ bends the tip toward `+x`; the instrument axis is `+z`. The tendon pair
/// loads every contact with the generalised force of virtual work on Eq. 1:
/// ```text
/// τ_j = F d_t cos φ_j − (T_a + T_b)(R − B) sin φ_j        (N·mm)
/// ```
/// (`F = T_a − T_b`; the second term is the pretension's straightening moment).
/// Each contact has an elastic restoring moment `k_φ φ_j` (the backbone), and
/// gravity and a tip force act on the links and the tool. The analytic solver
/// assumes equal contact angles `φ_j = θ/2n` and solves the balance of
/// generalised forces along θ; the rapier model ([`JointModelKind::Rapier`])
/// lets every contact find its own angle.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JointParams {
    /// Bending stiffness `k_φ` of one rolling contact, N·mm/rad.
    pub contact_stiffness_nmm_per_rad: f64,
    /// Length of one link (half a segment), mm.
    pub link_length_mm: f64,
    /// Outer radius of the links, mm.
    pub link_radius_mm: f64,
    /// Mass of one link, g.
    pub link_mass_g: f64,
    /// Length of the distal tool (gripper) beyond the last link, mm.
    pub tool_length_mm: f64,
    /// Mass of the tool, g.
    pub tool_mass_g: f64,
    /// Gravity in the instrument frame (`z` along the instrument, bending toward `+x`), m/s².
    pub gravity_m_per_s2: [f64; 3],
    /// External force on the tool tip (tool–tissue contact), instrument frame, N.
    pub tip_load_n: [f64; 3],
    /// Mechanical range of the bend: hard stops at ±this, deg.
    pub max_theta_deg: f64,
}

impl Default for JointParams {
    fn default() -> Self {
        Self {
            contact_stiffness_nmm_per_rad: crate::calibration::FITTED_CONTACT_STIFFNESS,
            link_length_mm: 4.0,
            link_radius_mm: 2.0,
            link_mass_g: 0.2,
            tool_length_mm: 8.0,
            tool_mass_g: 0.8,
            gravity_m_per_s2: [-9.81, 0.0, 0.0],
            tip_load_n: [0.0; 3],
            max_theta_deg: 120.0,
        }
    }
}

impl JointParams {
    /// The range of `contact_stiffness_nmm_per_rad` (`validate`).
    pub(crate) const CONTACT_STIFFNESS: Bounds = Bounds::open(0.0, 1e6);

    /// Checks the parameters against their physical ranges.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range, in
    /// declaration order (vector components as `gravity_m_per_s2.x`,
    /// `tip_load_n.z`, …); `max_theta_deg` must lie in `[90, 170]` deg, and a
    /// NaN or infinite value is out of every range.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Self::CONTACT_STIFFNESS.check(
            "contact_stiffness_nmm_per_rad",
            self.contact_stiffness_nmm_per_rad,
        )?;
        Bounds::open(0.0, 1e3).check("link_length_mm", self.link_length_mm)?;
        Bounds::open(0.0, 1e3).check("link_radius_mm", self.link_radius_mm)?;
        Bounds::open(0.0, 1e4).check("link_mass_g", self.link_mass_g)?;
        Bounds::closed(0.0, 1e3).check("tool_length_mm", self.tool_length_mm)?;
        Bounds::closed(0.0, 1e4).check("tool_mass_g", self.tool_mass_g)?;
        for (name, v) in [
            ("gravity_m_per_s2.x", self.gravity_m_per_s2[0]),
            ("gravity_m_per_s2.y", self.gravity_m_per_s2[1]),
            ("gravity_m_per_s2.z", self.gravity_m_per_s2[2]),
        ] {
            Bounds::closed(-100.0, 100.0).check(name, v)?;
        }
        for (name, v) in [
            ("tip_load_n.x", self.tip_load_n[0]),
            ("tip_load_n.y", self.tip_load_n[1]),
            ("tip_load_n.z", self.tip_load_n[2]),
        ] {
            Bounds::closed(-100.0, 100.0).check(name, v)?;
        }
        Bounds::closed(90.0, 170.0).check("max_theta_deg", self.max_theta_deg)?;
        Ok(())
    }
}

/// Position of a point of the chain in the bending plane: (x, z) in mm.
pub(crate) type PlanePoint = [f64; 2];

/// Upper bound on `2n` supported without allocation.
pub(crate) const MAX_CONTACTS: usize = 32;

/// Generalised force of gravity and tip load along θ (N·mm/rad), with all
/// `2n` contacts at `φ = θ/2n`: `(1/2n) Σ_j τ_j`, `τ_j` the moment about contact `j`.
pub(crate) fn external_generalised_force(joint: &JointParams, two_n: usize, theta: f64) -> f64 {
    let [gx, _, gz] = joint.gravity_m_per_s2;
    let [fx, _, fz] = joint.tip_load_n;
    if gx == 0.0 && gz == 0.0 && fx == 0.0 && fz == 0.0 {
        return 0.0;
    }
    let two_n = two_n.clamp(1, MAX_CONTACTS);
    let l = joint.link_length_mm;
    let (link_w, tool_w) = (joint.link_mass_g * 1e-3, joint.tool_mass_g * 1e-3); // kg: N per (m/s²)
    // headings ψ_j = (j+1)φ by incremental rotation: one sin_cos per call
    let (s1, c1) = (theta / two_n as f64).sin_cos();
    let (mut s, mut c) = (0.0f64, 1.0f64);
    let mut bases = [[0.0f64; 2]; MAX_CONTACTS];
    let mut coms = [[0.0f64; 2]; MAX_CONTACTS];
    let mut p = [0.0f64, 0.0];
    for j in 0..two_n {
        (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
        bases[j] = p;
        coms[j] = [p[0] + 0.5 * l * s, p[1] + 0.5 * l * c];
        p = [p[0] + l * s, p[1] + l * c];
    }
    let lt = joint.tool_length_mm;
    let tool_com = [p[0] + 0.5 * lt * s, p[1] + 0.5 * lt * c];
    let tip = [p[0] + lt * s, p[1] + lt * c];
    // moment about +y of a force (fx, fz) at r, about base b: Δz fx − Δx fz
    let moment =
        |b: PlanePoint, r: PlanePoint, fx: f64, fz: f64| (r[1] - b[1]) * fx - (r[0] - b[0]) * fz;
    let mut total = 0.0;
    for j in 0..two_n {
        let b = bases[j];
        for com in &coms[j..two_n] {
            total += moment(b, *com, link_w * gx, link_w * gz);
        }
        total += moment(b, tool_com, tool_w * gx, tool_w * gz);
        total += moment(b, tip, fx, fz);
    }
    total / two_n as f64
}

/// Moment of the tendon pair on one rolling contact at angle `phi` (rad), N·mm:
/// `F d_t cos φ − (T_a + T_b)(R − B) sin φ` (virtual work on Eq. 1:
/// `T_a ∂w_a/∂φ + T_b ∂w_b/∂φ` with `w = −ΔL` the tendons' pull-in).
#[cfg(feature = "multibody")]
pub(crate) fn contact_moment(geometry: &TendonGeometry, distal: &Distal, phi: f64) -> f64 {
    let (s, c) = phi.sin_cos();
    distal.force_n() * geometry.tendon_offset_mm * c
        - distal.tension_sum_n() * (geometry.r_mm - geometry.b_mm) * s
}

/// Pull-in of the two anchors `(w_a, w_b) = (−ΔL_a(θ), −ΔL_b(θ))`, mm.
pub(crate) fn anchors_mm(geometry: &TendonGeometry, theta: f64) -> (f64, f64) {
    let s = geometry.differential_stroke_mm(theta);
    let c = geometry.common_mode_mm(theta);
    (s - c, -s - c)
}

/// Newton steps the coupled fast path may take before handing over.
const NEWTON_STEPS: usize = 12;
/// Largest move per tick the fast path accepts, rad: beyond it the path is
/// followed step by step so a snap-through cannot be jumped over.
const NEWTON_REACH_RAD: f64 = 0.05;

/// Anchors, their slopes and curvatures along θ.
struct Anchors {
    w: [f64; 2],
    slope: [f64; 2],
    curvature: [f64; 2],
}

impl Anchors {
    /// The balance's slope along θ once the tendons answer with anchor
    /// stiffnesses `ka`, `kb` (`−dT/dw`): `g_θ − k_a w_a'² − k_b w_b'²`.
    fn condensed_slope(&self, slope_at_fixed_tensions: f64, ka: f64, kb: f64) -> f64 {
        slope_at_fixed_tensions
            - ka * self.slope[0] * self.slope[0]
            - kb * self.slope[1] * self.slope[1]
    }
}

fn anchors(geometry: &TendonGeometry, theta: f64) -> Anchors {
    let two_n = 2.0 * f64::from(geometry.n_segments);
    let (s, c) = (theta / two_n).sin_cos();
    let (d, rb) = (geometry.tendon_offset_mm, geometry.r_mm - geometry.b_mm);
    let (w_a, w_b) = anchors_mm(geometry, theta);
    Anchors {
        w: [w_a, w_b],
        slope: [d * c - rb * s, -d * c - rb * s],
        curvature: [(-d * s - rb * c) / two_n, (d * s - rb * c) / two_n],
    }
}

/// Residual of the generalised-force balance along θ (N·mm/rad), equal contact
/// angles, for anchor tensions `ta`, `tb` held fixed, and its slope along θ
/// at those tensions (neglecting the slow variation of the external loads).
fn balance_at(
    joint: &JointParams,
    two_n: f64,
    an: &Anchors,
    theta: f64,
    ta: f64,
    tb: f64,
) -> (f64, f64) {
    let k = joint.contact_stiffness_nmm_per_rad;
    let residual = ta * an.slope[0] + tb * an.slope[1] - k * theta / two_n
        + external_generalised_force(joint, two_n as usize, theta);
    let slope = ta * an.curvature[0] + tb * an.curvature[1] - k / two_n;
    (residual, slope)
}

/// The balance along θ with each tendon solved for its anchor there, and its
/// slope, exact for the tendons through their condensed stiffness; NaN
/// where a tendon's solve did not converge (its tension is not an answer
/// to steer the search by).
fn balance(
    geometry: &TendonGeometry,
    joint: &JointParams,
    sheath: &mut TendonSheath,
    theta: f64,
) -> (f64, f64) {
    let two_n = 2.0 * f64::from(geometry.n_segments);
    let an = anchors(geometry, theta);
    let distal = sheath.solve(an.w[0], an.w[1]);
    if !sheath.converged() {
        return (f64::NAN, f64::NAN);
    }
    let (residual, slope) = balance_at(
        joint,
        two_n,
        &an,
        theta,
        distal.tension_a_n,
        distal.tension_b_n,
    );
    let condensed = an.condensed_slope(
        slope,
        distal.stiffness_a_n_per_mm,
        distal.stiffness_b_n_per_mm,
    );
    (residual, condensed)
}

/// Quasi-static analytic solve: the bend θ (rad) at which the tendons, the
/// backbone and the external loads balance, within the hard stops, reached
/// from `theta_last` (the last tick's angle), to 1e-10 rad (6e-9 deg). The
/// sheath's trial state is left at (or within the tolerance of) that θ;
/// [`TendonSheath::commit`] solves it there.
///
/// First a coupled Newton iteration on the joint's balance and both
/// tendons' marches at once (three unknowns: θ and the two anchor tensions),
/// from the last tick's motion continued (`theta_before` is the angle a tick
/// earlier); it converges in two to four steps. It is accepted when it
/// converges to a stable balance near the last angle. Otherwise the path is
/// followed ([`crate::numeric::follow_root`]) with each tendon solved on its
/// own: under a tip load that pushes back along the instrument hard enough
/// to overcome the joint's stiffness, no equilibrium stays near the last
/// angle and the joint snaps through to the next one (buckling), as a real
/// one would. NaN where a tendon's solve fails on the way: its tension is
/// no answer to follow the path by.
pub(crate) fn solve_analytic(
    geometry: &TendonGeometry,
    joint: &JointParams,
    sheath: &mut TendonSheath,
    theta_last: f64,
    theta_before: f64,
) -> f64 {
    let max = joint.max_theta_deg.to_radians();
    let start = theta_last.clamp(-max, max);
    // first guess: the last tick's motion continued
    let guess = (2.0 * theta_last - theta_before)
        .clamp(
            start - NEWTON_REACH_RAD / 2.0,
            start + NEWTON_REACH_RAD / 2.0,
        )
        .clamp(-max, max);
    if let Some(theta) = coupled_newton(geometry, joint, sheath, start, guess, max) {
        return theta;
    }
    // follow the path from the last angle: under compressive loads the balance can
    // have several roots, and the joint reaches the first stable one in the
    // direction the net moment turns it
    let theta = crate::numeric::follow_root(
        |t| balance(geometry, joint, sheath, t),
        -max,
        max,
        start,
        0.01,
        1e-10,
    );
    // the sheath's trial state at θ (NaN where a tendon solve failed on the way)
    if theta.is_nan() || balance(geometry, joint, sheath, theta).0.is_nan() {
        return f64::NAN;
    }
    theta
}

fn coupled_newton(
    geometry: &TendonGeometry,
    joint: &JointParams,
    sheath: &mut TendonSheath,
    start: f64,
    guess: f64,
    max: f64,
) -> Option<f64> {
    let two_n = 2.0 * f64::from(geometry.n_segments);
    let (mut ta, mut tb) = sheath.extrapolated_tensions();
    let mut theta = guess;
    for _ in 0..NEWTON_STEPS {
        let an = anchors(geometry, theta);
        let (ma, mb) = sheath.march(ta, tb, an.w[0], an.w[1]);
        let (g, g_theta) = balance_at(joint, two_n, &an, theta, ta, tb);
        if !(g.is_finite() && ma.by_tension > 0.0 && mb.by_tension > 0.0) {
            return None;
        }
        // eliminate the tensions: ΔT = −(r + r_θ Δθ)/r_T, r_θ = r_w w'
        let (sa, sb) = (ma.by_anchor / ma.by_tension, mb.by_anchor / mb.by_tension);
        let slope = an.condensed_slope(g_theta, sa, sb);
        // a stable balance only (NaN fails too)
        if slope.is_nan() || slope >= 0.0 {
            return None;
        }
        let (ra, rb) = (
            ma.residual_mm / ma.by_tension,
            mb.residual_mm / mb.by_tension,
        );
        let condensed = g - an.slope[0] * ra - an.slope[1] * rb;
        let step = -condensed / slope;
        let next = theta + step;
        if next.abs() > max || (next - start).abs() > NEWTON_REACH_RAD {
            return None;
        }
        ta -= ra + sa * an.slope[0] * step;
        tb -= rb + sb * an.slope[1] * step;
        theta = next;
        let settled = ma.residual_mm.abs() <= crate::transmission::POSITION_TOL_MM
            && mb.residual_mm.abs() <= crate::transmission::POSITION_TOL_MM;
        if step.abs() < 1e-10 && settled {
            // the last step was below tolerance (commit solves the tendons at θ exactly)
            return Some(theta);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transmission::SheathParams;

    /// The motors at Eq. 1's strokes for `theta_c` (rad).
    fn advance(sheath: &mut TendonSheath, geometry: &TendonGeometry, theta_c: f64) {
        sheath
            .advance(
                geometry.differential_stroke_mm(theta_c),
                geometry.common_mode_mm(theta_c),
            )
            .unwrap();
    }

    #[test]
    fn balance_holds_at_the_solution() {
        let geometry = TendonGeometry::default();
        let joint = JointParams::default();
        let mut sheath = TendonSheath::new(SheathParams::default(), 90.0).unwrap();
        advance(&mut sheath, &geometry, 0.6);
        let theta = solve_analytic(&geometry, &joint, &mut sheath, 0.0, 0.0);
        assert!(theta > 0.0 && theta < 0.6, "{theta}");
        // a root: the balance changes sign across it
        assert!(balance(&geometry, &joint, &mut sheath, theta - 1e-9).0 > 0.0);
        assert!(balance(&geometry, &joint, &mut sheath, theta + 1e-9).0 < 0.0);
        // the same answer from a far-away start
        let again = solve_analytic(&geometry, &joint, &mut sheath, -1.5, -1.5);
        assert!((again - theta).abs() < 1e-9, "{again} vs {theta}");
    }

    #[test]
    fn gravity_opposing_the_bend_lowers_it() {
        let geometry = TendonGeometry::default();
        let mut sheath = TendonSheath::new(SheathParams::default(), 0.0).unwrap();
        advance(&mut sheath, &geometry, 0.6);
        let none = JointParams {
            gravity_m_per_s2: [0.0; 3],
            ..JointParams::default()
        };
        let heavy = JointParams {
            gravity_m_per_s2: [-9.81, 0.0, 0.0],
            tool_mass_g: 50.0,
            ..none
        };
        let t0 = solve_analytic(&geometry, &none, &mut sheath, 0.0, 0.0);
        let t1 = solve_analytic(&geometry, &heavy, &mut sheath, 0.0, 0.0);
        assert!(t1 < t0 - 1e-3, "{t0} vs {t1}");
    }

    #[test]
    fn tip_pushed_back_drives_the_joint_into_its_stop() {
        // A bent joint pressed backwards (−z) at the tip bends further, here past
        // the stop: the solver returns the stop, not an angle beyond it.
        let geometry = TendonGeometry::default();
        let joint = JointParams {
            tip_load_n: [0.0, 0.0, -60.0],
            ..JointParams::default()
        };
        let mut sheath = TendonSheath::new(SheathParams::default(), 0.0).unwrap();
        advance(&mut sheath, &geometry, 80f64.to_radians());
        let theta = solve_analytic(
            &geometry,
            &joint,
            &mut sheath,
            60f64.to_radians(),
            60f64.to_radians(),
        );
        assert_eq!(theta, joint.max_theta_deg.to_radians());
    }
}
