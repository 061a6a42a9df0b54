//! The closed loop (kflex-control's `ClosedLoopScenario`): compensator,
//! plant, the robot's camera and an estimator, tick by tick, in Rust
//! without the interpreter lock; and a run's MCAP log.

use std::path::PathBuf;

use kflex_control::{
    AngleEstimator, ClosedLoopScenario, ClosedLoopTrace, NoisyTruth, ReadingUse, RunMetrics,
    TickDetails,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::array;
use crate::error::{Error, Int, Result, unsigned};
use crate::models::PyKbjae;
use crate::plant::PyPlant;
use crate::retrieval::PyLbhjae;
use crate::value::{self, serde_class};

/// A stand-in estimator (kflex-control's `NoisyTruth`): the plant's true
/// angle at each camera frame plus Gaussian noise of `sigma_deg`, held
/// between frames; no pixels are rendered. Raises `RangeError` for
/// `sigma_deg` outside [0, 90].
#[pyclass(name = "NoisyTruth", module = "kflex")]
pub struct PyNoisyTruth {
    inner: NoisyTruth,
}

#[pymethods]
impl PyNoisyTruth {
    #[new]
    #[pyo3(signature = (sigma_deg, seed = 0))]
    fn py_new(sigma_deg: f64, seed: Int) -> Result<Self> {
        Ok(Self {
            inner: NoisyTruth::new(sigma_deg, unsigned("seed", seed)?)?,
        })
    }
}

serde_class!(
    /// One closed-loop run's settings (kflex-control's `ClosedLoopScenario`):
    /// `motion` (an `OpenLoopScenario`'s fields: input, duration, tick,
    /// pre-roll, translation), `camera` (`rate_hz`, `latency_s`,
    /// `drop_probability`), `frames` (a `FrameParams`' fields), `tolerances`
    /// (a `BuildTolerances`' fields: the robot's instrument and camera
    /// against the nominal ones) and `compensator` (a `CompensatorConfig`'s
    /// fields, or None for θ_c = θ_d).
    PyClosedLoopScenario, "ClosedLoopScenario", ClosedLoopScenario, {
        /// Runs the loop on `plant` (from its current state) with
        /// `estimator` (a `NoisyTruth`, `Kbjae` or `Lbhjae`, reset first),
        /// frames and losses drawn from `seed`, and returns the evaluated
        /// part. With `mcap_path`, also writes the run's MCAP log there.
        /// Raises `RangeError` for a setting out of range (before the plant
        /// moves), `TypeError` for another estimator, and the estimator's
        /// or the plant's errors; `OSError` when the log cannot be written.
        #[pyo3(signature = (plant, estimator, seed = 0, mcap_path = None))]
        fn run(
            &self,
            py: Python<'_>,
            mut plant: PyRefMut<'_, PyPlant>,
            estimator: &Bound<'_, PyAny>,
            seed: Int,
            mcap_path: Option<PathBuf>,
        ) -> Result<PyClosedLoopTrace> {
            let seed: u64 = unsigned("seed", seed)?;
            let scenario = self.inner.clone();
            let plant = &mut plant.inner;
            // the estimator's borrow lives in one of these for the run (a
            // shared KBJAE's lock is taken without the interpreter lock)
            let (mut noisy, kbjae, mut lbhjae);
            let chosen = if let Ok(e) = estimator.extract::<PyRefMut<'_, PyNoisyTruth>>() {
                noisy = e;
                Chosen::Own(&mut noisy.inner)
            } else if let Ok(e) = estimator.extract::<PyRef<'_, PyKbjae>>() {
                kbjae = e;
                Chosen::Shared(&kbjae.inner)
            } else if let Ok(e) = estimator.extract::<PyRefMut<'_, PyLbhjae>>() {
                lbhjae = e;
                Chosen::Own(
                    lbhjae
                        .inner
                        .get_mut()
                        .unwrap_or_else(std::sync::PoisonError::into_inner),
                )
            } else {
                return Err(Error::Py(pyo3::exceptions::PyTypeError::new_err(format!(
                    "estimator must be a NoisyTruth, Kbjae or Lbhjae, not {}",
                    estimator.get_type().name().map_err(Error::Py)?
                ))));
            };
            let trace = py.detach(|| {
                let mut guard;
                let estimator: &mut (dyn AngleEstimator + Send) = match chosen {
                    Chosen::Own(e) => e,
                    Chosen::Shared(m) => {
                        guard = m.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                        &mut *guard
                    }
                };
                let trace = scenario.run(plant, estimator, seed)?;
                if let Some(path) = &mcap_path {
                    trace.write_mcap(path, &scenario, seed)?;
                }
                Ok::<_, Error>(trace)
            })?;
            Ok(PyClosedLoopTrace { inner: trace })
        }
    }
);

