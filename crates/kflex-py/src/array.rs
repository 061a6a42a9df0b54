//! numpy arrays in and out: the glue's checks of dtype and shape, in one place.
//!
//! Inputs are copied into Rust buffers (any strides, so non-contiguous views
//! work) before a long call lets go of the interpreter: another Python thread
//! may then run, and must not be able to change an array under the call.

use kflex_model::Mask;
use numpy::ndarray::{Array2, Array3, ArrayD, IxDyn};
use numpy::prelude::*;
use numpy::{PyArrayDyn, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::{PyFloat, PyInt};

use crate::error::{Result, type_error};

/// Floats from Python: one number, or an array of any shape.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Floats {
    /// A Python `int` or `float` (or a numpy scalar).
    Scalar(f64),
    /// A float64 or float32 array (float32 widened exactly), in C order.
    Array(ArrayD<f64>),
}

impl Floats {
    /// Applies `f` to each value, keeping the shape (a scalar stays one).
    pub(crate) fn map(&self, f: impl Fn(f64) -> f64) -> Self {
        match self {
            Self::Scalar(x) => Self::Scalar(f(*x)),
            Self::Array(a) => Self::Array(a.mapv(f)),
        }
    }

    /// [`Floats::map`] with a function that may fail (the first error is returned).
    pub(crate) fn try_map<E>(
        &self,
        f: impl Fn(f64) -> std::result::Result<f64, E>,
    ) -> std::result::Result<Self, E> {
        Ok(match self {
            Self::Scalar(x) => Self::Scalar(f(*x)?),
            Self::Array(a) => {
                let values = a
                    .iter()
                    .map(|&x| f(x))
                    .collect::<std::result::Result<Vec<_>, E>>()?;
                Self::Array(ArrayD::from_shape_vec(a.raw_dim(), values).expect("same shape"))
            }
        })
    }

    /// As Python: a `float` or a float64 array.
    pub(crate) fn into_py(self, py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
        Ok(match self {
            Self::Scalar(x) => x.into_pyobject(py)?.into_any(),
            Self::Array(a) => a.into_pyarray(py).into_any(),
        })
    }
}

/// `obj` as floats: a Python number, a numpy float64 or float32 array (any
/// shape, any strides), or a list of numbers.
///
/// # Errors
/// `TypeError` naming `name`, the dtypes accepted and the one given.
pub(crate) fn floats(name: &str, obj: &Bound<'_, PyAny>) -> Result<Floats> {
    if obj.cast::<PyFloat>().is_ok() || obj.cast::<PyInt>().is_ok() {
        return Ok(Floats::Scalar(obj.extract()?));
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        return Ok(Floats::Array(a.readonly().as_array().to_owned()));
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        return Ok(Floats::Array(a.readonly().as_array().mapv(f64::from)));
    }
    if let Ok(a) = obj.cast::<PyUntypedArray>() {
        if a.ndim() == 0
            && let Ok(x) = obj.extract::<f64>()
        {
            return Ok(Floats::Scalar(x));
        }
        return Err(type_error(format!(
            "{name}: expected a float64 or float32 array, got dtype {}",
            a.dtype()
        )));
    }
    if let Ok(v) = obj.extract::<Vec<f64>>() {
        let n = v.len();
        return Ok(Floats::Array(
            ArrayD::from_shape_vec(IxDyn(&[n]), v).expect("1-D"),
        ));
    }
    if let Ok(x) = obj.extract::<f64>() {
        return Ok(Floats::Scalar(x));
    }
    Err(type_error(format!(
        "{name}: expected a number or a float64/float32 array, got {}",
        obj.get_type().name()?
    )))
}

/// A one-dimensional series of floats (`name` in the error).
///
/// # Errors
/// As [`floats`]; `TypeError` for an array that is not one-dimensional.
pub(crate) fn series(name: &str, obj: &Bound<'_, PyAny>) -> Result<Vec<f64>> {
    match floats(name, obj)? {
        Floats::Array(a) if a.ndim() == 1 => Ok(a.iter().copied().collect()),
        Floats::Array(a) => Err(type_error(format!(
            "{name}: expected a one-dimensional array, got shape {:?}",
            a.shape()
        ))),
        Floats::Scalar(_) => Err(type_error(format!(
            "{name}: expected a one-dimensional array, got a number"
        ))),
    }
}

