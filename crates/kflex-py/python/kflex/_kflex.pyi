# Hand-written stubs of the native module kflex._kflex (crates/kflex-py/src).
# Units are in the names: _deg, _rad, _mm, _s, _hz, _n, _px, ...
# tests/python/test_stubs.py checks that the fields listed here are the Rust
# types' own and that every name the module exports is stubbed.

import os
from typing import Any, Literal, Self, TypeAlias

import numpy as np
import numpy.typing as npt

FloatArray: TypeAlias = npt.NDArray[np.float64]
BoolArray: TypeAlias = npt.NDArray[np.bool_]
FloatsIn: TypeAlias = float | npt.NDArray[np.float64] | npt.NDArray[np.float32]
FloatsOut: TypeAlias = float | npt.NDArray[np.float64]

__version__: str

class RangeError(ValueError):
    """A value outside its valid range; the bounds' ends may be infinite."""

    name: str
    value: float
    min: float
    max: float
    min_inclusive: bool
    max_inclusive: bool

class NoInstrumentError(RuntimeError): ...

class _Params:
    """Stub-only base: what every parameter class has (a Rust serde struct
    read and written by field name). Not a runtime base class."""

    def __init__(self, **fields: Any) -> None: ...
    def to_dict(self) -> dict[str, Any]: ...
    @classmethod
    def from_dict(cls, fields: dict[str, Any]) -> Self: ...
    def copy(self) -> Self: ...
    def __eq__(self, other: object) -> bool: ...

# ---- plant ------------------------------------------------------------------

class SheathParams(_Params):
    friction_coefficient: float
    route_wrap_deg: float
    pretension_n: float
    tendon_stiffness_n_per_mm: float
    distal_stiffness_n_per_mm: float
    drive_backlash_mm: float
    backlash_engagement_mm: float
    presliding_mm: float
    elements: int
    sheath_path_mm_per_rad: float
    def validate(self) -> None: ...

class JointParams(_Params):
    contact_stiffness_nmm_per_rad: float
    link_length_mm: float
    link_radius_mm: float
    link_mass_g: float
    tool_length_mm: float
    tool_mass_g: float
    gravity_m_per_s2: list[float]
    tip_load_n: list[float]
    max_theta_deg: float
    def validate(self) -> None: ...

class Seating(_Params):
    friction_a: float
    friction_b: float
    backlash: float
    def validate(self) -> None: ...

class TranslationParams(_Params):
    min_mm: float
    max_mm: float
    max_speed_mm_per_s: float
    def validate(self) -> None: ...

class AuroraNoise(_Params):
    theta_std_deg: float
    translation_std_mm: float

class Command(_Params):
    theta_c_deg: float
    translation_mm: float

class PlantState(_Params):
    time_s: float
    command: dict[str, float]
    theta_a_deg: float
    translation_mm: float
    theta_a_measured_deg: float
    translation_measured_mm: float
    motor_stroke_a_mm: float
    motor_stroke_b_mm: float
    distal_stroke_a_mm: float
    distal_stroke_b_mm: float
    differential_force_n: float
    tensions: dict[str, float]
    friction_state: float

class TendonGeometry(_Params):
    n_segments: int
    r_mm: float
    b_mm: float
    tendon_offset_mm: float
    def validate(self, max_theta_rad: float) -> None: ...
    def delta_l_a_mm(self, theta_rad: FloatsIn) -> FloatsOut: ...
    def delta_l_b_mm(self, theta_rad: FloatsIn) -> FloatsOut: ...
    def differential_stroke_mm(self, theta_rad: FloatsIn) -> FloatsOut: ...
    def common_mode_mm(self, theta_rad: FloatsIn) -> FloatsOut: ...
    def theta_rad_from_delta_l_a(self, delta_l_a_mm: FloatsIn, max_theta_rad: float) -> FloatsOut: ...

class PlantConfig:
    """Groups are held by reference: config.sheath.friction_coefficient = 0.2 changes it."""

    geometry: TendonGeometry
    sheath: SheathParams
    sheath_deg: float
    seating: Seating
    joint: JointParams
    joint_model: Literal["analytic", "rapier"]
    translation: TranslationParams
    noise: AuroraNoise | None
    seed: int
    def __init__(self, **fields: Any) -> None: ...
    def validate(self) -> None: ...
    def perturbed(self, seed: int, rel_std: float) -> PlantConfig: ...
    def to_dict(self) -> dict[str, Any]: ...
    @staticmethod
    def from_dict(fields: dict[str, Any]) -> PlantConfig: ...
    def copy(self) -> PlantConfig: ...
    def __eq__(self, other: object) -> bool: ...

