//! Region-based segmentation (the paper's Fig. 4b): region of interest,
//! split, merge, threshold — giving the 48×48 binary image IBJAE consumes.
//!
//! 1. **Region of interest**: a rectangle of the frame ([`Roi`]).
//! 2. **Split**: a quadtree of aligned power-of-two blocks. A block is split in
//!    four while the range of its brightness or of its redness exceeds
//!    [`SegmentParams::split_range`] and its side exceeds [`SegmentParams::min_block`]
//!    px (at least 2). Block statistics come from a pyramid built bottom-up in one
//!    pass, so the split is linear in the pixels.
//! 3. **Merge**: adjacent leaves whose mean colours differ by less than
//!    [`SegmentParams::merge_distance`] become one region (union–find over the
//!    leaves' adjacency, on the regions' running means).
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

struct Leaf {
    sum: [f32; 3],
    count: u32,
}

/// Statistics of a block: brightness and redness ranges, colour sum, pixel count.
#[derive(Clone, Copy)]
struct Block {
    lo: [f32; 2],
    hi: [f32; 2],
    sum: [f32; 3],
    count: u32,
}

impl Block {
    const EMPTY: Block = Block {
        lo: [f32::MAX; 2],
        hi: [f32::MIN; 2],
        sum: [0.0; 3],
        count: 0,
    };

    fn add_pixel(&mut self, c: [f32; 3]) {
        let f = [(c[0] + c[1] + c[2]) / 3.0, c[0] - 0.5 * (c[1] + c[2])];
        self.lo = [self.lo[0].min(f[0]), self.lo[1].min(f[1])];
        self.hi = [self.hi[0].max(f[0]), self.hi[1].max(f[1])];
        self.sum = [self.sum[0] + c[0], self.sum[1] + c[1], self.sum[2] + c[2]];
        self.count += 1;
    }

