//! Shading the instrument: polished steel lit by the endoscope's light at
//! the camera (a diffuse term, a sharp highlight and a broad sheen), tinted
//! by the tissue it reflects (Schlick's Fresnel), matte tape, and the tape
//! band along the instrument's arc length.

use nalgebra::Vector3;

use super::Occlusion;
use crate::camera::Camera;
use crate::instrument::{Ends, Part};
use crate::raster::{CameraBody, SurfaceHit};

/// Base colour of the instrument's steel, linear RGB in [0, 1].
const METAL: [f32; 3] = [0.60, 0.62, 0.66];
/// Base colour of the tape: matte red.
const TAPE: [f32; 3] = [0.55, 0.05, 0.06];
/// Reflectance of steel at normal incidence (Schlick's `F₀`).
const STEEL_F0: f64 = 0.55;
/// Distance at which the endoscope's light gives the nominal exposure, mm;
/// the irradiance falls as its inverse square (capped at 2.5 up close).
pub(super) const LIGHT_MM: f64 = 30.0;

/// The endoscope light's strength on the instrument, in linear light at the
/// nominal distance: chosen with the camera's response (BT.709) so that
/// steel at 10 mm shows about 0.6 of full scale, at 30 mm 0.4 and at 50 mm
/// 0.25 (the tissue's strength is part of each background's look).
const INSTRUMENT_LIGHT: f64 = 0.5;

/// The light's falloff at distance `t_mm` from the camera: `(30/t)²`, at most 2.5.
#[inline]
pub(super) fn falloff(t_mm: f64) -> f64 {
    (LIGHT_MM / t_mm.max(1.0)).powi(2).min(2.5)
}

/// What the steel reflects: the tissue in front of the camera (the
/// background image, full frame, linear RGB), and its mean colour.
pub(super) struct Surroundings<'a> {
    pub(super) camera: &'a Camera,
    pub(super) image: &'a [f32],
    pub(super) mean: [f32; 3],
}

impl Surroundings<'_> {
    /// The tissue seen along the reflected ray `r` (camera frame): where
    /// it points ahead, the background pixel it would project to (clamped to
    /// the frame); where it points back past the camera, the dark overtube
    /// and shadowed tissue around it. The pixel is named, not read (see [`Look`]).
    fn along(&self, r: &Vector3<f64>) -> Seen {
        if r.z < 0.05 {
            return Seen::Colour(self.mean.map(|c| 0.3 * c));
        }
        let k = &self.camera.intrinsics;
        let [xd, yd] = self.camera.lens.distort(r.x / r.z, r.y / r.z);
        let u = (k.fx * xd + k.cx).clamp(0.0, f64::from(k.width) - 1.0) as usize;
        let v = (k.fy * yd + k.cy).clamp(0.0, f64::from(k.height) - 1.0) as usize;
        Seen::At(3 * (v * k.width as usize + u))
    }

    /// The colour at `i` of the background (its mean where outside).
    #[inline]
    fn at(&self, i: usize) -> [f32; 3] {
        match self.image.get(i..i + 3) {
            Some(p) => [p[0], p[1], p[2]],
            None => self.mean,
        }
    }
}

/// What the steel reflects at a point: a background pixel (the index of
/// its red value) or a colour.
#[derive(Debug, Clone, Copy)]
pub(super) enum Seen {
    At(usize),
    Colour([f32; 3]),
}

/// A surface's colour, or all of it but what the steel reflects: the
/// reflected pixel, in a background image too large for the cache, is read
/// after a whole frame's looks are made ([`Look::colour`]), in a loop of
/// independent reads the processor overlaps.
#[derive(Debug, Clone, Copy)]
pub(super) enum Look {
    Done([f32; 3]),
    Steel {
        diffuse: f64,
        reflected: f64,
        highlight: f64,
        seen: Seen,
    },
}

