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

use super::graph;
use super::regions::Region;
use super::{Scratch, SegmentParams};

/// Rounds of growing the instrument into the regions that run along it by
/// the colours beside them (step 4c, [`grow`]). Step 4b grows until no
/// region joins.
const GROW_ROUNDS: usize = 2;

/// How far from the line through the metal's and the tissue's colours a
/// region that grows into the instrument may lie, as a share of their
/// distance (step 4b).
const GROW_WIDTH: f32 = 0.3;

/// How far below full scale, in noise σ, a clipped channel's mean reads
/// (`1/√(2π)`, see [`classify`]), and how far above 0 a black one does.
const CLIP_NOISE: f32 = 0.398_942_3;

/// How far below a clipped channel's expected mean (with the frame's noise)
/// the clipping thresholds lie at least (see [`classify`]). Chosen on the
/// robustness matrix over six backgrounds per organ: noise σ 0.1 has 21
/// cases under a goal with the thresholds fixed, 18 at 0.01, 16 at 0.02;
/// moving them by the whole 0.4 σ at any noise (0.03 here) costs gain 1.6
/// five cases, where bright steel reads just under 0.97.
const CLIP_MARGIN: f32 = 0.02;

/// The lowest the clipping thresholds move to with the frame's noise: where
/// `CLIP_NOISE` σ + `CLIP_MARGIN` reaches it, σ = 0.2, twice the noise the
/// segmentation is specified for. Past that the estimate of σ is no guide
/// (it also reads texture), and bright unclipped steel (up to 0.97) would
/// count as clipped and take its neighbours' class.
const CLIP_FLOOR: f32 = 0.9;

/// The clipping thresholds `(clip_value, saturated_value)` on a frame of
/// noise `sigma`: each at most `CLIP_MARGIN` below a clipped channel's mean
/// reading, `1 − σ/√(2π)`, and never below `CLIP_FLOOR` (nor above its
/// setting).
fn clip_thresholds(clip_value: f32, saturated_value: f32, sigma: f32) -> (f32, f32) {
    let clipped_mean = (1.0 - CLIP_NOISE * sigma - CLIP_MARGIN).max(CLIP_FLOOR);
    (
        clip_value.min(clipped_mean),
        saturated_value.min(clipped_mean),
    )
}

/// A region's channel whose mean lies below this many times the frame's
/// noise σ is read back through [`floor_unclipped`] (step 0 of
/// [`classify`]); above it the sensor's clipping at 0 lifts the mean by
/// under 10⁻⁵ σ.
const UNCLIP_BELOW: f32 = 4.0;

/// The highest channel mean read back through the clipping at 0 (step 0 of
/// [`classify`]): where `UNCLIP_BELOW` σ passes it (σ above 0.125), the
/// clipping at 1 would matter as well.
const UNCLIP_MOST: f32 = 0.5;

/// Most Newton steps [`floor_unclipped`] takes (from `m` above black's
/// `σ/√(2π)` it needs 4 at most to reach 10⁻⁶ σ, over true values 0–4 σ in
/// double precision).
const UNCLIP_STEPS: usize = 12;

/// The standard normal density at `z`.
fn normal_density(z: f32) -> f32 {
    CLIP_NOISE * (-0.5 * z * z).exp()
}

/// The standard normal distribution function at `z`, through erf's
/// rational approximation of Abramowitz and Stegun (7.1.26: error under
/// 1.5 · 10⁻⁷).
fn normal_cdf(z: f32) -> f32 {
    let x = z.abs() * std::f32::consts::FRAC_1_SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let poly = t
        * (0.254_829_6
            + t * (-0.284_496_7 + t * (1.421_413_7 + t * (-1.453_152 + t * 1.061_405_4))));
    let erf = 1.0 - poly * (-x * x).exp();
    if z >= 0.0 {
        0.5 * (1.0 + erf)
    } else {
        0.5 * (1.0 - erf)
    }
}

/// The mean reading of a channel of true value `mu` under Gaussian noise
/// `sigma` that the sensor clips at 0: `μ Φ(μ/σ) + σ φ(μ/σ)`, at least `μ`.
fn floor_clipped_mean(mu: f32, sigma: f32) -> f32 {
    let z = mu / sigma;
    mu * normal_cdf(z) + sigma * normal_density(z)
}

