//! Regions of the split and merge: the quadtree leaves, their union by
//! colour, and the filter that drops small instrument components.

use super::classify::chroma;
use super::{Scratch, SegmentParams};

/// A leaf of the split, later a merged region: mean colour on [0, 1] and pixels.
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
    fn of_mean(mean: [f32; 3], count: f32) -> Region {
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
    s.votes.clear();
    s.votes.reserve(cols * rows);
    s.neighbours.clear();
    s.neighbours.reserve(cols * rows);
    s.roots.clear();
    s.roots.reserve(cols * rows);
    s.leaf_box.clear();
    s.leaf_box.reserve(cols * rows);
    s.boxes.clear();
    s.boxes.reserve(cols * rows);
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

/// Merges adjacent regions (4-neighbouring cells with different labels) whose
/// mean colours are closer than `distance`: union–find on running means.
/// Leaves each region's merged root in `s.parent`.
pub(super) fn merge(s: &mut Scratch, cols: usize, rows: usize, p: &SegmentParams, noise: f32) {
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let d2 = p.merge_distance * p.merge_distance;
    let c2 = p.merge_chroma * p.merge_chroma;
    let n2 = noise * noise;
    let Scratch {
        labels,
        regions,
        parent,
        ..
    } = s;
    parent.clear();
    parent.reserve(cols * rows);
    parent.extend(0..regions.len() as u32);
    let mut try_merge = |a: u32, b: u32, parent: &mut Vec<u32>| {
        let (ra, rb) = (find(parent, a), find(parent, b));
        if ra == rb {
            return;
        }
        let (pa, pb) = (regions[ra as usize], regions[rb as usize]);
        let gap = (0..3)
            .map(|k| (pa.mean[k] - pb.mean[k]).powi(2))
            .sum::<f32>();
        let spread = 1.0 / pa.count + 1.0 / pb.count;
        // the colour distance, then the chromaticity's: a mean of n pixels
        // with noise σ has chromaticity noise about σ √2 / (L √n)
        let close = gap < d2 + 3.0 * n2 * spread && {
            let (ca, cb) = (pa.chroma, pb.chroma);
            let l = pa.lum.min(pb.lum).max(0.05);
            let dc2 = (ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2);
            dc2 < c2 + 2.0 * n2 / (l * l) * spread
        };
        if close {
            parent[rb as usize] = ra;
            let count = pa.count + pb.count;
            let (wa, wb) = (pa.count / count, pb.count / count);
            regions[ra as usize] =
                Region::of_mean([0, 1, 2].map(|k| wa * pa.mean[k] + wb * pb.mean[k]), count);
        }
    };
    for y in 0..rows {
        let row = &labels[y * cols..(y + 1) * cols];
        let below = labels.get((y + 1) * cols..(y + 2) * cols);
        // along a horizontal boundary the same pair repeats cell after cell
        let mut last_down = (u32::MAX, u32::MAX);
        for x in 0..cols {
            let a = row[x];
            if x + 1 < cols && row[x + 1] != a {
                try_merge(a, row[x + 1], parent);
            }
            if let Some(below) = below {
                let b = below[x];
                if b != a && (a, b) != last_down {
                    try_merge(a, b, parent);
                    last_down = (a, b);
                }
            }
        }
    }
    for i in 0..parent.len() as u32 {
        let root = find(parent, i);
        parent[i as usize] = root;
    }
}

/// Clears the 4-connected components of set cells in `s.cells` (`cols × rows`
/// cells over `rw × rh` pixels) that hold fewer than `min` pixels. Returns the
/// pixels left set.
pub(super) fn drop_small_components(
    s: &mut Scratch,
    cols: usize,
    rows: usize,
    rw: usize,
    rh: usize,
    min: usize,
) -> usize {
    let Scratch {
        cells,
        seen,
        flood,
        component,
        ..
    } = s;
    let weight = |i: usize| (rw - 2 * (i % cols)).min(2) * (rh - 2 * (i / cols)).min(2);
    seen.clear();
    seen.resize(cells.len(), false);
    flood.clear();
    flood.reserve(cells.len());
    component.clear();
    component.reserve(cells.len());
    let mut kept = 0;
    for start in 0..cells.len() {
        if cells[start] == 0 || seen[start] {
            continue;
        }
        component.clear();
        flood.clear();
        flood.push(start);
        seen[start] = true;
        let mut pixels = 0;
        while let Some(i) = flood.pop() {
            component.push(i);
            pixels += weight(i);
            let (x, y) = (i % cols, i / cols);
            let mut visit = |j: usize| {
                if cells[j] != 0 && !seen[j] {
                    seen[j] = true;
                    flood.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < cols {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - cols);
            }
            if y + 1 < rows {
                visit(i + cols);
            }
        }
        if pixels < min {
            for &i in component.iter() {
                cells[i] = 0;
            }
        } else {
            kept += pixels;
        }
    }
    kept
}
