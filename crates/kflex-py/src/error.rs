//! The one place where kflex errors become Python exceptions.
//!
//! | Rust error | Python exception |
//! |---|---|
//! | a [`RangeError`] (`OutOfRange`, `OutOfWorkspace`, in any crate) | [`RangeError`](PyRangeError), a `ValueError` carrying `name`, `value`, `min`, `max`, `min_inclusive`, `max_inclusive` |
//! | a negative or too-large int for a count, size or seed (an argument Rust takes as unsigned; [`unsigned`]) | `ValueError` naming the argument, its value and the range |
//! | other bad values (non-finite input, unreachable tendon length, unknown background or tissue, a metric's bad series, a field value serde refuses) | `ValueError` |
//! | a buffer of the wrong size, a field of the wrong type, an unknown field | `TypeError` |
//! | no instrument in a frame | [`NoInstrumentError`](PyNoInstrumentError), a `RuntimeError` (`Segmenter.segment` returns `None` instead) |
//! | a file that cannot be read or written: a feature-index file (`FileNotFoundError`, `PermissionError` or `OSError`, by the system's error), a model or model card (`OSError`: the Rust error does not keep the system's kind) | `OSError` and its subclasses |
//! | a model whose card records another SHA-256, a model or database that is not what the estimator expects, a damaged or other-version index file, NaN in features, an empty index | `ValueError` |
//! | a buffer of the wrong length for an estimator (`Length`) | `TypeError` |
//! | ONNX Runtime missing (the message says what to install or set) or failing | `RuntimeError` |
//! | a diverged joint, nothing in view, a feature this build lacks, a data-set worker that stopped, anything new | `RuntimeError` |
//!
//! [`classify`] decides the exception from the error alone (no interpreter
//! needed, so it is unit-tested in plain Rust); `From<Error> for PyErr`
//! builds it.

use kflex_control::ControlError;
use kflex_estimate::EstimateError;
use kflex_model::{ModelError, RangeError};
use pyo3::exceptions::{
    PyAttributeError, PyFileNotFoundError, PyOSError, PyPermissionError, PyRuntimeError,
    PyTypeError, PyValueError,
};
use pyo3::prelude::*;
use std::io::ErrorKind;

/// The exceptions kflex defines, under the names Python shows
/// (`kflex.RangeError`, not the Rust-side `PyRangeError`).
mod exceptions {
    use pyo3::exceptions::{PyRuntimeError, PyValueError};

    pyo3::create_exception!(
        kflex,
        RangeError,
        PyValueError,
        "A value outside its valid range. Attributes: `name` (the quantity, unit in the name), `value`, `min`, `max`, `min_inclusive`, `max_inclusive` (the bounds; the ends may be infinite)."
    );

    pyo3::create_exception!(
        kflex,
        NoInstrumentError,
        PyRuntimeError,
        "The segmentation found no instrument in the region of interest (`Segmenter.segment` returns None instead of raising it)."
    );
}

pub use exceptions::{NoInstrumentError as PyNoInstrumentError, RangeError as PyRangeError};

/// Every error a wrapper can return; `?` converts the crates' errors into it.
#[derive(Debug)]
pub(crate) enum Error {
    /// From kflex-model.
    Model(ModelError),
    /// From kflex-estimate.
    Estimate(EstimateError),
    /// From kflex-control.
    Control(ControlError),
    /// Raised by the glue itself (argument checks), already a Python exception.
    Py(PyErr),
    /// A field value that serde refused; the string is serde's message.
    Serde(String),
    /// A field name the type does not have.
    NoField(String),
}

/// Result of a wrapper.
pub(crate) type Result<T> = std::result::Result<T, Error>;

impl From<ModelError> for Error {
    fn from(e: ModelError) -> Self {
        Self::Model(e)
    }
}

impl From<EstimateError> for Error {
    fn from(e: EstimateError) -> Self {
        Self::Estimate(e)
    }
}

impl From<ControlError> for Error {
    fn from(e: ControlError) -> Self {
        Self::Control(e)
    }
}

impl From<RangeError> for Error {
    fn from(e: RangeError) -> Self {
        Self::Model(ModelError::OutOfRange(e))
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Self::Py(e)
    }
}

/// The Python exception an error becomes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Kind {
    /// `kflex.RangeError` (a `ValueError`) with the bounds as attributes.
    Range(RangeError),
    /// `ValueError`.
    Value,
    /// `TypeError`.
    Type,
    /// `AttributeError`.
    Attribute,
    /// `kflex.NoInstrumentError` (a `RuntimeError`).
    NoInstrument,
    /// `OSError`, or its subclass for the kind (`FileNotFoundError`,
    /// `PermissionError`).
    Os(ErrorKind),
    /// `RuntimeError`.
    Runtime,
}

