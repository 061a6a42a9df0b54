//! Region-based segmentation (the paper's Fig. 4b): region of interest,
//! split, merge, threshold — giving the 48×48 binary image IBJAE consumes.
//!
//! 1. **Region of interest**: a rectangle of the frame ([`Roi`]).
//! 2. **Split**: a quadtree of aligned power-of-two blocks. A block is split in
//!    four while the range of its brightness or of its redness exceeds
//!    [`SegmentParams::split_range`] and its side exceeds [`SegmentParams::min_block`]
//!    px (at least 2). Block statistics (ranges and colour sums, in integers) come
//!    from a pyramid built bottom-up in one pass, so the split is linear in the
//!    pixels. On x86-64 CPUs with AVX2 the pyramid runs on a vectorised copy of
//!    the same code, chosen at run time.
//! 3. **Merge**: adjacent leaves whose mean colours differ by less than
//!    [`SegmentParams::merge_distance`] become one region (union–find over the
//!    leaves' adjacency, on the regions' running means). No leaf is smaller than
//!    a 2×2 cell, so merging, thresholding and the component filter work on the
//!    grid of cells, a quarter of the pixels.
//! 4. **Threshold**: a region is instrument where its mean colour is metallic —
//!    unsaturated (`(max − min)/max < max_saturation`), not reddish
//!    (`r − (g + b)/2 < max_redness`) and not dark (`max > min_value`) — and
//!    tissue where it is reddish or dark (lumen).
//!    Tape is red, so a taped part is lost, as in the paper. Connected instrument
//!    components smaller than [`SegmentParams::min_component`] of the region
//!    (specular spots on wet mucosa) are dropped.
//! 5. The result is resampled to `out × out` (area vote: a cell is set where at
//!    least half its pixels are). Fewer than [`SegmentParams::min_instrument`]
//!    of the region's pixels set: [`EstimateError::NoInstrument`].

use kflex_model::Mask;
use serde::{Deserialize, Serialize};

use crate::error::{EstimateError, Result};

/// A region of interest in pixels: `[x0, x0 + width) × [y0, y0 + height)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Roi {
    /// Left column.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

/// Segmentation thresholds. Colours on the [0, 1] scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentParams {
    /// Largest brightness or redness range of a block that is not split further.
    pub split_range: f32,
    /// Smallest block side, px.
    pub min_block: u32,
    /// Largest colour distance between adjacent regions that are merged.
    pub merge_distance: f32,
    /// Largest saturation of an instrument region.
    pub max_saturation: f32,
    /// Largest redness `r − (g + b)/2` of an instrument region (tissue is reddish).
    pub max_redness: f32,
    /// Smallest brightness (HSV value) of an instrument region.
    pub min_value: f32,
    /// Smallest instrument component kept, as a share of the region of interest.
    pub min_component: f32,
    /// Smallest instrument share of the region of interest that counts as found.
    pub min_instrument: f32,
    /// Side of the output image, px (the paper: 48).
    pub out: u32,
}

impl Default for SegmentParams {
    fn default() -> Self {
        Self {
            split_range: 0.12,
            min_block: 2,
            merge_distance: 0.08,
            max_saturation: 0.2,
            max_redness: 0.06,
            min_value: 0.22,
            min_component: 0.004,
            min_instrument: 0.002,
            out: 48,
        }
    }
}

/// The segmentation of one region of interest.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// Instrument mask at the region's own resolution.
    pub full: Mask,
    /// Resampled to `out × out` for IBJAE.
    pub small: Mask,
}

/// Brightness (`r + g + b`) and redness (`2r − g − b`) ranges of the aligned
/// blocks of one level of the split pyramid, in integer colour units (none at
/// level 0, whose 2×2 cells are never split).
/// Range planes indexed `[brightness, redness]`, blocks row-major.
#[derive(Debug, PartialEq)]
struct Level {
    cols: usize,
    rows: usize,
    lo: [Vec<i16>; 2],
    hi: [Vec<i16>; 2],
    /// Sums of brightness, redness and `g − b`.
    sum: [Vec<i32>; 3],
}

/// A leaf of the split, later a merged region: mean colour on [0, 1] and pixels.
#[derive(Clone, Copy)]
struct Region {
    mean: [f32; 3],
    count: f32,
}

