//! Shaded endoscope frames: the instrument over procedural clinical backgrounds,
//! lit by the endoscope's light, with occluding tape, illumination change,
//! blur and sensor noise — and the ground-truth masks of every frame.

mod background;
mod noise;
mod organs;
mod sensor;
mod shading;

use std::sync::{Arc, Mutex, PoisonError};

use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::Result;
use crate::instrument::InstrumentShape;
use crate::mask::Mask;
use crate::range::Bounds;
use crate::raster::{Rasterizer, RayBatch, SurfaceHit};
use crate::roi::Roi;
use crate::working::WorkingRegions;
pub use background::{Background, Tissue};
use sensor::{
    Normals, Response, Sensor, gaussian_blur, linear_from_encoded, normal_table, response_table,
};
use shading::{LookQueue, Surroundings, tape_band, under_tape};

/// What a cached background depends on: kind, tissue colour, seed, width, height.
type BackgroundKey = (Background, Tissue, u64, u32, u32);

/// A background as the scene uses it: linear-light RGB over the whole
/// image, and its mean colour (the light the steel reflects from afar).
#[derive(Debug)]
struct Backdrop {
    image: Vec<f32>,
    mean: [f32; 3],
}

/// The backgrounds made last, shared by every renderer of the process
/// (most recently used last): an experiment's runs make a renderer each,
/// and their repeats draw the same few backgrounds, each 0.1 s to make at
/// 640×480. At most [`SHARED_BACKDROP_BYTES`] are kept.
static SHARED_BACKDROPS: Mutex<Vec<(BackgroundKey, Arc<Backdrop>)>> = Mutex::new(Vec::new());

/// The most memory the shared backgrounds hold: eighteen at 640×480, none
/// at 4K (a renderer still keeps its own).
const SHARED_BACKDROP_BYTES: usize = 64 << 20;

/// The background of `key`, from the shared ones or made (and shared).
fn backdrop(key: BackgroundKey) -> Arc<Backdrop> {
    let shared = || {
        SHARED_BACKDROPS
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    };
    {
        let mut kept = shared();
        if let Some(i) = kept.iter().position(|e| e.0 == key) {
            let entry = kept.remove(i);
            let found = Arc::clone(&entry.1);
            kept.push(entry);
            return found;
        }
    }
    // made outside the lock: another thread's lookups do not wait for it
    let (kind, tissue, seed, w, h) = key;
    // the tissue's look is made as the camera shows it; the scene works in
    // linear light, which the camera's response encodes
    let mut image = background::background(kind, tissue, seed, w, h);
    image.iter_mut().for_each(|v| *v = linear_from_encoded(*v));
    let mean = mean_colour(&image);
    let made = Arc::new(Backdrop { image, mean });
    let bytes = |b: &Backdrop| b.image.len() * std::mem::size_of::<f32>();
    if bytes(&made) <= SHARED_BACKDROP_BYTES {
        let mut kept = shared();
        if !kept.iter().any(|e| e.0 == key) {
            let mut total: usize = kept.iter().map(|e| bytes(&e.1)).sum();
            while total + bytes(&made) > SHARED_BACKDROP_BYTES && !kept.is_empty() {
                total -= bytes(&kept.remove(0).1);
            }
            kept.push((key, Arc::clone(&made)));
        }
    }
    made
}

/// What a region's encoded background depends on: the background, the camera
/// (its vignetting), the region and the illumination gain (its bits).
type EncodedKey = (BackgroundKey, Camera, Roi, u32);

/// Tape over the instrument: a band covering `fraction` of the instrument's
/// pixels inside a region of interest (what IBJAE sees), as the paper
/// defines occlusion by the area the tape covers on the instrument it
/// analyses. The region is `region` where given, else the camera's working
/// region for the frame's translation ([`WorkingRegions::full`]; the nearest
/// band outside its range).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Occlusion {
    /// Share of the instrument's pixels in the working region covered, in
    /// [0, 1] (the paper: 0.2, 0.4).
    pub fraction: f64,
    /// Where the band sits along that part of the instrument: 0 starting at its
    /// proximal end, 0.5 centred on it (the paper's "middle"), 1 ending at the
    /// tool tip (the paper's "distal part").
    pub position: f64,
    /// Where the share is measured (the estimator's region of interest);
    /// `None`: the camera's working region for the frame's translation.
    #[serde(default)]
    pub region: Option<Roi>,
}

