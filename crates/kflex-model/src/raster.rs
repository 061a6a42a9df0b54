//! Software rasterizer: binary silhouettes of the instrument.

use crate::camera::{Camera, Intrinsics};
use crate::error::{ModelError, Result};
use crate::instrument::InstrumentShape;
use crate::mask::Mask;
use nalgebra::{Point3, Vector3};

/// Sides of the prism that stands for each cylinder.
const CYLINDER_SIDES: usize = 16;
/// Near clipping distance, mm: geometry closer to the camera is not drawn.
const Z_NEAR: f64 = 0.5;

/// Reusable rasterizer state.
///
/// Each capsule is drawn as its cylinder — a prism of 16 sides
/// whose cross-section has the circle's area — plus its end spheres, which are
/// filled exactly (a pixel is inside where the ray through its centre meets the
/// sphere). Triangles are clipped 0.5 mm in front of the camera and filled where the pixel
/// centre lies inside or on their edges. No GPU, no allocation per frame once
/// the [`Rasterizer`]'s buffers have grown.
#[derive(Debug, Default, Clone)]
pub struct Rasterizer {
    triangles: Vec<[Vector3<f64>; 3]>,
}

impl Rasterizer {
    /// A rasterizer with empty buffers.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Draws the silhouette of `shape` seen by `camera` into `mask` (which must have the
    /// camera's size); pixels already set stay set.
    ///
    /// # Errors
    /// [`ModelError::ImageSize`] when `mask` is not the camera's
    /// `width × height`; nothing is drawn then.
    pub fn silhouette(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        mask: &mut Mask,
    ) -> Result<()> {
        let k = &camera.intrinsics;
        if (mask.width(), mask.height()) != (k.width, k.height) {
            return Err(ModelError::ImageSize {
                what: "mask for this camera",
                width: k.width,
                height: k.height,
                expected: k.width as usize * k.height as usize,
                got: mask.data().len(),
            });
        }
        let area_radius = ((std::f64::consts::TAU / CYLINDER_SIDES as f64)
            / (std::f64::consts::TAU / CYLINDER_SIDES as f64).sin())
        .sqrt();
        for c in &shape.capsules {
            let a = (camera.camera_from_overtube * Point3::from(c.a_mm)).coords;
            let b = (camera.camera_from_overtube * Point3::from(c.b_mm)).coords;
            self.triangles.clear();
            prism(a, b, c.radius_mm * area_radius, &mut self.triangles);
            for tri in &self.triangles {
                fill_clipped(camera, tri, mask);
            }
            if c.cap_a {
                fill_sphere(camera, a, c.radius_mm, mask);
            }
            fill_sphere(camera, b, c.radius_mm, mask);
        }
        Ok(())
    }
}

/// Side triangles of a prism of radius `r` around segment `a`–`b`.
fn prism(a: Vector3<f64>, b: Vector3<f64>, r: f64, out: &mut Vec<[Vector3<f64>; 3]>) {
    let axis = b - a;
    if axis.norm() < 1e-12 {
        return; // a sphere only
    }
    let dir = axis.normalize();
    let helper = if dir.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = dir.cross(&helper).normalize();
    let w = dir.cross(&u);
    let ring = |k: usize| {
        let t = std::f64::consts::TAU * k as f64 / CYLINDER_SIDES as f64;
        (u * t.cos() + w * t.sin()) * r
    };
    let mut prev = ring(0);
    for k in 1..=CYLINDER_SIDES {
        let next = ring(k % CYLINDER_SIDES);
        out.push([a + prev, b + prev, b + next]);
        out.push([a + prev, b + next, a + next]);
        prev = next;
    }
}

/// Clips a camera-frame triangle at `z = Z_NEAR` and fills what is left.
fn fill_clipped(camera: &Camera, tri: &[Vector3<f64>; 3], mask: &mut Mask) {
    let inside = tri.map(|p| p.z >= Z_NEAR);
    if inside.iter().all(|&i| i) {
        fill_triangle(camera, tri, mask);
        return;
    }
    if !inside.iter().any(|&i| i) {
        return;
    }
    // Sutherland–Hodgman against one plane: at most four vertices
    let mut poly = [Vector3::zeros(); 4];
    let mut n = 0;
    for i in 0..3 {
        let (p, q) = (tri[i], tri[(i + 1) % 3]);
        let (ip, iq) = (inside[i], inside[(i + 1) % 3]);
        if ip {
            poly[n] = p;
            n += 1;
        }
        if ip != iq {
            let t = (Z_NEAR - p.z) / (q.z - p.z);
            poly[n] = p + (q - p) * t;
            n += 1;
        }
    }
    for i in 1..n.saturating_sub(1) {
        fill_triangle(camera, &[poly[0], poly[i], poly[i + 1]], mask);
    }
}

