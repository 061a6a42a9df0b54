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
#[derive(Debug, Default, PartialEq)]
struct Level {
    cols: usize,
    rows: usize,
    lo: [Vec<i16>; 2],
    hi: [Vec<i16>; 2],
    /// Sums of brightness, redness and `g − b`.
    sum: [Vec<i32>; 3],
}

/// A leaf of the split, later a merged region: mean colour on [0, 1] and pixels.
#[derive(Debug, Clone, Copy)]
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

/// Segments the instrument in `roi` of an RGB frame (`width × height`, 8 bits,
/// row-major). One-off: in a loop, keep a [`Segmenter`], which allocates nothing
/// once it has seen a region of the size.
pub fn segment(
    rgb: &[u8],
    width: u32,
    height: u32,
    roi: Roi,
    params: &SegmentParams,
) -> Result<Segmentation> {
    let mut segmenter = Segmenter::new(*params)?;
    segmenter.segment(rgb, width, height, roi)?;
    Ok(segmenter.output)
}

/// The segmentation stage of the estimation loop: [`segment`] with its working
/// memory kept from frame to frame, so that after the first frame of a region
/// size a frame costs no allocation.
#[derive(Debug)]
pub struct Segmenter {
    params: SegmentParams,
    scratch: Scratch,
    /// The last frame's result, its masks refilled by the next.
    output: Segmentation,
}

/// Working memory of a [`Segmenter`].
#[derive(Debug, Default)]
struct Scratch {
    levels: Vec<Level>,
    /// Features of a pair of pixel rows, `[brightness, redness, g − b]`.
    features: [[Vec<i16>; 3]; 2],
    /// Cell ranges of an even and an odd cell row, `[lo, hi] × [brightness, redness]`.
    cell_ranges: [[[Vec<i16>; 2]; 2]; 2],
    narrow: Vec<i16>,
    narrow_cells: Vec<i16>,
    wide: Vec<i32>,
    stack: Vec<(usize, usize, usize)>,
    labels: Vec<u32>,
    regions: Vec<Region>,
    parent: Vec<u32>,
    instrument: Vec<u8>,
    cells: Vec<u8>,
    seen: Vec<bool>,
    flood: Vec<usize>,
    component: Vec<usize>,
    row: Vec<u8>,
    column: Vec<u32>,
    spans: Vec<(usize, usize)>,
}

