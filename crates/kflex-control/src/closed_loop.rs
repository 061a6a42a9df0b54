//! The closed loop: θ_d → compensator → plant → camera → estimator → θ̂ →
//! compensator, on the simulated robot.
//!
//! One control tick `k` (time `t_k = k·dt`) of [`ClosedLoopScenario::run`]:
//!
//! 1. θ_d(t_k) from the scenario's trajectory (the pre-roll's ramp first);
//! 2. the compensator turns θ_d and the last estimate θ̂ into θ_c (without a
//!    compensator, θ_c = θ_d);
//! 3. the plant answers θ_c ([`Plant::step`]);
//! 4. the camera captures when a frame period has passed
//!    ([`CameraTiming::rate_hz`]): the as-built instrument at the plant's
//!    new angle ([`BuildTolerances`]: the robot's own instrument and camera,
//!    not the nominal ones an estimator's database is made from), rendered
//!    in the window the estimator asks for; the frame is lost with
//!    [`CameraTiming::drop_probability`], else it arrives
//!    [`CameraTiming::latency_s`] later;
//! 5. the estimator steps with the command the plant answered and the newest
//!    frame that has arrived (older ones that arrived in the same tick are
//!    stale and skipped), and gives θ̂ for the next tick.
//!
//! The estimator is anything that implements [`AngleEstimator`]: the
//! paper's estimators (KBJAE, IBJAE, LBHJAE in `kflex-estimate`, with its
//! `onnx` and `index` features) or a stand-in such as [`NoisyTruth`].

use std::collections::VecDeque;

use kflex_model::{
    Bounds, BuildTolerances, BuiltInstrument, Camera, Command, Frame, FrameParams, Instrument,
    InstrumentShape, Num, Plant, Roi, SceneRenderer, TrajectorySampler,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::compensator::{Compensator, CompensatorConfig};
use crate::error::Result;
use crate::experiment::{OpenLoopScenario, Trace};
use crate::metrics;

/// When the camera takes frames and when they reach the estimator.
///
/// The defaults: 30 frames per second (the rate of the USB endoscope
/// class the paper mounts, and of its ROS pipeline), delivered at once and
/// never lost; latency and losses are there to try what a real pipeline
/// does to the loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraTiming {
    /// Frames per second, in `(0, 1000]`. A frame is captured at the end of
    /// the first control tick at or after each multiple of `1/rate_hz` s.
    pub rate_hz: f64,
    /// Capture to arrival at the estimator, s, in `[0, 10]`: the frame
    /// arrives at the first tick at or after its capture time plus this.
    pub latency_s: f64,
    /// Chance that a frame never arrives, in `[0, 1]`.
    pub drop_probability: f64,
}

impl Default for CameraTiming {
    fn default() -> Self {
        Self {
            rate_hz: 30.0,
            latency_s: 0.0,
            drop_probability: 0.0,
        }
    }
}

impl CameraTiming {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`crate::ControlError::OutOfRange`] naming `camera.rate_hz`,
    /// `camera.latency_s` or `camera.drop_probability` (NaN is out of every
    /// range).
    pub fn validate(&self) -> Result<()> {
        Bounds::open_closed(0.0, 1000.0).check("camera.rate_hz", self.rate_hz)?;
        Bounds::closed(0.0, 10.0).check("camera.latency_s", self.latency_s)?;
        Bounds::closed(0.0, 1.0).check("camera.drop_probability", self.drop_probability)?;
        Ok(())
    }
}

/// What an estimator wants from the camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameRequest {
    /// No frames (a kinematic estimator): nothing is rendered.
    None,
    /// The frames' timing and ground truth, not their pixels (a stand-in
    /// estimator): nothing is rendered, but frames are captured, delayed and
    /// dropped as the camera's would be.
    Timing,
    /// The pixels of this window of the camera's image.
    Pixels(Roi),
}

/// A frame as it reaches the estimator.
#[derive(Debug, Clone, Copy)]
pub struct CameraFrame<'a> {
    /// The rendered pixels of `window` (its width and height are the
    /// window's); `None` where the estimator asked for [`FrameRequest::Timing`].
    pub image: Option<&'a Frame>,
    /// Where the image's pixels lie in the camera's full image.
    pub window: Option<Roi>,
    /// When the frame was captured, s since the run's start.
    pub captured_s: f64,
    /// The command the plant had answered at capture (its translation is
    /// the pose's).
    pub command: Command,
    /// The plant's true angle at capture, deg: ground truth, for scoring and
    /// for stand-in estimators; an estimator of the real robot cannot know it.
    pub truth_theta_a_deg: f64,
}

