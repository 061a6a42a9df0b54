//! The region-based segmentation, on numpy frames.

use kflex_estimate::{EstimateError, SegmentParams, Segmentation, Segmenter};
use pyo3::prelude::*;

use crate::array;
use crate::camera::PyRoi;
use crate::error::Result;
use crate::value::serde_class;

serde_class!(
    /// Segmentation thresholds (kflex-estimate's `SegmentParams`), colours on
    /// the [0, 1] scale; `out` is the output side, px (48).
    PySegmentParams, "SegmentParams", SegmentParams, {}
);

/// One region's segmentation: `full` (the region's own size) and `small`
/// (`out × out`, 48×48 by default), H×W bool arrays.
#[pyclass(name = "Segmentation", module = "kflex", frozen)]
pub struct PySegmentation {
    /// Instrument mask at the region's resolution, H×W bool.
    #[pyo3(get)]
    full: Py<PyAny>,
    /// Resampled to `out × out` for IBJAE, bool.
    #[pyo3(get)]
    small: Py<PyAny>,
}

impl PySegmentation {
    fn new(py: Python<'_>, s: &Segmentation) -> Self {
        Self {
            full: array::mask(py, &s.full).unbind(),
            small: array::mask(py, &s.small).unbind(),
        }
    }
}

/// The segmentation stage (kflex-estimate's `Segmenter`), keeping its
/// working memory from frame to frame. Segmentation runs without the
/// interpreter lock.
#[pyclass(name = "Segmenter", module = "kflex")]
pub struct PySegmenter {
    inner: Segmenter,
}

#[pymethods]
impl PySegmenter {
    /// A segmenter with these thresholds (default `SegmentParams()`);
    /// raises `RangeError` for one out of range.
    #[new]
    #[pyo3(signature = (params = None))]
    fn py_new(params: Option<PySegmentParams>) -> Result<Self> {
        let params = params.map_or_else(SegmentParams::default, |p| p.inner);
        Ok(Self {
            inner: Segmenter::new(params)?,
        })
    }

    /// The thresholds in use.
    #[getter]
    fn params(&self) -> PySegmentParams {
        (*self.inner.params()).into()
    }

    /// Segments the instrument in `roi` of `rgb` (an H×W×3 uint8 array; any
    /// strides). Returns a `Segmentation`, or None when the region holds no
    /// instrument (fewer pixels than `min_instrument` of it): a missing
    /// measurement, not an error. Raises `TypeError` for another dtype or
    /// shape, `RangeError` for a region outside the frame.
    fn segment(
        &mut self,
        py: Python<'_>,
        rgb: &Bound<'_, PyAny>,
        roi: PyRoi,
    ) -> Result<Option<PySegmentation>> {
        let (rgb, width, height) = array::rgb(rgb)?;
        let segmenter = &mut self.inner;
        let found = py.detach(|| match segmenter.segment(&rgb, width, height, roi.inner) {
            Ok(s) => Ok(Some(s.clone())),
            Err(EstimateError::NoInstrument { .. }) => Ok(None),
            Err(e) => Err(e),
        })?;
        Ok(found.map(|s| PySegmentation::new(py, &s)))
    }
}

/// One-off segmentation of `roi` of `rgb` with `params` (see
/// `Segmenter.segment`; keep a `Segmenter` in a loop).
#[pyfunction]
#[pyo3(signature = (rgb, roi, params = None))]
pub(crate) fn segment(
    py: Python<'_>,
    rgb: &Bound<'_, PyAny>,
    roi: PyRoi,
    params: Option<PySegmentParams>,
) -> Result<Option<PySegmentation>> {
    PySegmenter::py_new(params)?.segment(py, rgb, roi)
}