impl Region {
    /// From the sums of brightness, redness and `g − b` over `count` pixels.
    fn from_feature_sums([bright, red, gb]: [i32; 3], count: usize) -> Region {
        let r = (bright + red) as f32 / 3.0;
        let g_plus_b = bright as f32 - r;
        let scale = 1.0 / (255.0 * count as f32);
        Region {
            mean: [
                r * scale,
                0.5 * (g_plus_b + gb as f32) * scale,
                0.5 * (g_plus_b - gb as f32) * scale,
            ],
            count: count as f32,
        }
    }
}

/// Largest region of interest, px (colour sums of a region fit in `u32`).
const MAX_ROI_PIXELS: u64 = 1 << 24;

/// Segments the instrument in `roi` of an RGB frame (`width × height`, 8 bits, row-major).
pub fn segment(
    rgb: &[u8],
    width: u32,
    height: u32,
    roi: Roi,
    params: &SegmentParams,
) -> Result<Segmentation> {
    let expected = width as usize * height as usize * 3;
    if width == 0 || height == 0 || rgb.len() != expected {
        return Err(EstimateError::ImageSize {
            width,
            height,
            expected,
            got: rgb.len(),
        });
    }
    let right = u64::from(roi.x0) + u64::from(roi.width);
    if roi.width == 0
        || roi.height == 0
        || right > u64::from(width)
        || u64::from(roi.y0) + u64::from(roi.height) > u64::from(height)
    {
        return Err(EstimateError::InvalidParameter {
            name: "roi",
            value: right as f64,
            range: format!("a non-empty rectangle inside {width}×{height}"),
        });
    }
    if params.out == 0 || params.out > 4096 {
        return Err(EstimateError::InvalidParameter {
            name: "out",
            value: f64::from(params.out),
            range: "[1, 4096]".into(),
        });
    }
    let (rw, rh) = (roi.width as usize, roi.height as usize);
    if (rw * rh) as u64 > MAX_ROI_PIXELS {
        return Err(EstimateError::InvalidParameter {
            name: "roi pixels",
            value: (rw * rh) as f64,
            range: format!("[1, {MAX_ROI_PIXELS}]"),
        });
    }
    let stride = 3 * width as usize;
    let first = 3 * (roi.y0 as usize * width as usize + roi.x0 as usize);
    let roi_rows: Vec<&[u8]> = (0..rh)
        .map(|y| &rgb[first + y * stride..][..3 * rw])
        .collect();
    // The smallest leaf is a 2×2 cell, so everything after the split works on the
    // grid of cells (a quarter of the pixels), and the pixel mask is filled last.
    let (cols, rows) = (rw.div_ceil(2), rh.div_ceil(2));
    let levels = pyramid(&roi_rows, rw);
    let (split_bright, split_red) = (params.split_range * 765.0, params.split_range * 510.0);
    let mut labels = vec![0u32; cols * rows];
    let mut regions: Vec<Region> = Vec::new();
    let mut stack = vec![(levels.len() - 1, 0usize, 0usize)];
    while let Some((level, bx, by)) = stack.pop() {
        let l = &levels[level];
        let i = by * l.cols + bx;
        let side = 2usize << level; // pixels per block side at this level
        // 2×2 cells are never split, so level 0 carries no ranges
        let leaf = level == 0
            || side <= params.min_block as usize
            || (f32::from(l.hi[0][i] - l.lo[0][i]) <= split_bright
                && f32::from(l.hi[1][i] - l.lo[1][i]) <= split_red);
        if leaf {
            let id = regions.len() as u32;
            let cells = side / 2;
            let (x0, y0) = (bx * cells, by * cells);
            let (x1, y1) = ((x0 + cells).min(cols), (y0 + cells).min(rows));
            for cy in y0..y1 {
                labels[cy * cols + x0..cy * cols + x1].fill(id);
            }
            let count = ((2 * x1).min(rw) - 2 * x0) * ((2 * y1).min(rh) - 2 * y0);
            let sum = [0, 1, 2].map(|k| l.sum[k][i]);
            regions.push(Region::from_feature_sums(sum, count));
        } else {
            let below = &levels[level - 1];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (cx, cy) = (2 * bx + dx, 2 * by + dy);
                if cx < below.cols && cy < below.rows {
                    stack.push((level - 1, cx, cy));
                }
            }
        }
    }
    let root = merge(&labels, cols, rows, &mut regions, params.merge_distance);
    // threshold each merged region by its mean colour
    let is_instrument: Vec<u8> = root
        .iter()
        .map(|&r| {
            let m = regions[r as usize].mean;
            let (mx, mn) = (m[0].max(m[1]).max(m[2]), m[0].min(m[1]).min(m[2]));
            let redness = m[0] - 0.5 * (m[1] + m[2]);
            u8::from(
                mx > params.min_value
                    && (mx - mn) / mx < params.max_saturation
                    && redness < params.max_redness,
            )
        })
        .collect();
    let mut cells: Vec<u8> = labels.iter().map(|&l| is_instrument[l as usize]).collect();
    let weight = |cx: usize, cy: usize| (rw - 2 * cx).min(2) * (rh - 2 * cy).min(2);
    drop_small_components(
        &mut cells,
        cols,
        rows,
        weight,
        (params.min_component * (rw * rh) as f32).ceil() as usize,
    );
    let mut count = 0;
    for (cy, row) in cells.chunks_exact(cols).enumerate() {
        for (cx, &v) in row.iter().enumerate() {
            if v != 0 {
                count += weight(cx, cy);
            }
        }
    }
    let min = (params.min_instrument * (rw * rh) as f32).ceil().max(1.0) as usize;
    if count < min {
        return Err(EstimateError::NoInstrument { pixels: count, min });
    }
    let mut full = Vec::with_capacity(rw * rh);
    let mut row = vec![0u8; rw];
    for crow in cells.chunks_exact(cols) {
        for (pair, &v) in row.chunks_exact_mut(2).zip(crow) {
            pair[0] = v;
            pair[1] = v;
        }
        if rw % 2 == 1 {
            row[rw - 1] = crow[cols - 1];
        }
        full.extend_from_slice(&row);
        if full.len() < rw * rh {
            full.extend_from_slice(&row);
        }
    }
    let small = resample(&full, rw, rh, params.out as usize);
    Ok(Segmentation {
        full: Mask::from_raw(roi.width, roi.height, full)?,
        small: Mask::from_raw(params.out, params.out, small)?,
    })
}