class Plant:
    def __init__(self, config: PlantConfig | None = None) -> None: ...
    def step(self, theta_c_deg: float, translation_mm: float, dt_s: float) -> PlantState: ...
    def run(
        self,
        theta_c_deg: npt.NDArray[np.float64] | npt.NDArray[np.float32],
        translation_mm: FloatsIn,
        dt_s: float,
    ) -> dict[str, FloatArray]: ...
    def reset(self) -> None: ...
    @property
    def state(self) -> PlantState: ...
    @property
    def config(self) -> PlantConfig: ...
    def set_sheath_deg(self, sheath_deg: float) -> None: ...
    def check_command(self, theta_c_deg: float, translation_mm: float) -> None: ...

# ---- trajectories and experiments -----------------------------------------

class Sine(_Params):
    amplitude_deg: float
    offset_deg: float
    frequency_hz: float
    phase_rad: float
    @staticmethod
    def paper() -> Sine: ...
    def period_s(self) -> float: ...

class Trajectory(_Params):
    """Tagged by kind: "sine", "periodic_set", "band_limited", "steps"."""

    kind: str
    def __getattr__(self, name: str) -> Any: ...
    @staticmethod
    def paper() -> Trajectory: ...
    def sample(self, t_s: FloatsIn) -> tuple[FloatsOut, FloatsOut]: ...
    def natural_duration_s(self) -> float | None: ...

class OpenLoopScenario(_Params):
    trajectory: dict[str, Any]
    periods: float
    period_s: float
    dt_s: float
    pre_roll_s: float
    translation_mm: float
    def run(self, plant: Plant) -> Trace: ...

class Trace:
    @property
    def time_s(self) -> FloatArray: ...
    @property
    def theta_d_deg(self) -> FloatArray: ...
    @property
    def theta_d_rate_deg_per_s(self) -> FloatArray: ...
    @property
    def theta_a_deg(self) -> FloatArray: ...
    @property
    def theta_a_measured_deg(self) -> FloatArray: ...
    def metrics(self) -> dict[str, float]: ...
    def __len__(self) -> int: ...

# ---- camera and regions ----------------------------------------------------

class Intrinsics(_Params):
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    @staticmethod
    def default() -> Intrinsics: ...
    @staticmethod
    def from_fov(width: int, height: int, hfov_deg: float) -> Intrinsics: ...
    @staticmethod
    def full_hd() -> Intrinsics: ...
    def validate(self) -> None: ...
    def region(self, x0: float, y0: float, w: float, h: float, out_w: int, out_h: int) -> Intrinsics: ...

class Lens(_Params):
    division: float
    vignetting: float
    @staticmethod
    def pinhole() -> Lens: ...
    def validate(self, k: Intrinsics) -> None: ...
    def distort(self, xu: float, yu: float) -> list[float]: ...
    def undistort(self, xd: float, yd: float) -> list[float]: ...

class Camera:
    intrinsics: Intrinsics
    lens: Lens
    def __init__(self, intrinsics: Intrinsics | None = None, lens: Lens | None = None) -> None: ...
    @property
    def camera_from_overtube(self) -> list[list[float]]: ...
    def validate(self) -> None: ...
    def project(self, p_overtube_mm: list[float]) -> list[float] | None: ...
    def ray_direction(self, u: float, v: float) -> list[float]: ...
    def illumination(self, u: float, v: float) -> float: ...
    def with_intrinsics(self, intrinsics: Intrinsics) -> Camera: ...

class Roi(_Params):
    x0: int
    y0: int
    width: int
    height: int
    @staticmethod
    def whole(width: int, height: int) -> Roi: ...
    @staticmethod
    def paper(camera: Camera) -> Roi: ...
    @staticmethod
    def for_workspace(camera: Camera, instrument: Instrument, poses: PoseRange, margin_px: int) -> Roi: ...
    def holds(self, inner: Roi) -> bool: ...
    def check_within(self, width: int, height: int) -> None: ...
    def area(self) -> int: ...

