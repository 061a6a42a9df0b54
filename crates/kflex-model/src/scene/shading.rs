//! Shading the instrument: the exact surface point behind every silhouette
//! pixel (closed-form ray–capsule hits), Lambert plus a Blinn–Phong
//! highlight from the light at the camera, and the tape band along the
//! instrument's arc length.

use nalgebra::Vector3;

use super::Occlusion;
use crate::camera::Camera;
use crate::instrument::{Capsule, InstrumentShape, Part};
use crate::mask::Mask;

/// Base colour of the instrument's metal, linear RGB in [0, 1].
pub(super) const METAL: [f32; 3] = [0.62, 0.64, 0.68];
/// Base colour of the tape.
pub(super) const TAPE: [f32; 3] = [0.50, 0.04, 0.05];

/// One silhouette pixel, shaded.
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    /// Index of the pixel, row-major.
    pub(super) pixel: usize,
    /// Arc length along the instrument where the ray meets it, mm.
    pub(super) arc_mm: f32,
    /// Diffuse shade, with the light's falloff.
    pub(super) diffuse: f32,
    /// Specular highlight, with the light's falloff.
    pub(super) specular: f32,
}

/// Shades every pixel set in `silhouette` (of `camera`'s size) from the
/// surface point of `shape` its ray meets first, into `hits` (cleared first).
pub(super) fn shade(
    camera: &Camera,
    shape: &InstrumentShape,
    silhouette: &Mask,
    hits: &mut Vec<Hit>,
) {
    hits.clear();
    let w = camera.intrinsics.width as usize;
    let lengths = arc_starts(shape);
    // capsules in the camera frame, each with the pixel box its projection can cover
    let caps: Vec<CameraCapsule> = shape
        .capsules
        .iter()
        .map(|c| {
            let a = (camera.camera_from_overtube * nalgebra::Point3::from(c.a_mm)).coords;
            let b = (camera.camera_from_overtube * nalgebra::Point3::from(c.b_mm)).coords;
            CameraCapsule::new(a, b, c.radius_mm, screen_box(camera, a, b, c.radius_mm))
        })
        .collect();
    let mut row_caps: Vec<(usize, &CameraCapsule)> = Vec::with_capacity(caps.len());
    for (y, row) in silhouette.data().chunks_exact(w).enumerate() {
        let py = y as f64 + 0.5;
        // the capsules whose screen box meets this row
        row_caps.clear();
        row_caps.extend(
            caps.iter()
                .enumerate()
                .filter(|(_, c)| py >= c.screen[2] && py <= c.screen[3]),
        );
        for (x, _) in row.iter().enumerate().filter(|(_, v)| **v != 0) {
            let px = x as f64 + 0.5;
            let d = camera.ray_direction(px, py);
            let dir = Vector3::new(d[0], d[1], d[2]).normalize();
            let mut best: Option<(f64, f64, usize)> = None;
            for &(i, c) in &row_caps {
                if px < c.screen[0] || px > c.screen[1] {
                    continue;
                }
                if let Some((t, u)) = c.hit(&dir)
                    && best.is_none_or(|bst| t < bst.0)
                {
                    best = Some((t, u, i));
                }
            }
            let (diffuse, specular, arc_mm) = match best {
                Some((t, u, i)) => {
                    let n = caps[i].normal(&dir, t, u);
                    // light at the camera: Lambert plus a Blinn–Phong highlight, falling off with distance
                    let cos = (-n.dot(&dir)).max(0.0);
                    let falloff = (30.0 / t.max(5.0)).powi(2).min(1.6);
                    let diffuse = 0.25 + 0.75 * cos;
                    let spec = cos.powi(40) * 0.9;
                    let s = lengths[i] + u * caps[i].len;
                    (
                        (diffuse * falloff) as f32,
                        (spec * falloff) as f32,
                        s as f32,
                    )
                }
                None => (0.3, 0.0, lengths.last().copied().unwrap_or(0.0) as f32),
            };
            hits.push(Hit {
                pixel: y * w + x,
                arc_mm,
                diffuse,
                specular,
            });
        }
    }
}