/// Combines neighbouring pairs of `v` with `op` onto `out` (an odd last one
/// goes through `alone`).
#[inline(always)]
fn combine_pairs<T: Copy, U>(
    v: &[T],
    op: impl Fn(T, T) -> U,
    alone: impl Fn(T) -> U,
    out: &mut Vec<U>,
) {
    out.extend(v.chunks_exact(2).map(|p| op(p[0], p[1])));
    if let [.., last] = v
        && v.len() % 2 == 1
    {
        out.push(alone(*last));
    }
}

/// Combines each aligned 2×2 group of `src` (`cols × rows`) with `op`
/// (a group cut by the edge combines what it has).
#[inline(always)]
fn reduce_2x2<T: Copy + Default>(
    src: &[T],
    cols: usize,
    rows: usize,
    op: impl Fn(T, T) -> T,
) -> Vec<T> {
    let mut dst = Vec::with_capacity(cols.div_ceil(2) * rows.div_ceil(2));
    let mut vertical = vec![T::default(); cols];
    for pair in src.chunks(2 * cols) {
        let (a, b) = pair.split_at(cols.min(pair.len()));
        if b.is_empty() {
            // a last row alone (op is not idempotent: sums)
            vertical.copy_from_slice(a);
        } else {
            for ((v, &p), &q) in vertical.iter_mut().zip(a).zip(b) {
                *v = op(p, q);
            }
        }
        combine_pairs(&vertical, &op, |t| t, &mut dst);
    }
    dst
}

/// Per-pixel features of a row of RGB: brightness `r + g + b`, redness
/// `2r − g − b` and `g − b` (the three determine the colour).
#[inline(always)]
fn features(row: &[u8], out: &mut [Vec<i16>; 3]) {
    let [bright, red, gb] = out;
    for (((c, b), r), d) in row
        .chunks_exact(3)
        .zip(bright.iter_mut())
        .zip(red.iter_mut())
        .zip(gb.iter_mut())
    {
        let (x, y, z) = (i16::from(c[0]), i16::from(c[1]), i16::from(c[2]));
        *b = x + y + z;
        *r = 2 * x - y - z;
        *d = y - z;
    }
}

/// The split pyramid of the region (rows of RGB, `rw` pixels each): 2×2 cells
/// first, each level above from the one below, up to a single block.
fn pyramid(rows: &[&[u8]], rw: usize) -> Vec<Level> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { pyramid_avx2(rows, rw) };
    }
    pyramid_portable(rows, rw)
}

/// [`pyramid`] compiled for AVX2: its byte shuffles take the RGB triples apart
/// many pixels at a time (the x86-64 baseline has none) and its min, max and
/// sums run 16 lanes wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn pyramid_avx2(rows: &[&[u8]], rw: usize) -> Vec<Level> {
    pyramid_portable(rows, rw)
}

