//! IBJAE's feature index: the exact nearest neighbour of an embedding among
//! the database's, fast at 256 dimensions (cargo feature `index`).
//!
//! IBJAE (the paper's image-based estimator) embeds the segmented 48×48
//! silhouette with the Siamese CNN and returns the pose (θ, d) of the nearest
//! database embedding. [`FeatureIndex`] holds those embeddings (f32, any
//! dimension `D ≥ 1`; 256 for the SCNN) with one [`Pose`] each, answers
//! nearest-neighbour queries exactly, and reads and writes the database file
//! (see [`FeatureIndex::save`]).
//!
//! # How it is fast
//!
//! A k-d tree over 256 dimensions prunes almost nothing and is slower than a
//! linear scan below some 50,000 points. So the tree (kiddo's
//! `ImmutableKdTree`) is built over an orthonormal projection of the
//! mean-centred features on their `K` leading principal axes (`K` = 8, 12 or
//! 16; [`IndexParams::projection_dims`]), computed at build time from the
//! covariance (nalgebra's symmetric eigen-decomposition). An embedding of a
//! two-parameter family of images lies near a two-dimensional surface, so
//! those few axes carry almost all of its spread.
//!
//! On a small index the tree's walks are most of a query's time: one of
//! IBJAE's bands holds a few hundred points. Up to
//! [`Search::SCAN_MAX_POINTS`] points ([`Search::Auto`]) the projected
//! points are instead kept coordinate by coordinate, and one vectorised pass
//! computes every projected distance (16 points to an AVX-512 instruction),
//! keeping them for the pass over the pruning ball below: the same
//! candidates, no tree walk. On the synthetic manifold the scan takes half
//! the tree's time at 500 points and 0.8 of it at 2,000, and loses from
//! about 3,000 (`index_bench time --search tree|scan`).
//!
//! # Why it is exact
//!
//! For an orthonormal projection `P`, `‖P(x − q)‖ ≤ ‖x − q‖`: a projected
//! distance never exceeds the full one. A query (1) projects `q`, (2) takes
//! the nearest point in projected space (the tree's or the scan's) and
//! computes its full distance `f`, then (3) visits every point whose
//! projected distance is within `f` and computes their full distances,
//! keeping the best and shrinking the bound as it goes. A point outside that ball has a full distance larger
//! than `f`, so it cannot be the nearest: the answer is the exact nearest
//! neighbour, not an approximation.
//!
//! In floating point the bound is kept with explicit slack, so that no point
//! the linear scan would return can be pruned by rounding. The full squared
//! distance is computed in f32 in one fixed order (the same bits on every
//! CPU, and the same function [`FeatureIndex::nearest_linear`] uses); its
//! relative error is at most `γ_{D+2}` (`γ_n = n·u/(1 − n·u)`, `u = 2⁻²⁴`).
//! The stored f32 projection is only nearly orthonormal, so its largest
//! singular value `σ` is bounded at build time (Gershgorin on `P Pᵀ`, in
//! f64); projecting a point rounds it by at most `γ_{D+2} ‖P‖_F ‖x − mean‖`;
//! the projected squared distance adds `γ_{K+2}` (kiddo's, or the scan's:
//! the same `K` rounded squares, summed in another order). Together: a point
//! whose computed projected squared distance exceeds
//! `T(f)² = (√(1+γ_{K+2}) (σ √(f/(1−γ_{D+2})) + γ_{D+2} ‖P‖_F (R + ‖q − mean‖)))²`
//! (`R` the largest centred norm in the database, plus a term for
//! underflow; `‖q − mean‖ ≤ ‖q − x‖ + R` for the first point `x`, whose
//! full distance the search has in hand) has a computed full distance above
//! `f`. The radius handed to kiddo or the scan is `T(f)²` with another 10⁻⁴
//! relative slack for kiddo's own pruning arithmetic. For 256-d embeddings of norm ~1 this slack is ~10⁻⁴ of the
//! neighbour distance: it costs nothing measurable. So the index returns
//! exactly what the linear scan returns, bit for bit, ties included.
//!
//! **Ties**: among points at the same (computed) distance, the lowest index
//! wins, in the index and in the linear scan alike.
//!
//! **Distances** are squared L2 in feature units ([`Neighbour::distance_sq`];
//! [`Neighbour::distance`] takes the root).
//!
//! **Allocation**: a query allocates nothing once kiddo's per-thread query
//! scratch exists (created by the first query on each thread; the scan
//! keeps its distances on the stack, 8 KB);
//! `crates/kflex-estimate/tests/index_no_alloc.rs` holds that with a
//! counting allocator.

