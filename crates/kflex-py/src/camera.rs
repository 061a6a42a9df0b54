//! The endoscope camera, the instrument it sees, and the regions of interest.

use kflex_model::{
    Banding, BuildTolerances, BuiltInstrument, Camera, Instrument, InstrumentParams,
    InstrumentShape, Intrinsics, Lens, PoseRange, Roi, WorkingBand, WorkingRegions,
};
use pyo3::prelude::*;

use crate::error::{Error, Int, Result, unsigned};

/// `ValueError` naming the first of `values` that is not finite.
pub(crate) fn finite(names: [&'static str; 2], values: [f64; 2]) -> Result<()> {
    for (name, value) in names.into_iter().zip(values) {
        kflex_model::finite(name, value)?;
    }
    Ok(())
}

/// `ValueError` where normalised distorted coordinates `(xd, yd)` lie beyond
/// the division model's reach: `1 + λ r² ≤ 0` bends the ray backwards.
fn within_lens(lens: &kflex_model::Lens, xd: f64, yd: f64) -> Result<()> {
    let r2 = xd * xd + yd * yd;
    let q = 1.0 + lens.division * r2;
    if r2.is_finite() && q > 0.0 {
        return Ok(());
    }
    Err(Error::Py(pyo3::exceptions::PyValueError::new_err(format!(
        "normalised position ({xd:e}, {yd:e}) lies beyond the lens's reach: 1 + λ r² = \
         {} with λ = {} (r² must be finite and 1 + λ r² > 0 to bend the ray forward)",
        kflex_model::Num(q),
        kflex_model::Num(lens.division)
    ))))
}
use crate::plant::{PyJointParams, PyTranslationParams};
use crate::value::serde_class;

serde_class!(
    /// Pinhole intrinsics in pixels (kflex-model's `Intrinsics`): `width`,
    /// `height`, `fx`, `fy`, `cx`, `cy`; all required (`Intrinsics.default()`
    /// is the 640×480 default).
    PyIntrinsics, "Intrinsics", Intrinsics, {
        /// The default 640×480 camera's intrinsics.
        #[staticmethod]
        fn default() -> Self {
            Intrinsics::default().into()
        }

        /// Square pixels, centred principal point, horizontal field of view
        /// `hfov_deg` (deg); `RangeError` outside (1, 179).
        #[staticmethod]
        fn from_fov(width: Int, height: Int, hfov_deg: f64) -> Result<Self> {
            let (width, height) = (unsigned("width", width)?, unsigned("height", height)?);
            Ok(Intrinsics::from_fov(width, height, hfov_deg)?.into())
        }

        /// The paper's camera: 1920×1080, the default's field of view.
        #[staticmethod]
        fn full_hd() -> Self {
            Intrinsics::full_hd().into()
        }

        /// Checks size, focal lengths and principal point; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }

        /// The intrinsics of the camera that sees the region `x0, y0, w, h`
        /// (px) of this image resampled to `out_w × out_h`.
        fn region(&self, x0: f64, y0: f64, w: f64, h: f64, out_w: Int, out_h: Int) -> Result<Self> {
            let (out_w, out_h) = (unsigned("out_w", out_w)?, unsigned("out_h", out_h)?);
            Ok(self.inner.region(x0, y0, w, h, out_w, out_h)?.into())
        }
    }
);

serde_class!(
    /// Lens distortion (division model `division`, λ) and vignetting
    /// (`vignetting`, κ) (kflex-model's `Lens`); dimensionless.
    PyLens, "Lens", Lens, {
        /// An ideal pinhole: no distortion, no vignetting.
        #[staticmethod]
        fn pinhole() -> Self {
            Lens::PINHOLE.into()
        }

        /// Checks the coefficients for an image with intrinsics `k`; raises `RangeError`.
        fn validate(&self, k: PyIntrinsics) -> Result<()> {
            Ok(self.inner.validate(&k.inner)?)
        }

        /// Distorted normalised coordinates `[xd, yd]` of undistorted `(xu, yu)`.
        /// Raises `ValueError` for a coordinate that is not finite.
        fn distort(&self, xu: f64, yu: f64) -> Result<[f64; 2]> {
            finite(["xu", "yu"], [xu, yu])?;
            Ok(self.inner.distort(xu, yu))
        }

        /// Undistorted normalised coordinates `[xu, yu]` of distorted `(xd, yd)`.
        /// Raises `ValueError` for a coordinate that is not finite, or one
        /// beyond the division model's reach (`1 + λ r² ≤ 0`, where the
        /// formula would turn the ray around).
        fn undistort(&self, xd: f64, yd: f64) -> Result<[f64; 2]> {
            finite(["xd", "yd"], [xd, yd])?;
            within_lens(&self.inner, xd, yd)?;
            Ok(self.inner.undistort(xd, yd))
        }
    }
);

serde_class!(
    /// A region of interest in pixels, `[x0, x0 + width) × [y0, y0 + height)`
    /// (kflex-model's `Roi`); all four fields required.
    PyRoi, "Roi", Roi, {
        /// The whole of a `width × height` image.
        #[staticmethod]
        fn whole(width: Int, height: Int) -> Result<Self> {
            let (width, height) = (unsigned("width", width)?, unsigned("height", height)?);
            let roi = Roi::whole(width, height);
            // as `Roi(...)` refuses: a region holds at least one pixel
            roi.check_within(width, height)?;
            Ok(roi.into())
        }

        /// The working region of the paper's operating range (θ in [0, 50]
        /// deg at d = 10 mm) for `camera`.
        #[staticmethod]
        fn paper(py: Python<'_>, camera: PyRef<'_, PyCamera>) -> Result<Self> {
            let camera = camera.inner;
            Ok(py.detach(|| Roi::paper(&camera))?.into())
        }

        /// The smallest region of `camera`'s image holding the joint and
        /// gripper of `instrument` over `poses`, plus `margin_px` (px).
        #[staticmethod]
        fn for_workspace(py: Python<'_>, camera: PyRef<'_, PyCamera>, instrument: PyRef<'_, PyInstrument>, poses: PyPoseRange, margin_px: Int) -> Result<Self> {
            let margin_px = unsigned("margin_px", margin_px)?;
            let (camera, instrument) = (camera.inner, instrument.inner);
            Ok(py.detach(|| Roi::for_workspace(&camera, &instrument, &poses.inner, margin_px))?.into())
        }

        /// Whether `inner` lies inside this region.
        fn holds(&self, inner: PyRoi) -> bool {
            self.inner.holds(&inner.inner)
        }

        /// Checks that the region is not empty and lies inside a
        /// `width × height` image; raises `RangeError`.
        fn check_within(&self, width: Int, height: Int) -> Result<()> {
            let (width, height) = (unsigned("width", width)?, unsigned("height", height)?);
            Ok(self.inner.check_within(width, height)?)
        }

        /// Number of pixels.
        fn area(&self) -> u64 {
            self.inner.area()
        }
    }
);

serde_class!(
    /// The poses a working region covers (kflex-model's `PoseRange`):
    /// `theta_deg` [from, to] (deg), `translation_mm` [from, to] (mm).
    PyPoseRange, "PoseRange", PoseRange, {
        /// The paper's range: θ in [0, 50] deg at d = 10 mm.
        #[staticmethod]
        fn paper() -> Self {
            PoseRange::PAPER.into()
        }

        /// The default camera's full range: θ in [-90, 90] deg, d in [8, 40] mm.
        #[staticmethod]
        fn full() -> Self {
            PoseRange::FULL.into()
        }

        /// Whether the pose (deg, mm) lies in the range, ends included.
        fn contains(&self, theta_deg: f64, translation_mm: f64) -> bool {
            self.inner.contains(theta_deg, translation_mm)
        }
    }
);

serde_class!(
    /// How `WorkingRegions.for_workspace` cuts a pose range into bands
    /// (kflex-model's `Banding`): `margin_px`, `growth`, `theta_parts`,
    /// `theta_overlap_deg`.
    PyBanding, "Banding", Banding, {}
);

serde_class!(
    /// One band of `WorkingRegions` (kflex-model's `WorkingBand`): `poses`
    /// and `roi` (read as `dict`s).
    PyWorkingBand, "WorkingBand", WorkingBand, {
        /// The band's region as a `Roi`.
        #[getter]
        fn region(&self) -> PyRoi {
            self.inner.roi.into()
        }
    }
);

serde_class!(
    /// Shape parameters of the instrument (kflex-model's `InstrumentParams`): mm, deg.
    PyInstrumentParams, "InstrumentParams", InstrumentParams, {}
);

serde_class!(
    /// Manufacturing and mounting tolerances (kflex-model's
    /// `BuildTolerances`): the reality gap between the simulated robot and
    /// the nominal model. Relative tolerances dimensionless, deg, mm, px.
    PyBuildTolerances, "BuildTolerances", BuildTolerances, {
        /// No tolerances: the as-built instrument and camera are the nominal ones.
        #[staticmethod]
        fn none() -> Self {
            BuildTolerances::NONE.into()
        }

        /// Checks every tolerance; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }

        /// `nominal` as built, its links drawn with `seed`.
        fn instrument(&self, nominal: PyRef<'_, PyInstrument>, seed: Int) -> Result<PyBuiltInstrument> {
            let seed = unsigned("seed", seed)?;
            Ok(PyBuiltInstrument { inner: self.inner.instrument(&nominal.inner, seed)? })
        }

        /// `nominal` as mounted and calibrated, drawn with `seed`.
        fn camera(&self, nominal: PyRef<'_, PyCamera>, seed: Int) -> Result<PyCamera> {
            let seed = unsigned("seed", seed)?;
            Ok(PyCamera { inner: self.inner.camera(&nominal.inner, seed)? })
        }
    }
);

/// The endoscope camera (kflex-model's `Camera`): intrinsics, lens, and
/// `camera_from_overtube`, the rigid transform from the overtube's frame to
/// the camera's (mm). `intrinsics` and `lens` read as copies: assign one to
/// change it.
#[pyclass(name = "Camera", module = "kflex", eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyCamera {
    pub(crate) inner: Camera,
}

