//! The one error type of `kflex-control`.

use thiserror::Error;

/// What can go wrong running experiments or computing metrics.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ControlError {
    /// The plant or a trajectory refused its input.
    #[error(transparent)]
    Model(#[from] kflex_model::ModelError),
    /// A setting is outside its valid range.
    #[error("{name} = {value} is out of range: must be in {range}")]
    InvalidParameter {
        /// Setting name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// Valid range, in words.
        range: String,
    },
    /// A metric needs data it was not given.
    #[error("{metric} needs {needed}, got {got}")]
    NotEnoughData {
        /// Which metric.
        metric: &'static str,
        /// What it needs, in words.
        needed: &'static str,
        /// How much it got.
        got: usize,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, ControlError>;
