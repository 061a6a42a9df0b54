//! The one error type of `kflex-model`.

use thiserror::Error;

/// Everything that can go wrong in the testbed model.
///
/// Variants carry the offending value and the range it had to be in, so a
/// caller can print a message a person can act on without extra context.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ModelError {
    /// A configuration or call parameter is outside its physically meaningful range.
    #[error("{name} = {value} is out of range: must be in {range}")]
    InvalidParameter {
        /// Parameter name, as in the config struct (units in the name where they apply).
        name: &'static str,
        /// The value that was given.
        value: f64,
        /// The valid range, in words (e.g. "(0, inf)" or "[1, 16]").
        range: String,
    },
    /// A command or input is NaN or infinite.
    #[error("{name} is not finite ({value})")]
    NonFinite {
        /// Which input.
        name: &'static str,
        /// The value that was given.
        value: f64,
    },
    /// A commanded value lies outside the device's workspace.
    #[error("{name} = {value} is outside the workspace [{min}, {max}]")]
    OutOfWorkspace {
        /// Which command (`theta_deg`, `translation_mm`, ...).
        name: &'static str,
        /// The commanded value.
        value: f64,
        /// Lower limit, same units.
        min: f64,
        /// Upper limit, same units.
        max: f64,
    },
    /// A tendon length change that no joint angle in the mechanical range produces.
    #[error(
        "tendon length change {delta_l_mm} mm is not reachable: reachable range [{min_mm}, {max_mm}] mm"
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
    /// The physics engine produced a state that is not finite; the plant keeps its last good state.
    #[error("the joint simulation diverged ({what}); the plant state was left unchanged")]
    Diverged {
        /// What was found non-finite.
        what: &'static str,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, ModelError>;

/// Checks `value` is finite, naming it in the error.
pub(crate) fn finite(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ModelError::NonFinite { name, value })
    }
}

/// Checks `lo < value < hi` (open interval; use infinities for one-sided ranges).
pub(crate) fn open_range(name: &'static str, value: f64, lo: f64, hi: f64) -> Result<f64> {
    if value.is_finite() && value > lo && value < hi {
        Ok(value)
    } else {
        Err(ModelError::InvalidParameter {
            name,
            value,
            range: format!("({lo}, {hi})"),
        })
    }
}

/// Checks `lo <= value <= hi` (closed interval).
pub(crate) fn closed_range(name: &'static str, value: f64, lo: f64, hi: f64) -> Result<f64> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(ModelError::InvalidParameter {
            name,
            value,
            range: format!("[{lo}, {hi}]"),
        })
    }
}

/// Checks an image size: each dimension in `[1, 16384]` px.
pub(crate) fn image_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        return Err(ModelError::InvalidParameter {
            name: "image size",
            value: f64::from(width.min(height)),
            range: "[1, 16384] px in each dimension".into(),
        });
    }
    Ok(())
}
