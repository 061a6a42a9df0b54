//! IBJAE's image-pair set D^I (the paper's Section II-C-1, Fig. 4a) and the
//! nominal silhouette database it retrieves from.

use std::collections::HashMap;

use kflex_estimate::{EstimateError, SegmentParams, Segmenter};
use kflex_model::{
    Background, Bounds, BuildTolerances, Camera, FrameParams, Instrument, InstrumentShape, Mask,
    PoseRange, Rasterizer, Roi, SceneRenderer, Tissue, WorkingRegions,
};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{DatasetCard, parallel, stream};
use crate::error::{ControlError, Result};

/// Version of [`ImagePairsConfig::generate`]'s and
/// [`ImagePairsConfig::database`]'s output for a given configuration: it
/// changes with any change to the frames' or silhouettes' pixels (the
/// renderer, the lens, the segmentation). 2: overexposed tissue is clipped
/// by the sensor, after the lens, not before it, and its colour counts toward
/// the tissue's in the segmentation. 3: the segmentation's clipping
/// thresholds move down with a noisy frame's measured σ (a frame whose
/// measured σ is above 0.025; version 2's data were made before that change).
/// 4: the segmentation refines a blurred rim wider than a cell in up to
/// three passes (its boundary moves toward tissue by whole cells).
/// 5: where the boundary's two samples do not lie in their classes (a thin
/// part, a spike of blurred rim), the segmentation reads them at the
/// nearest cells clear of the boundary instead of keeping the cells' class.
pub const IMAGE_GENERATOR_VERSION: u32 = 5;

/// Side of IBJAE's silhouettes, px.
const SIDE: u32 = 48;
/// Pixels of one silhouette.
const PIXELS: usize = (SIDE * SIDE) as usize;

/// Stream tags: one per kind of draw.
const TAG_BLOCK: u64 = 0x6b66_6c65_7864_0001;
const TAG_QUERY: u64 = 0x6b66_6c65_7864_0002;

/// How to make D^I: pairs `(x^b, x^r, S)` of a segmented frame of the
/// simulated robot and a clean silhouette of the nominal model.
///
/// **The camera's poses and regions.** The default camera and the K-FLEX
/// instrument over `poses` (default [`PoseRange::FULL`]: θ ∈ [−90°, 90°],
/// d ∈ [8, 40] mm), in their working regions ([`WorkingRegions::full`]):
/// each query is rendered, and both its silhouettes made, in the region of
/// its own band (`regions.at(θ, d)`), as IBJAE reads it.
///
/// **Queries x^b.** A pose drawn uniformly (continuous) over `poses`; an
/// as-built instrument and camera drawn per query ([`BuildTolerances`],
/// `tolerances`); a shaded frame of the region (the block's background and
/// tissue, see below; illumination gain, noise and blur drawn per query; no
/// tape); segmented by kflex's region-based segmentation
/// ([`Segmenter`], `segment`) into 48×48. A frame the segmentation finds
/// no instrument in is drawn again (same pose, new as-built robot and
/// frame conditions), up to `max_attempts`; then a new pose.
///
/// **References x^r.** The nominal instrument through the nominal camera,
/// silhouetted straight into 48×48 (the region's intrinsics,
/// [`Rasterizer::silhouette`]), at poses on the database grid: θ every
/// `theta_step_deg` from θ's start, d every `translation_step_mm` from d's.
///
/// **Labels.** `S = 1` when the reference is the query's own grid cell —
/// `|θ^b − θ^r| ≤ theta_step_deg / 2` and `|d^b − d^r| ≤ translation_step_mm / 2`
/// (the entry a perfect retrieval returns) — and 0 otherwise. Each query
/// gives one positive and one negative pair (pairs `2q`, `2q + 1`), so the
/// set is balanced and a rendered frame serves two pairs. A negative is
/// *hard* with probability `hard_share`: the same d, θ a whole number of
/// grid steps `hard_offset_deg` away (either side, inside the band); else a
/// grid pose drawn uniformly from the band's other cells.
///
/// **Backgrounds.** Queries come in blocks of `block` that share a
/// background (kind from `backgrounds`, tissue from `tissues`, one of
/// `background_seeds` textures), drawn per block: a background is
/// synthesised once per block, not per frame.
///
/// Every draw comes from the stream of its query (or block) and the seed,
/// so the pairs do not depend on the thread count.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ImagePairsConfig {
    /// Number of pairs, even (the paper: 100,000).
    pub pairs: usize,
    /// The seed of every draw.
    pub seed: u64,
    /// The poses drawn.
    pub poses: PoseRange,
    /// Database grid step of θ, deg (≤ 1, as the paper's 1° resolution).
    pub theta_step_deg: f64,
    /// Database grid step of d, mm.
    pub translation_step_mm: f64,
    /// Share of negatives that are hard (`[0, 1]`).
    pub hard_share: f64,
    /// A hard negative's θ offset, `[min, max]` deg (rounded to grid steps).
    pub hard_offset_deg: [f64; 2],
    /// The as-built robot's tolerances (the reality gap).
    pub tolerances: BuildTolerances,
    /// Background kinds drawn per block.
    pub backgrounds: Vec<Background>,
    /// Tissue colours drawn per block.
    pub tissues: Vec<Tissue>,
    /// Background textures per kind (seeds `0..background_seeds`).
    pub background_seeds: u32,
    /// Queries per block (one background each).
    pub block: u32,
    /// Illumination gain, drawn uniformly from `[min, max]`.
    pub illumination_gain: [f64; 2],
    /// Sensor noise standard deviation on [0, 1], drawn from `[min, max]`.
    pub noise_std: [f64; 2],
    /// Share of frames blurred.
    pub blur_share: f64,
    /// Blur of a blurred frame, px, drawn from `[min, max]`.
    pub blur_px: [f64; 2],
    /// The segmentation's thresholds.
    pub segment: SegmentParams,
    /// Frames drawn for one pose before a new pose is drawn.
    pub max_attempts: u32,
}

