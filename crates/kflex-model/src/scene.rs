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
use crate::error::{ModelError, Result};
use crate::instrument::{InstrumentShape, Part};
use crate::mask::Mask;
use crate::range::Bounds;
use crate::raster::Rasterizer;

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
    /// Frame number: fresh sensor noise over the same background, as from a
    /// video camera (the background is cached per seed; the noise is not).
    pub frame: u64,
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
            frame: 0,
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
        Bounds::closed(0.05, 5.0).check("illumination_gain", self.illumination_gain)?;
        Bounds::closed(0.0, 1.0).check("noise_std", self.noise_std)?;
        Bounds::closed(0.0, 20.0).check("blur_px", self.blur_px)?;
        if let Some(o) = self.occlusion {
            Bounds::closed(0.0, 1.0).check("occlusion.fraction", o.fraction)?;
            Bounds::closed(0.0, 1.0).check("occlusion.position", o.position)?;
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

/// Size of the table of standard-normal samples behind the sensor noise.
const NORMALS: usize = 1 << 16;

/// The sensor model: gain, Gaussian noise from the table read by xorshift64*
/// (a Gaussian per pixel and channel at a fraction of a sampler's cost), 8 bits.
struct Sensor<'a> {
    normals: &'a [f32],
    key: u64,
    gain: f32,
    sigma: f32,
}

impl Sensor<'_> {
    /// 64 random bits for the group of four values from `group · 4` on: a
    /// counter-based hash (SplitMix64's finaliser), so values need no order and
    /// carry no dependency from one to the next.
    #[inline(always)]
    fn bits(&self, group: usize) -> u64 {
        let mut z = self
            .key
            .wrapping_add((group as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Gaussian noise from 16 of `bits`, lane 0–3.
    #[inline(always)]
    fn noise(&self, bits: u64, lane: usize) -> f32 {
        self.sigma * self.normals[((bits >> (16 * lane)) & 0xFFFF) as usize]
    }

    #[inline(always)]
    fn quantise(&self, v: f32, noise: f32) -> u8 {
        // v ≥ 0 after the clamp, so adding ½ and truncating rounds to nearest
        ((v * self.gain + noise).clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    }

    /// Value `i` of the image (`3 · pixel + channel`) as the sensor reads it.
    fn pixel(&self, i: usize, v: f32) -> u8 {
        let noise = if self.sigma > 0.0 {
            self.noise(self.bits(i / 4), i % 4)
        } else {
            0.0
        };
        self.quantise(v, noise)
    }

    /// The whole image as the sensor reads it: `pixel(i, values[i])` for every `i`.
    fn image(&self, values: &[f32]) -> Vec<u8> {
        let mut out = vec![0u8; values.len()];
        if self.sigma > 0.0 {
            let mut groups = out.chunks_exact_mut(4).zip(values.chunks_exact(4));
            for (g, (o, v)) in groups.by_ref().enumerate() {
                let bits = self.bits(g);
                for lane in 0..4 {
                    o[lane] = self.quantise(v[lane], self.noise(bits, lane));
                }
            }
        } else {
            for (o, &v) in out.iter_mut().zip(values) {
                *o = self.quantise(v, 0.0);
            }
        }
        let tail = values.len() - values.len() % 4;
        for i in tail..values.len() {
            out[i] = self.pixel(i, values[i]);
        }
        out
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
            .map(|c| {
                let a = (camera.camera_from_overtube * nalgebra::Point3::from(c.a_mm)).coords;
                let b = (camera.camera_from_overtube * nalgebra::Point3::from(c.b_mm)).coords;
                CameraCapsule::new(a, b, c.radius_mm, screen_box(camera, a, b, c.radius_mm))
            })
            .collect();
        let mut row_caps: Vec<(usize, &CameraCapsule)> = Vec::with_capacity(caps.len());
        for (y, row) in silhouette.data().chunks_exact(w as usize).enumerate() {
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
                let idx = y * w as usize + x;
                let (shade, s) = match best {
                    Some((t, u, i)) => {
                        let n = caps[i].normal(&dir, t, u);
                        // light at the camera: Lambert plus a Blinn–Phong highlight, falling off with distance
                        let cos = (-n.dot(&dir)).max(0.0);
                        let falloff = (30.0 / t.max(5.0)).powi(2).min(1.6);
                        let diffuse = 0.25 + 0.75 * cos;
                        let spec = cos.powi(40) * 0.9;
                        let s = lengths[i] + u * caps[i].len;
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
        let sensor = Sensor {
            normals: &self.normals,
            key: params.seed.wrapping_mul(0xD1B5_4A32_D192_ED03)
                ^ params.frame.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7)
                ^ 0x006e_6f69_7365,
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
            sensor.image(&img)
        } else {
            // no blur: quantise the background straight from the cache, then the instrument over it
            let mut rgb = sensor.image(background);
            for &(idx, c) in &shaded {
                for ch in 0..3 {
                    rgb[3 * idx + ch] = sensor.pixel(3 * idx + ch, c[ch]);
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
fn tape_band(hits: &[(usize, f32, [f32; 3])], o: Occlusion) -> Option<(f32, f32)> {
    if hits.is_empty() || o.fraction <= 0.0 {
        return None;
    }
    let mut s: Vec<f32> = hits.iter().map(|h| h.1).collect();
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

#[cfg(test)]
mod unit_tests {
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

    /// The sensor reads a value the same whether alone or in a whole image.
    #[test]
    fn sensor_pixel_and_image_agree() {
        let normals: Vec<f32> = (0..NORMALS)
            .map(|i| (i as f32 / NORMALS as f32) - 0.5)
            .collect();
        for sigma in [0.0, 0.02] {
            let sensor = Sensor {
                normals: &normals,
                key: 42,
                gain: 1.1,
                sigma,
            };
            let values: Vec<f32> = (0..1003).map(|i| (i as f32 * 0.37).sin().abs()).collect();
            let image = sensor.image(&values);
            for (i, &v) in values.iter().enumerate() {
                assert_eq!(image[i], sensor.pixel(i, v), "value {i}");
            }
        }
    }
}
