//! MCAP logs of closed-loop runs (cargo feature `mcap`), for Foxglove and
//! for re-reading a run.
//!
//! Every channel is JSON-encoded with a `jsonschema` schema, every message
//! logged at its time since the start of evaluation:
//! * [`JOINT_STATES_TOPIC`] ([`JOINT_STATE_SCHEMA`]): one message per
//!   evaluated tick with θ_d, its rate, θ_c, the true and the measured θ_a
//!   and the estimate θ̂ (`null` before the estimator had one); and, where
//!   the estimator tells them ([`TickDetails`]), θ̂'s standard deviation,
//!   rate and covariance, the readings it fused (KBJAE's angle; IBJAE's angle,
//!   uncertainty, silhouette IoU, hidden part and consistent bends on the
//!   ticks that read a frame) and what it did with each (`used`, `gated`
//!   with `ν²/S`, `missing`, `held`), and whether a frame reached it that
//!   tick: fields left out where there is none;
//! * where the run recorded its frames ([`ClosedLoopScenario::record_frames`]),
//!   per frame rendered, at its capture: [`IMAGE_TOPIC`], the window's
//!   pixels as a `foxglove.RawImage` (`rgb8`, the bytes in base64, as
//!   Foxglove reads JSON images; [`RAW_IMAGE_SCHEMA`]);
//!   [`SILHOUETTE_TOPIC`], kflex's segmentation of that whole window
//!   resampled to 48 × 48 (`mono8`, 255 instrument, an all-zero image where
//!   it found none; IBJAE segments each of its bands' own regions, which the
//!   window holds: for one band the two are the same); and [`CAMERA_FRAMES_TOPIC`]
//!   ([`CAMERA_FRAME_SCHEMA`]): where the window lies in the camera's image,
//!   when the frame reaches the estimator, the command and the true angle at
//!   capture. The three share the frame's sequence number.
//!
//! A metadata record `kflex.run` holds the scenario (its JSON form) and the
//! run's seed. The file is written beside its path and renamed into place
//! when complete, so a log is never half-written.
//!
//! [`read_mcap`] reads uncompressed logs, as kflex writes them; a log
//! compressed with zstd or lz4 (Python's `mcap` writer compresses with
//! zstd by default: pass `compression=CompressionType.NONE`) is refused
//! saying so. Its joint states must follow one another in time.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use serde::Serialize;

use crate::closed_loop::{
    ClosedLoopScenario, ClosedLoopTrace, REPLAY_MAX_ANGLE_DEG, RecordedFrame, ReplayTick,
    TickDetails, replay_command_error,
};
use crate::error::{ControlError, Result};
use kflex_model::{Command, Num, Roi};

/// The joint states' topic.
pub const JOINT_STATES_TOPIC: &str = "/kflex/joint_states";

/// The joint states' schema name.
pub const JOINT_STATE_SCHEMA_NAME: &str = "kflex.JointState";

/// The JSON schema of a joint-state message.
pub const JOINT_STATE_SCHEMA: &str = r#"{
  "title": "kflex.JointState",
  "description": "One control tick of a kflex closed-loop run; angles in degrees",
  "type": "object",
  "properties": {
    "time_s": {"type": "number", "description": "time since the start of evaluation, s"},
    "theta_d_deg": {"type": "number", "description": "desired angle"},
    "theta_d_rate_deg_per_s": {"type": "number", "description": "its rate, deg/s"},
    "theta_c_deg": {"type": "number", "description": "command sent to the plant"},
    "theta_a_deg": {"type": "number", "description": "true joint angle"},
    "theta_a_measured_deg": {"type": "number", "description": "joint angle as the tracker measured it"},
    "theta_hat_deg": {"type": ["number", "null"], "description": "the estimate; null before the estimator had one"},
    "frame_arrived": {"type": "boolean", "description": "whether the run's camera delivered a frame this tick"},
    "theta_hat_sigma_deg": {"type": "number", "description": "the estimate's standard deviation (a fusion filter's)"},
    "theta_hat_rate_deg_per_s": {"type": "number", "description": "the fusion's estimate of the rate, deg/s"},
    "theta_hat_covariance": {"type": "array", "items": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}, "minItems": 2, "maxItems": 2, "description": "the fusion filter's covariance of [theta_hat, its rate]: deg^2, deg^2/s, deg^2/s^2"},
    "kbjae_deg": {"type": "number", "description": "KBJAE's reading"},
    "kbjae_use": {"type": "string", "enum": ["used", "missing", "held", "gated", "other"], "description": "what the fusion did with KBJAE's reading"},
    "ibjae_deg": {"type": "number", "description": "IBJAE's reading of a frame read this tick"},
    "ibjae_sigma_deg": {"type": "number", "description": "the uncertainty IBJAE gives it"},
    "ibjae_silhouette_iou": {"type": "number", "description": "IoU of the segmented silhouette with the nominal one of the pose read"},
    "ibjae_occluded": {"type": "boolean", "description": "whether IBJAE took part of the instrument as hidden"},
    "ibjae_consistent_deg": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2, "description": "with a hidden part: the lowest and highest bends consistent with the visible pixels"},
    "ibjae_use": {"type": "string", "enum": ["used", "missing", "held", "gated", "other"], "description": "what the fusion did with IBJAE's reading"},
    "ibjae_nis": {"type": "number", "description": "a gated reading's normalised innovation squared"}
  },
  "required": ["time_s", "theta_d_deg", "theta_d_rate_deg_per_s", "theta_c_deg", "theta_a_deg", "theta_a_measured_deg", "theta_hat_deg"]
}"#;

