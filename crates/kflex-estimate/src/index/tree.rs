//! The k-d tree over the projected features: kiddo's `ImmutableKdTree`, one
//! monomorphisation per supported projection width.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::ProjectionDims;
use crate::error::{EstimateError, Result};

/// The widest supported projection: the size of a projected query on the stack.
pub(crate) const MAX_DIMS: usize = 16;

/// kiddo's immutable tree of `K`-dimensional f32 points, items `u32`.
pub(crate) enum ProjectedTree {
    K8(ImmutableKdTree<f32, 8>),
    K12(ImmutableKdTree<f32, 12>),
    K16(ImmutableKdTree<f32, 16>),
}

/// Runs `$body` with `$t` bound to the tree, whatever its width, and `$q`
/// to the first `K` values of the query buffer as `&[f32; K]`.
macro_rules! with_tree {
    ($tree:expr, $query:expr, |$t:ident, $q:ident| $body:expr) => {
        match $tree {
            ProjectedTree::K8($t) => {
                let $q: &[f32; 8] = first($query);
                $body
            }
            ProjectedTree::K12($t) => {
                let $q: &[f32; 12] = first($query);
                $body
            }
            ProjectedTree::K16($t) => {
                let $q: &[f32; 16] = first($query);
                $body
            }
        }
    };
}

/// The first `K` values of a projected query buffer.
fn first<const K: usize>(q: &[f32; MAX_DIMS]) -> &[f32; K] {
    q[..K].try_into().expect("K <= MAX_DIMS")
}

fn build<const K: usize>(points: &[f32]) -> Result<ImmutableKdTree<f32, K>> {
    let rows: Vec<[f32; K]> = points
        .chunks_exact(K)
        .map(|c| c.try_into().expect("chunks of K"))
        .collect();
    ImmutableKdTree::new_from_slice(&rows).map_err(|_| EstimateError::Length {
        what: "feature vectors (at most u32::MAX points)",
        expected: u32::MAX as usize,
        got: rows.len(),
    })
}

impl ProjectedTree {
    /// A tree over `points` (row-major, `dims.get()` wide), item `i` being row `i`.
    pub(crate) fn new(points: &[f32], dims: ProjectionDims) -> Result<Self> {
        Ok(match dims {
            ProjectionDims::K8 => Self::K8(build(points)?),
            ProjectionDims::K12 => Self::K12(build(points)?),
            ProjectionDims::K16 => Self::K16(build(points)?),
        })
    }

    /// The row nearest to `query` (its first `dims` values) in the projected
    /// space: `(row, projected squared distance)`.
    pub(crate) fn nearest_one(&self, query: &[f32; MAX_DIMS]) -> (usize, f32) {
        with_tree!(self, query, |t, q| {
            let n = t.query(q).nearest_one::<SquaredEuclidean<f32>>().execute();
            (n.item as usize, n.distance)
        })
    }

    /// Calls `visit(row, projected squared distance)` for every row within
    /// squared distance `radius_sq` of `query` (ends included), in no
    /// particular order. Allocates nothing after kiddo's per-thread scratch
    /// exists (the first query on a thread creates it).
    pub(crate) fn within<F: FnMut(usize, f32)>(
        &self,
        query: &[f32; MAX_DIMS],
        radius_sq: f32,
        mut visit: F,
    ) {
        with_tree!(self, query, |t, q| {
            t.query(q)
                .within::<SquaredEuclidean<f32>>(radius_sq)
                .unsorted()
                .visit(|r| visit(r.item as usize, r.distance))
        })
    }
}