/// One recorded tick, as [`ClosedLoopScenario::replay`] hands it to an estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplayTick {
    /// Time since the start of evaluation, s.
    pub time_s: f64,
    /// The command the plant answered.
    pub command: Command,
    /// The master's θ_d, deg.
    pub theta_d_deg: f64,
    /// Its rate, deg/s.
    pub theta_d_rate_deg_per_s: f64,
}

/// One control tick as the estimator sees it.
#[derive(Debug, Clone, Copy)]
pub struct EstimatorTick<'a> {
    /// Time since the run's start (pre-roll included), s.
    pub time_s: f64,
    /// Since the last tick, s.
    pub dt_s: f64,
    /// The command the plant answered this tick.
    pub command: Command,
    /// The master's command θ_d this tick, deg (θ_c where there is no
    /// compensator; in the pre-roll, the ramp's).
    pub theta_d_deg: f64,
    /// Its rate θ_d', deg/s (KBJAE's rate input).
    pub theta_d_rate_deg_per_s: f64,
    /// The newest frame that arrived this tick, if any.
    pub frame: Option<CameraFrame<'a>>,
}

/// A joint-angle estimator in the closed loop: stepped once per control
/// tick, after the plant.
pub trait AngleEstimator {
    /// What it wants from the camera for a frame captured now, with the
    /// plant at `command` (e.g. IBJAE: the working region of the band it
    /// would read).
    fn frame_request(&self, command: Command) -> FrameRequest;

    /// One tick: θ̂ in deg for the compensator's next tick, or `None` where
    /// the estimator has none yet (the compensator then counts toward its
    /// watchdog).
    ///
    /// # Errors
    /// The estimator's own faults; the run stops with them.
    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>>;

    /// [`AngleEstimator::step`] for one of several estimators stepped on
    /// the same tick (an experiment grid's estimation run): an IBJAE reader
    /// takes what a reader of the same models already read in this tick's
    /// frame from `reads` and leaves its own readings there
    /// ([`kflex_estimate::Ibjae::read_sharing`]), so that the frame is
    /// segmented, embedded and searched once. The estimate must be
    /// [`AngleEstimator::step`]'s; the caller clears `reads` before each
    /// tick. By default, `step`.
    ///
    /// # Errors
    /// As [`AngleEstimator::step`].
    #[cfg(feature = "estimators")]
    fn step_sharing(
        &mut self,
        tick: &EstimatorTick<'_>,
        reads: &mut kflex_estimate::FrameReads,
    ) -> Result<Option<f64>> {
        let _ = reads;
        self.step(tick)
    }

    /// Back to the state before the first tick.
    fn reset(&mut self);

    /// What went into the last tick's estimate, as far as the estimator
    /// tells (the readings it fused, its uncertainty, what it did with each
    /// reading), for logs and for studying the estimator offline; every
    /// field `None` by default.
    fn details(&self) -> TickDetails {
        TickDetails::default()
    }
}

/// What a fusion step did with a reading (`kflex_estimate::SensorUse`;
/// a gated reading's normalised innovation is in [`TickDetails`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum ReadingUse {
    /// It updated the estimate.
    Used,
    /// There was none this tick.
    Missing,
    /// The filter did not step this tick (the paper's filter "as written").
    Held,
    /// The filter rejected it (the chi-square gate, or a reading that
    /// reports itself too uncertain or with a hidden part).
    Gated,
    /// A use this version does not name (also what a log from a later
    /// version reads as where it names one this version does not know).
    #[serde(other)]
    Other,
}

impl ReadingUse {
    /// The use and, for a gated reading, its `ν²/S`.
    #[must_use]
    pub fn of(u: kflex_estimate::SensorUse) -> (Self, Option<f64>) {
        use kflex_estimate::SensorUse;
        match u {
            SensorUse::Used => (Self::Used, None),
            SensorUse::Missing => (Self::Missing, None),
            SensorUse::Held => (Self::Held, None),
            SensorUse::Gated { nis } => (Self::Gated, Some(nis)),
            _ => (Self::Other, None),
        }
    }
}