class PoseRange(_Params):
    theta_deg: list[float]
    translation_mm: list[float]
    @staticmethod
    def paper() -> PoseRange: ...
    @staticmethod
    def full() -> PoseRange: ...
    def contains(self, theta_deg: float, translation_mm: float) -> bool: ...

class Banding(_Params):
    margin_px: int
    growth: float
    theta_parts: int
    theta_overlap_deg: float

class WorkingBand(_Params):
    poses: dict[str, Any]
    roi: dict[str, Any]
    @property
    def region(self) -> Roi: ...

class WorkingRegions:
    @staticmethod
    def full(camera: Camera) -> WorkingRegions: ...
    @staticmethod
    def for_workspace(camera: Camera, instrument: Instrument, poses: PoseRange, banding: Banding) -> WorkingRegions: ...
    @property
    def poses(self) -> PoseRange: ...
    @property
    def bands(self) -> list[WorkingBand]: ...
    def at(self, theta_deg: float, translation_mm: float) -> WorkingBand: ...
    def nearest(self, theta_deg: float, translation_mm: float) -> WorkingBand | None: ...

class InstrumentParams(_Params):
    channel_offset_mm: list[float]
    shaft_radius_mm: float
    jaw_radius_mm: float
    jaw_opening_deg: float

class Instrument:
    def __init__(
        self, joint: JointParams, params: InstrumentParams, n_segments: int, translation: TranslationParams
    ) -> None: ...
    @staticmethod
    def kflex() -> Instrument: ...
    def shape(self, theta_deg: float, translation_mm: float) -> InstrumentShape: ...

class InstrumentShape:
    @property
    def tip_mm(self) -> list[float]: ...
    def __len__(self) -> int: ...
    def translation_mm(self) -> float: ...
    def bend_deg(self) -> float: ...

class BuildTolerances(_Params):
    link_length: float
    link_radius: float
    curvature: float
    camera_rotation_deg: float
    camera_offset_mm: float
    focal: float
    principal_px: float
    division: float
    @staticmethod
    def none() -> BuildTolerances: ...
    def validate(self) -> None: ...
    def instrument(self, nominal: Instrument, seed: int) -> BuiltInstrument: ...
    def camera(self, nominal: Camera, seed: int) -> Camera: ...

class BuiltInstrument:
    def shape(self, theta_deg: float, translation_mm: float) -> InstrumentShape: ...

# ---- rendering ---------------------------------------------------------------

class Occlusion(_Params):
    fraction: float
    position: float
    region: dict[str, int] | None

class FrameParams(_Params):
    background: Literal["colon", "stomach", "larynx"]
    tissue: Literal["organ", "grey", "pale", "white", "blue_green", "yellow"]
    seed: int
    frame: int
    illumination_gain: float
    noise_std: float
    blur_px: float
    occlusion: dict[str, Any] | None
    def validate(self) -> None: ...

class Frame:
    rgb: npt.NDArray[np.uint8]
    instrument: BoolArray
    occluder: BoolArray
    width: int
    height: int

class SceneRenderer:
    def __init__(self) -> None: ...
    def render(self, camera: Camera, shape: InstrumentShape, params: FrameParams | None = None) -> Frame: ...
    def render_window(
        self, camera: Camera, shape: InstrumentShape, window: Roi, params: FrameParams | None = None
    ) -> Frame: ...

class Rasterizer:
    def __init__(self) -> None: ...
    def silhouette(self, camera: Camera, shape: InstrumentShape) -> BoolArray: ...
    def silhouette_window(self, camera: Camera, shape: InstrumentShape, window: Roi) -> BoolArray: ...

# ---- segmentation --------------------------------------------------------------

class SegmentParams(_Params):
    split_range: float
    min_block: int
    merge_distance: float
    reference_brightness: float
    merge_noise_z: float
    merge_chroma: float
    metal_chroma: list[float]
    bright_ratio: float
    bright_metal_share: float
    grow_share: float
    grow_separation: float
    grow_brightness: float
    neighbour_ratio: float
    min_relative_value: float
    clip_value: float
    saturated_value: float
    highlight_ratio: float
    highlight_max: float
    highlight_min_value: float
    fill_holes: bool
    min_component: float
    min_component_of_total: float
    refine_reach_px: float
    refine_contrast: float
    min_instrument: float
    out: int

