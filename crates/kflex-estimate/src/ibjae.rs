//! IBJAE: image-based joint angle estimation (the paper's Section II-C-1):
//! segment the frame in the working region, embed the 48×48 silhouette with
//! the SCNN, and read the pose of the nearest rendered silhouette (cargo
//! features `onnx` and `index`).
//!
//! **Databases, one per working band.** Over the full pose range one region
//! cannot resolve 1° at every translation, so the camera's range is cut
//! into bands ([`kflex_model::WorkingRegions`]), each with its own region;
//! [`build_band_database`] renders the nominal instrument's silhouettes over
//! a (θ, d) grid of one band, through the same camera, lens and region as the
//! frames, embeds them and indexes them. The file records the SCNN's SHA-256,
//! the region and the grid; [`Ibjae::new`] refuses a database built with
//! another model.
//!
//! **Confidence.** Each reading carries `sigma_deg`: its distance to the
//! nearest silhouette expressed in degrees of bend, using how far apart the
//! database's own neighbouring bends lie in feature space (the median over
//! the grid of distance per degree, measured at build time). A frame that
//! matches nothing well (the tip hidden, a wrong segmentation) reads as
//! uncertain; [`crate::AdaptiveKalman`] takes it as the camera's noise.
//!
//! **Silhouette check** ([`Ibjae::with_silhouette_check`]). The feature
//! distance alone does not flag tape: measured with a trained SCNN (not
//! shipped; `training/README.md`, "A first trial") on frames at d = 10 mm,
//! θ 0–50°, tape over 20 %, 40 % and 40 % of the instrument at its tip
//! biased the reading by +5.9, +12.3 and −12.8° on average while its
//! uncertainty stayed at a median of 0.6, 1.3 and 2.6°. With the check,
//! IBJAE renders the nominal silhouette of the pose it read through the same
//! region and compares it with the segmented one: the reading must explain
//! the pixels it was read from. On the same frames (as-built instrument and
//! camera) their IoU is 0.904–0.993 (median 0.980) without tape, 0.73–0.78,
//! 0.51–0.56 and 0.58–0.73 with it. A reading under
//! [`DEFAULT_MIN_SILHOUETTE_IOU`] (0.85, between the two) that no pose with
//! a hidden part explains either (below) reports an uncertainty of at least
//! [`UNEXPLAINED_SIGMA_DEG`]; its angle is still the nearest silhouette's
//! (IBJAE alone still reads it, as the paper's does;
//! [`crate::AdaptiveKalman`] rejects it, the paper's filter does not look at
//! uncertainties).
//!
//! **Hidden parts** (with the check). An occluder hides instrument pixels;
//! it never adds any. So where the retrieved pose does not explain the
//! silhouette, IBJAE looks for the poses of the band's grid that explain
//! every segmented pixel, taking the instrument pixels missing from the
//! silhouette as hidden: each grid pose's nominal silhouette (rendered once
//! per band, when the band first needs it, into room reserved up front)
//! leaves `u` segmented pixels unexplained; the poses within
//! [`HIDDEN_TOLERANCE_PX`] (or a quarter) of the fewest are consistent with
//! what is visible. If the fewest are at most [`MAX_UNEXPLAINED_SHARE`] of
//! the silhouette (an occlusion, not a wrong segmentation) and the
//! consistent poses' bends lie within ±[`HIDDEN_SIGMA_DEG`] of their middle
//! (the visible part pins the bend), the reading becomes the consistent pose
//! that leaves the fewest pixels unexplained (of those, the one that adds
//! the fewest hidden), with `occluded` set, `sigma_deg` of
//! [`HIDDEN_SIGMA_DEG`] (at least half the grid's step) and the consistent
//! bends in `consistent_deg`; else the retrieved reading stands,
//! unexplained. Where that pose's own IoU reaches the least, nothing is
//! hidden (the retrieval missed): the reading is an explained one, its
//! uncertainty from its feature distance. A grid pose that cannot be
//! rendered (an instrument narrower in range than the grid) is never
//! consistent. The first frame that needs a band renders its grid: about
//! 30 µs a pose, 6–18 ms for the full range's bands of 202–606 poses
//! ([`Ibjae::prepare_hidden_parts`] renders them all up front, for a
//! controller that cannot spend that in one tick).
//!
//! Measured on as-built frames (d = 10 mm, θ 0–50°, three backgrounds, the
//! working region's band of a trial database): the consistent pose errs by
//! 2.59° RMSE with or without tape over the middle 20 or 40 % of the
//! instrument (consistent bends spread over 6–19°); tape over the distal 20
//! or 40 % hides the whole bend and gripper in the region, and every bend
//! of the band stays consistent (no image estimator can read the bend
//! there). On the paper's estimation grid with trial models (not shipped;
//! `kflex-cli run --scenario assets/scenarios/table_v.toml --models DIR`,
//! three repeats), IBJAE alone reads 1.39 / 5.80 / 10.58° at 0° under no
//! tape / the middle 20 / 40 % (was 1.40 / 22.57 / 33.12° reading the
//! retrieved pose) and 8.01° under the middle 40 % at 270° (Table VII; was
//! 24.27°); the paper's filter 1.40 / 1.65 / 2.38 and 11.07° (was 1.40 /
//! 1.44 / 2.56 and 12.86°). [`crate::AdaptiveKalman`] rejects such readings
//! (see its docs) and reads as before. Accepting readings whose consistent
//! bends spread wider (±9°) made clear frames worse (IBJAE alone 2.25°
//! where a reading just under the least IoU found a wide, wrongly centred
//! consistent set); keeping the retrieved pose where it is itself
//! consistent made taped frames worse (6.58 / 8.66°).

use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, PoisonError};

use kflex_model::{Camera, Instrument, InstrumentShape, Mask, Rasterizer, Roi, WorkingBand};

use crate::error::{EstimateError, Result};
use crate::index::{FeatureIndex, IndexParams, Pose};
use crate::scnn::{BITS_WORDS, Bits, EMBEDDING_DIM, SCNN_SIDE, Scnn, bits_of};
use crate::segment::{SegmentParams, Segmenter};

/// Metadata keys a band database carries.
pub mod keys {
    /// SHA-256 of the SCNN that embedded the database.
    pub const SCNN_SHA256: &str = "scnn_sha256";
    /// The region the silhouettes were rendered in: `x0,y0,width,height`, px.
    pub const ROI: &str = "roi";
    /// The band's poses: `theta_min,theta_max,d_min,d_max` (deg, mm).
    pub const BAND: &str = "band";
    /// The grid's steps: `theta_step_deg,translation_step_mm`.
    pub const GRID: &str = "grid";
    /// The camera the silhouettes were rendered through (intrinsics, lens
    /// and mounting), as text (`load_databases` compares it).
    pub const CAMERA: &str = "camera";
    /// Median feature distance between silhouettes one degree of bend apart.
    pub const DISTANCE_PER_DEG: &str = "distance_per_deg";
}