mod file;
mod kernel;
mod pca;
mod scan;
mod tree;

use std::collections::BTreeMap;

use kflex_model::Bounds;
use serde::{Deserialize, Serialize};

use crate::error::{EstimateError, Result};
use kernel::Kernel;
use pca::BoundConstants;
use scan::{ProjectedScan, SCAN_MAX_POINTS};
use tree::{MAX_DIMS, ProjectedTree};

pub use file::FORMAT_VERSION;

/// Largest magnitude a feature or query component may have: keeps every
/// squared distance finite in f32 for any dimension below 8·10⁷.
pub const MAX_FEATURE_ABS: f64 = 1e15;

/// The largest f32 not above [`MAX_FEATURE_ABS`] (`1e15` rounds up in f32).
const MAX_FEATURE_ABS_F32: f32 = 999_999_986_991_104.0;

/// The label of a database point: the pose its image was rendered at
/// (f64, as every angle and length of the workspace's API).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Bend θ of the continuum joint, deg.
    pub theta_deg: f64,
    /// Translation d of the instrument out of the overtube, mm.
    pub translation_mm: f64,
}

/// A nearest neighbour: which database point, its pose, and how far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Neighbour {
    /// Row of the point in the database, counted from 0.
    pub index: usize,
    /// Its pose (the label IBJAE returns).
    pub pose: Pose,
    /// Squared L2 distance from the query, in squared feature units (f32, as
    /// computed by the fixed-order kernel both searches share).
    pub distance_sq: f32,
}

impl Neighbour {
    /// Plain L2 distance from the query, in feature units.
    #[must_use]
    pub fn distance(&self) -> f32 {
        self.distance_sq.sqrt()
    }
}

/// How much work one exact query did (see [`FeatureIndex::nearest_with_stats`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SearchStats {
    /// Full `D`-dimensional distances computed (a linear scan computes one per point).
    pub full_distances: usize,
    /// Points visited inside the pruning ball (the tree's: as it stood when
    /// the walk began; the scan's: as it stood at each point).
    pub candidates: usize,
}

/// `K`, the number of principal axes the k-d tree is built over (kiddo's
/// tree dimension is a compile-time constant, so the choice is among these).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum ProjectionDims {
    /// 8 axes: the default, the fastest of the three on the synthetic 256-d
    /// embedding manifold at every size measured (README, "Feature index").
    #[default]
    K8,
    /// 12 axes.
    K12,
    /// 16 axes.
    K16,
}

impl ProjectionDims {
    /// All supported widths, narrowest first.
    pub const ALL: [ProjectionDims; 3] = [Self::K8, Self::K12, Self::K16];

    /// The number of axes.
    #[must_use]
    pub const fn get(self) -> usize {
        match self {
            Self::K8 => 8,
            Self::K12 => 12,
            Self::K16 => 16,
        }
    }

    /// The width with `k` axes, if supported.
    #[must_use]
    pub fn from_count(k: usize) -> Option<Self> {
        Self::ALL.into_iter().find(|d| d.get() == k)
    }
}

/// How a query finds its candidates in the projected space (the answer is
/// the same exact nearest neighbour either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Search {
    /// [`Search::Scan`] up to [`Search::SCAN_MAX_POINTS`] points, the tree
    /// above: the faster of the two at each size (README, "Feature index").
    #[default]
    Auto,
    /// kiddo's k-d tree: one walk for the nearest projected point, one for
    /// the points inside the pruning ball.
    Tree,
    /// Every point's projected distance in one vectorised pass, kept for
    /// the pass over the pruning ball: no tree walk. For at most
    /// [`Search::SCAN_MAX_POINTS`] points.
    Scan,
}

impl Search {
    /// The most points [`Search::Scan`] takes (and [`Search::Auto`] scans).
    /// Above about 3,000 points the tree is faster (measured on the
    /// synthetic manifold, `index_bench time --search`).
    pub const SCAN_MAX_POINTS: usize = SCAN_MAX_POINTS;

    /// What `self` means for an index of `len` points: `Tree` or `Scan`.
    fn resolve(self, len: usize) -> Result<Self> {
        match self {
            Self::Auto if len <= SCAN_MAX_POINTS => Ok(Self::Scan),
            Self::Auto => Ok(Self::Tree),
            Self::Scan => {
                scan::check_len(len)?;
                Ok(Self::Scan)
            }
            other => Ok(other),
        }
    }
}