class Segmentation:
    full: BoolArray
    small: BoolArray

class Segmenter:
    def __init__(self, params: SegmentParams | None = None) -> None: ...
    @property
    def params(self) -> SegmentParams: ...
    def segment(self, rgb: npt.NDArray[np.uint8], roi: Roi) -> Segmentation | None: ...

def segment(rgb: npt.NDArray[np.uint8], roi: Roi, params: SegmentParams | None = None) -> Segmentation | None: ...

# ---- fusion (LBHJAE's Kalman filters) ------------------------------------------

class KalmanParams(_Params):
    model_dt_s: float
    sigma_a: float
    sigma_z_deg: list[float]
    rate: str

class AdaptiveParams(_Params):
    accel_psd_deg2_per_s3: float
    bias_sigma_deg: float
    bias_time_s: float
    initial_sigma_z_deg: list[float]
    min_sigma_z_deg: float
    noise_time_s: float
    gate: float
    max_ibjae_sigma_deg: float

class Estimate:
    theta_hat_deg: float
    theta_hat_rate_deg_per_s: float
    covariance: FloatArray
    kbjae: str
    ibjae: str
    ibjae_nis: float | None

class _Fusion:
    def step(
        self,
        dt_s: float,
        kbjae_deg: float | None = None,
        ibjae_deg: float | None = None,
        ibjae_sigma_deg: float | None = None,
        ibjae_occluded: bool = False,
    ) -> Estimate: ...
    def run(
        self,
        dt_s: float,
        kbjae_deg: npt.ArrayLike | None = None,
        ibjae_deg: npt.ArrayLike | None = None,
        ibjae_sigma_deg: npt.ArrayLike | None = None,
        ibjae_occluded: npt.ArrayLike | None = None,
    ) -> dict[str, npt.NDArray[Any]]: ...
    def estimate(self) -> Estimate: ...
    def reset(self) -> None: ...

class PaperKalman(_Fusion):
    def __init__(self, params: KalmanParams | None = None) -> None: ...

class AdaptiveKalman(_Fusion):
    def __init__(self, params: AdaptiveParams | None = None) -> None: ...

# ---- training data -------------------------------------------------------------

Arrays: TypeAlias = dict[str, npt.NDArray[Any]]

class KinematicSetSpec(_Params):
    amplitude_deg: float
    frequency_hz: float
    train: bool

class KinematicDatasetConfig(_Params):
    sets: list[dict[str, Any]]
    samples_per_set: int
    dt_s: float
    warmup_cycles: int
    plant: dict[str, Any]
    spread: float
    noise: dict[str, float] | None
    translation_mm: float
    seed: int
    def validate(self) -> None: ...
    def generate(self, threads: int = 0) -> tuple[Arrays, dict[str, Any]]: ...

class ImagePairsConfig(_Params):
    pairs: int
    seed: int
    poses: dict[str, list[float]]
    theta_step_deg: float
    translation_step_mm: float
    hard_share: float
    hard_offset_deg: list[float]
    tolerances: dict[str, float]
    backgrounds: list[Literal["colon", "stomach", "larynx"]]
    tissues: list[Literal["organ", "grey", "pale", "white", "blue_green", "yellow"]]
    background_seeds: int
    block: int
    illumination_gain: list[float]
    noise_std: list[float]
    blur_share: float
    blur_px: list[float]
    segment: dict[str, Any]
    max_attempts: int
    def validate(self) -> None: ...
    def generate(self, threads: int = 0) -> tuple[Arrays, dict[str, Any]]: ...
    def database(self, threads: int = 0) -> tuple[Arrays, dict[str, Any]]: ...

# ---- compensator (kflex-control's Compensator, Eq. 3-5) -------------------------

class CompensatorConfig(_Params):
    kp: float
    ki_per_s: float
    kd_s: float
    derivative_filter_s: float
    backlash_term: Literal["off", "pid_correction", "total_correction"]
    direction_deadband_deg: float
    theta_c_min_deg: float
    theta_c_max_deg: float
    integral_limit_deg: float | None
    freeze_integral_when_saturated: bool
    rate_limit_deg_per_s: float
    watchdog_timeout_s: float
    def validate(self) -> None: ...