impl Segmenter {
    /// A segmenter with these thresholds; out-of-range thresholds are an error.
    pub fn new(params: SegmentParams) -> Result<Self> {
        let check = |name: &'static str, value: f32, lo: f32, hi: f32| {
            if value.is_finite() && (lo..=hi).contains(&value) {
                Ok(())
            } else {
                Err(EstimateError::InvalidParameter {
                    name,
                    value: f64::from(value),
                    range: format!("[{lo}, {hi}]"),
                })
            }
        };
        check("split_range", params.split_range, 0.0, 3.0)?;
        check("merge_distance", params.merge_distance, 0.0, 2.0)?;
        check("max_saturation", params.max_saturation, 0.0, 1.0)?;
        check("max_redness", params.max_redness, -1.0, 1.0)?;
        check("min_value", params.min_value, 0.0, 1.0)?;
        check("min_component", params.min_component, 0.0, 1.0)?;
        check("min_instrument", params.min_instrument, 0.0, 1.0)?;
        if params.out == 0 || params.out > 4096 {
            return Err(EstimateError::InvalidParameter {
                name: "out",
                value: f64::from(params.out),
                range: "[1, 4096]".into(),
            });
        }
        Ok(Self {
            params,
            scratch: Scratch::default(),
            output: Segmentation {
                full: Mask::new(1, 1)?,
                small: Mask::new(params.out, params.out)?,
            },
        })
    }

    /// The thresholds in use.
    pub fn params(&self) -> &SegmentParams {
        &self.params
    }

    /// Segments the instrument in `roi` of an RGB frame (`width × height`,
    /// 8 bits, row-major). The result lives until the next call.
    pub fn segment(
        &mut self,
        rgb: &[u8],
        width: u32,
        height: u32,
        roi: Roi,
    ) -> Result<&Segmentation> {
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
        let (rw, rh) = (roi.width as usize, roi.height as usize);
        if (rw * rh) as u64 > MAX_ROI_PIXELS {
            return Err(EstimateError::InvalidParameter {
                name: "roi pixels",
                value: (rw * rh) as f64,
                range: format!("[1, {MAX_ROI_PIXELS}]"),
            });
        }
        let region = Region2d {
            rgb,
            first: 3 * (roi.y0 as usize * width as usize + roi.x0 as usize),
            stride: 3 * width as usize,
            width: rw,
            height: rh,
        };
        let p = self.params;
        let s = &mut self.scratch;
        // The smallest leaf is a 2×2 cell, so everything after the split works on the
        // grid of cells (a quarter of the pixels), and the pixel mask is filled last.
        let (cols, rows) = (rw.div_ceil(2), rh.div_ceil(2));
        let depth = pyramid(&region, s);
        split(s, depth, rw, rh, p);
        merge(s, cols, rows, p.merge_distance);
        // threshold each merged region by its mean colour
        let Scratch {
            regions,
            parent,
            instrument,
            labels,
            cells,
            ..
        } = s;
        instrument.clear();
        instrument.reserve(cols * rows);
        instrument.extend(parent.iter().map(|&root| {
            let m = regions[root as usize].mean;
            let (mx, mn) = (m[0].max(m[1]).max(m[2]), m[0].min(m[1]).min(m[2]));
            let redness = m[0] - 0.5 * (m[1] + m[2]);
            u8::from(
                mx > p.min_value && (mx - mn) / mx < p.max_saturation && redness < p.max_redness,
            )
        }));
        cells.clear();
        cells.extend(labels.iter().map(|&l| instrument[l as usize]));
        let min_component = (p.min_component * (rw * rh) as f32).ceil() as usize;
        let count = drop_small_components(s, cols, rows, rw, rh, min_component);
        let min = (p.min_instrument * (rw * rh) as f32).ceil().max(1.0) as usize;
        if count < min {
            return Err(EstimateError::NoInstrument { pixels: count, min });
        }
        let output = &mut self.output;
        output.full.reshape(roi.width, roi.height)?;
        output.small.reshape(p.out, p.out)?;
        s.row.clear();
        s.row.resize(rw, 0);
        for (cy, crow) in s.cells.chunks_exact(cols).enumerate() {
            for (pair, &v) in s.row.chunks_exact_mut(2).zip(crow) {
                pair[0] = v;
                pair[1] = v;
            }
            if rw % 2 == 1 {
                s.row[rw - 1] = crow[cols - 1];
            }
            for y in (2 * cy..2 * cy + 2).filter(|&y| y < rh) {
                output.full.set_row(y as u32, &s.row)?;
            }
        }
        resample_cells(s, cols, rw, rh, &mut output.small)?;
        Ok(output)
    }
}

/// A region of an RGB frame: row `y` starts at byte `first + y · stride`.
struct Region2d<'a> {
    rgb: &'a [u8],
    first: usize,
    stride: usize,
    width: usize,
    height: usize,
}

impl Region2d<'_> {
    fn row(&self, y: usize) -> &[u8] {
        &self.rgb[self.first + y * self.stride..][..3 * self.width]
    }
}

/// Splits the pyramid's top block (level `depth − 1`) down to uniform blocks:
/// each leaf becomes a region and labels its cells.
fn split(s: &mut Scratch, depth: usize, rw: usize, rh: usize, p: SegmentParams) {
    let (split_bright, split_red) = (p.split_range * 765.0, p.split_range * 510.0);
    let (cols, rows) = (s.levels[0].cols, s.levels[0].rows);
    s.labels.clear();
    s.labels.resize(cols * rows, 0);
    // worst cases, reserved once so that no later frame of the size allocates:
    // a region per cell, and a depth-first stack of 3 blocks a level
    s.regions.clear();
    s.regions.reserve(cols * rows);
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

/// Combines each aligned 2×2 group of `src` (`cols × rows`) with `op` into
/// `dst` (a group cut by the edge combines what it has); `vertical` is scratch.
#[inline(always)]
fn reduce_2x2<T: Copy + Default>(
    src: &[T],
    cols: usize,
    op: impl Fn(T, T) -> T,
    dst: &mut Vec<T>,
    vertical: &mut Vec<T>,
) {
    dst.clear();
    vertical.clear();
    vertical.resize(cols, T::default());
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
        combine_pairs(vertical, &op, |t| t, dst);
    }
}

/// Per-pixel features of a row of RGB: brightness `r + g + b`, redness
/// `2r − g − b` and `g − b` (the three determine the colour); each plane of
/// `out` is a row long.
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

/// Builds the split pyramid of the region in `s.levels`: 2×2 cells first, each
/// level above from the one below, up to a single block. Returns the number of
/// levels.
fn pyramid(region: &Region2d, s: &mut Scratch) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { pyramid_avx2(region, s) };
    }
    pyramid_portable(region, s)
}