fn classify_model(e: &ModelError) -> Kind {
    if let Some(r) = e.range() {
        return Kind::Range(*r);
    }
    match e {
        ModelError::NonFinite { .. }
        | ModelError::Unreachable { .. }
        | ModelError::UnknownBackground { .. }
        | ModelError::UnknownTissue { .. } => Kind::Value,
        ModelError::ImageSize { .. } => Kind::Type,
        _ => Kind::Runtime,
    }
}

fn classify_estimate(e: &EstimateError) -> Kind {
    match e {
        EstimateError::Model(m) => classify_model(m),
        EstimateError::OutOfRange(r) => Kind::Range(*r),
        EstimateError::NoInstrument { .. } => Kind::NoInstrument,
        EstimateError::ImageSize { .. } | EstimateError::Length { .. } => Kind::Type,
        EstimateError::Io { kind, .. } => Kind::Os(*kind),
        EstimateError::ModelFile { .. }
        | EstimateError::ModelChecksum { .. }
        | EstimateError::ModelMismatch { .. }
        | EstimateError::IndexCorrupt { .. }
        | EstimateError::IndexVersion { .. }
        | EstimateError::NonFinite { .. }
        | EstimateError::EmptyIndex
        | EstimateError::NoBandDatabase
        | EstimateError::NoBand { .. } => Kind::Value,
        _ => Kind::Runtime,
    }
}

/// The exception `e` becomes (`None` for an error that is already a Python one).
pub(crate) fn classify(e: &Error) -> Option<Kind> {
    Some(match e {
        Error::Model(m) => classify_model(m),
        Error::Estimate(m) => classify_estimate(m),
        Error::Control(ControlError::Estimate(m)) => classify_estimate(m),
        Error::Control(ControlError::Model(m)) => classify_model(m),
        Error::Control(
            ControlError::OutOfRange(r) | ControlError::CaseOutOfRange { error: r, .. },
        ) => Kind::Range(*r),
        Error::Control(
            ControlError::NotEnoughData { .. }
            | ControlError::NonFiniteSample { .. }
            | ControlError::SharedCaseName { .. }
            | ControlError::SeedOverflow { .. }
            | ControlError::NoEstimate { .. },
        ) => Kind::Value,
        // a log file that cannot be written
        Error::Control(ControlError::Log { .. }) => Kind::Os(ErrorKind::Other),
        Error::Control(_) => Kind::Runtime,
        // serde's messages: "invalid value: …" and "unknown variant …" are bad
        // values; "invalid type: …", "missing field …", "unknown field …" are
        // the wrong kind of argument
        Error::Serde(msg) if msg.contains("invalid value") || msg.contains("unknown variant") => {
            Kind::Value
        }
        Error::Serde(_) => Kind::Type,
        Error::NoField(_) => Kind::Attribute,
        Error::Py(_) => return None,
    })
}

/// The message of `e` (the Rust error's own `Display`).
pub(crate) fn message(e: &Error) -> String {
    match e {
        Error::Model(m) => m.to_string(),
        Error::Estimate(m) => m.to_string(),
        Error::Control(m) => m.to_string(),
        Error::Py(p) => p.to_string(),
        Error::Serde(m) | Error::NoField(m) => m.clone(),
    }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> Self {
        let msg = message(&e);
        to_py(e, msg)
    }
}

/// `e` as its Python exception, the message prefixed with `at` (a file and
/// line, say: `"scenario.toml, line 3"`), its class and attributes as ever.
pub(crate) fn located(e: Error, at: &str) -> PyErr {
    let msg = format!("{at}: {}", message(&e));
    to_py(e, msg)
}

/// `e` as its Python exception with the message `msg`.
fn to_py(e: Error, msg: String) -> PyErr {
    {
        match classify(&e) {
            None => match e {
                Error::Py(p) => p,
                _ => PyRuntimeError::new_err(msg),
            },
            Some(Kind::Range(r)) => Python::attach(|py| range_error(py, &msg, &r)),
            Some(Kind::Value) => PyValueError::new_err(msg),
            Some(Kind::Type) => PyTypeError::new_err(msg),
            Some(Kind::Attribute) => PyAttributeError::new_err(msg),
            Some(Kind::NoInstrument) => PyNoInstrumentError::new_err(msg),
            Some(Kind::Os(ErrorKind::NotFound)) => PyFileNotFoundError::new_err(msg),
            Some(Kind::Os(ErrorKind::PermissionDenied)) => PyPermissionError::new_err(msg),
            Some(Kind::Os(_)) => PyOSError::new_err(msg),
            Some(Kind::Runtime) => PyRuntimeError::new_err(msg),
        }
    }
}

