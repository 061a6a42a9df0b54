//! Eq. 1–2 tendon kinematics, vectorised over numpy arrays.

use kflex_model::{ModelError, TendonGeometry};
use pyo3::prelude::*;

use crate::array;
use crate::error::Result;
use crate::value::serde_class;

/// `f` of each bend in `theta_rad` (rad; a number or an array, whose shape
/// the result keeps), after checking `geometry`'s parameters; a NaN or
/// infinite bend is a `ValueError` (the result is a tendon stroke, a motor's
/// command: never NaN).
fn of_theta<'py>(
    py: Python<'py>,
    geometry: &TendonGeometry,
    theta_rad: &Bound<'py, PyAny>,
    f: impl Fn(f64) -> f64,
) -> Result<Bound<'py, PyAny>> {
    geometry.validate_parameters()?;
    let out = array::floats("theta_rad", theta_rad)?.try_map(|t| {
        if t.is_finite() {
            Ok(f(t))
        } else {
            Err(ModelError::NonFinite {
                name: "theta_rad",
                value: t,
            })
        }
    })?;
    Ok(out.into_py(py)?)
}

serde_class!(
    /// Geometry of the continuum joint (kflex-model's `TendonGeometry`, Eq.
    /// 1): `n_segments`, `r_mm` (R), `b_mm` (B), `tendon_offset_mm` (d_t).
    /// Its functions take the bend in radians, as a number or a
    /// float64/float32 array (the result keeps the shape).
    PyTendonGeometry, "TendonGeometry", TendonGeometry, {
        /// Checks the parameters and that Eq. 1 is monotone over
        /// ±`max_theta_rad`; raises `RangeError`.
        fn validate(&self, max_theta_rad: f64) -> Result<()> {
            Ok(self.inner.validate(max_theta_rad)?)
        }

        /// Eq. 1: change of tendon a's path length, mm, at bend `theta_rad`.
        fn delta_l_a_mm<'py>(&self, py: Python<'py>, theta_rad: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
            of_theta(py, &self.inner, theta_rad, |t| self.inner.delta_l_a_mm(t))
        }

        /// Eq. 2: `ΔL_b(θ) = ΔL_a(−θ)`, mm.
        fn delta_l_b_mm<'py>(&self, py: Python<'py>, theta_rad: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
            of_theta(py, &self.inner, theta_rad, |t| self.inner.delta_l_b_mm(t))
        }

        /// Differential stroke `(ΔL_b − ΔL_a)/2`, mm.
        fn differential_stroke_mm<'py>(&self, py: Python<'py>, theta_rad: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
            of_theta(py, &self.inner, theta_rad, |t| self.inner.differential_stroke_mm(t))
        }

        /// Common-mode change `(ΔL_a + ΔL_b)/2`, mm.
        fn common_mode_mm<'py>(&self, py: Python<'py>, theta_rad: &Bound<'py, PyAny>) -> Result<Bound<'py, PyAny>> {
            of_theta(py, &self.inner, theta_rad, |t| self.inner.common_mode_mm(t))
        }

        /// Inverse of Eq. 1: the bend (rad, within ±`max_theta_rad`) at which
        /// tendon a's path changes by `delta_l_a_mm` (mm). Raises
        /// `ValueError` for an unreachable or non-finite length change.
        fn theta_rad_from_delta_l_a<'py>(&self, py: Python<'py>, delta_l_a_mm: &Bound<'py, PyAny>, max_theta_rad: f64) -> Result<Bound<'py, PyAny>> {
            let g = self.inner;
            let lengths = array::floats("delta_l_a_mm", delta_l_a_mm)?;
            // a root search per element: without the interpreter lock
            let theta = py.detach(|| lengths.try_map(|dl| g.theta_rad_from_delta_l_a(dl, max_theta_rad)))?;
            Ok(theta.into_py(py)?)
        }
    }
);
