//! Silhouettes and shaded frames as numpy arrays.

use kflex_model::{Frame, FrameParams, Mask, Occlusion, Rasterizer, Roi, SceneRenderer};
use pyo3::prelude::*;

use crate::array;
use crate::camera::{PyCamera, PyInstrumentShape, PyRoi};
use crate::error::Result;
use crate::value::serde_class;

serde_class!(
    /// How one frame is made (kflex-model's `FrameParams`): `background`
    /// ("colon", "stomach", "larynx"), `tissue` ("organ", "grey", "pale",
    /// "white", "blue_green", "yellow"), `seed`, `frame`,
    /// `illumination_gain`, `noise_std` (on [0, 1]), `blur_px` (px),
    /// `occlusion` (None or an `Occlusion`, read back as a `dict`).
    PyFrameParams, "FrameParams", FrameParams, {
        /// Checks the parameters; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }
    }
);

serde_class!(
    /// Tape over the instrument (kflex-model's `Occlusion`): `fraction` of
    /// the instrument's pixels in the working region, at `position` (0
    /// proximal, 1 distal), measured in `region` (a `Roi`, or None for the
    /// camera's working region).
    PyOcclusion, "Occlusion", Occlusion, {}
);

/// A rendered frame and its ground truth: `rgb` (H×W×3 uint8), `instrument`
/// and `occluder` (H×W bool masks: the untaped instrument's pixels, the tape's).
#[pyclass(name = "Frame", module = "kflex", frozen)]
pub struct PyFrame {
    /// The image, H×W×3 uint8, row-major RGB.
    #[pyo3(get)]
    rgb: Py<PyAny>,
    /// The instrument's visible pixels, H×W bool.
    #[pyo3(get)]
    instrument: Py<PyAny>,
    /// The tape's pixels, H×W bool.
    #[pyo3(get)]
    occluder: Py<PyAny>,
    /// Width, px.
    #[pyo3(get)]
    width: u32,
    /// Height, px.
    #[pyo3(get)]
    height: u32,
}

impl PyFrame {
    fn new(py: Python<'_>, f: Frame) -> Self {
        Self {
            instrument: array::mask(py, &f.instrument).unbind(),
            occluder: array::mask(py, &f.occluder).unbind(),
            rgb: array::image(py, f.rgb, f.width, f.height).unbind(),
            width: f.width,
            height: f.height,
        }
    }
}

/// Renders shaded frames, caching backgrounds (kflex-model's `SceneRenderer`).
/// Rendering runs without the interpreter lock.
#[pyclass(name = "SceneRenderer", module = "kflex")]
#[derive(Default)]
pub struct PySceneRenderer {
    inner: SceneRenderer,
}

#[pymethods]
impl PySceneRenderer {
    /// A renderer with an empty cache.
    #[new]
    fn py_new() -> Self {
        Self::default()
    }

    /// The whole frame of `shape` seen by `camera` with `params` (default
    /// `FrameParams()`). Raises `RangeError` for a parameter out of range.
    #[pyo3(signature = (camera, shape, params = None))]
    fn render(
        &mut self,
        py: Python<'_>,
        camera: PyRef<'_, PyCamera>,
        shape: PyRef<'_, PyInstrumentShape>,
        params: Option<PyFrameParams>,
    ) -> Result<PyFrame> {
        let k = camera.inner.intrinsics;
        self.render_window(
            py,
            camera,
            shape,
            PyRoi::from(Roi::whole(k.width, k.height)),
            params,
        )
    }

    /// The pixels of `render`'s frame inside `window` (a `Roi`), exactly, at
    /// a cost proportional to the window's area.
    #[pyo3(signature = (camera, shape, window, params = None))]
    fn render_window(
        &mut self,
        py: Python<'_>,
        camera: PyRef<'_, PyCamera>,
        shape: PyRef<'_, PyInstrumentShape>,
        window: PyRoi,
        params: Option<PyFrameParams>,
    ) -> Result<PyFrame> {
        let params = params.map_or_else(FrameParams::default, |p| p.inner);
        let camera = camera.inner;
        let shape = &shape.inner;
        let renderer = &mut self.inner;
        let frame = py.detach(|| renderer.render_window(&camera, shape, &params, window.inner))?;
        Ok(PyFrame::new(py, frame))
    }
}

/// Exact ray-cast silhouettes (kflex-model's `Rasterizer`), as H×W bool
/// arrays. Runs without the interpreter lock.
#[pyclass(name = "Rasterizer", module = "kflex")]
#[derive(Default)]
pub struct PyRasterizer {
    inner: Rasterizer,
}

#[pymethods]
impl PyRasterizer {
    /// A rasterizer with empty buffers.
    #[new]
    fn py_new() -> Self {
        Self::default()
    }

    /// The silhouette of `shape` over `camera`'s whole image.
    fn silhouette<'py>(
        &mut self,
        py: Python<'py>,
        camera: PyRef<'_, PyCamera>,
        shape: PyRef<'_, PyInstrumentShape>,
    ) -> Result<Bound<'py, PyAny>> {
        let k = camera.inner.intrinsics;
        self.silhouette_window(
            py,
            camera,
            shape,
            PyRoi::from(Roi::whole(k.width, k.height)),
        )
    }

    /// The silhouette inside `window` (a `Roi`) of `camera`'s image:
    /// exactly the whole image's crop.
    fn silhouette_window<'py>(
        &mut self,
        py: Python<'py>,
        camera: PyRef<'_, PyCamera>,
        shape: PyRef<'_, PyInstrumentShape>,
        window: PyRoi,
    ) -> Result<Bound<'py, PyAny>> {
        let camera = camera.inner;
        let shape = &shape.inner;
        let raster = &mut self.inner;
        let window = window.inner;
        let mask = py.detach(|| -> kflex_model::Result<Mask> {
            let mut mask = Mask::new(window.width, window.height)?;
            raster.silhouette_window(&camera, shape, window, &mut mask)?;
            Ok(mask)
        })?;
        Ok(array::mask(py, &mask))
    }
}