class Terms:
    @property
    def p_deg(self) -> float: ...
    @property
    def i_deg(self) -> float: ...
    @property
    def d_deg(self) -> float: ...
    @property
    def g_deg(self) -> float: ...
    def f_deg(self) -> float: ...

FaultKind: TypeAlias = Literal["non_finite_desired", "invalid_dt", "non_finite_estimate", "watchdog", "other"]

class Fault:
    kind: FaultKind
    message: str
    details: dict[str, float]

class CompensatorOutput:
    theta_c_deg: float
    fault: Fault | None
    terms: Terms
    limited: bool
    estimate_age_s: float
    reversed: bool

class Compensator:
    def __init__(self, config: CompensatorConfig | None = None) -> None: ...
    @property
    def config(self) -> CompensatorConfig: ...
    @property
    def theta_c_deg(self) -> float: ...
    def step(self, theta_d_deg: float, theta_hat_deg: float | None, dt_s: float) -> CompensatorOutput: ...
    def run(
        self,
        theta_d_deg: npt.ArrayLike,
        theta_hat_deg: npt.ArrayLike | None,
        dt_s: float,
        has_estimate: npt.NDArray[np.bool_] | list[bool] | None = None,
    ) -> dict[str, npt.NDArray[Any]]: ...
    def reset(self) -> None: ...

# ---- the closed loop -------------------------------------------------------

class NoisyTruth:
    def __init__(self, sigma_deg: float, seed: int = 0) -> None: ...

class ClosedLoopScenario(_Params):
    motion: dict[str, Any]
    camera: dict[str, Any]
    frames: dict[str, Any]
    tolerances: dict[str, Any]
    compensator: dict[str, Any] | None
    def run(
        self,
        plant: Plant,
        estimator: NoisyTruth | Kbjae | Lbhjae,
        seed: int = 0,
        mcap_path: str | os.PathLike[str] | None = None,
    ) -> ClosedLoopTrace: ...

class ClosedLoopTrace:
    @property
    def time_s(self) -> FloatArray: ...
    @property
    def theta_d_deg(self) -> FloatArray: ...
    @property
    def theta_c_deg(self) -> FloatArray: ...
    @property
    def theta_a_deg(self) -> FloatArray: ...
    @property
    def theta_a_measured_deg(self) -> FloatArray: ...
    @property
    def theta_hat_deg(self) -> FloatArray: ...
    @property
    def details(self) -> dict[str, npt.NDArray[Any]]: ...
    @property
    def fault_ticks(self) -> int: ...
    @property
    def frames(self) -> dict[str, int]: ...
    def metrics(self) -> dict[str, float]: ...
    def estimation_rmse_deg(self) -> float: ...
    def __len__(self) -> int: ...

# ---- the paper's experiments: a grid of cases, run in Rust ----------------------------

class ExperimentGrid(_Params):
    cases: list[dict[str, Any]]
    estimators: list[str]
    repeats: int
    seed: int
    spread: float
    backgrounds: list[str]
    noise: dict[str, Any] | None
    plant: dict[str, Any]
    scenario: dict[str, Any]
    @staticmethod
    def paper() -> ExperimentGrid: ...
    @staticmethod
    def load(path: str | os.PathLike[str]) -> ExperimentGrid: ...
    def quick(self) -> ExperimentGrid: ...

def run_experiment(
    grid: ExperimentGrid | str | os.PathLike[str],
    models: str | os.PathLike[str] | None = None,
    jobs: int | None = None,
    time_series: bool = True,
    mcap_dir: str | os.PathLike[str] | None = None,
    mcap_frames: bool = False,
    details: bool = True,
) -> dict[str, list[dict[str, Any]]]: ...

# ---- estimators on ONNX models: KBJAE, the SCNN, the feature index, IBJAE, LBHJAE --

PathIn: TypeAlias = str | os.PathLike[str]
SilhouettesIn: TypeAlias = npt.NDArray[np.bool_] | npt.NDArray[np.uint8] | npt.NDArray[np.float32]
Float32Array: TypeAlias = npt.NDArray[np.float32]

class Kbjae:
    @staticmethod
    def load(path: PathIn) -> Kbjae: ...
    @property
    def sha256(self) -> str: ...
    def step(self, theta_c_deg: float, dt_s: float, rate_deg_per_s: float | None = None) -> float: ...
    def run(self, theta_c_deg: npt.ArrayLike, dt_s: float) -> FloatArray: ...
    def predict(self, theta_deg: float, rate_deg_per_s: float) -> float: ...
    def errors(self, theta_deg: npt.ArrayLike, rate_deg_per_s: npt.ArrayLike) -> Float32Array: ...
    def reset(self) -> None: ...

