"""kflex: the simulated tendon-driven flexible surgery robot, from Python.

Thin wrappers over the Rust crates (kflex-model, kflex-estimate,
kflex-control); names and units follow the Rust API. Arrays are numpy:
frames H x W x 3 uint8, masks and silhouettes H x W bool, series float64.
Errors: ``RangeError`` (a ``ValueError`` carrying ``name``, ``value``,
``min``, ``max``) for out-of-range values, ``ValueError`` for other bad
values, ``TypeError`` for a wrong dtype or shape, ``RuntimeError`` for
runtime faults.

Training data: ``KinematicDatasetConfig().generate()`` (KBJAE's D^k) and
``ImagePairsConfig().generate()`` / ``.database()`` (IBJAE's D^I and its
retrieval database) return ``(arrays, card)``; ``kflex.npz.save`` and
``kflex.npz.load`` keep them on disk as ``.npz`` with a JSON card beside.

Control and estimation: ``Compensator`` (Eq. 3-5 with its limits, faults
and watchdog); ``Kbjae`` and ``Scnn`` run ONNX models through ONNX Runtime,
loaded from the ``onnxruntime`` wheel when the first model is (a
``RuntimeError`` says what to install when it is missing);
``FeatureIndex`` and ``build_band_database`` make IBJAE's databases;
``Ibjae`` and ``Lbhjae`` are the whole estimators.

The closed loop: ``ClosedLoopScenario().run(plant, estimator, seed)`` steps
the compensator, the plant, the robot's camera and an estimator (a
``NoisyTruth`` stand-in, ``Kbjae`` or ``Lbhjae``) in Rust and returns a
``ClosedLoopTrace``; with ``mcap_path`` it also writes the run's MCAP log.

The paper's experiments: ``run_experiment(ExperimentGrid.load("assets/scenarios/paper.toml"))``
runs a grid of Tables V–X in Rust (the estimators' trained models from a
``models`` directory) and returns its records and every run's time series
as numpy arrays.
"""

from kflex._kflex import (
    AdaptiveKalman,
    AdaptiveParams,
    AuroraNoise,
    Banding,
    BuildTolerances,
    BuiltInstrument,
    Camera,
    ClosedLoopScenario,
    ClosedLoopTrace,
    Command,
    Compensator,
    CompensatorConfig,
    CompensatorOutput,
    Estimate,
    ExperimentGrid,
    Fault,
    FeatureIndex,
    Frame,
    FrameParams,
    Ibjae,
    IbjaeReading,
    ImagePairsConfig,
    Instrument,
    InstrumentParams,
    InstrumentShape,
    Intrinsics,
    JointParams,
    KalmanParams,
    Kbjae,
    KinematicDatasetConfig,
    KinematicSetSpec,
    Lbhjae,
    LbhjaeEstimate,
    Lens,
    Neighbour,
    NoInstrumentError,
    NoisyTruth,
    Occlusion,
    OpenLoopScenario,
    PaperKalman,
    Plant,
    PlantConfig,
    PlantState,
    PoseRange,
    RangeError,
    Rasterizer,
    Roi,
    SceneRenderer,
    Scnn,
    Seating,
    Segmentation,
    Segmenter,
    SegmentParams,
    SheathParams,
    Sine,
    TendonGeometry,
    Terms,
    Trace,
    Trajectory,
    TranslationParams,
    WorkingBand,
    WorkingRegions,
    build_band_database,
    run_experiment,
    segment,
)
from kflex._kflex import (
    __version__ as __version__,
)


def _name_onnxruntime() -> None:
    # ONNX Runtime comes from the onnxruntime wheel; name this interpreter's
    # (found without importing it) so that an environment that is not
    # activated still finds its own. ORT_DYLIB_PATH, when set, still wins.
    import importlib.util

    from kflex._kflex import _prefer_onnxruntime_package

    spec = importlib.util.find_spec("onnxruntime")
    location = next(iter(spec.submodule_search_locations or []), None) if spec else None
    if location is not None:
        _prefer_onnxruntime_package(location)


_name_onnxruntime()

__all__ = [
    "AdaptiveKalman",
    "AdaptiveParams",
    "AuroraNoise",
    "Banding",
    "BuildTolerances",
    "BuiltInstrument",
    "Camera",
    "ClosedLoopScenario",
    "ClosedLoopTrace",
    "Command",
    "Compensator",
    "CompensatorConfig",
    "CompensatorOutput",
    "Estimate",
    "ExperimentGrid",
    "Fault",
    "FeatureIndex",
    "Frame",
    "FrameParams",
    "Ibjae",
    "IbjaeReading",
    "ImagePairsConfig",
    "Instrument",
    "InstrumentParams",
    "InstrumentShape",
    "Intrinsics",
    "JointParams",
    "KalmanParams",
    "Kbjae",
    "KinematicDatasetConfig",
    "KinematicSetSpec",
    "Lbhjae",
    "LbhjaeEstimate",
    "Lens",
    "Neighbour",
    "NoInstrumentError",
    "NoisyTruth",
    "Occlusion",
    "OpenLoopScenario",
    "PaperKalman",
    "Plant",
    "PlantConfig",
    "PlantState",
    "PoseRange",
    "RangeError",
    "Rasterizer",
    "Roi",
    "SceneRenderer",
    "Scnn",
    "Seating",
    "SegmentParams",
    "Segmentation",
    "Segmenter",
    "SheathParams",
    "Sine",
    "TendonGeometry",
    "Terms",
    "Trace",
    "Trajectory",
    "TranslationParams",
    "WorkingBand",
    "WorkingRegions",
    "build_band_database",
    "run_experiment",
    "segment",
]
