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

    /// Its name in scenario files, results and on the command line (what
    /// [`FromStr`] reads back).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Background::Colon => "colon",
            Background::Stomach => "stomach",
            Background::Larynx => "larynx",
        }
    }
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

/// The tissue's colour: the organ's own, or repainted with its texture,
/// folds, vessels and lighting kept (tissue that differs from the printed
/// organs: pale or anaemic mucosa, a white scar or fibrin, a drape or
/// narrow-band light, fat or bile). It is applied to the scene, so the steel
/// reflects the repainted tissue as it would in such a scene.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Tissue {
    /// The background's own colours.
    #[default]
    Organ,
    /// Neutral grey at each pixel's own brightness.
    Grey,
    /// The organ's hue at 30 % of its saturation.
    Pale,
    /// Bright and nearly neutral (15 % of the organ's saturation, lifted toward white).
    White,
    /// Blue-green at each pixel's brightness.
    BlueGreen,
    /// Yellow at each pixel's brightness.
    Yellow,
}

impl Tissue {
    /// All colours, the organ's own first.
    pub const ALL: [Tissue; 6] = [
        Tissue::Organ,
        Tissue::Grey,
        Tissue::Pale,
        Tissue::White,
        Tissue::BlueGreen,
        Tissue::Yellow,
    ];

    /// Repaints one pixel of the background as the camera shows it
    /// (encoded, 0 and up: above 1 is overexposed), keeping its brightness `y` (the mean of its
    /// channels) and, where the colour keeps any, its hue.
    pub(super) fn paint(self, c: [f32; 3]) -> [f32; 3] {
        let y = (c[0] + c[1] + c[2]) / 3.0;
        let out = match self {
            Tissue::Organ => c,
            Tissue::Grey => [y; 3],
            Tissue::Pale => c.map(|v| y + 0.3 * (v - y)),
            Tissue::White => {
                let bright = 70.0 / 255.0 + 0.85 * y;
                c.map(|v| bright + 0.15 * (v - y))
            }
            Tissue::BlueGreen => [0.55 * y, 1.15 * y, 1.3 * y],
            Tissue::Yellow => [1.25 * y, 1.1 * y, 0.65 * y],
        };
        out.map(|v| v.max(0.0))
    }
}