/// Pixel box `[u_min, u_max, v_min, v_max]` that contains the projection of the
/// capsule (camera frame): the corners of its bounding box, projected; the whole
/// plane if any corner is not in front of the camera.
fn screen_box(camera: &Camera, a: Vector3<f64>, b: Vector3<f64>, r: f64) -> [f64; 4] {
    let lo = a.inf(&b).add_scalar(-r);
    let hi = a.sup(&b).add_scalar(r);
    if lo.z <= 1e-6 {
        return [f64::MIN, f64::MAX, f64::MIN, f64::MAX];
    }
    let k = &camera.intrinsics;
    let mut out = [f64::MAX, f64::MIN, f64::MAX, f64::MIN];
    for corner in 0..8 {
        let x = if corner & 1 == 0 { lo.x } else { hi.x };
        let y = if corner & 2 == 0 { lo.y } else { hi.y };
        let z = if corner & 4 == 0 { lo.z } else { hi.z };
        let (u, v) = (k.fx * x / z + k.cx, k.fy * y / z + k.cy);
        out = [out[0].min(u), out[1].max(u), out[2].min(v), out[3].max(v)];
    }
    out
}

fn capsule_length(c: &Capsule) -> f64 {
    let d = [
        c.b_mm[0] - c.a_mm[0],
        c.b_mm[1] - c.a_mm[1],
        c.b_mm[2] - c.a_mm[2],
    ];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Arc length at the start of each capsule: along the chain, jaws in parallel at the end.
fn arc_starts(shape: &InstrumentShape) -> Vec<f64> {
    let mut out = Vec::with_capacity(shape.capsules.len());
    let mut s = 0.0;
    for c in &shape.capsules {
        out.push(s);
        if !matches!(c.part, Part::Jaw(_)) {
            s += capsule_length(c);
        }
    }
    out
}

/// The arc-length band `[lo, hi]` holding `o.fraction` of the pixels, placed at `o.position`.
pub(super) fn tape_band(hits: &[Hit], o: Occlusion) -> Option<(f32, f32)> {
    if hits.is_empty() || o.fraction <= 0.0 {
        return None;
    }
    let mut s: Vec<f32> = hits.iter().map(|h| h.arc_mm).collect();
    let n = s.len();
    let count = ((o.fraction * n as f64).round() as usize).min(n);
    if count == 0 {
        return None;
    }
    let start = (o.position * (n - count) as f64).round() as usize;
    // the start-th and (start + count − 1)-th smallest, without a full sort
    let (_, &mut lo, above) = s.select_nth_unstable_by(start, f32::total_cmp);
    let hi = if count == 1 {
        lo
    } else {
        *above.select_nth_unstable_by(count - 2, f32::total_cmp).1
    };
    Some((lo, hi))
}

/// A capsule in the camera frame, ready for rays from the camera centre.
struct CameraCapsule {
    a: Vector3<f64>,
    b: Vector3<f64>,
    /// Unit axis from `a` to `b`, and the length.
    axis: Vector3<f64>,
    len: f64,
    /// `a · axis`.
    a_axis: f64,
    /// The part of `−a` across the axis, and its squared length less `r²`.
    across: Vector3<f64>,
    across_c: f64,
    /// `|a|² − r²` and `|b|² − r²`, for the end spheres.
    ends: [f64; 2],
    /// Pixel box `[u_min, u_max, v_min, v_max]` that holds its projection.
    screen: [f64; 4],
}

impl CameraCapsule {
    fn new(a: Vector3<f64>, b: Vector3<f64>, r: f64, screen: [f64; 4]) -> Self {
        let ba = b - a;
        let len = ba.norm();
        let axis = if len > 1e-9 { ba / len } else { Vector3::z() };
        let across = -a - axis * (-a).dot(&axis);
        Self {
            a,
            b,
            axis,
            len,
            a_axis: a.dot(&axis),
            across,
            across_c: across.norm_squared() - r * r,
            ends: [a.norm_squared() - r * r, b.norm_squared() - r * r],
            screen,
        }
    }

    /// The first hit of the ray from the origin along unit `d`: its distance and
    /// axial parameter in [0, 1].
    #[inline]
    fn hit(&self, d: &Vector3<f64>) -> Option<(f64, f64)> {
        let mut best: Option<(f64, f64)> = None;
        // cylinder: |d t − a|² across the axis = r², nearer root
        if self.len > 1e-9 {
            let da = d.dot(&self.axis);
            let qa = 1.0 - da * da;
            let qb = 2.0 * d.dot(&self.across);
            let disc = qb * qb - 4.0 * qa * self.across_c;
            if qa > 1e-18 && disc >= 0.0 {
                let t = (-qb - disc.sqrt()) / (2.0 * qa);
                let along = t * da - self.a_axis;
                if t > 0.0 && (0.0..=self.len).contains(&along) {
                    best = Some((t, along / self.len));
                }
            }
        }
        // end spheres
        for (c, k, u) in [(&self.a, self.ends[0], 0.0), (&self.b, self.ends[1], 1.0)] {
            let cd = c.dot(d);
            let disc = cd * cd - k;
            if disc >= 0.0 {
                let t = cd - disc.sqrt();
                if t > 0.0 && best.is_none_or(|bst| t < bst.0) {
                    best = Some((t, u));
                }
            }
        }
        best
    }

    /// Outward unit normal where the ray along `d` meets the surface at `t`, axial parameter `u`.
    fn normal(&self, d: &Vector3<f64>, t: f64, u: f64) -> Vector3<f64> {
        (d * t - (self.a + (self.b - self.a) * u)).normalize()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance from `p` to the capsule `a`–`b` of radius `r` (negative inside).
    fn capsule_distance(p: Vector3<f64>, a: Vector3<f64>, b: Vector3<f64>, r: f64) -> f64 {
        let ba = b - a;
        let u = ((p - a).dot(&ba) / ba.norm_squared()).clamp(0.0, 1.0);
        (p - (a + ba * u)).norm() - r
    }

    /// The closed-form hit equals sphere tracing along the ray, over rays that
    /// meet the cylinder, the end caps, or nothing.
    #[test]
    fn capsule_hit_matches_sphere_tracing() {
        let (a, b, r) = (
            Vector3::new(-3.0, 1.0, 30.0),
            Vector3::new(4.0, -2.0, 45.0),
            2.5,
        );
        let capsule = CameraCapsule::new(a, b, r, [0.0; 4]);
        let (mut hits, mut misses) = (0, 0);
        for i in 0..41 {
            for j in 0..41 {
                let d = Vector3::new(
                    -0.3 + 0.015 * f64::from(i),
                    -0.3 + 0.015 * f64::from(j),
                    1.0,
                )
                .normalize();
                let mut t = 0.0;
                let traced = loop {
                    let dist = capsule_distance(d * t, a, b, r);
                    if dist < 1e-9 {
                        break Some(t);
                    }
                    t += dist;
                    if t > 200.0 {
                        break None;
                    }
                };
                match (capsule.hit(&d), traced) {
                    (Some((t, u)), Some(traced)) => {
                        hits += 1;
                        assert!((t - traced).abs() < 1e-6, "t {t} vs {traced}");
                        let n = capsule.normal(&d, t, u);
                        // the normal points out of the surface, towards the camera side
                        assert!((n.norm() - 1.0).abs() < 1e-9 && n.dot(&d) <= 1e-9);
                        assert!(capsule_distance(d * t + n * 1e-3, a, b, r) > 0.0);
                    }
                    (None, None) => misses += 1,
                    (got, want) => panic!("ray {d:?}: hit {got:?}, traced {want:?}"),
                }
            }
        }
        assert!(hits > 100 && misses > 100, "{hits} hits, {misses} misses");
    }
}
