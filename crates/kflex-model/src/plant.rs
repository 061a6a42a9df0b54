//! The testbed plant: command in, actual joint angle (and everything the
//! tendons did to get there) out.
//!
//! Per tick: the command θ_c becomes motor strokes through Eq. 1–2 (the
//! controller's kinematic model, as in the paper); the strokes pass the
//! tendon-sheath transmission ([`crate::transmission`]); the joint
//! ([`crate::joint`], analytic or rapier) settles where the tendons, its
//! backbone, gravity and the tip load balance. An optional Aurora-like sensor
//! adds Gaussian noise to the *measured* angle; the true angle is never noisy.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result, closed_range, finite, open_range};
use crate::joint::{JointModelKind, JointParams, solve_analytic};
use crate::joint_rapier::{RapierJoint, RapierSettings};
use crate::kinematics::TendonGeometry;
use crate::transmission::{SheathParams, TendonSheath, TendonTensions};

/// The two degrees of freedom the paper commands.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Command {
    /// Bending θ, deg.
    pub theta_deg: f64,
    /// Translation d along the overtube, mm.
    pub translation_mm: f64,
}

/// Limits and speed of the translation stage (no hysteresis: a stiff lead screw).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TranslationParams {
    /// Shortest extension out of the overtube, mm.
    pub min_mm: f64,
    /// Longest extension, mm.
    pub max_mm: f64,
    /// Speed limit of the stage, mm/s.
    pub max_speed_mm_s: f64,
}

impl Default for TranslationParams {
    fn default() -> Self {
        Self {
            min_mm: 0.0,
            max_mm: 40.0,
            max_speed_mm_s: 20.0,
        }
    }
}

/// Gaussian measurement noise of an electromagnetic tracker like NDI Aurora.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AuroraNoise {
    /// Standard deviation of the measured bend, deg.
    pub theta_std_deg: f64,
    /// Standard deviation of the measured translation, mm.
    pub translation_std_mm: f64,
}

impl Default for AuroraNoise {
    /// Of the order of the tracker's published orientation and position RMS errors.
    fn default() -> Self {
        Self {
            theta_std_deg: 0.2,
            translation_std_mm: 0.2,
        }
    }
}

/// Everything that defines a plant. Angles in degrees, lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlantConfig {
    /// Joint and tendon geometry (Eq. 1).
    pub geometry: TendonGeometry,
    /// Tendon-sheath transmission.
    pub sheath: SheathParams,
    /// Sheath configuration: total bend of the sheath, deg (the paper: 0, 90, 180, 270).
    pub sheath_deg: f64,
    /// Joint mechanics.
    pub joint: JointParams,
    /// Which joint model computes the angle.
    pub joint_model: JointModelKind,
    /// Translation stage.
    pub translation: TranslationParams,
    /// Measurement noise; `None` measures the true state.
    pub noise: Option<AuroraNoise>,
    /// Seed of the measurement noise.
    pub seed: u64,
}

impl Default for PlantConfig {
    fn default() -> Self {
        Self {
            geometry: TendonGeometry::default(),
            sheath: SheathParams::default(),
            sheath_deg: 0.0,
            joint: JointParams::default(),
            joint_model: JointModelKind::Analytic,
            translation: TranslationParams::default(),
            noise: None,
            seed: 0,
        }
    }
}

impl PlantConfig {
    /// Checks every parameter.
    pub fn validate(&self) -> Result<()> {
        self.joint.validate()?;
        self.geometry
            .validate(self.joint.max_theta_deg.to_radians())?;
        self.sheath.validate()?;
        closed_range("sheath_deg", self.sheath_deg, 0.0, 3600.0)?;
        let t = &self.translation;
        closed_range("translation.min_mm", t.min_mm, 0.0, 1e3)?;
        closed_range("translation.max_mm", t.max_mm, t.min_mm, 1e3)?;
        open_range("translation.max_speed_mm_s", t.max_speed_mm_s, 0.0, 1e4)?;
        if let Some(n) = self.noise {
            closed_range("noise.theta_std_deg", n.theta_std_deg, 0.0, 90.0)?;
            closed_range("noise.translation_std_mm", n.translation_std_mm, 0.0, 100.0)?;
        }
        Ok(())
    }