impl Default for ImagePairsConfig {
    /// 100,000 pairs over the full range, a 1° × 1 mm grid, half of the
    /// negatives hard (2–5° away), the default tolerances, the three organ
    /// backgrounds in their own tissue colour (8 textures each, 32 queries
    /// a block), gain 0.7–1.3, noise 0–0.02, a third of the frames blurred
    /// by 0.5–1.5 px; seed 2020.
    fn default() -> Self {
        Self {
            pairs: 100_000,
            seed: 2020,
            poses: PoseRange::FULL,
            theta_step_deg: 1.0,
            translation_step_mm: 1.0,
            hard_share: 0.5,
            hard_offset_deg: [2.0, 5.0],
            tolerances: BuildTolerances::default(),
            backgrounds: Background::ALL.to_vec(),
            tissues: vec![Tissue::Organ],
            background_seeds: 8,
            block: 32,
            illumination_gain: [0.7, 1.3],
            noise_std: [0.0, 0.02],
            blur_share: 1.0 / 3.0,
            blur_px: [0.5, 1.5],
            segment: SegmentParams::default(),
            max_attempts: 8,
        }
    }
}

/// D^I, one row per pair (arrays of `pairs` rows; silhouettes row-major,
/// 48 × 48 bytes each, 1 instrument, 0 background).
#[derive(Debug, Clone, PartialEq)]
pub struct ImagePairs {
    /// x^b: the segmented silhouettes of the simulated robot's frames.
    pub x_b: Vec<u8>,
    /// x^r: the nominal model's clean silhouettes.
    pub x_r: Vec<u8>,
    /// S: 1 for the same grid cell, 0 otherwise.
    pub s: Vec<u8>,
    /// Whether the pair is a hard negative.
    pub hard: Vec<u8>,
    /// The query (frame) of each pair: pairs `2q` and `2q + 1` share x^b.
    pub query: Vec<u32>,
    /// The band of the query (index into [`WorkingRegions::bands`]).
    pub band: Vec<u32>,
    /// θ of x^b, deg.
    pub theta_b_deg: Vec<f64>,
    /// d of x^b, mm.
    pub translation_b_mm: Vec<f64>,
    /// θ of x^r, deg.
    pub theta_r_deg: Vec<f64>,
    /// d of x^r, mm.
    pub translation_r_mm: Vec<f64>,
    /// What was made and how.
    pub card: DatasetCard<ImagePairsConfig>,
}

