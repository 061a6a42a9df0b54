//! The arithmetic every query shares: the full squared distance, one
//! projected coordinate, and the rounding-error constants of the exactness
//! bound (see the module docs of [`super`]).
//!
//! The full distance is computed in one fixed order whatever the CPU: 32
//! running sums, lane `l` taking the components `l, l + 32, l + 64, …`, then
//! the tail, then the lanes added pairwise in a fixed tree. The AVX2 and
//! AVX-512 builds of it (intrinsics, chosen at run time) only process 8 or 16
//! lanes per instruction, with the same separate multiply and add (no FMA),
//! so every build returns the same bits, and the index and the linear scan compare the very
//! same numbers (ties included). The projection on the principal axes is
//! likewise one order on every CPU ([`project`], 16 running sums a row);
//! its AVX2 and AVX-512 builds sum four rows at once, so a database's
//! projected points and a query's are the same bits wherever they are made.

/// Lanes of the distance kernel: two AVX-512 registers, four AVX2 ones, so
/// that independent sums hide the adder's latency.
const LANES: usize = 32;

/// Unit round-off of f32 (half an ulp of 1): `2^-24`.
pub(crate) const UNIT_ROUNDOFF: f64 = 1.0 / 16_777_216.0;

/// The classic bound `γ_n = n·u / (1 − n·u)` on the relative error of `n`
/// rounded f32 operations in a row (a sum of `n` non-negative terms, a dot
/// product of length `n`), for any order of summation.
pub(crate) fn gamma(n: usize) -> f64 {
    let nu = n as f64 * UNIT_ROUNDOFF;
    nu / (1.0 - nu).max(f64::MIN_POSITIVE)
}

/// Adds the squared differences of one chunk into the lanes.
#[inline(always)]
fn accumulate(acc: &mut [f32; LANES], x: &[f32; LANES], y: &[f32; LANES]) {
    for l in 0..LANES {
        let d = x[l] - y[l];
        acc[l] += d * d;
    }
}

/// The last, partial chunk of `a` and `b` padded with zeros (adding `+0.0`
/// to a non-negative lane sum changes no bit), if there is one.
#[inline(always)]
fn padded_tail(a: &[f32], b: &[f32]) -> Option<([f32; LANES], [f32; LANES])> {
    let start = a.len() - a.len() % LANES;
    if start == a.len() {
        return None;
    }
    let (mut x, mut y) = ([0.0_f32; LANES], [0.0_f32; LANES]);
    x[..a.len() - start].copy_from_slice(&a[start..]);
    y[..b.len() - start].copy_from_slice(&b[start..]);
    Some((x, y))
}

/// The fixed pairwise reduction of the lanes.
#[inline(always)]
fn reduce(mut acc: [f32; LANES]) -> f32 {
    for width in [16, 8, 4, 2, 1] {
        for l in 0..width {
            acc[l] += acc[l + width];
        }
    }
    acc[0]
}

/// Squared L2 distance between `a` and `b` (equal lengths), in the fixed
/// order described in the module docs; plain Rust.
fn squared_distance_portable(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0_f32; LANES];
    let (ca, _) = a.as_chunks::<LANES>();
    let (cb, _) = b.as_chunks::<LANES>();
    for (x, y) in ca.iter().zip(cb) {
        accumulate(&mut acc, x, y);
    }
    if let Some((x, y)) = padded_tail(a, b) {
        accumulate(&mut acc, &x, &y);
    }
    reduce(acc)
}

/// Defines `$name`, [`squared_distance_portable`] with `$width` lanes per
/// SIMD instruction of `$feature` (`LANES / $width` registers; separate
/// multiply and add, no FMA: the same roundings, so the same bits).
#[cfg(target_arch = "x86_64")]
macro_rules! simd_squared_distance {
    ($name:ident, $feature:literal, $width:literal, $vec:ident,
     $load:ident, $store:ident, $zero:ident, $sub:ident, $mul:ident, $add:ident) => {
        #[target_feature(enable = $feature)]
        fn $name(a: &[f32], b: &[f32]) -> f32 {
            use std::arch::x86_64::{$add, $load, $mul, $store, $sub, $vec, $zero};
            const REGS: usize = LANES / $width;
            #[target_feature(enable = $feature)]
            #[inline]
            fn step(acc: &mut [$vec; REGS], x: &[f32; LANES], y: &[f32; LANES]) {
                for (v, acc) in acc.iter_mut().enumerate() {
                    // SAFETY: x and y hold LANES = REGS × $width floats;
                    // unaligned loads.
                    let (p, q) = unsafe {
                        (
                            $load(x.as_ptr().add($width * v)),
                            $load(y.as_ptr().add($width * v)),
                        )
                    };
                    let d = $sub(p, q);
                    *acc = $add(*acc, $mul(d, d));
                }
            }
            let mut acc = [$zero(); REGS];
            let (ca, _) = a.as_chunks::<LANES>();
            let (cb, _) = b.as_chunks::<LANES>();
            for (x, y) in ca.iter().zip(cb) {
                step(&mut acc, x, y);
            }
            if let Some((x, y)) = padded_tail(a, b) {
                step(&mut acc, &x, &y);
            }
            let mut lanes = [0.0_f32; LANES];
            for (v, acc) in acc.iter().enumerate() {
                // SAFETY: lanes holds REGS × $width floats; unaligned store.
                unsafe { $store(lanes.as_mut_ptr().add($width * v), *acc) };
            }
            reduce(lanes)
        }
    };
}