    /// A copy whose friction and stiffness parameters are scaled by independent
    /// factors `1 + rel_std · N(0, 1)` (clamped to [0.5, 1.5]): unit-to-unit and
    /// day-to-day spread for repeated experiments. Deterministic in `seed`.
    pub fn perturbed(&self, seed: u64, rel_std: f64) -> Result<PlantConfig> {
        closed_range("rel_std", rel_std, 0.0, 0.5)?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6b66_6c65_7800_0001);
        let normal = Normal::new(0.0, 1.0).map_err(|_| ModelError::NonFinite {
            name: "rel_std",
            value: rel_std,
        })?;
        let mut factor = || (1.0 + rel_std * normal.sample(&mut rng)).clamp(0.5, 1.5);
        let mut out = *self;
        out.sheath.friction_coefficient *= factor();
        out.sheath.pretension_n *= factor();
        out.sheath.tendon_stiffness_n_per_mm *= factor();
        out.sheath.coulomb_friction_n *= factor();
        out.joint.contact_stiffness_nmm_per_rad *= factor();
        Ok(out)
    }
}

/// What the plant did in one tick. Angles in deg, lengths in mm, forces in N.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlantState {
    /// Time since the last reset, s.
    pub time_s: f64,
    /// The command this tick answered.
    pub command: Command,
    /// True bend θ_a, deg.
    pub theta_deg: f64,
    /// True translation, mm.
    pub translation_mm: f64,
    /// Bend as the tracker reports it (noisy if noise is on), deg.
    pub measured_theta_deg: f64,
    /// Translation as the tracker reports it, mm.
    pub measured_translation_mm: f64,
    /// Motor stroke on tendon `a` (pull-in positive, `−ΔL_a(θ_c)`), mm.
    pub motor_stroke_a_mm: f64,
    /// Motor stroke on tendon `b` (`−ΔL_b(θ_c)`), mm.
    pub motor_stroke_b_mm: f64,
    /// Pull-in of tendon `a` at the joint (`−ΔL_a(θ_a)`), mm.
    pub distal_stroke_a_mm: f64,
    /// Pull-in of tendon `b` at the joint, mm.
    pub distal_stroke_b_mm: f64,
    /// Differential distal force `T_a − T_b`, N.
    pub differential_force_n: f64,
    /// Tensions at both ends of both tendons, N.
    pub tensions: TendonTensions,
    /// Sheath friction direction state z ∈ [−1, 1].
    pub friction_state: f64,
}

enum JointSolver {
    Analytic,
    Rapier(Box<RapierJoint>),
}

/// The tendon-driven bending joint with its sheath: the ground truth of the testbed.
pub struct Plant {
    config: PlantConfig,
    sheath: TendonSheath,
    joint: JointSolver,
    rng: ChaCha8Rng,
    noise: Option<(Normal<f64>, Normal<f64>)>,
    state: PlantState,
}

impl std::fmt::Debug for Plant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Plant")
            .field("config", &self.config)
            .field("state", &self.state)
            .finish()
    }
}

impl Plant {
    /// A plant at rest, straight, at the shortest translation.
    pub fn new(config: PlantConfig) -> Result<Self> {
        config.validate()?;
        let sheath = TendonSheath::new(config.sheath, config.sheath_deg)?;
        let noise = match config.noise {
            Some(n) => Some((normal(n.theta_std_deg)?, normal(n.translation_std_mm)?)),
            None => None,
        };
        let mut plant = Self {
            config,
            sheath,
            joint: JointSolver::Analytic, // reset() builds the configured one
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            noise,
            state: PlantState::default(),
        };
        plant.reset();
        Ok(plant)
    }

    /// The configuration.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// The last state.
    pub fn state(&self) -> &PlantState {
        &self.state
    }

    /// Internal rapier steps taken so far (0 for the analytic joint).
    pub fn physics_steps(&self) -> u64 {
        match &self.joint {
            JointSolver::Analytic => 0,
            JointSolver::Rapier(j) => j.steps_total(),
        }
    }

    /// Back to rest: straight joint, tendons unloaded, noise re-seeded.
    pub fn reset(&mut self) {
        self.sheath.reset(0.0);
        self.joint = match self.config.joint_model {
            JointModelKind::Analytic => JointSolver::Analytic,
            JointModelKind::Rapier => JointSolver::Rapier(Box::new(RapierJoint::new(
                self.config.geometry,
                self.config.joint,
                &self.sheath,
                RapierSettings::default(),
            ))),
        };
        self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
        let t0 = self.config.sheath.pretension_n;
        let translation = self.config.translation.min_mm;
        self.state = PlantState {
            command: Command {
                theta_deg: 0.0,
                translation_mm: translation,
            },
            translation_mm: translation,
            measured_translation_mm: translation,
            tensions: TendonTensions {
                a_distal_n: t0,
                b_distal_n: t0,
                a_proximal_n: t0,
                b_proximal_n: t0,
            },
            ..PlantState::default()
        };
    }

