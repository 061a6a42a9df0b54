//! The threshold step, adapted to each frame: the merged regions are sorted
//! into instrument and tissue by their mean colour's chromaticity, with the
//! boundary placed between the frame's own tissue and instrument colours
//! (the frame's median tissue colour, re-estimated from the tissue class,
//! against the metal's known colour), not at fixed absolute thresholds.
//!
//! Chromaticity: a mean colour `(r, g, b)` of brightness `L = r + g + b`
//! maps to `x = (r − (g + b)/2) / L` (redness) and `y = (√3/2)(g − b) / L`
//! (green against blue): a colour's hue and saturation without its
//! brightness, so an illumination gain leaves it where it is.

use super::{Scratch, SegmentParams};

/// Bins of the chromaticity histograms, over `[-1, 1]`.
const BINS: usize = 512;

/// Chromaticity `[x, y]` of a mean colour (see the module docs); neutral for black.
pub(super) fn chroma(m: [f32; 3]) -> [f32; 2] {
    let l = m[0] + m[1] + m[2];
    if l <= 1e-6 {
        return [0.0, 0.0];
    }
    [
        (m[0] - 0.5 * (m[1] + m[2])) / l,
        0.866_025_4 * (m[1] - m[2]) / l,
    ]
}

/// A weighted histogram of values in `[-1, 1]` (or `[0, 3]` scaled by the caller).
struct Histogram {
    bins: [f64; BINS],
    total: f64,
}

impl Histogram {
    fn new() -> Self {
        Self {
            bins: [0.0; BINS],
            total: 0.0,
        }
    }

    /// Adds `weight` at `v` in `[lo, hi]` (clamped).
    fn add(&mut self, v: f32, lo: f32, hi: f32, weight: f64) {
        let t = ((v - lo) / (hi - lo) * BINS as f32).clamp(0.0, (BINS - 1) as f32);
        self.bins[t as usize] += weight;
        self.total += weight;
    }

    /// The weighted quantile `q` of what was added, at the centre of its bin.
    fn quantile(&self, q: f64, lo: f32, hi: f32) -> f32 {
        let target = q * self.total;
        let mut acc = 0.0;
        for (i, &b) in self.bins.iter().enumerate() {
            acc += b;
            if acc >= target && b > 0.0 {
                return lo + (hi - lo) * (i as f32 + 0.5) / BINS as f32;
            }
        }
        0.5 * (lo + hi)
    }
}

/// What the classification found, for the decision "instrument or not".
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Classes {
    /// Mean chromaticity of the instrument class (`None`: the class is empty).
    pub(super) instrument: Option<[f32; 2]>,
    /// Mean chromaticity of the (bright) tissue class.
    pub(super) tissue: [f32; 2],
}

fn dist2(a: [f32; 2], b: [f32; 2]) -> f32 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// Whether chromaticity `ch` lies on the metal's side of the line across
/// the segment from `metal` to `tissue` at `share` of its length (0.5: the
/// nearer of the two).
fn metal_side(ch: [f32; 2], metal: [f32; 2], tissue: [f32; 2], share: f32) -> bool {
    let d = [tissue[0] - metal[0], tissue[1] - metal[1]];
    let dd = d[0] * d[0] + d[1] * d[1];
    if dd <= 1e-12 {
        return false;
    }
    ((ch[0] - metal[0]) * d[0] + (ch[1] - metal[1]) * d[1]) < share * dd
}

