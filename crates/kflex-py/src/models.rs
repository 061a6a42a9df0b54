//! The estimators that run ONNX models (kflex-estimate's feature `onnx`):
//! KBJAE and IBJAE's Siamese CNN. ONNX Runtime is loaded on the first model
//! load, from the onnxruntime wheel (kflex-estimate's `onnx` module says
//! where it looks); without it, loading raises `RuntimeError` saying what to
//! install or set.

use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard, PoisonError};

use kflex_estimate::{EMBEDDING_DIM, Kbjae, SCNN_SIDE, Scnn};
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::prelude::*;

use crate::array;
use crate::error::{Int, Result, unsigned};

/// Locks `m` (the thread waits without the interpreter lock, so that the
/// thread holding `m` can finish and hand back its result); a lock whose
/// holder panicked is taken over, as every call leaves the model whole.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// KBJAE (kflex-estimate's `Kbjae`): the MLP that predicts the joint's
/// hysteresis error θ̃ from the command and its rate, so θ = θ_c + θ̃.
/// `step` keeps the command's history (its rate); `predict` and `errors`
/// keep none. Python threads may share one: their calls take turns.
#[pyclass(name = "Kbjae", module = "kflex", frozen)]
pub struct PyKbjae {
    pub(crate) inner: Mutex<Kbjae>,
    sha256: String,
}

#[pymethods]
impl PyKbjae {
    /// Loads KBJAE's ONNX model (input `theta_and_rate` [N, 2], output
    /// `theta_error` [N, 1]). Raises `OSError` for a file or card that
    /// cannot be read (`FileNotFoundError` for a missing one), `ValueError`
    /// when the card beside it (`NAME.card.json`) is not a model card,
    /// records another SHA-256, or the model's input or
    /// output is not KBJAE's, `RuntimeError` when ONNX Runtime is missing
    /// or refuses the file.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> Result<Self> {
        let kbjae = py.detach(|| Kbjae::load(&path))?;
        Ok(Self {
            sha256: kbjae.sha256().to_owned(),
            inner: Mutex::new(kbjae),
        })
    }

    /// The model file's SHA-256 (lowercase hex).
    #[getter]
    fn sha256(&self) -> &str {
        &self.sha256
    }

    /// One tick: the command `theta_c_deg` sent this tick, `dt_s` after
    /// the last; its rate `rate_deg_per_s` where given (in a compensated
    /// loop, the master's θ_d', as kflex's closed loop gives it), else a
    /// backward difference of the commands (0 on the first tick).
    /// Returns KBJAE's angle θ_c + θ̃, deg. Raises `ValueError` for a
    /// non-finite command or rate, `RangeError` for `dt_s` outside
    /// (0, 3600], a command beyond ±1e6 deg or a rate beyond ±1e9 deg/s
    /// (the one differenced from the commands too), `RuntimeError` for a
    /// model that answers with a value that is not finite (damaged
    /// weights); the estimator is then unchanged.
    #[pyo3(signature = (theta_c_deg, dt_s, rate_deg_per_s = None))]
    fn step(
        &self,
        py: Python<'_>,
        theta_c_deg: f64,
        dt_s: f64,
        rate_deg_per_s: Option<f64>,
    ) -> Result<f64> {
        Ok(py.detach(|| {
            let mut kbjae = lock(&self.inner);
            match rate_deg_per_s {
                Some(rate) => kbjae.step_with_rate(theta_c_deg, rate, dt_s),
                None => kbjae.step(theta_c_deg, dt_s),
            }
        })?)
    }

    /// `step` for each command of `theta_c_deg` (a one-dimensional array,
    /// deg), each `dt_s` after the one before; returns KBJAE's angles
    /// (float64). On a refused command the error is raised and the
    /// estimator is as it was before the call.
    fn run<'py>(
        &self,
        py: Python<'py>,
        theta_c_deg: &Bound<'py, PyAny>,
        dt_s: f64,
    ) -> Result<Bound<'py, PyAny>> {
        let theta = array::series("theta_c_deg", theta_c_deg)?;
        let angles = py.detach(|| lock(&self.inner).run(&theta, dt_s))?;
        Ok(array::column(py, angles))
    }

    /// KBJAE's angle θ + θ̃(θ, θ') for one command and its rate, deg (no
    /// history kept). Raises `ValueError` for a non-finite input,
    /// `RangeError` for one beyond ±1e6 deg or ±1e9 deg/s.
    fn predict(&self, py: Python<'_>, theta_deg: f64, rate_deg_per_s: f64) -> Result<f64> {
        Ok(py.detach(|| lock(&self.inner).predict(theta_deg, rate_deg_per_s))?)
    }

    /// The predicted errors θ̃ (not the angles) for many commands at once,
    /// in one model call: `theta_deg` and `rate_deg_per_s` one-dimensional
    /// arrays of one length (deg, deg/s; rounded to float32, the model's
    /// type). Returns a float32 array. Raises `TypeError` for arrays of
    /// other shapes or lengths, `ValueError` for a non-finite input,
    /// `RangeError` for one beyond ±1e6 deg or ±1e9 deg/s.
    fn errors<'py>(
        &self,
        py: Python<'py>,
        theta_deg: &Bound<'py, PyAny>,
        rate_deg_per_s: &Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyAny>> {
        let (theta, rate) = (
            array::series("theta_deg", theta_deg)?,
            array::series("rate_deg_per_s", rate_deg_per_s)?,
        );
        // checked as given, before float32 rounds a large value to infinity
        for (&t, &r) in theta.iter().zip(&rate) {
            Kbjae::check_input(t, r)?;
        }
        let f32s = |v: Vec<f64>| v.into_iter().map(|x| x as f32).collect::<Vec<f32>>();
        let (theta, rate) = (f32s(theta), f32s(rate));
        let out = py.detach(|| lock(&self.inner).errors(&theta, &rate))?;
        Ok(out.into_pyarray(py).into_any())
    }

    /// Forgets the command history (the next `step`'s rate is 0).
    fn reset(&self, py: Python<'_>) {
        py.detach(|| lock(&self.inner).reset());
    }

    fn __repr__(&self) -> String {
        format!("Kbjae(sha256={:?})", self.sha256)
    }
}

