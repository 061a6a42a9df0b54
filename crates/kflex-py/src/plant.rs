//! The plant: its configuration, stepping, and whole runs as numpy arrays.

use kflex_control::{OpenLoopScenario, RunMetrics, Trace};
use kflex_model::{
    AuroraNoise, Command, JointModelKind, JointParams, Plant, PlantConfig, PlantState, Seating,
    SheathParams, Sine, Trajectory, TranslationParams,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde_json::Value;

use crate::array;
use crate::error::{Int, Result, unsigned};
use crate::value::{self, serde_class};

serde_class!(
    /// Tendon-sheath transmission parameters (kflex-model's `SheathParams`):
    /// forces N, lengths mm, angles deg.
    PySheathParams, "SheathParams", SheathParams, {
        /// Checks every parameter against its physical range; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

serde_class!(
    /// Joint mechanics (kflex-model's `JointParams`): N·mm/rad, mm, g, N, deg.
    PyJointParams, "JointParams", JointParams, {
        /// Checks every parameter against its physical range; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

serde_class!(
    /// How the tendons sit in their sheaths at rest and where in its play the
    /// drive was homed (kflex-model's `Seating`), each in [-1, 1].
    PySeating, "Seating", Seating, {
        /// Checks that every field lies in [-1, 1]; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

serde_class!(
    /// The translation stage (kflex-model's `TranslationParams`): mm, mm/s.
    PyTranslationParams, "TranslationParams", TranslationParams, {
        /// Checks the travel and speed; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

serde_class!(
    /// Gaussian tracker noise on the measured angle and translation
    /// (kflex-model's `AuroraNoise`): deg, mm.
    PyAuroraNoise, "AuroraNoise", AuroraNoise, {}
);

serde_class!(
    /// A command to the plant (kflex-model's `Command`): `theta_c_deg` (deg),
    /// `translation_mm` (mm).
    PyCommand, "Command", Command, {}
);

serde_class!(
    /// What the plant did in one tick (kflex-model's `PlantState`): angles deg,
    /// lengths mm, forces N, time s. `command` and `tensions` read as `dict`s.
    PyPlantState, "PlantState", PlantState, {}
);

serde_class!(
    /// One sinusoid `offset_deg + amplitude_deg · sin(2π frequency_hz t + phase_rad)`
    /// (kflex-model's `Sine`); all four fields are required.
    PySine, "Sine", Sine, {
        /// The paper's test input, 25 sin(t) + 25 deg at 0.159 Hz.
        #[staticmethod]
        fn paper() -> Self {
            Sine::PAPER.into()
        }

        /// Period, s.
        fn period_s(&self) -> f64 {
            self.inner.period_s()
        }
    }
);

serde_class!(
    /// A master trajectory θ_d(t) (kflex-model's `Trajectory`), tagged by
    /// `kind`: `"sine"` (the fields of `Sine`), `"periodic_set"` (`legs`:
    /// [(peak deg, Hz)], `cycles_per_leg`), `"band_limited"` (`min_deg`,
    /// `max_deg`, `cutoff_hz`, `components`, `seed`), `"steps"` (`min_deg`,
    /// `max_deg`, `hold_s`, `ramp_s`, `seed`).
    PyTrajectory, "Trajectory", Trajectory, {
        /// The paper's test input (a sine, 25 sin(t) + 25 deg at 0.159 Hz).
        #[staticmethod]
        fn paper() -> Self {
            Trajectory::paper().into()
        }

        /// θ_d (deg) and its rate (deg/s) at times `t_s` (s; a number or a
        /// float64/float32 array, whose shape the results keep). Raises
        /// `RangeError` for a field out of its range, `ValueError` for a
        /// time that is not finite.
        fn sample<'py>(&self, py: Python<'py>, t_s: &Bound<'py, PyAny>) -> Result<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
            let sampler = self.inner.sampler()?;
            let t = array::floats("t_s", t_s)?;
            t.try_map(|t| kflex_model::finite("t_s", t))?;
            let theta = t.map(|t| sampler.sample(t).theta_d_deg);
            let rate = t.map(|t| sampler.sample(t).theta_d_rate_deg_per_s);
            Ok((theta.into_py(py)?, rate.into_py(py)?))
        }

        /// Length of the trajectory's natural experiment, s (the periodic
        /// set's), or None for unbounded ones.
        fn natural_duration_s(&self) -> Result<Option<f64>> {
            Ok(self.inner.sampler()?.natural_duration_s())
        }
    }
);

serde_class!(
    /// One open-loop run's settings (kflex-control's `OpenLoopScenario`):
    /// `trajectory`, `periods`, `period_s` (s), `dt_s` (s), `pre_roll_s` (s),
    /// `translation_mm` (mm).
    PyOpenLoopScenario, "OpenLoopScenario", OpenLoopScenario, {
        /// Drives `plant` from its current state through the scenario (a
        /// pre-roll to θ_d(0), then `periods` periods, θ_c = θ_d) and
        /// returns the evaluated part. The loop runs in Rust without the
        /// interpreter lock. Raises `RangeError` for a setting out of range
        /// (before the plant moves) or a command outside the workspace (the
        /// plant keeps the ticks it took).
        fn run(&self, py: Python<'_>, mut plant: PyRefMut<'_, PyPlant>) -> Result<PyTrace> {
            let scenario = self.inner.clone();
            let plant = &mut plant.inner;
            let trace = py.detach(|| scenario.run(plant))?;
            Ok(PyTrace { inner: trace })
        }
    }
);

/// A recorded open-loop run (kflex-control's `Trace`): one row per evaluated
/// tick, each column a float64 array.
#[pyclass(name = "Trace", module = "kflex")]
pub struct PyTrace {
    inner: Trace,
}

#[pymethods]
impl PyTrace {
    /// Time since the start of evaluation, s.
    #[getter]
    fn time_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.time_s.clone())
    }

    /// θ_d, deg.
    #[getter]
    fn theta_d_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.theta_d_deg.clone())
    }

    /// dθ_d/dt, deg/s.
    #[getter]
    fn theta_d_rate_deg_per_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.theta_d_rate_deg_per_s.clone())
    }

    /// True θ_a, deg.
    #[getter]
    fn theta_a_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.theta_a_deg.clone())
    }

    /// θ_a as the tracker measures it, deg.
    #[getter]
    fn theta_a_measured_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.theta_a_measured_deg.clone())
    }

    /// The paper's metrics on the measured angle, deg: a `dict` with
    /// `rmse_deg`, `max_hysteresis_deg` (the loop width),
    /// `error_peak_to_peak_deg`, `peak_loss_deg`. Raises `ValueError` for a
    /// trace they cannot be computed on.
    fn metrics<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyAny>> {
        let m: RunMetrics = self.inner.metrics()?;
        Ok(value::to_py(py, &value::to_value(&m)?)?)
    }

    fn __len__(&self) -> usize {
        self.inner.time_s.len()
    }
}