#[inline(always)]
fn pyramid_portable(rows: &[&[u8]], rw: usize) -> Vec<Level> {
    let (cols, cell_rows) = (rw.div_ceil(2), rows.len().div_ceil(2));
    let (cols1, rows1) = (cols.div_ceil(2), cell_rows.div_ceil(2));
    let plane = || Vec::with_capacity(cols1 * rows1);
    let mut lo: [Vec<i16>; 2] = [plane(), plane()];
    let mut hi: [Vec<i16>; 2] = [plane(), plane()];
    let sum_plane = || Vec::with_capacity(cols * cell_rows);
    let mut sums: [Vec<i32>; 3] = [sum_plane(), sum_plane(), sum_plane()];
    let row_buf = |n: usize| [vec![0i16; n], vec![0i16; n], vec![0i16; n]];
    let (mut fa, mut fb, mut v) = (row_buf(rw), row_buf(rw), vec![0i16; rw]);
    // the ranges of the cells of an even and an odd cell row, [lo, hi] × [bright, red]
    let cell_row = || {
        [
            [vec![0i16; cols], vec![0i16; cols]],
            [vec![0i16; cols], vec![0i16; cols]],
        ]
    };
    let (mut even, mut odd) = (cell_row(), cell_row());
    let mut w = vec![0i16; cols];
    for (cy, pair) in rows.chunks(2).enumerate() {
        features(pair[0], &mut fa);
        match pair.get(1) {
            Some(b) => features(b, &mut fb),
            None => fb.clone_from(&fa),
        }
        let single = pair.len() == 1;
        for k in 0..3 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = if single { p } else { p + q };
            }
            let wide = |p: i16, q: i16| i32::from(p) + i32::from(q);
            combine_pairs(&v, wide, i32::from, &mut sums[k]);
        }
        let ranges = if cy % 2 == 0 { &mut even } else { &mut odd };
        for k in 0..2 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.min(q);
            }
            ranges[0][k].clear();
            combine_pairs(&v, i16::min, |t| t, &mut ranges[0][k]);
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.max(q);
            }
            ranges[1][k].clear();
            combine_pairs(&v, i16::max, |t| t, &mut ranges[1][k]);
        }
        // level 1 (4×4 blocks) straight from each pair of cell rows
        if cy % 2 == 1 || cy + 1 == cell_rows {
            let second = if cy % 2 == 1 { &odd } else { &even };
            for k in 0..2 {
                for ((w, &p), &q) in w.iter_mut().zip(&even[0][k]).zip(&second[0][k]) {
                    *w = p.min(q);
                }
                combine_pairs(&w, i16::min, |t| t, &mut lo[k]);
                for ((w, &p), &q) in w.iter_mut().zip(&even[1][k]).zip(&second[1][k]) {
                    *w = p.max(q);
                }
                combine_pairs(&w, i16::max, |t| t, &mut hi[k]);
            }
        }
    }
    let base_sums = sums;
    let mut levels = vec![Level {
        cols,
        rows: cell_rows,
        lo: [Vec::new(), Vec::new()],
        hi: [Vec::new(), Vec::new()],
        sum: base_sums,
    }];
    if cols > 1 || cell_rows > 1 {
        let sum = [
            reduce_2x2(&levels[0].sum[0], cols, cell_rows, |p, q| p + q),
            reduce_2x2(&levels[0].sum[1], cols, cell_rows, |p, q| p + q),
            reduce_2x2(&levels[0].sum[2], cols, cell_rows, |p, q| p + q),
        ];
        levels.push(Level {
            cols: cols1,
            rows: rows1,
            lo,
            hi,
            sum,
        });
    }
    while let Some(l) = levels.last().filter(|l| l.cols > 1 || l.rows > 1) {
        let (c, r) = (l.cols, l.rows);
        let next = Level {
            cols: c.div_ceil(2),
            rows: r.div_ceil(2),
            lo: [
                reduce_2x2(&l.lo[0], c, r, i16::min),
                reduce_2x2(&l.lo[1], c, r, i16::min),
            ],
            hi: [
                reduce_2x2(&l.hi[0], c, r, i16::max),
                reduce_2x2(&l.hi[1], c, r, i16::max),
            ],
            sum: [
                reduce_2x2(&l.sum[0], c, r, |p, q| p + q),
                reduce_2x2(&l.sum[1], c, r, |p, q| p + q),
                reduce_2x2(&l.sum[2], c, r, |p, q| p + q),
            ],
        };
        levels.push(next);
    }
    levels
}

