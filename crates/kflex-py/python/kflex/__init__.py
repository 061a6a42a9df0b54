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
"""

from kflex._kflex import (
    AuroraNoise,
    Banding,
    BuildTolerances,
    BuiltInstrument,
    Camera,
    Command,
    Frame,
    FrameParams,
    ImagePairsConfig,
    Instrument,
    InstrumentParams,
    InstrumentShape,
    Intrinsics,
    JointParams,
    KinematicDatasetConfig,
    KinematicSetSpec,
    Lens,
    NoInstrumentError,
    Occlusion,
    OpenLoopScenario,
    Plant,
    PlantConfig,
    PlantState,
    PoseRange,
    RangeError,
    Rasterizer,
    Roi,
    SceneRenderer,
    Seating,
    Segmentation,
    Segmenter,
    SegmentParams,
    SheathParams,
    Sine,
    TendonGeometry,
    Trace,
    Trajectory,
    TranslationParams,
    WorkingBand,
    WorkingRegions,
    segment,
)
from kflex._kflex import (
    __version__ as __version__,
)

__all__ = [
    "AuroraNoise",
    "Banding",
    "BuildTolerances",
    "BuiltInstrument",
    "Camera",
    "Command",
    "Frame",
    "FrameParams",
    "ImagePairsConfig",
    "Instrument",
    "InstrumentParams",
    "InstrumentShape",
    "Intrinsics",
    "JointParams",
    "KinematicDatasetConfig",
    "KinematicSetSpec",
    "Lens",
    "NoInstrumentError",
    "Occlusion",
    "OpenLoopScenario",
    "Plant",
    "PlantConfig",
    "PlantState",
    "PoseRange",
    "RangeError",
    "Rasterizer",
    "Roi",
    "SceneRenderer",
    "Seating",
    "SegmentParams",
    "Segmentation",
    "Segmenter",
    "SheathParams",
    "Sine",
    "TendonGeometry",
    "Trace",
    "Trajectory",
    "TranslationParams",
    "WorkingBand",
    "WorkingRegions",
    "segment",
]
