//! Tendon kinematics of the continuum bending joint: the paper's Eq. 1–2.

use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};
use crate::range::{Bounds, RangeError};

/// Geometry of the tendon-driven continuum joint (Eq. 1). Lengths in mm.
///
/// ```text
/// ΔL_a(θ) = 2n { R − d_t sin(θ/2n) − (R − B) cos(θ/2n) − B }      (Eq. 1)
/// ΔL_b(θ) = ΔL_a(−θ)                                              (Eq. 2)
/// ```
/// with `n` segments (each has two rolling contacts, hence `2n` equal
/// contact angles `φ = θ/2n`), `R` the radius of the rolling contact surface,
/// `B` the offset of the tendon's exit point from that surface, and `d_t`
/// the tendon's lateral offset from the joint axis. The paper writes the
/// tendon offset `d`; here it is [`TendonGeometry::tendon_offset_mm`] so it
/// is not confused with the instrument's translation `d`.
///
/// Sign convention: positive θ bends the joint toward tendon `a`, which then
/// shortens (ΔL_a < 0); a motor *pulls* tendon `a` by `−ΔL_a`.
/// Angles are radians in this module (the plant's API speaks degrees).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TendonGeometry {
    /// Number of segments `n` of the continuum joint (the paper's K-FLEX joint has 2).
    pub n_segments: u32,
    /// `R`: radius of the rolling contact surfaces, mm.
    pub r_mm: f64,
    /// `B`: offset of the tendon exit point from the rolling surface, mm (`0 ≤ B < R`).
    pub b_mm: f64,
    /// `d_t` (the paper's `d`): lateral distance of each tendon from the joint axis, mm.
    pub tendon_offset_mm: f64,
}

impl Default for TendonGeometry {
    /// K-FLEX-scale defaults for an instrument about 4 mm across.
    fn default() -> Self {
        Self {
            n_segments: 2,
            r_mm: 3.0,
            b_mm: 1.2,
            tendon_offset_mm: 1.6,
        }
    }
}

impl TendonGeometry {
    /// Checks the parameters alone, the first part of
    /// [`TendonGeometry::validate`]: within them Eq. 1–2 and the strokes
    /// below are finite at every finite bend.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range
    /// (`n_segments` outside `[1, 16]`, `r_mm` outside `(0, 100)` mm, `b_mm`
    /// outside `[0, r_mm)` mm, `tendon_offset_mm` outside `(0, 100)` mm).
    pub fn validate_parameters(&self) -> Result<()> {
        Bounds::closed(1.0, 16.0).check("n_segments", f64::from(self.n_segments))?;
        Bounds::open(0.0, 100.0).check("r_mm", self.r_mm)?;
        Bounds::closed_open(0.0, self.r_mm).check("b_mm", self.b_mm)?;
        Bounds::open(0.0, 100.0).check("tendon_offset_mm", self.tendon_offset_mm)?;
        Ok(())
    }

    /// Checks the parameters and that Eq. 1 is strictly monotone over
    /// `[-max_theta, max_theta]` (radians), which the inverse needs:
    /// `dΔL_a/dθ = (R−B) sin φ − d_t cos φ < 0 ⇔ tan φ < d_t/(R−B)`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range
    /// (`n_segments` outside `[1, 16]`, `r_mm` outside `(0, 100)` mm, `b_mm`
    /// outside `[0, r_mm)` mm (`R − B` divides in the monotonicity limit),
    /// `tendon_offset_mm` outside `(0, 100)` mm); when
    /// Eq. 1 is not monotone over `±max_theta_rad`, one named
    /// `max_theta_deg` (Eq. 1 must be monotone over the joint's range) that
    /// carries `max_theta_rad` in degrees and, as its bounds, the range this
    /// geometry allows.
    pub fn validate(&self, max_theta_rad: f64) -> Result<()> {
        self.validate_parameters()?;
        let phi_max = max_theta_rad / self.two_n();
        let limit = (self.tendon_offset_mm / (self.r_mm - self.b_mm)).atan();
        // (NaN and a range that is not positive are out of it too)
        if phi_max.is_nan()
            || phi_max <= 0.0
            || phi_max >= limit
            || phi_max >= std::f64::consts::FRAC_PI_2
        {
            let theta_limit_deg = (2.0 * self.two_n() * limit).to_degrees() / 2.0;
            return Err(RangeError {
                name: "max_theta_deg",
                value: max_theta_rad.to_degrees(),
                bounds: Bounds::open(0.0, theta_limit_deg),
            }
            .into());
        }
        Ok(())
    }

    fn two_n(&self) -> f64 {
        2.0 * f64::from(self.n_segments)
    }

    /// Eq. 1: change of the length of tendon `a`'s path through the joint, mm, at bend `theta` (rad).
    #[must_use]
    pub fn delta_l_a_mm(&self, theta_rad: f64) -> f64 {
        let phi = theta_rad / self.two_n();
        self.two_n()
            * (self.r_mm
                - self.tendon_offset_mm * phi.sin()
                - (self.r_mm - self.b_mm) * phi.cos()
                - self.b_mm)
    }

