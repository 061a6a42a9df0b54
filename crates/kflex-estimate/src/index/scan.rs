//! The projected points laid out for a scan: every point's projected squared
//! distance in one pass, without a tree walk. For the few hundred points of
//! one of IBJAE's bands this is cheaper than kiddo's two walks (a query's
//! fixed cost is most of its time there); the tree wins on larger indexes
//! (see [`SCAN_MAX_POINTS`]).
//!
//! The points are stored by coordinate (structure of arrays), padded to a
//! whole number of [`BLOCK`]s with a far value, so that one block's
//! distances are `K` subtract-multiply-adds of [`BLOCK`] lanes each: the
//! compiler vectorises them for AVX2 and AVX-512 ([`Kernel`] picks the build).
//! Each distance is a sum of `K` rounded squares in coordinate order, with
//! separate multiply and add, so the exactness bound that covers kiddo's
//! projected distances (any order of `K` terms) covers these too.

use std::mem::MaybeUninit;

use kflex_model::Bounds;

use super::ProjectionDims;
use super::kernel::Kernel;
use super::tree::MAX_DIMS;
use crate::error::Result;

/// Points whose distances one block computes together.
pub(crate) const BLOCK: usize = 16;

/// The largest index searched by scan rather than by the tree. Measured
/// with `index_bench time` on the synthetic manifold and a trained band
/// (see the module docs of [`super`]).
pub(crate) const SCAN_MAX_POINTS: usize = 2048;

/// Blocks of the largest scanned index.
const MAX_BLOCKS: usize = SCAN_MAX_POINTS / BLOCK;

/// Room for one query's block distances, kept from the nearest-point pass
/// for the pass over the pruning ball (on the stack, not initialised: 8 KB
/// of zeros would cost a small index's query a third of its time).
pub(crate) type Scratch = [MaybeUninit<[f32; BLOCK]>; MAX_BLOCKS];

/// A fresh [`Scratch`].
pub(crate) fn scratch() -> Scratch {
    [const { MaybeUninit::uninit() }; MAX_BLOCKS]
}

/// Padding coordinate: its square overflows to `+∞`, so a padded slot is
/// never within any finite bound.
const FAR: f32 = f32::MAX;

/// Checks an index of `len` points can be scanned (at most
/// [`SCAN_MAX_POINTS`]: the stack's room for their distances).
pub(crate) fn check_len(len: usize) -> Result<()> {
    Bounds::closed(1.0, SCAN_MAX_POINTS as f64)
        .check("points of an index searched by scan", len as f64)?;
    Ok(())
}

/// The projected points, a block of [`BLOCK`] at a time.
pub(crate) struct ProjectedScan {
    /// `K`, the projection's width.
    dims: ProjectionDims,
    /// Real points.
    len: usize,
    /// Block after block, each `K` rows of [`BLOCK`] values: coordinate `k`
    /// of point `b·BLOCK + l` at `(b·K + k)·BLOCK + l`.
    coords: Vec<f32>,
}

impl ProjectedScan {
    /// The scan over `points` (row-major, `dims` wide), point `i` being row `i`.
    ///
    /// # Errors
    /// [`crate::EstimateError::OutOfRange`] for more than
    /// [`SCAN_MAX_POINTS`] points (or none).
    pub(crate) fn new(points: &[f32], dims: ProjectionDims) -> Result<Self> {
        let k = dims.get();
        let len = points.len() / k;
        check_len(len)?;
        let blocks = len.div_ceil(BLOCK);
        let mut coords = vec![FAR; blocks * k * BLOCK];
        for (i, p) in points.chunks_exact(k).enumerate() {
            let (b, l) = (i / BLOCK, i % BLOCK);
            for (c, v) in p.iter().enumerate() {
                coords[(b * k + c) * BLOCK + l] = *v;
            }
        }
        Ok(Self { dims, len, coords })
    }

    /// The nearest point to `query` (its first `K` values) in the
    /// projected space, the lowest index among equals, with its projected
    /// squared distance; and every point's projected squared distance,
    /// block by block, kept in `scratch` (see [`within`]).
    pub(crate) fn nearest<'s>(
        &self,
        kernel: Kernel,
        query: &[f32; MAX_DIMS],
        scratch: &'s mut Scratch,
    ) -> (usize, f32, &'s [[f32; BLOCK]]) {
        // one build per width: the query's coordinates stay in registers
        let ((first, least), blocks) = match self.dims {
            ProjectionDims::K8 => nearest_k::<8>(kernel, &self.coords, query, scratch),
            ProjectionDims::K12 => nearest_k::<12>(kernel, &self.coords, query, scratch),
            ProjectionDims::K16 => nearest_k::<16>(kernel, &self.coords, query, scratch),
        };
        // SAFETY: `nearest` wrote the first `blocks` entries of `scratch`
        // (`MaybeUninit<T>` has `T`'s layout).
        let kept =
            unsafe { std::slice::from_raw_parts(scratch.as_ptr().cast::<[f32; BLOCK]>(), blocks) };
        (first, least, kept)
    }

    /// Points in the scan.
    pub(crate) fn len(&self) -> usize {
        self.len
    }
}

/// Calls `visit(point, projected squared distance)` for every one of the
/// first `len` points of `blocks` (as [`ProjectedScan::nearest`] kept them),
/// in index order, whose distance is at most the bound `visit` returned
/// last (`bound` at first).
pub(crate) fn within(
    blocks: &[[f32; BLOCK]],
    len: usize,
    mut bound: f32,
    mut visit: impl FnMut(usize, f32) -> f32,
) {
    for (b, d) in blocks.iter().enumerate() {
        if d.iter().fold(false, |any, &v| any | (v <= bound)) {
            for (l, &v) in d.iter().enumerate() {
                let i = b * BLOCK + l;
                if v <= bound && i < len {
                    bound = visit(i, v);
                }
            }
        }
    }
}