/// [`pyramid`] compiled for AVX2: its byte shuffles take the RGB triples apart
/// many pixels at a time (the x86-64 baseline has none) and its min, max and
/// sums run 16 lanes wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn pyramid_avx2(region: &Region2d, s: &mut Scratch) -> usize {
    pyramid_portable(region, s)
}

#[inline(always)]
fn pyramid_portable(region: &Region2d, s: &mut Scratch) -> usize {
    let (rw, rh) = (region.width, region.height);
    let (cols, cell_rows) = (rw.div_ceil(2), rh.div_ceil(2));
    let depth = {
        // levels until one block: 2×2 cells, then halving
        let mut n = 1;
        let (mut c, mut r) = (cols, cell_rows);
        while c > 1 || r > 1 {
            (c, r) = (c.div_ceil(2), r.div_ceil(2));
            n += 1;
        }
        n
    };
    if s.levels.len() < depth {
        s.levels.resize_with(depth, Level::default);
    }
    let Scratch {
        levels,
        features: [fa, fb],
        cell_ranges,
        narrow: v,
        narrow_cells: w,
        wide,
        ..
    } = s;
    for plane in fa.iter_mut().chain(fb.iter_mut()) {
        plane.clear();
        plane.resize(rw, 0);
    }
    v.clear();
    v.resize(rw, 0);
    w.clear();
    w.resize(cols, 0);
    let (base, above) = levels.split_at_mut(1);
    let base = &mut base[0];
    (base.cols, base.rows) = (cols, cell_rows);
    for plane in base.sum.iter_mut() {
        plane.clear();
    }
    // level 1 (4×4 blocks) takes its ranges straight from pairs of cell rows
    let mut level1 = above.first_mut();
    if let Some(l1) = level1.as_deref_mut() {
        (l1.cols, l1.rows) = (cols.div_ceil(2), cell_rows.div_ceil(2));
        for plane in l1.lo.iter_mut().chain(l1.hi.iter_mut()) {
            plane.clear();
        }
    }
    let [even, odd] = cell_ranges;
    for cy in 0..cell_rows {
        features(region.row(2 * cy), fa);
        let single = 2 * cy + 1 >= rh;
        if single {
            fb.clone_from(fa);
        } else {
            features(region.row(2 * cy + 1), fb);
        }
        for k in 0..3 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = if single { p } else { p + q };
            }
            let wide_add = |p: i16, q: i16| i32::from(p) + i32::from(q);
            combine_pairs(v, wide_add, i32::from, &mut base.sum[k]);
        }
        let Some(l1) = level1.as_deref_mut() else {
            continue;
        };
        let ranges = if cy % 2 == 0 { &mut *even } else { &mut *odd };
        for k in 0..2 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.min(q);
            }
            ranges[0][k].clear();
            combine_pairs(v, i16::min, |t| t, &mut ranges[0][k]);
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.max(q);
            }
            ranges[1][k].clear();
            combine_pairs(v, i16::max, |t| t, &mut ranges[1][k]);
        }
        if cy % 2 == 1 || cy + 1 == cell_rows {
            let second = if cy % 2 == 1 { &*odd } else { &*even };
            for k in 0..2 {
                for ((w, &p), &q) in w.iter_mut().zip(&even[0][k]).zip(&second[0][k]) {
                    *w = p.min(q);
                }
                combine_pairs(w, i16::min, |t| t, &mut l1.lo[k]);
                for ((w, &p), &q) in w.iter_mut().zip(&even[1][k]).zip(&second[1][k]) {
                    *w = p.max(q);
                }
                combine_pairs(w, i16::max, |t| t, &mut l1.hi[k]);
            }
        }
    }
    for n in 1..depth {
        let (below, rest) = levels.split_at_mut(n);
        let (src, dst) = (&below[n - 1], &mut rest[0]);
        let c = src.cols;
        (dst.cols, dst.rows) = (c.div_ceil(2), src.rows.div_ceil(2));
        for k in 0..3 {
            reduce_2x2(&src.sum[k], c, |p, q| p + q, &mut dst.sum[k], wide);
        }
        if n > 1 {
            for k in 0..2 {
                reduce_2x2(&src.lo[k], c, i16::min, &mut dst.lo[k], v);
                reduce_2x2(&src.hi[k], c, i16::max, &mut dst.hi[k], v);
            }
        }
    }
    depth
}