/// Calls `f(a, b)` for the merged regions on either side of every cell
/// edge (right and down neighbours) leaving a cell of `window` (`[x0, y0,
/// x1, y1]`, inclusive) where they differ: `labels` are the cells' leaves,
/// `parent` each leaf's region (fully compressed). Cells of one leaf are
/// skipped without looking their region up.
#[inline(always)]
fn for_each_edge(
    labels: &[u32],
    parent: &[u32],
    cols: usize,
    [x0, y0, x1, y1]: [usize; 4],
    mut f: impl FnMut(usize, usize),
) {
    let rows = labels.len() / cols;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let la = labels[y * cols + x];
            let right = (x + 1 < cols).then(|| labels[y * cols + x + 1]);
            let down = (y + 1 < rows).then(|| labels[(y + 1) * cols + x]);
            for lb in [right, down].into_iter().flatten() {
                if la != lb {
                    let (a, b) = (parent[la as usize], parent[lb as usize]);
                    if a != b {
                        f(a as usize, b as usize);
                    }
                }
            }
        }
    }
}

/// Calls `f(r, other)` for every cell edge between a region `r` of class
/// `class` and another region: each such region's edges are walked in its
/// own box (one cell wider above and to the left), which for the few small
/// regions this is asked of (highlights, clipped light) is far less than
/// the whole grid; where the boxes add up to more than the grid, the grid is
/// walked once instead.
#[allow(clippy::too_many_arguments)]
fn edges_of_class(
    labels: &[u32],
    parent: &[u32],
    cols: usize,
    leaf_box: &[[u32; 4]],
    boxes: &mut Vec<[u32; 4]>,
    region_class: &[u8],
    class: u8,
    mut f: impl FnMut(usize, usize),
) {
    if cols == 0 || labels.is_empty() {
        return;
    }
    boxes.clear();
    boxes.resize(region_class.len(), [u32::MAX, u32::MAX, 0, 0]);
    for (leaf, b) in leaf_box.iter().enumerate() {
        let r = parent[leaf] as usize;
        if region_class[r] == class {
            let c = &mut boxes[r];
            *c = [
                c[0].min(b[0]),
                c[1].min(b[1]),
                c[2].max(b[2]),
                c[3].max(b[3]),
            ];
        }
    }
    let area: usize = boxes
        .iter()
        .filter(|c| c[0] != u32::MAX)
        .map(|c| (c[2] - c[0] + 2) as usize * (c[3] - c[1] + 2) as usize)
        .sum();
    if area > labels.len() {
        let whole = [0, 0, cols - 1, labels.len() / cols - 1];
        for_each_edge(labels, parent, cols, whole, |a, b| {
            if region_class[a] == class {
                f(a, b);
            }
            if region_class[b] == class {
                f(b, a);
            }
        });
        return;
    }
    for (r, c) in boxes.iter().enumerate() {
        if c[0] == u32::MAX {
            continue;
        }
        let window = [
            c[0].saturating_sub(1) as usize,
            c[1].saturating_sub(1) as usize,
            c[2] as usize,
            c[3] as usize,
        ];
        for_each_edge(labels, parent, cols, window, |a, b| {
            if a == r {
                f(r, b);
            } else if b == r {
                f(r, a);
            }
        });
    }
}