/// How to build a [`FeatureIndex`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct IndexParams {
    /// `K`: principal axes the k-d tree (or the scan) works in.
    pub projection_dims: ProjectionDims,
    /// How a query finds its candidates in that space.
    pub search: Search,
}

/// An exact nearest-neighbour index over `N` feature vectors of dimension
/// `D`, each labelled with the [`Pose`] it was rendered at: IBJAE's
/// database (see the [module docs](self) for the method and why it is exact).
pub struct FeatureIndex {
    dim: usize,
    features: Vec<f32>,
    poses: Vec<Pose>,
    mean: Vec<f32>,
    axes: Vec<f32>,
    projection: ProjectionDims,
    metadata: BTreeMap<String, String>,
    tree: ProjectedTree,
    scan: Option<ProjectedScan>,
    /// `Tree` or `Scan` (resolved from the build's [`Search`]).
    search: Search,
    bound: BoundConstants,
    kernel: Kernel,
}

impl std::fmt::Debug for FeatureIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FeatureIndex")
            .field("len", &self.poses.len())
            .field("dim", &self.dim)
            .field("projection_dims", &self.projection.get())
            .field("metadata", &self.metadata)
            .finish_non_exhaustive()
    }
}

/// Checks every component of `rows` (`dim` wide) is finite and within
/// [`MAX_FEATURE_ABS`].
fn check_values(kernel: Kernel, what: &'static str, rows: &[f32], dim: usize) -> Result<()> {
    // the common case in one branch-free pass (in f32 against the same
    // limit, in the CPU's widest build: the loop below took a quarter of a
    // query's search); NaN fails the comparison, so a bad value goes on to
    // the loop, which names it
    if kernel.all_within(rows, MAX_FEATURE_ABS_F32) {
        return Ok(());
    }
    for (index, row) in rows.chunks_exact(dim).enumerate() {
        for (component, v) in row.iter().enumerate() {
            let v = f64::from(*v);
            if !v.is_finite() {
                return Err(EstimateError::NonFinite {
                    what,
                    index,
                    component,
                    value: v,
                });
            }
            if v.abs() > MAX_FEATURE_ABS {
                Bounds::closed(-MAX_FEATURE_ABS, MAX_FEATURE_ABS).check("feature value", v)?;
            }
        }
    }
    Ok(())
}

/// The number of `dim`-wide rows in `values`, which must be whole.
fn whole_rows(what: &'static str, values: &[f32], dim: usize) -> Result<usize> {
    let n = values.len() / dim;
    if n * dim == values.len() {
        Ok(n)
    } else {
        Err(EstimateError::Length {
            what,
            expected: (n + 1) * dim,
            got: values.len(),
        })
    }
}

/// Checks a buffer holds `expected` values.
fn same_length(what: &'static str, expected: usize, got: usize) -> Result<()> {
    if expected == got {
        Ok(())
    } else {
        Err(EstimateError::Length {
            what,
            expected,
            got,
        })
    }
}

/// Checks the poses are finite.
fn check_poses(poses: &[Pose]) -> Result<()> {
    for (index, p) in poses.iter().enumerate() {
        for (component, v) in [p.theta_deg, p.translation_mm].into_iter().enumerate() {
            if !v.is_finite() {
                return Err(EstimateError::NonFinite {
                    what: "pose",
                    index,
                    component,
                    value: v,
                });
            }
        }
    }
    Ok(())
}

