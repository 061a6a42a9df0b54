//! The three organs' surfaces as the endoscope sees them: per image point,
//! the tissue's depth along the optical axis (mm), its albedo and how much it
//! is a fold's crest — from domain-warped smooth noise shaped per organ.
//!
//! Image points are in units of the image height, origin at the centre, x
//! right, y down; `FOCAL_H` turns them into ray slopes.

use std::f32::consts::PI;

use rand::Rng;

use super::noise::{Noise, smoothstep};

/// Focal length of the default camera in units of the image height
/// (268.5 px / 480 px, a 100° horizontal field of view): the ray through
/// image point `p` has slope `p / FOCAL_H`.
pub(super) const FOCAL_H: f32 = 0.56;

/// What a ray meets: depth along the optical axis, albedo (linear RGB), and
/// the crest measure in [0, 1] (1 on top of a fold: where the wet highlights sit).
#[derive(Debug, Clone, Copy)]
pub(super) struct Surface {
    pub(super) depth_mm: f32,
    pub(super) albedo: [f32; 3],
    pub(super) crest: f32,
}

/// A fold's cross-section over its phase `s` in [0, 1): a smooth ridge
/// centred on ½ of width `sigma` (≈ 0 at the ends, so phases join smoothly).
#[inline]
fn ridge(s: f32, sigma: f32) -> f32 {
    let q = (s - 0.5) / sigma;
    (-q * q).exp()
}

#[inline]
fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t)
}

/// The colon seen along its axis: a tube of radius `RADIUS_MM` whose wall
/// deepens toward an off-centre lumen, haustral folds across it.
#[derive(Debug)]
pub(super) struct Colon {
    lumen: [f32; 2],
    /// Orientation (cos, sin) and squash of the lumen's ellipse.
    axis: (f32, f32),
    squash: f32,
    warp: [Noise; 2],
    jitter: Noise,
    thickness: Noise,
    breaks: Noise,
    mottle: Noise,
    hue: Noise,
}

impl Colon {
    /// The wall's depth at `EDGE` image heights from the lumen, mm; it
    /// deepens as `(EDGE / r)^TAPER` toward the lumen (a colon that narrows
    /// and bends away: the lumen a smaller dark hole than a straight tube's).
    const EDGE_MM: f32 = 30.0;
    const EDGE: f32 = 0.6;
    const TAPER: f32 = 0.5;
    /// Haustral folds' spacing along the axis, mm, and height, mm.
    const SPACING_MM: f32 = 14.0;
    const FOLD_MM: f32 = 6.0;
    /// The depth the lumen's darkness is capped at, mm.
    const LUMEN_MM: f32 = 220.0;

    pub(super) fn new(rng: &mut impl Rng, seed: u64) -> Self {
        let angle: f32 = rng.random_range(0.0..PI);
        Self {
            lumen: [rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.05)],
            axis: (angle.cos(), angle.sin()),
            squash: rng.random_range(0.75..1.25),
            warp: [Noise::new(seed, 11), Noise::new(seed, 12)],
            jitter: Noise::new(seed, 13),
            thickness: Noise::new(seed, 14),
            breaks: Noise::new(seed, 15),
            mottle: Noise::new(seed, 16),
            hue: Noise::new(seed, 17),
        }
    }

    pub(super) fn surface(&self, x: f32, y: f32) -> Surface {
        let (dx, dy) = (x - self.lumen[0], y - self.lumen[1]);
        // domain warp: irregular, not concentric
        let wx = dx + 0.06 * self.warp[0].signed(2.2 * x, 2.2 * y, 2);
        let wy = dy + 0.06 * self.warp[1].signed(2.2 * x, 2.2 * y, 2);
        let (c, s) = self.axis;
        let (ax, ay) = (c * wx + s * wy, (-s * wx + c * wy) * self.squash);
        let r = (ax * ax + ay * ay).sqrt().max(1e-4);
        let wall = (Self::EDGE_MM * (Self::EDGE / r).powf(Self::TAPER)).min(Self::LUMEN_MM);
        // folds equally spaced along the axis: crowded toward the lumen
        let phase = wall / Self::SPACING_MM + 1.4 * self.jitter.signed(1.6 * x, 1.6 * y, 3);
        let k = phase.floor();
        let sigma = 0.12 + 0.16 * self.thickness.fbm(1.8 * x + k, 1.8 * y, 2);
        // each fold is broken somewhere around its circumference
        let (ux, uy) = (ax / r, ay / r);
        let whole = self.breaks.value(1.9 * ux + 5.3 * k, 1.9 * uy + 2.9 * k);
        let far = smoothstep(85.0, 45.0, wall);
        let fold = ridge(phase - k, sigma) * smoothstep(0.3, 0.55, whole) * far;
        let depth_mm = wall - Self::FOLD_MM * fold;
        let m = 1.0 + 0.35 * self.mottle.signed(14.0 * x, 14.0 * y, 3);
        let base = mix(
            [0.90, 0.50, 0.36],
            [0.86, 0.44, 0.44],
            self.hue.fbm(1.5 * x, 1.5 * y, 2),
        );
        // crests paler, the folds' feet in their own shade
        let albedo = mix(base.map(|v| v * m), [0.96, 0.70, 0.60], 0.35 * fold)
            .map(|v| v * (0.8 + 0.2 * fold.sqrt()));
        Surface {
            depth_mm,
            albedo,
            crest: fold,
        }
    }
}