/// One block's projected squared distances: the sum over coordinates of
/// `(x_k − q_k)²`, coordinate order, separate multiply and add.
#[inline(always)]
fn block_distances<const K: usize>(block: &[f32], q: &[f32; K]) -> [f32; BLOCK] {
    let mut acc = [0.0_f32; BLOCK];
    let (rows, _) = block.as_chunks::<BLOCK>();
    for (row, &qk) in rows.iter().zip(q) {
        for l in 0..BLOCK {
            let d = row[l] - qk;
            acc[l] += d * d;
        }
    }
    acc
}

/// [`ProjectedScan::nearest`] for a projection `K` wide, in the kernel's build.
fn nearest_k<const K: usize>(
    kernel: Kernel,
    coords: &[f32],
    query: &[f32; MAX_DIMS],
    scratch: &mut Scratch,
) -> ((usize, f32), usize) {
    let q: &[f32; K] = query[..K].try_into().expect("K <= MAX_DIMS");
    match kernel {
        Kernel::Portable => nearest(coords, q, scratch),
        // SAFETY: `Kernel::detect` chose this variant only after the CPU
        // reported the target feature the function is compiled for.
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx2 => unsafe { nearest_avx2(coords, q, scratch) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Kernel::Avx512 => unsafe { nearest_avx512(coords, q, scratch) },
    }
}

/// [`ProjectedScan::nearest`] over `coords`: the nearest point and its
/// distance, and how many blocks of `scratch` it wrote.
#[inline(always)]
fn nearest<const K: usize>(
    coords: &[f32],
    q: &[f32; K],
    scratch: &mut Scratch,
) -> ((usize, f32), usize) {
    // per lane the least distance and the first block that has it
    // (lane-wise compare and select: no reduction per block)
    let mut least = [f32::INFINITY; BLOCK];
    let mut first = [0_u32; BLOCK];
    let mut written = 0;
    for (b, (block, kept)) in coords
        .chunks_exact(K * BLOCK)
        .zip(scratch.iter_mut())
        .enumerate()
    {
        let d = block_distances(block, q);
        kept.write(d);
        written = b + 1;
        for l in 0..BLOCK {
            let nearer = d[l] < least[l];
            least[l] = if nearer { d[l] } else { least[l] };
            first[l] = if nearer { b as u32 } else { first[l] };
        }
    }
    // then across the lanes: the least value, the lowest point among equals
    let mut best = (0, f32::INFINITY);
    for l in 0..BLOCK {
        let i = first[l] as usize * BLOCK + l;
        if least[l] < best.1 || (least[l] == best.1 && i < best.0) {
            best = (i, least[l]);
        }
    }
    (best, written)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn nearest_avx2<const K: usize>(
    coords: &[f32],
    q: &[f32; K],
    scratch: &mut Scratch,
) -> ((usize, f32), usize) {
    nearest(coords, q, scratch)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn nearest_avx512<const K: usize>(
    coords: &[f32],
    q: &[f32; K],
    scratch: &mut Scratch,
) -> ((usize, f32), usize) {
    nearest(coords, q, scratch)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every build the CPU runs (and the portable one) finds the same
    /// nearest point and keeps the same distances, for every width and for
    /// sizes around the blocks.
    #[test]
    fn every_build_scans_alike() {
        let kernels = super::super::kernel::tests::every_kernel();
        // a fixed, uneven sequence of values, with ties
        let value = |i: usize| ((i * 7919) % 61) as f32 * 0.25 - 7.0;
        for dims in ProjectionDims::ALL {
            let k = dims.get();
            for len in [1, 15, 16, 17, 200] {
                let points: Vec<f32> = (0..len * k).map(value).collect();
                let scan = ProjectedScan::new(&points, dims).unwrap();
                let mut query = [0.0_f32; MAX_DIMS];
                for (c, q) in query.iter_mut().take(k).enumerate() {
                    *q = value(c * 13 + 5);
                }
                let mut answers = Vec::new();
                for &kernel in &kernels {
                    let mut scratch = scratch();
                    let (first, least, blocks) = scan.nearest(kernel, &query, &mut scratch);
                    let kept: Vec<f32> = blocks.iter().flatten().copied().collect();
                    // the reference: each point's sum of squares in order
                    let reference: Vec<f32> = points
                        .chunks_exact(k)
                        .map(|p| {
                            p.iter().zip(&query).fold(0.0_f32, |acc, (x, q)| {
                                let d = x - q;
                                acc + d * d
                            })
                        })
                        .collect();
                    assert_eq!(&kept[..len], &reference[..], "{kernel:?}");
                    let best = reference.iter().copied().fold(f32::INFINITY, f32::min);
                    let lowest = reference.iter().position(|&v| v == best).unwrap();
                    assert_eq!((first, least), (lowest, best), "{kernel:?}");
                    let mut visited = Vec::new();
                    within(blocks, len, best, |i, p| {
                        visited.push((i, p));
                        best
                    });
                    let expect: Vec<(usize, f32)> = reference
                        .iter()
                        .copied()
                        .enumerate()
                        .filter(|&(_, p)| p <= best)
                        .collect();
                    assert_eq!(visited, expect, "{kernel:?}");
                    answers.push((first, least));
                }
                assert!(answers.windows(2).all(|w| w[0] == w[1]));
            }
        }
        // more points than the stack holds are refused
        let many = vec![0.0_f32; (SCAN_MAX_POINTS + 1) * 8];
        assert!(ProjectedScan::new(&many, ProjectionDims::K8).is_err());
    }
}