/// The nominal silhouette database of [`ImagePairsConfig::database`].
#[derive(Debug, Clone, PartialEq)]
pub struct ImageDatabase {
    /// Silhouettes, 48 × 48 bytes each, row-major.
    pub masks: Vec<u8>,
    /// θ of each entry, deg.
    pub theta_deg: Vec<f64>,
    /// d of each entry, mm.
    pub translation_mm: Vec<f64>,
    /// Band of each entry (index into [`WorkingRegions::bands`]).
    pub band: Vec<u32>,
    /// What was made and how.
    pub card: DatasetCard<ImagePairsConfig>,
}

/// A grid axis: `start + k · step` for `k` in `0..=last`.
#[derive(Debug, Clone, Copy)]
struct Axis {
    start: f64,
    step: f64,
    last: i64,
}

impl Axis {
    fn new([lo, hi]: [f64; 2], step: f64) -> Self {
        Self {
            start: lo,
            step,
            last: ((hi - lo) / step + 1e-9).floor() as i64,
        }
    }

    fn at(&self, k: i64) -> f64 {
        self.start + self.step * k as f64
    }

    /// The nearest grid index to `x`.
    fn nearest(&self, x: f64) -> i64 {
        ((x - self.start) / self.step)
            .round()
            .clamp(0.0, self.last as f64) as i64
    }

    /// The grid indices inside `[lo, hi]`.
    fn within(&self, [lo, hi]: [f64; 2]) -> (i64, i64) {
        let a = ((lo - self.start) / self.step - 1e-9).ceil().max(0.0) as i64;
        let b = ((hi - self.start) / self.step + 1e-9).floor() as i64;
        (a, b.min(self.last))
    }
}

/// What every worker shares: the nominal camera, instrument and regions.
struct Setup {
    camera: Camera,
    instrument: Instrument,
    regions: WorkingRegions,
    /// Per band: the nominal camera resampled to its region at 48 × 48.
    small: Vec<Camera>,
    theta: Axis,
    translation: Axis,
}

/// A worker's own buffers.
struct Worker {
    /// One renderer per background (kind, tissue, texture seed), each
    /// caching its own: a background is synthesised once per worker.
    renderers: HashMap<(Background, Tissue, u64), SceneRenderer>,
    segmenter: Segmenter,
    raster: Rasterizer,
    mask: Mask,
    shape: InstrumentShape,
}

/// One query's two pairs.
struct QueryPairs {
    x_b: Vec<u8>,
    x_r: [Vec<u8>; 2],
    hard: bool,
    band: u32,
    pose_b: [f64; 2],
    pose_r: [[f64; 2]; 2],
    failures: u32,
}

/// A query's references: silhouettes (positive, negative), their poses
/// `[θ deg, d mm]`, and whether the negative is hard.
type References = ([Vec<u8>; 2], [[f64; 2]; 2], bool);

fn uniform(rng: &mut ChaCha8Rng, [lo, hi]: [f64; 2]) -> f64 {
    if hi > lo {
        rng.random_range(lo..=hi)
    } else {
        lo
    }
}

fn check_interval(name: &'static str, [lo, hi]: [f64; 2], bounds: Bounds) -> Result<()> {
    bounds.check(name, lo)?;
    Bounds::closed(lo, bounds.max).check(name, hi)?;
    Ok(())
}