/// A borrowed RGB frame (8 bits per channel), rows `stride` bytes apart:
/// the camera's whole image, or a window of it ([`RgbView::window`]).
#[derive(Debug, Clone, Copy)]
pub struct RgbView<'a> {
    data: &'a [u8],
    width: u32,
    height: u32,
    stride: usize,
    /// Where the view's first pixel lies in the camera's image.
    x0: u32,
    y0: u32,
}

impl<'a> RgbView<'a> {
    /// A view of `width × height` pixels whose rows start `stride` bytes
    /// apart (`stride ≥ 3·width`; the last row need not be padded).
    ///
    /// # Errors
    /// [`EstimateError::ImageSize`] when `data` is too short for the rows, or
    /// the stride is shorter than a row.
    pub fn new(data: &'a [u8], width: u32, height: u32, stride: usize) -> Result<Self> {
        let row = 3 * width as usize;
        // in checked arithmetic: a huge stride or size is refused, not wrapped
        let needed = if height == 0 {
            Some(0)
        } else {
            stride
                .checked_mul(height as usize - 1)
                .and_then(|n| n.checked_add(row))
        };
        let fits = needed.is_some_and(|n| data.len() >= n);
        if stride < row || !fits || width == 0 || height == 0 {
            return Err(EstimateError::ImageSize {
                width,
                height,
                expected: needed
                    .unwrap_or(usize::MAX)
                    .max(row.saturating_mul(height as usize)),
                got: data.len(),
            });
        }
        Ok(Self {
            data,
            width,
            height,
            stride,
            x0: 0,
            y0: 0,
        })
    }

    /// A view of the pixels of `window` of the camera's image only (as
    /// `SceneRenderer::render_window` renders them), rows `stride` bytes
    /// apart: regions are read in the camera's coordinates, and one outside
    /// the window is an error.
    ///
    /// # Errors
    /// As [`RgbView::new`] with the window's width and height.
    pub fn window(data: &'a [u8], window: Roi, stride: usize) -> Result<Self> {
        Ok(Self {
            x0: window.x0,
            y0: window.y0,
            ..Self::new(data, window.width, window.height, stride)?
        })
    }

    /// A tightly packed frame (`stride = 3·width`).
    ///
    /// # Errors
    /// As [`RgbView::new`].
    pub fn packed(data: &'a [u8], width: u32, height: u32) -> Result<Self> {
        Self::new(data, width, height, 3 * width as usize)
    }

    /// Copies `roi` (camera coordinates) into `out` as a packed RGB image.
    fn crop_into(&self, roi: Roi, out: &mut Vec<u8>) -> Result<()> {
        // the region in the view's own pixels; its right and bottom edges
        // are checked there, against the view's size
        let at_least = |name, v: u32, lo: u32| {
            kflex_model::Bounds::closed(f64::from(lo), f64::from(u32::MAX))
                .check(name, f64::from(v))
        };
        at_least("roi.x0", roi.x0, self.x0)?;
        at_least("roi.y0", roi.y0, self.y0)?;
        let roi = Roi {
            x0: roi.x0 - self.x0,
            y0: roi.y0 - self.y0,
            ..roi
        };
        roi.check_within(self.width, self.height)?;
        out.clear();
        let row = 3 * roi.width as usize;
        for y in roi.y0..roi.y0 + roi.height {
            let start = y as usize * self.stride + 3 * roi.x0 as usize;
            out.extend_from_slice(&self.data[start..start + row]);
        }
        Ok(())
    }
}

/// What IBJAE read from one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IbjaeReading {
    /// Bend of the database pose read (the nearest silhouette's, or with
    /// `occluded` the one that explains the visible pixels), deg.
    pub theta_deg: f64,
    /// Translation of that pose, mm.
    pub translation_mm: f64,
    /// Feature distance to it (L2, SCNN units).
    pub distance: f64,
    /// The reading's uncertainty, deg: the distance in degrees of bend, at
    /// least half the grid's step; at least [`UNEXPLAINED_SIGMA_DEG`] where
    /// the silhouette check finds it unexplained, [`HIDDEN_SIGMA_DEG`] with
    /// `occluded` (see the module docs).
    pub sigma_deg: f64,
    /// Which database answered (its position in [`Ibjae::new`]'s list).
    pub band: usize,
    /// With [`Ibjae::with_silhouette_check`]: the IoU between the segmented
    /// 48×48 silhouette and the nominal silhouette of the pose read.
    pub silhouette_iou: Option<f64>,
    /// Whether the pose read takes part of the instrument as hidden: the
    /// retrieved pose did not explain the silhouette, and this one explains
    /// its pixels with the rest occluded (see "Hidden parts" in the module
    /// docs). `distance` is then the feature distance to this pose.
    pub occluded: bool,
    /// With `occluded`: the lowest and highest bend of the grid poses that
    /// explain the visible pixels as well, deg (what the visible part says
    /// of the bend).
    pub consistent_deg: Option<[f64; 2]>,
}

/// The least IoU between a reading's segmented silhouette and the nominal
/// silhouette of the pose it reads for the reading to count as explained
/// (see the module docs: 0.904 at worst on clear as-built frames, 0.78 at
/// best under tape).
pub const DEFAULT_MIN_SILHOUETTE_IOU: f64 = 0.85;

/// The uncertainty an unexplained reading reports at least, deg: a quarter
/// of the bend's range, i.e. the reading says little about where the joint is.
pub const UNEXPLAINED_SIGMA_DEG: f64 = 45.0;

/// How many more unexplained pixels (of 48×48) than the fewest a grid pose
/// may leave and still count as consistent with the visible pixels (or a
/// quarter of the fewest, where more): the segmentation's rim and the
/// as-built instrument's own difference from the nominal (see "Hidden parts"
/// in the module docs).
pub const HIDDEN_TOLERANCE_PX: u32 = 3;

/// The uncertainty of a reading with a hidden part, deg (at least half the
/// grid's step), and the most that half the spread of the bends as
/// consistent with its visible pixels may be for one to be taken (see
/// "Hidden parts" in the module docs): such readings err by about this much
/// in the paper's estimation runs, more than the spread says, and a wider
/// spread leaves the bend too open.
pub const HIDDEN_SIGMA_DEG: f64 = 5.0;