/// Everything that defines a plant (kflex-model's `PlantConfig`). Angles deg,
/// lengths mm.
///
/// Its parameter groups (`geometry`, `sheath`, `seating`, `joint`,
/// `translation`, `noise`) are objects held by reference, as in a Python
/// dataclass: `config.sheath.friction_coefficient = 0.2` changes this
/// configuration.
#[pyclass(name = "PlantConfig", module = "kflex")]
pub struct PyPlantConfig {
    /// Joint and tendon geometry (Eq. 1).
    #[pyo3(get, set)]
    geometry: Py<PyTendonGeometryRef>,
    /// Tendon-sheath transmission.
    #[pyo3(get, set)]
    sheath: Py<PySheathParams>,
    /// Total bend of the sheath, deg (the paper: 0, 90, 180, 270).
    #[pyo3(get, set)]
    sheath_deg: f64,
    /// How the tendons sit at start and reset, and where the drive was homed.
    #[pyo3(get, set)]
    seating: Py<PySeating>,
    /// Joint mechanics.
    #[pyo3(get, set)]
    joint: Py<PyJointParams>,
    joint_model: JointModelKind,
    /// Translation stage.
    #[pyo3(get, set)]
    translation: Py<PyTranslationParams>,
    /// Measurement noise; None measures the true state.
    #[pyo3(get, set)]
    noise: Option<Py<PyAuroraNoise>>,
    /// Seed of the measurement noise.
    // set through `set_seed`, which names a negative or too-large one
    #[pyo3(get)]
    seed: u64,
}

/// `TendonGeometry` as `PlantConfig.geometry` holds it (the class of `kinematics`).
type PyTendonGeometryRef = crate::kinematics::PyTendonGeometry;

impl PyPlantConfig {
    /// Splits a Rust configuration into its Python parts.
    pub(crate) fn from_rust(py: Python<'_>, c: PlantConfig) -> PyResult<Self> {
        Ok(Self {
            geometry: Py::new(py, PyTendonGeometryRef::from(c.geometry))?,
            sheath: Py::new(py, PySheathParams::from(c.sheath))?,
            sheath_deg: c.sheath_deg,
            seating: Py::new(py, PySeating::from(c.seating))?,
            joint: Py::new(py, PyJointParams::from(c.joint))?,
            joint_model: c.joint_model,
            translation: Py::new(py, PyTranslationParams::from(c.translation))?,
            noise: c
                .noise
                .map(|n| Py::new(py, PyAuroraNoise::from(n)))
                .transpose()?,
            seed: c.seed,
        })
    }

