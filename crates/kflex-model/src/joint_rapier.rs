//! The bending joint as a rapier3d multibody chain.
//!
//! `2n` links hang from a fixed base (the overtube exit) by revolute joints
//! about `+y`. Each contact carries the backbone's elasticity as rapier's
//! implicit joint spring (`k_φ`), the tendon moment `τ_j` of
//! [`crate::joint`] as an internal torque pair on the two bodies it joins,
//! gravity on the links' and the tool's masses, and the tip load as a force at
//! the tool tip. The tendon force depends on where the joint is (through the
//! distal stroke `p = Σ d_t sin φ_j`), so it is recomputed every internal step.
//!
//! Quasi-static use: every plant tick integrates the chain until it is at rest.
//! Real links weigh a fraction of a gram, which would make the dynamics
//! needlessly stiff; an armature (rotor-like inertia on each joint, no weight)
//! and joint damping slow them to a critically damped settle of a few tens of
//! milliseconds. They change how the chain gets to rest, not where it rests.
//!
//! rapier works in `f32` with glam types; this module converts at the boundary
//! and works in metres, kilograms and newtons inside.

use rapier3d::math::Vector as RVec;
use rapier3d::prelude::*;

use crate::error::{ModelError, Result};
use crate::joint::JointParams;
use crate::kinematics::TendonGeometry;
use crate::range::Bounds;
use crate::transmission::TendonSheath;

/// Index of a revolute joint's angle in rapier's 6-DoF spatial coordinates:
/// rapier aligns the joint frame so the free axis is its first angular axis,
/// whatever the axis is in the bodies' frames (checked by the tests).
const FREE_ANGLE: usize = 3;

/// Integration settings of the rapier joint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RapierSettings {
    /// Internal time step, s.
    pub dt_s: f64,
    /// The chain counts as at rest when every joint rate is below this, rad/s.
    pub rest_rate_rad_per_s: f64,
    /// Internal steps at most per plant tick.
    pub max_steps_per_tick: u32,
}

impl Default for RapierSettings {
    fn default() -> Self {
        Self {
            dt_s: 1e-3,
            rest_rate_rad_per_s: 2e-4,
            max_steps_per_tick: 2000,
        }
    }
}

/// The multibody chain and its world.
pub(crate) struct RapierJoint {
    world: PhysicsWorld,
    base: RigidBodyHandle,
    links: Vec<RigidBodyHandle>,
    handles: Vec<MultibodyJointHandle>,
    geometry: TendonGeometry,
    joint: JointParams,
    settings: RapierSettings,
    steps_total: u64,
}

impl std::fmt::Debug for RapierJoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RapierJoint")
            .field("links", &self.links.len())
            .field("steps_total", &self.steps_total)
            .finish()
    }
}