/// The largest share of the silhouette's pixels the best grid pose may
/// leave unexplained for the rest of the instrument to be taken as hidden:
/// beyond it the silhouette holds what no pose explains (a wrong
/// segmentation), and the retrieved reading stands, unexplained. Measured
/// as-built and under tape: at most 33 of 250–700 pixels (about 5 %).
pub const MAX_UNEXPLAINED_SHARE: f64 = 0.1;

/// [`Mask::iou`] of two 48×48 masks held as bits: 1 where both are empty.
fn bits_iou(a: &Bits, b: &Bits) -> f64 {
    let count = |f: &dyn Fn(usize) -> u64| (0..BITS_WORDS).map(|w| f(w).count_ones()).sum::<u32>();
    let union = count(&|w| a[w] | b[w]);
    if union == 0 {
        1.0
    } else {
        f64::from(count(&|w| a[w] & b[w])) / f64::from(union)
    }
}

/// The nominal 48×48 silhouettes of every band's grid of poses (the
/// database's order), which the silhouette check's hidden-part search
/// compares a taped frame with (see "Hidden parts" in the module docs).
/// A band's are rendered the first time a reader needs them, into room
/// reserved up front (so that a read allocates nothing), once for every
/// reader sharing them: the estimators a model directory makes share one
/// per camera ([`Ibjae::with_shared_silhouette_check`]).
#[derive(Debug)]
pub struct HiddenPartGrids {
    camera: Camera,
    instrument: Instrument,
    /// The databases whose grids these are.
    bands: Arc<[BandDatabase]>,
    /// Per band, the silhouettes rendered so far.
    grid: Box<[Mutex<Vec<Bits>>]>,
}

impl HiddenPartGrids {
    /// Room for the grids of `bands`, rendered through `camera` (the one
    /// the databases were rendered through) of the nominal `instrument`.
    ///
    /// # Errors
    /// As [`Camera::validate`] for a bad camera;
    /// [`EstimateError::ModelMismatch`] naming both cameras when a database
    /// was rendered through another camera.
    pub fn new(
        camera: &Camera,
        instrument: &Instrument,
        bands: Arc<[BandDatabase]>,
    ) -> Result<Arc<Self>> {
        camera.validate()?;
        let expected = camera_key(camera);
        for b in bands.iter() {
            check_camera(&b.index, &expected, "feature database")?;
        }
        let grid = bands
            .iter()
            .map(|b| Mutex::new(Vec::with_capacity(b.index.len())))
            .collect();
        Ok(Arc::new(Self {
            camera: *camera,
            instrument: *instrument,
            bands,
            grid,
        }))
    }

    /// Band `b`'s silhouettes (as many as rendered so far), locked.
    fn band(&self, b: usize) -> Option<std::sync::MutexGuard<'_, Vec<Bits>>> {
        self.grid
            .get(b)
            .map(|g| g.lock().unwrap_or_else(PoisonError::into_inner))
    }

    /// [`HiddenPartGrids::band`] where no other reader holds it now
    /// (`None` then), without waiting.
    fn try_band(&self, b: usize) -> Option<std::sync::MutexGuard<'_, Vec<Bits>>> {
        match self.grid.get(b)?.try_lock() {
            Ok(g) => Some(g),
            Err(std::sync::TryLockError::Poisoned(p)) => Some(p.into_inner()),
            Err(std::sync::TryLockError::WouldBlock) => None,
        }
    }

    /// Entry `e` of band `b`'s silhouettes where it is rendered and no
    /// other reader holds the band now (`None` then: the caller renders
    /// it), without waiting.
    fn try_entry(&self, b: usize, e: usize) -> Option<Bits> {
        self.try_band(b)?.get(e).copied()
    }

    /// Whether every band's silhouettes are rendered (a band another
    /// reader is rendering or searching now counts as not ready, without
    /// waiting for it).
    fn ready(&self) -> bool {
        self.bands
            .iter()
            .enumerate()
            .all(|(b, db)| self.try_band(b).is_some_and(|g| g.len() >= db.index.len()))
    }
}

/// What [`Ibjae::with_silhouette_check`] needs: the nominal camera and
/// instrument the databases were rendered from (the grids'), the least IoU
/// that explains a frame, buffers, and the grids of the hidden-part search.
#[derive(Debug)]
struct SilhouetteCheck {
    min_iou: f64,
    raster: Rasterizer,
    shape: InstrumentShape,
    mask: Mask,
    grids: Arc<HiddenPartGrids>,
}

impl SilhouetteCheck {
    /// The nominal 48×48 silhouette of `pose` through `roi`, into `self.mask`.
    fn render(&mut self, roi: Roi, pose: Pose) -> Result<()> {
        let small = silhouette_camera(&self.grids.camera, roi)?;
        self.grids
            .instrument
            .shape_into(pose.theta_deg, pose.translation_mm, &mut self.shape)?;
        self.mask.clear();
        self.raster
            .silhouette(&small, &self.shape, &mut self.mask)?;
        Ok(())
    }

    /// The IoU ([`Mask::iou`]) of the 48×48 silhouette `seen` with the
    /// nominal silhouette of entry `e` of band `b` (database `db`), at
    /// `pose`: read from the band's grid where it is rendered there (the same
    /// render, as bits), else rendered now.
    fn iou_with_entry(
        &mut self,
        b: usize,
        db: &BandDatabase,
        (e, pose): (usize, Pose),
        seen: &Mask,
    ) -> Result<f64> {
        let side = (seen.width(), seen.height()) == (SCNN_SIDE, SCNN_SIDE);
        // a pose the grid could not render is all zeros there: render it
        // here, for its error
        if let Some(n) = self
            .grids
            .try_entry(b, e)
            .filter(|n| side && *n != [0; BITS_WORDS])
        {
            return Ok(bits_iou(&bits_of(seen), &n));
        }
        self.render(db.band.roi, pose)?;
        Ok(seen.iou(&self.mask)?)
    }

    /// Renders the nominal silhouettes of band `b`'s grid (database `db`)
    /// that are not rendered yet, into the room reserved for them (a reader
    /// sharing the grids and rendering the band meanwhile is waited for).
    fn fill(&mut self, b: usize, db: &BandDatabase) {
        let grids = Arc::clone(&self.grids);
        let Some(mut grid) = grids.band(b) else {
            return;
        };
        let poses = db.index.poses();
        if grid.len() < poses.len() {
            for &pose in &poses[grid.len()..] {
                // a pose the instrument cannot take explains nothing
                let bits = match self.render(db.band.roi, pose) {
                    Ok(()) => bits_of(&self.mask),
                    Err(_) => [0; BITS_WORDS],
                };
                grid.push(bits);
            }
        }
    }