/// The true value, at least 0, of a channel whose readings under Gaussian
/// noise `sigma`, clipped at 0 by the sensor, average `m`: the inverse of
/// [`floor_clipped_mean`], by Newton's method from `m`. The clipped mean is
/// increasing (its slope `Φ(μ/σ)`) and convex, so the steps fall toward the
/// root without passing it; they stop where one moves no more than 10⁻⁶ σ
/// (or than single precision resolves at the value).
/// Where `m` is at most what a black channel reads, `σ/√(2π)` (or is not
/// a number), it is 0; without noise (`sigma` not above 0), `m` (at least 0).
fn floor_unclipped(m: f32, sigma: f32) -> f32 {
    if sigma.is_nan() || sigma <= 0.0 {
        return m.max(0.0);
    }
    if m.is_nan() || m <= CLIP_NOISE * sigma {
        return 0.0;
    }
    let mut mu = m;
    for _ in 0..UNCLIP_STEPS {
        let step = (floor_clipped_mean(mu, sigma) - m) / normal_cdf(mu / sigma);
        mu -= step;
        if mu <= 0.0 {
            return 0.0;
        }
        // 10⁻⁶ σ, or what single precision resolves at `μ`
        if step.abs() <= (1e-6 * sigma).max(4.0 * f32::EPSILON * mu) {
            break;
        }
    }
    mu
}

/// The darkest channel of a mean colour.
fn darkest(m: [f32; 3]) -> f32 {
    m[0].min(m[1]).min(m[2])
}

/// The brightest channel of a mean colour.
fn brightest(m: [f32; 3]) -> f32 {
    m[0].max(m[1]).max(m[2])
}

/// A region counts as bright (the stricter rule of step 4; in step 4b only
/// within [`BRIGHT_GROW_SHARE`] and with at least [`JOIN_MIN_PX`] pixels) only where it is also at least this share of the region of
/// interest's 90th percentile brightness (pixel-weighted over the merged
/// regions), as well as [`SegmentParams::bright_ratio`] times its median.
/// Where the dark lumen fills most of the region its median is the lumen's,
/// and steel tinted by the tissue counted as bright by the median alone
/// (tint 25 %, colon 60° at 35 mm: IoU 0.818, 0.964 with this). Chosen on
/// the robustness matrix over six backgrounds per organ: 0.6 takes the
/// cases under a goal from 97 to 95, 0.7 to 96; both relative, so a gain
/// leaves them alone (an absolute floor lost the darkest frames).
const BRIGHT_OF_BRIGHTEST: f32 = 0.6;

/// Step 5: a region with a clipped channel (its darkest not clipped) is
/// tissue where its colour lies at least this share of the way from the
/// metal's colour to the tissue's, provided the tissue's colour lies more
/// than [`SegmentParams::grow_separation`] from the metal's (a colour at
/// all) and the region's more than half that (within it a share of so
/// short a way is the steel's own colour). Clipping lowers the channel
/// that is brightest, so it pulls a colour toward neutral, the metal's
/// side, and never past it: the colour the region reads is at most as far
/// toward the tissue's as its own. Steel tinted by the tissue lies at most
/// the tint's share of the way, 0.25 at the goal's tint (steel 25 % of the
/// way to pink tissue in RGB reads 0.23 of the way). Clipped pinkish-white
/// sheen beside the tip read 0.49 of the way and 0.082 from the metal's
/// colour (gain 1.6, larynx 0° at 35 mm, offset 300: 0.830 / 0.688), and
/// 0.066 from it at offset 100 (0.850 / 0.723): the earlier rule (past half
/// way, and more than `grow_separation` from the metal's) missed the first
/// for its share and the second for its distance and left both to their
/// neighbours' votes, the steel's. Over six backgrounds per organ any
/// share from 0.2 to 0.3 gave the same cases under a goal (76, before the
/// clipped tissue voted); 0.4 gave 77. It is also
/// [`SegmentParams::bright_metal_share`]'s default: a bright region that
/// is not clipped is tissue from the same share of the way.
///
/// The tissue colour's estimate (step 4's rounds) counts a clipped region's
/// colour by a different test, its distance from the metal's alone: the
/// share needs the tissue's colour, which that estimate is finding.
const CLIPPED_TISSUE_SHARE: f32 = 0.3;

/// A region's class before the threshold (`Scratch::region_class`): dark
/// (tissue: lumen, shadow), coloured (sorted by its colour, steps 4–4c) or
/// clipped (left for step 5); a candidate highlight while step 2 decides;
/// clipped tissue, once step 5 has found a clipped region's colour on the
/// tissue's side (it then votes as tissue on the other clipped regions);
/// clipped and already gathered into its blob by step 5's vote.
const DARK: u8 = 0;
/// See [`DARK`].
const COLOURED: u8 = 1;
/// See [`DARK`].
const CLIPPED: u8 = 2;
/// See [`DARK`].
const CANDIDATE: u8 = 3;
/// See [`DARK`].
const CLIPPED_TISSUE: u8 = 4;
/// See [`DARK`].
const CLIPPED_SEEN: u8 = 5;

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