impl FromStr for Tissue {
    type Err = ModelError;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().replace('-', "_").as_str() {
            "organ" => Ok(Tissue::Organ),
            "grey" | "gray" => Ok(Tissue::Grey),
            "pale" => Ok(Tissue::Pale),
            "white" => Ok(Tissue::White),
            "blue_green" | "bluegreen" => Ok(Tissue::BlueGreen),
            "yellow" => Ok(Tissue::Yellow),
            _ => Err(ModelError::UnknownTissue {
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
pub(super) struct Look {
    exposure: f32,
    ambient: f32,
    vessels: (u32, u32),
    vessel_strength: f32,
    highlights: (u32, u32),
}

pub(super) fn look(kind: Background) -> Look {
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

/// The background texture as the camera shows it at gain 1 through an ideal
/// lens (encoded RGB f32, row-major, 3 per pixel): 0 and up, where above 1 is
/// tissue the light overexposes, which the sensor clips after the lens.
pub(super) fn background(kind: Background, tissue: Tissue, seed: u64, w: u32, h: u32) -> Vec<f32> {
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
    // the tissue's radiance is not bounded: where the light overexposes it,
    // the sensor clips it, after the lens's vignetting (clamping here would
    // turn an overexposed fold into a neutral grey-white wherever the
    // vignetting then darkens it)
    for v in &mut img {
        *v = if v.is_finite() { v.max(0.0) } else { 0.0 };
    }
    if tissue != Tissue::Organ {
        for px in img.chunks_exact_mut(3) {
            px.copy_from_slice(&tissue.paint([px[0], px[1], px[2]]));
        }
    }
    img
}

/// Lights the albedo in `img` by the endoscope's light at the camera: the
/// inverse-square falloff of the distance along each pixel's ray, times the
/// cosine between the ray and the tissue's normal (from the depth map's
/// slope), over a floor of scattered light. Returns the cosines.
pub(super) fn light(img: &mut [f32], depth: &[f32], w: usize, h: usize, look: &Look) -> Vec<f32> {
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
            while width > 0.45 * px && steps < 400 && segments < 800 {
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
        let peak = rng.random_range(0.85..1.0);
        let parts = rng.random_range(1..=3);
        for p in 0..parts {
            let off = if p == 0 {
                0.0
            } else {
                long * rng.random_range(-0.8..0.8)
            };
            let scale = if p == 0 {
                1.0
            } else {
                rng.random_range(0.6..0.9)
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
    let reach = 1.5 * axes[0].max(axes[1]) + 1.0;
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
            // a flat bright core, a soft rim
            let a = peak * (1.0 - smoothstep(0.4, 1.4, d2.sqrt()));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_backgrounds_name_reads_back_and_is_its_serde_name() {
        for b in Background::ALL {
            assert_eq!(b.name().parse::<Background>().unwrap(), b);
            assert_eq!(
                serde_json::to_string(&b).unwrap(),
                format!("\"{}\"", b.name())
            );
        }
    }

    fn luma(img: &[f32]) -> Vec<f32> {
        img.chunks_exact(3)
            .map(|p| 0.3 * p[0] + 0.59 * p[1] + 0.11 * p[2])
            .collect()
    }

    #[test]
    fn backgrounds_are_finite_deterministic_and_seeded() {
        for kind in Background::ALL {
            let a = background(kind, Tissue::Organ, 5, 160, 120);
            // overexposed tissue may exceed full scale: the sensor clips it
            assert!(a.iter().all(|v| v.is_finite() && *v >= 0.0));
            assert_eq!(a, background(kind, Tissue::Organ, 5, 160, 120));
            let b = background(kind, Tissue::Organ, 6, 160, 120);
            let differ = a
                .iter()
                .zip(&b)
                .filter(|(x, y)| (*x - *y).abs() > 0.02)
                .count();
            assert!(differ > a.len() / 4, "{kind:?}: {differ} values differ");
        }
        // degenerate sizes do not panic
        for (w, h) in [(1, 1), (2, 1), (7, 9)] {
            assert_eq!(
                background(Background::Larynx, Tissue::Organ, 0, w, h).len(),
                (3 * w * h) as usize
            );
        }
    }

    /// Mean luma of the darkest and of all 32 × 32 blocks.
    fn darkest_block(l: &[f32], w: usize, h: usize) -> (f32, f32) {
        let mut blocks = Vec::new();
        for by in 0..h / 32 {
            for bx in 0..w / 32 {
                let mut s = 0.0;
                for y in 32 * by..32 * (by + 1) {
                    s += l[y * w + 32 * bx..y * w + 32 * (bx + 1)]
                        .iter()
                        .sum::<f32>();
                }
                blocks.push(s / 1024.0);
            }
        }
        let mean = blocks.iter().sum::<f32>() / blocks.len() as f32;
        (blocks.iter().copied().fold(f32::MAX, f32::min), mean)
    }

    #[test]
    fn the_colon_lumen_is_a_dark_hole_in_a_lit_wall() {
        for seed in 0..4 {
            let l = luma(&background(
                Background::Colon,
                Tissue::Organ,
                seed,
                640,
                480,
            ));
            let (dark, mean) = darkest_block(&l, 640, 480);
            assert!(
                dark < 0.12 * mean,
                "seed {seed}: lumen {dark:.3}, wall {mean:.3}"
            );
        }
    }

    /// Widths of the larynx's dark glottis (pixels darker than a fifth of
    /// the median) in the rows a quarter and three quarters down its length.
    fn glottis_widths(seed: u64) -> (usize, usize) {
        let (w, h) = (640, 480);
        let l = luma(&background(
            Background::Larynx,
            Tissue::Organ,
            seed,
            w as u32,
            h as u32,
        ));
        let mut sorted = l.clone();
        sorted.sort_by(f32::total_cmp);
        let dark = 0.2 * sorted[sorted.len() / 2];
        let width = |y: usize| (w / 4..3 * w / 4).filter(|&x| l[y * w + x] < dark).count();
        let rows: Vec<usize> = (0..h).filter(|&y| width(y) > 0).collect();
        let (top, bottom) = (rows[0], rows[rows.len() - 1]);
        let at = |f: f32| width(top + ((bottom - top) as f32 * f) as usize);
        (at(0.25), at(0.75))
    }

    #[test]
    fn the_glottis_narrows_toward_the_apex_of_the_v() {
        for seed in 0..4 {
            let (upper, lower) = glottis_widths(seed);
            assert!(
                upper > 0 && (upper as f32) < 0.7 * lower as f32,
                "seed {seed}: {upper} px a quarter down, {lower} px three quarters down"
            );
        }
    }

    #[test]
    fn highlights_are_blobs_not_single_pixels() {
        let (w, h) = (640usize, 480usize);
        for kind in Background::ALL {
            let img = background(kind, Tissue::Organ, 3, w as u32, h as u32);
            let bright: Vec<bool> = img
                .chunks_exact(3)
                .map(|p| p.iter().copied().fold(1.0f32, f32::min) > 0.8)
                .collect();
            // 4-connected components of the near-white pixels
            let mut seen = vec![false; w * h];
            let mut sizes = Vec::new();
            for start in 0..w * h {
                if !bright[start] || seen[start] {
                    continue;
                }
                let (mut stack, mut size) = (vec![start], 0);
                seen[start] = true;
                while let Some(i) = stack.pop() {
                    size += 1;
                    let (x, y) = (i % w, i / w);
                    let near = [
                        (x > 0).then(|| i - 1),
                        (x + 1 < w).then(|| i + 1),
                        (y > 0).then(|| i - w),
                        (y + 1 < h).then(|| i + w),
                    ];
                    for j in near.into_iter().flatten() {
                        if bright[j] && !seen[j] {
                            seen[j] = true;
                            stack.push(j);
                        }
                    }
                }
                sizes.push(size);
            }
            let total: usize = sizes.iter().sum();
            let in_blobs: usize = sizes.iter().filter(|&&s| s >= 6).sum();
            assert!(sizes.len() >= 3, "{kind:?}: {} highlights", sizes.len());
            assert!(
                in_blobs as f32 >= 0.9 * total as f32,
                "{kind:?}: components {sizes:?}"
            );
        }
    }

    #[test]
    fn a_repainted_tissue_keeps_its_texture_and_takes_its_colour() {
        let organ = background(Background::Colon, Tissue::Organ, 2, 160, 120);
        let mean = |img: &[f32]| {
            let mut m = [0.0f64; 3];
            for p in img.chunks_exact(3) {
                for k in 0..3 {
                    m[k] += f64::from(p[k]);
                }
            }
            m.map(|v| v / (img.len() / 3) as f64)
        };
        let o = mean(&organ);
        assert!(o[0] > o[2] + 0.1, "the colon is red: {o:?}");
        for tissue in Tissue::ALL {
            let img = background(Background::Colon, tissue, 2, 160, 120);
            assert!(img.iter().all(|v| v.is_finite() && *v >= 0.0), "{tissue:?}");
            let (l0, l1) = (luma(&organ), luma(&img));
            // the texture stays: brightness follows the organ's pixel for pixel
            let n = l0.len() as f32;
            let (m0, m1) = (l0.iter().sum::<f32>() / n, l1.iter().sum::<f32>() / n);
            let cov: f32 = l0.iter().zip(&l1).map(|(a, b)| (a - m0) * (b - m1)).sum();
            let v0: f32 = l0.iter().map(|a| (a - m0).powi(2)).sum();
            let v1: f32 = l1.iter().map(|b| (b - m1).powi(2)).sum();
            assert!(cov / (v0 * v1).sqrt() > 0.9, "{tissue:?}");
            let c = mean(&img);
            match tissue {
                Tissue::Organ => assert_eq!(img, organ),
                Tissue::Grey => assert!((c[0] - c[2]).abs() < 1e-3 && (c[0] - c[1]).abs() < 1e-3),
                Tissue::Pale => assert!(c[0] - c[2] < 0.4 * (o[0] - o[2]) && c[0] > c[2]),
                Tissue::White => assert!(c[1] > o[1] + 0.1 && c[0] - c[2] < 0.2 * (o[0] - o[2])),
                Tissue::BlueGreen => assert!(c[2] > c[1] && c[1] > c[0]),
                Tissue::Yellow => assert!(c[0] > c[1] && c[1] > c[2]),
            }
        }
    }

    #[test]
    fn tissue_colours_parse_by_name() {
        for (name, t) in [
            ("organ", Tissue::Organ),
            ("Grey", Tissue::Grey),
            ("gray", Tissue::Grey),
            ("blue-green", Tissue::BlueGreen),
            ("blue_green", Tissue::BlueGreen),
            ("yellow", Tissue::Yellow),
        ] {
            assert_eq!(name.parse::<Tissue>(), Ok(t));
        }
        let e = "purple".parse::<Tissue>().unwrap_err().to_string();
        assert!(e.contains("purple") && e.contains("blue_green"), "{e}");
    }
}