impl PyCamera {
    /// Takes `next` where it is valid, else stays as it is (`RangeError`).
    fn replace(&mut self, next: Camera) -> Result<()> {
        next.validate()?;
        self.inner = next;
        Ok(())
    }
}

#[pymethods]
impl PyCamera {
    /// At the centre of the overtube's face, looking along it; the default
    /// intrinsics and lens unless given. Raises `RangeError` naming the
    /// first parameter out of its range.
    #[new]
    #[pyo3(signature = (intrinsics = None, lens = None))]
    fn py_new(intrinsics: Option<PyIntrinsics>, lens: Option<PyLens>) -> Result<Self> {
        let mut inner = Camera::default();
        if let Some(k) = intrinsics {
            inner.intrinsics = k.inner;
        }
        if let Some(l) = lens {
            inner.lens = l.inner;
        }
        inner.validate()?;
        Ok(Self { inner })
    }

    /// Intrinsics (a copy).
    #[getter]
    fn intrinsics(&self) -> PyIntrinsics {
        self.inner.intrinsics.into()
    }

    /// Raises `RangeError` (the camera unchanged) for intrinsics out of range.
    #[setter]
    fn set_intrinsics(&mut self, k: PyIntrinsics) -> Result<()> {
        self.replace(Camera {
            intrinsics: k.inner,
            ..self.inner
        })
    }