/// Merges adjacent regions (4-neighbouring cells with different labels) whose
/// mean colours are closer than `distance`: union–find on running means.
/// Returns each region's merged root.
fn merge(
    labels: &[u32],
    cols: usize,
    rows: usize,
    regions: &mut [Region],
    distance: f32,
) -> Vec<u32> {
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let d2 = distance * distance;
    let mut parent: Vec<u32> = (0..regions.len() as u32).collect();
    let mut try_merge = |a: u32, b: u32, parent: &mut Vec<u32>| {
        let (ra, rb) = (find(parent, a), find(parent, b));
        if ra == rb {
            return;
        }
        let (pa, pb) = (regions[ra as usize], regions[rb as usize]);
        let gap = (0..3)
            .map(|k| (pa.mean[k] - pb.mean[k]).powi(2))
            .sum::<f32>();
        if gap < d2 {
            parent[rb as usize] = ra;
            let count = pa.count + pb.count;
            let (wa, wb) = (pa.count / count, pb.count / count);
            regions[ra as usize] = Region {
                mean: [0, 1, 2].map(|k| wa * pa.mean[k] + wb * pb.mean[k]),
                count,
            };
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
                try_merge(a, row[x + 1], &mut parent);
            }
            if let Some(below) = below {
                let b = below[x];
                if b != a && (a, b) != last_down {
                    try_merge(a, b, &mut parent);
                    last_down = (a, b);
                }
            }
        }
    }
    (0..regions.len() as u32)
        .map(|i| find(&mut parent, i))
        .collect()
}

/// Clears 4-connected components of set cells (`cols × rows`) that hold fewer
/// than `min` pixels, a cell at `(x, y)` holding `weight(x, y)` of them.
fn drop_small_components(
    cells: &mut [u8],
    cols: usize,
    rows: usize,
    weight: impl Fn(usize, usize) -> usize,
    min: usize,
) {
    let mut seen = vec![false; cells.len()];
    let mut stack = Vec::new();
    let mut component = Vec::new();
    for start in 0..cells.len() {
        if cells[start] == 0 || seen[start] {
            continue;
        }
        component.clear();
        stack.push(start);
        seen[start] = true;
        let mut pixels = 0;
        while let Some(i) = stack.pop() {
            component.push(i);
            let (x, y) = (i % cols, i / cols);
            pixels += weight(x, y);
            let mut visit = |j: usize| {
                if cells[j] != 0 && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
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
            for &i in &component {
                cells[i] = 0;
            }
        }
    }
}

/// Area vote: output cell set where at least half of the pixels it covers are.
pub fn resample(mask: &[u8], w: usize, h: usize, out: usize) -> Vec<u8> {
    let span = |i: usize, n: usize| {
        let lo = i * n / out;
        (lo, ((i + 1) * n / out).max(lo + 1).min(n))
    };
    let xs: Vec<(usize, usize)> = (0..out).map(|ox| span(ox, w)).collect();
    let mut res = vec![0u8; out * out];
    let mut column = vec![0u32; w];
    for (oy, res_row) in res.chunks_exact_mut(out).enumerate() {
        let (y0, y1) = span(oy, h);
        column.fill(0);
        for row in mask[y0 * w..y1 * w].chunks_exact(w) {
            for (c, &v) in column.iter_mut().zip(row) {
                *c += u32::from(v != 0);
            }
        }
        for (r, &(x0, x1)) in res_row.iter_mut().zip(&xs) {
            let set: u32 = column[x0..x1].iter().sum();
            *r = u8::from(2 * set as usize >= (y1 - y0) * (x1 - x0));
        }
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The vectorised pyramid (AVX2, where the CPU has it) equals the portable one.
    #[test]
    fn pyramid_is_the_same_on_every_code_path() {
        for (w, h) in [(1, 1), (3, 2), (17, 9), (64, 48), (101, 77)] {
            let rgb: Vec<u8> = (0..w * h * 3)
                .map(|i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8)
                .collect();
            let rows: Vec<&[u8]> = rgb.chunks_exact(3 * w).collect();
            let fast = pyramid(&rows, w);
            assert_eq!(fast, pyramid_portable(&rows, w), "{w}×{h}");
            let top = fast.last().unwrap();
            assert_eq!((top.cols, top.rows), (1, 1));
            // the top block's sums are the sums over all pixels
            let bright: i32 = rgb.iter().map(|&c| i32::from(c)).sum();
            assert_eq!(top.sum[0], vec![bright], "{w}×{h}");
        }
    }
}
