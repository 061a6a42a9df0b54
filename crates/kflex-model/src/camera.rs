//! Pinhole camera of the endoscope.

use nalgebra::{Isometry3, Point3};
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::range::Bounds;

/// Intrinsics of a pinhole camera, pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Focal length along x, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
}

impl Default for Intrinsics {
    /// 640×480 with a 100 deg horizontal field of view (a wide endoscope).
    fn default() -> Self {
        Self::from_fov(640, 480, 100.0).unwrap_or(Self {
            width: 640,
            height: 480,
            fx: 268.5,
            fy: 268.5,
            cx: 320.0,
            cy: 240.0,
        })
    }
}

impl Intrinsics {
    /// Square pixels, centred principal point, horizontal field of view `hfov_deg`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `hfov_deg` when it is outside
    /// `(1, 179)` deg, or `image width` / `image height` when a side is outside
    /// `[1, MAX_IMAGE_SIDE]`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn from_fov(width: u32, height: u32, hfov_deg: f64) -> Result<Self> {
        Bounds::open(1.0, 179.0).check("hfov_deg", hfov_deg)?;
        let f = 0.5 * f64::from(width) / (0.5 * hfov_deg.to_radians()).tan();
        let out = Self {
            width,
            height,
            fx: f,
            fy: f,
            cx: 0.5 * f64::from(width),
            cy: 0.5 * f64::from(height),
        };
        out.validate()?;
        Ok(out)
    }

    /// The paper's camera: 1920×1080, same field of view as the default.
    #[must_use]
    pub fn full_hd() -> Self {
        Self::from_fov(1920, 1080, 100.0).unwrap_or(Self {
            width: 1920,
            height: 1080,
            fx: 805.5,
            fy: 805.5,
            cx: 960.0,
            cy: 540.0,
        })
    }

    /// Checks sizes and focal lengths.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first quantity out of its range:
    /// `image width` or `image height` outside `[1, MAX_IMAGE_SIDE]`, `fx` or
    /// `fy` outside `(0, 1e6)` px; [`ModelError::NonFinite`] for a NaN or
    /// infinite `cx` or `cy`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn validate(&self) -> Result<()> {
        crate::range::check_image_size(self.width, self.height)?;
        Bounds::open(0.0, 1e6).check("fx", self.fx)?;
        Bounds::open(0.0, 1e6).check("fy", self.fy)?;
        crate::error::finite("cx", self.cx)?;
        crate::error::finite("cy", self.cy)?;
        Ok(())
    }

    /// The camera that sees the region `[x0, x0+w) × [y0, y0+h)` of this one's image
    /// resampled to `out_w × out_h` (a region of interest, e.g. IBJAE's 48×48).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `roi width` or `roi height` when it is
    /// outside `(0, 1e6)` px (an empty or huge region), `image width` or
    /// `image height` for an output size out of `[1, MAX_IMAGE_SIDE]`, or `fx`
    /// or `fy` when the rescaled focal length leaves `(0, 1e6)` px;
    /// [`ModelError::NonFinite`] naming `cx` or `cy` for a NaN or infinite `x0`
    /// or `y0`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn region(&self, x0: f64, y0: f64, w: f64, h: f64, out_w: u32, out_h: u32) -> Result<Self> {
        Bounds::open(0.0, 1e6).check("roi width", w)?;
        Bounds::open(0.0, 1e6).check("roi height", h)?;
        let (sx, sy) = (f64::from(out_w) / w, f64::from(out_h) / h);
        let out = Self {
            width: out_w,
            height: out_h,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx - x0) * sx,
            cy: (self.cy - y0) * sy,
        };
        out.validate()?;
        Ok(out)
    }
}

/// A camera: intrinsics and where it sits relative to the overtube.
///
/// Pixel convention: pixel `(i, j)` covers `[i, i+1) × [j, j+1)` and its centre is
/// `(i + 0.5, j + 0.5)`; a point `(x, y, z)` in the camera frame (x right, y down,
/// z forward, mm) projects to `u = f_x x/z + c_x`, `v = f_y y/z + c_y`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics.
    pub intrinsics: Intrinsics,
    /// Maps overtube coordinates to camera coordinates (mm).
    pub camera_from_overtube: Isometry3<f64>,
}

impl Default for Camera {
    /// At the centre of the overtube's face, looking along it.
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::default(),
            camera_from_overtube: Isometry3::identity(),
        }
    }
}

impl Camera {
    /// Projects a point given in the overtube frame; `None` if it is not in front of the camera.
    #[must_use]
    pub fn project(&self, p_overtube: [f64; 3]) -> Option<[f64; 2]> {
        let p = self.camera_from_overtube * Point3::from(p_overtube);
        (p.z > 1e-9).then(|| {
            let k = &self.intrinsics;
            [k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy]
        })
    }

    /// The ray through pixel position `(u, v)` in the camera frame (unnormalised direction).
    #[must_use]
    pub fn ray_direction(&self, u: f64, v: f64) -> [f64; 3] {
        let k = &self.intrinsics;
        [(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0]
    }

    /// The same camera with other intrinsics (e.g. a region of interest).
    #[must_use]
    pub fn with_intrinsics(&self, intrinsics: Intrinsics) -> Self {
        Self {
            intrinsics,
            ..*self
        }
    }
}