/// Which build of the distance kernel this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kernel {
    /// Whatever the compile target allows (SSE2 on x86-64).
    Portable,
    /// AVX2, detected at run time.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// AVX-512F, detected at run time.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Kernel {
    /// The widest build this CPU supports.
    pub(crate) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                return Self::Avx512;
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                return Self::Avx2;
            }
        }
        Self::Portable
    }

    /// Squared L2 distance between `a` and `b` (equal lengths); the same bits
    /// whichever build runs.
    #[inline]
    pub(crate) fn squared_distance(self, a: &[f32], b: &[f32]) -> f32 {
        debug_assert_eq!(a.len(), b.len());
        match self {
            Self::Portable => squared_distance_portable(a, b),
            // SAFETY: `detect` chose this variant only after the CPU reported
            // the target feature the function is compiled for.
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => unsafe { squared_distance_avx2(a, b) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => unsafe { squared_distance_avx512(a, b) },
        }
    }

    /// The nearest of the rows of `features` (row-major, `query.len()` wide)
    /// to `query` by a linear scan: `(row, squared distance)`, the lowest row
    /// among equals. `features` must hold at least one row.
    pub(crate) fn nearest_linear(self, features: &[f32], query: &[f32]) -> (usize, f32) {
        match self {
            Self::Portable => nearest_linear_portable(features, query),
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => unsafe { nearest_linear_avx2(features, query) },
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => unsafe { nearest_linear_avx512(features, query) },
        }
    }

    /// Whether every value of `values` lies within `±limit` (false when one
    /// is NaN).
    #[inline]
    pub(crate) fn all_within(self, values: &[f32], limit: f32) -> bool {
        match self {
            Self::Portable => all_within_with(values, limit),
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => unsafe { all_within_avx2(values, limit) },
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => unsafe { all_within_avx512(values, limit) },
        }
    }

    /// [`project`] (its bits) in this build: `x − mean` on the rows of
    /// `rows` (each `x.len()` wide) into `out`, one value a row.
    #[inline]
    pub(crate) fn project(self, rows: &[f32], mean: &[f32], x: &[f32], out: &mut [f32]) {
        // the SIMD builds read `x.len()` values of `mean`
        if mean.len() != x.len() {
            debug_assert!(false, "mean and x differ in length");
            return project(rows, mean, x, out);
        }
        match self {
            Self::Portable => project(rows, mean, x, out),
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => unsafe { project_avx2(rows, mean, x, out) },
            // SAFETY: as in `squared_distance`.
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => unsafe { project_avx512(rows, mean, x, out) },
        }
    }
}

