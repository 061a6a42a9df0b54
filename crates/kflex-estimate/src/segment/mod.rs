//! Region-based segmentation (the paper's Fig. 4b): region of interest,
//! split, merge, threshold — giving the 48×48 binary image IBJAE consumes.

mod classify;
mod graph;
mod pyramid;
mod refine;
mod regions;
mod resample;

use kflex_model::{Bounds, Mask, Roi};
use serde::{Deserialize, Serialize};

use crate::error::{EstimateError, Result};
use classify::classify;
use pyramid::{Level, Region2d, pyramid};
use refine::refine;
use regions::{Region, merge, split};
use resample::resample_cells;

/// Segmentation thresholds. Colours on the [0, 1] scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentParams {
    /// Largest brightness or redness range of a block that is not split further.
    pub split_range: f32,
    /// Smallest block side, px.
    pub min_block: u32,
    /// Largest colour distance between adjacent regions that are merged
    /// (before the allowance for noise, [`SegmentParams::merge_noise_z`]).
    pub merge_distance: f32,
    /// Mean brightness (`r + g + b` on `[0, 3]`) of a region of interest for
    /// which `split_range` and `merge_distance` are set. A darker region
    /// scales both down in proportion (to at most a fifth), so that an
    /// illumination gain below 1 splits and merges as at gain 1; a brighter
    /// one keeps them.
    pub reference_brightness: f32,
    /// Merging allows for the sensor noise each frame shows: two regions of
    /// `n_a` and `n_b` pixels may differ by `z σ √(3 (1/n_a + 1/n_b))` more
    /// than `merge_distance`, with σ estimated from the frame (the median
    /// absolute difference of neighbouring pixels) and `z` this.
    pub merge_noise_z: f32,
    /// Largest chromaticity difference between merged regions (before the
    /// allowance for noise, which grows as the regions darken). Steel on grey,
    /// pale or white tissue differs from it by about 0.01–0.02 in
    /// chromaticity and hardly at all in colour distance: without this test
    /// the two merge into one region wherever they are equally bright.
    pub merge_chroma: f32,
    /// The instrument's metal as chromaticity `[x, y]` (redness and green
    /// against blue over brightness, see [`Segmenter`]): where the threshold's
    /// instrument class starts. The default is the K-FLEX steel's base colour
    /// `(0.62, 0.64, 0.68)` as a BT.709 camera encodes it, `(0.787, 0.800,
    /// 0.825)`: slightly blue. In a scene the steel also reflects the tissue
    /// around it, which moves it toward the tissue's colour; the threshold
    /// places its boundary between the two from each frame's statistics.
    pub metal_chroma: [f32; 2],
    /// A region brighter than this many times the region of interest's
    /// median brightness (and than a share of its 90th percentile,
    /// `BRIGHT_OF_BRIGHTEST` in `classify.rs`, so that the dark lumen's
    /// median does not make a dim part bright) is instrument only where its
    /// chromaticity lies within [`SegmentParams::bright_metal_share`] of the
    /// way from the metal's to the tissue's (other regions: within half the
    /// way, the nearer class), and grows in by the rule of
    /// [`SegmentParams::grow_share`] only within 0.35 of the way and where
    /// it has at least 16 pixels (`BRIGHT_GROW_SHARE` and `JOIN_MIN_PX` in
    /// `classify.rs`: a lit flank of the shaft reflecting the tissue; by
    /// that of [`SegmentParams::neighbour_ratio`] as any region). Bright tissue is pulled toward
    /// white by its wet sheen and by its red channel clipping, toward the
    /// steel's near-neutral colour; bright steel is not pulled toward the
    /// tissue's.
    pub bright_ratio: f32,
    /// See [`SegmentParams::bright_ratio`].
    pub bright_metal_share: f32,
    /// A region that borders the instrument joins it where its chromaticity
    /// lies within this share of the way from the metal's to the tissue's
    /// (a bright region: within 0.35, see [`SegmentParams::bright_ratio`];
    /// other regions: half the way). The instrument is one object; a far
    /// gripper or a joint's disc that reflects the tissue around it lies
    /// past half way but borders the rest. At most 0.5 turns this off.
    pub grow_share: f32,
    /// The growth of [`SegmentParams::grow_share`] applies only where the
    /// tissue's chromaticity lies at least this far from the metal's: on
    /// grey, pale or white tissue a share of the way is within the noise.
    /// Also how far from the metal's a region left for the specular step
    /// (a clipped channel) must lie for its colour to count toward the
    /// tissue's; and, in step 5, how far the tissue's colour must lie from
    /// the metal's (and such a region's, half this) for the region's own
    /// colour to decide it: tissue at 0.3 of the way from the metal's to the
    /// tissue's or more (`CLIPPED_TISSUE_SHARE` in `classify.rs`: steel
    /// tinted by the tissue lies at most the tint's share of the way, and
    /// clipping only pulls a colour toward neutral).
    pub grow_separation: f32,
    /// A region grows into the instrument only where it is at most this many
    /// times as bright as the instrument it borders, and at least its
    /// inverse (a far gripper is no brighter than the joint it hangs from;
    /// the pale tissue around it is). The growth of
    /// [`SegmentParams::neighbour_ratio`] takes the same least brightness
    /// (and a brightest of its own, 1.1 times).
    pub grow_brightness: f32,
    /// A region that runs along the instrument (0.3 of its cell edges or
    /// more, see `joins_by_neighbours` in `classify.rs`) joins it where its
    /// chromaticity lies less than this many times as far from the
    /// instrument's beside it as from the tissue's beside it, and it is
    /// about as bright as the instrument there (between
    /// `1 / grow_brightness` and 1.1 times). Steel mirrors what lies
    /// around it: a lit flank of the shaft on white tissue, or a joint
    /// tinted by the tissue, can lie nearer the frame's tissue colour than
    /// the metal's and still nearer the steel beside it than the tissue
    /// beside it. At most 1 (nearer the steel); 0 turns this off.
    pub neighbour_ratio: f32,
    /// Smallest brightness of an instrument region, as a share of the median
    /// brightness of the region of interest (darker is lumen or shadow).
    pub min_relative_value: f32,
    /// A region whose darkest channel is above this is clipped specular light
    /// and takes the class of the regions around it. On a noisy frame a
    /// clipped channel reads below full scale (by `σ/√(2π)` for noise σ):
    /// this and [`SegmentParams::saturated_value`] then move down to stay
    /// 0.02 below that.
    pub clip_value: f32,
    /// A region whose brightest channel is above this has lost part of its
    /// chromaticity to the sensor's clipping (bright tissue under a high
    /// gain turns pale) and takes the class of the regions around it too,
    /// unless its darkest channel does not clip and its chromaticity lies
    /// at least 0.3 of the way from the metal's to the tissue's
    /// (`CLIPPED_TISSUE_SHARE` in `classify.rs`; where those lie more than
    /// [`SegmentParams::grow_separation`] apart, and it more than half that
    /// from the metal's): then it is tissue (steel that clips is white).
    pub saturated_value: f32,
    /// A region brighter than the region of interest's median and than the
    /// mean of its neighbours by this factor, and smaller than
    /// [`SegmentParams::highlight_max`], is a highlight (wet mucosa, the
    /// steel's own sheen) and takes the class of the regions around it;
    /// 0 turns the test off.
    pub highlight_ratio: f32,
    /// Largest highlight, as a share of the region of interest.
    pub highlight_max: f32,
    /// Least darkest channel of a highlight: highlights are near white,
    /// and a small steel part (a far gripper) brighter than the tissue
    /// around it is not.
    pub highlight_min_value: f32,
    /// Tissue enclosed by instrument (out of reach of the tissue on the
    /// region's border) is instrument: the silhouette has no holes.
    pub fill_holes: bool,
    /// Smallest instrument component kept, as a share of the region of interest.
    pub min_component: f32,
    /// Smallest instrument component kept, as a share of all the
    /// instrument found (every component together; the largest component is
    /// always kept): the instrument is one object, or two where tape hides
    /// its middle. Until 2026-11-29 this was a share of the largest
    /// component, `min_component_of_largest`, which let a wet glare through
    /// where tape halved the largest; a configuration that names the old
    /// field is refused, since the same number now means another threshold.
    pub min_component_of_total: f32,
    /// The boundary to the pixel: the pixels of the cells that border the
    /// other class each take the class whose colour they are nearer, the
    /// two colours read this far to either side across the boundary, px
    /// (see the steps on [`Segmenter`]); 0 keeps the cells' boundary.
    pub refine_reach_px: f32,
    /// The boundary's pixels are decided only where the two colours of
    /// [`SegmentParams::refine_reach_px`] differ by at least this (feature
    /// distance on the `[0, 1]` scale, scaled down in a dark region as
    /// [`SegmentParams::reference_brightness`] says; the largest possible
    /// distance is √17, so 5 turns the step off).
    pub refine_contrast: f32,
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
            reference_brightness: 1.3,
            merge_noise_z: 2.0,
            merge_chroma: 0.006,
            metal_chroma: classify::chroma([0.787, 0.800, 0.825]),
            bright_ratio: 1.2,
            bright_metal_share: 0.3,
            grow_share: 0.65,
            grow_separation: 0.08,
            grow_brightness: 1.4,
            neighbour_ratio: 0.7,
            min_relative_value: 0.15,
            clip_value: 0.94,
            saturated_value: 0.97,
            highlight_ratio: 1.2,
            highlight_max: 0.015,
            highlight_min_value: 0.7,
            fill_holes: true,
            min_component: 0.004,
            min_component_of_total: 0.1,
            refine_reach_px: 4.0,
            refine_contrast: 0.2,
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