    /// Lens (a copy).
    #[getter]
    fn lens(&self) -> PyLens {
        self.inner.lens.into()
    }

    /// Raises `RangeError` (the camera unchanged) for a lens out of range.
    #[setter]
    fn set_lens(&mut self, lens: PyLens) -> Result<()> {
        self.replace(Camera {
            lens: lens.inner,
            ..self.inner
        })
    }

    /// `camera_from_overtube` as a 4×4 homogeneous matrix (mm).
    #[getter]
    fn camera_from_overtube(&self) -> [[f64; 4]; 4] {
        let m = self.inner.camera_from_overtube.to_homogeneous();
        std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
    }

    /// Checks the intrinsics, then the lens; raises `RangeError`.
    fn validate(&self) -> Result<()> {
        Ok(self.inner.validate()?)
    }

    /// Pixel `[u, v]` of a point in the overtube frame (mm), or None behind the camera.
    fn project(&self, p_overtube_mm: [f64; 3]) -> Option<[f64; 2]> {
        self.inner.project(p_overtube_mm)
    }

    /// The ray through pixel position `(u, v)` in the camera frame (`z = 1`).
    /// Raises `ValueError` for a position that is not finite, or one so
    /// far outside the image that the lens model cannot bend it (`1 + λ r²
    /// ≤ 0`).
    fn ray_direction(&self, u: f64, v: f64) -> Result<[f64; 3]> {
        finite(["u", "v"], [u, v])?;
        let k = &self.inner.intrinsics;
        within_lens(&self.inner.lens, (u - k.cx) / k.fx, (v - k.cy) / k.fy)?;
        Ok(self.inner.ray_direction(u, v))
    }