/// `n` floats: a number (repeated `n` times) or a one-dimensional array of
/// `n` (`name` in the error).
///
/// # Errors
/// As [`floats`]; `TypeError` for an array of another shape.
pub(crate) fn broadcast(name: &str, obj: &Bound<'_, PyAny>, n: usize) -> Result<Vec<f64>> {
    match floats(name, obj)? {
        Floats::Scalar(x) => Ok(vec![x; n]),
        Floats::Array(a) if a.ndim() == 1 && a.len() == n => Ok(a.iter().copied().collect()),
        Floats::Array(a) => Err(type_error(format!(
            "{name}: expected a number or an array of shape ({n},), got shape {:?}",
            a.shape()
        ))),
    }
}

/// An RGB frame: `(rgb row-major, width, height)`.
///
/// # Errors
/// `TypeError` unless `obj` is an `H×W×3` uint8 array (any strides).
pub(crate) fn rgb(obj: &Bound<'_, PyAny>) -> Result<(Vec<u8>, u32, u32)> {
    let describe = || -> Result<String> {
        Ok(match obj.cast::<PyUntypedArray>() {
            Ok(a) => format!("shape {:?} dtype {}", a.shape(), a.dtype()),
            Err(_) => obj.get_type().name()?.to_string(),
        })
    };
    let Ok(a) = obj.cast::<numpy::PyArray3<u8>>() else {
        return Err(type_error(format!(
            "rgb: expected an HxWx3 uint8 array, got {}",
            describe()?
        )));
    };
    let view = a.readonly();
    let view = view.as_array();
    let (h, w, c) = view.dim();
    let (Ok(wu), Ok(hu)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(type_error(format!("rgb: image of {w}x{h} px is too large")));
    };
    if c != 3 {
        return Err(type_error(format!(
            "rgb: expected an HxWx3 uint8 array, got {}",
            describe()?
        )));
    }
    if w == 0 || h == 0 {
        return Err(type_error(format!(
            "rgb: an empty image ({w}x{h} px): an image needs at least one pixel, got {}",
            describe()?
        )));
    }
    Ok((view.iter().copied().collect(), wu, hu))
}

/// A mask as an `H×W` bool array.
pub(crate) fn mask<'py>(py: Python<'py>, m: &Mask) -> Bound<'py, PyAny> {
    let shape = (m.height() as usize, m.width() as usize);
    let values = m.data().iter().map(|&v| v != 0).collect();
    Array2::from_shape_vec(shape, values)
        .expect("a mask's buffer is width x height")
        .into_pyarray(py)
        .into_any()
}

/// An RGB buffer as an `H×W×3` uint8 array.
pub(crate) fn image<'py>(
    py: Python<'py>,
    rgb: Vec<u8>,
    width: u32,
    height: u32,
) -> Bound<'py, PyAny> {
    Array3::from_shape_vec((height as usize, width as usize, 3), rgb)
        .expect("a frame's buffer is width x height x 3")
        .into_pyarray(py)
        .into_any()
}

/// A series of floats as a float64 array.
pub(crate) fn column(py: Python<'_>, values: Vec<f64>) -> Bound<'_, PyAny> {
    values.into_pyarray(py).into_any()
}

/// 2×2 covariances as an `(n, 2, 2)` float64 array.
///
/// # Errors
/// Never for a whole series (the shape is the values'); a `RuntimeError` if it were not.
pub(crate) fn covariances<'py>(
    py: Python<'py>,
    values: impl Iterator<Item = [[f64; 2]; 2]>,
) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = values
        .flat_map(|c| [c[0][0], c[0][1], c[1][0], c[1][1]])
        .collect();
    let n = flat.len() / 4;
    let a = numpy::ndarray::Array3::from_shape_vec((n, 2, 2), flat)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py).into_any())
}

/// A one-dimensional series of flags: a bool array or a list of bools.
///
/// # Errors
/// `TypeError` naming `name` for another dtype or shape.
pub(crate) fn flags(name: &str, obj: &Bound<'_, PyAny>) -> Result<Vec<bool>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<bool>>() {
        let view = a.readonly();
        let view = view.as_array();
        if view.ndim() != 1 {
            return Err(type_error(format!(
                "{name}: expected a one-dimensional bool array, got shape {:?}",
                view.shape()
            )));
        }
        return Ok(view.iter().copied().collect());
    }
    obj.extract::<Vec<bool>>()
        .map_err(|_| wrong_dtype(name, "a one-dimensional bool array", obj))
}