/// The sensor noise's standard deviation on the [0, 1] scale, estimated
/// from the region's own pixels: the median absolute difference of
/// horizontally adjacent green values in rows spread over it (for pure noise
/// of σ, the difference has σ√2 and its median absolute value 0.954 σ);
/// edges and texture are a minority of the pairs and barely move the median.
fn noise_sigma(region: &Region2d) -> f32 {
    // about 8,000 pairs, from rows spread over the region: the median is
    // then good to a few per cent and costs a few microseconds
    let per_row = region.width.saturating_sub(1).max(1);
    let step = (region.height * per_row / NOISE_PAIRS).max(1);
    let mut hist = [0u32; 256];
    let mut n = 0u32;
    for y in (0..region.height).step_by(step) {
        let row = &region.rgb[region.first + y * region.stride..][..3 * region.width];
        let green = &row[1..];
        for pair in green.chunks_exact(3).zip(green.chunks(3).skip(1)) {
            hist[usize::from(pair.0[0].abs_diff(pair.1[0]))] += 1;
            n += 1;
        }
    }
    let (mut acc, half) = (0u32, n.div_ceil(2));
    for (d, &c) in hist.iter().enumerate() {
        acc += c;
        if acc >= half && c > 0 {
            return d as f32 / (0.954 * 255.0);
        }
    }
    0.0
}

/// Pixel pairs [`noise_sigma`] reads, about.
const NOISE_PAIRS: usize = 8192;

/// The least a dark region of interest scales the split and merge
/// thresholds by (see [`SegmentParams::reference_brightness`]).
const MIN_SCALE: f32 = 0.2;

/// Largest region of interest, px (2²⁴: a 4K frame, 8.3 MP, fits; block sums are `i64`).
const MAX_ROI_PIXELS: u64 = 1 << 24;