/// Whether chromaticity `ch` lies within `width` times the length of the
/// segment from `metal` to `tissue` of the line through them: a mixture of
/// the two lies on it, a mixture of the metal with something else (red
/// tape, a dark vessel) off it.
fn near_line(ch: [f32; 2], metal: [f32; 2], tissue: [f32; 2], width: f32) -> bool {
    let d = [tissue[0] - metal[0], tissue[1] - metal[1]];
    let v = [ch[0] - metal[0], ch[1] - metal[1]];
    let cross = d[0] * v[1] - d[1] * v[0];
    // |cross| / |d| is the distance from the line
    cross * cross <= width * width * (d[0] * d[0] + d[1] * d[1]).powi(2)
}

/// Grows the instrument over the merged regions `roots` for up to
/// `rounds` rounds (steps 4b and 4c): in each round every tissue
/// region `i` for which `joins(i, instrument)` holds becomes instrument
/// (`instrument`: 1 instrument, 0 tissue). A region that joins is marked 2,
/// neither class, until the round ends, so the rule reads every region of
/// a round against the classes the round began with (the order of the
/// regions does not matter) and the next round sees it as instrument. Stops
/// early after a round in which none joined.
///
/// Both rules read only a region's own colour and its neighbours' classes,
/// so after the first round only the neighbours of the regions that joined
/// in the last one can join: a round asks those alone (`frontier`; `joined`
/// lists a round's joiners), and all the rounds together ask at most every
/// region once and then each side of every edge of the regions' graph
/// (`graph`: its adjacency and where each region's starts) once. The
/// buffers hold as much (`regions::split` reserves it for the region's
/// size): no allocation.
fn grow(
    roots: &[u32],
    instrument: &mut [u8],
    rounds: usize,
    (adjacency, adjacency_start): (&[[u32; 2]], &[u32]),
    (frontier, joined): (&mut Vec<u32>, &mut Vec<u32>),
    mut joins: impl FnMut(usize, &[u8]) -> bool,
) {
    frontier.clear();
    frontier.extend_from_slice(roots);
    for _ in 0..rounds {
        joined.clear();
        // a region listed twice is asked once: the first time marks it 2
        for &i in frontier.iter() {
            let i = i as usize;
            if instrument[i] == 0 && joins(i, instrument) {
                instrument[i] = 2;
                joined.push(i as u32);
            }
        }
        if joined.is_empty() {
            break;
        }
        frontier.clear();
        for &j in joined.iter() {
            instrument[j as usize] = 1;
            let next = graph::neighbours(adjacency, adjacency_start, j as usize);
            frontier.extend(
                next.iter()
                    .map(|&[o, _]| o)
                    .filter(|&o| instrument[o as usize] == 0),
            );
        }
    }
}

/// What [`joins_by_neighbours`] reads of the regions' graph.
struct JoinGraph<'a> {
    regions: &'a [Region],
    region_class: &'a [u8],
    adjacency: &'a [[u32; 2]],
    adjacency_start: &'a [u32],
}

/// Least share of a region's cell edges that must border the instrument for
/// it to join by its neighbours' colours (step 4c): the lit flank of a shaft
/// or a tinted joint runs along the steel; a patch of wet tissue that
/// touches it at a corner does not. Chosen on the robustness matrix over six
/// backgrounds per organ (0.25–0.4 alike; a glint beside the shaft under
/// gain 1.6 joined with no such bound).
const JOIN_BORDER_SHARE: f32 = 0.3;

/// Brightest a region may be, as a multiple of the instrument it borders, to
/// join by its neighbours' colours (step 4c; the dimmest:
/// `1 / grow_brightness`): a lit flank reads a few per cent brighter than
/// the steel beside it, tissue's wet sheen much more. Chosen on the
/// robustness matrix (1.05 left a tinted case and two more white ones
/// under a goal; 1.1 and 1.15 alike).
const JOIN_BRIGHTER: f32 = 1.1;

/// Smallest region, px, that joins by its neighbours' colours (step 4c), and
/// smallest bright region that grows in by step 4b: one- and two-cell
/// regions in a blurred highlight's rim carry noise, not colour, and joined
/// one after another along the rim (blur 1.5 px, larynx −60° at 35 mm: IoU
/// 0.932 → 0.903 with no bound in step 4c; blur 3 px, stomach 0° at 35 mm:
/// 0.821 → 0.810 on the bend and gripper with none in step 4b).
const JOIN_MIN_PX: f32 = 16.0;