/// What went into one tick's estimate ([`AngleEstimator::details`]): each
/// field `None` where the estimator has no such thing this tick. LBHJAE
/// gives its uncertainty (σ, for plotting, and the covariance) and rate,
/// KBJAE's reading and what the filter did with each reading every tick,
/// and IBJAE's reading on the ticks that read a frame (its silhouette IoU with the silhouette check, its consistent
/// bends where it took a part as hidden, `ν²/S` where the filter gated it);
/// IBJAE alone its reading; KBJAE nothing (its reading is its estimate).
/// `frame_arrived` is the loop's, whatever the estimator: whether the run's
/// camera delivered a frame this tick (where several estimators share a
/// run, to each of them, including one that asked for none and ignores
/// it; one that arrived but gave a camera estimator no reading had no
/// instrument in it, or was taken for a window it no longer reads). Angles
/// in deg.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default)]
#[non_exhaustive]
pub struct TickDetails {
    /// Whether the run's camera delivered a frame this tick (set by the
    /// loop: [`ClosedLoopScenario::run`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_arrived: Option<bool>,
    /// The estimate's standard deviation, √P_θθ of the fusion filter.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta_hat_sigma_deg: Option<f64>,
    /// The fusion's estimate of the rate, deg/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta_hat_rate_deg_per_s: Option<f64>,
    /// The fusion filter's covariance of `[θ̂, θ̂']`, deg², deg²/s, deg²/s².
    #[serde(skip_serializing_if = "Option::is_none")]
    pub theta_hat_covariance: Option<[[f64; 2]; 2]>,
    /// KBJAE's angle.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kbjae_deg: Option<f64>,
    /// What the fusion did with it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kbjae_use: Option<ReadingUse>,
    /// IBJAE's angle, where it read a frame this tick.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_deg: Option<f64>,
    /// The uncertainty IBJAE gives its reading.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_sigma_deg: Option<f64>,
    /// The IoU of the segmented silhouette with the nominal one of the pose
    /// read (IBJAE's silhouette check).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_silhouette_iou: Option<f64>,
    /// Whether IBJAE took part of the instrument as hidden (tape).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_occluded: Option<bool>,
    /// With a hidden part, the lowest and highest bends consistent with the
    /// visible pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_consistent_deg: Option<[f64; 2]>,
    /// What the fusion did with IBJAE's reading.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_use: Option<ReadingUse>,
    /// A gated reading's normalised innovation squared `ν²/S`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ibjae_nis: Option<f64>,
}

impl TickDetails {
    /// These details with `frame_arrived` set (by the loop that delivered,
    /// or did not deliver, a frame this tick).
    #[must_use]
    pub(crate) fn with_frame(self, arrived: bool) -> Self {
        Self {
            frame_arrived: Some(arrived),
            ..self
        }
    }
}

/// A stand-in for a camera-based estimator: the plant's true angle at each
/// frame's capture plus Gaussian noise of `sigma_deg`, held between frames.
/// No pixels are rendered. It measures what the loop's timing and a
/// sensor's noise do to compensation, apart from any estimator's errors.
#[derive(Debug, Clone)]
pub struct NoisyTruth {
    sigma_deg: f64,
    rng: ChaCha8Rng,
    seed: u64,
    last: Option<f64>,
    /// Whether the last tick had a frame.
    read: bool,
}

impl NoisyTruth {
    /// Noise of `sigma_deg` (in `[0, 90]`), drawn from `seed`.
    ///
    /// # Errors
    /// [`crate::ControlError::OutOfRange`] naming `sigma_deg`.
    pub fn new(sigma_deg: f64, seed: u64) -> Result<Self> {
        Bounds::closed(0.0, 90.0).check("sigma_deg", sigma_deg)?;
        Ok(Self {
            sigma_deg,
            rng: ChaCha8Rng::seed_from_u64(seed),
            seed,
            last: None,
            read: false,
        })
    }
}

impl AngleEstimator for NoisyTruth {
    fn frame_request(&self, _command: Command) -> FrameRequest {
        FrameRequest::Timing
    }

    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        self.read = tick.frame.is_some();
        if let Some(frame) = tick.frame {
            self.last = Some(
                frame.truth_theta_a_deg
                    + self.sigma_deg * self.rng.sample::<f64, _>(StandardNormal),
            );
        }
        Ok(self.last)
    }

    fn reset(&mut self) {
        self.rng = ChaCha8Rng::seed_from_u64(self.seed);
        self.last = None;
        self.read = false;
    }

    /// A stand-in camera: on a tick with a frame, its reading (the
    /// estimate) and its noise as IBJAE's fields.
    fn details(&self) -> TickDetails {
        let reading = self.last.filter(|_| self.read);
        TickDetails {
            ibjae_deg: reading,
            ibjae_sigma_deg: reading.map(|_| self.sigma_deg),
            ..TickDetails::default()
        }
    }
}

