//! The endoscope camera's sensor: illumination gain, optical blur, the
//! camera's response (BT.709 encoding of linear light, as video endoscopes
//! deliver it), Gaussian noise and 8-bit quantisation.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Size of the table of standard-normal samples behind the sensor noise.
const NORMALS: usize = 1 << 16;

/// The standard-normal table behind the sensor noise (fixed seed: the table
/// is a constant of the simulator, each frame reads it in its own order).
pub(super) fn normal_table() -> Box<Normals> {
    let mut rng = ChaCha8Rng::seed_from_u64(0x6e6f_6973_6500_0000);
    let mut table = Box::new([0.0; NORMALS]);
    for v in table.iter_mut() {
        *v = Distribution::<f32>::sample(&StandardNormal, &mut rng);
    }
    table
}

/// [`normal_table`]'s type: its size known, so a 16-bit index needs no bounds check.
pub(super) type Normals = [f32; NORMALS];

/// Values [`Sensor::span_encoded`] quantises in one vectorised step: four groups of four.
const RUN: usize = 16;

/// Entries of the response table over linear light `[0, 1]`.
const RESPONSE: usize = 8192;

/// BT.709's opto-electronic transfer function: linear light `l` in `[0, 1]`
/// to the encoded value (`4.5 l` below 0.018, `1.099 l^0.45 − 0.099` above).
fn bt709(l: f32) -> f32 {
    if l < 0.018 {
        4.5 * l
    } else {
        1.099 * l.powf(0.45) - 0.099
    }
}

/// The inverse of [`bt709`], extended past 1 by the same power: an encoded
/// value back to linear light.
pub(super) fn linear_from_encoded(e: f32) -> f32 {
    if e < 0.081 {
        e / 4.5
    } else {
        ((e.max(0.0) + 0.099) / 1.099).powf(1.0 / 0.45)
    }
}

/// The camera's response as a table: [`bt709`] at `RESPONSE + 1` even steps
/// of linear light over `[0, 1]` (read at the nearest step: at most 0.3 of an
/// 8-bit level off, at the toe's slope of 4.5).
pub(super) fn response_table() -> Box<Response> {
    let mut table = Box::new([0.0; RESPONSE + 1]);
    for (i, v) in table.iter_mut().enumerate() {
        *v = bt709(i as f32 / RESPONSE as f32);
    }
    table
}

/// `y as u8` for `y` in `[0, 255.5]` (not NaN), in steps the compiler
/// vectorises (Rust's saturating `as` it does not): adding 2²³ rounds `y`
/// to the nearest integer, which lands in the low bits of the sum; one less
/// where that rounded up.
#[inline(always)]
fn truncate(y: f32) -> u8 {
    const MAGIC: f32 = 8_388_608.0;
    let m = y + MAGIC;
    let up = u32::from(m - MAGIC > y);
    (m.to_bits().wrapping_sub(MAGIC.to_bits()).wrapping_sub(up)) as u8
}

/// [`response_table`]'s type: its size known, so reading it needs no bounds check.
pub(super) type Response = [f32; RESPONSE + 1];

