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
    /// `fy` outside `[0.001, 1e6)` px, `cx` or `cy` outside `[-1e7, 1e7]` px;
    /// [`ModelError::NonFinite`] for a NaN or infinite `cx` or `cy`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn validate(&self) -> Result<()> {
        crate::range::check_image_size(self.width, self.height)?;
        // a focal length below a thousandth of a pixel, or a centre far off
        // the image, sends every ray to infinity
        Bounds::closed_open(1e-3, 1e6).check("fx", self.fx)?;
        Bounds::closed_open(1e-3, 1e6).check("fy", self.fy)?;
        crate::error::finite("cx", self.cx)?;
        crate::error::finite("cy", self.cy)?;
        Bounds::closed(-1e7, 1e7).check("cx", self.cx)?;
        Bounds::closed(-1e7, 1e7).check("cy", self.cy)?;
        Ok(())
    }

    /// The camera that sees the region `[x0, x0+w) × [y0, y0+h)` of this one's image
    /// resampled to `out_w × out_h` (a region of interest, e.g. IBJAE's 48×48).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `roi width` or `roi height` when it is
    /// outside `(0, 1e6)` px (an empty or huge region), `image width` or
    /// `image height` for an output size out of `[1, MAX_IMAGE_SIDE]`, `fx`
    /// or `fy` when the rescaled focal length leaves `[0.001, 1e6)` px, `cx`
    /// or `cy` when the rescaled centre leaves `[-1e7, 1e7]` px (as
    /// [`Intrinsics::validate`]); [`ModelError::NonFinite`] naming `cx` or
    /// `cy` for a NaN or infinite `x0` or `y0`.
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

/// The lens of a wide-angle endoscope: barrel distortion and vignetting.
///
/// Distortion follows the one-parameter division model (Fitzgibbon, CVPR
/// 2001), common for endoscopes because it is inverted in closed form. In
/// normalised image coordinates `x_d = (u − c_x)/f_x`, `y_d = (v − c_y)/f_y`,
/// a pixel at radius `r_d` sees the pinhole direction
/// `(x_u, y_u) = (x_d, y_d) / (1 + λ r_d²)` (the ray `(x_u, y_u, 1)`);
/// `λ < 0` is barrel distortion. The inverse (projection) is
/// `r_d = 2 r_u / (1 + √(1 − 4 λ r_u²))`. A region of interest keeps the
/// normalised coordinates ([`Intrinsics::region`]), so one `λ` serves the
/// full frame and every region of it.
///
/// Vignetting scales the light reaching the sensor by `(1 + κ r_d²)^−2`.
///
/// Defaults (`λ = −0.15`, `κ = 0.2`): the default 640×480 camera
/// ([`Intrinsics::default`]) then sees 113° across and 132° on the diagonal,
/// as wide-angle endoscopes do (120–140° diagonal is typical), with the
/// corners at 48 % of the centre's illumination.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Lens {
    /// Division-model coefficient `λ` (dimensionless, on normalised
    /// coordinates); 0 for a pinhole, negative for barrel distortion.
    pub division: f64,
    /// Vignetting coefficient `κ`; 0 for none.
    pub vignetting: f64,
}

impl Default for Lens {
    fn default() -> Self {
        Self {
            division: -0.15,
            vignetting: 0.2,
        }
    }
}

/// Smallest `1 + λ r_d²` anywhere in an image: keeps every pixel's ray well
/// inside the forward half-space (a field of view below 180°).
const MIN_DIVISION_FACTOR: f64 = 0.2;

impl Lens {
    /// An ideal pinhole: no distortion, no vignetting.
    pub const PINHOLE: Lens = Lens {
        division: 0.0,
        vignetting: 0.0,
    };

