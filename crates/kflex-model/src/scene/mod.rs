//! Shaded endoscope frames: the instrument over procedural clinical backgrounds,
//! lit by the endoscope's light, with occluding tape, illumination change,
//! blur and sensor noise — and the ground-truth masks of every frame.

mod background;
mod sensor;
mod shading;

use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::Result;
use crate::instrument::InstrumentShape;
use crate::mask::Mask;
use crate::range::Bounds;
use crate::raster::Rasterizer;
pub use background::Background;
use sensor::{Sensor, gaussian_blur, normal_table};
use shading::{Hit, METAL, TAPE, shade, tape_band};

/// What a cached background depends on: kind, seed, width, height.
type BackgroundKey = (Background, u64, u32, u32);

/// Tape over the instrument: a band covering `fraction` of its visible area.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Occlusion {
    /// Share of the visible instrument area covered, in [0, 1] (the paper: 0.2, 0.4).
    pub fraction: f64,
    /// Where the band sits along the instrument: 0 at the proximal end of what is
    /// visible, 1 ending at the tool tip (the paper's "distal part").
    pub position: f64,
}

/// How one frame is made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FrameParams {
    /// Background kind.
    pub background: Background,
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
    /// `illumination_gain` in [0.05, 5], `noise_std` in [0, 1], `blur_px` in
    /// [0, 20], `occlusion.fraction` and `occlusion.position` in [0, 1].
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.05, 5.0).check("illumination_gain", self.illumination_gain)?;
        Bounds::closed(0.0, 1.0).check("noise_std", self.noise_std)?;
        Bounds::closed(0.0, 20.0).check("blur_px", self.blur_px)?;
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
/// (kind, seed, size) in a [`SceneRenderer`], so a frame costs the instrument's
/// shading and the sensor model, not the texture synthesis.
#[derive(Debug, Default)]
pub struct SceneRenderer {
    raster: Rasterizer,
    cache: Option<(BackgroundKey, Vec<f32>)>,
    silhouette: Option<Mask>,
    hits: Vec<Hit>,
    /// Standard-normal samples; each frame reads them in a seeded pseudo-random order.
    normals: Vec<f32>,
}

impl SceneRenderer {
    /// A renderer with an empty cache.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Renders `shape` seen by `camera` with `params`: the instrument shaded
    /// over the cached background, tape where `params.occlusion` puts it,
    /// then the sensor (illumination gain, blur, noise, 8 bits). The masks of
    /// the frame are exact: the instrument's untaped pixels and the tape's.
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
    /// // 40 % of the visible instrument under tape, at its distal end
    /// let taped = FrameParams {
    ///     occlusion: Some(Occlusion { fraction: 0.4, position: 1.0 }),
    ///     ..FrameParams::default()
    /// };
    /// let frame = renderer.render(&camera, &shape, &taped)?;
    /// let share = frame.occluder.count() as f64 / clean.instrument.count() as f64;
    /// assert!((share - 0.4).abs() < 0.01);
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the first parameter of `params` or of
    /// `camera`'s intrinsics out of its range.
    pub fn render(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        params: &FrameParams,
    ) -> Result<Frame> {
        params.validate()?;
        let k = camera.intrinsics;
        k.validate()?;
        let (w, h) = (k.width, k.height);
        let key = (params.background, params.seed, w, h);
        if self.cache.as_ref().map(|c| c.0) != Some(key) {
            self.cache = Some((
                key,
                background::background(params.background, params.seed, w, h),
            ));
        }
        let mut silhouette = match self.silhouette.take() {
            Some(mut m) if (m.width(), m.height()) == (w, h) => {
                m.clear();
                m
            }
            _ => Mask::new(w, h)?,
        };
        self.raster.silhouette(camera, shape, &mut silhouette)?;
        shade(camera, shape, &silhouette, &mut self.hits);
        self.silhouette = Some(silhouette);
        // the tape: a band of arc length holding `fraction` of the visible pixels
        let band = params.occlusion.and_then(|o| tape_band(&self.hits, o));
        let (mut inst_raw, mut occ_raw) =
            (vec![0u8; (w * h) as usize], vec![0u8; (w * h) as usize]);
        let shaded: Vec<(usize, [f32; 3])> = self
            .hits
            .iter()
            .map(|hit| {
                let taped = band.is_some_and(|(lo, hi)| hit.arc_mm >= lo && hit.arc_mm <= hi);
                let (base, gloss) = if taped { (TAPE, 0.35) } else { (METAL, 1.0) };
                if taped {
                    occ_raw[hit.pixel] = 1;
                } else {
                    inst_raw[hit.pixel] = 1;
                }
                (
                    hit.pixel,
                    base.map(|c| c * hit.diffuse + hit.specular * gloss),
                )
            })
            .collect();
        let instrument = Mask::from_raw(w, h, inst_raw)?;
        let occluder = Mask::from_raw(w, h, occ_raw)?;
        let rgb = self.expose(params, w, h, &shaded);
        Ok(Frame {
            width: w,
            height: h,
            rgb,
            instrument,
            occluder,
        })
    }

    /// The sensor's image of the cached background with the `shaded`
    /// instrument pixels over it: illumination, blur, noise, quantisation.
    fn expose(
        &mut self,
        params: &FrameParams,
        w: u32,
        h: u32,
        shaded: &[(usize, [f32; 3])],
    ) -> Vec<u8> {
        if self.normals.is_empty() {
            self.normals = normal_table();
        }
        let sensor = Sensor {
            normals: &self.normals,
            key: params.seed.wrapping_mul(0xD1B5_4A32_D192_ED03)
                ^ params.frame.wrapping_mul(0x8CB9_2BA7_2F3D_8DD7)
                ^ 0x006e_6f69_7365,
            gain: params.illumination_gain as f32,
            sigma: params.noise_std as f32,
        };
        let background = self
            .cache
            .as_ref()
            .map(|c| c.1.as_slice())
            .unwrap_or_default();
        if params.blur_px > 0.0 {
            let mut img = background.to_vec();
            for &(idx, c) in shaded {
                img[3 * idx..3 * idx + 3].copy_from_slice(&c);
            }
            gaussian_blur(&mut img, w as usize, h as usize, params.blur_px);
            sensor.image(&img)
        } else {
            // no blur: quantise the background straight from the cache, then the instrument over it
            let mut rgb = sensor.image(background);
            for &(idx, c) in shaded {
                for ch in 0..3 {
                    rgb[3 * idx + ch] = sensor.pixel(3 * idx + ch, c[ch]);
                }
            }
            rgb
        }
    }
}