/// A `TypeError`: `name` expected `what` and got `obj` (its dtype, for an array).
fn wrong_dtype(name: &str, what: &str, obj: &Bound<'_, PyAny>) -> crate::error::Error {
    let got = match obj.cast::<PyUntypedArray>() {
        Ok(a) => format!("dtype {}", a.dtype()),
        Err(_) => obj
            .get_type()
            .name()
            .map_or_else(|_| "?".to_string(), |n| n.to_string()),
    };
    type_error(format!("{name}: expected {what}, got {got}"))
}

/// Rows of float32 values: a 2-D float32 or float64 array (float64 rounded
/// to float32), as `(values row-major, rows, columns)`; a 1-D array is one
/// row when `one_row_ok`.
///
/// # Errors
/// `TypeError` naming `name`, the shape and dtype expected and given;
/// `ValueError` naming the element of a finite float64 that rounds to
/// infinity in float32.
pub(crate) fn rows_f32(
    name: &str,
    obj: &Bound<'_, PyAny>,
    one_row_ok: bool,
) -> Result<(Vec<f32>, usize, usize)> {
    // a finite float64 that float32 cannot hold, named after the shape check
    let mut too_big = None;
    let a: ArrayD<f32> = if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        a.readonly().as_array().to_owned()
    } else if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        let view = a.readonly();
        let view = view.as_array();
        too_big = view
            .indexed_iter()
            .find(|(_, v)| v.is_finite() && (**v as f32).is_infinite())
            .map(|(at, v)| (numpy::ndarray::Dimension::slice(&at).to_vec(), *v));
        view.mapv(|x| x as f32)
    } else {
        return Err(wrong_dtype(name, "a float32 or float64 array", obj));
    };
    let (rows, cols) = match a.shape() {
        &[r, c] => (r, c),
        &[c] if one_row_ok => (1, c),
        other => {
            return Err(type_error(format!(
                "{name}: expected shape (N, D){}, got shape {other:?}",
                if one_row_ok { " or (D,)" } else { "" }
            )));
        }
    };
    // named as given, not as the infinity it would round to
    if let Some((at, v)) = too_big {
        return Err(crate::error::value_error(format!(
            "{name}{at:?} = {v:e} does not fit float32 (largest magnitude {:e})",
            f32::MAX
        )));
    }
    Ok((a.iter().copied().collect(), rows, cols))
}

/// Silhouettes of `side × side`: an `(N, side, side)` or `(side, side)`
/// array of bool, uint8 (nonzero: instrument) or float32 (0.0 or 1.0), as
/// masks; the flag says whether one silhouette was given without the batch
/// axis.
///
/// # Errors
/// `TypeError` naming the shape and dtype expected and given; `ValueError`
/// for a float32 value other than 0 and 1.
pub(crate) fn silhouettes(
    name: &str,
    obj: &Bound<'_, PyAny>,
    side: usize,
) -> Result<(Vec<Mask>, bool)> {
    let a: ArrayD<u8> = if let Ok(a) = obj.cast::<PyArrayDyn<bool>>() {
        a.readonly().as_array().mapv(u8::from)
    } else if let Ok(a) = obj.cast::<PyArrayDyn<u8>>() {
        a.readonly().as_array().to_owned()
    } else if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        let view = a.readonly();
        let view = view.as_array();
        if let Some(bad) = view.iter().find(|v| **v != 0.0 && **v != 1.0) {
            return Err(crate::error::value_error(format!(
                "{name}: float32 silhouettes must hold 0.0 (background) or 1.0 (instrument), found {bad}"
            )));
        }
        view.mapv(|v| u8::from(v != 0.0))
    } else {
        return Err(wrong_dtype(name, "a bool, uint8 or float32 array", obj));
    };
    let single = a.ndim() == 2;
    let n = match a.shape() {
        &[h, w] if h == side && w == side => 1,
        &[n, h, w] if h == side && w == side => n,
        other => {
            return Err(type_error(format!(
                "{name}: expected shape (N, {side}, {side}) or ({side}, {side}), got shape {other:?}"
            )));
        }
    };
    let values: Vec<u8> = a.iter().copied().collect();
    let s = u32::try_from(side).map_err(|_| type_error(format!("{name}: side too large")))?;
    let masks = if n == 0 {
        Vec::new()
    } else {
        values
            .chunks_exact(side * side)
            .map(|m| Mask::from_raw(s, s, m.to_vec()))
            .collect::<std::result::Result<Vec<_>, _>>()?
    };
    Ok((masks, single))
}