/// The sensor model: gain, the camera's response, Gaussian noise from the table indexed by a
/// counter-based hash (SplitMix64's finaliser; a Gaussian per pixel and
/// channel at a fraction of a sampler's cost), 8 bits.
pub(super) struct Sensor<'a> {
    /// [`normal_table`].
    pub(super) normals: &'a Normals,
    /// [`response_table`].
    pub(super) response: &'a Response,
    pub(super) key: u64,
    pub(super) gain: f32,
    pub(super) sigma: f32,
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

    /// Linear light `v` as the camera encodes it: the gain, the sensor's
    /// clipping, the camera's response.
    #[inline(always)]
    pub(super) fn encode(&self, v: f32) -> f32 {
        let light = (v * self.gain).clamp(0.0, 1.0);
        // the step is in [0, RESPONSE] (0 for NaN): converted through `i32`,
        // which the processor does in one instruction (`usize` takes two
        // and their fix-ups); the bound keeps any value in the table
        self.response[((light * RESPONSE as f32 + 0.5) as i32 as usize).min(RESPONSE)]
    }

    /// [`Sensor::encode`] of every value of `values`, in place: eight lanes
    /// wide where the processor has AVX2 (the table reads become gathers),
    /// the same operations in the same order, so the same bits.
    pub(super) fn encode_all(&self, values: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.encode_all_avx2(values) };
        }
        self.encode_all_portable(values);
    }

    /// [`Sensor::encode_all`] in AVX2, eight values at a time: the gain, the
    /// clamp to [0, 1] (as a max with 0 then a min with 1, which sends NaN
    /// to 0, the step `encode`'s cast gives it, and −0 to the same step as
    /// `encode`'s −0), the step, and the table read as a gather; the rest
    /// one at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn encode_all_avx2(&self, values: &mut [f32]) {
        use std::arch::x86_64::{
            _mm256_add_ps, _mm256_cvttps_epi32, _mm256_i32gather_ps, _mm256_loadu_ps,
            _mm256_max_ps, _mm256_min_epi32, _mm256_min_ps, _mm256_mul_ps, _mm256_set1_epi32,
            _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps,
        };
        let (gain, one, half) = (
            _mm256_set1_ps(self.gain),
            _mm256_set1_ps(1.0),
            _mm256_set1_ps(0.5),
        );
        let (steps, last) = (
            _mm256_set1_ps(RESPONSE as f32),
            _mm256_set1_epi32(RESPONSE as i32),
        );
        let mut chunks = values.chunks_exact_mut(8);
        for chunk in chunks.by_ref() {
            // SAFETY: `chunk` holds eight floats; the steps lie in
            // [0, RESPONSE], within the table's RESPONSE + 1 values.
            unsafe {
                let v = _mm256_mul_ps(_mm256_loadu_ps(chunk.as_ptr()), gain);
                let light = _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), one);
                let step = _mm256_min_epi32(
                    _mm256_cvttps_epi32(_mm256_add_ps(_mm256_mul_ps(light, steps), half)),
                    last,
                );
                let encoded = _mm256_i32gather_ps::<4>(self.response.as_ptr(), step);
                _mm256_storeu_ps(chunk.as_mut_ptr(), encoded);
            }
        }
        self.encode_all_portable(chunks.into_remainder());
    }

    #[inline(always)]
    fn encode_all_portable(&self, values: &mut [f32]) {
        for v in values {
            *v = self.encode(*v);
        }
    }

    /// An encoded value with its noise, in 8 bits: the noise is on the encoded
    /// image (as the paper's augmentation is); the value is ≥ 0 after the
    /// clamp, so adding ½ and truncating rounds to nearest.
    #[inline(always)]
    fn quantise(encoded: f32, noise: f32) -> u8 {
        truncate((encoded + noise).clamp(0.0, 1.0) * 255.0 + 0.5)
    }

    /// Value `i` of the image (`3 · pixel + channel`) as the sensor reads it.
    #[cfg(test)]
    pub(super) fn pixel(&self, i: usize, v: f32) -> u8 {
        let noise = if self.sigma > 0.0 {
            self.noise(self.bits(i / 4), i % 4)
        } else {
            0.0
        };
        Self::quantise(self.encode(v), noise)
    }

    /// Values `first..first + values.len()` of the image as the sensor reads
    /// them, into `out`: `pixel(first + j, values[j])` for every `j`, each
    /// group of four values' random bits drawn once.
    #[cfg(test)]
    pub(super) fn span(&self, first: usize, values: &[f32], out: &mut [u8]) {
        let encoded: Vec<f32> = values.iter().map(|&v| self.encode(v)).collect();
        self.span_encoded(first, &encoded, out);
    }

    /// [`Sensor::span`] of values already encoded ([`Sensor::encode`]).
    ///
    /// Whole runs of four groups (16 values) draw their 16 normals first and
    /// then add, clip and quantise them in one loop the compiler vectorises;
    /// the values are those [`Sensor::pixel`] gives, bit for bit.
    pub(super) fn span_encoded(&self, first: usize, encoded: &[f32], out: &mut [u8]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.span_encoded_avx2(first, encoded, out) };
        }
        self.span_encoded_portable(first, encoded, out);
    }

    /// [`Sensor::span_encoded`] compiled for AVX2: the table reads become
    /// gathers and the quantisation runs eight lanes wide. The same
    /// operations in the same order (no fused multiply-add), so the same bits.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn span_encoded_avx2(&self, first: usize, encoded: &[f32], out: &mut [u8]) {
        self.span_encoded_portable(first, encoded, out);
    }

    #[inline(always)]
    fn span_encoded_portable(&self, first: usize, encoded: &[f32], out: &mut [u8]) {
        let n = out.len().min(encoded.len());
        let (out, encoded) = (&mut out[..n], &encoded[..n]);
        if self.sigma <= 0.0 {
            for (o, &e) in out.iter_mut().zip(encoded) {
                *o = Self::quantise(e, 0.0);
            }
            return;
        }
        let one = |j: usize| {
            Self::quantise(
                encoded[j],
                self.noise(self.bits((first + j) / 4), (first + j) % 4),
            )
        };
        // up to the first whole group of four, then runs of four whole
        // groups, then the rest one by one
        let head = ((4 - first % 4) % 4).min(n);
        for (j, o) in out.iter_mut().enumerate().take(head) {
            *o = one(j);
        }
        let runs = (n - head) / RUN;
        let group0 = (first + head) / 4;
        let mut noise = [0.0f32; RUN];
        for (r, (o, e)) in out[head..head + RUN * runs]
            .chunks_exact_mut(RUN)
            .zip(encoded[head..head + RUN * runs].chunks_exact(RUN))
            .enumerate()
        {
            for (g, lanes) in noise.chunks_exact_mut(4).enumerate() {
                let bits = self.bits(group0 + RUN / 4 * r + g);
                for (lane, z) in lanes.iter_mut().enumerate() {
                    *z = self.normals[((bits >> (16 * lane)) & 0xFFFF) as usize];
                }
            }
            for ((o, &e), &z) in o.iter_mut().zip(e).zip(&noise) {
                *o = Self::quantise(e, self.sigma * z);
            }
        }
        for (j, o) in out.iter_mut().enumerate().skip(head + RUN * runs) {
            *o = one(j);
        }
    }

    /// The whole image as the sensor reads it: `pixel(i, values[i])` for every `i`.
    #[cfg(test)]
    pub(super) fn image(&self, values: &[f32]) -> Vec<u8> {
        let mut out = vec![0u8; values.len()];
        if self.sigma > 0.0 {
            let mut groups = out.chunks_exact_mut(4).zip(values.chunks_exact(4));
            for (g, (o, v)) in groups.by_ref().enumerate() {
                let bits = self.bits(g);
                for lane in 0..4 {
                    o[lane] = Self::quantise(self.encode(v[lane]), self.noise(bits, lane));
                }
            }
        } else {
            for (o, &v) in out.iter_mut().zip(values) {
                *o = Self::quantise(self.encode(v), 0.0);
            }
        }
        let tail = values.len() - values.len() % 4;
        for i in tail..values.len() {
            out[i] = self.pixel(i, values[i]);
        }
        out
    }
}