    /// The pose of band `b` (database `db`) that explains the segmented
    /// silhouette `seen` with the rest of the instrument hidden: its entry,
    /// the lowest and highest bends of the poses as consistent (see "Hidden
    /// parts" in the module docs), and its IoU with `seen` (as
    /// [`Mask::iou`] gives it); `None` where no pose explains it.
    fn hidden(
        &mut self,
        b: usize,
        db: &BandDatabase,
        seen: &Mask,
    ) -> Result<Option<(usize, [f64; 2], f64)>> {
        let poses = db.index.poses();
        self.fill(b, db);
        let grids = Arc::clone(&self.grids);
        let Some(grid) = grids.band(b) else {
            return Ok(None);
        };
        let s = bits_of(seen);
        let count =
            |f: &dyn Fn(usize) -> u64| (0..BITS_WORDS).map(|w| f(w).count_ones()).sum::<u32>();
        let unexplained = |n: &Bits| count(&|w| s[w] & !n[w]);
        let Some(fewest) = grid.iter().map(unexplained).min() else {
            return Ok(None);
        };
        let visible = count(&|w| s[w]);
        if f64::from(fewest) > MAX_UNEXPLAINED_SHARE * f64::from(visible) {
            return Ok(None);
        }
        let within = fewest + HIDDEN_TOLERANCE_PX.max(fewest / 4);
        let (mut best, mut lo, mut hi) = (None, f64::INFINITY, f64::NEG_INFINITY);
        for (e, (n, pose)) in grid.iter().zip(poses).enumerate() {
            let u = unexplained(n);
            if u > within {
                continue;
            }
            let hidden = count(&|w| n[w] & !s[w]);
            if best.is_none_or(|(bu, bh, _)| (u, hidden) < (bu, bh)) {
                best = Some((u, hidden, e));
            }
            lo = lo.min(pose.theta_deg);
            hi = hi.max(pose.theta_deg);
        }
        Ok(best.map(|(_, _, e)| (e, [lo, hi], bits_iou(&s, &grid[e]))))
    }
}

/// One working band's feature database.
#[derive(Debug)]
pub struct BandDatabase {
    /// The band (poses and region).
    pub band: WorkingBand,
    /// The SCNN embeddings of its grid, labelled with their poses.
    pub index: FeatureIndex,
    distance_per_deg: f64,
    theta_step_deg: f64,
}

impl BandDatabase {
    /// A hash of the band, its calibration, its metadata, every feature and
    /// every pose: what tells two readers' databases apart
    /// ([`Ibjae::read_sharing`]). Four lanes over the features' bits, two to
    /// a word: about 2 ms for the full range's 28 bands.
    fn content_hash(&self) -> u64 {
        let mut about = std::hash::DefaultHasher::new();
        format!(
            "{:?} {:?} {:?}",
            self.band, self.distance_per_deg, self.theta_step_deg
        )
        .hash(&mut about);
        self.index.metadata().hash(&mut about);
        let mut h = LaneHash::new();
        h.word(about.finish());
        let features = self.index.features();
        h.word(features.len() as u64);
        h.slice::<_, 2>(features, |p| {
            let lo = p.first().map_or(0, |f| u64::from(f.to_bits()));
            let hi = p.get(1).map_or(0, |f| u64::from(f.to_bits()));
            lo | (hi << 32)
        });
        for p in self.index.poses() {
            h.word(p.theta_deg.to_bits());
            h.word(p.translation_mm.to_bits());
        }
        h.finish()
    }

    /// Reads the band and calibration from an index's metadata (as
    /// [`build_band_database`] writes them, or a loaded file has them).
    ///
    /// # Errors
    /// [`EstimateError::ModelFile`] naming the metadata key that is missing,
    /// unreadable or out of its range (a region of whole, non-negative pixels;
    /// ranges whose lower end is not above their upper; positive grid steps
    /// and distance per degree).
    pub fn from_index(index: FeatureIndex) -> Result<Self> {
        let invalid = |key: &str, message: &str| EstimateError::ModelFile {
            path: format!("feature database metadata {key:?}"),
            message: message.into(),
        };
        let numbers = |key: &str, n: usize| -> Result<Vec<f64>> {
            let bad = || invalid(key, &format!("missing or not {n} comma-separated numbers"));
            let text = index.metadata().get(key).ok_or_else(bad)?;
            let v: Vec<f64> = text
                .split(',')
                .map(|s| s.trim().parse::<f64>())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| bad())?;
            if v.len() == n && v.iter().all(|x| x.is_finite()) {
                Ok(v)
            } else {
                Err(bad())
            }
        };
        let roi = numbers(keys::ROI, 4)?;
        // pixels: whole, not negative, a region of at least one pixel
        let side = f64::from(kflex_model::MAX_IMAGE_SIDE);
        if roi.iter().any(|&v| v < 0.0 || v.fract() != 0.0)
            || roi[2] < 1.0
            || roi[3] < 1.0
            || roi[0] + roi[2] > side
            || roi[1] + roi[3] > side
        {
            return Err(invalid(
                keys::ROI,
                &format!(
                    "not a region of whole pixels inside an image of at most {} px a side \
                     (x0, y0 ≥ 0; width, height ≥ 1)",
                    kflex_model::MAX_IMAGE_SIDE
                ),
            ));
        }
        let band = numbers(keys::BAND, 4)?;
        if band[0] > band[1] || band[2] > band[3] {
            return Err(invalid(
                keys::BAND,
                "a bend or translation range whose lower end is above its upper",
            ));
        }
        let grid = numbers(keys::GRID, 2)?;
        if grid.iter().any(|&v| v <= 0.0) {
            return Err(invalid(keys::GRID, "a grid step that is not positive"));
        }
        let per_deg = numbers(keys::DISTANCE_PER_DEG, 1)?[0];
        if per_deg <= 0.0 {
            return Err(invalid(keys::DISTANCE_PER_DEG, "not positive"));
        }
        Ok(Self {
            band: WorkingBand {
                poses: kflex_model::PoseRange {
                    theta_deg: [band[0], band[1]],
                    translation_mm: [band[2], band[3]],
                },
                roi: Roi {
                    x0: roi[0] as u32,
                    y0: roi[1] as u32,
                    width: roi[2] as u32,
                    height: roi[3] as u32,
                },
            },
            index,
            distance_per_deg: per_deg,
            theta_step_deg: grid[0],
        })
    }
}

/// The most poses a band's grid may hold ([`build_band_database`]): a band
/// of the full range at 0.1° and 0.1 mm holds some 25,000.
pub const MAX_BAND_POSES: usize = 200_000;

