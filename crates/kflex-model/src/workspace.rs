//! The workspace of the instrument: the joint's hard stops and the
//! translation stage's travel, and the one check of a pose against them.

use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result, finite};
use crate::range::Bounds;

/// Limits and speed of the translation stage (no hysteresis: a stiff lead screw).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TranslationParams {
    /// Shortest extension out of the overtube, mm.
    pub min_mm: f64,
    /// Longest extension, mm.
    pub max_mm: f64,
    /// Speed limit of the stage, mm/s.
    pub max_speed_mm_per_s: f64,
}

impl Default for TranslationParams {
    fn default() -> Self {
        Self {
            min_mm: 0.0,
            max_mm: 40.0,
            max_speed_mm_per_s: 20.0,
        }
    }
}

impl TranslationParams {
    /// Checks the limits and the speed.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range.
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.0, 1e3).check("translation.min_mm", self.min_mm)?;
        Bounds::closed(self.min_mm, 1e3).check("translation.max_mm", self.max_mm)?;
        Bounds::open(0.0, 1e4).check("translation.max_speed_mm_per_s", self.max_speed_mm_per_s)?;
        Ok(())
    }
}

/// Checks a pose (bend `theta_deg`, named `theta_name`, and translation)
/// against the joint's hard stops `±max_theta_deg` and the stage's travel.
///
/// # Errors
/// [`ModelError::NonFinite`] for NaN or infinite values,
/// [`ModelError::OutOfWorkspace`] for a pose past a limit.
pub(crate) fn check_pose(
    max_theta_deg: f64,
    translation: &TranslationParams,
    theta_name: &'static str,
    theta_deg: f64,
    translation_mm: f64,
) -> Result<()> {
    finite(theta_name, theta_deg)?;
    finite("translation_mm", translation_mm)?;
    Bounds::closed(-max_theta_deg, max_theta_deg)
        .check(theta_name, theta_deg)
        .map_err(ModelError::OutOfWorkspace)?;
    Bounds::closed(translation.min_mm, translation.max_mm)
        .check("translation_mm", translation_mm)
        .map_err(ModelError::OutOfWorkspace)?;
    Ok(())
}