/// Segments the instrument in `roi` of an RGB frame (`width × height`, 8 bits,
/// row-major). One-off: in a loop, keep a [`Segmenter`], which allocates nothing
/// once it has seen a region of the size.
///
/// # Errors
/// As [`Segmenter::new`] for out-of-range `params`, then as
/// [`Segmenter::segment`].
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
///
/// 1. **Region of interest**: a rectangle of the frame ([`Roi`]).
/// 2. **Split**: a quadtree of aligned power-of-two blocks. A block is split in
///    four while the range of its brightness or of its redness exceeds
///    [`SegmentParams::split_range`] and its side exceeds [`SegmentParams::min_block`]
///    px (at least 2); in a region of interest darker than
///    [`SegmentParams::reference_brightness`] the range shrinks in proportion.
///    Block statistics (ranges and colour sums, in integers) come
///    from a pyramid built bottom-up in one pass, so the split is linear in the
///    pixels. On x86-64 CPUs with AVX2 the pyramid runs on a vectorised copy of
///    the same code, chosen at run time.
/// 3. **Merge**: adjacent leaves whose mean colours differ by less than
///    [`SegmentParams::merge_distance`] (scaled like the split's range) and
///    whose chromaticities differ by less than [`SegmentParams::merge_chroma`],
///    each widened by what the frame's own noise explains for regions of
///    their sizes ([`SegmentParams::merge_noise_z`]), become one region
///    (union–find over the leaves' adjacency, on the regions' running means).
///    The pairs are merged in two passes: first only where the noise alone
///    explains the difference, so that the frame's even parts form and
///    their means settle, then with the thresholds too (in one pass a
///    region's mean walked along a slow change, a blurred edge or tissue as
///    grey as the steel, before the regions beside it had formed). No leaf is smaller than
///    a 2×2 cell, so merging and thresholding work on the grid of cells, a
///    quarter of the pixels.
/// 4. **Threshold**, from the frame's own statistics: each merged region's
///    mean colour (its channels under 4 σ read back through the sensor's
///    clipping of the noise at 0, which lifts a black channel to `σ/√(2π)`
///    for the frame's measured σ) is taken to chromaticity (hue and saturation without
///    brightness, so a gain leaves it unchanged), and a region is instrument
///    where it is nearer the metal's chromaticity ([`SegmentParams::metal_chroma`])
///    than the frame's tissue colour, which is estimated from the region of
///    interest itself (the median of the regions least like metal, then of the
///    tissue class, re-estimated twice). Regions darker than
///    [`SegmentParams::min_relative_value`] of the region's median brightness
///    are tissue (lumen); clipped specular regions (darkest channel above
///    [`SegmentParams::clip_value`]), regions with a clipped channel
///    ([`SegmentParams::saturated_value`]) and small highlights
///    ([`SegmentParams::highlight_ratio`]) take the class of the regions
///    around them once the growth of step 5 has run (the clipped tissue
///    below voting as tissue; clipped regions that touch vote as one blob,
///    so a glare ringed by a clipped rim hears the tissue around the rim),
///    except a region with a clipped channel but
///    an unclipped darkest one whose colour lies at least 0.3 of the way
///    from the metal's to the tissue's, where those differ by more than
///    [`SegmentParams::grow_separation`] and it lies more than half that
///    from the metal's (clipping pulls a colour toward neutral; steel
///    tinted by the tissue lies at most the tint's share of the way), which
///    is tissue. A frame of one colour has nothing to tell apart and finds
///    no instrument, whatever the colour.
///    Tape is red, so a taped part is lost, as in the paper.
/// 5. **The instrument is one object**, on the graph of the merged regions
///    (which share cell edges, and how many): a region that borders the
///    instrument joins it where it lies a little past half way toward the
///    tissue's colour and is about as bright as the steel it borders
///    ([`SegmentParams::grow_share`]: a far gripper tinted by the tissue it
///    reflects; a bright region within 0.35 of the way and of 16 px or
///    more; round after round, until none joins); a region that runs
///    along the instrument and is about as bright joins it where its colour
///    lies nearer the steel's beside it
///    than the tissue's beside it, by [`SegmentParams::neighbour_ratio`] (a
///    lit flank on white tissue, a joint tinted by the tissue); tissue
///    enclosed by instrument is instrument
///    ([`SegmentParams::fill_holes`]); connected components smaller than
///    [`SegmentParams::min_component`] of the region or
///    [`SegmentParams::min_component_of_total`] of all the instrument found
///    (specular spots and streaks on wet mucosa) are dropped.
/// 6. **The boundary to the pixel** ([`SegmentParams::refine_reach_px`]):
///    steps 2–5 decide 2×2 cells, so their boundary may be a pixel off, and
///    where the optics blur the edge the cells of the blurred rim go to
///    whichever class their mean is nearer. Each pixel of the cells that
///    border the other class takes the class whose colour it is nearer: the
///    colours of the 4×4 pixels a few pixels to either side of its cell
///    across the boundary (along the gradient of the cells' mask), its own
///    colour itself, or the mean of its 3×3 pixels where the frame's
///    measured noise is above 0.03. Half way between two colours is where a
///    straight step edge, blurred by any symmetric kernel, crosses; both
///    colours are read beside the pixel, so tissue that changes along the
///    instrument is no trouble. Where the two points are not of the two
///    classes (a thin part, a corner, a spike of blurred rim), the colours
///    are those of the nearest cell of each class whose neighbours are all
///    of it, a few cells away at most; where there is none, or the colours
///    differ by less than [`SegmentParams::refine_contrast`], the cells'
///    decision stands. A
///    blurred rim wider than a cell (a far or defocused edge) can leave the
///    cells' boundary more than a cell out: an instrument cell whose pixels
///    all went to tissue becomes tissue, and the boundary around it is
///    refined again (up to three passes; only toward tissue and only whole
///    cells: growing cells too, or moving a cell on a majority of its
///    pixels, lost pale, blue-green and yellow tissue cases).
/// 7. The result is resampled to `out × out` (area vote: a cell is set where at
///    least half its pixels are). Fewer than [`SegmentParams::min_instrument`]
///    of the region's pixels set (before step 6): [`EstimateError::NoInstrument`].
#[derive(Debug)]
pub struct Segmenter {
    params: SegmentParams,
    scratch: Scratch,
    /// The last frame's result, its masks refilled by the next.
    output: Segmentation,
}

/// Passes of the boundary's refinement at most (step 6): each after the
/// first moves the cells' boundary by a cell where the last one changed
/// all of a cell's pixels to tissue (`refine::flip_cells`).
const REFINE_PASSES: usize = 3;

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
    wide: Vec<i64>,
    stack: Vec<(usize, usize, usize)>,
    labels: Vec<u32>,
    /// The split's leaves, then the merged regions (their roots in
    /// `parent`); the threshold reads the roots' dark channels back through
    /// the sensor's clipping (see [`Region`]).
    regions: Vec<Region>,
    parent: Vec<u32>,
    instrument: Vec<u8>,
    /// Per region: dark, coloured, clipped, a candidate highlight,
    /// clipped tissue or clipped and gathered into a blob (see `classify`).
    region_class: Vec<u8>,
    /// The merged regions (roots of `parent`).
    roots: Vec<u32>,
    /// Per leaf: its cells' box `[x0, y0, x1, y1]`, inclusive.
    leaf_box: Vec<[u32; 4]>,
    /// Leaf pairs across cell edges, `[a, b, edges]`, recorded by the merge
    /// (one record a pair).
    leaf_edges: Vec<[u32; 3]>,
    /// Per cell column: the last leaf pair recorded across its right edge
    /// and where (`leaf_edges` index), to count a vertical boundary's run.
    last_right: Vec<(u32, u32, u32)>,
    /// The merged regions' graph (`graph::build`): neighbours and shared
    /// cell edges, region `r`'s from `adjacency_start[r]` to `adjacency_start[r + 1]`.
    adjacency: Vec<[u32; 2]>,
    adjacency_start: Vec<u32>,
    /// The regions a round of the instrument's growth asks (steps 4b and
    /// 4c), and those that joined in it (`classify::grow`); step 5's walk
    /// over a blob of clipped regions, and the blob.
    grow_frontier: Vec<u32>,
    grow_joined: Vec<u32>,
    /// Per region: whether it has a cell on the region of interest's edge.
    on_border: Vec<bool>,
    /// Per instrument component: its regions' range in `component`, and its pixels.
    component_spans: Vec<(usize, usize, f32)>,
    cells: Vec<u8>,
    /// The pixels whose class the boundary's refinement changed from their
    /// cell's, sorted by index (`refine::changed` reads one).
    changes: Vec<u32>,
    /// Per cell: whether a neighbour is of the other class (`refine`'s
    /// first pass), and the comparisons of a row's cells that give it.
    near: Vec<u8>,
    near_diff: Vec<u8>,
    /// Per cell, for the boundary step's later passes
    /// (`refine::flip_cells`): whether `refine` decides it again (and those
    /// cells listed), and how many of its pixels the last pass changed to
    /// tissue.
    redo: Vec<u8>,
    redo_list: Vec<u32>,
    to_tissue: Vec<u8>,
    /// A later pass's new changes, while they merge with the kept ones.
    tail: Vec<u32>,
    seen: Vec<bool>,
    flood: Vec<usize>,
    component: Vec<usize>,
    row: Vec<u8>,
    column: Vec<u32>,
    /// Per output column: the changed pixels' difference (`resample_cells`).
    changed: Vec<i32>,
    spans: Vec<(usize, usize)>,
}