/// The camera's images' topic (`foxglove.RawImage`).
pub const IMAGE_TOPIC: &str = "/kflex/camera/image";

/// The 48 × 48 silhouettes' topic (`foxglove.RawImage`, `mono8`).
pub const SILHOUETTE_TOPIC: &str = "/kflex/camera/silhouette";

/// The frames' placement and timing topic.
pub const CAMERA_FRAMES_TOPIC: &str = "/kflex/camera/frames";

/// The name Foxglove knows its raw image schema by.
pub const RAW_IMAGE_SCHEMA_NAME: &str = "foxglove.RawImage";

/// A JSON schema of Foxglove's raw image (the fields Foxglove reads; in
/// JSON its bytes are base64).
pub const RAW_IMAGE_SCHEMA: &str = r#"{
  "title": "foxglove.RawImage",
  "description": "A raw image",
  "type": "object",
  "properties": {
    "timestamp": {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}, "description": "capture time"},
    "frame_id": {"type": "string", "description": "the image's frame of reference"},
    "width": {"type": "integer", "minimum": 0, "description": "width, px"},
    "height": {"type": "integer", "minimum": 0, "description": "height, px"},
    "encoding": {"type": "string", "description": "rgb8 or mono8"},
    "step": {"type": "integer", "minimum": 0, "description": "bytes per row"},
    "data": {"type": "string", "contentEncoding": "base64", "description": "the pixels, row-major"}
  },
  "required": ["timestamp", "frame_id", "width", "height", "encoding", "step", "data"]
}"#;

/// The frames' placement and timing schema name.
pub const CAMERA_FRAME_SCHEMA_NAME: &str = "kflex.CameraFrame";

/// The JSON schema of a [`CAMERA_FRAMES_TOPIC`] message.
pub const CAMERA_FRAME_SCHEMA: &str = r#"{
  "title": "kflex.CameraFrame",
  "description": "Where a frame of /kflex/camera/image lies in the camera's image, and when it reaches the estimator; times in s since the start of evaluation, angles in degrees",
  "type": "object",
  "properties": {
    "captured_s": {"type": "number", "description": "capture time"},
    "arrives_s": {"type": "number", "description": "when the estimator gets it"},
    "window": {"type": "object", "properties": {"x0": {"type": "integer"}, "y0": {"type": "integer"}, "width": {"type": "integer"}, "height": {"type": "integer"}}, "required": ["x0", "y0", "width", "height"], "description": "the image's pixels in the camera's full image, px"},
    "theta_c_deg": {"type": "number", "description": "the command the plant had answered at capture"},
    "translation_mm": {"type": "number", "description": "the instrument's translation at capture"},
    "truth_theta_a_deg": {"type": ["number", "null"], "description": "the true joint angle at capture (ground truth; null where unknown)"}
  },
  "required": ["captured_s", "arrives_s", "window", "theta_c_deg", "translation_mm"]
}"#;

/// A window in a [`CameraFrameInfo`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct WindowInfo {
    /// Left column, px.
    pub x0: u32,
    /// Top row, px.
    pub y0: u32,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

/// One message of [`CAMERA_FRAMES_TOPIC`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct CameraFrameInfo {
    /// Capture time, s since the start of evaluation.
    pub captured_s: f64,
    /// When the estimator gets it, s since the start of evaluation.
    pub arrives_s: f64,
    /// Where its pixels lie in the camera's image.
    pub window: WindowInfo,
    /// The command at capture, deg.
    pub theta_c_deg: f64,
    /// The translation at capture, mm.
    pub translation_mm: f64,
    /// The true angle at capture, deg, where known.
    #[serde(default)]
    pub truth_theta_a_deg: Option<f64>,
}

