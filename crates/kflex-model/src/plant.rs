//! The testbed plant: command in, actual joint angle (and everything the
//! tendons did to get there) out.

use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};
use crate::hysteresis::Backlash;
use crate::joint::{JointModelKind, JointParams, anchors_mm, solve_analytic};
#[cfg(feature = "multibody")]
use crate::joint_rapier::{RapierJoint, RapierSettings};
use crate::kinematics::TendonGeometry;
use crate::range::Bounds;
use crate::transmission::{Seating, SheathParams, TendonSheath, TendonTensions};
use crate::workspace::{TranslationParams, check_pose};

/// The share of [`PlantConfig::perturbed`]'s spread that the parameters of
/// the instrument's build (stiffnesses, the drive's play) take: a repeated
/// experiment sets the same instrument up again, which changes its friction,
/// tension and sheath lay far more than its gears or its tendons' stiffness.
pub const BUILD_SHARE: f64 = 1.0 / 3.0;

/// How far from the middle of the drive's play [`PlantConfig::perturbed`]
/// homes the drive, as a share of the play's half-width (uniform): ±4.1 deg of
/// bend on the default drive. The paper brackets it (CALIBRATION.md, "Run-
/// to-run variation"): its uncompensated RMSE spread at a straight sheath
/// needs at least about 0.6 (0.7 leaves a margin over four sets of seeds),
/// its KBJAE row, which no feedforward estimator can correct for a homing
/// error, wants it small.
pub const HOMING_SHARE: f64 = 0.7;