impl Occlusion {
    /// A band over `fraction` of the instrument at `position`, its share
    /// measured in the camera's working region for the frame's translation.
    #[must_use]
    pub const fn new(fraction: f64, position: f64) -> Self {
        Self {
            fraction,
            position,
            region: None,
        }
    }

    /// The same band, its share measured in `region` (e.g. the region an
    /// estimator reads, [`Roi::paper`] for the paper's experiments).
    #[must_use]
    pub const fn within(self, region: Roi) -> Self {
        Self {
            region: Some(region),
            ..self
        }
    }
}

/// How one frame is made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FrameParams {
    /// Background kind.
    pub background: Background,
    /// The tissue's colour (the organ's own by default).
    pub tissue: Tissue,
    /// Seed of the background and of the sensor noise.
    pub seed: u64,
    /// Frame number: fresh sensor noise over the same background, as from a
    /// video camera (the background is cached per seed; the noise is not).
    pub frame: u64,
    /// Illumination gain (1: nominal).
    pub illumination_gain: f64,
    /// Standard deviation of Gaussian sensor noise on the [0, 1] image (the paper augments with 0.01).
    pub noise_std: f64,
    /// Gaussian blur, standard deviation in pixels (0: none).
    pub blur_px: f64,
    /// Tape over the instrument, if any.
    pub occlusion: Option<Occlusion>,
}

impl Default for FrameParams {
    fn default() -> Self {
        Self {
            background: Background::Colon,
            tissue: Tissue::Organ,
            seed: 0,
            frame: 0,
            illumination_gain: 1.0,
            noise_std: 0.01,
            blur_px: 0.0,
            occlusion: None,
        }
    }
}

impl FrameParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the first out of its range:
    /// `illumination_gain` in [0.05, 5], `noise_std` in [0, 1], `blur_px` 0 or
    /// in [0.01, 20], `occlusion.fraction` and `occlusion.position` in [0, 1].
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.05, 5.0).check("illumination_gain", self.illumination_gain)?;
        Bounds::closed(0.0, 1.0).check("noise_std", self.noise_std)?;
        Bounds::closed(0.0, 20.0).check("blur_px", self.blur_px)?;
        // a blur is none or at least a hundredth of a pixel: below, its
        // kernel's σ² underflows and the frame would come out black
        if self.blur_px > 0.0 && self.blur_px < 0.01 {
            Bounds::closed(0.01, 20.0).check("blur_px", self.blur_px)?;
        }
        if let Some(o) = self.occlusion {
            Bounds::closed(0.0, 1.0).check("occlusion.fraction", o.fraction)?;
            Bounds::closed(0.0, 1.0).check("occlusion.position", o.position)?;
        }
        Ok(())
    }
}

/// A rendered frame and its ground truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// RGB, 8 bits per channel, row-major.
    pub rgb: Vec<u8>,
    /// The instrument's visible (untaped) pixels.
    pub instrument: Mask,
    /// The tape's pixels.
    pub occluder: Mask,
}