    /// Changes the sheath configuration (deg) between ticks, as a surgeon reshaping the endoscope.
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        self.sheath.set_sheath_deg(sheath_deg)?;
        self.config.sheath_deg = sheath_deg;
        Ok(())
    }

    /// Checks a command against the workspace without moving.
    pub fn check_command(&self, command: &Command) -> Result<()> {
        finite("theta_deg", command.theta_deg)?;
        finite("translation_mm", command.translation_mm)?;
        let max = self.config.joint.max_theta_deg;
        if command.theta_deg.abs() > max {
            return Err(ModelError::OutOfWorkspace {
                name: "theta_deg",
                value: command.theta_deg,
                min: -max,
                max,
            });
        }
        let t = &self.config.translation;
        if command.translation_mm < t.min_mm || command.translation_mm > t.max_mm {
            return Err(ModelError::OutOfWorkspace {
                name: "translation_mm",
                value: command.translation_mm,
                min: t.min_mm,
                max: t.max_mm,
            });
        }
        Ok(())
    }

    /// Advances by `dt_s` under `command`. A bad command or `dt_s ≤ 0` is an
    /// error and leaves the plant exactly as it was.
    pub fn step(&mut self, command: Command, dt_s: f64) -> Result<PlantState> {
        open_range("dt_s", dt_s, 0.0, 1e3)?;
        self.check_command(&command)?;
        let geometry = self.config.geometry;
        let theta_c = command.theta_deg.to_radians();
        let q = geometry.differential_stroke(theta_c);
        let sheath_before = self.sheath.clone();
        self.sheath.advance(q)?;
        let theta = match &mut self.joint {
            JointSolver::Analytic => solve_analytic(
                &geometry,
                &self.config.joint,
                &self.sheath,
                self.state.theta_deg.to_radians(),
            ),
            JointSolver::Rapier(j) => match j.settle(&self.sheath) {
                Ok(t) => t,
                Err(e) => {
                    self.sheath = sheath_before;
                    return Err(e);
                }
            },
        };
        if !theta.is_finite() {
            self.sheath = sheath_before;
            return Err(ModelError::Diverged {
                what: "joint angle",
            });
        }
        // the joint has answered: the friction state moves to where it settled
        let p = match &self.joint {
            JointSolver::Analytic => geometry.differential_stroke(theta),
            JointSolver::Rapier(j) => j.distal_stroke_mm(),
        };
        if let Err(e) = self.sheath.commit(p) {
            self.sheath = sheath_before;
            return Err(e);
        }
        // translation: rate-limited stage
        let max_move = self.config.translation.max_speed_mm_s * dt_s;
        let translation = self.state.translation_mm
            + (command.translation_mm - self.state.translation_mm).clamp(-max_move, max_move);
        let force = self.sheath.distal_force(p);
        let theta_deg = theta.to_degrees();
        let (noise_theta, noise_translation) = match &self.noise {
            Some((nt, nd)) => (nt.sample(&mut self.rng), nd.sample(&mut self.rng)),
            None => (0.0, 0.0),
        };
        self.state = PlantState {
            time_s: self.state.time_s + dt_s,
            command,
            theta_deg,
            translation_mm: translation,
            measured_theta_deg: theta_deg + noise_theta,
            measured_translation_mm: translation + noise_translation,
            motor_stroke_a_mm: -geometry.delta_l_a(theta_c),
            motor_stroke_b_mm: -geometry.delta_l_b(theta_c),
            distal_stroke_a_mm: -geometry.delta_l_a(theta),
            distal_stroke_b_mm: -geometry.delta_l_b(theta),
            differential_force_n: force,
            tensions: self.sheath.tensions(force),
            friction_state: self.sheath.z(),
        };
        Ok(self.state)
    }
}

fn normal(std: f64) -> Result<Normal<f64>> {
    Normal::new(0.0, std).map_err(|_| ModelError::InvalidParameter {
        name: "noise std",
        value: std,
        range: "[0, inf)".into(),
    })
}