impl FeatureIndex {
    /// Builds the index over `features` (row-major, `N` rows of `dim`
    /// values) labelled with `poses` (`N` of them): the mean, the `K`
    /// principal axes, the k-d tree over the projected points.
    ///
    /// Takes a few tens of milliseconds for 10,000 points of 256 dimensions
    /// (the covariance is estimated from at most 8,192 evenly spaced rows).
    ///
    /// # Errors
    /// * [`EstimateError::OutOfRange`] for a `dim` of 0 or a component
    ///   beyond ±[`MAX_FEATURE_ABS`], or for [`Search::Scan`] on more than
    ///   [`Search::SCAN_MAX_POINTS`] points;
    /// * [`EstimateError::EmptyIndex`] for no features;
    /// * [`EstimateError::Length`] when `features` is not a whole number of
    ///   rows or `poses` does not have one pose per row;
    /// * [`EstimateError::NonFinite`] for a NaN or infinite component or pose.
    ///
    /// # Examples
    ///
    /// ```
    /// use kflex_estimate::{FeatureIndex, IndexParams, Pose};
    ///
    /// // three 4-d embeddings, labelled with the poses they were rendered at
    /// let features = [
    ///     0.0, 0.0, 0.0, 1.0, //
    ///     1.0, 0.0, 0.0, 0.0, //
    ///     0.0, 1.0, 0.0, 0.0,
    /// ];
    /// let poses = [
    ///     Pose { theta_deg: -30.0, translation_mm: 10.0 },
    ///     Pose { theta_deg: 0.0, translation_mm: 10.0 },
    ///     Pose { theta_deg: 30.0, translation_mm: 10.0 },
    /// ];
    /// let index = FeatureIndex::build(&features, 4, &poses, IndexParams::default())?;
    ///
    /// let found = index.nearest(&[0.9, 0.1, 0.0, 0.0])?;
    /// assert_eq!(found.index, 1);
    /// assert_eq!(found.pose.theta_deg, 0.0);
    /// assert!((found.distance_sq - 0.02).abs() < 1e-6);
    /// // the same answer as a linear scan, always
    /// assert_eq!(index.nearest_linear(&[0.9, 0.1, 0.0, 0.0])?, found);
    /// # Ok::<(), kflex_estimate::EstimateError>(())
    /// ```
    pub fn build(
        features: &[f32],
        dim: usize,
        poses: &[Pose],
        params: IndexParams,
    ) -> Result<Self> {
        Self::from_parts(
            features.to_vec(),
            dim,
            poses.to_vec(),
            params,
            None,
            BTreeMap::new(),
        )
    }

    /// Builds from owned parts; `stored` is `Some((mean, axes))` when loaded
    /// from a file, `None` to compute them.
    fn from_parts(
        features: Vec<f32>,
        dim: usize,
        poses: Vec<Pose>,
        params: IndexParams,
        stored: Option<(Vec<f32>, Vec<f32>)>,
        metadata: BTreeMap<String, String>,
    ) -> Result<Self> {
        if dim == 0 {
            Bounds::closed(1.0, f64::INFINITY).check("feature dimension", 0.0)?;
        }
        if features.is_empty() {
            return Err(EstimateError::EmptyIndex);
        }
        let n = whole_rows(
            "features (whole rows of the feature dimension)",
            &features,
            dim,
        )?;
        same_length("poses (one per feature vector)", n, poses.len())?;
        check_values(Kernel::detect(), "feature vector", &features, dim)?;
        check_poses(&poses)?;
        let (projection, search) = (params.projection_dims, params.search);
        let dims = projection.get();
        let (mean, axes) = match stored {
            Some(p) => p,
            None => {
                let mean = pca::mean(&features, dim);
                let axes = pca::principal_axes(&features, dim, &mean, dims);
                (mean, axes)
            }
        };
        let kernel = Kernel::detect();
        let projected = project_rows(kernel, &axes, &mean, &features, dim, dims);
        let tree = ProjectedTree::new(&projected, projection)?;
        let search = search.resolve(n)?;
        let scan = match search {
            Search::Scan => Some(ProjectedScan::new(&projected, projection)?),
            _ => None,
        };
        let bound = BoundConstants::new(&axes, dim, &features, &mean);
        Ok(Self {
            dim,
            features,
            poses,
            mean,
            axes,
            projection,
            metadata,
            tree,
            scan,
            search,
            bound,
            kernel,
        })
    }

    /// Points in the index (`N ≥ 1`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// Always `false`: an index holds at least one point (building an empty
    /// one is an error).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// `D`, the dimension of the features and of a query.
    #[must_use]
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// `K`, the principal axes the search works in.
    #[must_use]
    pub fn projection_dims(&self) -> ProjectionDims {
        self.projection
    }

    /// How queries search: [`Search::Tree`] or [`Search::Scan`] (an index
    /// built or loaded with [`Search::Auto`] says which it chose).
    #[must_use]
    pub fn search_method(&self) -> Search {
        self.search
    }

    /// Searches by `search` from now on (a loaded database file picks
    /// [`Search::Auto`]); the answers do not change, only their speed.
    ///
    /// # Errors
    /// [`EstimateError::OutOfRange`] for [`Search::Scan`] on more than
    /// [`Search::SCAN_MAX_POINTS`] points; the index is then unchanged.
    pub fn set_search(&mut self, search: Search) -> Result<()> {
        let search = search.resolve(self.len())?;
        self.scan = match search {
            Search::Scan => {
                let projected = project_rows(
                    self.kernel,
                    &self.axes,
                    &self.mean,
                    &self.features,
                    self.dim,
                    self.projection.get(),
                );
                Some(ProjectedScan::new(&projected, self.projection)?)
            }
            _ => None,
        };
        self.search = search;
        Ok(())
    }

