//! The robustness matrix of the segmentation (issue 9): rendered frames under
//! one perturbation at a time, scored against the renderer's ground truth in
//! the camera's working region. Shared by `tests/robustness.rs` (which
//! asserts the goals) and `examples/robustness_table.rs` (which prints the
//! table of the crate docs).
#![allow(dead_code)] // each user takes what it needs

use kflex_estimate::{EstimateError, Segmenter};
use kflex_model::{
    Background, Camera, Frame, FrameParams, Instrument, InstrumentShape, Mask, Occlusion, Part,
    Rasterizer, Roi, SceneRenderer, Tissue, WorkingRegions,
};

/// Bends of the matrix, deg.
pub const THETAS_DEG: [f64; 5] = [-60.0, -30.0, 0.0, 30.0, 60.0];
/// Translations of the matrix, mm.
pub const DS_MM: [f64; 3] = [8.0, 20.0, 35.0];
/// Issue 9's goal for a case's IoU in its working region.
#[allow(dead_code)] // read by the examples
pub const GOAL_ROI: f64 = 0.90;
/// Issue 9's goal for a case's IoU on the bend and gripper alone.
#[allow(dead_code)] // read by the examples
pub const GOAL_DISTAL: f64 = 0.85;
/// Distal truth smaller than this (px in the region) is not scored: at d = 0
/// little of the bend and gripper is out of the overtube.
pub const MIN_DISTAL_PX: usize = 200;

/// One perturbation of the frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    /// Default frame parameters.
    Baseline,
    /// Illumination gain.
    Gain(f64),
    /// Sensor noise σ on the [0, 1] image.
    Noise(f64),
    /// Gaussian blur σ, px.
    Blur(f64),
    /// Instrument pixels blended toward the mean tissue colour by this share.
    Tint(f64),
    /// Clipped-white streaks and blobs over tissue and over the instrument.
    Specular,
    /// The tissue repainted in the scene (the steel reflects it).
    Tissue(Tissue),
    /// The whole 8-bit frame multiplied by this factor.
    Dim(f64),
    /// Red tape over this share of the instrument in the working region, at
    /// this position along it (0.5 the middle, 1 the distal end): the
    /// paper's occlusions. The taped part is not instrument in the truth.
    Tape(f64, f64),
}

impl Condition {
    /// The conditions the goals hold for (issue 9).
    pub const GOALS: [Condition; 12] = [
        Condition::Baseline,
        Condition::Gain(0.4),
        Condition::Gain(1.6),
        Condition::Noise(0.1),
        Condition::Blur(3.0),
        Condition::Tint(0.25),
        Condition::Specular,
        Condition::Tissue(Tissue::Grey),
        Condition::Tissue(Tissue::Pale),
        Condition::Tissue(Tissue::White),
        Condition::Tissue(Tissue::BlueGreen),
        Condition::Tissue(Tissue::Yellow),
    ];
    /// The edges of the ranges IBJAE's training frames are drawn from
    /// (`kflex_control::ImagePairsConfig::default`: gain 0.7–1.3, noise σ up
    /// to 0.02, blur up to 1.5 px): reported, and asserted over other
    /// backgrounds (the pairs are drawn on many).
    #[allow(dead_code)] // read by the examples and one test
    pub const TRAINING: [Condition; 4] = [
        Condition::Gain(0.7),
        Condition::Gain(1.3),
        Condition::Noise(0.02),
        Condition::Blur(1.5),
    ];
    /// The paper's tape (Tables V–VIII): 20 and 40 % over the middle and
    /// the distal part. A taped part is lost, as in the paper, so the goal is
    /// the visible rest, whole: asserted as measured (`tests/robustness.rs`),
    /// so that a rule on the instrument's shape that a cut instrument breaks
    /// shows here (no other condition cuts it in two).
    #[allow(dead_code)] // read by the examples and one test
    pub const TAPE: [Condition; 4] = [
        Condition::Tape(0.2, 0.5),
        Condition::Tape(0.4, 0.5),
        Condition::Tape(0.2, 1.0),
        Condition::Tape(0.4, 1.0),
    ];
    /// Past the goals: reported, not asserted.
    pub const BEYOND: [Condition; 4] = [
        Condition::Tint(0.35),
        Condition::Blur(6.0),
        Condition::Dim(0.25),
        Condition::Gain(0.25),
    ];