/// Step 4b: a bright region (held to [`SegmentParams::bright_metal_share`]
/// by step 4) grows into the instrument where it lies within this share of
/// the way from the metal's colour to the tissue's, has at least
/// [`JOIN_MIN_PX`] pixels and is about as bright as the instrument it
/// borders. A lit flank of the shaft reflects the tissue at a grazing angle,
/// more than the rest of the shaft: under tint 25 % at 8 mm, 0.30–0.38 of
/// the way, beside steel as bright as itself (colon 0° at 8 mm, offset 600:
/// 0.743 / 0.793 with bright regions kept out of step 4b, 0.995 / 0.994
/// with this). Bright tissue's sheen lies further (the bright rule's
/// reason). Chosen on the robustness matrix over offsets 0–500 and
/// 600–1100 both: 0.35 takes the cases under a goal 75 → 73 and 84 → 78,
/// none newly under; 0.4 (with the size floor) gives 73 and 76 but puts a
/// blur case newly under.
const BRIGHT_GROW_SHARE: f32 = 0.35;

/// Step 4c, for region `i`, tissue: whether it joins the instrument by the
/// colours beside it. It does where it is left to its colour (neither dark
/// nor clipped: bright regions too), has at least [`JOIN_MIN_PX`] pixels,
/// borders the instrument along at least [`JOIN_BORDER_SHARE`] of its cell
/// edges, its chromaticity lies less than
/// [`SegmentParams::neighbour_ratio`] times as far from the instrument's
/// beside it as from the tissue's beside it (each the edge-weighted mean of
/// the neighbouring regions of that class left to their colour; the
/// frame's tissue colour `tissue` where it borders no such tissue), and its
/// brightness lies between `1 / grow_brightness` and [`JOIN_BRIGHTER`]
/// times the instrument's beside it. In the second round the regions
/// joined in the first count as instrument beside their neighbours: the
/// instrument grows along itself, as in step 4b. Steps 4 and 4b compare
/// with the frame's two colours; where the tissue's lies near the metal's
/// (white, grey) or the steel reflects it, the colours beside a region tell
/// more.
fn joins_by_neighbours(
    g: &JoinGraph,
    i: usize,
    instrument: &[u8],
    tissue: [f32; 2],
    p: &SegmentParams,
) -> bool {
    let r = &g.regions[i];
    if g.region_class[i] != COLOURED || r.count < JOIN_MIN_PX {
        return false;
    }
    // the instrument's and the tissue's colours (and the instrument's
    // brightness) over the cell edges they share with it
    let (mut steel, mut steel_lum, mut steel_edges) = ([0.0f32; 2], 0.0f32, 0u32);
    let (mut beside, mut beside_edges, mut edges) = ([0.0f32; 2], 0u32, 0u32);
    for &[o, n] in graph::neighbours(g.adjacency, g.adjacency_start, i) {
        let (o, w) = (o as usize, n as f32);
        edges += n;
        if g.region_class[o] != COLOURED {
            continue;
        }
        let c = g.regions[o].chroma;
        match instrument[o] {
            1 => {
                steel = [steel[0] + w * c[0], steel[1] + w * c[1]];
                steel_lum += w * g.regions[o].lum;
                steel_edges += n;
            }
            0 => {
                beside = [beside[0] + w * c[0], beside[1] + w * c[1]];
                beside_edges += n;
            }
            // joined this round: neither class until the round ends
            _ => {}
        }
    }
    if steel_edges == 0 || (steel_edges as f32) < JOIN_BORDER_SHARE * edges as f32 {
        return false;
    }
    let steel = steel.map(|v| v / steel_edges as f32);
    let steel_lum = steel_lum / steel_edges as f32;
    let beside = if beside_edges > 0 {
        beside.map(|v| v / beside_edges as f32)
    } else {
        tissue
    };
    dist2(r.chroma, steel) < p.neighbour_ratio * p.neighbour_ratio * dist2(r.chroma, beside)
        && r.lum <= JOIN_BRIGHTER * steel_lum
        && r.lum * p.grow_brightness >= steel_lum
}