/// The stomach's wall seen obliquely: a plane receding toward the top of
/// the image, long wavy rugae on it that merge and split.
#[derive(Debug)]
pub(super) struct Stomach {
    /// Unit image direction toward the near side of the wall.
    near: [f32; 2],
    /// The plane's tilt from facing the camera: cos, sin.
    tilt: (f32, f32),
    /// Rugae direction in the plane: cos, sin.
    run: (f32, f32),
    meander: [Noise; 2],
    thickness: Noise,
    mottle: Noise,
}

impl Stomach {
    /// Depth of the wall on the optical axis, mm; rugae spacing and height, mm.
    const CENTRE_MM: f32 = 34.0;
    const SPACING_MM: f32 = 9.0;
    const FOLD_MM: f32 = 4.0;

    pub(super) fn new(rng: &mut impl Rng, seed: u64) -> Self {
        let a: f32 = PI / 2.0 + rng.random_range(-0.5..0.5);
        let tilt: f32 = rng.random_range(0.35..0.5);
        let run: f32 = rng.random_range(-0.5..0.5);
        Self {
            near: [a.cos(), a.sin()],
            tilt: (tilt.cos(), tilt.sin()),
            run: (run.cos(), run.sin()),
            meander: [Noise::new(seed, 21), Noise::new(seed, 22)],
            thickness: Noise::new(seed, 23),
            mottle: Noise::new(seed, 24),
        }
    }

    pub(super) fn surface(&self, x: f32, y: f32) -> Surface {
        let (tx, ty) = (x / FOCAL_H, y / FOCAL_H);
        let along = self.near[0] * tx + self.near[1] * ty;
        let (cb, sb) = self.tilt;
        let d = Self::CENTRE_MM * cb;
        let wall = (d / (cb + sb * along).max(0.2)).min(200.0);
        // coordinates in the wall's plane, mm
        let (px, py, pz) = (wall * tx, wall * ty, wall);
        let u = -self.near[1] * px + self.near[0] * py;
        let v = cb * (self.near[0] * px + self.near[1] * py) - sb * pz;
        let (cr, sr) = self.run;
        let across = cr * v + sr * u;
        let phase = across / Self::SPACING_MM
            + 2.2 * self.meander[0].signed(u / 40.0, v / 40.0, 3)
            + 0.5 * self.meander[1].signed(u / 14.0, v / 14.0, 2);
        let k = phase.floor();
        // broad rounded crests, narrow valleys between them
        let sharp = 0.5 + 0.5 * self.thickness.fbm(u / 30.0, v / 30.0 + k, 2);
        let fold = (0.5 - 0.5 * (std::f32::consts::TAU * (phase - k)).cos()).powf(sharp);
        let depth_mm = wall - Self::FOLD_MM * fold;
        let m = 1.0 + 0.3 * self.mottle.signed(u / 3.0, v / 3.0, 4);
        let valley = 0.55 + 0.45 * fold;
        let albedo = mix([0.74, 0.22, 0.20], [0.82, 0.36, 0.32], fold).map(|c| c * m * valley);
        Surface {
            depth_mm,
            albedo,
            crest: fold,
        }
    }
}

/// The larynx from above: two vocal folds meeting at the front (the top of
/// the image) in a V, the dark glottis between them with the trachea's rings
/// deep inside, arytenoids at the open end, false folds beside.
#[derive(Debug)]
pub(super) struct Larynx {
    centre: [f32; 2],
    turn: (f32, f32),
    /// Glottis half-width at the open end, image heights.
    gap: f32,
    bow: f32,
    warp: Noise,
    bumps: Noise,
    mottle: Noise,
}