    /// A short name for tables and messages.
    pub fn name(&self) -> String {
        match self {
            Condition::Baseline => "baseline".into(),
            Condition::Gain(g) => format!("gain {g}"),
            Condition::Noise(s) => format!("noise σ {s}"),
            Condition::Blur(b) => format!("blur {b} px"),
            Condition::Tint(t) => format!("tint {:.0} %", 100.0 * t),
            Condition::Specular => "specular streaks".into(),
            Condition::Tissue(t) => format!("tissue {t:?}").to_lowercase(),
            Condition::Dim(f) => format!("frame ×{f}"),
            Condition::Tape(share, at) => format!(
                "tape {:.0} % {}",
                100.0 * share,
                if *at >= 1.0 { "distal" } else { "middle" }
            ),
        }
    }

    fn frame_params(&self, background: Background, seed: u64) -> FrameParams {
        let base = FrameParams {
            background,
            seed,
            ..FrameParams::default()
        };
        match *self {
            Condition::Gain(g) => FrameParams {
                illumination_gain: g,
                ..base
            },
            Condition::Noise(s) => FrameParams {
                noise_std: s,
                ..base
            },
            Condition::Blur(b) => FrameParams { blur_px: b, ..base },
            Condition::Tissue(tissue) => FrameParams { tissue, ..base },
            Condition::Tape(share, at) => FrameParams {
                occlusion: Some(Occlusion::new(share, at)),
                ..base
            },
            _ => base,
        }
    }
}

/// The instrument's parts in a frame, for the distal score.
#[derive(Debug, Clone)]
pub struct Parts {
    /// The bend and gripper's visible pixels.
    pub distal: Mask,
    /// The straight shaft's own pixels, visible or taped (not the bend's or
    /// the gripper's, wherever they lie in front of it).
    pub shaft: Mask,
}

impl Parts {
    /// Both masks cropped to `roi`.
    pub fn crop(&self, roi: Roi) -> Parts {
        Parts {
            distal: self.distal.crop(roi).expect("crop"),
            shaft: self.shaft.crop(roi).expect("crop"),
        }
    }
}

/// One scored frame.
#[derive(Debug, Clone, Copy)]
pub struct Score {
    /// IoU with the visible instrument in the region of interest.
    pub roi: f64,
    /// IoU on the bend and gripper alone (the shaft's own pixels left out of
    /// both masks); `None` where fewer than [`MIN_DISTAL_PX`] are in the region.
    pub distal: Option<f64>,
}

impl Score {
    /// The score of mask `found` against the visible instrument `truth` and
    /// the instrument's `parts`, all of one region.
    pub fn of(found: &Mask, truth: &Mask, parts: &Parts) -> Score {
        let roi = found.iou(truth).expect("same size");
        // leave the shaft's own pixels out of both masks, taped ones too: a
        // taped shaft pixel found is a fault of the shaft, not of the bend
        let (mut inter, mut union) = (0usize, 0usize);
        let pixels = found
            .data()
            .iter()
            .zip(parts.distal.data())
            .zip(parts.shaft.data());
        for ((&s, &d), &shaft) in pixels {
            if shaft != 0 {
                continue;
            }
            inter += usize::from(s != 0 && d != 0);
            union += usize::from(s != 0 || d != 0);
        }
        let distal = (parts.distal.count() >= MIN_DISTAL_PX).then(|| inter as f64 / union as f64);
        Score { roi, distal }
    }

    /// Whether the case reaches `roi_min` in the region and, where scored,
    /// `distal_min` on the bend and gripper.
    #[allow(dead_code)] // not every user of the module reads it
    pub fn meets(&self, roi_min: f64, distal_min: f64) -> bool {
        self.roi >= roi_min && self.distal.is_none_or(|d| d >= distal_min)
    }
}

/// A case of the matrix.
#[derive(Debug, Clone, Copy)]
pub struct Case {
    /// Background.
    pub background: Background,
    /// Bend, deg.
    pub theta_deg: f64,
    /// Translation, mm.
    pub d_mm: f64,
}

