//! The Kalman fusion filters (LBHJAE's fusion, kflex-estimate's `Fusion`),
//! one tick at a time or a whole sequence in one call.

use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, Estimate, Fusion, KalmanParams, Measurements, PaperKalman,
    SensorUse,
};
use numpy::{IntoPyArray, ndarray::Array2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::array;
use crate::error::{Result, type_error};
use crate::value::serde_class;

serde_class!(
    /// Parameters of the paper's filter (kflex-estimate's `KalmanParams`):
    /// `model_dt_s` (0.1), `sigma_a` (0.01), `sigma_z_deg` ([0.01, 0.01]),
    /// `rate` ("as_run" or "as_written").
    PyKalmanParams, "KalmanParams", KalmanParams, {}
);

serde_class!(
    /// Parameters of the adaptive filter (kflex-estimate's `AdaptiveParams`).
    PyAdaptiveParams, "AdaptiveParams", AdaptiveParams, {}
);

/// One tick's fused estimate.
#[pyclass(name = "Estimate", module = "kflex", frozen, get_all)]
pub struct PyEstimate {
    /// θ̂, deg.
    theta_hat_deg: f64,
    /// θ̂', deg/s.
    theta_hat_rate_deg_per_s: f64,
    /// Covariance of [θ̂, θ̂'], a 2×2 float64 array.
    covariance: Py<PyAny>,
    /// What became of KBJAE's measurement: "used", "missing", "held" or "gated".
    kbjae: &'static str,
    /// What became of IBJAE's measurement.
    ibjae: &'static str,
    /// IBJAE's normalised innovation squared when the gate rejected it, else None.
    ibjae_nis: Option<f64>,
}

fn use_name(u: SensorUse) -> &'static str {
    match u {
        SensorUse::Used => "used",
        SensorUse::Missing => "missing",
        SensorUse::Held => "held",
        SensorUse::Gated { .. } => "gated",
        _ => "other",
    }
}

pub(crate) fn estimate(py: Python<'_>, e: &Estimate) -> PyEstimate {
    let [[a, b], [c, d]] = e.covariance;
    let cov = Array2::from_shape_vec((2, 2), vec![a, b, c, d]).expect("2×2");
    PyEstimate {
        theta_hat_deg: e.theta_hat_deg,
        theta_hat_rate_deg_per_s: e.theta_hat_rate_deg_per_s,
        covariance: cov.into_pyarray(py).into_any().unbind(),
        kbjae: use_name(e.kbjae),
        ibjae: use_name(e.ibjae),
        ibjae_nis: match e.ibjae {
            SensorUse::Gated { nis } => Some(nis),
            _ => None,
        },
    }
}

/// A series of optional measurements: NaN marks a missing one.
fn optional_series(
    name: &str,
    obj: Option<&Bound<'_, PyAny>>,
    n: usize,
) -> Result<Vec<Option<f64>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(vec![None; n]);
    };
    let v = array::series(name, obj)?;
    if v.len() != n {
        return Err(type_error(format!(
            "{name}: expected {n} values (one per tick), got {}",
            v.len()
        )));
    }
    Ok(v.into_iter().map(|x| (!x.is_nan()).then_some(x)).collect())
}

