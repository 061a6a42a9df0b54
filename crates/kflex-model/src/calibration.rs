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

/// Fitted tendon-sheath parameters (all free in the fit except the distal run's
/// stiffness, set for about 50 mm of tendon pair between the sheath and the joint).
pub(crate) const FITTED_SHEATH: SheathParams = SheathParams {
    friction_coefficient: 0.1615,
    route_wrap_deg: 4.566,
    pretension_n: 3.757,
    tendon_stiffness_n_per_mm: 31.93,
    coulomb_friction_n: 0.9941,
    drive_backlash_mm: 0.1267,
    sheath_coupling_mm_per_rad: 0.0816,
    distal_stiffness_n_per_mm: 800.0,
};

/// Fitted bending stiffness of one rolling contact, N·mm/rad. The pretension's
/// straightening moment, `2T₀(R − B) ≈ 13.5` N·mm/rad per contact, adds to it.
pub(crate) const FITTED_CONTACT_STIFFNESS: f64 = 34.86;