impl Segmenter {
    /// A segmenter with these thresholds; out-of-range thresholds are an error.
    ///
    /// # Errors
    /// [`EstimateError::OutOfRange`] naming the first parameter out of its
    /// range, in this order (NaN is out of every range): `split_range` outside
    /// `[0, 3]`, `merge_distance` outside `[0, 2]`, `reference_brightness`
    /// outside `[0.01, 3]`, `merge_noise_z` outside `[0, 10]`, `merge_chroma`
    /// outside `[0, 2]`, either `metal_chroma` component outside `[-1, 1]`,
    /// `bright_ratio` outside `[0, 100]`, `bright_metal_share` or
    /// `grow_share` outside `[0, 1]`, `grow_separation` outside `[0, 2]`,
    /// `grow_brightness` outside `[0, 100]`, `neighbour_ratio` outside
    /// `[0, 1]`, `min_relative_value`,
    /// `clip_value` or `saturated_value` outside `[0, 1]`,
    /// `highlight_ratio` outside `[0, 100]`, `highlight_max`,
    /// `highlight_min_value`, `min_component` or `min_component_of_total`
    /// outside `[0, 1]`, `refine_reach_px` outside `[0, 64]`,
    /// `refine_contrast` outside `[0, 5]`, `min_instrument` outside
    /// `[0, 1]`, `out` outside `[1, 4096]` px. `min_block` is not checked (blocks stop at 2 px
    /// anyway).
    pub fn new(params: SegmentParams) -> Result<Self> {
        let check = |name, value: f32, lo, hi| Bounds::closed(lo, hi).check(name, f64::from(value));
        check("split_range", params.split_range, 0.0, 3.0)?;
        check("merge_distance", params.merge_distance, 0.0, 2.0)?;
        check(
            "reference_brightness",
            params.reference_brightness,
            0.01,
            3.0,
        )?;
        check("merge_noise_z", params.merge_noise_z, 0.0, 10.0)?;
        check("merge_chroma", params.merge_chroma, 0.0, 2.0)?;
        check("metal_chroma[0]", params.metal_chroma[0], -1.0, 1.0)?;
        check("metal_chroma[1]", params.metal_chroma[1], -1.0, 1.0)?;
        check("bright_ratio", params.bright_ratio, 0.0, 100.0)?;
        check("bright_metal_share", params.bright_metal_share, 0.0, 1.0)?;
        check("grow_share", params.grow_share, 0.0, 1.0)?;
        check("grow_separation", params.grow_separation, 0.0, 2.0)?;
        check("grow_brightness", params.grow_brightness, 0.0, 100.0)?;
        check("neighbour_ratio", params.neighbour_ratio, 0.0, 1.0)?;
        check("min_relative_value", params.min_relative_value, 0.0, 1.0)?;
        check("clip_value", params.clip_value, 0.0, 1.0)?;
        check("saturated_value", params.saturated_value, 0.0, 1.0)?;
        check("highlight_ratio", params.highlight_ratio, 0.0, 100.0)?;
        check("highlight_max", params.highlight_max, 0.0, 1.0)?;
        check("highlight_min_value", params.highlight_min_value, 0.0, 1.0)?;
        check("min_component", params.min_component, 0.0, 1.0)?;
        check(
            "min_component_of_total",
            params.min_component_of_total,
            0.0,
            1.0,
        )?;
        check("refine_reach_px", params.refine_reach_px, 0.0, 64.0)?;
        check("refine_contrast", params.refine_contrast, 0.0, 5.0)?;
        check("min_instrument", params.min_instrument, 0.0, 1.0)?;
        Bounds::closed(1.0, 4096.0).check("out", f64::from(params.out))?;
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
    #[must_use]
    pub fn params(&self) -> &SegmentParams {
        &self.params
    }

    /// Segments the instrument in `roi` of an RGB frame (`width × height`,
    /// 8 bits, row-major). The result lives until the next call.
    ///
    /// # Errors
    /// * [`EstimateError::ImageSize`] when `width` or `height` is 0 or
    ///   `rgb.len()` is not `width × height × 3`;
    /// * [`EstimateError::Model`] wrapping [`ModelError::OutOfRange`] naming
    ///   the axis of `roi` that is empty or reaches past the frame's edge
    ///   (`roi.width`, `roi.height`, `roi.x0 + roi.width`,
    ///   `roi.y0 + roi.height`, as [`Roi::check_within`]);
    /// * [`EstimateError::OutOfRange`] naming `roi.width` or `roi.height`
    ///   for a side over [`kflex_model::MAX_IMAGE_SIDE`] (16,384 px), or
    ///   `roi pixels` for a region of more than 2²⁴ pixels, before any work;
    /// * [`EstimateError::NoInstrument`] when fewer than
    ///   [`SegmentParams::min_instrument`] of the region's pixels (and at least
    ///   one) are instrument.
    ///
    /// # Examples
    ///
    /// ```
    /// use kflex_estimate::{SegmentParams, Segmenter};
    /// use kflex_model::{Camera, FrameParams, Instrument, Roi, SceneRenderer};
    /// let camera = Camera::default();
    /// let shape = Instrument::kflex().shape(30.0, 10.0)?;
    /// let frame = SceneRenderer::new().render(&camera, &shape, &FrameParams::default())?;
    /// let roi = Roi::paper(&camera)?;
    /// // keep the segmenter: later frames of this region size allocate nothing
    /// let mut segmenter = Segmenter::new(SegmentParams::default())?;
    /// let seg = segmenter.segment(&frame.rgb, frame.width, frame.height, roi)?;
    /// assert_eq!((seg.small.width(), seg.small.height()), (48, 48));
    /// assert!(seg.small.count() > 0);
    /// // at the region's resolution it matches the renderer's ground truth
    /// let truth = frame.instrument.crop(roi)?;
    /// assert!(seg.full.iou(&truth)? > 0.9);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// [`ModelError::OutOfRange`]: kflex_model::ModelError::OutOfRange
    pub fn segment(
        &mut self,
        rgb: &[u8],
        width: u32,
        height: u32,
        roi: Roi,
    ) -> Result<&Segmentation> {
        // in u128: sides up to u32::MAX cannot wrap the product
        let expected =
            (u128::from(width) * u128::from(height) * 3).min(usize::MAX as u128) as usize;
        if width == 0 || height == 0 || rgb.len() != expected {
            return Err(EstimateError::ImageSize {
                width,
                height,
                expected,
                got: rgb.len(),
            });
        }
        roi.check_within(width, height)?;
        let (rw, rh) = (roi.width as usize, roi.height as usize);
        // the masks' sides first (the region's masks are images), then the pixels
        let side = Bounds::closed(1.0, f64::from(kflex_model::MAX_IMAGE_SIDE));
        side.check("roi.width", f64::from(roi.width))?;
        side.check("roi.height", f64::from(roi.height))?;
        Bounds::closed(1.0, MAX_ROI_PIXELS as f64).check("roi pixels", roi.area() as f64)?;
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
        // a darker region of interest splits and merges at proportionally
        // smaller differences (an illumination gain leaves the result alone);
        // merging also allows for the sensor noise the frame itself shows
        let mean_l = s.levels[depth - 1].sum[0][0] as f64 / (255.0 * (rw * rh) as f64);
        let scale = (mean_l as f32 / p.reference_brightness).clamp(MIN_SCALE, 1.0);
        let scaled = SegmentParams {
            split_range: p.split_range * scale,
            merge_distance: p.merge_distance * scale,
            ..p
        };
        split(s, depth, rw, rh, scaled);
        let sigma = noise_sigma(&region);
        let noise = p.merge_noise_z * sigma;
        merge(s, cols, rows, &scaled, noise);
        classify(s, &p, cols, rows, sigma);
        if p.fill_holes {
            graph::fill_holes(s);
        }
        let min_component = (p.min_component * (rw * rh) as f32).ceil();
        let count = graph::keep_components(s, min_component, p.min_component_of_total);
        let Scratch {
            cells,
            labels,
            parent,
            instrument,
            ..
        } = &mut *s;
        cells.clear();
        cells.extend(
            labels
                .iter()
                .map(|&l| instrument[parent[l as usize] as usize]),
        );
        let min = (p.min_instrument * (rw * rh) as f32).ceil().max(1.0) as usize;
        if count < min {
            return Err(EstimateError::NoInstrument { pixels: count, min });
        }
        let output = &mut self.output;
        output.full.reshape(roi.width, roi.height)?;
        output.small.reshape(p.out, p.out)?;
        // in 8-bit units, and like the split's and merge's thresholds
        // smaller in a darker region (a gain leaves the result alone)
        let contrast = p.refine_contrast * 255.0 * scale;
        let reach = p.refine_reach_px;
        // the first pass decides every cell along the boundary
        s.changes.clear();
        s.redo_list.clear();
        refine(s, &region, cols, rows, reach, contrast, sigma);
        // a rim wider than a cell (a blurred edge) moves the boundary by
        // whole cells: the cells whose pixels all changed to tissue become
        // tissue, and the boundary is refined again around them
        for _ in 1..REFINE_PASSES {
            if !refine::flip_cells(s, cols, rw, rh) {
                break;
            }
            refine(s, &region, cols, rows, reach, contrast, sigma);
        }
        debug_assert!(
            s.changes
                .windows(2)
                .all(|w| refine::changed(w[0]).0 < refine::changed(w[1]).0),
            "the boundary's changes are sorted, one a pixel"
        );
        s.row.clear();
        s.row.resize(rw, 0);
        let mut next = 0;
        for (cy, crow) in s.cells.chunks_exact(cols).enumerate() {
            for y in (2 * cy..2 * cy + 2).filter(|&y| y < rh) {
                for (pair, &v) in s.row.chunks_exact_mut(2).zip(crow) {
                    pair[0] = v;
                    pair[1] = v;
                }
                if rw % 2 == 1 {
                    s.row[rw - 1] = crow[cols - 1];
                }
                // the pixels the boundary's refinement changed in this row
                while let Some((i, v)) = s.changes.get(next).map(|&c| refine::changed(c))
                    && i < (y + 1) * rw
                {
                    s.row[i - y * rw] = v;
                    next += 1;
                }
                output.full.set_row(y as u32, &s.row)?;
            }
        }
        resample_cells(s, cols, rw, rh, &mut output.small)?;
        Ok(output)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// An 8-bit frame of `colour(x, y)` (0–255) with Gaussian noise of
    /// `sigma` (on [0, 1]) added to every channel.
    fn paint(
        width: usize,
        height: usize,
        sigma: f64,
        seed: u64,
        colour: impl Fn(usize, usize) -> [f64; 3],
    ) -> Vec<u8> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, sigma * 255.0).unwrap();
        let mut rgb = Vec::with_capacity(3 * width * height);
        for y in 0..height {
            for x in 0..width {
                for c in colour(x, y) {
                    let v: f64 = c + normal.sample(&mut rng);
                    rgb.push(v.round().clamp(0.0, 255.0) as u8);
                }
            }
        }
        rgb
    }