impl Look {
    /// The colour, reading the reflected pixel from `env`.
    #[inline]
    pub(super) fn colour(&self, env: &Surroundings<'_>) -> [f32; 3] {
        match *self {
            Look::Done(c) => c,
            Look::Steel {
                diffuse,
                reflected,
                highlight,
                seen,
            } => {
                let seen = match seen {
                    Seen::At(i) => env.at(i),
                    Seen::Colour(c) => c,
                };
                std::array::from_fn(|k| {
                    (f64::from(METAL[k]) * diffuse + f64::from(seen[k]) * reflected + highlight)
                        as f32
                })
            }
        }
    }
}

/// Whether the surface at `hit` lies under the tape band `tape` (arc lengths).
pub(super) fn under_tape(hit: &SurfaceHit, tape: Option<(f32, f32)>) -> bool {
    let arc = hit.arc_mm as f32;
    tape.is_some_and(|(lo, hi)| arc >= lo && arc <= hi)
}

/// The look of the surface at `hit`, seen along unit `d`: tape where
/// [`under_tape`], else steel; `env` is what the steel reflects.
pub(super) fn surface_look(
    bodies: &[CameraBody],
    hit: &SurfaceHit,
    d: &Vector3<f64>,
    tape: Option<(f32, f32)>,
    env: &Surroundings<'_>,
) -> Look {
    let n = hit.normal;
    let cos = (-n.dot(d)).clamp(0.0, 1.0);
    let light = INSTRUMENT_LIGHT * falloff(hit.t);
    if under_tape(hit, tape) {
        // matte: Lambert, a faint sheen
        let diffuse = (0.15 + 0.85 * cos) * light;
        let sheen = 0.04 * cos.powi(16) * light;
        return Look::Done(TAPE.map(|c| (f64::from(c) * diffuse + sheen) as f32));
    }
    // the backbone, seen through the gaps between discs, sits in their shadow
    let body = &bodies[hit.body];
    let shadow = if matches!(body.part, Part::Link(_)) && body.ends == Ends::Round {
        0.45
    } else {
        1.0
    };
    // machined disc faces are duller than the polished sides
    let gloss = if hit.on_end && body.ends == Ends::Flat {
        0.3
    } else {
        1.0
    };
    let fresnel = STEEL_F0 + (1.0 - STEEL_F0) * (1.0 - cos).powi(5);
    // satin steel scatters some light back even at grazing incidence
    let diffuse = (0.28 + 0.42 * cos) * light * shadow;
    let mirror = d - n * (2.0 * d.dot(&n));
    let seen = env.along(&mirror);
    // the tissue it reflects is lit about as the steel is (no brighter than nominal)
    let reflected = 0.22 * fresnel * shadow * gloss * falloff(hit.t).min(1.0);
    let highlight = (0.9 * cos.powi(80) + 0.2 * cos.powi(10)) * light * shadow * gloss;
    Look::Steel {
        diffuse,
        reflected,
        highlight,
        seen,
    }
}

/// The arc-length band `[lo, hi]` holding `o.fraction` of `arcs` (the
/// instrument's pixels in the region the share is measured over), placed at
/// `o.position`: 0 starting at the nearest, 1 ending at the farthest arc length.
pub(super) fn tape_band(arcs: &mut [f32], o: Occlusion) -> Option<(f32, f32)> {
    let n = arcs.len();
    if n == 0 || o.fraction <= 0.0 {
        return None;
    }
    let count = ((o.fraction * n as f64).round() as usize).min(n);
    if count == 0 {
        return None;
    }
    let start = (o.position * (n - count) as f64).round() as usize;
    // the start-th and (start + count − 1)-th smallest, without a full sort
    let (_, &mut lo, above) = arcs.select_nth_unstable_by(start, f32::total_cmp);
    let hi = if count == 1 {
        lo
    } else {
        *above.select_nth_unstable_by(count - 2, f32::total_cmp).1
    };
    Some((lo, hi))
}
