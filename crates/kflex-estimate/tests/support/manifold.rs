//! A synthetic stand-in for the SCNN's embeddings, shared by the feature
//! index's tests, its criterion bench and `examples/index_bench.rs`: a
//! smooth two-parameter surface in `D` dimensions (one point per pose θ, d,
//! as the SCNN maps the silhouettes of a two-parameter family of poses),
//! plus Gaussian noise (rendering noise, a fresh frame never quite matching
//! its database image).
//!
//! Each component is a sum of random cosines of the normalised pose (up to 3
//! periods over the range, amplitudes falling with frequency, as a CNN's
//! smooth response would), so the surface is smooth but curls through ~100
//! dimensions, no few of which hold it all; points have norm ≈ 1.
#![allow(dead_code)]

use kflex_estimate::Pose;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// Cosines per component.
const WAVES: usize = 48;

/// The noise per component the tests, bench and `index_bench` use: a noise
/// vector of norm ≈ 0.08 against points of norm 1 and neighbours ≈ 0.1 apart
/// in a 6,000-point database.
pub const DEFAULT_NOISE_STD: f64 = 0.005;

/// The surface and its noise.
pub struct Manifold {
    dim: usize,
    /// Per wave: angular frequency in (u, v) and phase.
    waves: Vec<([f64; 2], f64)>,
    /// `dim × WAVES` amplitudes.
    amps: Vec<f64>,
    /// Standard deviation of the noise per component.
    pub noise_std: f64,
}

impl Manifold {
    /// The surface in `dim` dimensions drawn from `seed`, with noise of
    /// `noise_std` per component.
    pub fn new(dim: usize, noise_std: f64, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let waves: Vec<([f64; 2], f64)> = (0..WAVES)
            .map(|_| {
                let w = [rng.random_range(-6.0..6.0), rng.random_range(-6.0..6.0)];
                let w = w.map(|x: f64| x * std::f64::consts::PI);
                (w, rng.random_range(0.0..std::f64::consts::TAU))
            })
            .collect();
        // amplitudes fall with frequency; ≈ unit norm overall
        let weight: Vec<f64> = waves
            .iter()
            .map(|(w, _)| 1.0 / (1.0 + w[0].hypot(w[1]) / std::f64::consts::PI))
            .collect();
        let total: f64 = weight.iter().map(|w| w * w).sum();
        let scale = (2.0 / (dim as f64 * total)).sqrt();
        let amps = (0..dim * WAVES)
            .map(|i| {
                let z: f64 = StandardNormal.sample(&mut rng);
                scale * weight[i % WAVES] * z
            })
            .collect();
        Self {
            dim,
            waves,
            amps,
            noise_std,
        }
    }

    /// The embedding of `pose` (θ ∈ [−90°, 90°], d ∈ [8, 40] mm), with fresh
    /// noise from `rng`, appended to `out`.
    pub fn embed(&self, pose: Pose, rng: &mut impl Rng, out: &mut Vec<f32>) {
        let u = (pose.theta_deg + 90.0) / 180.0;
        let v = (pose.translation_mm - 8.0) / 32.0;
        let cosines: Vec<f64> = self
            .waves
            .iter()
            .map(|(w, phase)| (w[0] * u + w[1] * v + phase).cos())
            .collect();
        for j in 0..self.dim {
            let a = &self.amps[j * WAVES..][..WAVES];
            let x: f64 = a.iter().zip(&cosines).map(|(a, c)| a * c).sum();
            let noise: f64 = StandardNormal.sample(rng);
            out.push((x + self.noise_std * noise) as f32);
        }
    }

    /// `n` points at poses drawn uniformly over the full range, row-major,
    /// with their poses.
    pub fn sample(&self, n: usize, rng: &mut impl Rng) -> (Vec<f32>, Vec<Pose>) {
        let mut features = Vec::with_capacity(n * self.dim);
        let mut poses = Vec::with_capacity(n);
        for _ in 0..n {
            let pose = Pose {
                theta_deg: rng.random_range(-90.0..=90.0),
                translation_mm: rng.random_range(8.0..=40.0),
            };
            self.embed(pose, rng, &mut features);
            poses.push(pose);
        }
        (features, poses)
    }
}

/// `n` points with independent standard normal components times `scale`:
/// data with no structure, where no projection helps (the index's worst case).
pub fn random_points(n: usize, dim: usize, scale: f64, rng: &mut impl Rng) -> Vec<f32> {
    (0..n * dim)
        .map(|_| {
            let z: f64 = StandardNormal.sample(rng);
            (scale * z) as f32
        })
        .collect()
}

/// A deterministic generator for tests and benches.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}