/// One branch of IBJAE's Siamese CNN (kflex-estimate's `Scnn`): a 48×48
/// silhouette to a 256-dimensional embedding. Python threads may share
/// one: their calls take turns.
#[pyclass(name = "Scnn", module = "kflex", frozen)]
pub struct PyScnn {
    pub(crate) inner: Mutex<Scnn>,
    sha256: String,
}

#[pymethods]
impl PyScnn {
    /// Loads the SCNN's ONNX model (input `silhouette` [N, 1, 48, 48],
    /// output `embedding` [N, 256]) with `threads` intra-op threads.
    /// Raises as `Kbjae.load`.
    #[staticmethod]
    #[pyo3(signature = (path, threads = 1))]
    fn load(py: Python<'_>, path: PathBuf, threads: Int) -> Result<Self> {
        let threads: usize = unsigned("threads", threads)?;
        let scnn = py.detach(|| Scnn::load(&path, threads))?;
        Ok(Self {
            sha256: scnn.sha256().to_owned(),
            inner: Mutex::new(scnn),
        })
    }

    /// The model file's SHA-256 (a band database records it).
    #[getter]
    fn sha256(&self) -> &str {
        &self.sha256
    }

    /// Embeds silhouettes in one model call: an (N, 48, 48) array, or one
    /// (48, 48) silhouette, of bool, uint8 (nonzero: instrument) or float32
    /// (0.0 or 1.0). Returns float32 embeddings, (N, 256) or (256,). Raises
    /// `TypeError` for another shape or dtype, `ValueError` for a float32
    /// value other than 0 and 1, `RuntimeError` for a model that answers
    /// with a value that is not finite (damaged weights).
    fn embed<'py>(
        &self,
        py: Python<'py>,
        silhouettes: &Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyAny>> {
        let (masks, single) = array::silhouettes("silhouettes", silhouettes, SCNN_SIDE as usize)?;
        let n = masks.len();
        let values = if masks.is_empty() {
            Vec::new()
        } else {
            py.detach(|| lock(&self.inner).embed_batch(&masks))?
        };
        Ok(if single {
            values.into_pyarray(py).into_any()
        } else {
            Array2::from_shape_vec((n, EMBEDDING_DIM), values)
                .map_err(|e| {
                    crate::error::Error::Py(pyo3::exceptions::PyRuntimeError::new_err(format!(
                        "the SCNN's embeddings: {e}"
                    )))
                })?
                .into_pyarray(py)
                .into_any()
        })
    }

    fn __repr__(&self) -> String {
        format!("Scnn(sha256={:?})", self.sha256)
    }
}

/// Names the `onnxruntime` package directory of the interpreter running
/// `kflex` as the place to find ONNX Runtime after `ORT_DYLIB_PATH` (called
/// once by `kflex/__init__.py`). Returns whether this call set it.
#[pyfunction(name = "_prefer_onnxruntime_package")]
pub fn prefer_onnxruntime_package(dir: PathBuf) -> bool {
    kflex_estimate::onnx::prefer_onnxruntime_package(&dir)
}
