//! The paper's experiments from Python (kflex-control's `ExperimentGrid`):
//! a grid from a scenario file or built in Python, run in Rust on several
//! threads without the interpreter lock, its records and every run's time
//! series returned as numpy arrays.

use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use kflex_control::{
    CaseKind, ControlError, EstimatorKind, ExperimentGrid, GridRun, ModelDir, Record, ResultRow,
    TickDetails,
};
use kflex_model::Camera;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::array;
use crate::error::{Error, Int, Result, unsigned};
use crate::value::serde_class;

serde_class!(
    /// A grid of the paper's experiments (kflex-control's `ExperimentGrid`):
    /// `cases` (each a `dict` of `table`, `kind` "estimation" or
    /// "compensation", `sheath_deg`, `occlusion` "0%", "20%", "40%" or
    /// "40% distal"), `estimators` ("none", "kbjae", "ibjae", "lbhjae",
    /// "lbhjae-adaptive"), `repeats`, `seed`, `spread`, `backgrounds`,
    /// `noise`, `plant` and `scenario` (a `ClosedLoopScenario`'s fields).
    /// Fields left out keep the paper's grid (`ExperimentGrid.paper()`).
    PyExperimentGrid, "ExperimentGrid", ExperimentGrid, {
        /// The paper's experiments: Tables V–VII (estimation) and VIII–X
        /// (compensation), every estimator, three repeats.
        #[staticmethod]
        fn paper() -> Self {
            ExperimentGrid::paper().into()
        }

        /// A scenario file (TOML, as those in `assets/scenarios/`). Raises
        /// `OSError` when it cannot be read, `ValueError` naming the file,
        /// the line and the field for one that is not a grid. Its values
        /// are checked when it runs (`run_experiment`), so that a grid can
        /// be loaded and then completed in Python.
        #[staticmethod]
        fn load(path: PathBuf) -> Result<Self> {
            Ok(read_scenario(&path)?.0.into())
        }

        /// A reduced grid for a fast look: each table's first and last
        /// case, one repeat, at most one period of the input.
        fn quick(&self) -> Self {
            self.inner.quick().into()
        }
    }
);

/// A scenario file's grid and text: `OSError` when it cannot be read,
/// `ValueError` naming the file, the line and the field for one that is not
/// a grid.
fn read_scenario(path: &std::path::Path) -> Result<(ExperimentGrid, String)> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Error::Py(pyo3::exceptions::PyOSError::new_err(format!(
            "{}: {e}",
            path.display()
        )))
    })?;
    let grid: ExperimentGrid = toml::from_str(&text).map_err(|e| {
        Error::Py(pyo3::exceptions::PyValueError::new_err(format!(
            "{}: {e}",
            path.display()
        )))
    })?;
    Ok((grid, text))
}

/// One run's time series, kept for Python.
struct RunSeries {
    table: String,
    kind: CaseKind,
    sheath_deg: f64,
    occlusion: &'static str,
    seed: u64,
    background: String,
    estimators: Vec<EstimatorKind>,
    time_s: Vec<f64>,
    theta_d_deg: Vec<f64>,
    theta_c_deg: Vec<f64>,
    theta_a_deg: Vec<f64>,
    theta_a_measured_deg: Vec<f64>,
    estimates: Vec<Vec<f64>>,
    details: Vec<Vec<TickDetails>>,
}

impl RunSeries {
    /// The run's series; what went into each estimate only with `details`.
    fn of(run: &GridRun<'_>, details: bool) -> Self {
        let t = &run.trace.trace;
        Self {
            table: run.case.table.clone(),
            kind: run.case.kind,
            sheath_deg: run.case.sheath_deg,
            occlusion: run.case.occlusion.name(),
            seed: run.seed,
            background: run.background.name().to_owned(),
            estimators: run.estimators.to_vec(),
            time_s: t.time_s.clone(),
            theta_d_deg: t.theta_d_deg.clone(),
            theta_c_deg: run.trace.theta_c_deg.clone(),
            theta_a_deg: t.theta_a_deg.clone(),
            theta_a_measured_deg: t.theta_a_measured_deg.clone(),
            estimates: run
                .estimates
                .iter()
                .map(|e| e.iter().map(|h| h.unwrap_or(f64::NAN)).collect())
                .collect(),
            details: if details {
                run.details.iter().map(|d| d.to_vec()).collect()
            } else {
                Vec::new()
            },
        }
    }
}