/// A `kflex.RangeError` with the range's fields as attributes.
fn range_error(py: Python<'_>, msg: &str, r: &RangeError) -> PyErr {
    let err = PyRangeError::new_err(msg.to_owned());
    let value = err.value(py);
    let attach = || -> PyResult<()> {
        value.setattr("name", r.name)?;
        value.setattr("value", r.value)?;
        value.setattr("min", r.bounds.min)?;
        value.setattr("max", r.bounds.max)?;
        value.setattr("min_inclusive", r.bounds.min_inclusive)?;
        value.setattr("max_inclusive", r.bounds.max_inclusive)?;
        Ok(())
    };
    match attach() {
        Ok(()) => err,
        Err(e) => e,
    }
}

/// A `TypeError` raised by the glue's own argument checks.
pub(crate) fn type_error(msg: impl Into<String>) -> Error {
    Error::Py(PyTypeError::new_err(msg.into()))
}

/// A `ValueError` raised by the glue's own argument checks.
pub(crate) fn value_error(msg: impl Into<String>) -> Error {
    Error::Py(PyValueError::new_err(msg.into()))
}

/// A Python `int` argument that Rust takes as unsigned (a count, a size, a
/// seed), as the signature takes it: wide enough that a negative or
/// too-large value reaches the body, where [`unsigned`] converts it and
/// names it in the error. (Taken as `u32` itself, pyo3 would raise a bare
/// `OverflowError` that names neither.) Non-ints still raise pyo3's
/// `TypeError`; a bool is 0 or 1. An int beyond ±2**127 still raises pyo3's
/// `OverflowError`, the argument named only in the exception's note
/// ("while processing 'seed'").
pub(crate) type Int = i128;

/// The unsigned types an [`Int`] converts to, with their largest value.
pub(crate) trait Unsigned: TryFrom<Int> {
    /// The largest value, for the error message.
    const MAX: u128;
}

macro_rules! unsigned_types {
    ($($t:ty),*) => {
        $(impl Unsigned for $t {
            const MAX: u128 = <$t>::MAX as u128;
        })*
    };
}
unsigned_types!(u8, u16, u32, u64, usize);