/// Every case: the three shipped backgrounds × [`THETAS_DEG`] × [`DS_MM`].
pub fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    for background in Background::ALL {
        for theta_deg in THETAS_DEG {
            for d_mm in DS_MM {
                out.push(Case {
                    background,
                    theta_deg,
                    d_mm,
                });
            }
        }
    }
    out
}

/// Renders frames for the matrix (one renderer: backgrounds are cached).
pub struct Bench {
    /// The camera (the default 640×480).
    pub camera: Camera,
    /// Its working regions: each case is segmented in the region IBJAE
    /// reads at its pose (the nearest band where the pose lies outside them).
    pub regions: WorkingRegions,
    /// The region of frames without the instrument: the band of (0°, 10 mm).
    pub roi: Roi,
    /// Added to each background's seed (0: the backgrounds the bounds were
    /// measured on; the examples read `KFLEX_MATRIX_SEED` into it to try others).
    pub seed_offset: u64,
    renderer: SceneRenderer,
    raster: Rasterizer,
}

impl Default for Bench {
    fn default() -> Self {
        let camera = Camera::default();
        let regions = WorkingRegions::full(&camera).expect("working regions");
        Self {
            roi: regions.at(0.0, 10.0).expect("band").roi,
            regions,
            camera,
            seed_offset: 0,
            renderer: SceneRenderer::new(),
            raster: Rasterizer::new(),
        }
    }
}

/// A deterministic xorshift stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl Bench {
    /// The region `case` is segmented in.
    pub fn roi_of(&self, case: Case) -> Roi {
        self.regions
            .nearest(case.theta_deg, case.d_mm)
            .expect("a band")
            .roi
    }

    fn seed(&self, background: Background) -> u64 {
        (3 + background as u64).wrapping_add(self.seed_offset)
    }

    /// The frame of `case` under `condition`, with the instrument's parts:
    /// the visible pixels that are not the straight shaft, and the shaft's
    /// own, visible or taped.
    pub fn frame(&mut self, case: Case, condition: Condition) -> (Frame, Parts) {
        let shape = Instrument::kflex()
            .shape(case.theta_deg, case.d_mm)
            .expect("pose in the workspace");
        let params = condition.frame_params(case.background, self.seed(case.background));
        let mut frame = self
            .renderer
            .render(&self.camera, &shape, &params)
            .expect("frame");
        let mut distal_shape: InstrumentShape = shape.clone();
        distal_shape.bodies.retain(|c| c.part != Part::Shaft);
        let (w, h) = (frame.width, frame.height);
        let mut distal = Mask::new(w, h).expect("mask");
        self.raster
            .silhouette(&self.camera, &distal_shape, &mut distal)
            .expect("silhouette");
        let (mut distal_visible, mut shaft) = (Vec::new(), Vec::new());
        let pixels = distal
            .data()
            .iter()
            .zip(frame.instrument.data())
            .zip(frame.occluder.data());
        for ((&d, &visible), &taped) in pixels {
            distal_visible.push(u8::from(d != 0 && visible != 0));
            shaft.push(u8::from(d == 0 && (visible != 0 || taped != 0)));
        }
        let parts = Parts {
            distal: Mask::from_raw(w, h, distal_visible).expect("mask"),
            shaft: Mask::from_raw(w, h, shaft).expect("mask"),
        };
        let seed = (case.theta_deg.to_bits() ^ case.d_mm.to_bits().rotate_left(17))
            .wrapping_add(case.background as u64)
            | 1;
        perturb(&mut frame, self.roi_of(case), condition, seed);
        (frame, parts)
    }

    /// Segments the frame of `case` under `condition` and scores it.
    ///
    /// # Errors
    /// The segmenter's error (e.g. no instrument).
    pub fn score(
        &mut self,
        segmenter: &mut Segmenter,
        case: Case,
        condition: Condition,
    ) -> Result<Score, EstimateError> {
        let (frame, parts) = self.frame(case, condition);
        let roi = self.roi_of(case);
        let seg = segmenter.segment(&frame.rgb, frame.width, frame.height, roi)?;
        let truth = frame.instrument.crop(roi).expect("crop");
        Ok(Score::of(&seg.full, &truth, &parts.crop(roi)))
    }

    /// A frame of `background` without the instrument, its tissue coloured
    /// `tissue`, its background seed `seed` moved by [`Bench::seed_offset`].
    pub fn empty_frame(&mut self, background: Background, tissue: Tissue, seed: u64) -> Frame {
        let shape = InstrumentShape::default();
        let params = FrameParams {
            background,
            tissue,
            seed: seed.wrapping_add(self.seed_offset),
            ..FrameParams::default()
        };
        self.renderer
            .render(&self.camera, &shape, &params)
            .expect("frame")
    }
}

