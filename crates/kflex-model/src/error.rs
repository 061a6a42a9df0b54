//! The one error type of `kflex-model`.

use thiserror::Error;

use crate::range::{Num, RangeError};

/// Everything that can go wrong in the testbed model.
///
/// Variants carry the offending value and, where there is one, the range it
/// had to be in as numbers ([`RangeError`]), so a caller can match on them and
/// a person can act on the message without extra context. Building any
/// variant but [`ModelError::UnknownBackground`] and
/// [`ModelError::UnknownTissue`] allocates nothing.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A configuration or call parameter is outside its physically meaningful range.
    #[error(transparent)]
    OutOfRange(#[from] RangeError),
    /// A command or input is NaN or infinite.
    #[error("{name} is not finite ({value})")]
    NonFinite {
        /// Which input.
        name: &'static str,
        /// The value that was given.
        value: f64,
    },
    /// A commanded pose lies outside the device's workspace (the joint's hard
    /// stops, the translation stage's travel).
    #[error("{} = {} is outside the workspace {}", .0.name, Num(.0.value), .0.bounds)]
    OutOfWorkspace(RangeError),
    /// A tendon length change that no joint angle in the mechanical range produces.
    #[error(
        "tendon length change {} mm is not reachable: reachable range [{}, {}] mm",
        Num(*.delta_l_mm),
        Num(*.min_mm),
        Num(*.max_mm)
    )]
    Unreachable {
        /// The requested length change, mm.
        delta_l_mm: f64,
        /// Smallest reachable length change, mm.
        min_mm: f64,
        /// Largest reachable length change, mm.
        max_mm: f64,
    },
    /// An image buffer whose size does not match its dimensions, or images of different sizes.
    #[error("{what}: expected {expected} pixels ({width}×{height}), got {got}")]
    ImageSize {
        /// Which buffer.
        what: &'static str,
        /// Width it claims, px.
        width: u32,
        /// Height it claims, px.
        height: u32,
        /// Pixels it should have.
        expected: usize,
        /// Pixels it has.
        got: usize,
    },
    /// A background name that is not one of colon, stomach, larynx.
    #[error("unknown background {name:?}: expected colon, stomach or larynx")]
    UnknownBackground {
        /// The name given.
        name: String,
    },
    /// A tissue colour name that is not one of those of [`crate::Tissue`].
    #[error(
        "unknown tissue colour {name:?}: expected organ, grey, pale, white, blue_green or yellow"
    )]
    UnknownTissue {
        /// The name given.
        name: String,
    },
    /// The physics engine produced a state that is not finite; the plant keeps its last good state.
    #[error("the joint simulation diverged ({what}); the plant state was left unchanged")]
    Diverged {
        /// What was found non-finite.
        what: &'static str,
    },
    /// Something that had to be seen by the camera never is.
    #[error("{what} is never in view of the camera")]
    NotInView {
        /// What was looked for.
        what: &'static str,
    },
    /// A configuration asks for something this build was compiled without.
    #[error(
        "{what} needs kflex-model's cargo feature \"{feature}\", which this build was compiled without"
    )]
    FeatureDisabled {
        /// What was asked for, as the configuration names it.
        what: &'static str,
        /// The cargo feature that provides it.
        feature: &'static str,
    },
}

impl ModelError {
    /// The range error behind this error: the quantity, the value and its
    /// bounds, for [`ModelError::OutOfRange`] and [`ModelError::OutOfWorkspace`].
    ///
    /// ```
    /// use kflex_model::{Command, Plant, PlantConfig};
    /// let mut plant = Plant::new(PlantConfig::default())?;
    /// let err = plant.step(Command { theta_c_deg: 30.0, translation_mm: 5.0 }, -0.01).unwrap_err();
    /// let range = err.range().expect("a range error");
    /// assert_eq!((range.name, range.value, range.bounds.min), ("dt_s", -0.01, 0.0));
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    #[must_use]
    pub fn range(&self) -> Option<&RangeError> {
        match self {
            Self::OutOfRange(e) | Self::OutOfWorkspace(e) => Some(e),
            _ => None,
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, ModelError>;

/// Checks `value` is finite, naming it in the error
/// ([`ModelError::NonFinite`]): the one such check of every kflex crate.
///
/// # Errors
/// [`ModelError::NonFinite`] for NaN or an infinity.
pub fn finite(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NonFinite { name, value })
    }
}

/// In tests: the range error of `result`, which must be an out-of-range
/// error (or an out-of-workspace one) for the quantity `name`.
#[cfg(test)]
pub(crate) fn expect_range<T: std::fmt::Debug>(result: Result<T>, name: &str) -> RangeError {
    match result {
        Err(ref err) if err.range().is_some_and(|e| e.name == name) => *err.range().unwrap(),
        other => panic!("expected {name} out of range, got {other:?}"),
    }
}