/// Separable Gaussian blur of an RGB f32 image in place (edges clamped):
/// a horizontal pass into a scratch image, a vertical pass back.
pub(super) fn gaussian_blur(img: &mut [f32], w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let norm: f32 = kernel.iter().sum();
    let mut tmp = vec![0.0f32; img.len()];
    blur_pass(img, &mut tmp, w, h, &kernel, norm, true);
    blur_pass(&tmp, img, w, h, &kernel, norm, false);
}

/// One pass of [`gaussian_blur`] from `src` into `dst`, along rows or columns.
fn blur_pass(
    src: &[f32],
    dst: &mut [f32],
    w: usize,
    h: usize,
    kernel: &[f32],
    norm: f32,
    along_rows: bool,
) {
    let radius = (kernel.len() / 2) as isize;
    for y in 0..h as isize {
        for x in 0..w as isize {
            let mut acc = [0.0f32; 3];
            for (j, kv) in kernel.iter().enumerate() {
                let o = j as isize - radius;
                let (sx, sy) = if along_rows {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Blurring an impulse spreads it into a symmetric, normalised Gaussian
    /// whose spread is σ along both axes.
    #[test]
    fn blur_spreads_an_impulse_into_a_gaussian() {
        let (w, h, sigma) = (41usize, 31usize, 2.0);
        let mut img = vec![0.0f32; 3 * w * h];
        let centre = 3 * (15 * w + 20);
        img[centre + 1] = 1.0;
        gaussian_blur(&mut img, w, h, sigma);
        let green = |x: usize, y: usize| f64::from(img[3 * (y * w + x) + 1]);
        let total: f64 = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| green(x, y))
            .sum();
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        assert!((green(17, 15) - green(23, 15)).abs() < 1e-7);
        assert!((green(20, 12) - green(20, 18)).abs() < 1e-7);
        assert!(
            img[centre].abs() < 1e-9 && img[centre + 2].abs() < 1e-9,
            "channels stay apart"
        );
        let var_x: f64 = (0..w)
            .map(|x| (x as f64 - 20.0).powi(2) * (0..h).map(|y| green(x, y)).sum::<f64>())
            .sum();
        assert!((var_x.sqrt() - sigma).abs() < 0.05, "{}", var_x.sqrt());
    }

    /// The sensor reads a value the same whether alone, in a span or in a whole image.
    #[test]
    fn the_response_encodes_linear_light_as_bt709_does() {
        let table = response_table();
        assert_eq!(table.len(), RESPONSE + 1);
        assert!(table.windows(2).all(|w| w[1] > w[0]), "rising");
        assert_eq!((table[0], table[RESPONSE]), (0.0, 1.0));
        // BT.709's two pieces meet (continuity at 0.018) and its mid-grey:
        // 18 % linear light encodes to 0.409
        assert!((4.5f32 * 0.018 - (1.099 * 0.018f32.powf(0.45) - 0.099)).abs() < 1e-3);
        assert!((bt709(0.18) - 0.409).abs() < 1e-3, "{}", bt709(0.18));
        // the inverse undoes it, past 1 as well (to the standard's own
        // rounding where its two pieces meet: 2e-4 at 0.081)
        for e in [0.0f32, 0.03, 0.081, 0.2, 0.5, 0.9, 1.0] {
            assert!((bt709(linear_from_encoded(e)) - e).abs() < 1e-3, "{e}");
        }
        assert!(linear_from_encoded(1.2) > 1.0);
        // read at the nearest step: within a third of an 8-bit level
        for i in 0..=1000 {
            let l = i as f32 / 1000.0;
            let at = table[(l * RESPONSE as f32 + 0.5) as usize];
            assert!((at - bt709(l)).abs() * 255.0 < 0.34, "{l}");
        }
    }

    /// The vectorisable truncation is Rust's `as u8` on every value the
    /// quantiser makes (a sample of all `f32` around `[0, 1]`).
    #[test]
    fn quantising_truncates_as_a_cast_does() {
        let old = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        let check = |x: f32| assert_eq!(Sensor::quantise(x, 0.0), old(x), "{x}");
        for b in (0..=2.5f32.to_bits()).step_by(61) {
            check(f32::from_bits(b));
        }
        for b in ((-0.0f32).to_bits()..=(-1.5f32).to_bits()).step_by(1009) {
            check(f32::from_bits(b));
        }
        // every level's edges
        for k in 0..=255u32 {
            let edge = (k as f32 - 0.5) / 255.0;
            let mut x = edge;
            for _ in 0..64 {
                check(x);
                x = f32::from_bits(x.to_bits().wrapping_add(1));
            }
            check(f32::from_bits(edge.to_bits().wrapping_sub(1)));
            check(k as f32 / 255.0);
        }
        for x in [f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN, 1e-40] {
            check(x);
        }
    }

    /// The bulk encoding gives `encode`'s bits for every value, the edges
    /// of its clamp included (NaN, ±0, below 0, past 1, the infinities), in
    /// whole runs of eight and the rest.
    #[test]
    fn encoding_all_at_once_gives_each_values_encoding() {
        let normals = Box::new([0.0f32; NORMALS]);
        let response = response_table();
        for gain in [1.0, 0.7, 1.6] {
            let sensor = Sensor {
                normals: &normals,
                response: &response,
                key: 0,
                gain,
                sigma: 0.0,
            };
            let mut values: Vec<f32> = (0..1013).map(|i| (i as f32 * 0.0113).sin() * 1.3).collect();
            values.extend([
                f32::NAN,
                0.0,
                -0.0,
                -1e-30,
                1e-30,
                1.0,
                1.0 + f32::EPSILON,
                f32::INFINITY,
                f32::NEG_INFINITY,
                0.5 / RESPONSE as f32,
                f32::MAX,
            ]);
            for len in [values.len(), 8, 7, 1] {
                let mut all = values[..len].to_vec();
                sensor.encode_all(&mut all);
                for (i, (&got, &v)) in all.iter().zip(&values).enumerate() {
                    let want = sensor.encode(v);
                    assert_eq!(
                        got.to_bits(),
                        want.to_bits(),
                        "value {i} ({v}), gain {gain}"
                    );
                }
            }
        }
    }

    #[test]
    fn sensor_pixel_and_image_agree() {
        let mut normals = Box::new([0.0f32; NORMALS]);
        for (i, v) in normals.iter_mut().enumerate() {
            *v = (i as f32 / NORMALS as f32) - 0.5;
        }
        for sigma in [0.0, 0.02] {
            let response = response_table();
            let sensor = Sensor {
                normals: &normals,
                response: &response,
                key: 42,
                gain: 1.1,
                sigma,
            };
            let values: Vec<f32> = (0..1003).map(|i| (i as f32 * 0.37).sin().abs()).collect();
            let image = sensor.image(&values);
            for (i, &v) in values.iter().enumerate() {
                assert_eq!(image[i], sensor.pixel(i, v), "value {i}");
            }
            // a span from any start reads each value as the whole image does
            for (first, len) in [
                (0, 1003),
                (5, 17),
                (333, 1),
                (998, 5),
                (3, 16),
                (1, 50),
                (16, 32),
                (7, 996),
            ] {
                let mut out = vec![0u8; len];
                sensor.span(first, &values[first..first + len], &mut out);
                assert_eq!(out, image[first..first + len], "span {first}+{len}");
            }
        }
    }
}