/// One closed-loop run's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClosedLoopScenario {
    /// The input, its duration, the control tick and the pre-roll (as the
    /// open-loop experiments').
    pub motion: OpenLoopScenario,
    /// The camera's timing.
    pub camera: CameraTiming,
    /// How frames look: background, tissue, illumination, sensor noise,
    /// blur, tape. Its `seed` is replaced by the run's, its `frame` counts
    /// the frames.
    pub frames: FrameParams,
    /// How the robot's instrument and camera differ from the nominal design.
    pub tolerances: BuildTolerances,
    /// The compensator between θ_d and the plant; `None`: θ_c = θ_d (an
    /// estimation run, as the paper's estimation experiments).
    pub compensator: Option<CompensatorConfig>,
    /// Keep every rendered frame of the evaluated part in the trace
    /// ([`ClosedLoopTrace::camera_frames`], and so in its MCAP log): some
    /// 200 KB a frame of IBJAE's window, 190 MB a run of five periods at 30
    /// frames/s (its log about 250 MB: the images are base64 in JSON, as
    /// Foxglove reads them). A grid keeps one run's frames per thread at a
    /// time, and an estimation run writes them into each of its estimators'
    /// logs. Off by default.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub record_frames: bool,
}

impl Default for ClosedLoopScenario {
    fn default() -> Self {
        Self {
            motion: OpenLoopScenario::default(),
            camera: CameraTiming::default(),
            frames: FrameParams::default(),
            tolerances: BuildTolerances::default(),
            compensator: Some(CompensatorConfig::default()),
            record_frames: false,
        }
    }
}

/// What the camera did during a run (pre-roll included).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct FrameCounts {
    /// Frames captured.
    pub captured: usize,
    /// Frames lost on the way.
    pub dropped: usize,
    /// Frames handed to the estimator.
    pub delivered: usize,
    /// Frames that arrived in a tick with a newer one, and were skipped.
    pub stale: usize,
}

/// A recorded closed-loop run: one row per evaluated tick.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoopTrace {
    /// θ_d, θ_a and the measured θ_a against time, as an open-loop run's.
    pub trace: Trace,
    /// θ_c sent to the plant, deg.
    pub theta_c_deg: Vec<f64>,
    /// The estimate θ̂ after each tick, deg; `None` before the estimator
    /// had one.
    pub theta_hat_deg: Vec<Option<f64>>,
    /// What went into each tick's estimate ([`AngleEstimator::details`]).
    #[serde(default)]
    pub details: Vec<TickDetails>,
    /// Ticks in which the compensator held its command for a fault.
    pub fault_ticks: usize,
    /// The camera's frames.
    pub frames: FrameCounts,
    /// With [`ClosedLoopScenario::record_frames`]: every frame rendered in
    /// the evaluated part, in capture order (dropped frames are never
    /// rendered). Not serialised with the trace; its MCAP log holds them.
    #[serde(skip)]
    pub camera_frames: Vec<RecordedFrame>,
}

/// A rendered frame of a run, as its MCAP log records it.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedFrame {
    /// Capture time, s since the start of evaluation.
    pub captured_s: f64,
    /// When it reaches the estimator, s since the start of evaluation.
    pub arrives_s: f64,
    /// Where its pixels lie in the camera's full image.
    pub window: Roi,
    /// The window's pixels, RGB, row-major, `3 × width × height` bytes.
    pub rgb: Vec<u8>,
    /// The command the plant had answered at capture.
    pub command: Command,
    /// The plant's true angle at capture, deg (ground truth).
    pub truth_theta_a_deg: f64,
}

impl RecordedFrame {
    /// Why the frame cannot be replayed as recorded, if it cannot: a window
    /// wider or taller than [`kflex_model::MAX_IMAGE_SIDE`] or reaching past
    /// it, pixels that do not fill it exactly, a NaN or infinite time, or a
    /// command no run can have given (see [`replay_command_error`]).
    #[must_use]
    pub fn fill_error(&self) -> Option<String> {
        let (w, h) = (self.window.width, self.window.height);
        let side = u64::from(kflex_model::MAX_IMAGE_SIDE);
        if w > kflex_model::MAX_IMAGE_SIDE
            || h > kflex_model::MAX_IMAGE_SIDE
            || self.rgb.len() as u128 != 3 * u128::from(w) * u128::from(h)
        {
            return Some(format!(
                "a recorded frame of {} bytes does not fill its {w}×{h} window",
                self.rgb.len()
            ));
        }
        if u64::from(self.window.x0) + u64::from(w) > side
            || u64::from(self.window.y0) + u64::from(h) > side
        {
            return Some(format!(
                "a recorded frame's {w}×{h} window at ({}, {}) reaches past any image's side ({side} px)",
                self.window.x0, self.window.y0
            ));
        }
        if !(self.captured_s.is_finite() && self.arrives_s.is_finite()) {
            return Some(format!(
                "a recorded frame's capture or arrival time is not finite (captured_s {}, arrives_s {})",
                Num(self.captured_s),
                Num(self.arrives_s)
            ));
        }
        replay_command_error(&self.command).map(|e| format!("a recorded frame's {e}"))
    }
}

