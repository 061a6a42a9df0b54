//! Default parameters fitted to the paper's uncompensated measurements.
//!
//! Produced by `make fit` (`KFLEX_FIT_PROTOCOL=1 cargo run --release -p
//! kflex-control --example fit_calibration`), which minimises the squared
//! relative error to Table IX's "none" row within plausible boxes, held to
//! the tolerances, to the loop shape's goals (saturating widths, rounded
//! transitions) and to `kflex-cli run`'s protocol; the residuals are in the
//! crate docs (`CALIBRATION.md`).

use crate::transmission::SheathParams;

impl Default for SheathParams {
    /// Defaults fitted to Table IX's uncompensated row (see "Calibration to the
    /// paper" in the crate docs).
    fn default() -> Self {
        FITTED_SHEATH
    }
}

/// Tendon-sheath parameters. Set from the instrument and the literature:
/// route wrap, pretension, both runs' stiffnesses (0.3 mm steel tendon), the
/// backlash's engagement and the element count. Fitted to Table IX (`make
/// fit`): friction coefficient, the sheath's path change, the drive backlash
/// and the pre-sliding displacement (with the contacts' stiffness below, five
/// in all). CALIBRATION.md gives each value's source or range.
pub(crate) const FITTED_SHEATH: SheathParams = SheathParams {
    friction_coefficient: 0.4568,
    route_wrap_deg: 10.0,
    pretension_n: 3.0,
    tendon_stiffness_n_per_mm: 10.5,
    distal_stiffness_n_per_mm: 270.0,
    drive_backlash_mm: 0.166,
    backlash_engagement_mm: 0.05,
    presliding_mm: 0.0121,
    elements: 20,
    sheath_path_mm_per_rad: -0.1028,
};

/// Fitted bending stiffness of one rolling contact, N·mm/rad. The pretension's
/// straightening moment, `2T₀(R − B) ≈ 10.8` N·mm/rad per contact, adds to it.
pub(crate) const FITTED_CONTACT_STIFFNESS: f64 = 22.69;