    /// The features, row-major (`len() × dim()`).
    #[must_use]
    pub fn features(&self) -> &[f32] {
        &self.features
    }

    /// The poses, one per feature vector.
    #[must_use]
    pub fn poses(&self) -> &[Pose] {
        &self.poses
    }

    /// Free-form metadata saved with the index (the model's SHA-256, the
    /// camera and grid description, …), sorted by key.
    #[must_use]
    pub fn metadata(&self) -> &BTreeMap<String, String> {
        &self.metadata
    }

    /// Sets metadata `key` to `value` (replacing any earlier value).
    pub fn set_metadata(&mut self, key: impl Into<String>, value: impl Into<String>) {
        self.metadata.insert(key.into(), value.into());
    }

    /// Checks a query's length and values.
    fn check_query(&self, query: &[f32], index: usize) -> Result<()> {
        if query.len() != self.dim {
            return Err(EstimateError::Length {
                what: "query (the index's feature dimension)",
                expected: self.dim,
                got: query.len(),
            });
        }
        check_values(self.kernel, "query", query, self.dim).map_err(|e| match e {
            EstimateError::NonFinite {
                what,
                component,
                value,
                ..
            } => EstimateError::NonFinite {
                what,
                index,
                component,
                value,
            },
            e => e,
        })
    }

    fn neighbour(&self, index: usize, distance_sq: f32) -> Neighbour {
        Neighbour {
            index,
            pose: self.poses[index],
            distance_sq,
        }
    }

    /// The exact nearest neighbour of `query` (`dim()` values): the same
    /// point, pose and distance as [`Self::nearest_linear`], found in the
    /// projected space (by scan or by k-d tree: [`Self::search_method`]).
    ///
    /// # Errors
    /// [`EstimateError::Length`] when `query` is not `dim()` long,
    /// [`EstimateError::NonFinite`] for a NaN or infinite component,
    /// [`EstimateError::OutOfRange`] beyond ±[`MAX_FEATURE_ABS`].
    pub fn nearest(&self, query: &[f32]) -> Result<Neighbour> {
        self.nearest_with_stats(query).map(|(n, _)| n)
    }

    /// [`Self::nearest`], and how many full distances it took.
    ///
    /// # Errors
    /// As [`Self::nearest`].
    pub fn nearest_with_stats(&self, query: &[f32]) -> Result<(Neighbour, SearchStats)> {
        self.check_query(query, 0)?;
        Ok(self.search(query))
    }

    /// The search itself, on a checked query.
    fn search(&self, query: &[f32]) -> (Neighbour, SearchStats) {
        let dim = self.dim;
        let mut projected = [0.0_f32; MAX_DIMS];
        let dims = self.projection.get();
        self.kernel
            .project(&self.axes, &self.mean, query, &mut projected[..dims]);
        let full = |i: usize| {
            self.kernel
                .squared_distance(&self.features[i * dim..][..dim], query)
        };

        // the nearest point in the projected space, by scan or by tree
        let mut scratch = scan::scratch();
        let (first, kept) = match &self.scan {
            Some(scan) => {
                let (first, _, blocks) = scan.nearest(self.kernel, &projected, &mut scratch);
                (first, Some((scan, blocks)))
            }
            None => (self.tree.nearest_one(&projected).0, None),
        };
        let mut best = (full(first), first);
        let mut stats = SearchStats {
            full_distances: 1,
            candidates: 0,
        };

        // ‖q − mean‖ ≤ ‖q − x_first‖ + ‖x_first − mean‖, bounded above from
        // the f32 kernel's value: the pruning bound's rounding term needs no
        // distance of its own
        let centred = (f64::from(best.0) / (1.0 - self.bound.full_rounding)).sqrt()
            + self.bound.max_centred_norm;
        let (a, b) = self.bound.threshold(centred);
        let b = b + underflow_slack(a, dim, dims);
        let radius_sq = |f: f32| {
            let t = a * f64::from(f).sqrt() + b;
            (t * t * (1.0 + 1e-4) + 1e-30) as f32
        };

        // every point within the bound of the best so far, the bound
        // shrinking as the best improves; `visit` returns the bound
        let start = radius_sq(best.0);
        let mut bound_sq = start;
        let mut visit = |i: usize, p: f32| {
            stats.candidates += 1;
            if p <= bound_sq && i != first {
                let f = full(i);
                stats.full_distances += 1;
                if f < best.0 || (f == best.0 && i < best.1) {
                    best = (f, i);
                    bound_sq = radius_sq(f);
                }
            }
            bound_sq
        };
        match kept {
            Some((scan, blocks)) => scan::within(blocks, scan.len(), start, visit),
            None => self.tree.within(&projected, start, |i, p| {
                visit(i, p);
            }),
        }
        (self.neighbour(best.1, best.0), stats)
    }