/// Applies the image-space perturbations (the renderer does gain, noise and blur).
fn perturb(frame: &mut Frame, roi: Roi, condition: Condition, seed: u64) {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let instrument = frame.instrument.data().to_vec();
    let tissue = |i: usize| instrument[i] == 0 && frame.occluder.data()[i] == 0;
    let mut rgb = std::mem::take(&mut frame.rgb);
    match condition {
        Condition::Tint(share) => {
            // the mean tissue colour in the region of interest
            let mut sum = [0.0f64; 3];
            let mut n = 0.0;
            for y in roi.y0 as usize..(roi.y0 + roi.height) as usize {
                for x in roi.x0 as usize..(roi.x0 + roi.width) as usize {
                    let i = y * w + x;
                    if tissue(i) {
                        for (s, &c) in sum.iter_mut().zip(&rgb[3 * i..3 * i + 3]) {
                            *s += f64::from(c);
                        }
                        n += 1.0;
                    }
                }
            }
            let mean = sum.map(|s| s / n);
            for (i, &m) in instrument.iter().enumerate() {
                if m != 0 {
                    for (c, &t) in rgb[3 * i..3 * i + 3].iter_mut().zip(&mean) {
                        *c = ((1.0 - share) * f64::from(*c) + share * t).round() as u8;
                    }
                }
            }
        }
        Condition::Specular => {
            let mut rng = Rng(seed);
            let side = f64::from(roi.width.min(roi.height));
            let inside = |rng: &mut Rng, want_instrument: bool| {
                for _ in 0..10_000 {
                    let x = roi.x0 as usize + (rng.unit() * f64::from(roi.width)) as usize;
                    let y = roi.y0 as usize + (rng.unit() * f64::from(roi.height)) as usize;
                    if (instrument[y * w + x] != 0) == want_instrument {
                        return Some((x as f64, y as f64));
                    }
                }
                None
            };
            // three streaks and two blobs over tissue, two streaks and a blob over the instrument
            for (on_instrument, streak) in [
                (false, true),
                (false, true),
                (false, true),
                (false, false),
                (false, false),
                (true, true),
                (true, true),
                (true, false),
            ] {
                let Some((cx, cy)) = inside(&mut rng, on_instrument) else {
                    continue;
                };
                let angle = rng.unit() * std::f64::consts::PI;
                let (half_len, half_width) = if streak {
                    (side * (0.06 + 0.06 * rng.unit()), 1.5)
                } else {
                    (side * 0.02, side * 0.02)
                };
                let (ux, uy) = (angle.cos(), angle.sin());
                let reach = half_len.max(half_width).ceil() as i64 + 1;
                for dy in -reach..=reach {
                    for dx in -reach..=reach {
                        let (x, y) = (cx as i64 + dx, cy as i64 + dy);
                        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                            continue;
                        }
                        let (px, py) = (dx as f64, dy as f64);
                        let along = px * ux + py * uy;
                        let across = -px * uy + py * ux;
                        if along.abs() <= half_len && across.abs() <= half_width {
                            let i = y as usize * w + x as usize;
                            rgb[3 * i..3 * i + 3].fill(255);
                        }
                    }
                }
            }
        }
        Condition::Dim(f) => {
            for c in &mut rgb {
                *c = (f64::from(*c) * f).round() as u8;
            }
        }
        Condition::Baseline
        | Condition::Gain(_)
        | Condition::Noise(_)
        | Condition::Blur(_)
        | Condition::Tissue(_)
        | Condition::Tape(..) => {}
    }
    frame.rgb = rgb;
}

/// Minimum and median of `v` (NaN-free); `None` when empty.
pub fn min_median(v: &mut [f64]) -> Option<(f64, f64)> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some((v[0], v[v.len() / 2]))
}