    fn absorb(&mut self, o: &Block) {
        self.lo = [self.lo[0].min(o.lo[0]), self.lo[1].min(o.lo[1])];
        self.hi = [self.hi[0].max(o.hi[0]), self.hi[1].max(o.hi[1])];
        self.sum = [
            self.sum[0] + o.sum[0],
            self.sum[1] + o.sum[1],
            self.sum[2] + o.sum[2],
        ];
        self.count += o.count;
    }
}

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
    if roi.width == 0
        || roi.height == 0
        || roi.x0 + roi.width > width
        || roi.y0 + roi.height > height
    {
        return Err(EstimateError::InvalidParameter {
            name: "roi",
            value: f64::from(roi.x0 + roi.width),
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
    // split: a quadtree of aligned power-of-two blocks. Statistics of every block
    // come from a pyramid built bottom-up in one pass (2×2 blocks from the pixels,
    // each level from the one below), so the split costs O(pixels), not O(pixels · depth).
    let mut levels: Vec<(usize, usize, Vec<Block>)> = Vec::new(); // (columns, rows, blocks)
    {
        let (cols, rows) = (rw.div_ceil(2), rh.div_ceil(2));
        let mut base = vec![Block::EMPTY; cols * rows];
        for y in 0..rh {
            let row = 3 * ((roi.y0 as usize + y) * width as usize + roi.x0 as usize);
            let brow = (y / 2) * cols;
            for (x, c) in rgb[row..row + 3 * rw].chunks_exact(3).enumerate() {
                base[brow + x / 2].add_pixel([
                    f32::from(c[0]) / 255.0,
                    f32::from(c[1]) / 255.0,
                    f32::from(c[2]) / 255.0,
                ]);
            }
        }
        levels.push((cols, rows, base));
        while let Some((pc, pr, prev)) = levels.last().filter(|l| l.0 > 1 || l.1 > 1) {
            let (pc, pr) = (*pc, *pr);
            let (cols, rows) = (pc.div_ceil(2), pr.div_ceil(2));
            let mut next = vec![Block::EMPTY; cols * rows];
            for y in 0..pr {
                for x in 0..pc {
                    next[(y / 2) * cols + x / 2].absorb(&prev[y * pc + x]);
                }
            }
            levels.push((cols, rows, next));
        }
    }
    let mut labels = vec![0u32; rw * rh];
    let mut leaves: Vec<Leaf> = Vec::new();
    let top = levels.len() - 1;
    let mut stack = vec![(top, 0usize, 0usize)];
    while let Some((level, bx, by)) = stack.pop() {
        let (cols, _, blocks) = &levels[level];
        let b = &blocks[by * cols + bx];
        if b.count == 0 {
            continue;
        }
        let uniform =
            b.hi[0] - b.lo[0] <= params.split_range && b.hi[1] - b.lo[1] <= params.split_range;
        let side = 2usize << level; // pixels per block side at this level
        if uniform || side <= params.min_block.max(2) as usize || level == 0 {
            let id = leaves.len() as u32;
            leaves.push(Leaf {
                sum: b.sum,
                count: b.count,
            });
            let (x0, y0) = (bx * side, by * side);
            let (x1, y1) = ((x0 + side).min(rw), (y0 + side).min(rh));
            for yy in y0..y1 {
                labels[yy * rw + x0..yy * rw + x1].fill(id);
            }
        } else {
            let (cc, cr, _) = &levels[level - 1];
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let (cx, cy) = (2 * bx + dx, 2 * by + dy);
                if cx < *cc && cy < *cr {
                    stack.push((level - 1, cx, cy));
                }
            }
        }
    }
    // merge: union–find over adjacent leaves with similar means
    let mut parent: Vec<u32> = (0..leaves.len() as u32).collect();
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    let mean = |l: &Leaf| l.sum.map(|s| s / l.count as f32);
    let try_merge = |a: u32, b: u32, parent: &mut Vec<u32>, leaves: &mut Vec<Leaf>| {
        let (ra, rb) = (find(parent, a), find(parent, b));
        if ra == rb {
            return;
        }
        let (ma, mb) = (mean(&leaves[ra as usize]), mean(&leaves[rb as usize]));
        let d =
            ((ma[0] - mb[0]).powi(2) + (ma[1] - mb[1]).powi(2) + (ma[2] - mb[2]).powi(2)).sqrt();
        if d < params.merge_distance {
            parent[rb as usize] = ra;
            let (s, c) = (leaves[rb as usize].sum, leaves[rb as usize].count);
            let l = &mut leaves[ra as usize];
            for (acc, add) in l.sum.iter_mut().zip(s) {
                *acc += add;
            }
            l.count += c;
        }
    };
    for y in 0..rh {
        for x in 0..rw {
            let a = labels[y * rw + x];
            if x + 1 < rw && labels[y * rw + x + 1] != a {
                try_merge(a, labels[y * rw + x + 1], &mut parent, &mut leaves);
            }
            if y + 1 < rh && labels[(y + 1) * rw + x] != a {
                try_merge(a, labels[(y + 1) * rw + x], &mut parent, &mut leaves);
            }
        }
    }
    // threshold each merged region by its mean colour
    let is_instrument: Vec<bool> = (0..leaves.len() as u32)
        .map(|i| {
            let r = find(&mut parent, i);
            let m = mean(&leaves[r as usize]);
            let (mx, mn) = (m[0].max(m[1]).max(m[2]), m[0].min(m[1]).min(m[2]));
            let redness = m[0] - 0.5 * (m[1] + m[2]);
            mx > params.min_value
                && (mx - mn) / mx < params.max_saturation
                && redness < params.max_redness
        })
        .collect();
    let mut full: Vec<u8> = labels
        .iter()
        .map(|&l| u8::from(is_instrument[l as usize]))
        .collect();
    drop_small_components(
        &mut full,
        rw,
        rh,
        (params.min_component * (rw * rh) as f32).ceil() as usize,
    );
    let count = full.iter().filter(|&&v| v != 0).count();
    let min = (params.min_instrument * (rw * rh) as f32).ceil().max(1.0) as usize;
    if count < min {
        return Err(EstimateError::NoInstrument { pixels: count, min });
    }
    let small = resample(&full, rw, rh, params.out as usize);
    Ok(Segmentation {
        full: Mask::from_raw(roi.width, roi.height, full)?,
        small: Mask::from_raw(params.out, params.out, small)?,
    })
}

/// Clears 4-connected components of set pixels smaller than `min` pixels.
fn drop_small_components(mask: &mut [u8], w: usize, h: usize, min: usize) {
    let mut seen = vec![false; mask.len()];
    let mut stack = Vec::new();
    let mut component = Vec::new();
    for start in 0..mask.len() {
        if mask[start] == 0 || seen[start] {
            continue;
        }
        component.clear();
        stack.push(start);
        seen[start] = true;
        while let Some(i) = stack.pop() {
            component.push(i);
            let (x, y) = (i % w, i / w);
            let mut visit = |j: usize| {
                if mask[j] != 0 && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < w {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - w);
            }
            if y + 1 < h {
                visit(i + w);
            }
        }
        if component.len() < min {
            for &i in &component {
                mask[i] = 0;
            }
        }
    }
}

/// Area vote: output cell set where at least half of the pixels it covers are.
pub fn resample(mask: &[u8], w: usize, h: usize, out: usize) -> Vec<u8> {
    let mut res = vec![0u8; out * out];
    for oy in 0..out {
        let (y0, y1) = (
            oy * h / out,
            ((oy + 1) * h / out).max(oy * h / out + 1).min(h),
        );
        for ox in 0..out {
            let (x0, x1) = (
                ox * w / out,
                ((ox + 1) * w / out).max(ox * w / out + 1).min(w),
            );
            let mut set = 0usize;
            for y in y0..y1 {
                set += mask[y * w + x0..y * w + x1]
                    .iter()
                    .filter(|&&v| v != 0)
                    .count();
            }
            res[oy * out + ox] = u8::from(2 * set >= (y1 - y0) * (x1 - x0));
        }
    }
    res
}
