//! Procedural clinical backgrounds: colon, stomach and larynx textures from
//! smooth value noise, folds shaped per organ, vessels and wet highlights.

use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

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

/// Lattice value noise in [0, 1], smooth, from a hashed seed.
fn value_noise(x: f64, y: f64, seed: u64) -> f64 {
    let hash = |i: i64, j: i64| -> f64 {
        let mut v = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ seed;
        v ^= v >> 31;
        v = v.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        v ^= v >> 29;
        (v >> 11) as f64 / (1u64 << 53) as f64
    };
    let (xi, yi) = (x.floor() as i64, y.floor() as i64);
    let (fx, fy) = (x - x.floor(), y - y.floor());
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let top = hash(xi, yi) * (1.0 - sx) + hash(xi + 1, yi) * sx;
    let bottom = hash(xi, yi + 1) * (1.0 - sx) + hash(xi + 1, yi + 1) * sx;
    top * (1.0 - sy) + bottom * sy
}

fn fbm(x: f64, y: f64, seed: u64) -> f64 {
    (0..4)
        .map(|o| {
            value_noise(
                x * f64::from(1 << o),
                y * f64::from(1 << o),
                seed.wrapping_add(o),
            ) / f64::from(1 << o)
        })
        .sum::<f64>()
        / 1.875
}

/// The background texture, RGB f32 in [0, 1].
pub(super) fn background(kind: Background, seed: u64, w: u32, h: u32) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ (kind as u64 * 0x1000_0001));
    let (base, dark): ([f64; 3], [f64; 3]) = match kind {
        Background::Colon => ([0.88, 0.58, 0.45], [0.35, 0.12, 0.10]),
        Background::Stomach => ([0.72, 0.28, 0.25], [0.30, 0.06, 0.07]),
        Background::Larynx => ([0.92, 0.74, 0.70], [0.30, 0.15, 0.15]),
    };
    let (wf, hf) = (f64::from(w), f64::from(h));
    let scale = 8.0 / wf.max(hf);
    let lumen = [
        wf * rng.random_range(0.35..0.65),
        hf * rng.random_range(0.3..0.55),
    ];
    let phase = rng.random_range(0.0..std::f64::consts::TAU);
    let mut img = vec![0.0f32; (w * h * 3) as usize];
    for y in 0..h {
        for x in 0..w {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let n = fbm(xf * scale, yf * scale, seed);
            let (dx, dy) = ((xf - lumen[0]) / wf, (yf - lumen[1]) / hf);
            let r = (dx * dx + dy * dy).sqrt();
            // folds: darker troughs between brighter ridges, shaped per organ
            let fold = match kind {
                Background::Colon => (r * 28.0 + 2.0 * n + phase).sin(),
                Background::Stomach => {
                    ((yf / hf) * 22.0 + 4.0 * (xf / wf * 3.0 + phase).sin() + 3.0 * n).sin()
                }
                Background::Larynx => {
                    let v = (dx.abs() * 3.0 - dy.abs() * 0.4 - 0.05).abs();
                    if v < 0.04 {
                        1.0
                    } else {
                        ((yf / hf) * 30.0 + n).sin() * 0.5
                    }
                }
            };
            let depth = match kind {
                Background::Larynx => {
                    (1.0 - (-(dx * dx * 30.0 + dy * dy * 4.0) * 40.0).exp() * 0.85).max(0.1)
                }
                _ => (1.0 - (-r * r * 60.0).exp() * 0.9).max(0.05),
            };
            // the endoscope's light falls off toward the corners
            let vignette = 1.0 - 0.45 * ((xf / wf - 0.5).powi(2) + (yf / hf - 0.5).powi(2)) * 2.0;
            let t = (0.55 + 0.25 * fold + 0.35 * (n - 0.5)).clamp(0.0, 1.0);
            let i = 3 * (y * w + x) as usize;
            for ch in 0..3 {
                img[i + ch] = ((dark[ch] + (base[ch] - dark[ch]) * t) * depth * vignette) as f32;
            }
        }
    }
    // vessels: random walks, dark red-purple
    for _ in 0..rng.random_range(6..12) {
        let (mut px, mut py) = (rng.random_range(0.0..wf), rng.random_range(0.0..hf));
        let mut heading = rng.random_range(0.0..std::f64::consts::TAU);
        for _ in 0..rng.random_range(80..260) {
            heading += rng.random_range(-0.25..0.25);
            px += heading.cos() * 1.5;
            py += heading.sin() * 1.5;
            if px < 0.0 || py < 0.0 || px >= wf || py >= hf {
                break;
            }
            let i = 3 * (py as u32 * w + px as u32) as usize;
            img[i] *= 0.72;
            img[i + 1] *= 0.55;
            img[i + 2] *= 0.65;
        }
    }
    // specular spots on wet mucosa
    for _ in 0..rng.random_range(10..25) {
        let (cx, cy, rad) = (
            rng.random_range(0.0..wf),
            rng.random_range(0.0..hf),
            rng.random_range(1.0..3.5),
        );
        let (x0, x1) = (
            (cx - 2.0 * rad).max(0.0) as u32,
            ((cx + 2.0 * rad) as u32).min(w - 1),
        );
        let (y0, y1) = (
            (cy - 2.0 * rad).max(0.0) as u32,
            ((cy + 2.0 * rad) as u32).min(h - 1),
        );
        for y in y0..=y1 {
            for x in x0..=x1 {
                let d2 = (f64::from(x) - cx).powi(2) + (f64::from(y) - cy).powi(2);
                let a = (-(d2) / (rad * rad)).exp() as f32;
                let i = 3 * (y * w + x) as usize;
                for ch in 0..3 {
                    img[i + ch] = img[i + ch] * (1.0 - a) + a;
                }
            }
        }
    }
    img
}
