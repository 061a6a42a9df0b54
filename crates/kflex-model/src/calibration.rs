//! Default parameters fitted to the paper's uncompensated measurements.
//!
//! Produced by `make fit` (`cargo run --release -p kflex-control --example
//! fit_calibration`), which minimises the squared relative error to Table
//! IX's "none" row within plausible boxes, held to the tolerances and to the
//! loop shape's goals (widths growing at every 15 deg up to 180 deg and
//! saturating beyond, rounded transitions); `kflex-cli run`'s protocol and
//! the run-to-run spread are checked by the tests. The residuals are in the
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
/// route wrap, both runs' stiffnesses (0.3 mm steel tendon), the backlash's
/// engagement and the element count; the pre-sliding displacement is held at
/// the value the last fit that freed it found. Fitted to Table IX (`make
/// fit`): friction coefficient, the sheath's path change, the drive backlash
/// and the pretension (with the contacts' stiffness below, five in all).
/// CALIBRATION.md gives each value's source or range.
pub(crate) const FITTED_SHEATH: SheathParams = SheathParams {
    friction_coefficient: 0.4972,
    route_wrap_deg: 10.0,
    pretension_n: 2.201,
    tendon_stiffness_n_per_mm: 10.5,
    distal_stiffness_n_per_mm: 270.0,
    drive_backlash_mm: 0.1654,
    backlash_engagement_mm: 0.05,
    presliding_mm: 0.0121,
    elements: 20,
    sheath_path_mm_per_rad: -0.0768,
};

/// Fitted bending stiffness of one rolling contact, N·mm/rad. The pretension's
/// straightening moment, `2T₀(R − B) ≈ 7.9` N·mm/rad per contact, adds to it.
pub(crate) const FITTED_CONTACT_STIFFNESS: f64 = 22.10;