impl Larynx {
    /// The V's apex and open end, image heights from the centre.
    const APEX: f32 = -0.30;
    const END: f32 = 0.14;

    pub(super) fn new(rng: &mut impl Rng, seed: u64) -> Self {
        let turn: f32 = rng.random_range(-0.15..0.15);
        Self {
            centre: [rng.random_range(-0.08..0.08), rng.random_range(-0.04..0.04)],
            turn: (turn.cos(), turn.sin()),
            gap: rng.random_range(0.055..0.09),
            bow: rng.random_range(0.0..0.02),
            warp: Noise::new(seed, 31),
            bumps: Noise::new(seed, 32),
            mottle: Noise::new(seed, 33),
        }
    }

    /// Half-width of the glottis at `t` (0 at the apex, 1 at the open end).
    fn half_gap(&self, t: f32) -> f32 {
        if t <= 0.0 {
            0.0
        } else if t <= 1.0 {
            self.gap * t + self.bow * (PI * t).sin()
        } else {
            // the rounded posterior end between the arytenoids
            let q = ((t - 1.0) / 0.22).min(1.0);
            self.gap * (1.0 - q * q).max(0.0).sqrt()
        }
    }

    pub(super) fn surface(&self, x: f32, y: f32) -> Surface {
        let (dx, dy) = (x - self.centre[0], y - self.centre[1]);
        let (c, s) = self.turn;
        let lx = c * dx + s * dy + 0.012 * self.warp.signed(5.0 * x, 5.0 * y, 2);
        let ly = -s * dx + c * dy;
        let t = (ly - Self::APEX) / (Self::END - Self::APEX);
        let g = self.half_gap(t);
        let width = 0.035 + 0.035 * t.clamp(0.0, 1.0);
        let e = lx.abs() - g;
        let u = e / width;
        let span = smoothstep(-0.15, 0.02, t) * smoothstep(1.3, 1.05, t);
        // vocal fold: a smooth rounded band from the glottis's edge outward
        let cord = if (0.0..1.0).contains(&u) {
            (1.0 - (2.0 * u - 1.0).powi(2)).sqrt() * span
        } else {
            0.0
        };
        let ventricle = (-((u - 1.15) / 0.15).powi(2)).exp() * span;
        let false_fold = (-((u - 2.1) / 0.6).powi(2)).exp() * span;
        let ary_x = self.gap + 0.045;
        let ary = {
            let q = ((lx.abs() - ary_x).powi(2) + (ly - Self::END - 0.06).powi(2)) / 0.004;
            (-q).exp()
        };
        let funnel = 30.0 + 16.0 * (-(lx * lx / 0.09 + (ly + 0.05).powi(2) / 0.12)).exp();
        let tissue = funnel - 1.2 * cord + 1.0 * ventricle - 2.5 * false_fold - 6.0 * ary
            + 3.0 * self.bumps.signed(3.0 * x, 3.0 * y, 3);
        // the glottis: the trachea far below, its cartilage rings
        let open = if t > 0.0 && t < 1.25 {
            smoothstep(0.0, -0.02, e)
        } else {
            0.0
        };
        let ring = ridge((22.0 * ly + 60.0 * lx * lx).rem_euclid(1.0), 0.2);
        let deep = 95.0 + 30.0 * t.clamp(0.0, 1.0) - 5.0 * ring;
        let depth_mm = tissue + (deep - tissue) * open;
        let m = 1.0 + 0.25 * self.mottle.signed(12.0 * x, 12.0 * y, 4);
        let pink = [0.92, 0.60, 0.58].map(|v| v * m);
        let fold_shade = 0.75 + 0.25 * false_fold.max(cord) - 0.2 * ventricle;
        let skin = mix(
            mix(
                pink.map(|v| v * fold_shade),
                [0.96, 0.74, 0.70],
                cord.powf(0.3),
            ),
            [0.95, 0.70, 0.66],
            ary,
        );
        let trachea = mix([0.80, 0.45, 0.42], [0.92, 0.66, 0.60], ring);
        Surface {
            depth_mm,
            albedo: mix(skin, trachea, open),
            crest: (cord * 0.9 + ary + 0.6 * false_fold).min(1.0) * (1.0 - open),
        }
    }
}