class Scnn:
    @staticmethod
    def load(path: PathIn, threads: int = 1) -> Scnn: ...
    @property
    def sha256(self) -> str: ...
    def embed(self, silhouettes: SilhouettesIn) -> Float32Array: ...

class Neighbour:
    @property
    def index(self) -> int: ...
    @property
    def theta_deg(self) -> float: ...
    @property
    def translation_mm(self) -> float: ...
    @property
    def distance_sq(self) -> float: ...
    @property
    def distance(self) -> float: ...

FeaturesIn: TypeAlias = npt.NDArray[np.float32] | npt.NDArray[np.float64]

class FeatureIndex:
    @staticmethod
    def build(
        features: FeaturesIn,
        theta_deg: npt.ArrayLike,
        translation_mm: FloatsIn | None = None,
        projection_dims: Literal[8, 12, 16] = 8,
        search: Literal["auto", "tree", "scan"] = "auto",
    ) -> FeatureIndex: ...
    @staticmethod
    def load(path: PathIn) -> FeatureIndex: ...
    def save(self, path: PathIn) -> None: ...
    def nearest(self, query: FeaturesIn) -> Neighbour: ...
    def nearest_linear(self, query: FeaturesIn) -> Neighbour: ...
    def nearest_batch(self, queries: FeaturesIn) -> dict[str, npt.NDArray[Any]]: ...
    def __len__(self) -> int: ...
    @property
    def dim(self) -> int: ...
    @property
    def projection_dims(self) -> int: ...
    @property
    def search(self) -> Literal["tree", "scan"]: ...
    @property
    def features(self) -> Float32Array: ...
    @property
    def theta_deg(self) -> FloatArray: ...
    @property
    def translation_mm(self) -> FloatArray: ...
    @property
    def metadata(self) -> dict[str, str]: ...
    def set_metadata(self, key: str, value: str) -> None: ...

def build_band_database(
    scnn: Scnn,
    camera: Camera,
    instrument: Instrument,
    band: WorkingBand,
    theta_step_deg: float,
    translation_step_mm: float,
) -> FeatureIndex: ...

class IbjaeReading:
    theta_deg: float
    translation_mm: float
    distance: float
    sigma_deg: float
    band: int
    silhouette_iou: float | None
    occluded: bool
    consistent_deg: list[float] | None

class Ibjae:
    def __init__(
        self,
        scnn: PathIn,
        databases: list[FeatureIndex],
        segment: SegmentParams | None = None,
        threads: int = 1,
        camera: Camera | None = None,
        instrument: Instrument | None = None,
        min_silhouette_iou: float | None = None,
    ) -> None: ...
    @property
    def bands(self) -> list[WorkingBand]: ...
    def bands_for(self, theta_hint_deg: float | None, translation_mm: float) -> list[int]: ...
    def read(self, rgb: npt.NDArray[np.uint8], bands: list[int]) -> IbjaeReading | None: ...
    def prepare_hidden_parts(self) -> None: ...
    @property
    def hidden_parts_ready(self) -> bool: ...

class LbhjaeEstimate:
    fused: Estimate
    kbjae_deg: float
    ibjae: IbjaeReading | None

class Lbhjae:
    def __init__(
        self,
        kbjae: PathIn,
        scnn: PathIn,
        databases: list[FeatureIndex],
        fusion: KalmanParams | AdaptiveParams,
        segment: SegmentParams | None = None,
        camera: Camera | None = None,
        instrument: Instrument | None = None,
        min_silhouette_iou: float | None = None,
    ) -> None: ...
    def step(
        self,
        theta_c_deg: float,
        translation_mm: float,
        dt_s: float,
        rgb: npt.NDArray[np.uint8] | None = None,
        rate_deg_per_s: float | None = None,
    ) -> LbhjaeEstimate: ...
    def reset(self) -> None: ...
    def prepare_hidden_parts(self) -> None: ...
    @property
    def hidden_parts_ready(self) -> bool: ...

def _prefer_onnxruntime_package(dir: str | os.PathLike[str]) -> bool: ...
