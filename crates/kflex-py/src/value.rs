//! Parameter types as Python classes, through their serde form.
//!
//! kflex's configuration types are plain serde structs (the same form
//! `kflex-cli run --config` reads as TOML or JSON). Their Python classes
//! ([`serde_class!`]) hold the Rust value and read and write its fields
//! through that form: `SheathParams(friction_coefficient=0.2)` is the JSON
//! object `{"friction_coefficient": 0.2}` read by serde, so the defaults,
//! the field names, the required fields and the refused unknown ones are
//! the Rust type's own; a field added in Rust is there in Python with no
//! change here. Nested structs read back as `dict`s (copies); assign a
//! whole `dict` or parameter object to change one.

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::{Map, Number, Value};

use crate::error::{Error, Result, type_error, value_error};

/// A Python value as JSON: `None`, `bool`, `int`, `float`, `str`, lists and
/// tuples, `dict`s with `str` keys, numpy scalars and arrays (through
/// `tolist()`), and kflex's parameter objects (through `to_dict()`).
///
/// # Errors
/// `ValueError` for a NaN or infinite float (no kflex parameter takes one) or
/// an integer outside the 64-bit range; `TypeError` for anything else.
pub(crate) fn from_py(name: &str, obj: &Bound<'_, PyAny>) -> Result<Value> {
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if obj.cast::<PyInt>().is_ok() {
        return int(name, obj);
    }
    if let Ok(f) = obj.cast::<PyFloat>() {
        return float(name, f.value());
    }
    if let Ok(s) = obj.cast::<PyString>() {
        return Ok(Value::String(s.to_str()?.to_owned()));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut map = Map::new();
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| type_error(format!("{name}: dict keys must be str")))?;
            let inner = format!("{name}.{key}");
            map.insert(key, from_py(&inner, &v)?);
        }
        return Ok(Value::Object(map));
    }
    if obj.cast::<PyList>().is_ok() || obj.cast::<PyTuple>().is_ok() {
        let items = obj
            .try_iter()?
            .enumerate()
            .map(|(i, v)| from_py(&format!("{name}[{i}]"), &v?))
            .collect::<Result<Vec<_>>>()?;
        return Ok(Value::Array(items));
    }
    if let Some(to_dict) = obj.getattr_opt("to_dict")? {
        return from_py(name, &to_dict.call0()?);
    }
    if let Some(tolist) = obj.getattr_opt("tolist")? {
        // numpy arrays and scalars
        return from_py(name, &tolist.call0()?);
    }
    if let Ok(x) = obj.extract::<f64>() {
        return float(name, x);
    }
    Err(type_error(format!(
        "{name}: expected a number, bool, str, list, dict, None or a kflex parameter object, got {}",
        obj.get_type().name()?
    )))
}

fn int(name: &str, obj: &Bound<'_, PyAny>) -> Result<Value> {
    if let Ok(u) = obj.extract::<u64>() {
        return Ok(Value::Number(u.into()));
    }
    obj.extract::<i64>()
        .map(|i| Value::Number(i.into()))
        .map_err(|_| value_error(format!("{name} = {obj}: integer out of the 64-bit range")))
}

fn float(name: &str, x: f64) -> Result<Value> {
    Number::from_f64(x)
        .map(Value::Number)
        .ok_or_else(|| value_error(format!("{name} = {x}: must be a finite number")))
}

/// A JSON value as a Python one (objects as `dict`, arrays as `list`).
pub(crate) fn to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => u.into_pyobject(py)?.into_any(),
            (None, Some(i)) => i.into_pyobject(py)?.into_any(),
            _ => n.as_f64().unwrap_or(f64::NAN).into_pyobject(py)?.into_any(),
        },
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, to_py(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// The serde form of `value` (a JSON object for a struct).
pub(crate) fn to_value<T: Serialize>(value: &T) -> Result<Value> {
    serde_json::to_value(value).map_err(|e| Error::Serde(e.to_string()))
}

/// `T` from its serde form; `what` names it in the error.
pub(crate) fn from_value<T: DeserializeOwned>(what: &str, value: Value) -> Result<T> {
    serde_json::from_value(value).map_err(|e| Error::Serde(format!("{what}: {e}")))
}

/// `T` from keyword arguments (serde's defaults for the fields left out,
/// where `T` has them).
pub(crate) fn from_kwargs<T: DeserializeOwned>(
    what: &str,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> Result<T> {
    let fields = match kwargs {
        Some(d) => from_py(what, d.as_any())?,
        None => Value::Object(Map::new()),
    };
    from_value(what, fields)
}

/// Field `name` of `value`, as Python.
pub(crate) fn get_field<'py, T: Serialize>(
    py: Python<'py>,
    what: &str,
    value: &T,
    name: &str,
) -> Result<Bound<'py, PyAny>> {
    match to_value(value)? {
        Value::Object(map) => match map.get(name) {
            Some(v) => Ok(to_py(py, v)?),
            None => Err(no_field(what, name, &map)),
        },
        _ => Err(Error::NoField(format!("{what} has no field '{name}'"))),
    }
}