/// Renders, embeds and indexes the nominal instrument's silhouettes over one
/// band: θ from the band's lower to its upper bend every `theta_step_deg`,
/// d likewise every `translation_step_mm`, each a 48×48 silhouette of the
/// band's region as `camera` (with its lens) sees it.
///
/// # Errors
/// [`EstimateError::OutOfRange`] for steps outside `(0, 90]` deg and
/// `(0, 100]` mm, or so fine that the grid would hold more than
/// [`MAX_BAND_POSES`] poses; errors of the renderer, the SCNN and the index.
pub fn build_band_database(
    scnn: &mut Scnn,
    camera: &Camera,
    instrument: &Instrument,
    band: &WorkingBand,
    theta_step_deg: f64,
    translation_step_mm: f64,
) -> Result<BandDatabase> {
    kflex_model::Bounds::open_closed(0.0, 90.0).check("theta_step_deg", theta_step_deg)?;
    kflex_model::Bounds::open_closed(0.0, 100.0)
        .check("translation_step_mm", translation_step_mm)?;
    let [t0, t1] = band.poses.theta_deg;
    let [d0, d1] = band.poses.translation_mm;
    // counted in f64 first: a step far below the band's span would
    // otherwise ask for more poses than memory holds
    let steps = |lo: f64, hi: f64, step: f64| ((hi - lo) / step + 1e-9).floor() + 1.0;
    let (nt, nd) = (
        steps(t0, t1, theta_step_deg),
        steps(d0, d1, translation_step_mm),
    );
    kflex_model::Bounds::closed(1.0, MAX_BAND_POSES as f64).check(
        "poses in the band's grid (theta and translation steps)",
        nt * nd,
    )?;
    let (nt, nd) = (nt as usize, nd as usize);
    let small = silhouette_camera(camera, band.roi)?;
    let mut raster = Rasterizer::new();
    let mut poses = Vec::with_capacity(nt * nd);
    let mut masks = Vec::with_capacity(nt * nd);
    for j in 0..nd {
        let d = d0 + j as f64 * translation_step_mm;
        for i in 0..nt {
            let theta = t0 + i as f64 * theta_step_deg;
            let mut mask = Mask::new(SCNN_SIDE, SCNN_SIDE)?;
            raster.silhouette(&small, &instrument.shape(theta, d)?, &mut mask)?;
            masks.push(mask);
            poses.push(Pose {
                theta_deg: theta,
                translation_mm: d,
            });
        }
    }
    let mut features = Vec::with_capacity(masks.len() * EMBEDDING_DIM);
    for chunk in masks.chunks(256) {
        features.extend(scnn.embed_batch(chunk)?);
    }
    // how far apart neighbouring bends lie in feature space, per degree
    let mut per_deg: Vec<f64> = Vec::with_capacity(nt * nd);
    for j in 0..nd {
        for i in 1..nt {
            let (a, b) = (j * nt + i - 1, j * nt + i);
            let fa = &features[a * EMBEDDING_DIM..(a + 1) * EMBEDDING_DIM];
            let fb = &features[b * EMBEDDING_DIM..(b + 1) * EMBEDDING_DIM];
            let dist: f64 = fa
                .iter()
                .zip(fb)
                .map(|(x, y)| f64::from(x - y).powi(2))
                .sum::<f64>()
                .sqrt();
            per_deg.push(dist / theta_step_deg);
        }
    }
    per_deg.sort_by(f64::total_cmp);
    let median = per_deg
        .get(per_deg.len() / 2)
        .copied()
        .unwrap_or(1.0)
        .max(1e-12);
    let mut index = FeatureIndex::build(&features, EMBEDDING_DIM, &poses, IndexParams::default())?;
    let r = band.roi;
    index.set_metadata(keys::SCNN_SHA256, scnn.sha256());
    index.set_metadata(
        keys::ROI,
        format!("{},{},{},{}", r.x0, r.y0, r.width, r.height),
    );
    index.set_metadata(keys::BAND, format!("{t0},{t1},{d0},{d1}"));
    index.set_metadata(
        keys::GRID,
        format!("{theta_step_deg},{translation_step_mm}"),
    );
    index.set_metadata(keys::CAMERA, camera_key(camera));
    index.set_metadata(keys::DISTANCE_PER_DEG, format!("{median}"));
    BandDatabase::from_index(index)
}

/// `camera` seeing only `roi`, resampled to the SCNN's 48×48: how a band's
/// silhouettes are rendered, for its database and for IBJAE's silhouette check.
fn silhouette_camera(camera: &Camera, roi: Roi) -> Result<Camera> {
    Ok(camera.with_intrinsics(roi.intrinsics(&camera.intrinsics, SCNN_SIDE, SCNN_SIDE)?))
}

/// The camera as a database's metadata names it: every field, exactly
/// (Rust's debug text of an `f64` reads back to the same number).
pub(crate) fn camera_key(camera: &Camera) -> String {
    format!("{camera:?}")
}

/// Checks that the database `index` (named `path` in the error) was
/// rendered through the camera whose [`camera_key`] is `expected`.
pub(crate) fn check_camera(index: &FeatureIndex, expected: &str, path: &str) -> Result<()> {
    let found = index
        .metadata()
        .get(keys::CAMERA)
        .map_or("(none)", String::as_str);
    if found == expected {
        return Ok(());
    }
    Err(EstimateError::ModelMismatch {
        path: path.to_string(),
        which: "camera",
        expected: expected.to_string(),
        found: found.to_string(),
    })
}

/// IBJAE: segmentation, SCNN embedding and retrieval in one.
#[derive(Debug)]
pub struct Ibjae {
    scnn: Scnn,
    segmenter: Segmenter,
    /// The databases, shared with other readers of the same files
    /// ([`Ibjae::new_shared`]).
    bands: Arc<[BandDatabase]>,
    crop: Vec<u8>,
    embedding: [f32; EMBEDDING_DIM],
    check: Option<SilhouetteCheck>,
    /// What tells its readings apart from another reader's, once a shared
    /// read has needed it ([`Ibjae::read_sharing`]).
    fingerprint: Option<u64>,
}

/// IBJAE's readings of one frame, band by band, for several readers of the
/// same frame ([`Ibjae::read_sharing`]): an experiment grid puts several
/// estimators on one run, and each IBJAE among them (IBJAE alone, LBHJAE
/// with either filter) would otherwise segment, embed and search the same
/// regions of the same frame again. The first reader of a band reads it;
/// the others, if they are readers of the same models and settings, take
/// its reading. It knows the frame its readings are of (a hash of the
/// frame's pixels and place) and forgets them when a reader brings another
/// frame; [`FrameReads::clear`] forgets them at once.
#[derive(Debug, Clone, Default)]
pub struct FrameReads {
    /// The fingerprint of the readers whose readings these are (the first
    /// to read since the last clear).
    reader: Option<u64>,
    /// The frame the readings are of ([`frame_key`]).
    frame: Option<u64>,
    /// Each band read in this frame and what it read (`None`: no instrument).
    reads: Vec<(usize, Option<IbjaeReading>)>,
    /// Readings taken from here instead of read, since it was made.
    taken: u64,
}