/// Runs `filter` over whole series (the loop in Rust, without the
/// interpreter lock) and returns the columns.
fn run_series<'py>(
    py: Python<'py>,
    filter: &mut (dyn Fusion + Send),
    dt_s: f64,
    kbjae_deg: Option<&Bound<'py, PyAny>>,
    ibjae_deg: Option<&Bound<'py, PyAny>>,
    ibjae_sigma_deg: Option<&Bound<'py, PyAny>>,
    ibjae_occluded: Option<&Bound<'py, PyAny>>,
) -> Result<Bound<'py, PyDict>> {
    let n = [kbjae_deg, ibjae_deg]
        .iter()
        .flatten()
        .filter(|o| !o.is_none())
        .map(|o| array::series("measurements", o).map(|v| v.len()))
        .next()
        .transpose()?
        .ok_or_else(|| type_error("give kbjae_deg, ibjae_deg or both as arrays"))?;
    let z1 = optional_series("kbjae_deg", kbjae_deg, n)?;
    let z2 = optional_series("ibjae_deg", ibjae_deg, n)?;
    let sg = optional_series("ibjae_sigma_deg", ibjae_sigma_deg, n)?;
    let hidden = flag_series("ibjae_occluded", ibjae_occluded, n)?;
    let out = py.detach(|| -> Result<Vec<Estimate>> {
        (0..n)
            .map(|k| {
                filter
                    .step(
                        dt_s,
                        Measurements {
                            kbjae_deg: z1[k],
                            ibjae_deg: z2[k],
                            ibjae_sigma_deg: sg[k],
                            ibjae_occluded: hidden[k],
                        },
                    )
                    .map_err(Into::into)
            })
            .collect()
    })?;
    let d = PyDict::new(py);
    let col = |f: fn(&Estimate) -> f64| out.iter().map(f).collect::<Vec<f64>>();
    d.set_item("theta_hat_deg", array::column(py, col(|e| e.theta_hat_deg)))?;
    d.set_item(
        "theta_hat_rate_deg_per_s",
        array::column(py, col(|e| e.theta_hat_rate_deg_per_s)),
    )?;
    d.set_item(
        "theta_var_deg2",
        array::column(py, col(|e| e.covariance[0][0])),
    )?;
    let flags =
        |f: fn(&Estimate) -> bool| out.iter().map(f).collect::<Vec<bool>>().into_pyarray(py);
    d.set_item("kbjae_used", flags(|e| e.kbjae == SensorUse::Used))?;
    d.set_item("ibjae_used", flags(|e| e.ibjae == SensorUse::Used))?;
    d.set_item(
        "ibjae_gated",
        flags(|e| matches!(e.ibjae, SensorUse::Gated { .. })),
    )?;
    // as `run_experiment`'s details name them
    d.set_item(
        "theta_hat_covariance",
        array::covariances(py, out.iter().map(|e| e.covariance))?,
    )?;
    d.set_item(
        "ibjae_nis",
        array::column(
            py,
            col(|e| match e.ibjae {
                SensorUse::Gated { nis } => nis,
                _ => f64::NAN,
            }),
        ),
    )?;
    let numpy = py.import("numpy")?;
    let uses = |f: fn(&Estimate) -> SensorUse| -> Result<Bound<'py, PyAny>> {
        let names: Vec<&str> = out.iter().map(|e| use_name(f(e))).collect();
        Ok(numpy.call_method1("array", (names, "U7"))?)
    };
    d.set_item("kbjae_use", uses(|e| e.kbjae)?)?;
    d.set_item("ibjae_use", uses(|e| e.ibjae)?)?;
    Ok(d)
}

/// A series of flags, one per tick (all false where not given).
fn flag_series(name: &str, obj: Option<&Bound<'_, PyAny>>, n: usize) -> Result<Vec<bool>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(vec![false; n]);
    };
    let v = array::flags(name, obj)?;
    if v.len() != n {
        return Err(type_error(format!(
            "{name}: expected {n} values (one per tick), got {}",
            v.len()
        )));
    }
    Ok(v)
}