/// The largest joint angle a replay reads, deg: a full turn each way (the
/// joint's hard stops lie well inside; a log past it holds no joint's angle).
pub const REPLAY_MAX_ANGLE_DEG: f64 = 360.0;

/// The translations a replay reads, mm: those any stage's limits can allow
/// (`kflex_model::TranslationParams::validate`).
const REPLAY_TRANSLATION_MM: [f64; 2] = [0.0, 1e3];

/// Why a recorded command cannot be one a run gave, if it cannot: θ_c NaN,
/// infinite or past ±[`REPLAY_MAX_ANGLE_DEG`], or a translation NaN or
/// outside 0–1,000 mm (an estimator reads its working band from it).
#[must_use]
pub fn replay_command_error(command: &Command) -> Option<String> {
    let (theta, d) = (command.theta_c_deg, command.translation_mm);
    if !(theta.is_finite() && theta.abs() <= REPLAY_MAX_ANGLE_DEG) {
        return Some(format!(
            "command theta_c_deg = {} is outside ±{REPLAY_MAX_ANGLE_DEG} deg",
            Num(theta)
        ));
    }
    let [lo, hi] = REPLAY_TRANSLATION_MM;
    if !(lo..=hi).contains(&d) {
        return Some(format!(
            "command translation_mm = {} is outside [{lo}, {hi}] mm",
            Num(d)
        ));
    }
    None
}

impl ClosedLoopTrace {
    /// RMSE of the estimate against the plant's true angle over the ticks
    /// that have one, deg.
    ///
    /// # Errors
    /// [`crate::ControlError::NotEnoughData`] where no tick has an estimate.
    pub fn estimation_rmse_deg(&self) -> Result<f64> {
        estimation_rmse_deg(&self.trace.theta_a_deg, &self.theta_hat_deg)
    }
}

/// RMSE of `estimate` against `truth` over the ticks that have an estimate
/// (the two series aligned at their ends: an estimator's series may begin
/// earlier, with the pre-roll), deg.
///
/// # Errors
/// [`crate::ControlError::NotEnoughData`] where no tick has an estimate.
pub fn estimation_rmse_deg(truth: &[f64], estimate: &[Option<f64>]) -> Result<f64> {
    let estimate = &estimate[estimate.len().saturating_sub(truth.len())..];
    let truth = &truth[truth.len().saturating_sub(estimate.len())..];
    let (truth, estimate): (Vec<f64>, Vec<f64>) = truth
        .iter()
        .zip(estimate)
        .filter_map(|(&a, h)| h.map(|h| (a, h)))
        .unzip();
    metrics::rmse(&truth, &estimate)
}

/// A frame on its way to the estimator.
struct InFlight {
    arrives_s: f64,
    image: Option<Frame>,
    window: Option<Roi>,
    captured_s: f64,
    command: Command,
    truth_theta_a_deg: f64,
}

/// The simulated robot's camera: the as-built instrument and camera, the
/// renderer and the frames in flight.
struct RobotCamera {
    camera: Camera,
    instrument: BuiltInstrument,
    renderer: SceneRenderer,
    shape: InstrumentShape,
    params: FrameParams,
    in_flight: VecDeque<InFlight>,
    rng: ChaCha8Rng,
    counts: FrameCounts,
    next_capture: u64,
}