const BASE64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// `bytes` in standard base64 with padding (RFC 4648).
fn base64_encode(bytes: &[u8]) -> String {
    let mut out = String::with_capacity(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            chunk.get(1).copied().unwrap_or(0),
            chunk.get(2).copied().unwrap_or(0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(char::from(BASE64[(n >> (18 - 6 * k)) as usize & 63]));
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Standard base64 (RFC 4648, padding optional, no whitespace) back to
/// bytes; `None` for anything else.
#[must_use]
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let text = text.trim_end_matches('=');
    // each byte's sextet, 255 for a byte outside the alphabet
    const VALUE: [u8; 256] = {
        let mut table = [255u8; 256];
        let mut i = 0;
        while i < 64 {
            table[BASE64[i] as usize] = i as u8;
            i += 1;
        }
        table
    };
    let mut out = Vec::with_capacity(text.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in text.bytes() {
        let v = VALUE[usize::from(c)];
        if v == 255 {
            return None;
        }
        let v = u32::from(v);
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    // a lone sextet cannot end a valid encoding
    (bits < 6).then_some(out)
}

/// A `foxglove.RawImage` message's fields.
#[derive(Serialize)]
struct RawImage<'a> {
    timestamp: Stamp,
    frame_id: &'static str,
    width: u32,
    height: u32,
    encoding: &'static str,
    step: u32,
    data: &'a str,
}

#[derive(Serialize)]
struct Stamp {
    sec: u64,
    nsec: u64,
}

/// One message of [`JOINT_STATES_TOPIC`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct JointState {
    /// Time since the start of evaluation, s.
    pub time_s: f64,
    /// θ_d, deg.
    pub theta_d_deg: f64,
    /// dθ_d/dt, deg/s.
    pub theta_d_rate_deg_per_s: f64,
    /// θ_c, deg.
    pub theta_c_deg: f64,
    /// True θ_a, deg.
    pub theta_a_deg: f64,
    /// Measured θ_a, deg.
    pub theta_a_measured_deg: f64,
    /// θ̂, deg; `None` before the estimator had one.
    pub theta_hat_deg: Option<f64>,
    /// What went into θ̂, where the estimator tells (each field left out
    /// of the message where `None`).
    #[serde(flatten)]
    pub details: TickDetails,
}

fn log_error(path: &Path, e: impl std::fmt::Display) -> ControlError {
    ControlError::Log {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// A log that cannot be read, what to do about it where that is known:
/// kflex reads uncompressed chunks (its own logs are), and Python's `mcap`
/// writer compresses with zstd unless told not to.
fn read_error(path: &Path, e: &mcap::McapError) -> ControlError {
    match e {
        mcap::McapError::UnsupportedCompression(kind) => log_error(
            path,
            format!(
                "its chunks are compressed with {kind}, and kflex reads uncompressed MCAP \
                 only: write it without compression (Python's mcap: \
                 Writer(f, compression=CompressionType.NONE))"
            ),
        ),
        e => log_error(path, with_causes(e)),
    }
}

/// `e` and the errors beneath it, "outer: inner: …": the MCAP writer's
/// "I/O error from writing" says why only in its source ("No space left on
/// device").
fn with_causes<E: std::error::Error + ?Sized>(e: &E) -> String {
    let mut message = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !message.ends_with(&text) {
            message = format!("{message}: {text}");
        }
        cause = c.source();
    }
    message
}

impl ClosedLoopTrace {
    /// The joint states of every evaluated tick, in order.
    pub fn joint_states(&self) -> impl Iterator<Item = JointState> + '_ {
        self.joint_states_with(&self.theta_hat_deg, &self.details)
    }

    /// [`ClosedLoopTrace::joint_states`] with `estimate` (aligned with the
    /// ticks) as θ̂ and `details` as what went into it.
    fn joint_states_with<'a>(
        &'a self,
        estimate: &'a [Option<f64>],
        details: &'a [TickDetails],
    ) -> impl Iterator<Item = JointState> + 'a {
        let t = &self.trace;
        (0..t.time_s.len()).map(move |k| JointState {
            time_s: t.time_s[k],
            theta_d_deg: t.theta_d_deg[k],
            theta_d_rate_deg_per_s: t.theta_d_rate_deg_per_s[k],
            theta_c_deg: self.theta_c_deg[k],
            theta_a_deg: t.theta_a_deg[k],
            theta_a_measured_deg: t.theta_a_measured_deg[k],
            theta_hat_deg: estimate.get(k).copied().flatten(),
            details: details.get(k).copied().unwrap_or_default(),
        })
    }

    /// Writes this run as an MCAP log at `path` (see the module docs):
    /// the joint states and, as metadata, `scenario` and `seed`.
    ///
    /// # Errors
    /// [`ControlError::Log`] naming the path when the file cannot be
    /// written (nothing is left at `path` then), or a time that does not fit
    /// the log's nanoseconds.
    pub fn write_mcap(&self, path: &Path, scenario: &ClosedLoopScenario, seed: u64) -> Result<()> {
        self.write_mcap_with_estimate(path, scenario, seed, &self.theta_hat_deg, &self.details)
    }

    /// [`ClosedLoopTrace::write_mcap`] with `estimate` as θ̂ and `details`
    /// as what went into it (another estimator's on the same run, aligned
    /// with the ticks), without copying the trace and its frames.
    ///
    /// # Errors
    /// As [`ClosedLoopTrace::write_mcap`].
    pub fn write_mcap_with_estimate(
        &self,
        path: &Path,
        scenario: &ClosedLoopScenario,
        seed: u64,
        estimate: &[Option<f64>],
        details: &[TickDetails],
    ) -> Result<()> {
        // every series as long as the ticks (the fields are public, and a
        // trace may come from JSON): nothing is written otherwise
        let t = &self.trace;
        let n = t.time_s.len();
        let lengths = [
            t.theta_d_deg.len(),
            t.theta_d_rate_deg_per_s.len(),
            t.theta_a_deg.len(),
            t.theta_a_measured_deg.len(),
            self.theta_c_deg.len(),
        ];
        if let Some(&bad) = lengths.iter().find(|&&l| l != n) {
            return Err(log_error(
                path,
                format!("the trace's series are not all {n} ticks long (one has {bad})"),
            ));
        }
        if let Some(message) = self
            .camera_frames
            .iter()
            .find_map(RecordedFrame::fill_error)
        {
            return Err(log_error(path, message));
        }
        // nothing the reader would refuse ([`read_mcap`])
        if let Some(message) = self
            .joint_states_with(estimate, details)
            .enumerate()
            .find_map(|(i, s)| joint_state_error(&s).map(|e| format!("joint state {i}: {e}")))
        {
            return Err(log_error(path, message));
        }
        // a hidden name of this process's and this call's own beside the log
        // (`.NAME.PID-CALL.tmp`: a run killed mid-write leaves no file that
        // looks like a log)
        static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let name = path
            .file_name()
            .map_or_else(|| "log.mcap".into(), |n| n.to_string_lossy().into_owned());
        let tmp = path.with_file_name(format!(".{name}.{}-{call}.tmp", std::process::id()));
        // a failure names the log, not its hidden copy
        let written = self
            .write_mcap_to(&tmp, scenario, seed, estimate, details)
            .map_err(|e| match e {
                ControlError::Log { message, .. } => log_error(path, message),
                e => e,
            });
        match written.and_then(|()| std::fs::rename(&tmp, path).map_err(|e| log_error(path, e))) {
            Ok(()) => Ok(()),
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    fn write_mcap_to(
        &self,
        path: &Path,
        scenario: &ClosedLoopScenario,
        seed: u64,
        estimate: &[Option<f64>],
        details: &[TickDetails],
    ) -> Result<()> {
        let err = |message: String| log_error(path, message);
        let file = std::fs::File::create(path).map_err(|e| err(with_causes(&e)))?;
        let mut out = mcap::Writer::with_options(
            BufWriter::new(file),
            mcap::WriteOptions::new()
                .compression(None)
                .library(concat!("kflex-control ", env!("CARGO_PKG_VERSION"))),
        )
        .map_err(|e| err(with_causes(&e)))?;
        let schema = out
            .add_schema(
                JOINT_STATE_SCHEMA_NAME,
                "jsonschema",
                JOINT_STATE_SCHEMA.as_bytes(),
            )
            .map_err(|e| err(with_causes(&e)))?;
        let channel = out
            .add_channel(schema, JOINT_STATES_TOPIC, "json", &BTreeMap::new())
            .map_err(|e| err(with_causes(&e)))?;
        let scenario_json = serde_json::to_string(scenario).map_err(|e| err(with_causes(&e)))?;
        out.write_metadata(&mcap::records::Metadata {
            name: "kflex.run".into(),
            metadata: BTreeMap::from([
                ("scenario".to_string(), scenario_json),
                ("seed".to_string(), seed.to_string()),
            ]),
        })
        .map_err(|e| err(with_causes(&e)))?;
        // to the nearest nanosecond (2.01 s is 2,010,000,000 ns)
        let nanos = |time_s: f64| {
            let ns = (time_s * 1e9).round();
            if (0.0..1.8e19).contains(&ns) {
                Ok(ns as u64)
            } else {
                Err(err(format!("time {} s does not fit the log", Num(time_s))))
            }
        };
        let frames = if self.camera_frames.is_empty() {
            None
        } else {
            let image = out
                .add_schema(
                    RAW_IMAGE_SCHEMA_NAME,
                    "jsonschema",
                    RAW_IMAGE_SCHEMA.as_bytes(),
                )
                .map_err(|e| err(with_causes(&e)))?;
            let info = out
                .add_schema(
                    CAMERA_FRAME_SCHEMA_NAME,
                    "jsonschema",
                    CAMERA_FRAME_SCHEMA.as_bytes(),
                )
                .map_err(|e| err(with_causes(&e)))?;
            let mut channel = |schema, topic| {
                out.add_channel(schema, topic, "json", &BTreeMap::new())
                    .map_err(|e| err(with_causes(&e)))
            };
            Some((
                channel(image, IMAGE_TOPIC)?,
                channel(image, SILHOUETTE_TOPIC)?,
                channel(info, CAMERA_FRAMES_TOPIC)?,
            ))
        };
        let mut segmenter =
            kflex_estimate::Segmenter::new(kflex_estimate::SegmentParams::default())
                .map_err(|e| err(with_causes(&e)))?;
        let mut data = Vec::new();
        let mut next_frame = 0;
        for (k, state) in self.joint_states_with(estimate, details).enumerate() {
            let ns = nanos(state.time_s)?;
            // the frames captured by now, in time order with the ticks
            while let (Some(f), Some(channels)) = (self.camera_frames.get(next_frame), frames)
                && nanos(f.captured_s)? <= ns
            {
                write_frame(
                    &mut out,
                    channels,
                    next_frame,
                    f,
                    nanos(f.captured_s)?,
                    &mut segmenter,
                )
                .map_err(|e| err(with_causes(&*e)))?;
                next_frame += 1;
            }
            data.clear();
            serde_json::to_writer(&mut data, &state).map_err(|e| err(with_causes(&e)))?;
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: u32::try_from(k).unwrap_or(u32::MAX),
                log_time: ns,
                publish_time: ns,
            };
            out.write_to_known_channel(&header, &data)
                .map_err(|e| err(with_causes(&e)))?;
        }
        if let Some(channels) = frames {
            for (i, f) in self.camera_frames.iter().enumerate().skip(next_frame) {
                write_frame(
                    &mut out,
                    channels,
                    i,
                    f,
                    nanos(f.captured_s)?,
                    &mut segmenter,
                )
                .map_err(|e| err(with_causes(&*e)))?;
            }
        }
        out.finish().map_err(|e| err(with_causes(&e)))?;
        let file = out
            .into_inner()
            .into_inner()
            .map_err(|e| err(with_causes(e.error())))?;
        file.sync_all().map_err(|e| err(with_causes(&e)))
    }
}

/// What [`read_mcap`] finds in a log.
#[derive(Debug, Clone, Default)]
pub struct RecordedLog {
    /// The run's scenario (metadata `kflex.run`), where the log has it.
    pub scenario: Option<ClosedLoopScenario>,
    /// The run's seed, where the log has it.
    pub seed: Option<u64>,
    /// Every tick's joint state, in time order.
    pub states: Vec<JointState>,
    /// Every frame, in order of arrival.
    pub frames: Vec<RecordedFrame>,
}

impl RecordedLog {
    /// The ticks to replay ([`ClosedLoopScenario::replay`]): each joint
    /// state's time, command (θ_c at `translation_mm`, which the joint
    /// states do not carry) and θ_d with its rate.
    #[must_use]
    pub fn replay_ticks(&self, translation_mm: f64) -> Vec<ReplayTick> {
        self.states
            .iter()
            .map(|s| ReplayTick {
                time_s: s.time_s,
                command: Command {
                    theta_c_deg: s.theta_c_deg,
                    translation_mm,
                },
                theta_d_deg: s.theta_d_deg,
                theta_d_rate_deg_per_s: s.theta_d_rate_deg_per_s,
            })
            .collect()
    }
}

/// A message's JSON, or a [`ControlError::Log`] naming `path` and `what`.
fn parse<T: serde::de::DeserializeOwned>(path: &Path, what: &str, data: &[u8]) -> Result<T> {
    serde_json::from_slice(data).map_err(|e| log_error(path, format!("{what}: {e}")))
}

/// The fields of a `foxglove.RawImage` message that a frame needs.
#[derive(serde::Deserialize)]
struct RawImageIn {
    width: u32,
    height: u32,
    encoding: String,
    #[serde(default)]
    step: Option<u32>,
    data: String,
}

/// Reads a run's log (see the module docs): its joint states, and its
/// frames, each image of [`IMAGE_TOPIC`] with the [`CAMERA_FRAMES_TOPIC`]
/// message of the same sequence number. A log whose frames came from
/// elsewhere is read as long as its channels follow the schemas: an image
/// without its placement is taken as the camera's whole image, captured and
/// arriving at its log time, with the command of the tick before it.
/// Images must be `rgb8` without row padding.
///
/// # Errors
/// [`ControlError::Log`] naming the file and what is wrong: unreadable, not
/// MCAP, no joint states, a message that does not follow its schema, an
/// image of another encoding or whose data does not fill it; and what no
/// run can have written, named by record and field: a NaN or infinite
/// value, θ_c, θ_a or its measurement past ±[`REPLAY_MAX_ANGLE_DEG`], a
/// frame [`RecordedFrame::fill_error`] refuses, a scenario translation
/// outside 0–1,000 mm. [`ClosedLoopTrace::write_mcap`] refuses the same,
/// so a log it wrote is read.
pub fn read_mcap(path: &Path) -> Result<RecordedLog> {
    let bytes = std::fs::read(path).map_err(|e| log_error(path, e))?;
    let mut log = RecordedLog::default();
    // metadata: the scenario and the seed
    if let Ok(Some(summary)) = mcap::Summary::read(&bytes) {
        for index in &summary.metadata_indexes {
            let meta = mcap::read::metadata(&bytes, index).map_err(|e| log_error(path, e))?;
            if meta.name == "kflex.run" {
                if let Some(json) = meta.metadata.get("scenario") {
                    log.scenario = Some(parse(path, "the scenario metadata", json.as_bytes())?);
                }
                log.seed = meta.metadata.get("seed").and_then(|s| s.parse().ok());
            }
        }
    }
    // an image and its placement share their log time and sequence number
    let mut images: BTreeMap<(u64, u32), RawImageIn> = BTreeMap::new();
    let mut infos: BTreeMap<(u64, u32), CameraFrameInfo> = BTreeMap::new();
    // the first joint state's log time and time_s: the two clocks' offset
    let mut first_state: Option<(u64, f64)> = None;
    for message in mcap::MessageStream::new(&bytes).map_err(|e| read_error(path, &e))? {
        let m = message.map_err(|e| read_error(path, &e))?;
        let key = (m.log_time, m.sequence);
        let twice = |topic: &str| {
            log_error(
                path,
                format!(
                    "two {topic} messages share log time {} ns and sequence {}",
                    key.0, key.1
                ),
            )
        };
        match m.channel.topic.as_str() {
            JOINT_STATES_TOPIC => {
                let state: JointState = parse(path, JOINT_STATES_TOPIC, &m.data)?;
                if first_state.is_none_or(|(t, _)| m.log_time < t) {
                    first_state = Some((m.log_time, state.time_s));
                }
                log.states.push(state);
            }
            IMAGE_TOPIC => images
                .insert(key, parse(path, IMAGE_TOPIC, &m.data)?)
                .map_or(Ok(()), |_| Err(twice(IMAGE_TOPIC)))?,
            CAMERA_FRAMES_TOPIC => infos
                .insert(key, parse(path, CAMERA_FRAMES_TOPIC, &m.data)?)
                .map_or(Ok(()), |_| Err(twice(CAMERA_FRAMES_TOPIC)))?,
            _ => {}
        }
    }
    let Some((state_log0, state_time0)) = first_state else {
        return Err(log_error(
            path,
            format!("no joint states ({JOINT_STATES_TOPIC})"),
        ));
    };
    log.states.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    let translation = log
        .scenario
        .as_ref()
        .map_or(0.0, |s| s.motion.translation_mm);
    for ((log_time, sequence), image) in images {
        if image.encoding != "rgb8"
            || image
                .step
                .is_some_and(|s| u128::from(s) != 3 * u128::from(image.width))
        {
            return Err(log_error(
                path,
                format!(
                    "image {sequence}: encoding {:?}, step {:?}: replay reads rgb8 without row padding",
                    image.encoding, image.step
                ),
            ));
        }
        let rgb = base64_decode(&image.data)
            .filter(|d| d.len() as u128 == 3 * u128::from(image.width) * u128::from(image.height))
            .ok_or_else(|| {
                log_error(
                    path,
                    format!(
                        "image {sequence}: its data is not base64 of {}×{} rgb8 pixels",
                        image.width, image.height
                    ),
                )
            })?;
        // on the joint states' clock
        // (the difference in integer nanoseconds: an epoch clock's f64 would
        // lose the microseconds)
        let time_s = state_time0 + (i128::from(log_time) - i128::from(state_log0)) as f64 / 1e9;
        let frame = match infos.get(&(log_time, sequence)) {
            Some(info) => RecordedFrame {
                captured_s: info.captured_s,
                arrives_s: info.arrives_s,
                window: Roi {
                    x0: info.window.x0,
                    y0: info.window.y0,
                    width: info.window.width,
                    height: info.window.height,
                },
                rgb,
                command: kflex_model::Command {
                    theta_c_deg: info.theta_c_deg,
                    translation_mm: info.translation_mm,
                },
                truth_theta_a_deg: info.truth_theta_a_deg.unwrap_or(f64::NAN),
            },
            None => {
                let before = log
                    .states
                    .iter()
                    .take_while(|s| s.time_s <= time_s + 1e-9)
                    .last()
                    .or(log.states.first());
                RecordedFrame {
                    captured_s: time_s,
                    arrives_s: time_s,
                    window: Roi::whole(image.width, image.height),
                    rgb,
                    command: kflex_model::Command {
                        theta_c_deg: before.map_or(0.0, |s| s.theta_c_deg),
                        translation_mm: translation,
                    },
                    truth_theta_a_deg: f64::NAN,
                }
            }
        };
        if frame.window.width != image.width || frame.window.height != image.height {
            return Err(log_error(
                path,
                format!(
                    "image {sequence} is {}×{}, its window {}×{}",
                    image.width, image.height, frame.window.width, frame.window.height
                ),
            ));
        }
        log.frames.push(frame);
    }
    log.frames
        .sort_by(|a, b| a.arrives_s.total_cmp(&b.arrives_s));
    check_recorded(path, &log)?;
    Ok(log)
}

/// Why a joint state cannot be one a run wrote, if it cannot: a value NaN
/// or infinite, or an angle the plant bounds (θ_c, θ_a and its
/// measurement) past ±[`REPLAY_MAX_ANGLE_DEG`] (its square would overflow a
/// table's RMSE). θ_d and θ̂ are held to finite values only: a trajectory
/// may command past the joint's stops, and an estimate may err as far.
fn joint_state_error(s: &JointState) -> Option<String> {
    let bounded = [
        ("theta_c_deg", s.theta_c_deg),
        ("theta_a_deg", s.theta_a_deg),
        ("theta_a_measured_deg", s.theta_a_measured_deg),
    ];
    let finite = [
        ("time_s", s.time_s),
        ("theta_d_deg", s.theta_d_deg),
        ("theta_d_rate_deg_per_s", s.theta_d_rate_deg_per_s),
        ("theta_hat_deg", s.theta_hat_deg.unwrap_or(0.0)),
    ];
    bounded
        .iter()
        .find(|(_, v)| !(v.is_finite() && v.abs() <= REPLAY_MAX_ANGLE_DEG))
        .or_else(|| finite.iter().find(|(_, v)| !v.is_finite()))
        .map(|(name, value)| {
            format!(
                "{name} = {}: every value must be finite, θ_c, θ_a and its measurement \
                 within ±{REPLAY_MAX_ANGLE_DEG} deg",
                Num(*value)
            )
        })
}

/// What no run can have written: a joint state [`joint_state_error`]
/// refuses, a frame [`RecordedFrame::fill_error`] refuses, or a scenario
/// whose translation no stage allows. Named by index and field.
fn check_recorded(path: &Path, log: &RecordedLog) -> Result<()> {
    for (i, s) in log.states.iter().enumerate() {
        if let Some(e) = joint_state_error(s) {
            return Err(log_error(path, format!("joint state {i} (by time): {e}")));
        }
    }
    // each tick after the one before: a replay steps the estimators by
    // the time between them
    for (i, pair) in log.states.windows(2).enumerate() {
        if pair[1].time_s <= pair[0].time_s {
            return Err(log_error(
                path,
                format!(
                    "joint state {} (by time): time_s = {} does not come after the one \
                     before it ({}): a run's ticks follow one another",
                    i + 1,
                    Num(pair[1].time_s),
                    Num(pair[0].time_s)
                ),
            ));
        }
    }
    for (i, f) in log.frames.iter().enumerate() {
        if let Some(e) = f.fill_error() {
            return Err(log_error(
                path,
                format!("camera frame {i} (by arrival): {e}"),
            ));
        }
    }
    if let Some(scenario) = &log.scenario {
        let command = Command {
            theta_c_deg: 0.0,
            translation_mm: scenario.motion.translation_mm,
        };
        if let Some(e) = replay_command_error(&command) {
            return Err(log_error(path, format!("the scenario metadata's {e}")));
        }
    }
    Ok(())
}

/// Writes frame `i` of a run: its image, its silhouette and where and when
/// it lies, on `channels` (image, silhouette, frames), at `ns`.
fn write_frame<W: std::io::Write + std::io::Seek>(
    out: &mut mcap::Writer<W>,
    (image, silhouette, info): (u16, u16, u16),
    i: usize,
    f: &RecordedFrame,
    ns: u64,
    segmenter: &mut kflex_estimate::Segmenter,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let header = |channel_id| mcap::records::MessageHeader {
        channel_id,
        sequence: u32::try_from(i).unwrap_or(u32::MAX),
        log_time: ns,
        publish_time: ns,
    };
    let stamp = || Stamp {
        sec: ns / 1_000_000_000,
        nsec: ns % 1_000_000_000,
    };
    let (w, h) = (f.window.width, f.window.height);
    let rgb = base64_encode(&f.rgb);
    let message = serde_json::to_vec(&RawImage {
        timestamp: stamp(),
        frame_id: "endoscope",
        width: w,
        height: h,
        encoding: "rgb8",
        step: 3 * w,
        data: &rgb,
    })?;
    out.write_to_known_channel(&header(image), &message)?;
    // the segmentation as IBJAE reads the window: 48 × 48, or nothing found
    let side = kflex_estimate::SegmentParams::default().out;
    let small: Vec<u8> = match segmenter.segment(&f.rgb, w, h, Roi::whole(w, h)) {
        Ok(s) => s
            .small
            .data()
            .iter()
            .map(|&v| if v != 0 { 255 } else { 0 })
            .collect(),
        // nothing found, or a window the segmentation refuses: an empty
        // silhouette (it is a view for people; the image is what replays)
        Err(_) => vec![0; side as usize * side as usize],
    };
    let mono = base64_encode(&small);
    let message = serde_json::to_vec(&RawImage {
        timestamp: stamp(),
        frame_id: "silhouette",
        width: side,
        height: side,
        encoding: "mono8",
        step: side,
        data: &mono,
    })?;
    out.write_to_known_channel(&header(silhouette), &message)?;
    let message = serde_json::to_vec(&CameraFrameInfo {
        captured_s: f.captured_s,
        arrives_s: f.arrives_s,
        window: WindowInfo {
            x0: f.window.x0,
            y0: f.window.y0,
            width: w,
            height: h,
        },
        theta_c_deg: f.command.theta_c_deg,
        translation_mm: f.command.translation_mm,
        truth_theta_a_deg: Some(f.truth_theta_a_deg),
    })?;
    out.write_to_known_channel(&header(info), &message)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_error_says_why_beneath_the_writers_words() {
        let full = std::io::Error::other("No space left on device (os error 28)");
        let e = mcap::McapError::Io(full);
        let message = with_causes(&e);
        assert!(message.starts_with(&e.to_string()), "{message}");
        assert!(
            message.ends_with("No space left on device (os error 28)"),
            "{message}"
        );
        // an error that already says its cause says it once
        let plain = std::io::Error::other("denied");
        assert_eq!(with_causes(&plain), "denied");
    }

    #[test]
    fn base64_round_trips_and_matches_the_rfc_examples() {
        // RFC 4648, section 10
        for (plain, coded) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64_encode(plain.as_bytes()), coded);
            assert_eq!(base64_decode(coded).unwrap(), plain.as_bytes());
        }
        let bytes: Vec<u8> = (0..=255).collect();
        assert_eq!(base64_decode(&base64_encode(&bytes)).unwrap(), bytes);
        assert!(base64_decode("Zm9v!").is_none());
        assert!(base64_decode("Z").is_none());
    }
}