/// Sorts every merged region (root of `s.parent`) into instrument or tissue
/// (`s.instrument`, per region), after building the regions' graph
/// (`graph::build`):
///
/// 0. on a noisy frame the sensor clips the noise of a dark channel at 0,
///    so its mean reads high (black reads `σ/√(2π)`, 0.04 at σ 0.1) and a
///    dark region looks greyer and brighter than it is: nearer the steel's
///    colour and above the lumen's threshold (noise σ 0.1, larynx 30° at
///    20 mm, offset 300: the lumen above the joint was steel, IoU 0.824).
///    Each region's channels below [`UNCLIP_BELOW`] σ are read back to the
///    value whose clipped mean they are ([`floor_unclipped`], for the
///    frame's measured σ);
/// 1. regions darker than [`SegmentParams::min_relative_value`] of the
///    region of interest's median brightness are tissue (lumen, shadow);
/// 2. regions whose darkest channel is above [`SegmentParams::clip_value`]
///    (clipped specular light), whose brightest is above
///    [`SegmentParams::saturated_value`] (a clipped channel: no trustworthy
///    chromaticity), or which are highlights (small, brighter than the
///    median and [`SegmentParams::highlight_ratio`] times brighter than the
///    regions around them) are left for step 5; on a noisy frame both
///    thresholds move down with the mean a clipped channel reads,
///    `1 − σ/√(2π)` for the frame's measured σ, staying `CLIP_MARGIN` below
///    it and above `CLIP_FLOOR`;
/// 3. the tissue colour `T` starts at the median chromaticity of the
///    regions left to their colour (neither dark nor clipped) on the region
///    of interest's border where they hold more than
///    60 % of it (the instrument enters from one side, so it holds a
///    minority of the border even where its shaft fills the region); else at
///    the median chromaticity of the regions whose distance from the metal's
///    `M` ([`SegmentParams::metal_chroma`]) lies between the median and the
///    80th percentile;
/// 4. a region is instrument where its chromaticity is nearer `M` than `T`
///    (for a region brighter than [`SegmentParams::bright_ratio`] times the
///    median and `BRIGHT_OF_BRIGHTEST` times the 90th percentile: where it
///    lies within [`SegmentParams::bright_metal_share`] of the way from `M`
///    to `T`);
///    then `T` becomes the pixel-weighted median of the tissue class, with
///    the regions left for step 5 whose darkest channel does not clip and
///    whose chromaticity lies more than [`SegmentParams::grow_separation`]
///    from `M` (overexposed tissue keeps a colour, paler than its own and
///    never the metal's), and the regions are sorted again (two rounds);
///    then (4b) a region that borders the instrument joins it where it lies
///    within [`SegmentParams::grow_share`] of the way from `M` to `T` (a
///    bright region: within [`BRIGHT_GROW_SHARE`], and with at least
///    [`JOIN_MIN_PX`] pixels), near the line through them, and is about as
///    bright as the instrument it borders
///    ([`SegmentParams::grow_brightness`]; not where `T` lies within
///    [`SegmentParams::grow_separation`] of `M`), round after round until
///    none joins (a far gripper tinted a little more at each of its parts
///    joins part by part; each round but the last adds a region, so there
///    are at most as many rounds as regions);
///    then (4c) a region that runs along the instrument and is about as
///    bright joins it where its colour lies less than
///    [`SegmentParams::neighbour_ratio`] times as far from the steel's
///    beside it as from the tissue's beside it ([`joins_by_neighbours`]),
///    two rounds;
/// 5. a region with a clipped channel whose darkest channel does not clip
///    and whose chromaticity lies at least [`CLIPPED_TISSUE_SHARE`] of the
///    way from `M` to `T` is tissue (where `T` lies more than
///    [`SegmentParams::grow_separation`] from `M`, and the region more than
///    half that): one clipped channel
///    leaves a colour, pulled toward neutral, and steel that clips is white
///    (a pinkish-white sheen beside the tip, 0.49 of the way, took the
///    steel's class from its neighbours at gain 1.6; where noise lowers the
///    thresholds, bright pink tissue beside the tip, bordered mostly by
///    other clipped tissue, took the instrument's class from the few
///    regions around it that were not clipped); then every other specular
///    region takes the class that borders most of it, over the regions
///    that are not clipped and the clipped tissue just found (a white glare
///    beside the gripper, bordered by clipped pink tissue, took the
///    gripper's class when that tissue had no vote), clipped regions that
///    touch voting as one blob over what borders the blob (a glare ringed
///    by a clipped rim heard only the gripper at its tip).
pub(super) fn classify(
    s: &mut Scratch,
    p: &SegmentParams,
    cols: usize,
    rows: usize,
    sigma: f32,
) -> Classes {
    graph::build(s, cols, rows);
    let Scratch {
        regions,
        parent,
        instrument,
        labels,
        region_class,
        roots,
        adjacency,
        adjacency_start,
        grow_frontier,
        grow_joined,
        ..
    } = s;
    // the merged regions, once: every loop below runs over them, not the leaves
    roots.clear();
    roots.extend((0..parent.len() as u32).filter(|&i| parent[i as usize] == i));
    // 0: a dark channel's mean, lifted by the noise the sensor clips at 0,
    // back to the value that reads so
    if sigma > 0.0 {
        let below = (UNCLIP_BELOW * sigma).min(UNCLIP_MOST);
        for &i in roots.iter() {
            let r = &mut regions[i as usize];
            if r.mean.iter().any(|&c| c < below) {
                let mean = r.mean.map(|c| {
                    if c < below {
                        floor_unclipped(c, sigma)
                    } else {
                        c
                    }
                });
                *r = Region::of_mean(mean, r.count);
            }
        }
    }
    // 1–3: the frame's statistics
    let mut brightness = Histogram::new();
    for &i in roots.iter() {
        let r = &regions[i as usize];
        brightness.add(r.lum, 0.0, 3.0, f64::from(r.count));
    }
    let median_l = brightness.quantile(0.5, 0.0, 3.0);
    let min_l = p.min_relative_value * median_l;
    // a bright region (held to the stricter rule below, and to
    // `BRIGHT_GROW_SHARE` and `JOIN_MIN_PX` in step 4b) is bright against the frame's brightest regions too: where
    // the dark lumen fills most of the region, its median is the lumen's,
    // and a tinted joint at 35 mm counted as bright by it alone
    let bright_l =
        (p.bright_ratio * median_l).max(BRIGHT_OF_BRIGHTEST * brightness.quantile(0.9, 0.0, 3.0));
    // a channel that clips reads below full scale by the noise clipped
    // with it: the mean of min(1, 1 + n) for n ~ N(0, σ) is 1 − σ/√(2π);
    // where that falls to within `CLIP_MARGIN` of the thresholds, they move
    // down with it (`saturated_value` 0.97 for σ above 0.025, `clip_value`
    // 0.94 above 0.1), to `CLIP_FLOOR` at most (σ 0.2)
    let (clip_value, saturated_value) = clip_thresholds(p.clip_value, p.saturated_value, sigma);
    region_class.clear();
    region_class.resize(regions.len(), DARK);
    for &i in roots.iter() {
        let m = regions[i as usize].mean;
        region_class[i as usize] = if m[0] + m[1] + m[2] < min_l {
            DARK
        } else if darkest(m) > clip_value || brightest(m) > saturated_value {
            CLIPPED
        } else {
            COLOURED
        };
    }
    // highlights: small near-white regions brighter than the median and
    // than what surrounds them are treated as clipped (step 5)
    if p.highlight_ratio > 0.0 {
        let total: f32 = roots.iter().map(|&i| regions[i as usize].count).sum();
        let mut any = false;
        for &i in roots.iter() {
            let (r, c) = (&regions[i as usize], &mut region_class[i as usize]);
            if *c == COLOURED
                && r.count < p.highlight_max * total
                && r.lum > median_l
                && darkest(r.mean) > p.highlight_min_value
            {
                *c = CANDIDATE;
                any = true;
            }
        }
        if any {
            for &i in roots.iter() {
                let i = i as usize;
                if region_class[i] == CANDIDATE {
                    // the brightness across its cell edges
                    let (mut sum, mut edges) = (0.0f32, 0u32);
                    for &[o, n] in graph::neighbours(adjacency, adjacency_start, i) {
                        sum += regions[o as usize].lum * n as f32;
                        edges += n;
                    }
                    region_class[i] =
                        if edges > 0 && regions[i].lum > p.highlight_ratio * sum / edges as f32 {
                            CLIPPED
                        } else {
                            COLOURED
                        };
                }
            }
        }
    }
    let coloured = || {
        roots
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| region_class[i] == COLOURED)
            .map(|i| &regions[i])
    };
    // the tissue colour starts at the median colour of the regions whose
    // distance from the metal's colour lies between the median and the 80th
    // percentile (pixel-weighted): tissue, whether the instrument covers a
    // little or most of the region, and not the reddest tenth (red tape, dark
    // vessels); medians, not means, throughout
    let mut far = Histogram::new();
    for r in coloured() {
        far.add(
            dist2(r.chroma, p.metal_chroma).sqrt(),
            0.0,
            2.0,
            f64::from(r.count),
        );
    }
    let (near, farthest) = (far.quantile(0.5, 0.0, 2.0), far.quantile(0.8, 0.0, 2.0));
    let (mut hx, mut hy, mut fallback) = (Histogram::new(), Histogram::new(), [0.0f32; 2]);
    for r in coloured() {
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
        if region_class[root] == COLOURED {
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
    // a region whose brightest channel clips and darkest does not keeps a
    // colour (steel that clips is white): the tissue colour's rounds count
    // it, step 5 may decide it by it
    let keeps_a_colour = |m: [f32; 3]| brightest(m) > saturated_value && darkest(m) <= clip_value;
    // bright tissue is pulled toward white (its sheen, its red channel
    // clipping), so a bright region must lie nearer the metal
    let share = |lum: f32| {
        if lum > bright_l {
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
        for r in coloured() {
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
        // tissue whose brightest channel clips keeps a colour (steel that
        // clips is white): where it lies more than `grow_separation` off the
        // metal's, its colour counts toward the tissue's (step 5 decides its
        // class by its share of the way, `CLIPPED_TISSUE_SHARE`); the clipped
        // channel pulls it toward neutral, so it is paler than the tissue,
        // never the metal's
        for &i in roots.iter() {
            let r = &regions[i as usize];
            if region_class[i as usize] == CLIPPED
                && keeps_a_colour(r.mean)
                && dist2(r.chroma, metal) > p.grow_separation.powi(2)
            {
                hx.add(r.chroma[0], -1.0, 1.0, f64::from(r.count));
                hy.add(r.chroma[1], -1.0, 1.0, f64::from(r.count));
            }
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
            region_class[i] == COLOURED && metal_side(ch, metal, tissue, share(regions[i].lum)),
        );
    }
    // the tissue's colour lies clearly off the metal's: a share of the way
    // from one to the other means something (steps 4b and 5)
    let tissue_coloured = dist2(metal, tissue) > p.grow_separation.powi(2);
    // 4b: the instrument is one object: a region that borders it and lies
    // within `grow_share` of the way from the metal to the tissue joins it
    // (a far gripper or a joint's disc tinted by the tissue it reflects);
    // a bright region within `BRIGHT_GROW_SHARE` of the way, and of some
    // size (a lit flank reflecting the tissue)
    if p.grow_share > 0.5 && tissue_coloured {
        // each round but the last adds a region: at most as many as there are
        grow(
            roots,
            instrument,
            roots.len(),
            (adjacency, adjacency_start),
            (grow_frontier, grow_joined),
            |i, instrument| {
                let r = &regions[i];
                let bright = r.lum > bright_l;
                let share = if bright {
                    BRIGHT_GROW_SHARE
                } else {
                    p.grow_share
                };
                if region_class[i] != COLOURED
                    || (bright && r.count < JOIN_MIN_PX)
                    || !metal_side(r.chroma, metal, tissue, share)
                    || !near_line(r.chroma, metal, tissue, GROW_WIDTH)
                {
                    return false;
                }
                // the instrument's brightness over the cell edges it shares
                // with this region
                let (mut sum, mut edges) = (0.0f32, 0u32);
                for &[o, n] in graph::neighbours(adjacency, adjacency_start, i) {
                    if instrument[o as usize] == 1 {
                        sum += regions[o as usize].lum * n as f32;
                        edges += n;
                    }
                }
                let around = sum / edges.max(1) as f32;
                edges > 0
                    && r.lum <= p.grow_brightness * around
                    && r.lum * p.grow_brightness >= around
            },
        );
    }
    // 4c: steel mirrors what lies around it, so a part of it may lie nearer
    // the frame's tissue colour than the metal's (a lit flank on white
    // tissue, a joint tinted by the tissue) and still lie nearer the steel
    // beside it than the tissue beside it
    if p.neighbour_ratio > 0.0 {
        let g = JoinGraph {
            regions,
            region_class,
            adjacency,
            adjacency_start,
        };
        grow(
            roots,
            instrument,
            GROW_ROUNDS,
            (adjacency, adjacency_start),
            (grow_frontier, grow_joined),
            |i, instrument| joins_by_neighbours(&g, i, instrument, tissue, p),
        );
    }
    // 5: one channel clipping leaves a colour, and a region (its darkest
    // channel not clipped) whose colour lies at least `CLIPPED_TISSUE_SHARE`
    // of the way toward the tissue's is tissue, where the tissue's colour
    // lies more than `grow_separation` from the metal's and the region's
    // more than half that (steel that clips is white); then the other clipped regions
    // and highlights take their neighbours' class, by shared cell edges,
    // the clipped tissue of the first pass voting as tissue (a white glare
    // beside the tip, bordered by clipped pink tissue and the gripper,
    // took the gripper's class from the only neighbour left to vote), and
    // clipped regions that touch vote as one blob (a glare clipped white,
    // ringed by a clipped rim, is bordered by the tissue around the rim:
    // voting alone, it heard only the gripper at its tip)
    for &i in roots.iter() {
        let i = i as usize;
        let r = &regions[i];
        if region_class[i] == CLIPPED
            && tissue_coloured
            && keeps_a_colour(r.mean)
            && dist2(r.chroma, metal) > (0.5 * p.grow_separation).powi(2)
            && !metal_side(r.chroma, metal, tissue, CLIPPED_TISSUE_SHARE)
        {
            instrument[i] = 0;
            region_class[i] = CLIPPED_TISSUE;
        }
    }
    for &i in roots.iter() {
        let i = i as usize;
        if region_class[i] != CLIPPED {
            continue;
        }
        // the clipped regions linked to this one through clipped regions
        // (a glare and the clipped rim around it) are one blob, which takes
        // the class of what borders it, by shared cell edges
        grow_frontier.clear();
        grow_joined.clear();
        region_class[i] = CLIPPED_SEEN;
        grow_frontier.push(i as u32);
        let mut votes = [0u32; 2];
        while let Some(j) = grow_frontier.pop() {
            grow_joined.push(j);
            for &[o, n] in graph::neighbours(adjacency, adjacency_start, j as usize) {
                let o = o as usize;
                match region_class[o] {
                    CLIPPED => {
                        region_class[o] = CLIPPED_SEEN;
                        grow_frontier.push(o as u32);
                    }
                    CLIPPED_SEEN => {}
                    _ => votes[usize::from(instrument[o])] += n,
                }
            }
        }
        let class = u8::from(votes[1] > votes[0]);
        for &j in grow_joined.iter() {
            instrument[j as usize] = class;
        }
    }
    Classes {
        instrument: found,
        tissue,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thresholds stay at their settings on a clean frame, follow a
    /// clipped channel's mean down with the noise, and stop at the floor
    /// however large the noise estimate.
    #[test]
    fn clip_thresholds_follow_the_noise_down_to_the_floor() {
        let (clip, saturated) = (0.94, 0.97);
        assert_eq!(clip_thresholds(clip, saturated, 0.0), (clip, saturated));
        assert_eq!(clip_thresholds(clip, saturated, 0.02), (clip, saturated));
        // σ 0.1: a clipped channel reads 0.960 on average; 0.02 below it
        let (c, s) = clip_thresholds(clip, saturated, 0.1);
        assert!((s - (1.0 - 0.398_942_3 * 0.1 - 0.02)).abs() < 1e-6, "{s}");
        assert!((c - clip.min(s)).abs() < 1e-6, "{c}");
        let mut last = (clip, saturated);
        for k in 0..=200 {
            let sigma = k as f32 * 0.01; // up to 2, past anything a frame gives
            let (c, s) = clip_thresholds(clip, saturated, sigma);
            assert!(c <= last.0 && s <= last.1, "σ {sigma}: not monotone");
            assert!(c >= CLIP_FLOOR && s >= CLIP_FLOOR, "σ {sigma}: {c} {s}");
            last = (c, s);
        }
        assert_eq!(last, (CLIP_FLOOR, CLIP_FLOOR));
        // a setting below the floor is kept as set
        assert_eq!(clip_thresholds(0.5, 0.6, 1.0), (0.5, 0.6));
    }

    /// The normal distribution function against tabulated values, and the
    /// clipped mean read back over the range a dark channel takes.
    #[test]
    fn a_floor_clipped_mean_reads_back_to_its_value() {
        const TOLERANCE: f32 = 1e-5;
        for (z, cdf) in [
            (0.0, 0.5),
            (1.0, 0.841_344_7),
            (-1.96, 0.024_997_9),
            (3.0, 0.998_650_1),
        ] {
            assert!((normal_cdf(z) - cdf).abs() < 1e-6, "Φ({z})");
        }
        // black reads σ/√(2π); far above the floor, the value itself
        assert!((floor_clipped_mean(0.0, 0.1) - 0.039_894_2).abs() < 1e-6);
        assert!((floor_clipped_mean(0.6, 0.1) - 0.6).abs() < 1e-6);
        for sigma in [0.1f32, 0.01, 0.004] {
            for k in 0..=40 {
                let mu = k as f32 * 0.1 * sigma; // 0 to 4σ
                let m = floor_clipped_mean(mu, sigma);
                assert!(m >= mu, "σ {sigma}, μ {mu}: {m}");
                let back = floor_unclipped(m, sigma);
                assert!(
                    (back - mu).abs() <= TOLERANCE * sigma,
                    "σ {sigma}, μ {mu}: read {m}, back {back}"
                );
            }
        }
        // what no value reads (below black's mean, or not a number) is
        // black; without noise, as read
        assert_eq!(floor_unclipped(0.01, 0.1), 0.0);
        assert_eq!(floor_unclipped(-0.2, 0.1), 0.0);
        assert_eq!(floor_unclipped(f32::NAN, 0.1), 0.0);
        assert_eq!(floor_unclipped(0.2, 0.0), 0.2);
        assert_eq!(floor_unclipped(0.2, f32::NAN), 0.2);
        assert_eq!(floor_unclipped(-0.2, 0.0), 0.0);
    }

    #[test]
    fn darkest_and_brightest_are_the_least_and_greatest_channel() {
        assert_eq!(darkest([0.3, 0.1, 0.2]), 0.1);
        assert_eq!(darkest([0.9, 0.95, 0.7]), 0.7);
        assert_eq!(brightest([0.3, 0.1, 0.2]), 0.3);
        assert_eq!(brightest([0.9, 0.95, 0.7]), 0.95);
    }
}