impl RobotCamera {
    fn new(scenario: &ClosedLoopScenario, seed: u64) -> Result<Self> {
        let tolerances = &scenario.tolerances;
        Ok(Self {
            camera: tolerances.camera(&Camera::default(), seed)?,
            instrument: tolerances.instrument(&Instrument::kflex(), seed)?,
            renderer: SceneRenderer::new(),
            shape: InstrumentShape::default(),
            params: FrameParams {
                seed,
                ..scenario.frames
            },
            in_flight: VecDeque::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x6361_6d65_7261),
            counts: FrameCounts::default(),
            next_capture: 0,
        })
    }

    /// Captures a frame if one is due at `time_s` (the end of a tick), of
    /// what `estimator` asks for then (asked only when a frame is due).
    fn capture(
        &mut self,
        timing: &CameraTiming,
        time_s: f64,
        command: Command,
        theta_a_deg: f64,
        estimator: &dyn AngleEstimator,
    ) -> Result<()> {
        // due: the next multiple of the frame period has been reached
        // (a small tolerance absorbs the ticks' rounding); one frame
        // however many periods a long tick spans
        let due = |n: u64| n as f64 / timing.rate_hz <= time_s + 1e-9;
        if !due(self.next_capture) {
            return Ok(());
        }
        while due(self.next_capture) {
            self.next_capture += 1;
        }
        let request = estimator.frame_request(command);
        if request == FrameRequest::None {
            return Ok(());
        }
        self.counts.captured += 1;
        self.params.frame += 1;
        if self.rng.random::<f64>() < timing.drop_probability {
            self.counts.dropped += 1;
            return Ok(());
        }
        let (image, window) = match request {
            FrameRequest::Pixels(window) => {
                self.instrument
                    .shape_into(theta_a_deg, command.translation_mm, &mut self.shape)?;
                let frame =
                    self.renderer
                        .render_window(&self.camera, &self.shape, &self.params, window)?;
                (Some(frame), Some(window))
            }
            FrameRequest::Timing | FrameRequest::None => (None, None),
        };
        self.in_flight.push_back(InFlight {
            arrives_s: time_s + timing.latency_s,
            image,
            window,
            captured_s: time_s,
            command,
            truth_theta_a_deg: theta_a_deg,
        });
        Ok(())
    }

    /// The frame [`RobotCamera::capture`] has just put in flight, if it
    /// rendered one, as a recording with its times shifted by `-offset_s`.
    fn record_last(&self, since: usize, offset_s: f64) -> Option<RecordedFrame> {
        if self.in_flight.len() <= since {
            return None;
        }
        let f = self.in_flight.back()?;
        let (image, window) = (f.image.as_ref()?, f.window?);
        Some(RecordedFrame {
            captured_s: f.captured_s - offset_s,
            arrives_s: f.arrives_s - offset_s,
            window,
            rgb: image.rgb.clone(),
            command: f.command,
            truth_theta_a_deg: f.truth_theta_a_deg,
        })
    }

    /// The newest frame that has arrived by `time_s`; older arrivals are stale.
    fn arrived(&mut self, time_s: f64) -> Option<InFlight> {
        let mut newest = None;
        while self
            .in_flight
            .front()
            .is_some_and(|f| f.arrives_s <= time_s + 1e-9)
        {
            if newest.is_some() {
                self.counts.stale += 1;
            }
            newest = self.in_flight.pop_front();
        }
        if newest.is_some() {
            self.counts.delivered += 1;
        }
        newest
    }
}

impl ClosedLoopScenario {
    /// Checks every setting before anything moves.
    ///
    /// # Errors
    /// As [`OpenLoopScenario::run`]'s checks, [`CameraTiming::validate`],
    /// [`FrameParams::validate`], [`BuildTolerances::validate`] and
    /// [`CompensatorConfig::validate`].
    pub fn validate(&self) -> Result<()> {
        self.checked().map(|_| ())
    }

    /// [`ClosedLoopScenario::validate`], returning the prepared trajectory.
    fn checked(&self) -> Result<TrajectorySampler> {
        let sampler = self.motion.validate()?;
        self.camera.validate()?;
        self.frames.validate()?;
        self.tolerances.validate()?;
        if let Some(c) = &self.compensator {
            c.validate()?;
            // the compensator steps at most a second at a time
            // (`Compensator::step`), and would otherwise hold every tick
            Bounds::open_closed(0.0, crate::compensator::MAX_STEP_S)
                .check("dt_s", self.motion.dt_s)?;
        }
        Ok(sampler)
    }

