//! Procedural clinical backgrounds: colon, stomach and larynx from
//! domain-warped smooth noise shaped per organ ([`super::organs`]), branching
//! vessels and wet highlights, lit by the endoscope's light at the camera
//! with the same inverse-square falloff as the instrument
//! ([`super::shading::falloff`]) and a cosine term from the tissue's slope.

use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::noise::smoothstep;
use super::organs::{Colon, FOCAL_H, Larynx, Stomach, Surface};
use super::shading::falloff;
use crate::error::{ModelError, Result};

/// Procedural clinical background, after the paper's printed colon, stomach and larynx images.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Background {
    /// Orange-pink mucosa, haustral folds ringing a dark lumen, fine vessels.
    Colon,
    /// Deep red mucosa with long wavy rugae.
    Stomach,
    /// Pale pink tissue, two bright vocal folds converging on a dark glottis, tracheal rings.
    Larynx,
}

impl Background {
    /// All kinds, in the paper's order.
    pub const ALL: [Background; 3] = [Background::Colon, Background::Stomach, Background::Larynx];
}

impl FromStr for Background {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "colon" => Ok(Background::Colon),
            "stomach" => Ok(Background::Stomach),
            "larynx" => Ok(Background::Larynx),
            _ => Err(ModelError::UnknownBackground {
                name: s.to_string(),
            }),
        }
    }
}

/// One organ's surface model.
enum Organ {
    Colon(Colon),
    Stomach(Stomach),
    Larynx(Larynx),
}

impl Organ {
    fn surface(&self, x: f32, y: f32) -> Surface {
        match self {
            Organ::Colon(o) => o.surface(x, y),
            Organ::Stomach(o) => o.surface(x, y),
            Organ::Larynx(o) => o.surface(x, y),
        }
    }
}

/// Per kind: the endoscope's exposure (the gain that puts the centre of the
/// view at the old backgrounds' level), the light scattered back by the
/// surrounding wet tissue (a floor under the cosine term), the vessels'
/// count and strength, and the wet highlights' count.
struct Look {
    exposure: f32,
    ambient: f32,
    vessels: (u32, u32),
    vessel_strength: f32,
    highlights: (u32, u32),
}

fn look(kind: Background) -> Look {
    match kind {
        Background::Colon => Look {
            exposure: 2.7,
            ambient: 0.2,
            vessels: (5, 9),
            vessel_strength: 0.55,
            highlights: (10, 18),
        },
        Background::Stomach => Look {
            exposure: 1.08,
            ambient: 0.2,
            vessels: (2, 4),
            vessel_strength: 0.4,
            highlights: (12, 20),
        },
        Background::Larynx => Look {
            exposure: 1.95,
            ambient: 0.2,
            vessels: (3, 6),
            vessel_strength: 0.45,
            highlights: (5, 9),
        },
    }
}

/// Vessels' colour: the albedo is multiplied toward it (dark red-purple).
const VESSEL: [f32; 3] = [0.60, 0.34, 0.48];
/// Wet highlights' colour at their core: white, a little warm.
const SPECULAR: [f32; 3] = [1.0, 0.97, 0.93];

/// The background texture, linear RGB f32 in [0, 1], row-major, 3 per pixel.
pub(super) fn background(kind: Background, seed: u64, w: u32, h: u32) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (kind as u64 * 0x1000_0001));
    let organ = match kind {
        Background::Colon => Organ::Colon(Colon::new(&mut rng, seed)),
        Background::Stomach => Organ::Stomach(Stomach::new(&mut rng, seed)),
        Background::Larynx => Organ::Larynx(Larynx::new(&mut rng, seed)),
    };
    let look = look(kind);
    let (wu, hu) = (w as usize, h as usize);
    let vessels = vessel_tree(&mut rng, &look, wu, hu);
    let n = wu * hu;
    let mut img = vec![0.0f32; 3 * n];
    let mut depth = vec![0.0f32; n];
    let mut crest = vec![0.0f32; n];
    let (hf, half_w, half_h) = (h.max(1) as f32, w as f32 / 2.0, h as f32 / 2.0);
    for y in 0..hu {
        let py = (y as f32 + 0.5 - half_h) / hf;
        for x in 0..wu {
            let px = (x as f32 + 0.5 - half_w) / hf;
            let s = organ.surface(px, py);
            let i = y * wu + x;
            let a = vessels[i];
            for k in 0..3 {
                img[3 * i + k] = s.albedo[k] * (1.0 - a * (1.0 - VESSEL[k]));
            }
            depth[i] = s.depth_mm.max(1.0);
            crest[i] = s.crest;
        }
    }
    let cos = light(&mut img, &depth, wu, hu, &look);
    highlights(&mut img, &mut rng, &look, &crest, &cos, &depth, wu, hu);
    for v in &mut img {
        *v = if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        };
    }
    img
}