    /// A smooth gradient with Gaussian noise of `sigma` (on [0, 1]) added.
    fn noisy(width: usize, height: usize, sigma: f64, seed: u64) -> Vec<u8> {
        paint(width, height, sigma, seed, |x, y| {
            [60.0 + 120.0 * (x + y) as f64 / (width + height) as f64; 3]
        })
    }

    #[test]
    fn the_noise_estimate_reads_the_noise_in_the_frame() {
        for (sigma, seed) in [(0.01, 1), (0.03, 2), (0.1, 3)] {
            for (w, h) in [(220, 220), (640, 480), (31, 7)] {
                let rgb = noisy(w, h, sigma, seed);
                let region = Region2d {
                    rgb: &rgb,
                    first: 0,
                    stride: 3 * w,
                    width: w,
                    height: h,
                };
                let est = f64::from(noise_sigma(&region));
                // 8-bit rounding adds 1/√12 of a level; the median of the
                // absolute differences comes in whole levels
                let expected = (sigma * sigma + (1.0 / 255.0f64).powi(2) / 12.0).sqrt();
                let tol = 0.15 * expected + 0.5 / 255.0;
                assert!(
                    (est - expected).abs() < tol,
                    "σ {sigma} at {w}×{h}: estimated {est:.4}, expected {expected:.4}"
                );
            }
        }
    }