    /// Runs the loop on `plant` (from its current state) with `estimator`,
    /// the camera's frames and losses drawn from `seed`, and records the
    /// evaluated part. The estimator is reset first.
    ///
    /// # Errors
    /// Every setting is checked first, before the plant moves (see
    /// [`ClosedLoopScenario::validate`]). Then, stopping the run: the
    /// plant's errors (e.g. a translation outside the workspace), the
    /// renderer's (a requested window outside the image), the estimator's.
    pub fn run(
        &self,
        plant: &mut Plant,
        estimator: &mut dyn AngleEstimator,
        seed: u64,
    ) -> Result<ClosedLoopTrace> {
        let sampler = self.checked()?;
        let motion = &self.motion;
        let mut compensator = self.compensator.map(Compensator::new).transpose()?;
        let mut camera = RobotCamera::new(self, seed)?;
        estimator.reset();
        let dt = motion.dt_s;
        let start = sampler.sample(0.0).theta_d_deg;
        let rest = plant.state().command.theta_c_deg;
        let pre_roll: Vec<f64> = motion.pre_roll(rest, start).collect();
        let n = motion.evaluated_ticks();
        let mut out = ClosedLoopTrace::default();
        let mut theta_hat = None;
        for k in 0..pre_roll.len() + n {
            let time_s = (k + 1) as f64 * dt;
            // the evaluated part starts after the pre-roll, at its own t = 0
            let evaluated = k.checked_sub(pre_roll.len());
            let (theta_d, rate) = match evaluated {
                Some(j) => {
                    let s = sampler.sample((j + 1) as f64 * dt);
                    (s.theta_d_deg, s.theta_d_rate_deg_per_s)
                }
                None => {
                    let before = k.checked_sub(1).map_or(rest, |i| pre_roll[i]);
                    (pre_roll[k], (pre_roll[k] - before) / dt)
                }
            };
            let theta_c = match compensator.as_mut() {
                Some(c) => {
                    let o = c.step(theta_d, theta_hat, dt);
                    out.fault_ticks += usize::from(o.fault.is_some() && evaluated.is_some());
                    o.theta_c_deg
                }
                None => theta_d,
            };
            let command = Command {
                theta_c_deg: theta_c,
                translation_mm: motion.translation_mm,
            };
            let state = plant.step(command, dt)?;
            let in_flight = camera.in_flight.len();
            camera.capture(&self.camera, time_s, command, state.theta_a_deg, estimator)?;
            if self.record_frames
                && evaluated.is_some()
                && let Some(f) = camera.record_last(in_flight, pre_roll.len() as f64 * dt)
            {
                out.camera_frames.push(f);
            }
            let arrived = camera.arrived(time_s);
            let frame = arrived.as_ref().map(|f| CameraFrame {
                image: f.image.as_ref(),
                window: f.window,
                captured_s: f.captured_s,
                command: f.command,
                truth_theta_a_deg: f.truth_theta_a_deg,
            });
            theta_hat = estimator.step(&EstimatorTick {
                time_s,
                dt_s: dt,
                command,
                theta_d_deg: theta_d,
                theta_d_rate_deg_per_s: rate,
                frame,
            })?;
            if let Some(j) = evaluated {
                let t = &mut out.trace;
                t.time_s.push((j + 1) as f64 * dt);
                t.theta_d_deg.push(theta_d);
                t.theta_d_rate_deg_per_s.push(rate);
                t.theta_a_deg.push(state.theta_a_deg);
                t.theta_a_measured_deg.push(state.theta_a_measured_deg);
                out.theta_c_deg.push(theta_c);
                out.theta_hat_deg.push(theta_hat);
                out.details
                    .push(estimator.details().with_frame(frame.is_some()));
            }
        }
        out.frames = camera.counts;
        Ok(out)
    }

    /// Replays `estimator` over a recorded run of this scenario: the
    /// evaluated `ticks` (each with its time, s since the start of
    /// evaluation, `(j + 1)·dt_s` for tick `j` of a kflex run; the command
    /// the plant answered; the master's θ_d and rate) and the `frames` the
    /// run rendered (times on the same clock), each handed over at the first
    /// tick at or after its arrival (the newest one where several arrive, as
    /// the run does). The estimator is reset, then stepped through the
    /// pre-roll first: from rest to θ_d(0) as the run's (exact for an
    /// estimation run, θ_c = θ_d; for a compensated run the pre-roll's
    /// commands were the compensator's and are not recorded, so the ramp ends
    /// at the first recorded command instead), without frames, since a log
    /// holds only the evaluated part's. Its estimate after every evaluated tick.
    ///
    /// # Errors
    /// As [`ClosedLoopScenario::validate`]; the estimator's errors; a frame
    /// [`RecordedFrame::fill_error`] refuses (pixels that do not fill its
    /// window, a window past any image's side, a NaN time, a command no
    /// run gave: [`replay_command_error`]), or a tick with a NaN or
    /// infinite time, θ_d or rate, or such a command
    /// ([`crate::ControlError::Worker`]).
    pub fn replay(
        &self,
        estimator: &mut dyn AngleEstimator,
        ticks: &[ReplayTick],
        frames: &[RecordedFrame],
    ) -> Result<Vec<Option<f64>>> {
        Ok(self.replay_with_details(estimator, ticks, frames)?.0)
    }