/// Renders frames, caching backgrounds.
///
/// Backgrounds are generated from a seed ([`Background`]) and cached per
/// (kind, tissue, seed, size) in a [`SceneRenderer`], so a frame costs the
/// instrument's shading and the sensor model, not the texture synthesis; the
/// last ones made (up to 64 MB, eighteen at 640×480) are also shared by
/// every renderer of the process, so that the runs of an experiment, a
/// renderer each, make each background once.
///
/// A frame is made in three passes over the window asked for (grown by the
/// blur's reach and one pixel, so that a window's pixels equal the full
/// frame's crop):
/// 1. **Rays.** The ray through each pixel's centre, bent by the lens, meets
///    the instrument's bodies exactly ([`Rasterizer`]): this decides the
///    ground-truth masks.
/// 2. **Shading.** In linear light: steel lit by the endoscope's light at the
///    camera, tinted by the tissue it reflects, matte tape; the light falls
///    off with the inverse square of the distance. (The backgrounds' looks are
///    made as the camera shows them and taken back to linear light.) Pixels on the silhouette's edge (where a
///    neighbour's centre ray disagrees) are shaded from four rays inside the
///    pixel and blended with the background by their coverage: anti-aliased
///    edges.
/// 3. **Sensor.** The lens's vignetting, the illumination gain, Gaussian
///    blur, clipping, the camera's response (BT.709's encoding of linear
///    light, as video endoscopes deliver it: a far instrument at a quarter of
///    the near one's light shows at about half its level, as on a real
///    endoscope, not a quarter), Gaussian noise on the encoded image (as
///    the paper's augmentation; counter-based, so each pixel's noise depends
///    on its place in the full frame only), 8 bits.
#[derive(Debug, Default)]
pub struct SceneRenderer {
    raster: Rasterizer,
    cache: Option<(BackgroundKey, Arc<Backdrop>)>,
    /// Centre-ray hits of the last frame's work region, each with its pixel
    /// (full image), and per pixel of the region the index of its hit plus
    /// one (0: none).
    hits: Vec<SurfaceHit>,
    hit_pixels: Vec<[u32; 2]>,
    inside: Vec<u32>,
    /// The region `inside` covers (its entries are zero but at `hit_pixels`).
    inside_region: Option<Roi>,
    arcs: Vec<f32>,
    /// The last camera's vignetting over the last shaded region.
    vignetting: Option<((Camera, Roi), Vec<f32>)>,
    /// The last camera's working regions (where the tape's share is measured
    /// by default); `None` in the pair where the camera has none.
    working: Option<(Camera, Option<WorkingRegions>)>,
    /// Standard-normal samples; each frame reads them in a seeded pseudo-random order.
    normals: Option<Box<Normals>>,
    /// Encoded background of the last sharp frame's region (see
    /// `render_window`); between frames it holds the background alone.
    encoded: Option<(EncodedKey, Vec<f32>)>,
    /// The pixels the instrument changed in the last shaded region: index in
    /// the region and linear colour.
    patches: Vec<(u32, [f32; 3])>,
    /// The encoded background values a frame's patches covered, to put back.
    undo: Vec<[f32; 3]>,
    /// The patches' colours through the lens (three values a patch), then encoded.
    lit: Vec<f32>,
    /// The looks of a frame's patches, queued and made a batch at a time.
    queue: Box<LookQueue>,
    /// A tile's edge pixels (their patch and background colour) and the
    /// pixel positions of their four rays each, cast together by `rays`.
    edge_pixels: Vec<(u32, [f32; 3])>,
    edge_points: Vec<(f64, f64)>,
    rays: Box<RayBatch>,
    /// One row of encoded values.
    row: Vec<f32>,
    /// The camera's response (`sensor::response_table`), once made.
    response: Option<Box<Response>>,
}

/// `r` grown by `by` pixels on each side, clipped to a `w × h` image.
fn grow(r: Roi, by: u32, w: u32, h: u32) -> Roi {
    let (x0, y0) = (r.x0.saturating_sub(by), r.y0.saturating_sub(by));
    let x1 = (r.x0 + r.width).saturating_add(by).min(w);
    let y1 = (r.y0 + r.height).saturating_add(by).min(h);
    Roi {
        x0,
        y0,
        width: x1 - x0,
        height: y1 - y0,
    }
}

/// Sub-pixel offsets of the four rays that shade an edge pixel (a rotated grid).
const EDGE_SAMPLES: [(f64, f64); 4] = [
    (-0.125, -0.375),
    (0.375, -0.125),
    (0.125, 0.375),
    (-0.375, 0.125),
];

impl SceneRenderer {
    /// A renderer with an empty cache.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Renders `shape` seen by `camera` with `params`: the instrument shaded
    /// over the cached background, tape where `params.occlusion` puts it,
    /// then the sensor (vignetting, illumination gain, blur, noise, 8 bits).
    /// The masks of the frame are exact: the pixels whose centre ray meets
    /// the instrument's untaped surface, and the tape's.
    ///
    /// # Examples
    /// ```
    /// use kflex_model::{Camera, FrameParams, Instrument, Occlusion, SceneRenderer};
    /// let camera = Camera::default();
    /// let shape = Instrument::kflex().shape(30.0, 10.0)?;
    /// let mut renderer = SceneRenderer::new();
    /// let clean = renderer.render(&camera, &shape, &FrameParams::default())?;
    /// assert_eq!(clean.rgb.len(), 640 * 480 * 3);
    /// assert_eq!(clean.occluder.count(), 0);
    /// // tape over 40 % of the instrument IBJAE sees, at its distal end
    /// let taped = FrameParams {
    ///     occlusion: Some(Occlusion::new(0.4, 1.0)),
    ///     ..FrameParams::default()
    /// };
    /// let frame = renderer.render(&camera, &shape, &taped)?;
    /// assert!(frame.occluder.count() > 0);
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the first parameter of `params`, of
    /// `camera`'s intrinsics or of its lens out of its range, or a shape of
    /// more than [`crate::MAX_BODIES`] bodies.
    pub fn render(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        params: &FrameParams,
    ) -> Result<Frame> {
        let k = &camera.intrinsics;
        let full = Roi::whole(k.width, k.height);
        self.render_window(camera, shape, params, full)
    }