impl FrameReads {
    /// Holds no readings.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Forgets the readings, for the next frame (the count of readings
    /// taken stays).
    pub fn clear(&mut self) {
        self.reader = None;
        self.frame = None;
        self.reads.clear();
    }

    /// How many bands were read in this frame.
    #[must_use]
    pub fn bands_read(&self) -> usize {
        self.reads.len()
    }

    /// How many readings readers took from here instead of reading them,
    /// since it was made.
    #[must_use]
    pub fn taken(&self) -> u64 {
        self.taken
    }

    /// Band `band`'s reading in this frame, if it was read.
    fn get(&self, band: usize) -> Option<Option<IbjaeReading>> {
        self.reads.iter().find(|r| r.0 == band).map(|r| r.1)
    }
}

/// A hash of `frame`'s pixels, its size and its place in the camera's
/// image: what tells [`FrameReads`] that a reader brings another frame. It
/// reads every byte once, 32 bytes a step in four independent lanes (the
/// multiplications of one lane wait for each other, of four do not). In
/// the paper's Table V grid (three readers a frame) it takes about 1 % of
/// the run's time; one lane took 4 %.
fn frame_key(frame: &RgbView) -> u64 {
    let mut h = LaneHash::new();
    for v in [frame.width, frame.height, frame.x0, frame.y0] {
        h.word(u64::from(v));
    }
    let row = 3 * frame.width as usize;
    for y in 0..frame.height as usize {
        let pixels = &frame.data[y * frame.stride..y * frame.stride + row];
        h.slice::<_, 8>(pixels, |b| {
            let mut w = [0u8; 8];
            w[..b.len()].copy_from_slice(b);
            u64::from_le_bytes(w)
        });
        // the row's end, so rows cannot slide into each other
        h.word(y as u64);
    }
    h.finish()
}

/// A hash in four independent lanes (the multiplications of one lane wait
/// for each other, of four do not): not for adversaries, for telling data
/// apart fast.
struct LaneHash {
    lanes: [u64; 4],
}

impl LaneHash {
    const K: u64 = 0x517c_c1b7_2722_0a95;

    fn new() -> Self {
        Self {
            lanes: [1, 2, 3, 4],
        }
    }

    fn mix(h: u64, word: u64) -> u64 {
        (h.rotate_left(5) ^ word).wrapping_mul(Self::K)
    }

    /// Four words, one a lane.
    fn words(&mut self, words: [u64; 4]) {
        for (lane, w) in self.lanes.iter_mut().zip(words) {
            *lane = Self::mix(*lane, w);
        }
    }

    /// One word, into the first lane.
    fn word(&mut self, word: u64) {
        self.lanes[0] = Self::mix(self.lanes[0], word);
    }

    /// `items`, `N` to a word (`word` makes one of up to `N` items), four
    /// words a step; the last items' words into the first lane.
    fn slice<T, const N: usize>(&mut self, items: &[T], word: impl Fn(&[T]) -> u64) {
        let mut blocks = items.chunks_exact(4 * N);
        for b in blocks.by_ref() {
            self.words([
                word(&b[..N]),
                word(&b[N..2 * N]),
                word(&b[2 * N..3 * N]),
                word(&b[3 * N..]),
            ]);
        }
        for w in blocks.remainder().chunks(N) {
            self.word(word(w));
        }
    }

    fn finish(self) -> u64 {
        self.lanes.into_iter().fold(0, Self::mix)
    }
}

impl Ibjae {
    /// IBJAE over the given band databases, each of which must have been
    /// embedded by this SCNN.
    ///
    /// # Errors
    /// [`EstimateError::ModelMismatch`] naming both SHA-256s when a database
    /// was built with another model; [`EstimateError::NoBandDatabase`] for no
    /// databases; as [`Segmenter::new`] for bad segmentation parameters.
    pub fn new(scnn: Scnn, segment: SegmentParams, bands: Vec<BandDatabase>) -> Result<Self> {
        Self::new_shared(scnn, segment, Arc::from(bands))
    }

    /// [`Ibjae::new`] over databases shared with other readers (an
    /// experiment's runs each make their estimators, which need not load
    /// and hold the same databases again): no reading changes, as the
    /// databases do not.
    ///
    /// # Errors
    /// As [`Ibjae::new`].
    pub fn new_shared(
        scnn: Scnn,
        segment: SegmentParams,
        bands: Arc<[BandDatabase]>,
    ) -> Result<Self> {
        if bands.is_empty() {
            return Err(EstimateError::NoBandDatabase);
        }
        for b in bands.iter() {
            let built = b
                .index
                .metadata()
                .get(keys::SCNN_SHA256)
                .map_or("(none)", String::as_str);
            if built != scnn.sha256() {
                return Err(EstimateError::ModelMismatch {
                    path: "feature database".to_string(),
                    which: "SCNN",
                    expected: scnn.sha256().to_string(),
                    found: built.to_string(),
                });
            }
        }
        let largest = bands
            .iter()
            .map(|b| 3 * b.band.roi.area() as usize)
            .max()
            .unwrap_or(0);
        Ok(Self {
            scnn,
            segmenter: Segmenter::new(segment)?,
            bands,
            crop: Vec::with_capacity(largest),
            embedding: [0.0; EMBEDDING_DIM],
            check: None,
            fingerprint: None,
        })
    }

    /// The same IBJAE, checking each reading against the nominal silhouette
    /// of the pose it reads (see the module docs): `camera` and `instrument`
    /// the nominal ones the databases were rendered from, `min_iou` the least
    /// IoU of an explained reading ([`DEFAULT_MIN_SILHOUETTE_IOU`]). A
    /// reading below it is read again with a hidden part, or reports
    /// `sigma_deg` of at least [`UNEXPLAINED_SIGMA_DEG`]; every reading
    /// reports its `silhouette_iou`.
    ///
    /// # Errors
    /// [`EstimateError::OutOfRange`] for `min_iou` outside `[0, 1]`; as
    /// [`Camera::validate`] for a bad camera;
    /// [`EstimateError::ModelMismatch`] naming both cameras when a database
    /// was rendered through another camera (its metadata, as
    /// [`crate::load_databases`] checks it).
    pub fn with_silhouette_check(
        self,
        camera: &Camera,
        instrument: &Instrument,
        min_iou: f64,
    ) -> Result<Self> {
        kflex_model::Bounds::closed(0.0, 1.0).check("min_silhouette_iou", min_iou)?;
        let grids = HiddenPartGrids::new(camera, instrument, Arc::clone(&self.bands))?;
        self.with_shared_silhouette_check(&grids, min_iou)
    }