/// The two degrees of freedom the paper commands.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Command {
    /// Bend θ_c sent to the plant, deg (Eq. 3's compensated command; θ_d when uncompensated).
    pub theta_c_deg: f64,
    /// Translation d along the overtube, mm.
    pub translation_mm: f64,
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
    /// How the tendons sit in their sheaths when the plant starts or resets,
    /// and where in its play the drive was homed.
    pub seating: Seating,
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
            seating: Seating::default(),
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
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter out of its range,
    /// checked in this order: the joint's ([`JointParams::validate`]), the
    /// geometry's ([`TendonGeometry::validate`] over `±joint.max_theta_deg`),
    /// the sheath's ([`SheathParams::validate`]), `sheath_deg` outside
    /// `[0, 3600]` deg or past what the sheath's element chain resolves
    /// ([`SheathParams::max_sheath_deg`]), the seating's ([`Seating::validate`]), the translation stage's
    /// ([`TranslationParams::validate`]), then, with noise on,
    /// `noise.theta_std_deg` outside `[0, 90]` deg or
    /// `noise.translation_std_mm` outside `[0, 100]` mm.
    pub fn validate(&self) -> Result<()> {
        self.joint.validate()?;
        self.geometry
            .validate(self.joint.max_theta_deg.to_radians())?;
        self.sheath.validate()?;
        // the element chain resolves a total wrap of `elements / μ` rad
        // (what `TendonSheath::new` checks): said here, on the values as given
        Bounds::closed(0.0, self.sheath.max_sheath_deg()).check("sheath_deg", self.sheath_deg)?;
        self.seating.validate()?;
        self.translation.validate()?;
        if let Some(n) = self.noise {
            Bounds::closed(0.0, 90.0).check("noise.theta_std_deg", n.theta_std_deg)?;
            Bounds::closed(0.0, 100.0).check("noise.translation_std_mm", n.translation_std_mm)?;
        }
        Ok(())
    }

    /// A copy drawn around this one for a repeated experiment: the same
    /// instrument set up again. These physical parameters of the
    /// transmission and the joint are scaled, each by its own factor
    /// `1 + share · rel_std · N(0, 1)` (clamped to `[0.5, 1.5]`; the geometry,
    /// masses, gravity, stops and element count are not drawn):
    /// * how the instrument is set up for a run, `share` 1: the friction
    ///   coefficient (lubrication, temperature, wear-in), the route wrap (how
    ///   the sheath leaves the drive), the pretension (re-tensioned, creep),
    ///   the pre-sliding displacement (the surfaces' state);
    /// * how it was built, `share` [`BUILD_SHARE`]: both tendon stiffnesses,
    ///   the drive's backlash and its engagement, the sheath's path change
    ///   (the lumens' clearance), the contacts' stiffness.
    ///
    /// With `rel_std > 0` each repeat also starts from its own seating
    /// (see [`Seating`]): the friction states drawn uniformly from `[−1, 1]`
    /// (how the instrument was last moved), and the drive's homing position
    /// uniformly from `±`[`HOMING_SHARE`] of the play's half-width, its
    /// middle 70 % (where it was zeroed, which offsets every command all
    /// run). Deterministic in `seed`. This configuration is checked first,
    /// so an error names the value as given, not a scaled one; and a draw
    /// never makes a valid configuration invalid: each drawn value is held
    /// inside the range [`PlantConfig::validate`] allows, and a friction
    /// coefficient drawn past what the element chain resolves at this wrap
    /// (`μ (Φ₀ + Φ_s) ≤ elements` rad, [`SheathParams::max_wrap_deg`]) is held
    /// at that limit (for this configuration's `sheath_deg`: a sheath angle
    /// set later, [`Plant::set_sheath_deg`], is checked against the drawn μ).
    ///
    /// The split and the homing are what put the run-to-run spread within a
    /// factor of 3 of the paper's ± at every sheath angle, for the RMSE and
    /// the loop width alike (CALIBRATION.md, "Run-to-run variation").
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `rel_std` when it is outside `[0, 0.5]`
    /// (NaN included), or the first parameter of this configuration out of
    /// its range ([`PlantConfig::validate`]).
    pub fn perturbed(&self, seed: u64, rel_std: f64) -> Result<PlantConfig> {
        Bounds::closed(0.0, 0.5).check("rel_std", rel_std)?;
        self.validate()?;
        let mut out = *self;
        if rel_std == 0.0 {
            return Ok(out);
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6b66_6c65_7800_0002);
        let normal = Normal::new(0.0, rel_std).map_err(|_| ModelError::NonFinite {
            name: "rel_std",
            value: rel_std,
        })?;
        let mut scale = |x: &mut f64, share: f64| {
            *x *= (1.0 + share * normal.sample(&mut rng)).clamp(0.5, 1.5);
        };
        let s = &mut out.sheath;
        // how the instrument is set up for a run: the full spread
        scale(&mut s.friction_coefficient, 1.0);
        scale(&mut s.route_wrap_deg, 1.0);
        scale(&mut s.pretension_n, 1.0);
        scale(&mut s.presliding_mm, 1.0);
        // how it was built: a third of it
        scale(&mut s.tendon_stiffness_n_per_mm, BUILD_SHARE);
        scale(&mut s.distal_stiffness_n_per_mm, BUILD_SHARE);
        scale(&mut s.drive_backlash_mm, BUILD_SHARE);
        scale(&mut s.backlash_engagement_mm, BUILD_SHARE);
        scale(&mut s.sheath_path_mm_per_rad, BUILD_SHARE);
        scale(&mut out.joint.contact_stiffness_nmm_per_rad, BUILD_SHARE);
        // each draw held inside the range `validate` allows (an open end
        // just inside it), so a repeat names no value the user never set
        let s = &mut out.sheath;
        s.friction_coefficient = SheathParams::FRICTION_COEFFICIENT.hold(s.friction_coefficient);
        s.route_wrap_deg = SheathParams::ROUTE_WRAP_DEG.hold(s.route_wrap_deg);
        s.pretension_n = SheathParams::PRETENSION_N.hold(s.pretension_n);
        s.tendon_stiffness_n_per_mm =
            SheathParams::TENDON_STIFFNESS.hold(s.tendon_stiffness_n_per_mm);
        s.distal_stiffness_n_per_mm =
            SheathParams::DISTAL_STIFFNESS.hold(s.distal_stiffness_n_per_mm);
        s.drive_backlash_mm = SheathParams::BACKLASH_MM.hold(s.drive_backlash_mm);
        s.backlash_engagement_mm = SheathParams::BACKLASH_MM.hold(s.backlash_engagement_mm);
        s.presliding_mm = SheathParams::PRESLIDING_MM.hold(s.presliding_mm);
        s.sheath_path_mm_per_rad = SheathParams::PATH_MM_PER_RAD.hold(s.sheath_path_mm_per_rad);
        let k = &mut out.joint.contact_stiffness_nmm_per_rad;
        *k = JointParams::CONTACT_STIFFNESS.hold(*k);
        // a larger μ or route wrap drawn near the chain's limit would refuse a
        // sheath angle the configuration as given accepts (an error naming a
        // bound the user never set): such a draw of μ is held at the limit,
        // `μ (Φ₀ + Φ_s) ≤ elements` rad, a hair inside it
        let wrap_rad = (out.sheath.route_wrap_deg + out.sheath_deg).to_radians();
        if wrap_rad > 0.0 {
            let limit = f64::from(out.sheath.elements) / wrap_rad * (1.0 - 1e-9);
            out.sheath.friction_coefficient = out.sheath.friction_coefficient.min(limit);
        }
        out.seating = Seating {
            friction_a: rng.random_range(-1.0..=1.0),
            friction_b: rng.random_range(-1.0..=1.0),
            backlash: rng.random_range(-HOMING_SHARE..=HOMING_SHARE),
        };
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
    pub theta_a_deg: f64,
    /// True translation, mm.
    pub translation_mm: f64,
    /// Bend as the tracker reports it (noisy if noise is on), deg.
    pub theta_a_measured_deg: f64,
    /// Translation as the tracker reports it, mm.
    pub translation_measured_mm: f64,
    /// Motor stroke on tendon `a` (pull-in positive, `−ΔL_a(θ_c)`), mm, from
    /// the motor's homed zero (before the drive's play).
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
    #[cfg(feature = "multibody")]
    Rapier(Box<RapierJoint>),
}

