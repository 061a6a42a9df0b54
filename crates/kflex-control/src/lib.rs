//! # kflex-control — experiments and metrics
//!
//! Runs the seed paper's experiments on the kflex testbed and scores them.
//! This first version drives the *uncompensated* plant ([`OpenLoopGrid`],
//! [`OpenLoopScenario`]) and defines the paper's metrics once ([`rmse`],
//! [`loop_width`], [`error_peak_to_peak`]). The compensator of Eq. 3–5
//! ([`Compensator`]: PID plus the backlash term G, with saturation,
//! anti-windup, a rate limit, faults and a watchdog; kflex's reading of
//! Eq. 5 is in its module docs) is stepped once per control tick by the
//! caller; `cargo run --release -p kflex-control --no-default-features
//! --example embedded_loop` embeds it in a fixed-rate loop.
//! [`ClosedLoopScenario::run`] closes the loop on the simulated robot:
//! compensator, plant, the robot's camera (its rate, latency and lost
//! frames; the window the estimator reads) and any [`AngleEstimator`]. The
//! paper's grid of closed-loop experiments comes next.
//!
//! It also makes the learned estimators' training data on the testbed: the
//! kinematic set D^k of KBJAE ([`KinematicDatasetConfig`]: periodic signals
//! through perturbed plants, with the tracker's noise) and the image-pair set
//! D^I of IBJAE's Siamese CNN ([`ImagePairsConfig`]: segmented frames of the
//! as-built robot against the nominal model's silhouettes), with the nominal
//! silhouette database IBJAE retrieves from ([`ImagePairsConfig::database`]).
//! Both are deterministic from a seed, whatever the number of threads, and
//! carry a [`DatasetCard`]. `cargo run --release -p kflex-control --example
//! dataset_speed` measures them.
//!
//! ## Cargo features
//!
//! * `multibody` (default): experiments may run the plant with the rapier3d
//!   multibody joint (kflex-model's feature of the same name). A controller
//!   that embeds only the compensator and the metrics turns default features
//!   off and compiles none of rapier3d, parry3d or image.
//! * `estimators` (off): KBJAE, IBJAE (`IbjaeAlone`) and LBHJAE as
//!   [`AngleEstimator`]s in the closed loop (KBJAE on the command θ_c and
//!   the master's rate θ_d', see below); it turns on
//!   kflex-estimate's `onnx` (ONNX Runtime, loaded at run time) and `index`.
//! * `mcap` (off): [`ClosedLoopTrace::write_mcap`], a run's MCAP log
//!   (JSON-encoded joint states with their JSON schema, the scenario as
//!   metadata) for Foxglove.
//!
//! ## KBJAE's input in the closed loop: θ_c and the master's rate
//!
//! The paper feeds KBJAE the master's `{θ_d, θ_d'}` and trains it open
//! loop, where `θ_c = θ_d`. Closed loop the two differ, and kflex's KBJAE
//! (alone and inside LBHJAE) reads **the command the plant answered, θ_c,
//! with the master's rate θ_d'** (`Kbjae::step_with_rate`):
//! * θ_c, because the joint follows what it is sent: KBJAE then estimates
//!   the compensated joint, and the compensator's feedback on it is a
//!   feedback like IBJAE's, with one set of gains for every estimator.
//!   With θ_d instead, KBJAE predicts the *uncompensated* joint whatever
//!   the compensator does: its error never falls, the integral winds up
//!   (27.6° RMSE at a 0° sheath with the default gains, against 7.95 with
//!   no compensation), and inside LBHJAE it pulls the fusion away from
//!   the camera's compensated joint. It works only as pure feedforward
//!   (`K_p` 1, no integral, no G): 2.33 / 5.50 / 11.26 / 17.20° at 0 / 90 /
//!   180 / 270°.
//! * θ_d', because the rate picks the hysteresis branch: the compensator's
//!   corrections make θ_c' wiggle around each reversal and a memoryless
//!   (θ, θ') model reads every wiggle as a reversal. With θ_c's own rate the
//!   compensated joint chattered by ±3–5° and RMSE at 0° fell only to 4.94°
//!   (−38 %); with θ_d' it is 2.46 / 5.10 / 10.83 / 16.79° (the paper's
//!   KBJAE: 2.48 / 5.09 / 9.27 / 12.80).
//!
//! Those figures are Table IX's cases (three repeats) with a KBJAE trained
//! by `training/train_kbjae.py` on this plant (held-out RMSE 2.03°), the
//! default compensator. Open loop (the estimation tables) θ_c = θ_d and the
//! rates differ only by the difference quotient's lag.
#![warn(missing_docs)]

mod closed_loop;
mod compensator;
mod dataset;
mod error;
#[cfg(feature = "estimators")]
mod estimators;
mod experiment;
mod grid;
#[cfg(feature = "mcap")]
mod mcap_log;
mod metrics;
#[cfg(feature = "estimators")]
mod models;
#[cfg(feature = "paper")]
mod paper;
#[cfg(feature = "paper")]
mod results;

pub use closed_loop::{
    AngleEstimator, CameraFrame, CameraTiming, ClosedLoopScenario, ClosedLoopTrace, EstimatorTick,
    FrameCounts, FrameRequest, NoisyTruth, REPLAY_MAX_ANGLE_DEG, ReadingUse, RecordedFrame,
    ReplayTick, TickDetails, estimation_rmse_deg, replay_command_error,
};
pub use compensator::{
    BacklashTerm, Compensator, CompensatorConfig, CompensatorOutput, Fault, Terms,
};
pub use dataset::{
    DatasetCard, ImageDatabase, ImagePairs, ImagePairsConfig, KinematicDataset,
    KinematicDatasetConfig, KinematicSet, KinematicSetSpec,
};
pub use error::{ControlError, Result};
#[cfg(feature = "estimators")]
pub use estimators::IbjaeAlone;
pub use experiment::{GridRow, MAX_REPEATS, OpenLoopGrid, OpenLoopScenario, RunMetrics, Trace};
pub use grid::{
    Case, CaseKind, EstimatorKind, ExperimentGrid, GridRun, MakeEstimator, OcclusionCase, OnRun,
    Record, safe_file_name,
};
#[cfg(feature = "mcap")]
pub use mcap_log::{
    CAMERA_FRAME_SCHEMA, CAMERA_FRAME_SCHEMA_NAME, CAMERA_FRAMES_TOPIC, CameraFrameInfo,
    IMAGE_TOPIC, JOINT_STATE_SCHEMA, JOINT_STATE_SCHEMA_NAME, JOINT_STATES_TOPIC, JointState,
    RAW_IMAGE_SCHEMA, RAW_IMAGE_SCHEMA_NAME, RecordedLog, SILHOUETTE_TOPIC, WindowInfo,
    base64_decode, read_mcap,
};
pub use metrics::{LOOP_BIN_DEG, MeanStd, error_peak_to_peak, loop_width, peak_loss, rmse};
#[cfg(feature = "estimators")]
pub use models::{MODELS_DIR, ModelDir};
#[cfg(feature = "paper")]
pub use paper::{PaperFigure, paper_figure};
#[cfg(feature = "paper")]
pub use results::ResultRow;