/// A record as `results.json` has it (kflex-control's `ResultRow`: the
/// paper's figures beside ours).
fn record_dict<'py>(
    py: Python<'py>,
    r: &Record,
    grid: &ExperimentGrid,
) -> Result<Bound<'py, PyAny>> {
    let row = ResultRow::of(r, grid)?;
    crate::value::to_py(py, &crate::value::to_value(&row)?).map_err(Error::Py)
}

fn run_dict(py: Python<'_>, run: RunSeries) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("kind", run.kind.name())?;
    d.set_item("table", run.table)?;
    d.set_item("sheath_deg", run.sheath_deg)?;
    d.set_item("occlusion", run.occlusion)?;
    d.set_item("seed", run.seed)?;
    d.set_item("background", run.background)?;
    d.set_item(
        "estimators",
        run.estimators.iter().map(|e| e.name()).collect::<Vec<_>>(),
    )?;
    d.set_item("time_s", array::column(py, run.time_s))?;
    d.set_item("theta_d_deg", array::column(py, run.theta_d_deg))?;
    d.set_item("theta_c_deg", array::column(py, run.theta_c_deg))?;
    d.set_item("theta_a_deg", array::column(py, run.theta_a_deg))?;
    d.set_item(
        "theta_a_measured_deg",
        array::column(py, run.theta_a_measured_deg),
    )?;
    let estimates = PyDict::new(py);
    let details = PyDict::new(py);
    for (i, (e, series)) in run.estimators.iter().zip(run.estimates).enumerate() {
        if *e != EstimatorKind::None {
            estimates.set_item(e.name(), array::column(py, series))?;
            if let Some(ticks) = run.details.get(i) {
                details.set_item(e.name(), crate::closed_loop::details_dict(py, ticks)?)?;
            }
        }
    }
    d.set_item("estimates", estimates)?;
    if !run.details.is_empty() {
        d.set_item("details", details)?;
    }
    Ok(d)
}