fn fill_triangle(camera: &Camera, tri: &[Vector3<f64>; 3], mask: &mut Mask) {
    let k = &camera.intrinsics;
    let proj = tri.map(|p| [k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy]);
    let [p0, p1, p2] = proj;
    let area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]);
    // back faces of the prism project inside its front faces and the end spheres: skip them
    if area.is_nan() || area <= 1e-12 {
        return;
    }
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let y_lo = proj
        .iter()
        .map(|p| p[1])
        .fold(f64::MAX, f64::min)
        .floor()
        .max(0.0);
    let y_hi = proj
        .iter()
        .map(|p| p[1])
        .fold(f64::MIN, f64::max)
        .ceil()
        .min(h);
    if y_lo >= y_hi {
        return;
    }
    // edge functions a x + b y + c ≥ 0 inside
    let edge = |p: [f64; 2], q: [f64; 2]| {
        let (ea, eb) = (p[1] - q[1], q[0] - p[0]);
        (ea, eb, -(ea * p[0] + eb * p[1]))
    };
    let edges = [edge(p0, p1), edge(p1, p2), edge(p2, p0)];
    for y in y_lo as usize..y_hi as usize {
        let yc = y as f64 + 0.5;
        // the span of pixel centres x + 0.5 inside all three half-planes on this row
        let (mut x_min, mut x_max) = (0.0f64, w);
        for &(ea, eb, ec) in &edges {
            let rest = eb * yc + ec; // ea x + rest ≥ 0
            if ea > 0.0 {
                x_min = x_min.max(-rest / ea);
            } else if ea < 0.0 {
                x_max = x_max.min(-rest / ea);
            } else if rest < 0.0 {
                x_max = -1.0;
            }
        }
        // pixel x is inside iff x_min ≤ x + 0.5 ≤ x_max
        let first = (x_min - 0.5).ceil().max(0.0);
        let last = (x_max - 0.5).floor().min(w - 1.0);
        if first <= last {
            let row = y * k.width as usize;
            mask.fill_span(row + first as usize, row + last as usize);
        }
    }
}

/// Fills the pixels whose centre ray meets the sphere (camera frame, mm).
/// Pixel box `[u_min, v_min, u_max, v_max]` of a sphere (centre `c` in the
/// camera frame, radius `r`, mm) under intrinsics `k`: along each image axis,
/// where the planes through the centre of projection touch the sphere (the
/// tangent lines of its disc in the (axis, z) plane). `None` where the
/// sphere reaches the camera's plane, so that no finite box holds it.
pub(crate) fn sphere_extent(k: &Intrinsics, c: Vector3<f64>, r: f64) -> Option<[f64; 4]> {
    let along = |x: f64, f: f64, centre: f64| -> Option<(f64, f64)> {
        let rho = x.hypot(c.z);
        if rho <= r {
            return None;
        }
        let (alpha, delta) = (x.atan2(c.z), (r / rho).asin());
        let (lo, hi) = (alpha - delta, alpha + delta);
        let limit = std::f64::consts::FRAC_PI_2 - 1e-9;
        if lo <= -limit || hi >= limit {
            return None;
        }
        Some((centre + f * lo.tan(), centre + f * hi.tan()))
    };
    let (u0, u1) = along(c.x, k.fx, k.cx)?;
    let (v0, v1) = along(c.y, k.fy, k.cy)?;
    Some([u0, v0, u1, v1])
}

fn fill_sphere(camera: &Camera, c: Vector3<f64>, r: f64, mask: &mut Mask) {
    if c.z + r < Z_NEAR {
        return;
    }
    let k = &camera.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let [x_lo, y_lo, x_hi, y_hi] = match sphere_extent(k, c, r) {
        Some([u0, v0, u1, v1]) => [
            u0.floor().max(0.0),
            v0.floor().max(0.0),
            u1.ceil().min(w),
            v1.ceil().min(h),
        ],
        None => [0.0, 0.0, w, h],
    };
    let (cc, rr) = (c.norm_squared(), r * r);
    for y in y_lo as usize..y_hi.max(y_lo) as usize {
        let dy = (y as f64 + 0.5 - k.cy) / k.fy;
        for x in x_lo as usize..x_hi.max(x_lo) as usize {
            let dx = (x as f64 + 0.5 - k.cx) / k.fx;
            // ray d = (dx, dy, 1): hits iff |c|² − (c·d)²/|d|² ≤ r² with c·d > 0
            let cd = c.x * dx + c.y * dy + c.z;
            let dd = dx * dx + dy * dy + 1.0;
            if cd > 0.0 && cc - cd * cd / dd <= rr {
                mask.set(x, y);
            }
        }
    }
}