impl ImagePairsConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`ControlError::OutOfRange`] naming the first setting out of its
    /// range: `pairs` odd or outside `[2, 1e6]`, `theta_step_deg` outside
    /// `[0.05, 1]`, `translation_step_mm` outside `[0.1, 10]`, `hard_share`
    /// or `blur_share` outside `[0, 1]`, `hard_offset_deg` outside `[1, 45]`
    /// or reversed, `backgrounds.len()`/`tissues.len()` 0,
    /// `background_seeds` or `block` outside `[1, 1e6]`,
    /// `illumination_gain` outside `[0.05, 5]`, `noise_std` outside
    /// `[0, 1]`, `blur_px` outside `[0, 20]`, `max_attempts` outside
    /// `[1, 1000]`; as [`BuildTolerances::validate`] and [`Segmenter::new`].
    pub fn validate(&self) -> Result<()> {
        // two 48×48 silhouettes a pair: a million pairs take 4.6 GB
        Bounds::closed(2.0, 1e6).check("pairs", self.pairs as f64)?;
        if self.pairs % 2 == 1 {
            return Err(ControlError::NotEnoughData {
                metric: "image pairs",
                needed: "an even number of pairs (one positive and one negative per query)",
                got: self.pairs,
            });
        }
        Bounds::closed(0.05, 1.0).check("theta_step_deg", self.theta_step_deg)?;
        Bounds::closed(0.1, 10.0).check("translation_step_mm", self.translation_step_mm)?;
        Bounds::closed(0.0, 1.0).check("hard_share", self.hard_share)?;
        check_interval(
            "hard_offset_deg",
            self.hard_offset_deg,
            Bounds::closed(1.0, 45.0),
        )?;
        Bounds::closed(1.0, 1e6).check("backgrounds.len()", self.backgrounds.len() as f64)?;
        Bounds::closed(1.0, 1e6).check("tissues.len()", self.tissues.len() as f64)?;
        Bounds::closed(1.0, 1e6).check("background_seeds", f64::from(self.background_seeds))?;
        Bounds::closed(1.0, 1e6).check("block", f64::from(self.block))?;
        check_interval(
            "illumination_gain",
            self.illumination_gain,
            Bounds::closed(0.05, 5.0),
        )?;
        check_interval("noise_std", self.noise_std, Bounds::closed(0.0, 1.0))?;
        Bounds::closed(0.0, 1.0).check("blur_share", self.blur_share)?;
        check_interval("blur_px", self.blur_px, Bounds::closed(0.0, 20.0))?;
        Bounds::closed(1.0, 1000.0).check("max_attempts", f64::from(self.max_attempts))?;
        self.tolerances.validate()?;
        Segmenter::new(self.segment)?;
        Ok(())
    }

    fn setup(&self) -> Result<Setup> {
        self.validate()?;
        let camera = Camera::default();
        let instrument = Instrument::kflex();
        let regions = WorkingRegions::for_workspace(
            &camera,
            &instrument,
            &self.poses,
            &kflex_model::Banding::default(),
        )?;
        let theta = Axis::new(self.poses.theta_deg, self.theta_step_deg);
        let translation = Axis::new(self.poses.translation_mm, self.translation_step_mm);
        for band in regions.bands() {
            let (t_lo, t_hi) = theta.within(band.poses.theta_deg);
            let (d_lo, d_hi) = translation.within(band.poses.translation_mm);
            let cells = (t_hi - t_lo + 1).max(0) * (d_hi - d_lo + 1).max(0);
            if cells < 2 {
                return Err(ControlError::NotEnoughData {
                    metric: "image pairs",
                    needed: "at least two grid cells in every band (a wider pose range or a finer grid)",
                    got: cells.max(0) as usize,
                });
            }
        }
        let small = regions
            .bands()
            .iter()
            .map(|b| {
                Ok(camera.with_intrinsics(b.roi.intrinsics(&camera.intrinsics, SIDE, SIDE)?))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Setup {
            camera,
            instrument,
            regions,
            small,
            theta,
            translation,
        })
    }

    fn worker(&self) -> Result<Worker> {
        Ok(Worker {
            renderers: HashMap::new(),
            segmenter: Segmenter::new(self.segment)?,
            raster: Rasterizer::new(),
            mask: Mask::new(SIDE, SIDE)?,
            shape: InstrumentShape::default(),
        })
    }

    /// Makes D^I over `threads` worker threads (0: every core), in blocks
    /// of queries. Deterministic in the configuration, whatever `threads`.
    ///
    /// # Examples
    /// ```
    /// use kflex_control::ImagePairsConfig;
    /// let pairs = ImagePairsConfig { pairs: 8, block: 2, ..ImagePairsConfig::default() }.generate(0)?;
    /// assert_eq!(pairs.s, [1, 0, 1, 0, 1, 0, 1, 0]);
    /// assert_eq!(pairs.x_b.len(), 8 * 48 * 48);
    /// // a positive's reference is the query's grid cell
    /// assert!((pairs.theta_b_deg[0] - pairs.theta_r_deg[0]).abs() <= 0.5);
    /// # Ok::<(), kflex_control::ControlError>(())
    /// ```
    ///
    /// # Errors
    /// As [`ImagePairsConfig::validate`] and [`WorkingRegions::for_workspace`]
    /// (for `poses`), before any frame is made; [`ControlError::Estimate`]
    /// when the segmentation finds no instrument in `max_attempts` frames
    /// of each of `max_attempts` poses; [`ControlError::Model`] for a
    /// rendering error.
    pub fn generate(&self, threads: usize) -> Result<ImagePairs> {
        let setup = self.setup()?;
        let queries = self.pairs / 2;
        let block = self.block as usize;
        let blocks = queries.div_ceil(block);
        let results = parallel(
            blocks,
            threads,
            || self.worker(),
            |b, worker| {
                let bg = self.block_background(b as u64);
                (b * block..((b + 1) * block).min(queries))
                    .map(|q| self.query(&setup, worker, &bg, q as u64))
                    .collect::<Result<Vec<_>>>()
            },
        )?;
        Ok(self.assemble(&setup, results.into_iter().flatten().collect()))
    }

    /// The background of block `b`: kind, tissue, texture seed.
    fn block_background(&self, b: u64) -> (Background, Tissue, u64) {
        let mut rng = stream(self.seed, TAG_BLOCK, b);
        let kind = self.backgrounds[rng.random_range(0..self.backgrounds.len())];
        let tissue = self.tissues[rng.random_range(0..self.tissues.len())];
        let seed = rng.random_range(0..u64::from(self.background_seeds));
        (kind, tissue, seed)
    }

    /// Query `q`: its frame, segmented, and its two references.
    fn query(
        &self,
        setup: &Setup,
        w: &mut Worker,
        &(background, tissue, bg_seed): &(Background, Tissue, u64),
        q: u64,
    ) -> Result<QueryPairs> {
        let mut rng = stream(self.seed, TAG_QUERY, q);
        let mut failures = 0;
        let mut last_error = None;
        for _ in 0..self.max_attempts {
            let theta = uniform(&mut rng, self.poses.theta_deg);
            let d = uniform(&mut rng, self.poses.translation_mm);
            let band = setup.regions.at(theta, d)?;
            let band_index = setup
                .regions
                .bands()
                .iter()
                .position(|b| std::ptr::eq(b, band))
                .unwrap_or(0);
            let roi = band.roi;
            for _ in 0..self.max_attempts {
                let built_seed: u64 = rng.random();
                let built = self.tolerances.instrument(&setup.instrument, built_seed)?;
                let camera = self.tolerances.camera(&setup.camera, built_seed)?;
                let blurred = rng.random_bool(self.blur_share);
                let params = FrameParams {
                    background,
                    tissue,
                    seed: bg_seed,
                    frame: q,
                    illumination_gain: uniform(&mut rng, self.illumination_gain),
                    noise_std: uniform(&mut rng, self.noise_std),
                    blur_px: if blurred {
                        uniform(&mut rng, self.blur_px)
                    } else {
                        0.0
                    },
                    occlusion: None,
                };
                built.shape_into(theta, d, &mut w.shape)?;
                let renderer = w
                    .renderers
                    .entry((background, tissue, bg_seed))
                    .or_default();
                let frame = renderer.render_window(&camera, &w.shape, &params, roi)?;
                let whole = Roi::whole(roi.width, roi.height);
                match w
                    .segmenter
                    .segment(&frame.rgb, roi.width, roi.height, whole)
                {
                    Ok(seg) => {
                        let x_b = seg.small.data().to_vec();
                        let (x_r, pose_r, hard) =
                            self.references(setup, w, &mut rng, band_index, [theta, d])?;
                        return Ok(QueryPairs {
                            x_b,
                            x_r,
                            hard,
                            band: band_index as u32,
                            pose_b: [theta, d],
                            pose_r,
                            failures,
                        });
                    }
                    Err(e @ EstimateError::NoInstrument { .. }) => {
                        failures += 1;
                        last_error = Some(e);
                    }
                    Err(e) => return Err(e.into()),
                }
            }
        }
        Err(last_error.map_or(
            ControlError::Worker {
                message: "no frame drawn".to_owned(),
            },
            ControlError::from,
        ))
    }

    /// The positive and negative references of a query at `(θ, d)` in band
    /// `band`: their silhouettes, their poses, and whether the negative is hard.
    fn references(
        &self,
        setup: &Setup,
        w: &mut Worker,
        rng: &mut ChaCha8Rng,
        band: usize,
        [theta, d]: [f64; 2],
    ) -> Result<References> {
        let poses = setup.regions.bands()[band].poses;
        let (kt, kd) = (setup.theta.nearest(theta), setup.translation.nearest(d));
        let (t_lo, t_hi) = setup.theta.within(poses.theta_deg);
        let (d_lo, d_hi) = setup.translation.within(poses.translation_mm);
        let step = self.theta_step_deg;
        let (h_lo, h_hi) = (
            (self.hard_offset_deg[0] / step).round().max(1.0) as i64,
            (self.hard_offset_deg[1] / step).round().max(1.0) as i64,
        );
        let mut hard = None;
        if rng.random_bool(self.hard_share) {
            let off = rng.random_range(h_lo..=h_hi.max(h_lo));
            let sign = if rng.random_bool(0.5) { 1 } else { -1 };
            hard = [kt + sign * off, kt - sign * off]
                .into_iter()
                .find(|k| (t_lo..=t_hi).contains(k));
        }
        let negative = match hard {
            Some(k) => (k, kd),
            None => loop {
                // the band's other cells (`setup` checked it has several)
                let cell = (
                    rng.random_range(t_lo..=t_hi.max(t_lo)),
                    rng.random_range(d_lo..=d_hi.max(d_lo)),
                );
                if cell != (kt, kd) {
                    break cell;
                }
            },
        };
        let mut x_r = [Vec::new(), Vec::new()];
        let mut pose_r = [[0.0; 2]; 2];
        for (i, (k_theta, k_d)) in [(kt, kd), negative].into_iter().enumerate() {
            let pose = [setup.theta.at(k_theta), setup.translation.at(k_d)];
            setup
                .instrument
                .shape_into(pose[0], pose[1], &mut w.shape)?;
            w.mask.clear();
            w.raster
                .silhouette(&setup.small[band], &w.shape, &mut w.mask)?;
            x_r[i] = w.mask.data().to_vec();
            pose_r[i] = pose;
        }
        Ok((x_r, pose_r, hard.is_some()))
    }

    fn assemble(&self, setup: &Setup, queries: Vec<QueryPairs>) -> ImagePairs {
        let n = 2 * queries.len();
        let mut out = ImagePairs {
            x_b: Vec::with_capacity(n * PIXELS),
            x_r: Vec::with_capacity(n * PIXELS),
            s: Vec::with_capacity(n),
            hard: Vec::with_capacity(n),
            query: Vec::with_capacity(n),
            band: Vec::with_capacity(n),
            theta_b_deg: Vec::with_capacity(n),
            translation_b_mm: Vec::with_capacity(n),
            theta_r_deg: Vec::with_capacity(n),
            translation_r_mm: Vec::with_capacity(n),
            card: DatasetCard::new(
                "image_pairs",
                "kflex_control::ImagePairsConfig::generate",
                IMAGE_GENERATOR_VERSION,
                self.seed,
                self.clone(),
            ),
        };
        let mut failures = 0u64;
        let mut hard = 0u64;
        for (q, p) in queries.into_iter().enumerate() {
            failures += u64::from(p.failures);
            hard += u64::from(p.hard);
            for i in 0..2 {
                out.x_b.extend_from_slice(&p.x_b);
                out.x_r.extend_from_slice(&p.x_r[i]);
                out.s.push(u8::from(i == 0));
                out.hard.push(u8::from(i == 1 && p.hard));
                out.query.push(q as u32);
                out.band.push(p.band);
                out.theta_b_deg.push(p.pose_b[0]);
                out.translation_b_mm.push(p.pose_b[1]);
                out.theta_r_deg.push(p.pose_r[i][0]);
                out.translation_r_mm.push(p.pose_r[i][1]);
            }
        }
        let card = &mut out.card;
        for name in ["x_b", "x_r"] {
            card.sizes
                .insert(name.to_owned(), vec![n, SIDE as usize, SIDE as usize]);
        }
        for name in [
            "s",
            "hard",
            "query",
            "band",
            "theta_b_deg",
            "translation_b_mm",
            "theta_r_deg",
            "translation_r_mm",
        ] {
            card.sizes.insert(name.to_owned(), vec![n]);
        }
        card.range("theta_b_deg", out.theta_b_deg.iter().copied());
        card.range("translation_b_mm", out.translation_b_mm.iter().copied());
        card.range("theta_r_deg", out.theta_r_deg.iter().copied());
        card.range("translation_r_mm", out.translation_r_mm.iter().copied());
        let stats = &mut card.stats;
        stats.insert("queries".to_owned(), (n / 2) as f64);
        stats.insert("positives".to_owned(), (n / 2) as f64);
        stats.insert("negatives".to_owned(), (n / 2) as f64);
        stats.insert("hard_negatives".to_owned(), hard as f64);
        stats.insert("segmentation_failures_redrawn".to_owned(), failures as f64);
        stats.insert("bands".to_owned(), setup.regions.bands().len() as f64);
        out
    }

    /// The nominal silhouette database IBJAE retrieves from: for each band
    /// of the working regions, every grid pose inside the band's poses
    /// (θ every `theta_step_deg`, d every `translation_step_mm`), silhouetted
    /// from the nominal model in the band's region at 48 × 48, as the
    /// references x^r of [`ImagePairsConfig::generate`]. A pose in two
    /// bands (they overlap) is in both bands' databases.
    ///
    /// # Errors
    /// As [`ImagePairsConfig::validate`] and [`WorkingRegions::for_workspace`].
    pub fn database(&self, threads: usize) -> Result<ImageDatabase> {
        let setup = self.setup()?;
        let bands = setup.regions.bands().len();
        let per_band = parallel(
            bands,
            threads,
            || self.worker(),
            |b, w| {
                let poses = setup.regions.bands()[b].poses;
                let (t_lo, t_hi) = setup.theta.within(poses.theta_deg);
                let (d_lo, d_hi) = setup.translation.within(poses.translation_mm);
                let mut entries = Vec::new();
                for kd in d_lo..=d_hi {
                    for kt in t_lo..=t_hi {
                        let pose = [setup.theta.at(kt), setup.translation.at(kd)];
                        setup
                            .instrument
                            .shape_into(pose[0], pose[1], &mut w.shape)?;
                        w.mask.clear();
                        w.raster
                            .silhouette(&setup.small[b], &w.shape, &mut w.mask)?;
                        entries.push((pose, w.mask.data().to_vec()));
                    }
                }
                Ok(entries)
            },
        )?;
        let mut db = ImageDatabase {
            masks: Vec::new(),
            theta_deg: Vec::new(),
            translation_mm: Vec::new(),
            band: Vec::new(),
            card: DatasetCard::new(
                "image_database",
                "kflex_control::ImagePairsConfig::database",
                IMAGE_GENERATOR_VERSION,
                self.seed,
                self.clone(),
            ),
        };
        for (b, entries) in per_band.into_iter().enumerate() {
            for ([theta, d], mask) in entries {
                db.masks.extend_from_slice(&mask);
                db.theta_deg.push(theta);
                db.translation_mm.push(d);
                db.band.push(b as u32);
            }
        }
        let n = db.theta_deg.len();
        let card = &mut db.card;
        card.sizes
            .insert("masks".to_owned(), vec![n, SIDE as usize, SIDE as usize]);
        for name in ["theta_deg", "translation_mm", "band"] {
            card.sizes.insert(name.to_owned(), vec![n]);
        }
        card.range("theta_deg", db.theta_deg.iter().copied());
        card.range("translation_mm", db.translation_mm.iter().copied());
        card.stats.insert("bands".to_owned(), bands as f64);
        Ok(db)
    }
}