fn v3(a: [f64; 3]) -> RVec {
    RVec::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

impl RapierJoint {
    /// Builds the chain straight (θ = 0).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] when the geometry, the joint or the
    /// settings are out of range (checked here, not assumed).
    pub(crate) fn new(
        geometry: TendonGeometry,
        joint: JointParams,
        sheath: &TendonSheath,
        settings: RapierSettings,
    ) -> Result<Self> {
        joint.validate()?;
        geometry.validate(joint.max_theta_deg.to_radians())?;
        Bounds::open(0.0, 1.0).check("rapier dt_s", settings.dt_s)?;
        Bounds::open(0.0, f64::INFINITY)
            .check("rapier rest_rate_rad_per_s", settings.rest_rate_rad_per_s)?;
        Bounds::closed(1.0, 1e7).check(
            "rapier max_steps_per_tick",
            f64::from(settings.max_steps_per_tick),
        )?;
        let two_n = 2 * geometry.n_segments as usize;
        let l = (joint.link_length_mm * 1e-3) as f32;
        let r = (joint.link_radius_mm * 1e-3) as f32;
        let mut world = PhysicsWorld::new();
        world.gravity = v3(joint.gravity_m_per_s2);
        world.integration_parameters.dt = settings.dt_s as f32;
        let base = world.bodies.insert(RigidBodyBuilder::fixed());
        let mut links = Vec::with_capacity(two_n);
        let mut handles = Vec::with_capacity(two_n);
        let max_phi = (joint.max_theta_deg.to_radians() / two_n as f64) as f32;
        let mut parent = base;
        for j in 0..two_n {
            let m = (joint.link_mass_g * 1e-3) as f32;
            // solid cylinder about its end-on axis z; transverse inertia about the COM
            let i_t = m * (3.0 * r * r + l * l) / 12.0;
            let i_z = 0.5 * m * r * r;
            let mut mass =
                MassProperties::new(RVec::new(0.0, 0.0, 0.5 * l), m, RVec::new(i_t, i_t, i_z));
            if j + 1 == two_n && joint.tool_mass_g > 0.0 {
                let mt = (joint.tool_mass_g * 1e-3) as f32;
                let lt = (joint.tool_length_mm * 1e-3) as f32;
                let it = mt * (3.0 * r * r + lt * lt) / 12.0;
                mass += MassProperties::new(
                    RVec::new(0.0, 0.0, l + 0.5 * lt),
                    mt,
                    RVec::new(it, it, 0.5 * mt * r * r),
                );
            }
            let body = RigidBodyBuilder::dynamic()
                .translation(RVec::new(0.0, 0.0, l * j as f32))
                .additional_mass_properties(mass)
                .can_sleep(false)
                .build();
            let h = world.bodies.insert(body);
            let anchor1 = if j == 0 {
                RVec::ZERO
            } else {
                RVec::new(0.0, 0.0, l)
            };
            let rev = RevoluteJointBuilder::new(RVec::Y)
                .local_anchor1(anchor1)
                .local_anchor2(RVec::ZERO)
                .limits([-max_phi, max_phi]);
            // Insertion fails only for a loop in the multibody graph, which a chain cannot have.
            if let Some(jh) = world.multibody_joints.insert(parent, h, rev, true) {
                handles.push(jh);
            }
            links.push(h);
            parent = h;
        }
        let mut out = Self {
            world,
            base,
            links,
            handles,
            geometry,
            joint,
            settings,
            steps_total: 0,
        };
        out.configure_dofs(sheath);
        Ok(out)
    }

    /// Springs, armature and damping on every contact (see the module docs for the choice).
    fn configure_dofs(&mut self, sheath: &TendonSheath) {
        let two_n = self.links.len() as f64;
        let k_phi = self.joint.contact_stiffness_nmm_per_rad * 1e-3; // N·m/rad
        // stiffest mode: backbone plus the tendon coupling all contacts (rank one)
        let d = self.geometry.tendon_offset_mm * 1e-3;
        let k_tendon = sheath.taut_stiffness_n_per_mm() * 1e3 * d * d * two_n; // N·m/rad
        let k_max = k_phi + k_tendon;
        let omega_max = 0.5 / self.settings.dt_s;
        let armature = k_max / (omega_max * omega_max);
        // softest mode: backbone plus the pretension's straightening moment, damped a little over critical
        let k_min = k_phi
            + 2.0 * sheath.params().pretension_n * (self.geometry.r_mm - self.geometry.b_mm) * 1e-3;
        let damping = 1.5 * 2.0 * (k_min * armature).sqrt();
        for &jh in &self.handles {
            if let Some(link) = self
                .world
                .multibody_joints
                .get_mut(jh)
                .and_then(|(mb, id)| mb.link_mut(id))
            {
                link.joint.set_spring(FREE_ANGLE, k_phi as f32, 0.0);
            }
        }
        if let Some((mb, _)) = self
            .handles
            .first()
            .and_then(|&jh| self.world.multibody_joints.get_mut(jh))
        {
            mb.armature_mut().fill(armature as f32);
            mb.damping_mut().fill(damping as f32);
        }
    }

    /// Reads the contact angles φ_j (rad) into `out`; returns how many there are.
    fn read_angles(&self, out: &mut [f64; crate::joint::MAX_CONTACTS]) -> usize {
        let n = self.handles.len().min(crate::joint::MAX_CONTACTS);
        for (slot, &jh) in out.iter_mut().zip(&self.handles) {
            *slot = self
                .world
                .multibody_joints
                .get(jh)
                .and_then(|(mb, id)| {
                    mb.link(id)
                        .map(|l| f64::from(l.joint().coords()[FREE_ANGLE]))
                })
                .unwrap_or(0.0);
        }
        n
    }

    /// Total bend θ = Σ φ_j, rad.
    pub fn theta(&self) -> f64 {
        let mut phis = [0.0; crate::joint::MAX_CONTACTS];
        let n = self.read_angles(&mut phis);
        phis[..n].iter().sum()
    }

    /// Pull-in of the two tendon anchors `(w_a, w_b)` for the chain's contact
    /// angles: `Σ ±d_t sin φ_j − (R − B)(1 − cos φ_j)`, mm (Eq. 1 contact by contact).
    pub fn anchors_mm(&self) -> (f64, f64) {
        let mut phis = [0.0; crate::joint::MAX_CONTACTS];
        let n = self.read_angles(&mut phis);
        anchors_of(&self.geometry, &phis[..n])
    }

    /// Internal steps taken since construction.
    pub fn steps_total(&self) -> u64 {
        self.steps_total
    }

    /// Integrates until the chain is at rest under the current tendon state. Returns θ (rad).
    pub fn settle(&mut self, sheath: &mut TendonSheath) -> Result<f64> {
        let tip_force = v3(self.joint.tip_load_n);
        let tip_local = RVec::new(
            0.0,
            0.0,
            ((self.joint.link_length_mm + self.joint.tool_length_mm) * 1e-3) as f32,
        );
        let mut phis = [0.0f64; crate::joint::MAX_CONTACTS];
        let n = self.links.len().min(crate::joint::MAX_CONTACTS);
        for step in 0..self.settings.max_steps_per_tick {
            // current contact angles and the tendon force they imply
            self.read_angles(&mut phis);
            let (w_a, w_b) = anchors_of(&self.geometry, &phis[..n]);
            let distal = sheath.solve(w_a, w_b);
            if !sheath.converged() {
                return Err(ModelError::Diverged {
                    what: "tendon element balance",
                });
            }
            for b in &self.links {
                if let Some(body) = self.world.bodies.get_mut(*b) {
                    body.reset_forces(false);
                    body.reset_torques(false);
                }
            }
            for (i, phi) in phis.iter().enumerate().take(n) {
                let tau = crate::joint::contact_moment(&self.geometry, &distal, *phi) * 1e-3; // N·m
                let torque = RVec::new(0.0, tau as f32, 0.0);
                if let Some(child) = self.world.bodies.get_mut(self.links[i]) {
                    child.add_torque(torque, true);
                }
                let parent = if i == 0 { self.base } else { self.links[i - 1] };
                if let Some(parent) = self.world.bodies.get_mut(parent) {
                    parent.add_torque(-torque, true);
                }
            }
            if let Some(last) = self
                .links
                .last()
                .and_then(|h| self.world.bodies.get_mut(*h))
            {
                let point = last.position() * tip_local;
                last.add_force_at_point(tip_force, point, true);
            }
            self.world.step();
            self.steps_total += 1;
            let rate = self.max_rate();
            if !rate.is_finite() {
                return Err(ModelError::Diverged { what: "joint rate" });
            }
            if step > 2 && rate < self.settings.rest_rate_rad_per_s {
                break;
            }
        }
        let theta = self.theta();
        if theta.is_finite() {
            Ok(theta)
        } else {
            Err(ModelError::Diverged {
                what: "joint angle",
            })
        }
    }

    fn max_rate(&self) -> f64 {
        self.handles
            .first()
            .and_then(|&jh| self.world.multibody_joints.get(jh))
            .map(|(mb, _)| {
                mb.generalized_velocity()
                    .iter()
                    .fold(0.0f64, |m, v| m.max(f64::from(v.abs())))
            })
            .unwrap_or(0.0)
    }
}

/// Anchor pull-ins `(w_a, w_b)` for contact angles `phis` (rad), mm.
fn anchors_of(geometry: &TendonGeometry, phis: &[f64]) -> (f64, f64) {
    let rb = geometry.r_mm - geometry.b_mm;
    phis.iter().fold((0.0, 0.0), |(a, b), phi| {
        let (s, c) = phi.sin_cos();
        let (diff, common) = (geometry.tendon_offset_mm * s, rb * (1.0 - c));
        (a + diff - common, b - diff - common)
    })
}