    /// [`ClosedLoopScenario::replay`], with what went into each estimate
    /// ([`AngleEstimator::details`], `frame_arrived` set as a run sets it,
    /// except before the first logged frame arrives: a frame captured in
    /// the pre-roll is not in a log), aligned with the estimates.
    ///
    /// # Errors
    /// As [`ClosedLoopScenario::replay`].
    pub fn replay_with_details(
        &self,
        estimator: &mut dyn AngleEstimator,
        ticks: &[ReplayTick],
        frames: &[RecordedFrame],
    ) -> Result<(Vec<Option<f64>>, Vec<TickDetails>)> {
        let sampler = self.checked()?;
        let motion = &self.motion;
        let dt = motion.dt_s;
        if let Some(message) = frames.iter().find_map(RecordedFrame::fill_error) {
            return Err(crate::ControlError::Worker { message });
        }
        if let Some(message) = ticks.iter().enumerate().find_map(|(i, t)| {
            let finite = [t.time_s, t.theta_d_deg, t.theta_d_rate_deg_per_s]
                .iter()
                .all(|v| v.is_finite());
            if finite {
                replay_command_error(&t.command).map(|e| format!("replay tick {i}: {e}"))
            } else {
                Some(format!(
                    "replay tick {i}: time_s {}, theta_d_deg {}, theta_d_rate_deg_per_s {}: \
                     each must be finite",
                    Num(t.time_s),
                    Num(t.theta_d_deg),
                    Num(t.theta_d_rate_deg_per_s)
                ))
            }
        }) {
            return Err(crate::ControlError::Worker { message });
        }
        // each frame is built when it is handed over
        let image_of = |f: &RecordedFrame| -> Result<Frame> {
            let (w, h) = (f.window.width, f.window.height);
            Ok(Frame {
                width: w,
                height: h,
                rgb: f.rgb.clone(),
                instrument: kflex_model::Mask::new(w, h)?,
                occluder: kflex_model::Mask::new(w, h)?,
            })
        };
        estimator.reset();
        let target = match (self.compensator, ticks.first()) {
            (Some(_), Some(t)) => t.command.theta_c_deg,
            _ => sampler.sample(0.0).theta_d_deg,
        };
        let translation_mm = ticks
            .first()
            .map_or(motion.translation_mm, |t| t.command.translation_mm);
        let pre_roll: Vec<f64> = motion.pre_roll(0.0, target).collect();
        // the master's own ramp, to θ_d(0) (the commands' ends at the first
        // recorded command where a compensator made them)
        let master: Vec<f64> = motion
            .pre_roll(0.0, sampler.sample(0.0).theta_d_deg)
            .collect();
        // times since the run's start, pre-roll included, as the run's
        let offset_s = pre_roll.len() as f64 * dt;
        for (k, (&theta_c_deg, &theta_d_deg)) in pre_roll.iter().zip(&master).enumerate() {
            let before = k.checked_sub(1).map_or(0.0, |i| master[i]);
            estimator.step(&EstimatorTick {
                time_s: (k + 1) as f64 * dt,
                dt_s: dt,
                command: Command {
                    theta_c_deg,
                    translation_mm,
                },
                theta_d_deg,
                theta_d_rate_deg_per_s: (theta_d_deg - before) / dt,
                frame: None,
            })?;
        }
        let mut out = Vec::with_capacity(ticks.len());
        let mut details = Vec::with_capacity(ticks.len());
        let mut next = 0;
        for tick in ticks {
            let (command, time_s) = (tick.command, offset_s + tick.time_s);
            // the newest frame that has arrived by now
            let mut arrived = None;
            while next < frames.len() && frames[next].arrives_s + offset_s <= time_s + 1e-9 {
                arrived = Some(next);
                next += 1;
            }
            let image = arrived.map(|i| image_of(&frames[i])).transpose()?;
            let frame = arrived.map(|i| CameraFrame {
                image: image.as_ref(),
                window: Some(frames[i].window),
                captured_s: frames[i].captured_s + offset_s,
                command: frames[i].command,
                truth_theta_a_deg: frames[i].truth_theta_a_deg,
            });
            out.push(estimator.step(&EstimatorTick {
                time_s,
                dt_s: dt,
                command,
                theta_d_deg: tick.theta_d_deg,
                theta_d_rate_deg_per_s: tick.theta_d_rate_deg_per_s,
                frame,
            })?);
            details.push(estimator.details().with_frame(frame.is_some()));
        }
        Ok((out, details))
    }
}