/// Sorts every merged region (root of `s.parent`) into instrument or tissue
/// and marks the cells of instrument regions in `s.cells`:
///
/// 1. regions darker than [`SegmentParams::min_relative_value`] of the
///    region of interest's median brightness are tissue (lumen, shadow);
/// 2. regions whose darkest channel is above [`SegmentParams::clip_value`]
///    (clipped specular light), whose brightest is above
///    [`SegmentParams::saturated_value`] (a clipped channel: no trustworthy
///    chromaticity), or which are highlights (small, brighter than the
///    median and [`SegmentParams::highlight_ratio`] times brighter than the
///    regions around them) are left for step 5;
/// 3. the tissue colour `T` starts at the median chromaticity of the bright
///    regions on the region of interest's border where they hold more than
///    60 % of it (the instrument enters from one side, so it holds a
///    minority of the border even where its shaft fills the region); else at
///    the median chromaticity of the regions whose distance from the metal's
///    `M` ([`SegmentParams::metal_chroma`]) lies between the median and the
///    80th percentile;
/// 4. a region is instrument where its chromaticity is nearer `M` than `T`
///    (for a region brighter than [`SegmentParams::bright_ratio`] times the
///    median: where it lies within [`SegmentParams::bright_metal_share`] of
///    the way from `M` to `T`);
///    then `T` becomes the pixel-weighted median of the tissue class and the
///    regions are sorted again (two rounds);
/// 5. a specular region takes the class that borders most of it.
pub(super) fn classify(s: &mut Scratch, p: &SegmentParams, cols: usize) -> Classes {
    let Scratch {
        regions,
        parent,
        instrument,
        labels,
        cells,
        region_class,
        votes,
        neighbours,
        roots,
        leaf_box,
        boxes,
        ..
    } = s;
    // 1–3: the frame's statistics
    // the merged regions, once: every loop below runs over them, not the leaves
    roots.clear();
    roots.extend((0..parent.len() as u32).filter(|&i| parent[i as usize] == i));
    let mut brightness = Histogram::new();
    for &i in roots.iter() {
        let r = &regions[i as usize];
        brightness.add(r.lum, 0.0, 3.0, f64::from(r.count));
    }
    let median_l = brightness.quantile(0.5, 0.0, 3.0);
    let min_l = p.min_relative_value * median_l;
    const DARK: u8 = 0;
    const BRIGHT: u8 = 1;
    const CLIPPED: u8 = 2;
    region_class.clear();
    region_class.resize(regions.len(), DARK);
    for &i in roots.iter() {
        let m = regions[i as usize].mean;
        region_class[i as usize] = if m[0] + m[1] + m[2] < min_l {
            DARK
        } else if m[0].min(m[1]).min(m[2]) > p.clip_value
            || m[0].max(m[1]).max(m[2]) > p.saturated_value
        {
            CLIPPED
        } else {
            BRIGHT
        };
    }
    // highlights: small near-white regions brighter than the median and
    // than what surrounds them are treated as clipped (step 5)
    const CANDIDATE: u8 = 3;
    if p.highlight_ratio > 0.0 {
        let total: f32 = roots.iter().map(|&i| regions[i as usize].count).sum();
        let mut any = false;
        for &i in roots.iter() {
            let (r, c) = (&regions[i as usize], &mut region_class[i as usize]);
            if *c == BRIGHT
                && r.count < p.highlight_max * total
                && r.lum > median_l
                && r.mean.iter().copied().fold(f32::INFINITY, f32::min) > p.highlight_min_value
            {
                *c = CANDIDATE;
                any = true;
            }
        }
        if any {
            neighbours.clear();
            neighbours.resize(regions.len(), [0.0, 0.0]);
            edges_of_class(
                labels,
                parent,
                cols,
                leaf_box,
                boxes,
                region_class,
                CANDIDATE,
                |r, other| {
                    neighbours[r][0] += regions[other].lum;
                    neighbours[r][1] += 1.0;
                },
            );
            for &i in roots.iter() {
                let i = i as usize;
                if region_class[i] == CANDIDATE {
                    let [sum, edges] = neighbours[i];
                    region_class[i] =
                        if edges > 0.0 && regions[i].lum > p.highlight_ratio * sum / edges {
                            CLIPPED
                        } else {
                            BRIGHT
                        };
                }
            }
        }
    }
    let bright = || {
        roots
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| region_class[i] == BRIGHT)
            .map(|i| &regions[i])
    };
    // the tissue colour starts at the median colour of the regions whose
    // distance from the metal's colour lies between the median and the 80th
    // percentile (pixel-weighted): tissue, whether the instrument covers a
    // little or most of the region, and not the reddest tenth (red tape, dark
    // vessels); medians, not means, throughout
    let mut far = Histogram::new();
    for r in bright() {
        far.add(
            dist2(r.chroma, p.metal_chroma).sqrt(),
            0.0,
            2.0,
            f64::from(r.count),
        );
    }
    let (near, farthest) = (far.quantile(0.5, 0.0, 2.0), far.quantile(0.8, 0.0, 2.0));
    let (mut hx, mut hy, mut fallback) = (Histogram::new(), Histogram::new(), [0.0f32; 2]);
    for r in bright() {
        let ch = r.chroma;
        fallback = ch;
        let d = dist2(ch, p.metal_chroma).sqrt();
        if d >= near && d <= farthest {
            hx.add(ch[0], -1.0, 1.0, f64::from(r.count));
            hy.add(ch[1], -1.0, 1.0, f64::from(r.count));
        }
    }
    let mut tissue = if hx.total > 0.0 {
        [hx.quantile(0.5, -1.0, 1.0), hy.quantile(0.5, -1.0, 1.0)]
    } else {
        fallback
    };
    // where the region's border is mostly bright tissue, its median colour is
    // the better start: the instrument enters the region from one side, so it
    // holds a minority of the border even where it fills most of the region
    let rows = labels.len() / cols.max(1);
    let (mut bx, mut by) = (Histogram::new(), Histogram::new());
    let mut border = 0usize;
    let ring = (0..cols)
        .flat_map(|x| [x, (rows.saturating_sub(1)) * cols + x])
        .chain((1..rows.saturating_sub(1)).flat_map(|y| [y * cols, y * cols + cols - 1]));
    for i in ring {
        let Some(&l) = labels.get(i) else { continue };
        border += 1;
        let root = parent[l as usize] as usize;
        if region_class[root] == BRIGHT {
            let ch = regions[root].chroma;
            bx.add(ch[0], -1.0, 1.0, 1.0);
            by.add(ch[1], -1.0, 1.0, 1.0);
        }
    }
    if bx.total > 0.6 * border as f64 {
        tissue = [bx.quantile(0.5, -1.0, 1.0), by.quantile(0.5, -1.0, 1.0)];
    }
    // the metal's colour stays the known one: re-estimating it as well (full
    // k-means) lets it drift onto pale tissue (measured: gain 1.6 on the
    // larynx fell to IoU 0.64)
    let metal = p.metal_chroma;
    // bright tissue is pulled toward white (its sheen, its red channel
    // clipping), so a bright region must lie nearer the metal
    let share = |lum: f32| {
        if lum > p.bright_ratio * median_l {
            p.bright_metal_share
        } else {
            0.5
        }
    };
    // 4: nearest class colour, twice re-estimated
    let mut found = None;
    for round in 0..3 {
        let (mut sum_m, mut n_m) = ([0.0f64; 2], 0.0f64);
        let (mut hx, mut hy) = (Histogram::new(), Histogram::new());
        for r in bright() {
            let ch = r.chroma;
            let w = f64::from(r.count);
            if metal_side(ch, metal, tissue, share(r.lum)) {
                sum_m = [
                    sum_m[0] + w * f64::from(ch[0]),
                    sum_m[1] + w * f64::from(ch[1]),
                ];
                n_m += w;
            } else {
                hx.add(ch[0], -1.0, 1.0, w);
                hy.add(ch[1], -1.0, 1.0, w);
            }
        }
        found = (n_m > 0.0).then(|| sum_m.map(|v| (v / n_m) as f32));
        if round == 2 {
            break;
        }
        if hx.total > 0.0 {
            tissue = [hx.quantile(0.5, -1.0, 1.0), hy.quantile(0.5, -1.0, 1.0)];
        }
    }
    instrument.clear();
    instrument.resize(regions.len(), 0);
    for &i in roots.iter() {
        let i = i as usize;
        let ch = regions[i].chroma;
        instrument[i] = u8::from(
            region_class[i] == BRIGHT && metal_side(ch, metal, tissue, share(regions[i].lum)),
        );
    }
    // 5: clipped regions and highlights take their neighbours' class, by
    // shared cell edges
    if roots.iter().any(|&i| region_class[i as usize] == CLIPPED) {
        votes.clear();
        votes.resize(regions.len(), [0, 0]);
        edges_of_class(
            labels,
            parent,
            cols,
            leaf_box,
            boxes,
            region_class,
            CLIPPED,
            |r, other| {
                if region_class[other] != CLIPPED {
                    votes[r][usize::from(instrument[other])] += 1;
                }
            },
        );
        for &i in roots.iter() {
            let i = i as usize;
            if region_class[i] == CLIPPED {
                instrument[i] = u8::from(votes[i][1] > votes[i][0]);
            }
        }
    }
    cells.clear();
    cells.extend(
        labels
            .iter()
            .map(|&l| instrument[parent[l as usize] as usize]),
    );
    Classes {
        instrument: found,
        tissue,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every edge between a region of the class and another, counted by
    /// brute force over the grid.
    fn brute(labels: &[u32], parent: &[u32], cols: usize, class_of: &[u8], class: u8) -> Vec<u32> {
        let n = class_of.len();
        let mut count = vec![0u32; n * n];
        let rows = labels.len() / cols;
        for y in 0..rows {
            for x in 0..cols {
                let a = parent[labels[y * cols + x] as usize] as usize;
                let mut pair = |b: usize| {
                    if a != b {
                        if class_of[a] == class {
                            count[a * n + b] += 1;
                        }
                        if class_of[b] == class {
                            count[b * n + a] += 1;
                        }
                    }
                };
                if x + 1 < cols {
                    pair(parent[labels[y * cols + x + 1] as usize] as usize);
                }
                if y + 1 < rows {
                    pair(parent[labels[(y + 1) * cols + x] as usize] as usize);
                }
            }
        }
        count
    }

    #[test]
    fn walking_boxes_finds_the_edges_the_whole_grid_has() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for (cols, rows, roots, small) in [(17, 11, 6, true), (17, 11, 6, false), (40, 3, 9, true)]
        {
            // one leaf a cell; leaves grouped into regions: blobs around a
            // few seeds when `small` (the box walk), else scattered (the
            // grid walk, the boxes adding up to more than the grid)
            let n = cols * rows;
            let seeds: Vec<(usize, usize)> = (0..roots)
                .map(|_| (rng.random_range(0..cols), rng.random_range(0..rows)))
                .collect();
            let region: Vec<usize> = (0..n)
                .map(|i| {
                    let (x, y) = (i % cols, i / cols);
                    if small {
                        seeds
                            .iter()
                            .position(|&(sx, sy)| sx.abs_diff(x) <= 2 && sy.abs_diff(y) <= 1)
                            .unwrap_or(roots)
                    } else {
                        rng.random_range(0..=roots)
                    }
                })
                .collect();
            // each region's root: its first leaf
            let mut first = vec![usize::MAX; roots + 1];
            for (i, &r) in region.iter().enumerate() {
                if first[r] == usize::MAX {
                    first[r] = i;
                }
            }
            let parent: Vec<u32> = region.iter().map(|&r| first[r] as u32).collect();
            let labels: Vec<u32> = (0..n as u32).collect();
            let leaf_box: Vec<[u32; 4]> = (0..n)
                .map(|i| {
                    let (x, y) = ((i % cols) as u32, (i / cols) as u32);
                    [x, y, x, y]
                })
                .collect();
            let mut class_of = vec![0u8; n];
            for (r, &leaf) in first.iter().enumerate() {
                if leaf != usize::MAX {
                    class_of[leaf] = if r < roots && r % 2 == 0 { 3 } else { 1 };
                }
            }
            let mut got = vec![0u32; n * n];
            let mut boxes = Vec::new();
            edges_of_class(
                &labels,
                &parent,
                cols,
                &leaf_box,
                &mut boxes,
                &class_of,
                3,
                |r, o| {
                    got[r * n + o] += 1;
                },
            );
            assert_eq!(
                got,
                brute(&labels, &parent, cols, &class_of, 3),
                "{cols}×{rows} small {small}"
            );
            assert!(got.iter().any(|&c| c > 0));
        }
    }
}