/// Whether every value lies within `±limit` (false for a NaN): one
/// branch-free pass that the SIMD builds compare 8 or 16 values at a time.
#[inline(always)]
fn all_within_with(values: &[f32], limit: f32) -> bool {
    values.iter().fold(true, |ok, v| ok & (v.abs() <= limit))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn all_within_avx2(values: &[f32], limit: f32) -> bool {
    all_within_with(values, limit)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn all_within_avx512(values: &[f32], limit: f32) -> bool {
    all_within_with(values, limit)
}

/// The linear scan, with the distance kernel `dist` inlined into the loop.
#[inline(always)]
fn nearest_linear_with(
    features: &[f32],
    query: &[f32],
    dist: impl Fn(&[f32], &[f32]) -> f32,
) -> (usize, f32) {
    let mut best = (0, f32::INFINITY);
    for (i, row) in features.chunks_exact(query.len()).enumerate() {
        let d = dist(row, query);
        if d < best.1 {
            best = (i, d);
        }
    }
    best
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn nearest_linear_avx512(features: &[f32], query: &[f32]) -> (usize, f32) {
    nearest_linear_with(features, query, |a, b| squared_distance_avx512(a, b))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn nearest_linear_avx2(features: &[f32], query: &[f32]) -> (usize, f32) {
    nearest_linear_with(features, query, |a, b| squared_distance_avx2(a, b))
}

fn nearest_linear_portable(features: &[f32], query: &[f32]) -> (usize, f32) {
    nearest_linear_with(features, query, squared_distance_portable)
}

/// Lanes of the projection's sums: coordinate `l` of a 16-wide chunk goes
/// to lane `l` (see [`project`]).
const PROJECT_LANES: usize = 16;

/// Rows the SIMD projections sum at once: independent sums that hide the
/// adder's latency, sharing each chunk's `x − mean`.
const PROJECT_GROUP: usize = 4;

/// The end of one row's projection: the tail's components (fewer than
/// [`PROJECT_LANES`]) into lanes `0, 1, …`, then the lanes summed in order.
#[inline(always)]
fn project_tail(mut acc: [f32; PROJECT_LANES], row: &[f32], mean: &[f32], x: &[f32]) -> f32 {
    let start = x.len() - x.len() % PROJECT_LANES;
    for (l, ((r, m), v)) in row[start..]
        .iter()
        .zip(&mean[start..])
        .zip(&x[start..])
        .enumerate()
    {
        acc[l] += r * (v - m);
    }
    acc.iter().sum()
}

/// Projects `x − mean` on the rows of `rows` (each `x.len()` wide) into
/// `out` (one value per row): the coordinates the k-d tree holds. Plain
/// Rust, the reference: per row 16 running sums, lane `l` taking the
/// components `l, l + 16, …` (`r · (v − m)`, a separate multiply and add),
/// the tail into lanes `0, 1, …`, then the lanes summed in order.
pub(crate) fn project(rows: &[f32], mean: &[f32], x: &[f32], out: &mut [f32]) {
    for (o, row) in out.iter_mut().zip(rows.chunks_exact(x.len())) {
        *o = project_row(row, mean, x);
    }
}

/// One row of [`project`].
#[inline(always)]
fn project_row(row: &[f32], mean: &[f32], x: &[f32]) -> f32 {
    let mut acc = [0.0_f32; PROJECT_LANES];
    let (cr, _) = row.as_chunks::<PROJECT_LANES>();
    let (cm, _) = mean.as_chunks::<PROJECT_LANES>();
    let (cx, _) = x.as_chunks::<PROJECT_LANES>();
    for ((r, m), v) in cr.iter().zip(cm).zip(cx) {
        for l in 0..PROJECT_LANES {
            acc[l] += r[l] * (v[l] - m[l]);
        }
    }
    project_tail(acc, row, mean, x)
}

/// Defines `$name`, [`project`] with `$width` lanes per SIMD instruction of
/// `$feature`: [`PROJECT_GROUP`] rows at a time, each chunk's `x − mean`
/// made once for them, every lane's sum the reference's (the same
/// operations in the same order, no FMA: the same bits). Rows past the
/// last whole group go as the reference's.
#[cfg(target_arch = "x86_64")]
macro_rules! simd_project {
    ($name:ident, $feature:literal, $width:literal,
     $load:ident, $store:ident, $zero:ident, $sub:ident, $mul:ident, $add:ident) => {
        #[target_feature(enable = $feature)]
        fn $name(rows: &[f32], mean: &[f32], x: &[f32], out: &mut [f32]) {
            use std::arch::x86_64::{$add, $load, $mul, $store, $sub, $zero};
            const REGS: usize = PROJECT_LANES / $width;
            let dim = x.len();
            let chunks = dim / PROJECT_LANES;
            let n = out.len().min(rows.len() / dim.max(1));
            let whole = n - n % PROJECT_GROUP;
            for g in (0..whole).step_by(PROJECT_GROUP) {
                let mut acc = [[$zero(); REGS]; PROJECT_GROUP];
                for c in 0..chunks {
                    for k in 0..REGS {
                        let at = c * PROJECT_LANES + k * $width;
                        // SAFETY: `at + $width <= chunks * 16 <= dim`, the
                        // length of `x` and `mean`, and row `g + j` (`< n`)
                        // lies within `rows`; unaligned loads.
                        unsafe {
                            let d = $sub($load(x.as_ptr().add(at)), $load(mean.as_ptr().add(at)));
                            for (j, acc) in acc.iter_mut().enumerate() {
                                let r = $load(rows.as_ptr().add((g + j) * dim + at));
                                acc[k] = $add(acc[k], $mul(r, d));
                            }
                        }
                    }
                }
                for (j, acc) in acc.iter().enumerate() {
                    let mut lanes = [0.0_f32; PROJECT_LANES];
                    for (k, v) in acc.iter().enumerate() {
                        // SAFETY: lanes holds REGS × $width floats; unaligned store.
                        unsafe { $store(lanes.as_mut_ptr().add(k * $width), *v) };
                    }
                    let row = &rows[(g + j) * dim..(g + j + 1) * dim];
                    out[g + j] = project_tail(lanes, row, mean, x);
                }
            }
            for (o, row) in out[whole..n]
                .iter_mut()
                .zip(rows[whole * dim..].chunks_exact(dim))
            {
                *o = project_row(row, mean, x);
            }
        }
    };
}

/// Both SIMD kernels of one instruction set: the distance
/// ([`simd_squared_distance`]) and the projection ([`simd_project`]).
#[cfg(target_arch = "x86_64")]
macro_rules! simd_kernels {
    ($distance:ident, $project:ident, $feature:literal, $width:literal, $vec:ident,
     $load:ident, $store:ident, $zero:ident, $sub:ident, $mul:ident, $add:ident) => {
        simd_squared_distance!(
            $distance, $feature, $width, $vec, $load, $store, $zero, $sub, $mul, $add
        );
        simd_project!(
            $project, $feature, $width, $load, $store, $zero, $sub, $mul, $add
        );
    };
}

#[cfg(target_arch = "x86_64")]
simd_kernels!(
    squared_distance_avx2,
    project_avx2,
    "avx2",
    8,
    __m256,
    _mm256_loadu_ps,
    _mm256_storeu_ps,
    _mm256_setzero_ps,
    _mm256_sub_ps,
    _mm256_mul_ps,
    _mm256_add_ps
);

#[cfg(target_arch = "x86_64")]
simd_kernels!(
    squared_distance_avx512,
    project_avx512,
    "avx512f",
    16,
    __m512,
    _mm512_loadu_ps,
    _mm512_storeu_ps,
    _mm512_setzero_ps,
    _mm512_sub_ps,
    _mm512_mul_ps,
    _mm512_add_ps
);

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Every build of the kernels this CPU runs, the portable one first.
    pub(crate) fn every_kernel() -> Vec<Kernel> {
        let mut kernels = vec![Kernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                kernels.push(Kernel::Avx2);
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                kernels.push(Kernel::Avx512);
            }
        }
        kernels
    }

    #[test]
    fn every_build_returns_the_same_bits() {
        let a: Vec<f32> = (0..261).map(|i| (i as f32 * 0.37).sin() * 3.1).collect();
        let b: Vec<f32> = (0..261).map(|i| (i as f32 * 0.11).cos() * 2.7).collect();
        let kernels = every_kernel();
        for n in [1, 15, 16, 17, 31, 32, 33, 64, 255, 256, 261] {
            let want = squared_distance_portable(&a[..n], &b[..n]);
            for k in &kernels {
                let got = k.squared_distance(&a[..n], &b[..n]);
                assert_eq!(got.to_bits(), want.to_bits(), "{k:?}, n = {n}");
                let rows: Vec<f32> = b[..n].iter().chain(&a[..n]).copied().collect();
                assert_eq!(k.nearest_linear(&rows, &a[..n]), (1, 0.0));
            }
            let exact: f64 = a[..n]
                .iter()
                .zip(&b[..n])
                .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
                .sum();
            assert!((f64::from(want) - exact).abs() <= gamma(n + 2) * exact);
        }
    }

    /// Every build projects to the reference's bits, for widths with and
    /// without a tail and row counts with and without a partial group.
    #[test]
    fn every_build_projects_the_same_bits() {
        let kernels = every_kernel();
        for dim in [1, 15, 16, 17, 40, 256, 261] {
            let x: Vec<f32> = (0..dim).map(|i| (i as f32 * 0.37).sin() * 3.1).collect();
            let mean: Vec<f32> = (0..dim).map(|i| (i as f32 * 0.23).cos() * 0.4).collect();
            for n in [1, 3, 4, 7, 8, 12, 16] {
                let rows: Vec<f32> = (0..n * dim)
                    .map(|i| (i as f32 * 0.11 + 0.5).sin() * 0.9)
                    .collect();
                let mut want = vec![0.0_f32; n];
                project(&rows, &mean, &x, &mut want);
                for k in &kernels {
                    let mut got = vec![f32::NAN; n];
                    k.project(&rows, &mean, &x, &mut got);
                    let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&got), bits(&want), "{k:?}, dim {dim}, rows {n}");
                }
            }
        }
    }

    #[test]
    fn linear_scan_keeps_the_lowest_row_of_equals() {
        let features = [1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0];
        assert_eq!(
            Kernel::detect().nearest_linear(&features, &[0.0, 0.0]),
            (1, 0.0)
        );
        assert_eq!(
            Kernel::detect().nearest_linear(&features, &[1.0, 1.0]),
            (0, 0.0)
        );
    }

    #[test]
    fn projection_of_the_mean_is_zero() {
        let rows = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let mean = [0.5, -2.0, 3.0];
        let mut out = [9.0; 2];
        project(&rows, &mean, &mean, &mut out);
        assert_eq!(out, [0.0, 0.0]);
        project(&rows, &mean, &[1.5, -1.0, 0.0], &mut out);
        assert_eq!(out, [1.0, 1.0]);
    }
}
