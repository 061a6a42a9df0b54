//! # kflex-model — the testbed
//!
//! The simulated flexible surgery robot on which kflex reproduces the seed
//! paper (Baek et al., RA-L 2020): the bending joint's tendon kinematics
//! (Eq. 1–2), hysteresis operators (Bouc–Wen, play), the tendon-sheath
//! transmission (each tendon a chain of Bouc–Wen friction elements, whose
//! friction grows with the sheath's bend by the capstan law), the
//! joint's mechanics (analytic, or a rapier3d multibody chain), command
//! trajectories, and the endoscope camera (instrument geometry, a
//! wide-angle lens, an exact ray caster for silhouettes, shaded frames over
//! clinical backgrounds, and the as-built instrument and camera that keep a
//! reality gap between the simulated robot and the nominal model).
//! [`Plant`] puts the mechanics together; it is the ground truth of the
//! testbed and is never read by the estimators.
//!
//! It also owns the small types every kflex crate shares: [`Command`],
//! [`Mask`], [`Roi`], and the range check [`Bounds`] with its error
//! [`RangeError`].
//!
//! ```
//! use kflex_model::{Command, Plant, PlantConfig};
//! let mut plant = Plant::new(PlantConfig { sheath_deg: 180.0, ..PlantConfig::default() })?;
//! let state = plant.step(Command { theta_c_deg: 30.0, translation_mm: 5.0 }, 0.01)?;
//! assert!(state.theta_a_deg < 30.0); // the joint lags the command
//! # Ok::<(), kflex_model::ModelError>(())
//! ```
//!
//! ## Names and units
//!
//! The paper's angles keep its names: `theta_d` the desired angle from the
//! master, `theta_c` the command sent to the plant (Eq. 3), `theta_a` the
//! actual angle, `theta_hat` an estimate. A geometric function that takes
//! any bend says plain `theta`.
//!
//! Every physical quantity carries its unit as a suffix, spelled one way:
//! `_deg`, `_rad`, `_mm`, `_m`, `_s`, `_hz`, `_g`, `_n` (newton), `_nmm`
//! (newton-millimetre); a quotient joins its units with `_per_`
//! (`_n_per_mm`, `_nmm_per_rad`, `_deg_per_s`, `_mm_per_s`, `_m_per_s2`).
//! Image sizes, pixel coordinates and the intrinsics `fx`, `fy`, `cx`, `cy`
//! are in pixels by convention and carry no suffix; other pixel quantities
//! say `_px` (`blur_px`, `margin_px`). Dimensionless quantities (ratios,
//! friction coefficients, normalised states) carry none.
//!
//! ## Cargo features
//!
//! * `multibody` (default): the joint as a rapier3d multibody chain
//!   ([`JointModelKind::Rapier`]). Without it, kflex-model compiles none of
//!   rapier3d, parry3d or their dependencies; the analytic joint, the plant,
//!   the camera and every shared type stay, and a configuration that asks
//!   for the rapier joint is refused with [`ModelError::FeatureDisabled`].
#![doc = include_str!("../CALIBRATION.md")]
#![warn(missing_docs)]

mod as_built;
mod calibration;
mod camera;
mod error;
mod hysteresis;
mod instrument;
mod joint;
#[cfg(feature = "multibody")]
mod joint_rapier;
mod kinematics;
mod mask;
mod numeric;
mod plant;
mod range;
mod raster;
mod roi;
mod scene;
mod trajectory;
mod transmission;
mod working;
mod workspace;

pub use as_built::{BuildTolerances, BuiltInstrument};
pub use camera::{Camera, Intrinsics, Lens};
pub use error::{ModelError, Result, finite};
pub use hysteresis::{Backlash, BoucWen, BoucWenParams, Play};
pub use instrument::{Body, Ends, Instrument, InstrumentParams, InstrumentShape, Part};
pub use joint::{JointModelKind, JointParams};
pub use kinematics::TendonGeometry;
pub use mask::Mask;
pub use plant::{AuroraNoise, BUILD_SHARE, Command, HOMING_SHARE, Plant, PlantConfig, PlantState};
pub use range::MAX_IMAGE_SIDE;
pub use range::{Bounds, Num, RangeError};
pub use raster::{MAX_BODIES, Rasterizer};
pub use roi::Roi;
pub use scene::{Background, Frame, FrameParams, Occlusion, SceneRenderer, Tissue};
pub use trajectory::{Sample, Sine, Trajectory, TrajectorySampler};
pub use transmission::{Distal, Seating, SheathParams, TendonSheath, TendonTensions};
pub use working::{Banding, PoseRange, WorkingBand, WorkingRegions};
pub use workspace::TranslationParams;