/// The tendon-driven bending joint with its sheath: the ground truth of the testbed.
///
/// Per tick: the command θ_c passes the drive's backlash ([`Backlash`] on
/// its differential stroke, with the flanks' engagement) and becomes both
/// motors' strokes through Eq. 1–2 (the controller's kinematic model, as in
/// the paper: differential and common mode); the strokes pass the
/// tendon-sheath transmission ([`TendonSheath`]: each tendon a chain of
/// friction elements); the joint ([`JointParams`], analytic or rapier)
/// settles where the tendons, its backbone, gravity and the tip load
/// balance. An optional Aurora-like sensor adds Gaussian noise to the
/// *measured* angle; the true angle is never noisy. [`PlantConfig::seating`]
/// says how the tendons sit when it starts and where in its play the drive
/// was homed, which offsets every command for as long as it runs.
pub struct Plant {
    config: PlantConfig,
    sheath: TendonSheath,
    joint: JointSolver,
    rng: ChaCha8Rng,
    noise: Option<(Normal<f64>, Normal<f64>)>,
    state: PlantState,
    /// θ_a one tick before the last, rad (the solver extrapolates from it).
    theta_before_rad: f64,
    /// The drive's backlash, on the differential stroke of the command.
    backlash: Backlash,
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
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter of `config` out of
    /// its range; [`ModelError::FeatureDisabled`] for the rapier joint in a
    /// build without the `multibody` feature.
    pub fn new(config: PlantConfig) -> Result<Self> {
        config.validate()?;
        #[cfg(not(feature = "multibody"))]
        if config.joint_model == JointModelKind::Rapier {
            return Err(ModelError::FeatureDisabled {
                what: "joint_model = rapier",
                feature: "multibody",
            });
        }
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
            theta_before_rad: 0.0,
            backlash: Backlash::new(
                config.sheath.drive_backlash_mm,
                config.sheath.backlash_engagement_mm,
            )?,
        };
        plant.reset()?;
        Ok(plant)
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// The last state.
    #[must_use]
    pub fn state(&self) -> &PlantState {
        &self.state
    }

    /// Internal rapier steps taken so far (0 for the analytic joint).
    #[must_use]
    pub fn physics_steps(&self) -> u64 {
        match &self.joint {
            JointSolver::Analytic => 0,
            #[cfg(feature = "multibody")]
            JointSolver::Rapier(j) => j.steps_total(),
        }
    }