    /// Eq. 2: `ΔL_b(θ) = ΔL_a(−θ)`, mm.
    #[must_use]
    pub fn delta_l_b_mm(&self, theta_rad: f64) -> f64 {
        self.delta_l_a_mm(-theta_rad)
    }

    /// `dΔL_a/dθ`, mm/rad.
    #[must_use]
    pub fn delta_l_a_slope_mm_per_rad(&self, theta_rad: f64) -> f64 {
        let phi = theta_rad / self.two_n();
        (self.r_mm - self.b_mm) * phi.sin() - self.tendon_offset_mm * phi.cos()
    }

    /// Differential stroke `s(θ) = (ΔL_b − ΔL_a)/2 = 2n d_t sin(θ/2n)`, mm: how far
    /// tendon `a` is pulled in, and `b` paid out, relative to their mean.
    #[must_use]
    pub fn differential_stroke_mm(&self, theta_rad: f64) -> f64 {
        self.two_n() * self.tendon_offset_mm * (theta_rad / self.two_n()).sin()
    }

    /// `ds/dθ = d_t cos(θ/2n)`, mm/rad: the moment arm of the differential tendon force.
    #[must_use]
    pub fn stroke_slope_mm_per_rad(&self, theta_rad: f64) -> f64 {
        self.tendon_offset_mm * (theta_rad / self.two_n()).cos()
    }

    /// Common-mode change `(ΔL_a + ΔL_b)/2 = 2n (R−B)(1 − cos(θ/2n))`, mm: both
    /// tendon paths lengthen as the joint bends (the motors pay tendon out).
    #[must_use]
    pub fn common_mode_mm(&self, theta_rad: f64) -> f64 {
        self.two_n() * (self.r_mm - self.b_mm) * (1.0 - (theta_rad / self.two_n()).cos())
    }

    /// Inverse of Eq. 1: the bend θ (rad, within `[-max_theta, max_theta]`) at which
    /// tendon `a`'s path changes by `delta_l_a_mm`.
    ///
    /// Eq. 1 is strictly decreasing over a validated range, so a safeguarded
    /// Newton iteration on the bracket (bisecting whenever a Newton step
    /// leaves it) converges for every reachable value.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `delta_l_a_mm`;
    /// as [`TendonGeometry::validate`] for a bad geometry or a `max_theta_rad`
    /// that is not positive or past the geometry's range (NaN included);
    /// [`ModelError::Unreachable`] when `delta_l_a_mm` lies outside
    /// `[ΔL_a(max_theta), ΔL_a(−max_theta)]`, the range it reports.
    pub fn theta_rad_from_delta_l_a(&self, delta_l_a_mm: f64, max_theta_rad: f64) -> Result<f64> {
        crate::error::finite("delta_l_a_mm", delta_l_a_mm)?;
        // the geometry and the range it is inverted over
        self.validate(max_theta_rad)?;
        let (lo, hi) = (-max_theta_rad, max_theta_rad);
        // decreasing: f(lo) is the largest value, f(hi) the smallest
        let (f_lo, f_hi) = (self.delta_l_a_mm(lo), self.delta_l_a_mm(hi));
        if delta_l_a_mm > f_lo || delta_l_a_mm < f_hi {
            return Err(ModelError::Unreachable {
                delta_l_mm: delta_l_a_mm,
                min_mm: f_hi,
                max_mm: f_lo,
            });
        }
        let theta = crate::numeric::root_decreasing(
            |t| {
                (
                    self.delta_l_a_mm(t) - delta_l_a_mm,
                    self.delta_l_a_slope_mm_per_rad(t),
                )
            },
            lo,
            hi,
            -delta_l_a_mm / self.tendon_offset_mm, // small-angle guess
            1e-14,
        );
        Ok(theta)
    }