    /// The nearest neighbour of `query` by a plain linear scan over every
    /// point: the reference [`Self::nearest`] is tested against, and the
    /// baseline of the benchmarks. Lowest index among equals.
    ///
    /// # Errors
    /// As [`Self::nearest`].
    pub fn nearest_linear(&self, query: &[f32]) -> Result<Neighbour> {
        self.check_query(query, 0)?;
        let (i, d) = self.kernel.nearest_linear(&self.features, query);
        Ok(self.neighbour(i, d))
    }

    /// [`Self::nearest`] for each row of `queries` (row-major, `dim()`
    /// wide), written into `out` (one per row). Runs on the calling thread;
    /// allocates nothing.
    ///
    /// # Errors
    /// [`EstimateError::Length`] when `queries` is not whole rows or `out`
    /// has not one slot per row; otherwise as [`Self::nearest`], naming the
    /// first bad row (`out` is then left as it was).
    pub fn nearest_batch_into(&self, queries: &[f32], out: &mut [Neighbour]) -> Result<()> {
        let n = whole_rows(
            "queries (whole rows of the feature dimension)",
            queries,
            self.dim,
        )?;
        same_length("output (one neighbour per query)", n, out.len())?;
        for (i, q) in queries.chunks_exact(self.dim).enumerate() {
            self.check_query(q, i)?;
        }
        for (q, o) in queries.chunks_exact(self.dim).zip(out.iter_mut()) {
            *o = self.search(q).0;
        }
        Ok(())
    }

    /// [`Self::nearest`] for each row of `queries`, as a new vector.
    ///
    /// # Errors
    /// As [`Self::nearest_batch_into`].
    pub fn nearest_batch(&self, queries: &[f32]) -> Result<Vec<Neighbour>> {
        let mut out = vec![Neighbour::default(); queries.len() / self.dim.max(1)];
        self.nearest_batch_into(queries, &mut out)?;
        Ok(out)
    }
}

/// Every row of `features` (`dim` wide) projected on the `dims` rows of
/// `axes` around `mean`: the points the tree and the scan hold.
fn project_rows(
    kernel: Kernel,
    axes: &[f32],
    mean: &[f32],
    features: &[f32],
    dim: usize,
    dims: usize,
) -> Vec<f32> {
    let mut projected = vec![0.0_f32; features.len() / dim * dims];
    for (x, p) in features
        .chunks_exact(dim)
        .zip(projected.chunks_exact_mut(dims))
    {
        kernel.project(axes, mean, x, p);
    }
    projected
}

/// Absolute slack for underflow in the pruning threshold: squares and
/// products below f32's normal range lose their relative accuracy (at most
/// 2⁻¹⁴⁹ each), which the relative bounds do not cover.
fn underflow_slack(a: f64, dim: usize, dims: usize) -> f64 {
    let tiny = f64::powi(2.0, -149);
    a * (dim as f64 * tiny).sqrt()
        + (dims as f64).sqrt() * dim as f64 * tiny
        + (dims as f64 * tiny).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_f32_limit_is_the_f64_limit() {
        // the query check compares in f32: the same values must pass
        let limit = MAX_FEATURE_ABS_F32;
        assert!(f64::from(limit) <= MAX_FEATURE_ABS);
        assert!(f64::from(limit.next_up()) > MAX_FEATURE_ABS);
        for kernel in [Kernel::Portable, Kernel::detect()] {
            for (v, ok) in [
                (limit, true),
                (-limit, true),
                (limit.next_up(), false),
                (f32::NAN, false),
                (f32::NEG_INFINITY, false),
            ] {
                // the value at every position of a row: each SIMD lane and the tail
                for at in 0..37 {
                    let mut row = [0.5_f32; 37];
                    row[at] = v;
                    assert_eq!(kernel.all_within(&row, limit), ok, "{v} at {at}");
                    assert_eq!(check_values(kernel, "query", &row, 37).is_ok(), ok);
                }
            }
        }
    }
}