/// Lights the albedo in `img` by the endoscope's light at the camera: the
/// inverse-square falloff of the distance along each pixel's ray, times the
/// cosine between the ray and the tissue's normal (from the depth map's
/// slope), over a floor of scattered light. Returns the cosines.
fn light(img: &mut [f32], depth: &[f32], w: usize, h: usize, look: &Look) -> Vec<f32> {
    let mut cos = vec![1.0f32; w * h];
    if w < 2 || h < 2 {
        return cos;
    }
    let hf = h as f32;
    // one pixel in ray slope
    let step = 1.0 / (hf * FOCAL_H);
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
        let ty = (y as f32 + 0.5 - hf / 2.0) * step;
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let tx = (x as f32 + 0.5 - w as f32 / 2.0) * step;
            let i = y * w + x;
            let z = depth[i];
            let zx = (depth[y * w + x1] - depth[y * w + x0]) / ((x1 - x0) as f32 * step);
            let zy = (depth[y1 * w + x] - depth[y0 * w + x]) / ((y1 - y0) as f32 * step);
            // the surface z(tx, ty)·(tx, ty, 1) has normal (−z_x, −z_y, z + tx z_x + ty z_y)
            let n = [-zx, -zy, z + tx * zx + ty * zy];
            let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let ray = (1.0 + tx * tx + ty * ty).sqrt();
            let c = if norm > 0.0 {
                (z / (norm * ray)).clamp(0.0, 1.0)
            } else {
                1.0
            };
            cos[i] = c;
            let gain = look.exposure
                * falloff(f64::from(z * ray)) as f32
                * (look.ambient + (1.0 - look.ambient) * c);
            img[3 * i..3 * i + 3].iter_mut().for_each(|v| *v *= gain);
        }
    }
    cos
}

/// Branching vessels: smooth random curves whose width tapers, each branch
/// thinner than its parent; the opacity in [0, 1] per pixel.
fn vessel_tree(rng: &mut impl Rng, look: &Look, w: usize, h: usize) -> Vec<f32> {
    let mut alpha = vec![0.0f32; w * h];
    let px = h as f32 / 480.0;
    let (wf, hf) = (w as f32, h as f32);
    let count = rng.random_range(look.vessels.0..=look.vessels.1);
    for _ in 0..count {
        let strength = look.vessel_strength * rng.random_range(0.6..1.0);
        // (x, y, heading, width, steps) in pixels
        let mut stack = vec![(
            rng.random_range(0.0..wf),
            rng.random_range(0.0..hf),
            rng.random_range(0.0..std::f32::consts::TAU),
            px * rng.random_range(2.2..4.5),
            0u32,
        )];
        let mut segments = 0;
        while let Some((mut x, mut y, mut heading, mut width, mut steps)) = stack.pop() {
            let mut turn = 0.0f32;
            while width > 0.45 * px && steps < 400 && segments < 4000 {
                turn = 0.85 * turn + rng.random_range(-0.04..0.04);
                heading += turn;
                let len = 3.5 * px;
                let (nx, ny) = (x + len * heading.cos(), y + len * heading.sin());
                let next = width * 0.992;
                capsule(&mut alpha, w, h, [x, y, nx, ny], [width, next], strength);
                (x, y, width) = (nx, ny, next);
                steps += 1;
                segments += 1;
                if x < -20.0 * px || y < -20.0 * px || x > wf + 20.0 * px || y > hf + 20.0 * px {
                    break;
                }
                if width > 0.9 * px && rng.random_bool(0.035) {
                    let side = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    let fork = heading + side * rng.random_range(0.4..1.0);
                    stack.push((x, y, fork, width * 0.7, steps));
                    width *= 0.85;
                    heading -= side * 0.2;
                }
            }
        }
    }
    alpha
}

