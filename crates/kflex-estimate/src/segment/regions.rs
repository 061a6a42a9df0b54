//! Regions of the split and merge: the quadtree leaves and their union by
//! colour.

use super::classify::chroma;
use super::{Scratch, SegmentParams};

/// A leaf of the split, later a merged region: mean colour on [0, 1] and pixels.
/// From the threshold on, a merged region's mean is the one its readings
/// stand for: its dark channels read back through the sensor's clipping of
/// the noise at 0 (step 0 in `classify.rs`).
#[derive(Debug, Clone, Copy)]
pub(super) struct Region {
    pub(super) mean: [f32; 3],
    pub(super) count: f32,
    /// `chroma(mean)`, kept with the mean (merge and threshold read it often).
    pub(super) chroma: [f32; 2],
    /// `r + g + b` of the mean.
    pub(super) lum: f32,
}

impl Region {
    pub(super) fn of_mean(mean: [f32; 3], count: f32) -> Region {
        Region {
            mean,
            count,
            chroma: chroma(mean),
            lum: mean[0] + mean[1] + mean[2],
        }
    }

    /// From the sums of brightness, redness and `g − b` over `count` pixels.
    /// The sums are exact in `i64`; the means are taken in `f64` (exact for
    /// any sum below 2⁵³) and rounded to `f32` once.
    fn from_feature_sums([bright, red, gb]: [i64; 3], count: usize) -> Region {
        let r = (bright + red) as f64 / 3.0;
        let g_plus_b = bright as f64 - r;
        let scale = 1.0 / (255.0 * count as f64);
        Region::of_mean(
            [
                (r * scale) as f32,
                (0.5 * (g_plus_b + gb as f64) * scale) as f32,
                (0.5 * (g_plus_b - gb as f64) * scale) as f32,
            ],
            count as f32,
        )
    }
}

/// Splits the pyramid's top block (level `depth − 1`) down to uniform blocks:
/// each leaf becomes a region and labels its cells.
pub(super) fn split(s: &mut Scratch, depth: usize, rw: usize, rh: usize, p: SegmentParams) {
    let (split_bright, split_red) = (p.split_range * 765.0, p.split_range * 510.0);
    let (cols, rows) = (s.levels[0].cols, s.levels[0].rows);
    s.labels.clear();
    s.labels.resize(cols * rows, 0);
    // worst cases, reserved once so that no later frame of the size allocates:
    // a region per cell, and a depth-first stack of 3 blocks a level
    s.regions.clear();
    s.regions.reserve(cols * rows);
    // and the threshold's per-region buffers, which hold one entry a region
    for buffer in [&mut s.region_class, &mut s.instrument] {
        buffer.clear();
        buffer.reserve(cols * rows);
    }
    s.roots.clear();
    s.roots.reserve(cols * rows);
    s.leaf_box.clear();
    s.leaf_box.reserve(cols * rows);
    // the regions' graph: a leaf pair per cell edge at most, each listed
    // from both sides; a component per region at most
    s.leaf_edges.clear();
    s.leaf_edges.reserve(2 * cols * rows);
    s.last_right.clear();
    s.last_right.reserve(cols);
    s.adjacency.clear();
    s.adjacency.reserve(4 * cols * rows);
    s.adjacency_start.clear();
    s.adjacency_start.reserve(cols * rows + 1);
    for buffer in [&mut s.flood, &mut s.component] {
        buffer.clear();
        buffer.reserve(cols * rows);
    }
    // the growth's rounds: every side of every edge (as the adjacency), and
    // a region each (step 5's blob walk holds a region each in both)
    s.grow_frontier.clear();
    s.grow_frontier.reserve(4 * cols * rows);
    s.grow_joined.clear();
    s.grow_joined.reserve(cols * rows);
    s.on_border.clear();
    s.on_border.reserve(cols * rows);
    s.seen.clear();
    s.seen.reserve(cols * rows);
    s.component_spans.clear();
    s.component_spans.reserve(cols * rows);
    s.stack.clear();
    s.stack.reserve(3 * depth + 1);
    s.stack.push((depth - 1, 0, 0));
    while let Some((level, bx, by)) = s.stack.pop() {
        let l = &s.levels[level];
        let i = by * l.cols + bx;
        let side = 2usize << level; // pixels per block side at this level
        // 2×2 cells are never split, so level 0 carries no ranges
        let leaf = level == 0
            || side <= p.min_block as usize
            || (f32::from(l.hi[0][i] - l.lo[0][i]) <= split_bright
                && f32::from(l.hi[1][i] - l.lo[1][i]) <= split_red);
        if leaf {
            let id = s.regions.len() as u32;
            let cells = side / 2;
            let (x0, y0) = (bx * cells, by * cells);
            let (x1, y1) = ((x0 + cells).min(cols), (y0 + cells).min(rows));
            for cy in y0..y1 {
                s.labels[cy * cols + x0..cy * cols + x1].fill(id);
            }
            let count = ((2 * x1).min(rw) - 2 * x0) * ((2 * y1).min(rh) - 2 * y0);
            let sum = [l.sum[0][i], l.sum[1][i], l.sum[2][i]];
            s.regions.push(Region::from_feature_sums(sum, count));
            s.leaf_box
                .push([x0 as u32, y0 as u32, (x1 - 1) as u32, (y1 - 1) as u32]);
        } else {
            let below = &s.levels[level - 1];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (cx, cy) = (2 * bx + dx, 2 * by + dy);
                if cx < below.cols && cy < below.rows {
                    s.stack.push((level - 1, cx, cy));
                }
            }
        }
    }
}