    /// Inverse of the differential stroke: θ (rad) from `s` (mm), closed form.
    #[must_use]
    pub fn theta_rad_from_stroke(&self, stroke_mm: f64) -> Option<f64> {
        let x = stroke_mm / (self.two_n() * self.tendon_offset_mm);
        (x.abs() <= 1.0).then(|| self.two_n() * x.asin())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::expect_range;
    use proptest::prelude::*;

    const MAX: f64 = 120.0 * std::f64::consts::PI / 180.0;

    #[test]
    fn zero_bend_changes_nothing() {
        let g = TendonGeometry::default();
        assert_eq!(g.delta_l_a_mm(0.0), 0.0);
        assert_eq!(g.differential_stroke_mm(0.0), 0.0);
        assert!(g.validate(MAX).is_ok());
    }

    #[test]
    fn small_angle_slope_is_minus_the_offset() {
        let g = TendonGeometry::default();
        let h = 1e-6;
        let slope = (g.delta_l_a_mm(h) - g.delta_l_a_mm(-h)) / (2.0 * h);
        assert!((slope + g.tendon_offset_mm).abs() < 1e-6, "{slope}");
    }

    #[test]
    fn rejects_non_monotone_range_and_bad_geometry() {
        // the inverse checks its range and geometry (NaN bounds would panic a clamp)
        let k = TendonGeometry::default();
        for max in [f64::NAN, -1.0, 0.0, 10.0] {
            assert_eq!(
                expect_range(k.theta_rad_from_delta_l_a(0.0, max), "max_theta_deg")
                    .value
                    .is_nan(),
                max.is_nan()
            );
        }
        let zero = TendonGeometry {
            n_segments: 0,
            ..Default::default()
        };
        expect_range(zero.theta_rad_from_delta_l_a(0.0, 1.0), "n_segments");
        let g = TendonGeometry {
            r_mm: 5.0,
            b_mm: 0.0,
            tendon_offset_mm: 0.5,
            n_segments: 1,
        };
        let e = expect_range(g.validate(MAX), "max_theta_deg");
        // tan(φ) < d_t/(R − B) = 0.1 with 2n = 2 contacts: θ < 2·atan(0.1) = 11.4°
        assert!((e.bounds.max - 2.0 * 0.1f64.atan().to_degrees()).abs() < 1e-9);
        assert!((e.value - MAX.to_degrees()).abs() < 1e-9);
        let g = TendonGeometry {
            n_segments: 0,
            ..Default::default()
        };
        assert_eq!(expect_range(g.validate(MAX), "n_segments").value, 0.0);
        let g = TendonGeometry {
            b_mm: 4.0,
            ..Default::default()
        };
        let e = expect_range(g.validate(MAX), "b_mm");
        assert_eq!((e.value, e.bounds.max), (4.0, 3.0));
        // B = R leaves R − B = 0 to divide by: refused, the bound open
        let g = TendonGeometry {
            b_mm: 3.0,
            ..Default::default()
        };
        let e = expect_range(g.validate(MAX), "b_mm");
        assert_eq!(
            (e.value, e.bounds.max, e.bounds.max_inclusive),
            (3.0, 3.0, false)
        );
        assert!(
            g.validate(MAX)
                .unwrap_err()
                .to_string()
                .ends_with("must be in [0, 3)")
        );
        assert!(
            TendonGeometry {
                b_mm: 2.999,
                ..Default::default()
            }
            .validate(MAX)
            .is_ok()
        );
    }

    #[test]
    fn unreachable_length_is_an_error() {
        let g = TendonGeometry::default();
        // a huge length prints in scientific notation, not 301 digits
        let msg = g
            .theta_rad_from_delta_l_a(-1e300, MAX)
            .unwrap_err()
            .to_string();
        assert!(
            msg.starts_with("tendon length change -1e300 mm is not reachable: reachable range ["),
            "{msg}"
        );
        assert!(msg.len() < 120, "{msg}");
        assert!(matches!(
            g.theta_rad_from_delta_l_a(100.0, MAX),
            Err(ModelError::Unreachable { .. })
        ));
        assert!(matches!(
            g.theta_rad_from_delta_l_a(f64::NAN, MAX),
            Err(ModelError::NonFinite {
                name: "delta_l_a_mm",
                ..
            })
        ));
    }

    proptest! {
        #[test]
        fn inverse_of_forward_is_identity(theta in -MAX..MAX) {
            let g = TendonGeometry::default();
            let back = g.theta_rad_from_delta_l_a(g.delta_l_a_mm(theta), MAX).unwrap();
            prop_assert!((back - theta).abs() < 1e-9, "{theta} -> {back}");
            let back = g.theta_rad_from_stroke(g.differential_stroke_mm(theta)).unwrap();
            prop_assert!((back - theta).abs() < 1e-9);
        }

        #[test]
        fn forward_is_strictly_decreasing(a in -MAX..MAX, b in -MAX..MAX) {
            let g = TendonGeometry::default();
            prop_assume!((a - b).abs() > 1e-9);
            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
            prop_assert!(g.delta_l_a_mm(lo) > g.delta_l_a_mm(hi));
        }

        #[test]
        fn antagonist_is_the_mirror(theta in -MAX..MAX) {
            let g = TendonGeometry::default();
            prop_assert!((g.delta_l_b_mm(theta) - g.delta_l_a_mm(-theta)).abs() < 1e-15);
            // the sum is the common mode, the half-difference is the stroke
            let sum = 0.5 * (g.delta_l_a_mm(theta) + g.delta_l_b_mm(theta));
            prop_assert!((sum - g.common_mode_mm(theta)).abs() < 1e-12);
            let diff = 0.5 * (g.delta_l_b_mm(theta) - g.delta_l_a_mm(theta));
            prop_assert!((diff - g.differential_stroke_mm(theta)).abs() < 1e-12);
        }
    }
}