    /// The lens's relative illumination at pixel position `(u, v)`. Raises
    /// `ValueError` for a position that is not finite.
    fn illumination(&self, u: f64, v: f64) -> Result<f64> {
        finite(["u", "v"], [u, v])?;
        let light = self.inner.illumination(u, v);
        if !light.is_finite() {
            // so far out that r² overflows
            return Err(Error::Py(pyo3::exceptions::PyValueError::new_err(format!(
                "pixel position ({u:e}, {v:e}) is too far outside the image for the lens model"
            ))));
        }
        Ok(light)
    }

    /// The same camera with other intrinsics (e.g. a region's). Raises
    /// `RangeError` where the intrinsics, or the lens with them, are out of
    /// range (as `validate` does).
    fn with_intrinsics(&self, intrinsics: PyIntrinsics) -> Result<Self> {
        let camera = self.inner.with_intrinsics(intrinsics.inner);
        camera.validate()?;
        Ok(Self { inner: camera })
    }

    fn __repr__(&self) -> String {
        let k = &self.inner.intrinsics;
        format!(
            "Camera({}x{}, fx={}, lens={:?})",
            k.width, k.height, k.fx, self.inner.lens
        )
    }
}

/// The instrument's geometry (kflex-model's `Instrument`).
#[pyclass(name = "Instrument", module = "kflex")]
#[derive(Debug, Clone)]
pub struct PyInstrument {
    pub(crate) inner: Instrument,
}

#[pymethods]
impl PyInstrument {
    /// A validated instrument; raises `RangeError` for a parameter out of range.
    #[new]
    fn py_new(
        joint: PyJointParams,
        params: PyInstrumentParams,
        n_segments: Int,
        translation: PyTranslationParams,
    ) -> Result<Self> {
        let n_segments = unsigned("n_segments", n_segments)?;
        Ok(Self {
            inner: Instrument::new(joint.inner, params.inner, n_segments, translation.inner)?,
        })
    }

    /// The default K-FLEX-scale instrument (the plant's defaults).
    #[staticmethod]
    fn kflex() -> Self {
        Self {
            inner: Instrument::kflex(),
        }
    }

    /// The shape at bend `theta_deg` (deg) and translation `translation_mm`
    /// (mm); raises `RangeError` outside the workspace.
    fn shape(&self, theta_deg: f64, translation_mm: f64) -> Result<PyInstrumentShape> {
        Ok(PyInstrumentShape {
            inner: self.inner.shape(theta_deg, translation_mm)?,
        })
    }
}