    /// Checks the coefficients for an image with intrinsics `k`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `lens.division` when it is outside
    /// `[λ_min, 0]`, where `λ_min` keeps `1 + λ r_d² ≥ 0.2` at the image's
    /// corners (so every pixel's ray points forward), or `lens.vignetting`
    /// outside `[0, 10]`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self, k: &Intrinsics) -> Result<()> {
        let corner = |u: f64, v: f64| {
            let (x, y) = ((u - k.cx) / k.fx, (v - k.cy) / k.fy);
            x * x + y * y
        };
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        let r2 = corner(0.0, 0.0)
            .max(corner(w, 0.0))
            .max(corner(0.0, h))
            .max(corner(w, h));
        let lowest = if r2 > 0.0 {
            -(1.0 - MIN_DIVISION_FACTOR) / r2
        } else {
            -1.0
        };
        // the least value depends on the intrinsics: a principal point moved
        // towards one side (cx, cy) or a shorter focal length puts the
        // farthest corner farther out, so say so where it was set
        Bounds::closed(lowest, 0.0).check(
            "lens.division (its least value set by the intrinsics: the image corner \
             farthest from the principal point cx, cy, in focal lengths)",
            self.division,
        )?;
        Bounds::closed(0.0, 10.0).check("lens.vignetting", self.vignetting)?;
        Ok(())
    }

    /// The pinhole direction `(x_u, y_u)` seen at normalised distorted coordinates `(x_d, y_d)`.
    #[inline]
    #[must_use]
    pub fn undistort(&self, xd: f64, yd: f64) -> [f64; 2] {
        let s = 1.0 / (1.0 + self.division * (xd * xd + yd * yd));
        [xd * s, yd * s]
    }

    /// Normalised distorted coordinates of the pinhole direction `(x_u, y_u)`.
    #[inline]
    #[must_use]
    pub fn distort(&self, xu: f64, yu: f64) -> [f64; 2] {
        let ru2 = xu * xu + yu * yu;
        let s = 2.0 / (1.0 + (1.0 - 4.0 * self.division * ru2).max(0.0).sqrt());
        [xu * s, yu * s]
    }

    /// Relative illumination at normalised distorted coordinates `(x_d, y_d)`, in (0, 1].
    #[inline]
    #[must_use]
    pub fn illumination(&self, xd: f64, yd: f64) -> f64 {
        let q = 1.0 + self.vignetting * (xd * xd + yd * yd);
        1.0 / (q * q)
    }
}

/// A camera: intrinsics, lens and where it sits relative to the overtube.
///
/// Pixel convention: pixel `(i, j)` covers `[i, i+1) × [j, j+1)` and its centre is
/// `(i + 0.5, j + 0.5)`; a point `(x, y, z)` in the camera frame (x right, y down,
/// z forward, mm) has the pinhole direction `(x/z, y/z)`, which the lens
/// ([`Lens`]) bends to `(x_d, y_d)`, at pixel `u = f_x x_d + c_x`,
/// `v = f_y y_d + c_y`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Intrinsics.
    pub intrinsics: Intrinsics,
    /// Lens distortion and vignetting.
    pub lens: Lens,
    /// Maps overtube coordinates to camera coordinates (mm).
    pub camera_from_overtube: Isometry3<f64>,
}

impl Default for Camera {
    /// At the centre of the overtube's face, looking along it, with the default lens.
    fn default() -> Self {
        Self {
            intrinsics: Intrinsics::default(),
            lens: Lens::default(),
            camera_from_overtube: Isometry3::identity(),
        }
    }
}

impl Camera {
    /// Checks the intrinsics, then the lens for them, then the mounting.
    ///
    /// # Errors
    /// As [`Intrinsics::validate`], then [`Lens::validate`]; then
    /// [`ModelError::NonFinite`](crate::ModelError::NonFinite) naming `camera_from_overtube` for a NaN or
    /// infinite entry of the mounting.
    pub fn validate(&self) -> Result<()> {
        self.intrinsics.validate()?;
        self.lens.validate(&self.intrinsics)?;
        let m = self.camera_from_overtube.to_homogeneous();
        if let Some(&bad) = m.iter().find(|v| !v.is_finite()) {
            return Err(crate::ModelError::NonFinite {
                name: "camera_from_overtube",
                value: bad,
            });
        }
        Ok(())
    }

    /// Projects a point given in the overtube frame; `None` if it is not in front of the camera.
    #[must_use]
    pub fn project(&self, p_overtube: [f64; 3]) -> Option<[f64; 2]> {
        let p = self.camera_from_overtube * Point3::from(p_overtube);
        (p.z > 1e-9).then(|| {
            let k = &self.intrinsics;
            let [xd, yd] = self.lens.distort(p.x / p.z, p.y / p.z);
            [k.fx * xd + k.cx, k.fy * yd + k.cy]
        })
    }

    /// The ray through pixel position `(u, v)` in the camera frame
    /// (unnormalised direction, `z = 1`).
    #[inline]
    #[must_use]
    pub fn ray_direction(&self, u: f64, v: f64) -> [f64; 3] {
        let k = &self.intrinsics;
        let [x, y] = self.lens.undistort((u - k.cx) / k.fx, (v - k.cy) / k.fy);
        [x, y, 1.0]
    }

    /// The lens's relative illumination at pixel position `(u, v)`.
    #[must_use]
    pub fn illumination(&self, u: f64, v: f64) -> f64 {
        let k = &self.intrinsics;
        self.lens.illumination((u - k.cx) / k.fx, (v - k.cy) / k.fy)
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