/// Sets field `name` of `value`; `value` is unchanged on error.
pub(crate) fn set_field<T: Serialize + DeserializeOwned>(
    what: &str,
    value: &mut T,
    name: &str,
    new: &Bound<'_, PyAny>,
) -> Result<()> {
    let Value::Object(mut map) = to_value(value)? else {
        return Err(Error::NoField(format!("{what} has no field '{name}'")));
    };
    if !map.contains_key(name) {
        return Err(no_field(what, name, &map));
    }
    let path = format!("{what}.{name}");
    map.insert(name.to_owned(), from_py(&path, new)?);
    *value = from_value(&path, Value::Object(map))?;
    Ok(())
}

fn no_field(what: &str, name: &str, map: &Map<String, Value>) -> Error {
    let fields: Vec<&str> = map.keys().map(String::as_str).collect();
    Error::NoField(format!(
        "{what} has no field '{name}'; its fields: {}",
        fields.join(", ")
    ))
}

/// `Name(field=value, ...)` of a serde struct.
pub(crate) fn repr<T: Serialize>(what: &str, value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(Value::Object(map)) => {
            let fields: Vec<String> = map
                .iter()
                .map(|(k, v)| format!("{k}={}", py_repr(v)))
                .collect();
            format!("{what}({})", fields.join(", "))
        }
        Ok(v) => format!("{what}({})", py_repr(&v)),
        Err(e) => format!("{what}(<{e}>)"),
    }
}

/// A JSON value written as Python would write its Python form.
fn py_repr(v: &Value) -> String {
    match v {
        Value::Null => "None".into(),
        Value::Bool(b) => if *b { "True" } else { "False" }.into(),
        Value::Number(n) => match n.as_f64() {
            Some(x) if !n.is_u64() && !n.is_i64() && x.fract() == 0.0 && x.abs() < 1e16 => {
                format!("{x:.1}")
            }
            _ => n.to_string(),
        },
        Value::String(s) => format!("{s:?}"),
        Value::Array(items) => {
            let parts: Vec<String> = items.iter().map(py_repr).collect();
            format!("[{}]", parts.join(", "))
        }
        Value::Object(map) => {
            let parts: Vec<String> = map
                .iter()
                .map(|(k, v)| format!("{k:?}: {}", py_repr(v)))
                .collect();
            format!("{{{}}}", parts.join(", "))
        }
    }
}

/// A Python class over a serde struct `$rust`: keyword construction, field
/// access by name, `to_dict`/`from_dict`, `==` and `repr`, plus the
/// methods given in braces.
macro_rules! serde_class {
    ($(#[$doc:meta])* $py:ident, $name:literal, $rust:ty, { $($methods:tt)* }) => {
        $(#[$doc])*
        #[pyclass(name = $name, module = "kflex", eq, from_py_object)]
        #[derive(Debug, Clone, PartialEq)]
        pub struct $py {
            pub(crate) inner: $rust,
        }

        impl From<$rust> for $py {
            fn from(inner: $rust) -> Self {
                Self { inner }
            }
        }

        #[pymethods]
        impl $py {
            /// Built from keyword arguments, the Rust type's serde fields; fields
            /// left out take the Rust type's defaults where it has them.
            #[new]
            #[pyo3(signature = (**fields))]
            fn py_new(fields: Option<&Bound<'_, pyo3::types::PyDict>>) -> $crate::error::Result<Self> {
                Ok(Self { inner: $crate::value::from_kwargs($name, fields)? })
            }

            fn __getattr__<'py>(&self, py: Python<'py>, name: &str) -> $crate::error::Result<Bound<'py, PyAny>> {
                $crate::value::get_field(py, $name, &self.inner, name)
            }

            fn __setattr__(&mut self, name: &str, value: &Bound<'_, PyAny>) -> $crate::error::Result<()> {
                $crate::value::set_field($name, &mut self.inner, name, value)
            }

            fn __repr__(&self) -> String {
                $crate::value::repr($name, &self.inner)
            }

            /// The fields as a `dict` (nested structs as `dict`s).
            fn to_dict<'py>(&self, py: Python<'py>) -> $crate::error::Result<Bound<'py, PyAny>> {
                Ok($crate::value::to_py(py, &$crate::value::to_value(&self.inner)?)?)
            }

            /// Built from a `dict` of fields (as the constructor's keywords).
            #[staticmethod]
            fn from_dict(fields: &Bound<'_, pyo3::types::PyDict>) -> $crate::error::Result<Self> {
                Ok(Self { inner: $crate::value::from_kwargs($name, Some(fields))? })
            }

            /// A copy.
            fn copy(&self) -> Self {
                self.clone()
            }

            fn __copy__(&self) -> Self {
                self.clone()
            }

            fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
                self.clone()
            }

            $($methods)*
        }
    };
}

pub(crate) use serde_class;