/// `value`, the Python argument `name`, as the unsigned type `T`. Raises
/// `ValueError` outside `T`'s range, e.g. "width = -1: must be a whole
/// number from 0 to 4294967295". Checks of its own after the conversion (a
/// size of 0 refused, say) stay the wrapped function's.
pub(crate) fn unsigned<T: Unsigned>(name: &str, value: Int) -> Result<T> {
    T::try_from(value).map_err(|_| {
        value_error(format!(
            "{name} = {value}: must be a whole number from 0 to {}",
            T::MAX
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use kflex_model::Bounds;

    fn range() -> RangeError {
        Bounds::open(0.0, 1e3).check("dt_s", -1.0).unwrap_err()
    }

    #[test]
    fn unsigned_takes_exactly_the_types_range() {
        assert!(matches!(unsigned::<u32>("width", 0), Ok(0)));
        assert!(matches!(
            unsigned::<u32>("width", 4_294_967_295),
            Ok(u32::MAX)
        ));
        assert!(unsigned::<u32>("width", 4_294_967_296).is_err());
        assert!(unsigned::<u32>("width", -1).is_err());
        assert!(matches!(
            unsigned::<u64>("seed", (1 << 64) - 1),
            Ok(u64::MAX)
        ));
        assert!(unsigned::<u64>("seed", 1 << 64).is_err());
        assert!(unsigned::<usize>("threads", -1).is_err());
        assert_eq!(<u64 as Unsigned>::MAX, u128::from(u64::MAX));
    }

    #[test]
    fn range_errors_keep_their_bounds_from_every_crate() {
        let r = range();
        for e in [
            Error::from(r),
            Error::Model(ModelError::OutOfWorkspace(r)),
            Error::Estimate(EstimateError::OutOfRange(r)),
            Error::Estimate(EstimateError::Model(ModelError::OutOfRange(r))),
            Error::Control(ControlError::OutOfRange(r)),
            Error::Control(ControlError::Model(ModelError::OutOfRange(r))),
            Error::Control(ControlError::Estimate(EstimateError::OutOfRange(r))),
        ] {
            assert_eq!(classify(&e), Some(Kind::Range(r)), "{e:?}");
        }
        assert_eq!(
            message(&Error::from(r)),
            "dt_s = -1 is out of range: must be in (0, 1000)"
        );
    }

    #[test]
    fn bad_values_shapes_and_faults_go_to_their_exceptions() {
        let cases = [
            (
                Error::Model(ModelError::NonFinite {
                    name: "theta_c_deg",
                    value: f64::NAN,
                }),
                Kind::Value,
            ),
            (
                Error::Model(ModelError::UnknownBackground { name: "x".into() }),
                Kind::Value,
            ),
            (
                Error::Model(ModelError::ImageSize {
                    what: "mask",
                    width: 2,
                    height: 2,
                    expected: 4,
                    got: 3,
                }),
                Kind::Type,
            ),
            (
                Error::Estimate(EstimateError::ImageSize {
                    width: 2,
                    height: 2,
                    expected: 12,
                    got: 3,
                }),
                Kind::Type,
            ),
            (
                Error::Estimate(EstimateError::NoInstrument { pixels: 0, min: 5 }),
                Kind::NoInstrument,
            ),
            (
                Error::Model(ModelError::Diverged {
                    what: "joint angle",
                }),
                Kind::Runtime,
            ),
            (
                Error::Model(ModelError::FeatureDisabled {
                    what: "joint_model = rapier",
                    feature: "multibody",
                }),
                Kind::Runtime,
            ),
            (
                Error::Control(ControlError::NotEnoughData {
                    metric: "rmse",
                    needed: "one sample",
                    got: 0,
                }),
                Kind::Value,
            ),
            (
                Error::Control(ControlError::SeedOverflow {
                    seed: u64::MAX,
                    repeats: 3,
                    largest_base: u64::MAX - 2,
                }),
                Kind::Value,
            ),
            (
                Error::Control(ControlError::NoEstimate {
                    estimator: "ibjae",
                    case: "V_0deg_0pct".into(),
                    seed: 1,
                }),
                Kind::Value,
            ),
            (
                Error::Control(ControlError::CaseOutOfRange {
                    case: 2,
                    stem: "IX_90deg_0pct".into(),
                    error: range(),
                }),
                Kind::Range(range()),
            ),
            (Error::Estimate(EstimateError::NoBandDatabase), Kind::Value),
            (
                Error::Estimate(EstimateError::NoBand {
                    translation_mm: 15.0,
                    held: "10, 20".into(),
                }),
                Kind::Value,
            ),
            (
                Error::Serde("invalid type: string \"a\", expected f64".into()),
                Kind::Type,
            ),
            (
                Error::Serde("unknown field `x`, expected `a` or `b`".into()),
                Kind::Type,
            ),
            (
                Error::Serde("invalid value: integer `-1`, expected u32".into()),
                Kind::Value,
            ),
            (
                Error::Serde("unknown variant `x`, expected `analytic` or `rapier`".into()),
                Kind::Value,
            ),
            (
                Error::Control(ControlError::Estimate(EstimateError::NoInstrument {
                    pixels: 0,
                    min: 5,
                })),
                Kind::NoInstrument,
            ),
            (
                Error::Control(ControlError::Worker {
                    message: "a worker panicked".into(),
                }),
                Kind::Runtime,
            ),
            (Error::NoField("no field".into()), Kind::Attribute),
        ];
        for (e, kind) in cases {
            assert_eq!(classify(&e), Some(kind), "{e:?}");
        }
    }

    #[test]
    fn estimation_errors_go_to_their_exceptions() {
        let path = std::path::PathBuf::from("db.kfi");
        let cases = [
            (
                EstimateError::Io {
                    path: path.clone(),
                    kind: ErrorKind::NotFound,
                    message: "gone".into(),
                },
                Kind::Os(ErrorKind::NotFound),
            ),
            (
                EstimateError::ModelFile {
                    path: "m.card.json".into(),
                    message: "not a model card".into(),
                },
                Kind::Value,
            ),
            (
                EstimateError::ModelChecksum {
                    path: "m.onnx".into(),
                    card: "00".into(),
                    file: "ff".into(),
                },
                Kind::Value,
            ),
            (
                EstimateError::IndexCorrupt {
                    path,
                    reason: "checksum".into(),
                },
                Kind::Value,
            ),
            (EstimateError::EmptyIndex, Kind::Value),
            (
                EstimateError::Length {
                    what: "query",
                    expected: 256,
                    got: 3,
                },
                Kind::Type,
            ),
            (
                EstimateError::OnnxRuntimeMissing {
                    searched: "nowhere".into(),
                },
                Kind::Runtime,
            ),
        ];
        for (e, kind) in cases {
            let e = Error::Estimate(e);
            assert_eq!(classify(&e), Some(kind), "{e:?}");
        }
    }
}
