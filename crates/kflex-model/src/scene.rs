//! Shaded endoscope frames: the instrument over procedural clinical backgrounds,
//! lit by the endoscope's light, with occluding tape, illumination change,
//! blur and sensor noise — and the ground-truth masks of every frame.
//!
//! Backgrounds are generated from a seed ([`Background`]) and cached per
//! (kind, seed, size) in a [`SceneRenderer`], so a frame costs the instrument's
//! shading and the sensor model, not the texture synthesis.

use std::str::FromStr;

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::{ModelError, Result, closed_range};
use crate::instrument::{InstrumentShape, Part};
use crate::raster::{Mask, Rasterizer};

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

/// Tape over the instrument: a band covering `fraction` of its visible area.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Occlusion {
    /// Share of the visible instrument area covered, in [0, 1] (the paper: 0.2, 0.4).
    pub fraction: f64,
    /// Where the band sits along the instrument: 0 at the proximal end of what is
    /// visible, 1 ending at the tool tip (the paper's "distal part").
    pub position: f64,
}

/// How one frame is made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FrameParams {
    /// Background kind.
    pub background: Background,
    /// Seed of the background and of the sensor noise.
    pub seed: u64,
    /// Illumination gain (1: nominal).
    pub illumination_gain: f64,
    /// Standard deviation of Gaussian sensor noise on the [0, 1] image (the paper augments with 0.01).
    pub noise_std: f64,
    /// Gaussian blur, standard deviation in pixels (0: none).
    pub blur_px: f64,
    /// Tape over the instrument, if any.
    pub occlusion: Option<Occlusion>,
}

impl Default for FrameParams {
    fn default() -> Self {
        Self {
            background: Background::Colon,
            seed: 0,
            illumination_gain: 1.0,
            noise_std: 0.01,
            blur_px: 0.0,
            occlusion: None,
        }
    }
}

impl FrameParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        closed_range("illumination_gain", self.illumination_gain, 0.05, 5.0)?;
        closed_range("noise_std", self.noise_std, 0.0, 1.0)?;
        closed_range("blur_px", self.blur_px, 0.0, 20.0)?;
        if let Some(o) = self.occlusion {
            closed_range("occlusion.fraction", o.fraction, 0.0, 1.0)?;
            closed_range("occlusion.position", o.position, 0.0, 1.0)?;
        }
        Ok(())
    }
}

/// A rendered frame and its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// RGB, 8 bits per channel, row-major.
    pub rgb: Vec<u8>,
    /// The instrument's visible (untaped) pixels.
    pub instrument: Mask,
    /// The tape's pixels.
    pub occluder: Mask,
}

/// Renders frames, caching backgrounds.
#[derive(Debug, Default)]
pub struct SceneRenderer {
    raster: Rasterizer,
    cache: Option<(BackgroundKey, Vec<f32>)>,
    silhouette: Option<Mask>,
    /// Standard-normal samples; each frame reads them in a seeded pseudo-random order.
    normals: Vec<f32>,
}

/// What a cached background depends on: kind, seed, width, height.
type BackgroundKey = (Background, u64, u32, u32);

/// A capsule in the camera frame: ends, radius, index in the shape, and the pixel
/// box `[u_min, u_max, v_min, v_max]` its projection can cover.
type CameraCapsule = (Vector3<f64>, Vector3<f64>, f64, usize, [f64; 4]);

/// Size of the table of standard-normal samples behind the sensor noise.
const NORMALS: usize = 1 << 16;

/// The sensor model: gain, Gaussian noise from the table read by xorshift64*
/// (a Gaussian per pixel and channel at a fraction of a sampler's cost), 8 bits.
struct Sensor<'a> {
    normals: &'a [f32],
    state: u64,
    gain: f32,
    sigma: f32,
}