/// A leaf pair's flag in its edge count, while the merge runs: the first
/// pass joined its leaves (they stay one region).
const JOINED: u32 = 1 << 31;

/// Merges adjacent regions (4-neighbouring cells with different labels) whose
/// mean colours are close (the colour distance and the chromaticity's, each
/// within its threshold plus what the noise `noise` explains for regions of
/// their sizes): union–find on running means. Leaves each region's merged
/// root in `s.parent`, and in `s.leaf_edges` every pair of leaves across
/// cell edges with the number of those edges.
///
/// Two passes, each trying every pair once. The first, as the cells are
/// walked and each pair is met, joins only the pairs whose difference the
/// frame's noise alone explains (the fixed thresholds `merge_distance` and
/// `merge_chroma` left out), so that the frame's even parts form first and
/// their means settle; the second, over the pairs recorded, allows the
/// thresholds too. (Where `noise` is 0 the first pass joins nothing and the
/// second does all.) In one pass, in the order a raster scan meets the
/// pairs (a pair along a vertical boundary tried again on every row), a
/// region's running mean could walk along a slow change (an edge blurred by
/// the optics, tissue nearly as grey as the steel) before the regions on
/// either side of it had formed: over the robustness matrix's six
/// backgrounds per organ, 118 cases under a goal with one pass, 99 with two
/// (29 fixed, 10 newly under; grey tissue 23 → 19, white 26 → 21, noise
/// σ 0.1 16 → 12, gain 1.6 8 → 5), at 7–10 % more time for the
/// segmentation.
pub(super) fn merge(s: &mut Scratch, cols: usize, rows: usize, p: &SegmentParams, noise: f32) {
    let limits = MergeLimits {
        d2: p.merge_distance * p.merge_distance,
        c2: p.merge_chroma * p.merge_chroma,
        n2: noise * noise,
    };
    let Scratch {
        labels,
        regions,
        parent,
        leaf_edges,
        last_right,
        ..
    } = s;
    parent.clear();
    parent.reserve(cols * rows);
    parent.extend(0..regions.len() as u32);
    record_pairs(labels, cols, rows, leaf_edges, last_right, |a, b| {
        try_merge(a, b, 0.0, &limits, parent, regions)
    });
    for e in leaf_edges.iter_mut() {
        if e[2] & JOINED == 0 {
            try_merge(e[0], e[1], 1.0, &limits, parent, regions);
        }
        e[2] &= !JOINED;
    }
    for i in 0..parent.len() as u32 {
        let root = find(parent, i);
        parent[i as usize] = root;
    }
}