    /// The Rust configuration these parts make now.
    pub(crate) fn to_rust(&self, py: Python<'_>) -> PlantConfig {
        PlantConfig {
            geometry: self.geometry.borrow(py).inner,
            sheath: self.sheath.borrow(py).inner,
            sheath_deg: self.sheath_deg,
            seating: self.seating.borrow(py).inner,
            joint: self.joint.borrow(py).inner,
            joint_model: self.joint_model,
            translation: self.translation.borrow(py).inner,
            noise: self.noise.as_ref().map(|n| n.borrow(py).inner),
            seed: self.seed,
        }
    }
}

#[pymethods]
impl PyPlantConfig {
    /// Built from keyword arguments, the fields of kflex-model's
    /// `PlantConfig` (parameter groups as parameter objects or `dict`s of
    /// their fields); fields left out take the defaults.
    #[new]
    #[pyo3(signature = (**fields))]
    fn py_new(py: Python<'_>, fields: Option<&Bound<'_, PyDict>>) -> Result<Self> {
        let c: PlantConfig = value::from_kwargs("PlantConfig", fields)?;
        Ok(Self::from_rust(py, c)?)
    }

    #[setter]
    fn set_seed(&mut self, seed: Int) -> Result<()> {
        self.seed = unsigned("seed", seed)?;
        Ok(())
    }

    /// Which joint model computes the angle: `"analytic"` (the module's
    /// build has only this one) or `"rapier"`.
    #[getter]
    fn joint_model(&self) -> Result<String> {
        match value::to_value(&self.joint_model)? {
            Value::String(s) => Ok(s),
            v => Ok(v.to_string()),
        }
    }

    #[setter]
    fn set_joint_model(&mut self, name: &Bound<'_, PyAny>) -> Result<()> {
        self.joint_model = value::from_value(
            "PlantConfig.joint_model",
            value::from_py("joint_model", name)?,
        )?;
        Ok(())
    }

    /// Checks every parameter; raises `RangeError` naming the first out of its range.
    fn validate(&self, py: Python<'_>) -> Result<()> {
        Ok(self.to_rust(py).validate()?)
    }

    /// A copy drawn around this one for a repeated experiment (the set-up's
    /// parameters scaled by `1 + rel_std · N(0, 1)`, the build's by
    /// `1 + rel_std/3 · N(0, 1)`, each clamped to [0.5, 1.5], and a drawn
    /// seating, which homes the drive within the middle 70 % of its play);
    /// deterministic in `seed`. Raises
    /// `RangeError` for `rel_std` outside [0, 0.5] or a parameter out of range.
    fn perturbed(&self, py: Python<'_>, seed: Int, rel_std: f64) -> Result<Self> {
        let c = self
            .to_rust(py)
            .perturbed(unsigned("seed", seed)?, rel_std)?;
        Ok(Self::from_rust(py, c)?)
    }

    /// The fields as a `dict` (groups as `dict`s): the JSON form `kflex-cli run --config` reads.
    fn to_dict<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyAny>> {
        Ok(value::to_py(py, &value::to_value(&self.to_rust(py))?)?)
    }

    /// Built from a `dict` of fields (as the constructor's keywords).
    #[staticmethod]
    fn from_dict(py: Python<'_>, fields: &Bound<'_, PyDict>) -> Result<Self> {
        Self::py_new(py, Some(fields))
    }

    /// A deep copy (its groups are new objects).
    fn copy(&self, py: Python<'_>) -> PyResult<Self> {
        Self::from_rust(py, self.to_rust(py))
    }

    fn __copy__(&self, py: Python<'_>) -> PyResult<Self> {
        self.copy(py)
    }

    fn __deepcopy__(&self, py: Python<'_>, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        self.copy(py)
    }

    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<Self>()
            .is_ok_and(|o| o.borrow().to_rust(py) == self.to_rust(py))
    }

    fn __repr__(&self, py: Python<'_>) -> String {
        value::repr("PlantConfig", &self.to_rust(py))
    }
}

/// The tendon-driven joint with its sheath, the testbed's ground truth
/// (kflex-model's `Plant`).
#[pyclass(name = "Plant", module = "kflex")]
pub struct PyPlant {
    pub(crate) inner: Plant,
}

#[pymethods]
impl PyPlant {
    /// A plant at rest, straight, at the shortest translation. Raises
    /// `RangeError` naming the first parameter of `config` out of range,
    /// `RuntimeError` for the rapier joint (not in this build).
    #[new]
    #[pyo3(signature = (config = None))]
    fn py_new(py: Python<'_>, config: Option<PyRef<'_, PyPlantConfig>>) -> Result<Self> {
        let config = config.map_or_else(PlantConfig::default, |c| c.to_rust(py));
        Ok(Self {
            inner: Plant::new(config)?,
        })
    }