macro_rules! fusion_class {
    ($(#[$doc:meta])* $py:ident, $name:literal, $rust:ty, $params:ident) => {
        $(#[$doc])*
        #[pyclass(name = $name, module = "kflex")]
        pub struct $py {
            inner: $rust,
        }

        #[pymethods]
        impl $py {
            /// A filter at its initial state; raises `RangeError` for a
            /// parameter out of range.
            #[new]
            #[pyo3(signature = (params = None))]
            fn py_new(params: Option<$params>) -> Result<Self> {
                let params = params.map_or_else(Default::default, |p| p.inner);
                Ok(Self {
                    inner: <$rust>::new(params)?,
                })
            }

            /// One tick of `dt_s` seconds with this tick's measurements (deg;
            /// None where a sensor has none); `ibjae_occluded`: IBJAE's
            /// reading takes part of the instrument as hidden
            /// (`IbjaeReading.occluded`; the adaptive filter rejects it).
            /// Raises `ValueError` for a NaN or infinite value or
            /// `RangeError` for `dt_s`; the filter is then unchanged.
            #[pyo3(signature = (
                dt_s, kbjae_deg = None, ibjae_deg = None, ibjae_sigma_deg = None,
                ibjae_occluded = false
            ))]
            fn step(
                &mut self,
                py: Python<'_>,
                dt_s: f64,
                kbjae_deg: Option<f64>,
                ibjae_deg: Option<f64>,
                ibjae_sigma_deg: Option<f64>,
                ibjae_occluded: bool,
            ) -> Result<PyEstimate> {
                let e = self.inner.step(
                    dt_s,
                    Measurements {
                        kbjae_deg,
                        ibjae_deg,
                        ibjae_sigma_deg,
                        ibjae_occluded,
                    },
                )?;
                Ok(estimate(py, &e))
            }

            /// Whole series in one call, one tick of `dt_s` per element:
            /// arrays of KBJAE's and IBJAE's angles (deg; NaN where a sensor
            /// has no measurement), optionally IBJAE's own uncertainty and
            /// its hidden-part flags (bools; `run_experiment`'s details
            /// replay as they were logged). Returns a `dict` of arrays:
            /// `theta_hat_deg`, `theta_hat_rate_deg_per_s`, `theta_var_deg2`,
            /// `theta_hat_covariance` (n × 2 × 2), `kbjae_use` and
            /// `ibjae_use` (strings as `Estimate` names them), `ibjae_nis`
            /// (NaN where not gated), and the bool shorthands `kbjae_used`,
            /// `ibjae_used`, `ibjae_gated`. A series with a rejected tick
            /// raises as `step` would and leaves the filter as it was.
            #[pyo3(signature = (
                dt_s, kbjae_deg = None, ibjae_deg = None, ibjae_sigma_deg = None,
                ibjae_occluded = None
            ))]
            fn run<'py>(
                &mut self,
                py: Python<'py>,
                dt_s: f64,
                kbjae_deg: Option<&Bound<'py, PyAny>>,
                ibjae_deg: Option<&Bound<'py, PyAny>>,
                ibjae_sigma_deg: Option<&Bound<'py, PyAny>>,
                ibjae_occluded: Option<&Bound<'py, PyAny>>,
            ) -> Result<Bound<'py, PyDict>> {
                // on a copy, kept only when every tick was accepted: a
                // rejected series leaves the filter as it was
                let mut filter = self.inner.clone();
                let out = run_series(
                    py,
                    &mut filter,
                    dt_s,
                    kbjae_deg,
                    ibjae_deg,
                    ibjae_sigma_deg,
                    ibjae_occluded,
                )?;
                self.inner = filter;
                Ok(out)
            }

            /// The current estimate, without stepping.
            fn estimate(&self, py: Python<'_>) -> PyEstimate {
                estimate(py, &self.inner.estimate())
            }

            /// Back to the initial state.
            fn reset(&mut self) {
                self.inner.reset();
            }
        }
    };
}

fusion_class!(
    /// The paper's fusion filter (Eq. 6–12; kflex-estimate's `PaperKalman`):
    /// KBJAE and IBJAE as two sensors of a constant-velocity model.
    PyPaperKalman, "PaperKalman", PaperKalman, PyKalmanParams
);

fusion_class!(
    /// The adaptive fusion filter (kflex-estimate's `AdaptiveKalman`):
    /// real-time model, KBJAE's bias as a state, sensor noise from the
    /// innovations, a chi-square gate on the camera.
    PyAdaptiveKalman, "AdaptiveKalman", AdaptiveKalman, PyAdaptiveParams
);
