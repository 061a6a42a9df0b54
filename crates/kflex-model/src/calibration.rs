//! Default parameters fitted to the paper's uncompensated measurements.
//!
//! Produced by `make fit` (`cargo run --release -p kflex-control --example
//! fit_calibration`), which minimises the squared relative error to Table IX's
//! "none" row within plausible boxes; the residuals are in the crate docs
//! (`CALIBRATION.md`).

use crate::transmission::SheathParams;

/// Fitted tendon-sheath parameters (all of them free in the fit).
pub const FITTED_SHEATH: SheathParams = SheathParams {
    friction_coefficient: 0.1519,
    route_wrap_deg: 1.0003,
    pretension_n: 3.935,
    tendon_stiffness_n_per_mm: 27.48,
    coulomb_friction_n: 0.0233,
    drive_backlash_mm: 0.1569,
    sheath_coupling_mm_per_rad: 0.0856,
    friction_sharpness: 6.0,
};

/// Fitted bending stiffness of one rolling contact, N·mm/rad. The pretension's
/// straightening moment, `2T₀(R − B) ≈ 14.2` N·mm/rad per contact, adds to it.
pub const FITTED_CONTACT_STIFFNESS: f64 = 29.29;