impl Sensor<'_> {
    fn pixel(&mut self, v: f32) -> u8 {
        let n = if self.sigma > 0.0 {
            self.state ^= self.state >> 12;
            self.state ^= self.state << 25;
            self.state ^= self.state >> 27;
            self.sigma
                * self.normals[(self.state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 48) as usize]
        } else {
            0.0
        };
        ((v * self.gain + n).clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

const METAL: [f32; 3] = [0.62, 0.64, 0.68];
const TAPE: [f32; 3] = [0.50, 0.04, 0.05];

impl SceneRenderer {
    /// A renderer with an empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// Renders `shape` seen by `camera` with `params`.
    pub fn render(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        params: &FrameParams,
    ) -> Result<Frame> {
        params.validate()?;
        let k = camera.intrinsics;
        k.validate()?;
        let (w, h) = (k.width, k.height);
        let key = (params.background, params.seed, w, h);
        if self.cache.as_ref().map(|c| c.0) != Some(key) {
            self.cache = Some((key, background(params.background, params.seed, w, h)));
        }
        let silhouette = match self.silhouette.take() {
            Some(mut m) if (m.width(), m.height()) == (w, h) => {
                m.clear();
                m
            }
            _ => Mask::new(w, h)?,
        };
        let mut silhouette = silhouette;
        self.raster.silhouette(camera, shape, &mut silhouette)?;
        // shade every silhouette pixel from the exact surface point the ray meets
        let lengths = arc_starts(shape);
        let mut hits: Vec<(usize, f32, [f32; 3])> = Vec::new(); // (pixel, arc length, shade)
        // capsules in the camera frame, each with the pixel box its projection can cover
        let caps: Vec<CameraCapsule> = shape
            .capsules
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let a = (camera.camera_from_overtube * nalgebra::Point3::from(c.a)).coords;
                let b = (camera.camera_from_overtube * nalgebra::Point3::from(c.b)).coords;
                (a, b, c.radius, i, screen_box(camera, a, b, c.radius))
            })
            .collect();
        for y in 0..h {
            for x in 0..w {
                if !silhouette.get(x, y) {
                    continue;
                }
                let d = camera.ray_direction(f64::from(x) + 0.5, f64::from(y) + 0.5);
                let dir = Vector3::new(d[0], d[1], d[2]).normalize();
                let mut best: Option<(f64, Vector3<f64>, usize, f64)> = None;
                let (px, py) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                for &(a, b, r, i, bx) in &caps {
                    if px < bx[0] || px > bx[1] || py < bx[2] || py > bx[3] {
                        continue;
                    }
                    if let Some((t, n, u)) = ray_capsule(dir, a, b, r)
                        && best.is_none_or(|bst| t < bst.0)
                    {
                        best = Some((t, n, i, u));
                    }
                }
                let idx = (y * w + x) as usize;
                let (shade, s) = match best {
                    Some((t, n, i, u)) => {
                        // light at the camera: Lambert plus a Blinn–Phong highlight, falling off with distance
                        let cos = (-n.dot(&dir)).max(0.0);
                        let falloff = (30.0 / t.max(5.0)).powi(2).min(1.6);
                        let diffuse = 0.25 + 0.75 * cos;
                        let spec = cos.powi(40) * 0.9;
                        let s = lengths[i] + u * capsule_length(&shape.capsules[i]);
                        (
                            ((diffuse * falloff) as f32, (spec * falloff) as f32),
                            s as f32,
                        )
                    }
                    None => ((0.3, 0.0), lengths.last().copied().unwrap_or(0.0) as f32),
                };
                hits.push((idx, s, [shade.0, shade.1, 0.0]));
            }
        }
        // the tape: a band of arc length holding `fraction` of the visible pixels
        let band = params.occlusion.and_then(|o| tape_band(&hits, o));
        let (mut inst_raw, mut occ_raw) =
            (vec![0u8; (w * h) as usize], vec![0u8; (w * h) as usize]);
        let shaded: Vec<(usize, [f32; 3])> = hits
            .iter()
            .map(|&(idx, s, [diffuse, spec, _])| {
                let taped = band.is_some_and(|(lo, hi)| s >= lo && s <= hi);
                let (base, gloss) = if taped { (TAPE, 0.35) } else { (METAL, 1.0) };
                if taped {
                    occ_raw[idx] = 1;
                } else {
                    inst_raw[idx] = 1;
                }
                (idx, base.map(|c| c * diffuse + spec * gloss))
            })
            .collect();
        let instrument = Mask::from_raw(w, h, inst_raw)?;
        let occluder = Mask::from_raw(w, h, occ_raw)?;
        self.silhouette = Some(silhouette);
        // sensor: illumination, blur, noise, quantisation
        if self.normals.is_empty() {
            let mut rng = ChaCha8Rng::seed_from_u64(0x6e6f_6973_6500_0000);
            self.normals = (0..NORMALS)
                .map(|_| Distribution::<f32>::sample(&StandardNormal, &mut rng))
                .collect();
        }
        let mut sensor = Sensor {
            normals: &self.normals,
            state: params.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1,
            gain: params.illumination_gain as f32,
            sigma: params.noise_std as f32,
        };
        let background = self
            .cache
            .as_ref()
            .map(|c| c.1.as_slice())
            .unwrap_or_default();
        let rgb = if params.blur_px > 0.0 {
            let mut img = background.to_vec();
            for &(idx, c) in &shaded {
                img[3 * idx..3 * idx + 3].copy_from_slice(&c);
            }
            gaussian_blur(&mut img, w as usize, h as usize, params.blur_px);
            img.iter().map(|&v| sensor.pixel(v)).collect()
        } else {
            // no blur: quantise the background straight from the cache, then the instrument over it
            let mut rgb: Vec<u8> = background.iter().map(|&v| sensor.pixel(v)).collect();
            for &(idx, c) in &shaded {
                for ch in 0..3 {
                    rgb[3 * idx + ch] = sensor.pixel(c[ch]);
                }
            }
            rgb
        };
        Ok(Frame {
            width: w,
            height: h,
            rgb,
            instrument,
            occluder,
        })
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

fn capsule_length(c: &crate::instrument::Capsule) -> f64 {
    let d = [c.b[0] - c.a[0], c.b[1] - c.a[1], c.b[2] - c.a[2]];
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
fn tape_band(hits: &[(usize, f32, [f32; 3])], o: Occlusion) -> Option<(f32, f32)> {
    if hits.is_empty() || o.fraction <= 0.0 {
        return None;
    }
    let mut s: Vec<f32> = hits.iter().map(|h| h.1).collect();
    s.sort_by(f32::total_cmp);
    let n = s.len();
    let count = ((o.fraction * n as f64).round() as usize).min(n);
    if count == 0 {
        return None;
    }
    let start = (o.position * (n - count) as f64).round() as usize;
    Some((s[start], s[start + count - 1]))
}

/// Ray from the origin along unit `d` against the capsule `a`–`b` of radius `r`:
/// distance, outward normal, and the axial parameter in [0, 1] of the hit.
fn ray_capsule(
    d: Vector3<f64>,
    a: Vector3<f64>,
    b: Vector3<f64>,
    r: f64,
) -> Option<(f64, Vector3<f64>, f64)> {
    let mut best: Option<(f64, Vector3<f64>, f64)> = None;
    let ba = b - a;
    let len2 = ba.norm_squared();
    // cylinder part
    if len2 > 1e-18 {
        let axis = ba / len2.sqrt();
        let oa = -a; // origin − a
        let dp = d - axis * d.dot(&axis);
        let op = oa - axis * oa.dot(&axis);
        let qa = dp.norm_squared();
        let qb = 2.0 * dp.dot(&op);
        let qc = op.norm_squared() - r * r;
        let disc = qb * qb - 4.0 * qa * qc;
        if qa > 1e-18 && disc >= 0.0 {
            let t = (-qb - disc.sqrt()) / (2.0 * qa);
            if t > 0.0 {
                let p = d * t;
                let u = (p - a).dot(&ba) / len2;
                if (0.0..=1.0).contains(&u) {
                    let n = (p - (a + ba * u)).normalize();
                    best = Some((t, n, u));
                }
            }
        }
    }
    // end spheres
    for (c, u) in [(a, 0.0), (b, 1.0)] {
        let cd = c.dot(&d);
        let disc = cd * cd - (c.norm_squared() - r * r);
        if disc >= 0.0 {
            let t = cd - disc.sqrt();
            if t > 0.0 && best.is_none_or(|bst| t < bst.0) {
                best = Some((t, (d * t - c).normalize(), u));
            }
        }
    }
    best
}

/// Separable Gaussian blur of an RGB f32 image in place.
fn gaussian_blur(img: &mut [f32], w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let norm: f32 = kernel.iter().sum();
    let mut tmp = vec![0.0f32; img.len()];
    for pass in 0..2 {
        let (src, dst): (&[f32], &mut [f32]) = if pass == 0 {
            (img, &mut tmp)
        } else {
            (&tmp, img)
        };
        let src = src.to_vec();
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut acc = [0.0f32; 3];
                for (j, kv) in kernel.iter().enumerate() {
                    let o = j as isize - radius;
                    let (sx, sy) = if pass == 0 {
                        ((x + o).clamp(0, w as isize - 1), y)
                    } else {
                        (x, (y + o).clamp(0, h as isize - 1))
                    };
                    let i = 3 * (sy as usize * w + sx as usize);
                    for ch in 0..3 {
                        acc[ch] += kv * src[i + ch];
                    }
                }
                let i = 3 * (y as usize * w + x as usize);
                for ch in 0..3 {
                    dst[i + ch] = acc[ch] / norm;
                }
            }
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
fn background(kind: Background, seed: u64, w: u32, h: u32) -> Vec<f32> {
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