    #[test]
    fn a_blurred_edge_between_cells_is_placed_to_the_pixel() {
        // tissue left of the pixel corner x = 81, steel right of it, the
        // edge blurred by a Gaussian of 2 px: the cells (2×2 px) cannot draw
        // an edge at an odd column, the refinement puts it there exactly
        let (w, h) = (128usize, 64usize);
        let edge = 81.0;
        let phi = |z: f64| 0.5 * (1.0 + libm_erf(z / std::f64::consts::SQRT_2));
        let frame = |gain: f64| {
            paint(w, h, 0.0, 1, |x, _| {
                let s = phi((x as f64 + 0.5 - edge) / 2.0);
                let (tissue, metal) = ([118.0, 88.0, 84.0], [100.0, 101.0, 106.0]);
                std::array::from_fn(|k| gain * (tissue[k] + s * (metal[k] - tissue[k])))
            })
        };
        let roi = Roi {
            x0: 0,
            y0: 0,
            width: w as u32,
            height: h as u32,
        };
        let truth: Vec<u8> = (0..w).map(|x| u8::from(x >= 81)).collect();
        let rows = |params: &SegmentParams, gain: f64| -> Vec<Vec<u8>> {
            let seg = segment(&frame(gain), w as u32, h as u32, roi, params).unwrap();
            seg.full
                .data()
                .chunks_exact(w)
                .map(<[u8]>::to_vec)
                .collect()
        };
        let refined = rows(&SegmentParams::default(), 1.0);
        assert!(refined.iter().all(|r| *r == truth), "{:?}", refined[h / 2]);
        // the same edge under a gain of 0.4: the contrast it needs scales
        // with the region's brightness, as the split's and merge's do
        let dark = rows(&SegmentParams::default(), 0.4);
        assert!(dark.iter().all(|r| *r == truth), "{:?}", dark[h / 2]);
        // the cells alone: a pixel off on every row; a contrast above any
        // two colours' (√17): the same
        for params in [
            SegmentParams {
                refine_reach_px: 0.0,
                ..SegmentParams::default()
            },
            SegmentParams {
                refine_contrast: 5.0,
                ..SegmentParams::default()
            },
        ] {
            let cells = rows(&params, 1.0);
            assert!(cells.iter().all(|r| *r != truth));
            assert!(
                cells
                    .iter()
                    .all(|r| { r.iter().zip(&truth).filter(|(a, b)| a != b).count() == 1 })
            );
        }
    }

