//! # kflex-model — the testbed
//!
//! The simulated flexible surgery robot on which kflex reproduces the seed
//! paper (Baek et al., RA-L 2020): the bending joint's tendon kinematics
//! (Eq. 1–2), hysteresis operators (Bouc–Wen, play), the tendon-sheath
//! transmission whose friction grows with the sheath's bend (capstan law), the
//! joint's mechanics (analytic, or a rapier3d multibody chain), and command
//! trajectories. [`Plant`] puts them together; it is the ground truth of the
//! testbed and is never read by the estimators.
//!
//! ```
//! use kflex_model::{Command, Plant, PlantConfig};
//! let mut plant = Plant::new(PlantConfig { sheath_deg: 180.0, ..PlantConfig::default() })?;
//! let state = plant.step(Command { theta_deg: 30.0, translation_mm: 5.0 }, 0.01)?;
//! assert!(state.theta_deg < 30.0); // the joint lags the command
//! # Ok::<(), kflex_model::ModelError>(())
//! ```
#![doc = include_str!("../CALIBRATION.md")]
#![warn(missing_docs)]

pub mod calibration;
pub mod camera;
pub mod error;
pub mod hysteresis;
pub mod instrument;
pub mod joint;
pub mod joint_rapier;
pub mod kinematics;
pub mod numeric;
pub mod plant;
pub mod raster;
pub mod scene;
pub mod trajectory;
pub mod transmission;

pub use camera::{Camera, Intrinsics};
pub use error::{ModelError, Result};
pub use hysteresis::{BoucWen, BoucWenParams, Play};
pub use instrument::{Capsule, Instrument, InstrumentParams, InstrumentShape, Part};
pub use joint::{JointModelKind, JointParams};
pub use kinematics::TendonGeometry;
pub use plant::{AuroraNoise, Command, Plant, PlantConfig, PlantState, TranslationParams};
pub use raster::Mask;
pub use trajectory::{Sample, Sine, Trajectory, TrajectorySampler};
pub use transmission::{Distal, SheathParams, TendonSheath, TendonTensions};