    /// Advances by `dt_s` (s) under the command (`theta_c_deg` deg,
    /// `translation_mm` mm) and returns the new state. A refused input
    /// (`RangeError` for `dt_s` outside (0, 1000) or a command outside the
    /// workspace, `ValueError` for a non-finite one) leaves the plant as it was.
    fn step(&mut self, theta_c_deg: f64, translation_mm: f64, dt_s: f64) -> Result<PyPlantState> {
        let command = Command {
            theta_c_deg,
            translation_mm,
        };
        Ok(self.inner.step(command, dt_s)?.into())
    }

    /// Runs one tick per command, in Rust without the interpreter lock:
    /// `theta_c_deg` a one-dimensional float64/float32 array (deg),
    /// `translation_mm` a number or an array of the same length (mm), `dt_s`
    /// the tick (s). Returns a `dict` of float64 arrays, one row per tick:
    /// each numeric field of `PlantState` under its name, nested ones as
    /// `"command.theta_c_deg"`, `"tensions.a_distal_n"`, …. On a refused
    /// command the error is raised and the plant keeps the ticks before it.
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        theta_c_deg: &Bound<'py, PyAny>,
        translation_mm: &Bound<'py, PyAny>,
        dt_s: f64,
    ) -> Result<Bound<'py, PyDict>> {
        let theta = array::series("theta_c_deg", theta_c_deg)?;
        let translation = array::broadcast("translation_mm", translation_mm, theta.len())?;
        let plant = &mut self.inner;
        let states = py.detach(|| {
            theta
                .iter()
                .zip(&translation)
                .map(|(&theta_c_deg, &translation_mm)| {
                    plant.step(
                        Command {
                            theta_c_deg,
                            translation_mm,
                        },
                        dt_s,
                    )
                })
                .collect::<std::result::Result<Vec<PlantState>, _>>()
        })?;
        columns(py, &states)
    }

    /// Back to rest: straight joint, tendons unloaded, noise re-seeded.
    fn reset(&mut self) -> Result<()> {
        Ok(self.inner.reset()?)
    }

    /// The last state.
    #[getter]
    fn state(&self) -> PyPlantState {
        (*self.inner.state()).into()
    }

    /// A copy of the configuration (changing it does not change the plant).
    #[getter]
    fn config(&self, py: Python<'_>) -> PyResult<PyPlantConfig> {
        PyPlantConfig::from_rust(py, *self.inner.config())
    }

    /// Changes the sheath's bend (deg) between ticks; `RangeError` outside [0, 3600].
    fn set_sheath_deg(&mut self, sheath_deg: f64) -> Result<()> {
        Ok(self.inner.set_sheath_deg(sheath_deg)?)
    }

    /// Checks a command (deg, mm) against the workspace without moving.
    fn check_command(&self, theta_c_deg: f64, translation_mm: f64) -> Result<()> {
        Ok(self.inner.check_command(&Command {
            theta_c_deg,
            translation_mm,
        })?)
    }

    fn __repr__(&self) -> String {
        format!("Plant(time_s={})", self.inner.state().time_s)
    }
}

/// The states as columns: each numeric leaf of the serde form under its
/// dotted path (converted without the interpreter lock).
fn columns<'py>(py: Python<'py>, states: &[PlantState]) -> Result<Bound<'py, PyDict>> {
    let (names, cols) = py.detach(|| state_columns(states))?;
    let out = PyDict::new(py);
    for (name, col) in names.into_iter().zip(cols) {
        out.set_item(name, array::column(py, col))?;
    }
    Ok(out)
}

/// [`columns`]' names and values.
fn state_columns(states: &[PlantState]) -> Result<(Vec<String>, Vec<Vec<f64>>)> {
    let mut names: Vec<String> = Vec::new();
    let mut cols: Vec<Vec<f64>> = Vec::new();
    let mut row = Vec::new();
    for (i, s) in states.iter().enumerate() {
        row.clear();
        flatten("", &value::to_value(s)?, &mut row);
        if i == 0 {
            names = row.iter().map(|(k, _)| k.clone()).collect();
            cols = vec![Vec::with_capacity(states.len()); names.len()];
        }
        for (col, (_, v)) in cols.iter_mut().zip(&row) {
            col.push(*v);
        }
    }
    if states.is_empty() {
        flatten("", &value::to_value(&PlantState::default())?, &mut row);
        names = row.iter().map(|(k, _)| k.clone()).collect();
        cols = vec![Vec::new(); names.len()];
    }
    Ok((names, cols))
}

fn flatten(prefix: &str, v: &Value, out: &mut Vec<(String, f64)>) {
    match v {
        Value::Object(map) => {
            for (k, item) in map {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten(&path, item, out);
            }
        }
        Value::Number(n) => out.push((prefix.to_owned(), n.as_f64().unwrap_or(f64::NAN))),
        _ => {}
    }
}