    /// Back to rest: straight joint, tendons unloaded, noise re-seeded.
    ///
    /// # Errors
    /// Only if the rapier joint cannot be rebuilt from the configuration,
    /// which [`Plant::new`] has already checked; the plant is then unchanged.
    pub fn reset(&mut self) -> Result<()> {
        let joint = match self.config.joint_model {
            #[cfg(feature = "multibody")]
            JointModelKind::Rapier => JointSolver::Rapier(Box::new(RapierJoint::new(
                self.config.geometry,
                self.config.joint,
                &self.sheath,
                RapierSettings::default(),
            )?)),
            _ => JointSolver::Analytic,
        };
        self.sheath.reset(&self.config.seating)?;
        let distal = self.sheath.distal(0.0, 0.0)?;
        self.joint = joint;
        self.rng = ChaCha8Rng::seed_from_u64(self.config.seed);
        self.theta_before_rad = 0.0;
        // homed with the joint straight: the play's output at 0, the motor
        // where the seating puts it inside the play, and its zero set there
        let zero = self.drive_zero_mm();
        self.backlash.reset(zero, -zero);
        let translation = self.config.translation.min_mm;
        self.state = PlantState {
            command: Command {
                theta_c_deg: 0.0,
                translation_mm: translation,
            },
            translation_mm: translation,
            translation_measured_mm: translation,
            differential_force_n: distal.force_n(),
            tensions: self.sheath.tensions(&distal),
            friction_state: self.sheath.friction_state(),
            ..PlantState::default()
        };
        Ok(())
    }

    /// Where the motor's zero sits inside the drive's play, on the
    /// differential stroke, mm: the drive was homed with the joint straight,
    /// which it is for any motor position inside the play, so the zero
    /// lands where [`Seating::backlash`] says and stays there all run.
    fn drive_zero_mm(&self) -> f64 {
        -self.config.seating.backlash * self.config.sheath.drive_backlash_mm
    }