/// `BuildTolerances.instrument`'s as-built instrument (kflex-model's `BuiltInstrument`).
#[pyclass(name = "BuiltInstrument", module = "kflex")]
pub struct PyBuiltInstrument {
    inner: BuiltInstrument,
}

#[pymethods]
impl PyBuiltInstrument {
    /// The as-built shape at bend `theta_deg` (deg) and translation
    /// `translation_mm` (mm); raises `RangeError` outside the workspace.
    fn shape(&self, theta_deg: f64, translation_mm: f64) -> Result<PyInstrumentShape> {
        Ok(PyInstrumentShape {
            inner: self.inner.shape(theta_deg, translation_mm)?,
        })
    }
}

/// The instrument's bodies at one pose (kflex-model's `InstrumentShape`),
/// in the overtube frame, mm.
#[pyclass(name = "InstrumentShape", module = "kflex")]
pub struct PyInstrumentShape {
    pub(crate) inner: InstrumentShape,
}

#[pymethods]
impl PyInstrumentShape {
    /// The tool tip, mm.
    #[getter]
    fn tip_mm(&self) -> [f64; 3] {
        self.inner.tip_mm
    }

    /// Number of bodies (discs, backbone, clevis, pin, jaws…).
    fn __len__(&self) -> usize {
        self.inner.bodies.len()
    }

    /// The translation the shape was built at, mm.
    fn translation_mm(&self) -> f64 {
        self.inner.translation_mm()
    }

    /// The bend the shape shows, deg.
    fn bend_deg(&self) -> f64 {
        self.inner.bend_deg()
    }
}

/// Working regions over a pose range, one per band of it (kflex-model's `WorkingRegions`).
#[pyclass(name = "WorkingRegions", module = "kflex")]
pub struct PyWorkingRegions {
    inner: WorkingRegions,
}

#[pymethods]
impl PyWorkingRegions {
    /// The default working regions of `camera` (the K-FLEX instrument over
    /// the full range, default banding). Runs without the interpreter lock.
    #[staticmethod]
    fn full(py: Python<'_>, camera: PyRef<'_, PyCamera>) -> Result<Self> {
        let camera = camera.inner;
        Ok(Self {
            inner: py.detach(|| WorkingRegions::full(&camera))?,
        })
    }

    /// Bands of `poses` for `camera` and `instrument`, cut as `banding` says.
    #[staticmethod]
    fn for_workspace(
        py: Python<'_>,
        camera: PyRef<'_, PyCamera>,
        instrument: PyRef<'_, PyInstrument>,
        poses: PyPoseRange,
        banding: PyBanding,
    ) -> Result<Self> {
        let (camera, instrument) = (camera.inner, instrument.inner);
        Ok(Self {
            inner: py.detach(|| {
                WorkingRegions::for_workspace(&camera, &instrument, &poses.inner, &banding.inner)
            })?,
        })
    }

    /// The poses the regions cover.
    #[getter]
    fn poses(&self) -> PyPoseRange {
        (*self.inner.poses()).into()
    }

    /// The bands, by part of the bend range, nearest first.
    #[getter]
    fn bands(&self) -> Vec<PyWorkingBand> {
        self.inner.bands().iter().map(|b| (*b).into()).collect()
    }

    /// The band for the pose (deg, mm); raises `RangeError` outside the range.
    fn at(&self, theta_deg: f64, translation_mm: f64) -> Result<PyWorkingBand> {
        Ok((*self.inner.at(theta_deg, translation_mm)?).into())
    }

    /// The band for the pose clamped into the range (None if there is none).
    /// Raises `ValueError` for a value that is not finite (no clamp places it).
    fn nearest(&self, theta_deg: f64, translation_mm: f64) -> Result<Option<PyWorkingBand>> {
        finite(["theta_deg", "translation_mm"], [theta_deg, translation_mm])?;
        Ok(self
            .inner
            .nearest(theta_deg, translation_mm)
            .map(|b| (*b).into()))
    }
}
