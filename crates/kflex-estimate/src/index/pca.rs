//! The projection the k-d tree lives in: the database's mean and its `K`
//! leading principal axes (PCA), and the constants that make the pruning
//! bound hold for the f32 projection actually stored.

use nalgebra::{DMatrix, SymmetricEigen};

use super::kernel::gamma;

/// Rows the covariance is estimated from, at most (an even stride through
/// the database). The projection only has to be orthonormal for the search
/// to be exact; a sample this size finds the leading axes of an embedding
/// just as well and keeps the build of a 100k-point database quick.
const MAX_COVARIANCE_ROWS: usize = 8192;

/// The mean of the rows of `features` (`dim` wide), in f64 then rounded to f32.
pub(crate) fn mean(features: &[f32], dim: usize) -> Vec<f32> {
    let mut sum = vec![0.0_f64; dim];
    let mut n = 0_usize;
    for row in features.chunks_exact(dim) {
        for (s, x) in sum.iter_mut().zip(row) {
            *s += f64::from(*x);
        }
        n += 1;
    }
    sum.iter().map(|s| (s / n.max(1) as f64) as f32).collect()
}

/// `dims` orthonormal rows, each `dim` wide (row-major), spanning the
/// leading principal axes of `features` around `mean`, largest variance
/// first. Where `dim ≤ dims` the first `dim` rows are the identity (the tree
/// then holds the features themselves); rows beyond the data's dimension are
/// zero, which keeps the projection a contraction.
pub(crate) fn principal_axes(features: &[f32], dim: usize, mean: &[f32], dims: usize) -> Vec<f32> {
    let mut rows = vec![0.0_f32; dims * dim];
    if dim <= dims {
        for i in 0..dim {
            rows[i * dim + i] = 1.0;
        }
        return rows;
    }
    let n = features.len() / dim;
    let m = n.min(MAX_COVARIANCE_ROWS);
    let mut x = DMatrix::<f64>::zeros(m, dim);
    for j in 0..m {
        let row = &features[(j * n / m) * dim..][..dim];
        for (c, (v, mu)) in row.iter().zip(mean).enumerate() {
            x[(j, c)] = f64::from(*v) - f64::from(*mu);
        }
    }
    let covariance = x.transpose() * &x;
    let eigen = SymmetricEigen::new(covariance);
    let mut order: Vec<usize> = (0..dim).collect();
    // largest eigenvalue first; the axis index breaks ties, so the choice is
    // deterministic
    order.sort_by(|&a, &b| {
        eigen.eigenvalues[b]
            .total_cmp(&eigen.eigenvalues[a])
            .then(a.cmp(&b))
    });
    for (r, &axis) in order.iter().take(dims).enumerate() {
        let v = eigen.eigenvectors.column(axis);
        for c in 0..dim {
            rows[r * dim + c] = v[c] as f32;
        }
    }
    rows
}

/// What the pruning bound needs to know about a stored projection `P`
/// (`dims × dim`, f32) and the database it projects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BoundConstants {
    /// An upper bound on the largest singular value σ of `P`: `‖P v‖ ≤ σ ‖v‖`
    /// for every `v`. Gershgorin on `P Pᵀ` (computed in f64, exact products
    /// of f32 values): √(max row sum of |P Pᵀ|), plus a hair.
    pub sigma: f64,
    /// `γ_{dim+2} ‖P‖_F`: the f32 rounding of a projected point is at most
    /// this times the norm of the centred point.
    pub projection_rounding: f64,
    /// The largest norm of a centred database point, `max ‖x − mean‖`.
    pub max_centred_norm: f64,
    /// `γ_{dim+2}`: relative error of a full squared distance in f32.
    pub full_rounding: f64,
    /// `γ_{dims+2}`: relative error of a projected squared distance in f32.
    pub projected_rounding: f64,
}

impl BoundConstants {
    /// The constants for projection `rows` (`dims × dim`) and the database
    /// `features` around `mean`.
    pub(crate) fn new(rows: &[f32], dim: usize, features: &[f32], mean: &[f32]) -> Self {
        let dims = rows.len() / dim;
        let row = |i: usize| &rows[i * dim..][..dim];
        let dot = |a: &[f32], b: &[f32]| -> f64 {
            a.iter()
                .zip(b)
                .map(|(x, y)| f64::from(*x) * f64::from(*y))
                .sum()
        };
        let mut max_row_sum = 0.0_f64;
        let mut frobenius_sq = 0.0_f64;
        for i in 0..dims {
            let sum: f64 = (0..dims).map(|j| dot(row(i), row(j)).abs()).sum();
            max_row_sum = max_row_sum.max(sum);
            frobenius_sq += dot(row(i), row(i));
        }
        let max_centred_sq = features
            .chunks_exact(dim)
            .map(|x| {
                x.iter()
                    .zip(mean)
                    .map(|(v, m)| (f64::from(*v) - f64::from(*m)).powi(2))
                    .sum::<f64>()
            })
            .fold(0.0_f64, f64::max);
        let full_rounding = gamma(dim + 2);
        Self {
            sigma: max_row_sum.sqrt() * (1.0 + 1e-12),
            projection_rounding: full_rounding * frobenius_sq.sqrt() * (1.0 + 1e-12),
            max_centred_norm: max_centred_sq.sqrt() * (1.0 + 1e-12),
            full_rounding,
            projected_rounding: gamma(dims + 2),
        }
    }

    /// The pruning threshold, as `(a, b)` with `T(f) = a √f + b`: a point
    /// whose computed projected squared distance exceeds `T(f)²` has a
    /// computed full squared distance above `f`, so it can neither beat nor
    /// tie a best-so-far of `f`. `query_centred_norm` is `‖q − mean‖`.
    ///
    /// From the bounds: `√p̂ ≤ √(1+γ_K) (‖P(x − q)‖ + ρ (‖x_c‖ + ‖q_c‖))`,
    /// `‖P(x − q)‖ ≤ σ ‖x − q‖`, and `‖x − q‖² ≤ f(x) / (1 − γ_D)`.
    pub(crate) fn threshold(&self, query_centred_norm: f64) -> (f64, f64) {
        let k = (1.0 + self.projected_rounding).sqrt();
        let a = k * self.sigma / (1.0 - self.full_rounding).sqrt();
        let b = k * self.projection_rounding * (self.max_centred_norm + query_centred_norm);
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_are_orthonormal_and_find_the_spread() {
        // points on a line along (1, 1, 0, 0, 0) plus a little on axis 2
        let dim = 5;
        let mut features = Vec::new();
        for i in 0..50 {
            let t = i as f32 - 25.0;
            features.extend([t, t, 0.01 * (i % 3) as f32, 0.0, 0.0]);
        }
        let mu = mean(&features, dim);
        let rows = principal_axes(&features, dim, &mu, 2);
        let first = &rows[..dim];
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((first[0].abs() - s).abs() < 1e-5 && (first[1] - first[0]).abs() < 1e-5);
        let c = BoundConstants::new(&rows, dim, &features, &mu);
        assert!(c.sigma >= 1.0 && c.sigma < 1.0 + 1e-6, "{c:?}");
    }

    #[test]
    fn narrow_features_get_the_identity_padded_with_zeros() {
        let rows = principal_axes(&[1.0, 2.0, 3.0, 4.0], 2, &[2.0, 3.0], 8);
        assert_eq!(&rows[..4], &[1.0, 0.0, 0.0, 1.0]);
        assert!(rows[4..].iter().all(|v| *v == 0.0));
    }
}