/// Runs a grid of the paper's experiments (an `ExperimentGrid`, or the path
/// of a scenario file) in Rust, on `jobs` threads (default one per core; the
/// results are the same for any count), without the interpreter lock. The
/// estimators load their trained models from `models` (a directory with
/// `kbjae.onnx`, `scnn.onnx` and `db/`; default `assets/models`); "none"
/// needs none.
///
/// Returns a `dict`: `records`, one `dict` per case and estimator over the
/// repeats (as `kflex-cli run --scenario`'s `results.json`: `kind`,
/// `table`, `estimator`, `sheath_deg`, `occlusion`, `rmse_deg`,
/// `rmse_std_deg`, the three readings of the maximum hysteresis for
/// compensation records, else None, the paper's `paper_rmse_deg`,
/// `paper_rmse_std_deg`, `paper_max_hysteresis_deg` and
/// `paper_max_hysteresis_std_deg` where it has them, else None, `repeats`,
/// `seeds`, `backgrounds`, `periods`, `dt_s`); and with
/// `time_series`, `runs`, one `dict` per run (`kind`, `table`,
/// `sheath_deg`, `occlusion`, `seed`, `background`, `estimators`, and
/// float64 arrays `time_s`, `theta_d_deg`, `theta_c_deg`, `theta_a_deg`,
/// `theta_a_measured_deg`, `estimates`: estimator name to its estimate,
/// NaN before it had one, and with `details` (default), `details`:
/// estimator name to what went into its estimate each tick, as arrays
/// named as the MCAP joint states name them (kflex-control's
/// `TickDetails`, as `ClosedLoopTrace.details`: about 150 bytes a tick and
/// estimator, some 200 MB over the paper's grid; `details=False` leaves
/// them out), in the order the runs ended. With
/// `mcap_dir`, every run's MCAP log goes there as `kflex-cli run --mcap`
/// writes them (one per estimator of the run,
/// `IX_90deg_0pct_none_seed2020.mcap`), and with `mcap_frames` the logs hold
/// the camera's frames too.
///
/// Raises `ValueError` naming the file, line and field for a bad scenario
/// file, `RangeError` for a setting out of range, `RuntimeError` naming the
/// missing files when an estimator's models are not there (before any
/// run), and the runs' own errors. Ctrl-C stops it: the runs in progress
/// finish, no further run starts, and `KeyboardInterrupt` is raised.
#[pyfunction]
#[pyo3(signature = (grid, models = None, jobs = None, time_series = true, mcap_dir = None, mcap_frames = false, details = true))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments
pub fn run_experiment<'py>(
    py: Python<'py>,
    grid: &Bound<'py, PyAny>,
    models: Option<PathBuf>,
    jobs: Option<Int>,
    time_series: bool,
    mcap_dir: Option<PathBuf>,
    mcap_frames: bool,
    details: bool,
) -> Result<Bound<'py, PyDict>> {
    let jobs: Option<usize> = jobs.map(|j| unsigned("jobs", j)).transpose()?;
    let mut grid: ExperimentGrid = if let Ok(g) = grid.extract::<PyExperimentGrid>() {
        g.inner
    } else if let Ok(path) = grid.extract::<PathBuf>() {
        let (grid, text) = read_scenario(&path)?;
        // every setting checked before any work; a value out of range is
        // named with the file's line that sets it
        if let Err(e) = grid.validate() {
            let at = match e.line_in(&text) {
                Some(line) => format!("{}, line {line}", path.display()),
                None => path.display().to_string(),
            };
            return Err(Error::Py(crate::error::located(e.into(), &at)));
        }
        grid
    } else {
        return Err(Error::Py(pyo3::exceptions::PyTypeError::new_err(format!(
            "grid must be an ExperimentGrid or the path of a scenario file, not {}",
            grid.get_type().name().map_err(Error::Py)?
        ))));
    };
    // the logs' directory is made before any run, so that one that cannot
    // be is an error before the work
    if let Some(dir) = &mcap_dir {
        std::fs::create_dir_all(dir).map_err(|e| {
            Error::Py(pyo3::exceptions::PyOSError::new_err(format!(
                "the MCAP directory {} cannot be made: {e}",
                dir.display()
            )))
        })?;
    }
    grid.scenario.record_frames =
        mcap_dir.is_some() && (mcap_frames || grid.scenario.record_frames);
    let models = ModelDir::new(&models.unwrap_or_else(|| PathBuf::from(kflex_control::MODELS_DIR)));
    let jobs = jobs
        .unwrap_or_else(|| {
            std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
        })
        .max(1);
    let camera = Camera::default();
    let runs: Mutex<Vec<RunSeries>> = Mutex::new(Vec::new());
    // Ctrl-C: Python sees its signals on the main thread only, so the grid
    // runs on another while this one looks for them; the runs in progress
    // finish, no further run starts, and the KeyboardInterrupt is raised
    let stop = AtomicBool::new(false);
    let mut signal: Option<PyErr> = None;
    let records = py.detach(|| {
        let make = |kind| models.make(kind, &camera);
        models.check(&grid.estimators, &camera)?;
        let on_run = |run: &GridRun<'_>| {
            if time_series && let Ok(mut r) = runs.lock() {
                r.push(RunSeries::of(run, details));
            }
            if let Some(dir) = &mcap_dir {
                run.write_logs(dir)?;
            }
            Ok(())
        };
        std::thread::scope(|scope| {
            let grid_run = scope.spawn(|| grid.run_until(jobs, &make, &|_, _| {}, &on_run, &stop));
            while !grid_run.is_finished() {
                if signal.is_none()
                    && let Err(e) = Python::attach(|py| py.check_signals())
                {
                    signal = Some(e);
                    stop.store(true, Ordering::Relaxed);
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
            grid_run.join().unwrap_or_else(|_| {
                Err(ControlError::Worker {
                    message: "the experiment's thread panicked".into(),
                })
            })
        })
    });
    if let Some(e) = signal {
        return Err(Error::Py(e));
    }
    let records = records?;
    let out = PyDict::new(py);
    let list = PyList::empty(py);
    for r in &records {
        list.append(record_dict(py, r, &grid)?).map_err(Error::Py)?;
    }
    out.set_item("records", list).map_err(Error::Py)?;
    if time_series {
        let list = PyList::empty(py);
        let runs = runs
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        for run in runs {
            list.append(run_dict(py, run).map_err(Error::Py)?)
                .map_err(Error::Py)?;
        }
        out.set_item("runs", list).map_err(Error::Py)?;
    }
    Ok(out)
}