/// Merges adjacent regions (4-neighbouring cells with different labels) whose
/// mean colours are closer than `distance`: union–find on running means.
/// Leaves each region's merged root in `s.parent`.
fn merge(s: &mut Scratch, cols: usize, rows: usize, distance: f32) {
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let d2 = distance * distance;
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
fn drop_small_components(
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

/// The area vote of [`resample`] from the cells (`cols` a row, each the value
/// of its up to 2×2 pixels of the `rw × rh` region) into `out`.
fn resample_cells(
    s: &mut Scratch,
    cols: usize,
    rw: usize,
    rh: usize,
    out: &mut Mask,
) -> Result<()> {
    let n = out.width() as usize;
    s.spans.clear();
    s.spans.extend((0..n).map(|ox| vote_span(ox, rw, n)));
    s.row.clear();
    s.row.resize(n, 0);
    s.column.clear();
    s.column.resize(cols, 0);
    for oy in 0..n {
        let (y0, y1) = vote_span(oy, rh, n);
        // pixels set in each cell column over pixel rows y0..y1
        s.column.fill(0);
        for y in y0..y1 {
            let crow = &s.cells[(y / 2) * cols..][..cols];
            for (c, &v) in s.column.iter_mut().zip(crow) {
                *c += u32::from(v);
            }
        }
        for (r, &(x0, x1)) in s.row.iter_mut().zip(&s.spans) {
            let set: u32 = (x0..x1).map(|x| s.column[x / 2]).sum();
            *r = u8::from(2 * set as usize >= (y1 - y0) * (x1 - x0));
        }
        out.set_row(oy as u32, &s.row)?;
    }
    Ok(())
}

/// The pixels `[lo, hi)` of `len` that output cell `i` of `n` covers in the area
/// vote (at least one).
fn vote_span(i: usize, len: usize, n: usize) -> (usize, usize) {
    let lo = i * len / n;
    (lo, ((i + 1) * len / n).max(lo + 1).min(len))
}

/// Area vote: output cell set where at least half of the pixels it covers are.
pub fn resample(mask: &[u8], w: usize, h: usize, out: usize) -> Vec<u8> {
    let xs: Vec<(usize, usize)> = (0..out).map(|ox| vote_span(ox, w, out)).collect();
    let mut res = vec![0u8; out * out];
    let mut column = vec![0u32; w];
    for (oy, res_row) in res.chunks_exact_mut(out).enumerate() {
        let (y0, y1) = vote_span(oy, h, out);
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

    fn region(rgb: &[u8], w: usize, h: usize) -> Region2d<'_> {
        Region2d {
            rgb,
            first: 0,
            stride: 3 * w,
            width: w,
            height: h,
        }
    }

    /// The vectorised pyramid (AVX2, where the CPU has it) equals the portable one.
    #[test]
    fn pyramid_is_the_same_on_every_code_path() {
        for (w, h) in [(1, 1), (3, 2), (17, 9), (64, 48), (101, 77)] {
            let rgb: Vec<u8> = (0..w * h * 3)
                .map(|i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8)
                .collect();
            let (mut fast, mut portable) = (Scratch::default(), Scratch::default());
            let depth = pyramid(&region(&rgb, w, h), &mut fast);
            assert_eq!(depth, pyramid_portable(&region(&rgb, w, h), &mut portable));
            assert_eq!(fast.levels[..depth], portable.levels[..depth], "{w}×{h}");
            let top = &fast.levels[depth - 1];
            assert_eq!((top.cols, top.rows), (1, 1));
            // the top block's sums are the sums over all pixels
            let bright: i32 = rgb.iter().map(|&c| i32::from(c)).sum();
            assert_eq!(top.sum[0], vec![bright], "{w}×{h}");
        }
    }

    /// The area vote from the cells equals the one from the pixel mask.
    #[test]
    fn resampling_cells_equals_resampling_pixels() {
        for (rw, rh, n) in [
            (1usize, 1usize, 48usize),
            (7, 5, 3),
            (220, 220, 48),
            (101, 37, 48),
            (30, 90, 7),
        ] {
            let (cols, rows) = (rw.div_ceil(2), rh.div_ceil(2));
            let mut s = Scratch {
                cells: (0..cols * rows)
                    .map(|i| u8::from(i % 7 < 3 || i % 5 == 0))
                    .collect(),
                ..Scratch::default()
            };
            let pixels: Vec<u8> = (0..rw * rh)
                .map(|i| s.cells[(i / rw / 2) * cols + (i % rw) / 2])
                .collect();
            let mut out = Mask::new(n as u32, n as u32).unwrap();
            resample_cells(&mut s, cols, rw, rh, &mut out).unwrap();
            assert_eq!(out.data(), resample(&pixels, rw, rh, n), "{rw}×{rh} → {n}");
        }
    }
}