    /// The pixels of [`SceneRenderer::render`]'s frame inside `window`,
    /// exactly (image and masks), at a cost proportional to the window's area
    /// (the closed loop needs only the region of interest). The frame's
    /// `width` and `height` are the window's.
    ///
    /// # Errors
    /// As [`SceneRenderer::render`]; as [`Roi::check_within`] for a window
    /// outside the image.
    pub fn render_window(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        params: &FrameParams,
        window: Roi,
    ) -> Result<Frame> {
        params.validate()?;
        camera.validate()?;
        Rasterizer::check_shape(shape)?;
        let k = camera.intrinsics;
        let (w, h) = (k.width, k.height);
        window.check_within(w, h)?;
        if let Some(r) = params.occlusion.and_then(|o| o.region) {
            r.check_within(w, h)?;
        }
        let key_bg = (params.background, params.tissue, params.seed, w, h);
        if self.cache.as_ref().map(|c| c.0) != Some(key_bg) {
            self.cache = Some((key_bg, backdrop(key_bg)));
        }
        let reach = if params.blur_px > 0.0 {
            (3.0 * params.blur_px).ceil() as u32
        } else {
            0
        };
        let shaded_region = grow(window, reach, w, h);
        let work = grow(shaded_region, 1, w, h);
        self.raster.prepare(camera, shape);
        self.cast_centres(camera, work);
        let band = match params.occlusion {
            Some(o) => self.tape_band(camera, shape, o, work),
            None => None,
        };
        self.shade(camera, shaded_region, work, band);
        // the sensor: vignetting first (the lens), then blur, noise and 8 bits
        let (sw, sh) = (shaded_region.width as usize, shaded_region.height as usize);
        // the lens's vignetting: separable in neither axis, so a table of the
        // region kept while the camera and the region stay (a loop's do)
        let key = (*camera, shaded_region);
        if self.vignetting.as_ref().map(|v| v.0) != Some(key) {
            let mut table = Vec::with_capacity(sw * sh);
            for y in shaded_region.y0..shaded_region.y0 + shaded_region.height {
                for x in shaded_region.x0..shaded_region.x0 + shaded_region.width {
                    table.push(camera.illumination(f64::from(x) + 0.5, f64::from(y) + 0.5) as f32);
                }
            }
            self.vignetting = Some((key, table));
        }
        let normals = self.normals.get_or_insert_with(normal_table);
        let response = self.response.get_or_insert_with(response_table);
        let sensor = Sensor {
            normals,
            response,
            key: params.seed.wrapping_mul(0xD1B5_4A32_D192_ED03)
                ^ params.frame.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7)
                ^ 0x006e_6f69_7365,
            gain: params.illumination_gain as f32,
            sigma: params.noise_std as f32,
        };
        let vignetting = self.vignetting.as_ref().map_or(&[][..], |v| &v.1[..]);
        let (ww, wh) = (window.width as usize, window.height as usize);
        let mut rgb = vec![0u8; 3 * ww * wh];
        // the window's values in the shaded region: rows of `sw` pixels from `origin`
        let origin = 3
            * ((window.y0 - shaded_region.y0) as usize * sw
                + (window.x0 - shaded_region.x0) as usize);
        let first = |y: usize| 3 * ((window.y0 as usize + y) * w as usize + window.x0 as usize);
        let background = self.cache.as_ref().map_or(&[][..], |c| &c.1.image[..]);
        if params.blur_px <= 0.0 {
            // without blur a background pixel's encoded value is the same
            // every frame: kept per (background, camera, region, gain), so a
            // frame encodes only the pixels the instrument changed, over it,
            // and puts the background back after
            let bg_key = (key_bg, *camera, shaded_region, sensor.gain.to_bits());
            let encoded = match &mut self.encoded {
                Some((k, e)) if *k == bg_key => e,
                slot => {
                    let mut encoded = Vec::with_capacity(3 * sw * sh);
                    for y in 0..sh {
                        let start = 3
                            * ((shaded_region.y0 as usize + y) * w as usize
                                + shaded_region.x0 as usize);
                        let row = &background[start..start + 3 * sw];
                        for (px, &v) in row.chunks_exact(3).zip(&vignetting[y * sw..(y + 1) * sw]) {
                            encoded.extend(px.iter().map(|&c| sensor.encode(c * v)));
                        }
                    }
                    &mut slot.insert((bg_key, encoded)).1
                }
            };
            // the patches' light through the lens, encoded all at once
            // (eight lanes wide), then put over the background
            self.lit.clear();
            self.lit.resize(3 * self.patches.len(), 0.0);
            for (lit, &(p, c)) in self.lit.chunks_exact_mut(3).zip(&self.patches) {
                let v = vignetting.get(p as usize).copied().unwrap_or(1.0);
                lit.copy_from_slice(&c.map(|c| c * v));
            }
            sensor.encode_all(&mut self.lit);
            self.undo.clear();
            self.undo.resize(self.patches.len(), [0.0; 3]);
            for ((&(p, _), lit), old) in self
                .patches
                .iter()
                .zip(self.lit.chunks_exact(3))
                .zip(self.undo.iter_mut())
            {
                let px = &mut encoded[3 * p as usize..3 * p as usize + 3];
                *old = [px[0], px[1], px[2]];
                px.copy_from_slice(lit);
            }
            for (y, out) in rgb.chunks_exact_mut(3 * ww).enumerate() {
                let src = origin + 3 * y * sw;
                sensor.span_encoded(first(y), &encoded[src..src + 3 * ww], out);
            }
            for (&(p, _), old) in self.patches.iter().zip(&self.undo) {
                encoded[3 * p as usize..3 * p as usize + 3].copy_from_slice(old);
            }
        } else {
            // the scene's light over the region, the lens's vignetting, then
            // the optics' blur
            let mut img = Vec::with_capacity(3 * sw * sh);
            for y in 0..sh {
                let start =
                    3 * ((shaded_region.y0 as usize + y) * w as usize + shaded_region.x0 as usize);
                img.extend_from_slice(&background[start..start + 3 * sw]);
            }
            for &(p, c) in &self.patches {
                img[3 * p as usize..3 * p as usize + 3].copy_from_slice(&c);
            }
            for (px, &v) in img.chunks_exact_mut(3).zip(vignetting) {
                px.iter_mut().for_each(|c| *c *= v);
            }
            gaussian_blur(&mut img, sw, sh, params.blur_px);
            let mut row = std::mem::take(&mut self.row);
            for (y, out) in rgb.chunks_exact_mut(3 * ww).enumerate() {
                let src = origin + 3 * y * sw;
                row.clear();
                row.extend_from_slice(&img[src..src + 3 * ww]);
                sensor.encode_all(&mut row);
                sensor.span_encoded(first(y), &row, out);
            }
            self.row = row;
        }
        // the masks: each centre hit inside the window, under the tape or
        // not, read row by row from the work region's hit table (the window
        // lies inside the work region, which holds every centre hit)
        let mut instrument = vec![0u8; ww * wh];
        let mut occluder = vec![0u8; ww * wh];
        let work_w = work.width as usize;
        let (dx, dy) = (
            window.x0.saturating_sub(work.x0) as usize,
            window.y0.saturating_sub(work.y0) as usize,
        );
        debug_assert!(work.holds(&window), "the work region is the window grown");
        for (y, (inst, occl)) in instrument
            .chunks_exact_mut(ww)
            .zip(occluder.chunks_exact_mut(ww))
            .enumerate()
        {
            let start = (dy + y) * work_w + dx;
            let Some(row) = self.inside.get(start..start + ww) else {
                break;
            };
            match band {
                None => {
                    for (m, &h) in inst.iter_mut().zip(row) {
                        *m = u8::from(h != 0);
                    }
                }
                Some(_) => {
                    for ((m, o), &h) in inst.iter_mut().zip(occl.iter_mut()).zip(row) {
                        if let Some(hit) = h.checked_sub(1).and_then(|k| self.hits.get(k as usize))
                        {
                            if under_tape(hit, band) {
                                *o = 1;
                            } else {
                                *m = 1;
                            }
                        }
                    }
                }
            }
        }
        Ok(Frame {
            width: window.width,
            height: window.height,
            rgb,
            instrument: Mask::from_raw(window.width, window.height, instrument)?,
            occluder: Mask::from_raw(window.width, window.height, occluder)?,
        })
    }

    /// Casts the ray through every pixel centre of `work`: `hits`,
    /// `hit_pixels` and `inside`.
    fn cast_centres(&mut self, camera: &Camera, work: Roi) {
        let Self {
            raster,
            hits,
            hit_pixels,
            inside,
            inside_region,
            ..
        } = self;
        let ww = work.width as usize;
        let at = |x: u32, y: u32| (y - work.y0) as usize * ww + (x - work.x0) as usize;
        if *inside_region == Some(work) {
            // only last frame's hits to clear
            for &[x, y] in hit_pixels.iter() {
                inside[at(x, y)] = 0;
            }
        } else {
            inside.clear();
            inside.resize(work.area() as usize, 0);
            *inside_region = Some(work);
        }
        hits.clear();
        hit_pixels.clear();
        raster.centre_hits(camera, work, |x, y, hit| {
            hits.push(hit);
            hit_pixels.push([x, y]);
            inside[at(x, y)] = hits.len() as u32;
        });
    }

    /// The tape's arc-length band: `o.fraction` of the instrument's pixels
    /// inside `o.region`, else the camera's working region for the shape's
    /// translation (what IBJAE sees; the whole image where the camera has
    /// none), placed at `o.position` along them.
    fn tape_band(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        o: Occlusion,
        work: Roi,
    ) -> Option<(f32, f32)> {
        let k = &camera.intrinsics;
        let region = match o.region {
            Some(r) => r,
            None => {
                if self.working.as_ref().map(|w| w.0) != Some(*camera) {
                    self.working = Some((*camera, WorkingRegions::full(camera).ok()));
                }
                self.working
                    .as_ref()
                    .and_then(|w| w.1.as_ref())
                    .and_then(|w| w.nearest(shape.bend_deg(), shape.translation_mm()))
                    .map_or(Roi::whole(k.width, k.height), |b| b.roi)
            }
        };
        let Self {
            raster,
            arcs,
            hits,
            hit_pixels,
            ..
        } = self;
        arcs.clear();
        if work.holds(&region) {
            // the centre rays already cast there (the band is of the arcs'
            // order statistics, so the order they come in does not matter)
            let (x1, y1) = (region.x0 + region.width, region.y0 + region.height);
            for (hit, &[x, y]) in hits.iter().zip(hit_pixels.iter()) {
                if (region.x0..x1).contains(&x) && (region.y0..y1).contains(&y) {
                    arcs.push(hit.arc_mm as f32);
                }
            }
            return tape_band(arcs, o);
        }
        raster.centre_hits(camera, region, |_, _, hit| arcs.push(hit.arc_mm as f32));
        tape_band(arcs, o)
    }

    /// The scene's light over `region` where the instrument changes it:
    /// `patches`, each pixel's index in the region and its linear RGB (the
    /// instrument shaded, edges anti-aliased over the background).
    fn shade(&mut self, camera: &Camera, region: Roi, work: Roi, band: Option<(f32, f32)>) {
        self.patches.clear();
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let Some((_, backdrop)) = self.cache.as_ref() else {
            return;
        };
        let background = &backdrop.image[..];
        let env = Surroundings {
            camera,
            image: background,
            mean: backdrop.mean,
        };
        let rw = region.width as usize;
        let Self {
            raster,
            hits,
            inside,
            patches,
            queue,
            rays,
            edge_pixels,
            edge_points,
            ..
        } = self;
        edge_pixels.clear();
        edge_points.clear();
        queue.clear();
        let (work_x0, work_y0, work_w) = (work.x0 as usize, work.y0 as usize, work.width as usize);
        // row `y` of `inside` (the work region holds the rows next to the region's)
        let row = |y: usize| &inside[(y - work_y0) * work_w..(y - work_y0 + 1) * work_w];
        raster.tiles(
            camera,
            region,
            |scene, optics, [x0, y0, x1, y1], candidates| {
                for y in y0 as usize..y1 as usize {
                    // the centre rays of this row and of the rows above and
                    // below it where the image has them
                    let (mid, above, below) = (
                        row(y),
                        (y > 0).then(|| row(y - 1)),
                        (y + 1 < h).then(|| row(y + 1)),
                    );
                    for x in x0 as usize..x1 as usize {
                        let i = x - work_x0;
                        let here = mid[i].checked_sub(1);
                        // an edge: a neighbour's centre ray disagrees (within
                        // the image; a neighbour outside it agrees)
                        let set = here.is_some();
                        let left = if x > 0 { mid[i - 1] != 0 } else { set };
                        let right = if x + 1 < w { mid[i + 1] != 0 } else { set };
                        let up = above.map_or(set, |r| r[i] != 0);
                        let down = below.map_or(set, |r| r[i] != 0);
                        let edge = (left != set) | (right != set) | (up != set) | (down != set);
                        let p = ((y - region.y0 as usize) * rw + (x - region.x0 as usize)) as u32;
                        if edge {
                            // its four rays, cast with the tile's other edges' below
                            let o = 3 * (y * w + x);
                            let bg = [background[o], background[o + 1], background[o + 2]];
                            edge_pixels.push((patches.len() as u32, bg));
                            patches.push((p, [0.0; 3]));
                            edge_points.extend(
                                EDGE_SAMPLES
                                    .map(|(dx, dy)| (x as f64 + 0.5 + dx, y as f64 + 0.5 + dy)),
                            );
                        } else if let Some(i) = here {
                            let hit = &hits[i as usize];
                            let d = optics.ray(x as u32, y as u32);
                            let slot = (patches.len() as u32, false);
                            patches.push((p, [0.0; 3]));
                            queue.push(&scene.bodies, hit, &d, band, slot, &env, patches);
                        }
                    }
                }
                // an edge's colour: a quarter of each of its rays', in order
                rays.first_hits(camera, scene, candidates, edge_points, |k, hit, d| {
                    let (patch, bg) = edge_pixels[k / 4];
                    match hit {
                        Some(hit) => {
                            queue.push(&scene.bodies, &hit, d, band, (patch, true), &env, patches);
                        }
                        None => queue.push_colour(bg, (patch, true), &env, patches),
                    }
                });
                edge_pixels.clear();
                edge_points.clear();
            },
        );
        queue.flush(&env, patches);
    }
}