    /// Changes the sheath configuration (deg) between ticks, as a surgeon reshaping the endoscope.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `sheath_deg` when it is outside
    /// `[0, 3600]` deg (NaN included); the plant is then unchanged.
    pub fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        self.sheath.set_sheath_deg(sheath_deg)?;
        self.config.sheath_deg = sheath_deg;
        Ok(())
    }

    /// Checks a command against the workspace without moving.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite command,
    /// [`ModelError::OutOfWorkspace`] past the joint's hard stops or the stage's travel.
    pub fn check_command(&self, command: &Command) -> Result<()> {
        check_pose(
            self.config.joint.max_theta_deg,
            &self.config.translation,
            "theta_c_deg",
            command.theta_c_deg,
            command.translation_mm,
        )
    }

    /// Advances by `dt_s` under `command`. A bad command or `dt_s ≤ 0` is an
    /// error and leaves the plant exactly as it was.
    ///
    /// # Errors
    /// A refused input leaves the plant exactly as it was; after
    /// [`ModelError::Diverged`] its state and transmission are restored (the
    /// rapier joint's own bodies are not):
    /// * [`ModelError::OutOfRange`] naming `dt_s` when it is outside `(0, 1000)` s
    ///   (NaN included);
    /// * [`ModelError::NonFinite`] for a NaN or infinite `theta_c_deg` or
    ///   `translation_mm`, [`ModelError::OutOfWorkspace`] for a command past
    ///   the joint's hard stops or the stage's travel (as
    ///   [`Plant::check_command`]);
    /// * [`ModelError::Diverged`] when the joint's solution is not finite
    ///   (the rapier joint also reports a non-finite joint rate).
    ///
    /// # Examples
    ///
    /// ```
    /// use kflex_model::{Command, ModelError, Plant, PlantConfig};
    /// let mut plant = Plant::new(PlantConfig { sheath_deg: 180.0, ..PlantConfig::default() })?;
    /// // ramp the command from 0 to 30 deg over 1 s in 10 ms ticks
    /// for k in 1..=100 {
    ///     let command = Command { theta_c_deg: 0.3 * f64::from(k), translation_mm: 10.0 };
    ///     let state = plant.step(command, 0.01)?;
    ///     assert!(state.theta_a_deg < command.theta_c_deg); // θ_a lags θ_c
    /// }
    /// let state = *plant.state();
    /// assert!(state.theta_a_deg > 0.0 && state.theta_a_deg < 30.0);
    /// assert!((state.time_s - 1.0).abs() < 1e-9);
    ///
    /// // a bad tick is refused with the range it had to be in, and nothing moves
    /// let hold = Command { theta_c_deg: 30.0, translation_mm: 10.0 };
    /// let err = plant.step(hold, 0.0).unwrap_err();
    /// let range = err.range().expect("dt_s is range-checked");
    /// assert_eq!((range.name, range.value), ("dt_s", 0.0));
    /// assert!(!range.bounds.contains(0.0) && range.bounds.contains(0.01));
    /// assert_eq!(plant.state(), &state);
    /// // so is a bend past the joint's hard stops
    /// let err = plant.step(Command { theta_c_deg: 200.0, ..hold }, 0.01).unwrap_err();
    /// assert!(matches!(err, ModelError::OutOfWorkspace(r) if r.name == "theta_c_deg"));
    /// # Ok::<(), ModelError>(())
    /// ```
    pub fn step(&mut self, command: Command, dt_s: f64) -> Result<PlantState> {
        Bounds::open(0.0, 1e3).check("dt_s", dt_s)?;
        self.check_command(&command)?;
        let geometry = self.config.geometry;
        let theta_c = command.theta_c_deg.to_radians();
        // the drive: the command's stroke through the backlash, then both
        // tendons' paths of Eq. 1 for the angle that stroke stands for
        let mut backlash = self.backlash;
        let stroke =
            backlash.advance(geometry.differential_stroke_mm(theta_c) + self.drive_zero_mm())?;
        let theta_b = geometry.theta_rad_from_stroke(stroke).unwrap_or(theta_c);
        self.sheath
            .advance(stroke, geometry.common_mode_mm(theta_b))?;
        let theta = match &mut self.joint {
            JointSolver::Analytic => solve_analytic(
                &geometry,
                &self.config.joint,
                &mut self.sheath,
                self.state.theta_a_deg.to_radians(),
                self.theta_before_rad,
            ),
            #[cfg(feature = "multibody")]
            JointSolver::Rapier(j) => match j.settle(&mut self.sheath) {
                Ok(t) => t,
                Err(e) => {
                    self.sheath.discard();
                    return Err(e);
                }
            },
        };
        if !theta.is_finite() {
            // the tendons' own solve, where that is what failed
            let what = if self.sheath.converged() {
                "joint angle"
            } else {
                "tendon element balance"
            };
            self.sheath.discard();
            return Err(ModelError::Diverged { what });
        }
        // the joint has answered: the tendons and their friction move to where it settled
        let (w_a, w_b) = match &self.joint {
            JointSolver::Analytic => anchors_mm(&geometry, theta),
            #[cfg(feature = "multibody")]
            JointSolver::Rapier(j) => j.anchors_mm(),
        };
        let distal = match self.sheath.commit(w_a, w_b) {
            Ok(d) => d,
            Err(e) => {
                self.sheath.discard();
                return Err(e);
            }
        };
        // translation: rate-limited stage
        let max_move = self.config.translation.max_speed_mm_per_s * dt_s;
        let translation = self.state.translation_mm
            + (command.translation_mm - self.state.translation_mm).clamp(-max_move, max_move);
        self.theta_before_rad = self.state.theta_a_deg.to_radians();
        self.backlash = backlash;
        let theta_a_deg = theta.to_degrees();
        let (noise_theta, noise_translation) = match &self.noise {
            Some((nt, nd)) => (nt.sample(&mut self.rng), nd.sample(&mut self.rng)),
            None => (0.0, 0.0),
        };
        self.state = PlantState {
            time_s: self.state.time_s + dt_s,
            command,
            theta_a_deg,
            translation_mm: translation,
            theta_a_measured_deg: theta_a_deg + noise_theta,
            translation_measured_mm: translation + noise_translation,
            motor_stroke_a_mm: -geometry.delta_l_a_mm(theta_c),
            motor_stroke_b_mm: -geometry.delta_l_b_mm(theta_c),
            distal_stroke_a_mm: -geometry.delta_l_a_mm(theta),
            distal_stroke_b_mm: -geometry.delta_l_b_mm(theta),
            differential_force_n: distal.force_n(),
            tensions: self.sheath.tensions(&distal),
            friction_state: self.sheath.friction_state(),
        };
        Ok(self.state)
    }
}

fn normal(std: f64) -> Result<Normal<f64>> {
    let std = Bounds::closed_open(0.0, f64::INFINITY).check("noise std", std)?;
    Normal::new(0.0, std).map_err(|_| ModelError::NonFinite {
        name: "noise std",
        value: std,
    })
}