/// Draws a segment `[x0, y0, x1, y1]` (pixels) of widths `[w0, w1]` into
/// `alpha`, soft-edged, keeping each pixel's largest opacity.
fn capsule(alpha: &mut [f32], w: usize, h: usize, seg: [f32; 4], width: [f32; 2], strength: f32) {
    let [x0, y0, x1, y1] = seg;
    let reach = width[0].max(width[1]) + 1.0;
    let (bx0, bx1) = (x0.min(x1) - reach, x0.max(x1) + reach);
    let (by0, by1) = (y0.min(y1) - reach, y0.max(y1) + reach);
    if bx1 < 0.0 || by1 < 0.0 || bx0 >= w as f32 || by0 >= h as f32 {
        return;
    }
    let (dx, dy) = (x1 - x0, y1 - y0);
    let l2 = (dx * dx + dy * dy).max(1e-6);
    for y in by0.max(0.0) as usize..(by1.ceil() as usize).min(h) {
        for x in bx0.max(0.0) as usize..(bx1.ceil() as usize).min(w) {
            let (qx, qy) = (x as f32 + 0.5 - x0, y as f32 + 0.5 - y0);
            let t = ((qx * dx + qy * dy) / l2).clamp(0.0, 1.0);
            let (ex, ey) = (qx - t * dx, qy - t * dy);
            let d = (ex * ex + ey * ey).sqrt();
            let half = 0.5 * (width[0] + (width[1] - width[0]) * t);
            let a = strength * (1.0 - smoothstep(half - 0.6, half + 0.6, d));
            let p = &mut alpha[y * w + x];
            *p = p.max(a);
        }
    }
}

/// Wet highlights: a seeded number of small elongated blobs on fold crests
/// that face the light (each two or three overlapping ellipses along the
/// fold, a bright core with a soft edge, toward white).
#[allow(clippy::too_many_arguments)]
fn highlights(
    img: &mut [f32],
    rng: &mut impl Rng,
    look: &Look,
    crest: &[f32],
    cos: &[f32],
    depth: &[f32],
    w: usize,
    h: usize,
) {
    if w < 8 || h < 8 {
        return;
    }
    let px = h as f32 / 480.0;
    let count = rng.random_range(look.highlights.0..=look.highlights.1);
    for _ in 0..count {
        // a crest that faces the light, not too far: up to 200 tries
        let mut spot = None;
        for _ in 0..200 {
            let (x, y) = (rng.random_range(3..w - 3), rng.random_range(3..h - 3));
            let i = y * w + x;
            if crest[i] > 0.6 && cos[i] > 0.55 && depth[i] < 45.0 {
                spot = Some((x, y));
                break;
            }
        }
        let Some((x, y)) = spot else { continue };
        // along the fold: across the crest measure's gradient
        let gx = crest[y * w + x + 2] - crest[y * w + x - 2];
        let gy = crest[(y + 2) * w + x] - crest[(y - 2) * w + x];
        let g = (gx * gx + gy * gy).sqrt();
        let (tx, ty) = if g > 1e-4 {
            (-gy / g, gx / g)
        } else {
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            (a.cos(), a.sin())
        };
        let long = px * rng.random_range(5.0..11.0);
        let short = px * rng.random_range(2.0..3.5);
        let peak = rng.random_range(0.7..1.0);
        let parts = rng.random_range(1..=3);
        for p in 0..parts {
            let off = if p == 0 {
                0.0
            } else {
                long * rng.random_range(-1.1..1.1)
            };
            let scale = if p == 0 {
                1.0
            } else {
                rng.random_range(0.45..0.8)
            };
            let (cx, cy) = (x as f32 + 0.5 + off * tx, y as f32 + 0.5 + off * ty);
            blob(
                img,
                w,
                h,
                [cx, cy],
                [tx, ty],
                [long * scale, short * scale],
                peak * scale.sqrt(),
            );
        }
    }
}

/// One elliptic highlight centred at `c`, long axis along unit `t`.
fn blob(img: &mut [f32], w: usize, h: usize, c: [f32; 2], t: [f32; 2], axes: [f32; 2], peak: f32) {
    let reach = 2.5 * axes[0].max(axes[1]);
    let (x0, x1) = (
        (c[0] - reach).max(0.0) as usize,
        ((c[0] + reach) as usize).min(w - 1),
    );
    let (y0, y1) = (
        (c[1] - reach).max(0.0) as usize,
        ((c[1] + reach) as usize).min(h - 1),
    );
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (dx, dy) = (x as f32 + 0.5 - c[0], y as f32 + 0.5 - c[1]);
            let (u, v) = (dx * t[0] + dy * t[1], -dx * t[1] + dy * t[0]);
            let d2 = (u / axes[0]).powi(2) + (v / axes[1]).powi(2);
            let a = peak * (-1.2 * d2).exp();
            if a < 1e-3 {
                continue;
            }
            let i = 3 * (y * w + x);
            for k in 0..3 {
                img[i + k] += a * (SPECULAR[k] - img[i + k]).max(0.0);
            }
        }
    }
}