    /// The error function (Abramowitz and Stegun 7.1.26, |error| < 1.5e-7).
    fn libm_erf(x: f64) -> f64 {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let y = 1.0
            - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736)
                * t
                + 0.254_829_592)
                * t
                * (-x * x).exp();
        y.copysign(x)
    }

    /// Segments the whole `w × h` frame with the default thresholds and
    /// asserts, on every row, instrument left of column `instrument_to` and
    /// tissue from column `tissue_from` (the boundary's few pixels between
    /// them free).
    fn assert_instrument_left(
        rgb: &[u8],
        w: usize,
        h: usize,
        instrument_to: usize,
        tissue_from: usize,
    ) {
        let params = SegmentParams::default();
        assert_instrument_left_with(rgb, w, h, instrument_to, tissue_from, &params);
    }

    /// [`assert_instrument_left`] with thresholds `params`.
    fn assert_instrument_left_with(
        rgb: &[u8],
        w: usize,
        h: usize,
        instrument_to: usize,
        tissue_from: usize,
        params: &SegmentParams,
    ) {
        let (width, height) = (w as u32, h as u32);
        let roi = Roi::whole(width, height);
        let seg = segment(rgb, width, height, roi, params).unwrap();
        for (y, row) in seg.full.data().chunks_exact(w).enumerate() {
            let near = &row[instrument_to.saturating_sub(4)..(tissue_from + 4).min(w)];
            assert!(
                row[..instrument_to].iter().all(|&v| v == 1),
                "row {y}: instrument lost, {near:?}"
            );
            assert!(
                row[tissue_from..].iter().all(|&v| v == 0),
                "row {y}: tissue taken, {near:?}"
            );
        }
    }

    #[test]
    fn tissue_with_one_clipped_channel_stays_tissue_beside_the_steel() {
        // steel, then two blocks of bright pink tissue whose red channel
        // clips (regions left to their neighbours' class), then pink tissue
        // that does not clip: the first pink block borders no region but
        // the steel that is not clipped itself, yet its colour, though one
        // channel clipped, lies far on the tissue's side: tissue
        let (w, h) = (160usize, 96usize);
        let rgb = paint(w, h, 0.01, 5, |x, _| match x {
            0..48 => [150.0, 152.0, 160.0],
            48..96 => [255.0, 140.0, 125.0],
            96..128 => [255.0, 185.0, 165.0],
            _ => [200.0, 110.0, 100.0],
        });
        assert_instrument_left(&rgb, w, h, 44, 52);
    }

    /// A 208×96 frame, noise σ 0.01: steel (columns 0–47), a sheen
    /// `sheen` whose red channel clips (48–79), pale tissue whose red
    /// channel clips too (80–111) and pink tissue (112–207). The steel is
    /// the only region beside the sheen that is not clipped, so the sheen
    /// takes the steel's class unless its own colour decides it.
    fn steel_clipped_sheen_pink_tissue(sheen: [f64; 3]) -> (Vec<u8>, usize, usize) {
        let (w, h) = (208usize, 96usize);
        let rgb = paint(w, h, 0.01, 12, |x, _| match x {
            0..48 => [150.0, 152.0, 160.0],
            48..80 => sheen,
            80..112 => [255.0, 240.0, 236.0],
            _ => [200.0, 130.0, 120.0],
        });
        (rgb, w, h)
    }

    #[test]
    fn a_clipped_sheen_past_the_tints_share_is_tissue() {
        // the sheen's colour lies 0.38 of the way from the metal's to the
        // tissue's but only 0.069 from the metal's (within
        // `grow_separation`): clipping pulls a colour toward neutral, and
        // steel tinted by the tissue lies at most the tint's share of the
        // way, so it is tissue (under the rule before, past half way and
        // more than `grow_separation` from the metal's, it took the steel's
        // class: gain 1.6, larynx 0 deg at 35 mm)
        let (rgb, w, h) = steel_clipped_sheen_pink_tissue([255.0, 220.0, 212.0]);
        assert_instrument_left(&rgb, w, h, 44, 52);
    }

    #[test]
    fn a_part_tinted_more_at_each_step_grows_in_until_none_joins() {
        // steel, three strips each further from the metal's colour toward
        // the pink tissue's (0.55, 0.64 and 0.76 of the way: tissue by the
        // nearer colour, within a `grow_share` of 0.8), the middle one 15 %
        // darker (so that the split tells the last two apart), then the
        // tissue: step 4b takes one strip a round, so the third joins in
        // the third round (two rounds, as before, left it tissue). Step 4c
        // is off, so that step 4b alone is tested.
        let (w, h) = (208usize, 96usize);
        let rgb = paint(w, h, 0.01, 15, |x, _| match x {
            0..48 => [150.0, 152.0, 160.0],
            48..64 => [181.0, 142.0, 140.0],
            64..80 => [158.0, 119.0, 116.0],
            80..96 => [192.0, 138.0, 132.0],
            _ => [200.0, 130.0, 120.0],
        });
        let params = SegmentParams {
            grow_share: 0.8,
            neighbour_ratio: 0.0,
            ..SegmentParams::default()
        };
        assert_instrument_left_with(&rgb, w, h, 92, 100, &params);
    }

    /// A 208×96 frame, noise σ 0.01 (seed `seed`): steel (columns 0–55)
    /// with a sheen `sheen` at its edge (columns 40–55, rows 32–63), then
    /// tissue `tissue`. Where the sheen takes the class of the regions
    /// around it, mostly steel, the instrument ends at column 56 on every row.
    fn sheen_at_the_steels_edge(seed: u64, sheen: [f64; 3], tissue: [f64; 3]) -> Vec<u8> {
        paint(208, 96, 0.01, seed, |x, y| match (x, y) {
            (40..56, 32..64) => sheen,
            (0..56, _) => [150.0, 152.0, 160.0],
            _ => tissue,
        })
    }

    #[test]
    fn a_bright_flank_reflecting_the_tissue_grows_in() {
        // bright steel, a flank as bright as it 0.33 of the way toward the
        // dim pink tissue's colour (a lit flank reflecting the tissue at a
        // grazing angle), then the tissue: the bright rule (within 0.3 of
        // the way) makes the flank tissue, and step 4b, which kept bright
        // regions out, now takes it within `BRIGHT_GROW_SHARE`. Step 4c,
        // which would take it too, is off, so that step 4b alone is tested.
        let (w, h) = (208usize, 96usize);
        let rgb = paint(w, h, 0.01, 16, |x, _| match x {
            0..48 => [200.0, 202.0, 212.0],
            48..64 => [232.0, 191.0, 191.0],
            _ => [150.0, 85.0, 75.0],
        });
        let params = SegmentParams {
            neighbour_ratio: 0.0,
            ..SegmentParams::default()
        };
        assert_instrument_left_with(&rgb, w, h, 60, 68, &params);
    }

    #[test]
    fn a_clipped_sheen_near_the_metals_colour_stays_steel() {
        // pale warm tissue 0.086 from the metal's colour (just past
        // `grow_separation`, so step 5's colour rule is on) and a sheen at
        // the steel's edge, its red channel clipped, 0.38 of the way toward
        // the tissue's colour but only 0.033 from the metal's: a share of so
        // short a way is within the steel's own colour, and it takes the
        // class of the regions around it, mostly steel (without the floor
        // of half `grow_separation` it would be tissue)
        let rgb = sheen_at_the_steels_edge(14, [255.0, 241.0, 238.0], [200.0, 166.0, 158.0]);
        assert_instrument_left(&rgb, 208, 96, 52, 60);
    }

    #[test]
    fn a_white_glare_beside_the_steel_among_clipped_tissue_is_tissue() {
        // a glare clipped white in every channel (rows 24–71 of columns
        // 48–79) borders the steel on its left and, on its other three
        // sides, pink tissue whose red channel clips (columns 48–111): that
        // tissue's colour makes it tissue, and it votes so on the glare,
        // which borders it along 112 px and the steel along 48 (when only
        // regions that are not clipped voted, the steel alone did)
        let (w, h) = (208usize, 96usize);
        let rgb = paint(w, h, 0.01, 13, |x, y| match (x, y) {
            (0..48, _) => [150.0, 152.0, 160.0],
            (48..80, 24..72) => [255.0, 255.0, 255.0],
            (48..112, _) => [255.0, 200.0, 185.0],
            _ => [200.0, 130.0, 120.0],
        });
        assert_instrument_left(&rgb, w, h, 44, 52);
    }

    #[test]
    fn a_white_glare_ringed_by_a_clipped_rim_is_tissue() {
        // a glare clipped white in every channel (rows 24–71 of columns
        // 48–79) borders the steel on its left and, on its other sides, a
        // rim clipped in red and green (its blue, 0.93, under `clip_value`),
        // so near neutral (0.037 from the metal's colour, under half of
        // `grow_separation`) that its colour decides nothing (rows 8–87 of
        // columns 48–127), inside pink tissue: the glare and the rim vote
        // as one blob, bordered by the tissue along 240 px and the steel
        // along 80 (voting alone, the glare heard only the steel: gain 1.6,
        // colon −60° at 8 mm, a fold's glare at the gripper's tip)
        let (w, h) = (208usize, 96usize);
        let rgb = paint(w, h, 0.01, 17, |x, y| match (x, y) {
            (0..48, _) => [150.0, 152.0, 160.0],
            (48..80, 24..72) => [255.0, 255.0, 255.0],
            (48..128, 8..88) => [255.0, 252.0, 236.0],
            _ => [200.0, 130.0, 120.0],
        });
        assert_instrument_left(&rgb, w, h, 44, 52);
    }

    #[test]
    fn a_clipped_sheen_within_the_tints_share_stays_steel() {
        // a sheen at the steel's edge beside pink tissue, its red channel
        // clipped, 0.24 of the way from the metal's colour to the tissue's
        // (what steel tinted 25 % by this tissue reads at most): it takes
        // the class of the regions around it, mostly steel
        let rgb = sheen_at_the_steels_edge(6, [255.0, 235.0, 230.0], [200.0, 130.0, 120.0]);
        assert_instrument_left(&rgb, 208, 96, 52, 60);
    }

    #[test]
    fn clipped_steel_beside_the_steel_stays_steel() {
        // a sheen at the steel's edge, its red channel clipped and tinted
        // by the pale tissue beside it (0.73 of the way to its colour): the
        // tissue's colour lies within `grow_separation` of the metal's (0.054),
        // where a share of the way says nothing, so the sheen takes the
        // class of the regions around it, mostly steel
        let (w, h) = (160usize, 96usize);
        let rgb = paint(w, h, 0.01, 6, |x, y| match (x, y) {
            (40..56, 32..64) => [255.0, 240.0, 232.0],
            (0..56, _) => [150.0, 152.0, 160.0],
            _ => [200.0, 180.0, 175.0],
        });
        assert_instrument_left(&rgb, w, h, 52, 60);
    }

    #[test]
    fn a_dim_tinted_part_beside_the_lumen_is_not_held_to_the_bright_rule() {
        // dark lumen over most of the region (its median is the lumen's),
        // steel, a dim part of the steel tinted about 0.4 of the way toward
        // the tissue colour the frame estimates (the lumen's, reddish), pink
        // tissue: the dim part is brighter than 1.2 times the median, yet
        // dim against the steel, so it is judged by the nearer colour (the
        // bright rule, within 0.3 of the way, would make it tissue)
        let (w, h) = (160usize, 96usize);
        let rgb = paint(w, h, 0.01, 7, |x, _| match x {
            0..32 => [150.0, 152.0, 160.0],
            32..48 => [76.5, 60.8, 61.2],
            48..64 => [200.0, 110.0, 100.0],
            _ => [40.0, 25.0, 22.0],
        });
        assert_instrument_left(&rgb, w, h, 46, 50);
    }

    /// A 160×96 frame of steel (columns 0–31), a strip of colour `strip`
    /// (32–47) and warm white tissue, with noise σ 0.01: the frame and its size.
    fn steel_strip_white_tissue(strip: [f64; 3]) -> (Vec<u8>, usize, usize) {
        let (w, h) = (160usize, 96usize);
        let rgb = paint(w, h, 0.01, 11, |x, _| match x {
            0..32 => [141.0, 143.0, 147.0],
            32..48 => strip,
            _ => [120.0, 114.0, 113.0],
        });
        (rgb, w, h)
    }

    #[test]
    fn a_noisy_dark_lumen_beside_the_steel_stays_tissue() {
        // steel on the left, a near-black reddish lumen over most of the
        // region, pink tissue around it (on the region's border), under
        // noise σ 0.1: the sensor clips the lumen's noise at 0, so it reads
        // about (0.065, 0.055, 0.055) for (0.043, 0.027, 0.027): 0.42 of the
        // way from the steel's colour to the tissue's, where its own is 0.8
        // of the way, and (the region's median being the lumen's) not dark.
        // The frame's noise measures 0.074 (the clipping shrinks the
        // differences it reads), so the lumen reads back short, to about
        // (0.055, 0.042, 0.042), 0.65 of the way: tissue. Without the
        // read-back (`UNCLIP_BELOW` 0) all 8,064 lumen pixels asserted on
        // were steel.
        let (w, h) = (160usize, 96usize);
        let rgb = paint(w, h, 0.1, 13, |x, y| match (x, y) {
            (0..32, _) => [150.0, 152.0, 160.0],
            (32..152, 8..88) => [11.0, 7.0, 7.0],
            _ => [180.0, 120.0, 115.0],
        });
        let (width, height) = (w as u32, h as u32);
        let seg = segment(
            &rgb,
            width,
            height,
            Roi::whole(width, height),
            &SegmentParams::default(),
        )
        .unwrap();
        let found = |xs: std::ops::Range<usize>, ys: std::ops::Range<usize>| -> usize {
            let rows = seg.full.data().chunks_exact(w);
            rows.skip(ys.start)
                .take(ys.len())
                .map(|row| row[xs.clone()].iter().filter(|&&v| v == 1).count())
                .sum()
        };
        // the lumen's pixels clear of its edges: tissue, but for a few
        let taken = found(36..148, 12..84);
        assert!(
            taken * 100 < 112 * 72,
            "{taken} lumen pixels taken for steel"
        );
        // the steel's: found
        let steel = found(0..28, 0..h);
        assert!(steel * 100 > 99 * 28 * h, "{steel} steel pixels found");
    }

    #[test]
    fn a_lit_flank_on_white_tissue_joins_the_steel_beside_it() {
        // steel, its lit flank (6 % brighter, a third of the way toward the
        // warm white tissue's colour the frame estimates), warm white
        // tissue: the tissue's colour lies so near the metal's that the
        // growth by shares is off, and the flank, bright, is held to the
        // bright rule (within 0.3 of the way) and would be tissue; it lies
        // twice as near the steel beside it as the tissue beside it
        let (rgb, w, h) = steel_strip_white_tissue([153.0, 151.5, 154.5]);
        assert_instrument_left(&rgb, w, h, 46, 50);
        // without the step, the flank is tissue
        let without = SegmentParams {
            neighbour_ratio: 0.0,
            ..SegmentParams::default()
        };
        assert_instrument_left_with(&rgb, w, h, 30, 34, &without);
    }

    #[test]
    fn a_glint_on_white_tissue_beside_the_steel_stays_tissue() {
        // as above, but the strip beside the steel is 30 % brighter than
        // it: wet tissue's sheen, near white, so its colour lies nearer the
        // steel's than the tissue's; too bright for steel beside steel (the
        // bound of 1.1 times keeps it tissue: step 4 alone would too, so
        // this guards the bound, not the step). The strip is a tenth of
        // the frame, far larger than a highlight (`highlight_max`)
        let (rgb, w, h) = steel_strip_white_tissue([185.0, 184.0, 187.0]);
        assert_instrument_left(&rgb, w, h, 30, 34);
    }

    #[test]
    fn a_dark_frame_splits_and_merges_as_the_bright_one() {
        // the same tiles at full light and at 0.4: a quarter metal-grey, the
        // rest tissue-red, with a little noise; at 0.4 the colours differ by
        // less than the split's and the merge's thresholds, which the
        // frame's darkness scales down: both give the same mask
        let (w, h) = (128usize, 128usize);
        let frame = |gain: f64| -> Vec<u8> {
            paint(w, h, 0.01 * gain, 9, |x, y| {
                let metal = (x / 32) % 2 == 0 && (y / 32) % 2 == 0;
                let c: [f64; 3] = if metal {
                    [100.0, 101.0, 106.0]
                } else {
                    [118.0, 88.0, 84.0]
                };
                c.map(|v| v * gain)
            })
        };
        let roi = Roi {
            x0: 0,
            y0: 0,
            width: w as u32,
            height: h as u32,
        };
        let params = SegmentParams::default();
        let bright = segment(&frame(1.0), w as u32, h as u32, roi, &params).unwrap();
        let dark = segment(&frame(0.4), w as u32, h as u32, roi, &params).unwrap();
        assert!(bright.full.count() > 0);
        let iou = dark.full.iou(&bright.full).unwrap();
        assert!(
            iou > 0.98,
            "IoU {iou}, {} and {} px",
            bright.full.count(),
            dark.full.count()
        );
    }
}