/// The merge's squared thresholds: colour distance, chromaticity, noise.
struct MergeLimits {
    d2: f32,
    c2: f32,
    n2: f32,
}

/// The root of `i`'s set, halving the path on the way.
#[inline(always)]
fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        parent[i as usize] = parent[parent[i as usize] as usize];
        i = parent[i as usize];
    }
    i
}

/// Joins the regions of leaves `a` and `b` where their means are close:
/// within the noise's allowance, plus `fixed` times the fixed thresholds.
/// Whether they are one region after.
#[inline(always)]
fn try_merge(
    a: u32,
    b: u32,
    fixed: f32,
    l: &MergeLimits,
    parent: &mut [u32],
    regions: &mut [Region],
) -> bool {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra == rb {
        return true;
    }
    let (pa, pb) = (regions[ra as usize], regions[rb as usize]);
    let gap = (0..3)
        .map(|k| (pa.mean[k] - pb.mean[k]).powi(2))
        .sum::<f32>();
    let count = pa.count + pb.count;
    let spread = count / (pa.count * pb.count);
    // the colour distance, then the chromaticity's: a mean of n pixels
    // with noise σ has chromaticity noise about σ √2 / (L √n)
    let (ca, cb) = (pa.chroma, pb.chroma);
    let lum = pa.lum.min(pb.lum).max(0.05);
    let dc2 = (ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2);
    let close = (gap < fixed * l.d2 + 3.0 * l.n2 * spread)
        & (dc2 * lum * lum < fixed * l.c2 * lum * lum + 2.0 * l.n2 * spread);
    if close {
        let (wa, wb) = (pa.count / count, pb.count / count);
        parent[rb as usize] = ra;
        regions[ra as usize] =
            Region::of_mean([0, 1, 2].map(|k| wa * pa.mean[k] + wb * pb.mean[k]), count);
    }
    close
}

/// Lists in `leaf_edges` every pair of leaves across a cell edge, `[a, b,
/// edges]` (`a` left of or above `b`), with the cell edges they share. Two
/// leaves (aligned blocks) share one straight run of edges: along a
/// horizontal boundary the pair repeats cell after cell in a row, along a
/// vertical one row after row at the same column (`last_right`), and each
/// run is one record.
fn record_pairs(
    labels: &[u32],
    cols: usize,
    rows: usize,
    leaf_edges: &mut Vec<[u32; 3]>,
    last_right: &mut Vec<(u32, u32, u32)>,
    mut first: impl FnMut(u32, u32) -> bool,
) {
    leaf_edges.clear();
    last_right.clear();
    last_right.resize(cols, (u32::MAX, u32::MAX, 0));
    for y in 0..rows {
        let row = &labels[y * cols..(y + 1) * cols];
        let below = labels.get((y + 1) * cols..(y + 2) * cols);
        let mut last_down = (u32::MAX, u32::MAX, 0);
        for x in 0..cols {
            let a = row[x];
            if x + 1 < cols && row[x + 1] != a {
                let b = row[x + 1];
                let run = &mut last_right[x];
                if (run.0, run.1) == (a, b) {
                    leaf_edges[run.2 as usize][2] += 1;
                } else {
                    *run = (a, b, leaf_edges.len() as u32);
                    leaf_edges.push([a, b, 1 | if first(a, b) { JOINED } else { 0 }]);
                }
            }
            if let Some(below) = below {
                let b = below[x];
                if b != a {
                    if (last_down.0, last_down.1) == (a, b) {
                        leaf_edges[last_down.2 as usize][2] += 1;
                    } else {
                        last_down = (a, b, leaf_edges.len() as u32);
                        leaf_edges.push([a, b, 1 | if first(a, b) { JOINED } else { 0 }]);
                    }
                }
            }
        }
    }
}
