//! The hysteresis compensator (kflex-control's `Compensator`, Eq. 3–5), one
//! tick at a time or a whole series of ticks in one call.

use kflex_control::{Compensator, CompensatorConfig, CompensatorOutput, Fault, Terms};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::array;
use crate::error::{Result, type_error};
use crate::value::serde_class;

serde_class!(
    /// Gains and limits of the compensator (kflex-control's
    /// `CompensatorConfig`): `kp`, `ki_per_s`, `kd_s`, `derivative_filter_s`,
    /// `backlash_term` ("off", "pid_correction", "total_correction"),
    /// `direction_deadband_deg`, `theta_c_min_deg`, `theta_c_max_deg`,
    /// `integral_limit_deg` (None: no clamp),
    /// `freeze_integral_when_saturated`, `rate_limit_deg_per_s`,
    /// `watchdog_timeout_s`. An unknown field is refused (`TypeError`).
    PyCompensatorConfig, "CompensatorConfig", CompensatorConfig, {
        /// Checks every field against its range; raises `RangeError` naming
        /// the first one out of it.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

/// The terms of Eq. 3–5 on one tick, deg: `p_deg`, `i_deg`, `d_deg` (Eq. 4's
/// `f` is their sum, `f_deg()`) and `g_deg`, Eq. 5's backlash term.
#[pyclass(name = "Terms", module = "kflex", frozen)]
pub struct PyTerms {
    inner: Terms,
}

#[pymethods]
impl PyTerms {
    /// `K_p e`, deg.
    #[getter]
    fn p_deg(&self) -> f64 {
        self.inner.p_deg
    }

    /// `K_i ∫ e dt` since the last reversal (after its clamp), deg.
    #[getter]
    fn i_deg(&self) -> f64 {
        self.inner.i_deg
    }

    /// `K_d e'` (filtered), deg.
    #[getter]
    fn d_deg(&self) -> f64 {
        self.inner.d_deg
    }

    /// Eq. 5's backlash term `G`, deg.
    #[getter]
    fn g_deg(&self) -> f64 {
        self.inner.g_deg
    }

    /// Eq. 4's `f = p + i + d`, deg.
    fn f_deg(&self) -> f64 {
        self.inner.f_deg()
    }

    fn __repr__(&self) -> String {
        let t = &self.inner;
        format!(
            "Terms(p_deg={}, i_deg={}, d_deg={}, g_deg={})",
            t.p_deg, t.i_deg, t.d_deg, t.g_deg
        )
    }
}

/// Why a tick held the last command: `kind` ("non_finite_desired",
/// "invalid_dt", "non_finite_estimate", "watchdog"), `message` (the Rust
/// fault's text) and `details`, the fault's numbers by name (`value`;
/// for "invalid_dt" also `min` and `max`; for "watchdog" `age_s` and
/// `timeout_s`).
#[pyclass(name = "Fault", module = "kflex", frozen, get_all)]
pub struct PyFault {
    /// Which fault.
    kind: &'static str,
    /// The fault's description.
    message: String,
    /// Its numbers, by name.
    details: Py<PyDict>,
}

#[pymethods]
impl PyFault {
    fn __repr__(&self) -> String {
        format!("Fault(kind={:?}, message={:?})", self.kind, self.message)
    }
}

/// A fault's kind, as Python names it.
fn fault_kind(f: &Fault) -> &'static str {
    match f {
        Fault::NonFiniteDesired { .. } => "non_finite_desired",
        Fault::InvalidDt(_) => "invalid_dt",
        Fault::NonFiniteEstimate { .. } => "non_finite_estimate",
        Fault::Watchdog { .. } => "watchdog",
        _ => "other",
    }
}

fn fault(py: Python<'_>, f: &Fault) -> PyResult<PyFault> {
    let details = PyDict::new(py);
    match f {
        Fault::NonFiniteDesired { value } | Fault::NonFiniteEstimate { value } => {
            details.set_item("value", value)?;
        }
        Fault::InvalidDt(r) => {
            details.set_item("value", r.value)?;
            details.set_item("min", r.bounds.min)?;
            details.set_item("max", r.bounds.max)?;
        }
        Fault::Watchdog { age_s, timeout_s } => {
            details.set_item("age_s", age_s)?;
            details.set_item("timeout_s", timeout_s)?;
        }
        _ => {}
    }
    Ok(PyFault {
        kind: fault_kind(f),
        message: f.to_string(),
        details: details.unbind(),
    })
}

/// One tick's result: `theta_c_deg` (the command to send: finite, within
/// the joint limits), `fault` (a `Fault`, or None), `terms`, `limited`
/// (whether the joint or rate limit changed the target), `estimate_age_s`
/// and `reversed` (whether θ_d changed direction this tick).
#[pyclass(name = "CompensatorOutput", module = "kflex", frozen, get_all)]
pub struct PyCompensatorOutput {
    /// θ_c, deg.
    theta_c_deg: f64,
    /// Why the tick held the last command, if it did.
    fault: Option<Py<PyFault>>,
    /// The terms of Eq. 3–5.
    terms: Py<PyTerms>,
    /// Whether a limit changed the target `θ_d + f + G`.
    limited: bool,
    /// Time since the last finite estimate, s.
    estimate_age_s: f64,
    /// Whether θ_d reversed this tick.
    reversed: bool,
}

#[pymethods]
impl PyCompensatorOutput {
    fn __repr__(&self, py: Python<'_>) -> String {
        let fault = self.fault.as_ref().map(|f| f.get().kind);
        let py_bool = |b: bool| if b { "True" } else { "False" };
        format!(
            "CompensatorOutput(theta_c_deg={}, fault={}, terms={}, limited={}, estimate_age_s={}, reversed={})",
            self.theta_c_deg,
            fault.map_or_else(|| "None".to_string(), |k| format!("{k:?}")),
            self.terms.borrow(py).__repr__(),
            py_bool(self.limited),
            self.estimate_age_s,
            py_bool(self.reversed)
        )
    }
}

fn output(py: Python<'_>, o: &CompensatorOutput) -> PyResult<PyCompensatorOutput> {
    Ok(PyCompensatorOutput {
        theta_c_deg: o.theta_c_deg,
        fault: o
            .fault
            .as_ref()
            .map(|f| Py::new(py, fault(py, f)?))
            .transpose()?,
        terms: Py::new(py, PyTerms { inner: o.terms })?,
        limited: o.limited,
        estimate_age_s: o.estimate_age_s,
        reversed: o.reversed,
    })
}

/// The estimates of a run: `theta_hat_deg` (None: no estimate on any tick)
/// with `has_estimate` (None: an estimate on every tick) saying which ticks
/// have one. NaN stays NaN: the compensator reports it as a fault.
fn estimates(
    py: Python<'_>,
    theta_hat_deg: Option<&Bound<'_, PyAny>>,
    has_estimate: Option<&Bound<'_, PyAny>>,
    n: usize,
) -> Result<Vec<Option<f64>>> {
    let Some(obj) = theta_hat_deg.filter(|o| !o.is_none()) else {
        if has_estimate.is_some_and(|o| !o.is_none()) {
            return Err(type_error("has_estimate given without theta_hat_deg"));
        }
        return Ok(vec![None; n]);
    };
    let masked = py.import("numpy.ma")?.getattr("MaskedArray")?;
    if obj.is_instance(&masked)? {
        return Err(type_error(
            "theta_hat_deg: a masked array; pass its data and has_estimate=~mask instead",
        ));
    }
    let values = array::series("theta_hat_deg", obj)?;
    if values.len() != n {
        return Err(type_error(format!(
            "theta_hat_deg: expected shape ({n},) (one per tick of theta_d_deg), got ({},)",
            values.len()
        )));
    }
    let Some(mask) = has_estimate.filter(|o| !o.is_none()) else {
        return Ok(values.into_iter().map(Some).collect());
    };
    let mask = array::flags("has_estimate", mask)?;
    if mask.len() != n {
        return Err(type_error(format!(
            "has_estimate: expected shape ({n},) (one per tick of theta_d_deg), got ({},)",
            mask.len()
        )));
    }
    Ok(values
        .into_iter()
        .zip(mask)
        .map(|(v, m)| m.then_some(v))
        .collect())
}

/// The hysteresis compensator of Eq. 3–5 (kflex-control's `Compensator`):
/// a PID on the estimated joint angle plus a backlash term, with joint and
/// rate limits, anti-windup, faults and a watchdog. A bad input never
/// raises: the tick holds the last command and reports a `Fault`.
#[pyclass(name = "Compensator", module = "kflex")]
pub struct PyCompensator {
    inner: Compensator,
}

#[pymethods]
impl PyCompensator {
    /// A compensator at rest (last command 0 deg clamped into the limits, no
    /// correction, the watchdog counting from now). Raises `RangeError`
    /// naming the first field of `config` out of range.
    #[new]
    #[pyo3(signature = (config = None))]
    fn py_new(config: Option<PyCompensatorConfig>) -> Result<Self> {
        let config = config.map_or_else(CompensatorConfig::default, |c| c.inner);
        Ok(Self {
            inner: Compensator::new(config)?,
        })
    }

    /// A copy of the configuration.
    #[getter]
    fn config(&self) -> PyCompensatorConfig {
        (*self.inner.config()).into()
    }

    /// The last command returned (the one a fault holds), deg.
    #[getter]
    fn theta_c_deg(&self) -> f64 {
        self.inner.theta_c_deg()
    }

    /// One control tick: θ_d and the estimate θ̂ (None when none arrived this
    /// tick), deg, and the tick's length `dt_s`, s. A NaN or infinite θ_d or
    /// θ̂, or a `dt_s` outside (0, 1], holds the last command and is reported
    /// in the output's `fault`, as is a watchdog trip.
    fn step(
        &mut self,
        py: Python<'_>,
        theta_d_deg: f64,
        theta_hat_deg: Option<f64>,
        dt_s: f64,
    ) -> PyResult<PyCompensatorOutput> {
        output(py, &self.inner.step(theta_d_deg, theta_hat_deg, dt_s))
    }

    /// One tick per element of `theta_d_deg` (a one-dimensional float
    /// array, deg), each `dt_s` long, in Rust without the interpreter lock.
    /// `theta_hat_deg`: the estimates (an array of the same length, deg;
    /// None: no estimate on any tick); `has_estimate`: a bool array, False
    /// on the ticks without an estimate (None: every tick has one). NaN is
    /// not "missing": it is passed on and reported as a fault, as `step`
    /// does (masked arrays are refused for that reason). Returns a `dict`
    /// of arrays, one row per tick: `theta_c_deg`, `p_deg`, `i_deg`,
    /// `d_deg`, `g_deg`, `estimate_age_s` (float64), `limited`, `reversed`
    /// (bool) and `fault` (str: the fault's kind, "" where none).
    #[pyo3(signature = (theta_d_deg, theta_hat_deg, dt_s, has_estimate = None))]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        theta_d_deg: &Bound<'py, PyAny>,
        theta_hat_deg: Option<&Bound<'py, PyAny>>,
        dt_s: f64,
        has_estimate: Option<&Bound<'py, PyAny>>,
    ) -> Result<Bound<'py, PyDict>> {
        let theta_d = array::series("theta_d_deg", theta_d_deg)?;
        let theta_hat = estimates(py, theta_hat_deg, has_estimate, theta_d.len())?;
        let comp = &mut self.inner;
        let out: Vec<CompensatorOutput> = py.detach(|| {
            theta_d
                .iter()
                .zip(&theta_hat)
                .map(|(&d, &h)| comp.step(d, h, dt_s))
                .collect()
        });
        let d = PyDict::new(py);
        let col = |f: fn(&CompensatorOutput) -> f64| {
            array::column(py, out.iter().map(f).collect::<Vec<f64>>())
        };
        d.set_item("theta_c_deg", col(|o| o.theta_c_deg))?;
        d.set_item("p_deg", col(|o| o.terms.p_deg))?;
        d.set_item("i_deg", col(|o| o.terms.i_deg))?;
        d.set_item("d_deg", col(|o| o.terms.d_deg))?;
        d.set_item("g_deg", col(|o| o.terms.g_deg))?;
        d.set_item("estimate_age_s", col(|o| o.estimate_age_s))?;
        let flags = |f: fn(&CompensatorOutput) -> bool| {
            out.iter().map(f).collect::<Vec<bool>>().into_pyarray(py)
        };
        d.set_item("limited", flags(|o| o.limited))?;
        d.set_item("reversed", flags(|o| o.reversed))?;
        let kinds: Vec<&str> = out
            .iter()
            .map(|o| o.fault.as_ref().map_or("", fault_kind))
            .collect();
        let kw = PyDict::new(py);
        kw.set_item("dtype", "str")?;
        let kinds = py
            .import("numpy")?
            .call_method("array", (kinds,), Some(&kw))?;
        d.set_item("fault", kinds)?;
        Ok(d)
    }

    /// Back to the state a new compensator has.
    fn reset(&mut self) {
        self.inner.reset();
    }

    fn __repr__(&self) -> String {
        format!("Compensator(theta_c_deg={})", self.inner.theta_c_deg())
    }
}