/// The estimator a closed-loop run steps: one the run borrows alone, or a
/// KBJAE that Python threads share (locked for the run).
enum Chosen<'a> {
    Own(&'a mut (dyn AngleEstimator + Send)),
    Shared(&'a std::sync::Mutex<kflex_estimate::Kbjae>),
}

/// A recorded closed-loop run (kflex-control's `ClosedLoopTrace`): one row
/// per evaluated tick, each column a float64 array.
#[pyclass(name = "ClosedLoopTrace", module = "kflex")]
pub struct PyClosedLoopTrace {
    inner: ClosedLoopTrace,
}

#[pymethods]
impl PyClosedLoopTrace {
    /// Time since the start of evaluation, s.
    #[getter]
    fn time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.trace.time_s.clone())
    }

    /// θ_d, deg.
    #[getter]
    fn theta_d_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.trace.theta_d_deg.clone())
    }

    /// θ_c sent to the plant, deg.
    #[getter]
    fn theta_c_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.theta_c_deg.clone())
    }

    /// True θ_a, deg.
    #[getter]
    fn theta_a_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.trace.theta_a_deg.clone())
    }

    /// θ_a as the tracker measures it, deg.
    #[getter]
    fn theta_a_measured_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.trace.theta_a_measured_deg.clone())
    }

    /// The estimate θ̂, deg; NaN before the estimator had one.
    #[getter]
    fn theta_hat_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        let hat = self
            .inner
            .theta_hat_deg
            .iter()
            .map(|h| h.unwrap_or(f64::NAN))
            .collect();
        array::column(py, hat)
    }

    /// What went into each tick's estimate, as the estimator tells it
    /// (kflex-control's `TickDetails`, as `run_experiment`'s `details`): a
    /// `dict` of arrays named as the MCAP joint states' fields (float64,
    /// NaN where a tick has none; bool; `kbjae_use` and `ibjae_use` as
    /// strings, `""` where none).
    #[getter]
    fn details<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        details_dict(py, &self.inner.details)
    }

    /// Ticks in which the compensator held its command for a fault.
    #[getter]
    fn fault_ticks(&self) -> usize {
        self.inner.fault_ticks
    }

    /// The camera's frames: a `dict` of `captured`, `dropped`, `delivered`
    /// and `stale`.
    #[getter]
    fn frames<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyAny>> {
        Ok(value::to_py(py, &value::to_value(&self.inner.frames)?)?)
    }

    /// θ_a against θ_d, the paper's metrics on the measured angle, deg (as
    /// `Trace.metrics`).
    fn metrics<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyAny>> {
        let m: RunMetrics = self.inner.trace.metrics()?;
        Ok(value::to_py(py, &value::to_value(&m)?)?)
    }

    /// RMSE of the estimate against the true angle over the ticks that have
    /// one, deg. Raises `ValueError` where none has.
    fn estimation_rmse_deg(&self) -> Result<f64> {
        Ok(self.inner.estimation_rmse_deg()?)
    }

    fn __len__(&self) -> usize {
        self.inner.trace.time_s.len()
    }
}

/// One estimator's [`TickDetails`] over a run as arrays, named as the MCAP
/// joint states name them: float64 with NaN where a tick has none
/// (`ibjae_consistent_deg` n × 2, `theta_hat_covariance` n × 2 × 2), bool `frame_arrived` and
/// `ibjae_occluded` (false where none), and `kbjae_use` / `ibjae_use` as
/// strings (`"used"`, `"gated"`, `"missing"`, `"held"`, `"other"`; `""`
/// where none).
pub(crate) fn details_dict<'py>(
    py: Python<'py>,
    ticks: &[TickDetails],
) -> PyResult<Bound<'py, PyDict>> {
    use numpy::IntoPyArray;
    use numpy::ndarray::Array2;
    let d = PyDict::new(py);
    type Float = fn(&TickDetails) -> Option<f64>;
    type Flag = fn(&TickDetails) -> bool;
    type Use = fn(&TickDetails) -> Option<ReadingUse>;
    let floats: [(&str, Float); 7] = [
        ("theta_hat_sigma_deg", |t| t.theta_hat_sigma_deg),
        ("theta_hat_rate_deg_per_s", |t| t.theta_hat_rate_deg_per_s),
        ("kbjae_deg", |t| t.kbjae_deg),
        ("ibjae_deg", |t| t.ibjae_deg),
        ("ibjae_sigma_deg", |t| t.ibjae_sigma_deg),
        ("ibjae_silhouette_iou", |t| t.ibjae_silhouette_iou),
        ("ibjae_nis", |t| t.ibjae_nis),
    ];
    for (name, f) in floats {
        let column = ticks.iter().map(|t| f(t).unwrap_or(f64::NAN)).collect();
        d.set_item(name, array::column(py, column))?;
    }
    let consistent: Vec<f64> = ticks
        .iter()
        .flat_map(|t| t.ibjae_consistent_deg.unwrap_or([f64::NAN; 2]))
        .collect();
    let consistent = Array2::from_shape_vec((ticks.len(), 2), consistent)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    d.set_item("ibjae_consistent_deg", consistent.into_pyarray(py))?;
    let covariances = ticks
        .iter()
        .map(|t| t.theta_hat_covariance.unwrap_or([[f64::NAN; 2]; 2]));
    d.set_item("theta_hat_covariance", array::covariances(py, covariances)?)?;
    let flags: [(&str, Flag); 2] = [
        ("frame_arrived", |t| t.frame_arrived == Some(true)),
        ("ibjae_occluded", |t| t.ibjae_occluded == Some(true)),
    ];
    for (name, f) in flags {
        let column: Vec<bool> = ticks.iter().map(f).collect();
        d.set_item(name, column.into_pyarray(py))?;
    }
    let numpy = py.import("numpy")?;
    let uses: [(&str, Use); 2] = [
        ("kbjae_use", |t| t.kbjae_use),
        ("ibjae_use", |t| t.ibjae_use),
    ];
    for (name, f) in uses {
        let column: Vec<&str> = ticks
            .iter()
            .map(|t| match f(t) {
                Some(ReadingUse::Used) => "used",
                Some(ReadingUse::Missing) => "missing",
                Some(ReadingUse::Held) => "held",
                Some(ReadingUse::Gated) => "gated",
                Some(_) => "other",
                None => "",
            })
            .collect();
        d.set_item(name, numpy.call_method1("array", (column, "U7"))?)?;
    }
    Ok(d)
}