/// Mean colour of an RGB image.
fn mean_colour(img: &[f32]) -> [f32; 3] {
    let mut sum = [0.0f64; 3];
    for px in img.chunks_exact(3) {
        (0..3).for_each(|k| sum[k] += f64::from(px[k]));
    }
    let n = (img.len() / 3).max(1) as f64;
    sum.map(|s| (s / n) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::instrument::Instrument;

    /// Renderers share the backgrounds they make: a second renderer takes
    /// the first one's (the same memory, so not made again), and the shared
    /// ones stay within their budget, the least recently used going first.
    #[test]
    fn renderers_share_their_backgrounds_within_a_budget() {
        let camera = Camera::default();
        let shape = Instrument::kflex().shape(20.0, 10.0).unwrap();
        // a seed no other test uses, so that this test's entries are its own
        let params = FrameParams {
            seed: 0x5eed_5ba2_ed00,
            ..FrameParams::default()
        };
        let (mut a, mut b) = (SceneRenderer::new(), SceneRenderer::new());
        let fa = a.render(&camera, &shape, &params).unwrap();
        let fb = b.render(&camera, &shape, &params).unwrap();
        assert_eq!(fa, fb);
        let (ka, da) = a.cache.as_ref().unwrap();
        let (kb, db) = b.cache.as_ref().unwrap();
        assert_eq!(ka, kb);
        assert!(Arc::ptr_eq(da, db), "the second renderer made its own");
        // many more backgrounds than the budget holds
        let (w, h) = (camera.intrinsics.width, camera.intrinsics.height);
        let each = 3 * w as usize * h as usize * std::mem::size_of::<f32>();
        let n = SHARED_BACKDROP_BYTES / each + 3;
        for seed in 0..n as u64 {
            let key = (Background::Stomach, Tissue::Organ, 0x5eed_0000 + seed, w, h);
            let _ = backdrop(key);
        }
        let kept = SHARED_BACKDROPS.lock().unwrap();
        let bytes: usize = kept.iter().map(|e| e.1.image.len() * 4).sum();
        assert!(bytes <= SHARED_BACKDROP_BYTES, "{bytes}");
        // the newest is kept, the first of the run is gone
        let has = |seed: u64| {
            kept.iter()
                .any(|e| e.0 == (Background::Stomach, Tissue::Organ, 0x5eed_0000 + seed, w, h))
        };
        assert!(has(n as u64 - 1) && !has(0));
    }
}
