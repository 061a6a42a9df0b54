//! # kflex-control — experiments and metrics
//!
//! Runs the seed paper's experiments on the kflex testbed and scores them.
//! This first version drives the *uncompensated* plant ([`OpenLoopGrid`],
//! [`OpenLoopScenario`]) and defines the paper's metrics once ([`rmse`],
//! [`loop_width`], [`error_peak_to_peak`]); the compensator (Eq. 3–5) and
//! the closed loop come with the estimators.
//!
//! ## Cargo features
//!
//! * `multibody` (default): experiments may run the plant with the rapier3d
//!   multibody joint (kflex-model's feature of the same name). A controller
//!   that embeds only the compensator and the metrics turns default features
//!   off and compiles none of rapier3d, parry3d or image.
#![warn(missing_docs)]

mod error;
mod experiment;
mod metrics;

pub use error::{ControlError, Result};
pub use experiment::{GridRow, OpenLoopGrid, OpenLoopScenario, RunMetrics, Trace};
pub use metrics::{LOOP_BIN_DEG, MeanStd, error_peak_to_peak, loop_width, peak_loss, rmse};