    /// [`Ibjae::with_silhouette_check`] with the nominal camera, instrument
    /// and hidden-part grids of `grids`, shared with the other readers given
    /// them: each band's grid is rendered once for all of them.
    ///
    /// # Errors
    /// [`EstimateError::OutOfRange`] for `min_iou` outside `[0, 1]`;
    /// [`EstimateError::ModelMismatch`] when `grids` were made for other
    /// databases than this reader's (the same shared ones,
    /// [`Ibjae::new_shared`], are needed).
    pub fn with_shared_silhouette_check(
        mut self,
        grids: &Arc<HiddenPartGrids>,
        min_iou: f64,
    ) -> Result<Self> {
        kflex_model::Bounds::closed(0.0, 1.0).check("min_silhouette_iou", min_iou)?;
        if !Arc::ptr_eq(&grids.bands, &self.bands) {
            return Err(EstimateError::ModelMismatch {
                path: "hidden-part grids".to_string(),
                which: "databases",
                expected: "the reader's own (shared) databases".to_string(),
                found: "another set of databases".to_string(),
            });
        }
        self.fingerprint = None;
        self.check = Some(SilhouetteCheck {
            min_iou,
            raster: Rasterizer::new(),
            shape: InstrumentShape::default(),
            mask: Mask::new(SCNN_SIDE, SCNN_SIDE)?,
            grids: Arc::clone(grids),
        });
        Ok(self)
    }

    /// Renders now the nominal silhouettes every band's hidden-part search
    /// needs (see "Hidden parts" in the module docs), which a read otherwise
    /// renders the first time a band needs them: 6–18 ms for a band of the
    /// full range, once, in whichever control tick first reads a taped frame
    /// in it itself (a reading taken from another reader through
    /// [`Ibjae::read_sharing`] renders nothing). With grids shared
    /// ([`Ibjae::with_shared_silhouette_check`]) a band is rendered once for
    /// every reader sharing them, so one reader's call prepares them all, and
    /// a reader that needs a band another is rendering waits for it. A
    /// controller with a deadline per tick calls this once at start-up
    /// (about 0.3 s for the 28 bands of the full range), after which no read
    /// renders. Nothing to do without the silhouette check.
    pub fn prepare_hidden_parts(&mut self) {
        if let Some(check) = self.check.as_mut() {
            for (b, db) in self.bands.iter().enumerate() {
                check.fill(b, db);
            }
        }
    }

    /// Whether no read will render a band's nominal silhouettes any more:
    /// every band's are rendered ([`Ibjae::prepare_hidden_parts`], or reads
    /// that needed them), or there is no silhouette check.
    #[must_use]
    pub fn hidden_parts_ready(&self) -> bool {
        self.check.as_ref().is_none_or(|c| c.grids.ready())
    }

    /// The band databases.
    #[must_use]
    pub fn bands(&self) -> &[BandDatabase] {
        &self.bands
    }

    /// The bands to ask for a frame at translation `translation_mm`: those
    /// whose poses hold it and, given an estimate of the bend, the one that
    /// holds that bend deepest inside; without one, every band at that
    /// translation (IBJAE then keeps the nearest answer).
    #[must_use]
    pub fn bands_for(&self, theta_hint_deg: Option<f64>, translation_mm: f64) -> Vec<usize> {
        let mut out = Vec::new();
        self.bands_for_into(theta_hint_deg, translation_mm, &mut out);
        out
    }

    /// [`Ibjae::bands_for`] into `out` (cleared first), reusing its
    /// allocation: a control tick allocates nothing.
    pub fn bands_for_into(
        &self,
        theta_hint_deg: Option<f64>,
        translation_mm: f64,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        out.extend((0..self.bands.len()).filter(|&i| {
            let [d0, d1] = self.bands[i].band.poses.translation_mm;
            (d0..=d1).contains(&translation_mm)
        }));
        let Some(theta) = theta_hint_deg.filter(|t| t.is_finite()) else {
            return;
        };
        let room = |i: &usize| {
            let [lo, hi] = self.bands[*i].band.poses.theta_deg;
            (theta - lo).min(hi - theta)
        };
        if let Some(best) = out
            .iter()
            .copied()
            .filter(|i| room(i) >= 0.0)
            .max_by(|a, b| room(a).total_cmp(&room(b)))
        {
            out.clear();
            out.push(best);
        }
    }

    /// The smallest window of the camera's image holding the regions of
    /// `bands` (what a frame must cover for [`Ibjae::read`]); `None` for no
    /// bands or none that exists.
    #[must_use]
    pub fn window(&self, bands: &[usize]) -> Option<Roi> {
        bands
            .iter()
            .filter_map(|&i| self.bands.get(i).map(|b| b.band.roi))
            .reduce(|a, b| a.union(&b))
    }

    /// Reads the joint from `frame` with the databases `bands` (see
    /// [`Ibjae::bands_for`]); `Ok(None)` when the segmentation finds no
    /// instrument in any of their regions: never a made-up angle.
    ///
    /// # Errors
    /// [`EstimateError::OutOfRange`] naming `band` for an index past the
    /// databases; [`EstimateError::ImageSize`] or a range error for a region
    /// outside the frame; errors of the SCNN and the index.
    pub fn read(&mut self, frame: &RgbView, bands: &[usize]) -> Result<Option<IbjaeReading>> {
        self.read_from(frame, bands, None)
    }

    /// [`Ibjae::read`] for one of several readers of the same frame (an
    /// experiment's estimators sharing one run): a band that a reader of the
    /// same models and settings already read in this frame is taken from
    /// `reads`, the others are read and left there. The reading is the one
    /// [`Ibjae::read`] gives, bit for bit. `reads` holds one frame's
    /// readings: given another frame it forgets the last one's; a reader of
    /// other models or settings reads everything itself.
    ///
    /// # Errors
    /// As [`Ibjae::read`].
    pub fn read_sharing(
        &mut self,
        frame: &RgbView,
        bands: &[usize],
        reads: &mut FrameReads,
    ) -> Result<Option<IbjaeReading>> {
        self.read_from(frame, bands, Some(reads))
    }

