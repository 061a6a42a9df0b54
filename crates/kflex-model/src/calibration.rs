//! Default parameters fitted to the paper's uncompensated measurements.
//!
//! Produced by `make fit` (`cargo run --release -p kflex-control --example
//! fit_calibration`), which minimises the squared relative error to Table IX's
//! "none" row within plausible boxes; the residuals are in the crate docs
//! (`CALIBRATION.md`).

use crate::transmission::SheathParams;

impl Default for SheathParams {
    /// Defaults fitted to Table IX's uncompensated row (see "Calibration to the
    /// paper" in the crate docs).
    fn default() -> Self {
        FITTED_SHEATH
    }
}

/// Tendon-sheath parameters: physical values from the K-FLEX instrument and
/// the literature, and the fitted ones (see CALIBRATION.md for which and why).
pub(crate) const FITTED_SHEATH: SheathParams = SheathParams {
    friction_coefficient: 0.15,
    route_wrap_deg: 30.0,
    pretension_n: 3.0,
    tendon_stiffness_n_per_mm: 10.5,
    distal_stiffness_n_per_mm: 270.0,
    drive_backlash_mm: 0.1,
    presliding_mm: 0.02,
    elements: 20,
    sheath_path_mm_per_rad: 0.0,
};

/// Fitted bending stiffness of one rolling contact, N·mm/rad. The pretension's
/// straightening moment, `2T₀(R − B) ≈ 13.5` N·mm/rad per contact, adds to it.
pub(crate) const FITTED_CONTACT_STIFFNESS: f64 = 34.86;
