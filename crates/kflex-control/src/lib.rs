//! # kflex-control — experiments and metrics
//!
//! Runs the seed paper's experiments on the kflex testbed and scores them.
//! This first version drives the *uncompensated* plant ([`experiment`]) and
//! defines the paper's metrics once ([`metrics`]); the compensator (Eq. 3–5)
//! and the closed loop come with the estimators.
#![warn(missing_docs)]

pub mod error;
pub mod experiment;
pub mod metrics;

pub use error::{ControlError, Result};
pub use experiment::{GridRow, OpenLoopGrid, OpenLoopScenario, RunMetrics, Trace};
pub use metrics::MeanStd;
