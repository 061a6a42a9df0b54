"""Counts, sizes and seeds (the arguments Rust takes as unsigned integers):
a negative or too-large int is a ValueError naming the argument, its value
and the range, not pyo3's bare OverflowError; a non-int stays a TypeError.

IBJAE's `read` (its `bands`) is checked in test_estimation.py, beside the
models it needs."""

from __future__ import annotations

import re

import kflex
import numpy as np
import pytest

U32 = "from 0 to 4294967295"
U64 = "from 0 to 18446744073709551615"


def set_seed(value: int) -> None:
    kflex.PlantConfig().seed = value


def features() -> np.ndarray:
    return np.arange(20 * 16, dtype=np.float32).reshape(20, 16)


# (argument, range in the message, a call with `v` in that argument)
CALLS = {
    "Intrinsics.from_fov width": ("width", U32, lambda v: kflex.Intrinsics.from_fov(v, 480, 60.0)),
    "Intrinsics.from_fov height": ("height", U32, lambda v: kflex.Intrinsics.from_fov(640, v, 60.0)),
    "Intrinsics.region out_w": ("out_w", U32, lambda v: kflex.Intrinsics.default().region(0, 0, 10, 10, v, 10)),
    "Intrinsics.region out_h": ("out_h", U32, lambda v: kflex.Intrinsics.default().region(0, 0, 10, 10, 10, v)),
    "Roi.whole width": ("width", U32, lambda v: kflex.Roi.whole(v, 5)),
    "Roi.whole height": ("height", U32, lambda v: kflex.Roi.whole(5, v)),
    "Roi.for_workspace margin_px": (
        "margin_px",
        U32,
        lambda v: kflex.Roi.for_workspace(kflex.Camera(), kflex.Instrument.kflex(), kflex.PoseRange.paper(), v),
    ),
    "Roi.check_within width": ("width", U32, lambda v: kflex.Roi.whole(5, 5).check_within(v, 5)),
    "Roi.check_within height": ("height", U32, lambda v: kflex.Roi.whole(5, 5).check_within(5, v)),
    "BuildTolerances.instrument seed": (
        "seed",
        U64,
        lambda v: kflex.BuildTolerances().instrument(kflex.Instrument.kflex(), v),
    ),
    "BuildTolerances.camera seed": ("seed", U64, lambda v: kflex.BuildTolerances().camera(kflex.Camera(), v)),
    "Instrument n_segments": (
        "n_segments",
        U32,
        lambda v: kflex.Instrument(kflex.JointParams(), kflex.InstrumentParams(), v, kflex.TranslationParams()),
    ),
    "NoisyTruth seed": ("seed", U64, lambda v: kflex.NoisyTruth(1.0, seed=v)),
    "ClosedLoopScenario.run seed": (
        "seed",
        U64,
        lambda v: kflex.ClosedLoopScenario().run(kflex.Plant(), kflex.NoisyTruth(1.0), seed=v),
    ),
    "PlantConfig.perturbed seed": ("seed", U64, lambda v: kflex.PlantConfig().perturbed(v, 0.1)),
    "PlantConfig.seed": ("seed", U64, set_seed),
    "KinematicDatasetConfig.generate threads": (
        "threads",
        U64,
        lambda v: kflex.KinematicDatasetConfig().generate(threads=v),
    ),
    "ImagePairsConfig.generate threads": ("threads", U64, lambda v: kflex.ImagePairsConfig().generate(threads=v)),
    "ImagePairsConfig.database threads": ("threads", U64, lambda v: kflex.ImagePairsConfig().database(threads=v)),
    "run_experiment jobs": ("jobs", U64, lambda v: kflex.run_experiment(kflex.ExperimentGrid(), jobs=v)),
    "Scnn.load threads": ("threads", U64, lambda v: kflex.Scnn.load("no_such_model.onnx", threads=v)),
    "Ibjae threads": ("threads", U64, lambda v: kflex.Ibjae("no_such_model.onnx", [], threads=v)),
    # only 8, 12 or 16 are taken: the message says so
    "FeatureIndex.build projection_dims": (
        "projection_dims",
        "must be 8, 12 or 16",
        lambda v: kflex.FeatureIndex.build(features(), np.arange(20.0), projection_dims=v),
    ),
}


@pytest.mark.parametrize("case", sorted(CALLS))
def test_a_negative_count_is_a_value_error_naming_it(case: str) -> None:
    name, allowed, call = CALLS[case]
    with pytest.raises(ValueError, match=re.escape(f"{name} = -1: ")) as err:
        call(-1)
    assert allowed in str(err.value)


@pytest.mark.parametrize("case", sorted(CALLS))
def test_an_int_too_large_for_the_type_is_a_value_error_naming_it(case: str) -> None:
    name, allowed, call = CALLS[case]
    with pytest.raises(ValueError, match=re.escape(f"{name} = {2**64}: ")) as err:
        call(2**64)
    assert allowed in str(err.value)


def test_the_message_gives_the_value_and_the_whole_range() -> None:
    with pytest.raises(ValueError) as err:
        kflex.Roi.whole(-1, 5)
    assert str(err.value) == "width = -1: must be a whole number from 0 to 4294967295"
    with pytest.raises(ValueError) as err:
        kflex.NoisyTruth(1.0, seed=2**64)
    assert str(err.value) == (
        "seed = 18446744073709551616: must be a whole number from 0 to 18446744073709551615"
    )


def test_the_ends_of_the_range_are_taken() -> None:
    kflex.NoisyTruth(1.0, seed=0)
    kflex.NoisyTruth(1.0, seed=2**64 - 1)
    config = kflex.PlantConfig()
    config.seed = 2**64 - 1
    assert config.seed == 2**64 - 1
    assert config.perturbed(2**64 - 1, 0.1).seed == 2**64 - 1
    assert kflex.Intrinsics.from_fov(640, 480, 60.0).width == 640


def test_ints_of_other_kinds_are_taken_and_non_ints_stay_type_errors() -> None:
    assert kflex.Roi.whole(np.int64(3), True) == kflex.Roi(x0=0, y0=0, width=3, height=1)
    with pytest.raises(ValueError, match=re.escape("height = -2: ")):
        kflex.Roi.whole(3, np.int64(-2))
    for bad in (1.5, "3", None):
        with pytest.raises(TypeError):
            kflex.Roi.whole(bad, 5)
        with pytest.raises(TypeError):
            kflex.NoisyTruth(1.0, seed=bad)
    with pytest.raises(TypeError):
        kflex.PlantConfig().seed = 1.5


def test_checks_after_the_conversion_stay() -> None:
    # a region of no pixels is refused as before, by the Rust check
    with pytest.raises(kflex.RangeError):
        kflex.Roi.whole(0, 5)