    fn read_from(
        &mut self,
        frame: &RgbView,
        bands: &[usize],
        mut reads: Option<&mut FrameReads>,
    ) -> Result<Option<IbjaeReading>> {
        if let Some(r) = reads.as_deref_mut() {
            // readings of another frame are forgotten
            let key = frame_key(frame);
            if r.frame != Some(key) {
                r.clear();
                r.frame = Some(key);
            }
            let mine = self.fingerprint();
            let theirs = *r.reader.get_or_insert(mine);
            if theirs != mine {
                reads = None;
            }
        }
        // an explained reading before one with a hidden part, before an
        // unexplained one; then the nearest
        let min_iou = self.check.as_ref().map_or(0.0, |c| c.min_iou);
        let rank = |r: &IbjaeReading| {
            let class = if r.occluded {
                1
            } else if r.silhouette_iou.is_some_and(|iou| iou < min_iou) {
                2
            } else {
                0
            };
            (class, r.distance)
        };
        let mut best: Option<IbjaeReading> = None;
        for &i in bands {
            if i >= self.bands.len() {
                let last = self.bands.len().saturating_sub(1);
                kflex_model::Bounds::closed(0.0, last as f64).check("band", i as f64)?;
                continue;
            }
            let shared = reads.as_deref().and_then(|r| r.get(i));
            let reading = match shared {
                Some(reading) => {
                    if let Some(r) = reads.as_deref_mut() {
                        r.taken += 1;
                    }
                    reading
                }
                None => {
                    let reading = self.read_band(frame, i)?;
                    if let Some(r) = reads.as_deref_mut() {
                        r.reads.push((i, reading));
                    }
                    reading
                }
            };
            if let Some(reading) = reading
                && best.is_none_or(|b| rank(&reading) < rank(&b))
            {
                best = Some(reading);
            }
        }
        Ok(best)
    }

    /// What band `i` (an index of `self.bands`) reads from `frame`: `None`
    /// where its region shows no instrument.
    fn read_band(&mut self, frame: &RgbView, i: usize) -> Result<Option<IbjaeReading>> {
        let Some(db) = self.bands.get(i) else {
            let last = self.bands.len().saturating_sub(1);
            kflex_model::Bounds::closed(0.0, last as f64).check("band", i as f64)?;
            return Ok(None);
        };
        let roi = db.band.roi;
        frame.crop_into(roi, &mut self.crop)?;
        let segmented = match self.segmenter.segment(
            &self.crop,
            roi.width,
            roi.height,
            Roi::whole(roi.width, roi.height),
        ) {
            Ok(s) => s,
            Err(EstimateError::NoInstrument { .. }) => return Ok(None),
            Err(e) => return Err(e),
        };
        self.scnn.embed(&segmented.small, &mut self.embedding)?;
        let db = &self.bands[i];
        let n = db.index.nearest(&self.embedding)?;
        let distance = f64::from(n.distance());
        let mut reading = IbjaeReading {
            theta_deg: n.pose.theta_deg,
            translation_mm: n.pose.translation_mm,
            distance,
            sigma_deg: (distance / db.distance_per_deg).max(0.5 * db.theta_step_deg),
            band: i,
            silhouette_iou: None,
            occluded: false,
            consistent_deg: None,
        };
        if let Some(c) = self.check.as_mut() {
            // the nominal silhouette of the pose read, as the database
            // rendered it (build_band_database)
            let iou = c.iou_with_entry(i, db, (n.index, n.pose), &segmented.small)?;
            reading.silhouette_iou = Some(iou);
            if iou < c.min_iou {
                reading.sigma_deg = reading.sigma_deg.max(UNEXPLAINED_SIGMA_DEG);
                // taken only where the visible pixels pin the bend
                if let Some((e, [lo, hi], iou)) = c.hidden(i, db, &segmented.small)?
                    && 0.5 * (hi - lo) <= HIDDEN_SIGMA_DEG
                    && let Some(&pose) = db.index.poses().get(e)
                {
                    let dim = db.index.dim();
                    let d2: f32 = db
                        .index
                        .features()
                        .get(e * dim..(e + 1) * dim)
                        .unwrap_or_default()
                        .iter()
                        .zip(&self.embedding)
                        .map(|(a, b)| (a - b) * (a - b))
                        .sum();
                    let distance = f64::from(d2.sqrt());
                    // a pose that explains the silhouette: nothing hidden
                    let explained = iou >= c.min_iou;
                    reading = IbjaeReading {
                        theta_deg: pose.theta_deg,
                        translation_mm: pose.translation_mm,
                        distance,
                        sigma_deg: if explained {
                            distance / db.distance_per_deg
                        } else {
                            HIDDEN_SIGMA_DEG
                        }
                        .max(0.5 * db.theta_step_deg),
                        silhouette_iou: Some(iou),
                        occluded: !explained,
                        consistent_deg: (!explained).then_some([lo, hi]),
                        ..reading
                    };
                }
            }
        }
        Ok(Some(reading))
    }

    /// What tells this reader's readings apart from another's: its SCNN
    /// (the model and its threads), segmentation settings, databases and
    /// silhouette check (a hash of them, made on the first shared read).
    fn fingerprint(&mut self) -> u64 {
        if let Some(f) = self.fingerprint {
            return f;
        }
        let mut h = std::hash::DefaultHasher::new();
        self.scnn.sha256().hash(&mut h);
        self.scnn.threads().hash(&mut h);
        format!("{:?}", self.segmenter.params()).hash(&mut h);
        match &self.check {
            Some(c) => format!(
                "{:?} {:?} {:?}",
                c.grids.camera, c.grids.instrument, c.min_iou
            )
            .hash(&mut h),
            None => "no check".hash(&mut h),
        }
        for b in self.bands.iter() {
            b.content_hash().hash(&mut h);
        }
        let f = h.finish();
        self.fingerprint = Some(f);
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every byte of the pixels counts (in the four lanes and in a row's
    /// last bytes), and so do the size and the place; the padding between
    /// rows does not.
    #[test]
    fn a_frame_key_sees_every_pixel_byte_and_no_padding() {
        // 13 px a row: 39 bytes, a 32-byte block and 7 bytes left; stride 48
        let (w, h, stride) = (13u32, 5u32, 48usize);
        let data: Vec<u8> = (0..stride * h as usize)
            .map(|i| (i * 7 % 251) as u8)
            .collect();
        let key = |d: &[u8]| frame_key(&RgbView::new(d, w, h, stride).unwrap());
        let base = key(&data);
        for y in 0..h as usize {
            for i in 0..3 * w as usize {
                let mut d = data.clone();
                d[y * stride + i] ^= 1;
                assert_ne!(key(&d), base, "byte {i} of row {y}");
            }
            let mut padded = data.clone();
            padded[y * stride + 3 * w as usize] ^= 0xff;
            assert_eq!(key(&padded), base, "padding of row {y}");
        }
        // the same bytes as another size, or at another place
        let wide = RgbView::new(&data, 16, 5, stride).unwrap();
        assert_ne!(frame_key(&wide), base);
        let mut moved = RgbView::new(&data, w, h, stride).unwrap();
        moved.x0 = 1;
        assert_ne!(frame_key(&moved), base);
    }
}
