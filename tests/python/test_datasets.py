"""The training data sets from Python: D^k (KBJAE), D^I and its database
(IBJAE), their cards, the .npz files, and equality with the Rust crates."""

from __future__ import annotations

import json

import kflex
import kflex.npz
import numpy as np
import pytest
from test_api import _progress_while


@pytest.fixture(scope="module")
def kinematic():
    config = kflex.KinematicDatasetConfig(samples_per_set=400)
    return config, *config.generate()


@pytest.fixture(scope="module")
def pairs():
    config = kflex.ImagePairsConfig(pairs=48, block=4, seed=3)
    return config, *config.generate()


# ---- D^k -------------------------------------------------------------------


def test_kinematic_arrays_shapes_dtypes_and_the_papers_split(kinematic):
    config, arrays, card = kinematic
    for name in ("theta_d_deg", "theta_d_rate_deg_per_s", "theta_a_deg", "theta_a_measured_deg"):
        assert arrays[name].shape == (12, 400) and arrays[name].dtype == np.float64, name
    assert arrays["train"].dtype == np.bool_ and arrays["seed"].dtype == np.uint64
    train = arrays["amplitude_deg"][arrays["train"]]
    test = arrays["amplitude_deg"][~arrays["train"]]
    assert train.tolist() == [35, 45, 55, 65, 75, 85] and test.tolist() == [30, 40, 50, 60, 70, 80]
    assert arrays["seed"].tolist() == list(range(2020, 2032))
    # each signal sweeps [0, A]; the measured angle carries the tracker's noise
    assert np.all(arrays["theta_d_deg"] >= 0) and np.all(arrays["theta_d_deg"].T <= arrays["amplitude_deg"] + 1e-9)
    assert not np.array_equal(arrays["theta_a_deg"], arrays["theta_a_measured_deg"])
    assert card["kind"] == "kinematic" and card["seed"] == 2020
    assert card["sizes"]["theta_d_deg"] == [12, 400]
    assert card["params"] == config.to_dict()
    assert card["kflex_version"] and card["generator_version"] >= 1


def test_kinematic_is_deterministic_in_its_seed_whatever_the_threads(kinematic):
    config, arrays, _ = kinematic
    again, _ = config.generate(threads=1)
    for name, values in arrays.items():
        assert np.array_equal(values, again[name]), name
    other = config.copy()
    other.seed = 1
    changed, _ = other.generate()
    assert not np.array_equal(changed["theta_a_deg"], arrays["theta_a_deg"])


def test_kinematic_errors():
    with pytest.raises(kflex.RangeError, match="samples_per_set") as e:
        kflex.KinematicDatasetConfig(samples_per_set=0).generate()
    assert e.value.name == "samples_per_set"
    with pytest.raises(kflex.RangeError, match="amplitude_deg"):
        kflex.KinematicDatasetConfig(sets=[{"amplitude_deg": -5.0, "frequency_hz": 0.1, "train": True}]).generate()
    with pytest.raises(TypeError, match="missing field"):
        kflex.KinematicSetSpec(amplitude_deg=30.0)
    with pytest.raises(TypeError, match="unknown field"):
        kflex.KinematicDatasetConfig(samples=5)
    # each field in range, but together more than memory holds: refused
    # before anything is allocated
    sets = [{"amplitude_deg": 30.0, "frequency_hz": 0.1, "train": True}] * 1000
    with pytest.raises(kflex.RangeError, match="samples_per_set"):
        kflex.KinematicDatasetConfig(sets=sets, samples_per_set=10**7).validate()


# ---- D^I ---------------------------------------------------------------------


def test_pairs_shapes_dtypes_balance_and_hard_negatives(pairs):
    config, a, card = pairs
    n = 48
    assert a["x_b"].shape == a["x_r"].shape == (n, 48, 48) and a["x_b"].dtype == np.bool_
    assert a["s"].dtype == np.uint8 and a["hard"].dtype == np.bool_
    assert a["query"].dtype == np.int64 and a["band"].dtype == np.int64
    assert a["s"].sum() == n // 2  # balanced
    assert a["hard"].any() and not (a["hard"] & (a["s"] == 1)).any()
    # labels: the query's grid cell (1 deg x 1 mm)
    same = (np.abs(a["theta_b_deg"] - a["theta_r_deg"]) <= 0.5) & (
        np.abs(a["translation_b_mm"] - a["translation_r_mm"]) <= 0.5
    )
    assert np.array_equal(same, a["s"] == 1)
    # hard negatives: same d, a few degrees apart
    hard = a["hard"]
    offset = np.abs(a["theta_r_deg"][hard] - np.round(a["theta_b_deg"][hard]))
    assert np.all((offset >= 2) & (offset <= 5))
    assert np.array_equal(a["translation_r_mm"][hard], np.round(a["translation_b_mm"][hard]))
    # poses over the full range, every silhouette showing the instrument
    assert np.all(np.abs(a["theta_b_deg"]) <= 90) and np.all(
        (a["translation_b_mm"] >= 8) & (a["translation_b_mm"] <= 40)
    )
    assert a["x_b"].reshape(n, -1).any(axis=1).all() and a["x_r"].reshape(n, -1).any(axis=1).all()
    assert card["kind"] == "image_pairs" and card["stats"]["positives"] == n // 2
    assert card["stats"]["hard_negatives"] == hard.sum()
    assert card["params"] == config.to_dict()


def test_pairs_are_deterministic_in_their_seed_whatever_the_threads(pairs):
    config, a, _ = pairs
    again, _ = config.generate(threads=1)
    for name, values in a.items():
        assert np.array_equal(values, again[name]), name


def test_database_entries_lie_on_the_grid_in_every_band():
    config = kflex.ImagePairsConfig(poses=kflex.PoseRange(theta_deg=[0.0, 30.0], translation_mm=[10.0, 14.0]))
    db, card = config.database()
    n = len(db["theta_deg"])
    assert db["masks"].shape == (n, 48, 48) and db["masks"].dtype == np.bool_
    assert np.all(db["theta_deg"] == np.round(db["theta_deg"]))
    assert set(np.unique(db["band"])) == set(range(int(card["stats"]["bands"])))
    assert card["kind"] == "image_database" and card["sizes"]["masks"] == [n, 48, 48]


def test_pairs_errors():
    with pytest.raises(ValueError, match="even number"):
        kflex.ImagePairsConfig(pairs=3).generate()
    with pytest.raises(kflex.RangeError, match="theta_step_deg"):
        kflex.ImagePairsConfig(pairs=2, theta_step_deg=2.0).generate()
    with pytest.raises(kflex.RangeError, match="hard_share"):
        kflex.ImagePairsConfig(hard_share=1.5).validate()
    with pytest.raises(kflex.RangeError, match="pairs"):
        kflex.ImagePairsConfig(pairs=10**7).validate()
    with pytest.raises(ValueError, match="unknown variant"):
        kflex.ImagePairsConfig(backgrounds=["mars"])


def test_generation_releases_the_interpreter():
    config = kflex.ImagePairsConfig(pairs=40, block=4)
    duration, share = _progress_while(lambda: config.generate(threads=1))
    assert duration > 0.05, "the call is too short to tell"
    # released, this thread runs through most of the call (see test_api)
    assert share > 0.5, (duration, share)


# ---- files -----------------------------------------------------------------


def test_npz_round_trip_with_its_card(tmp_path, pairs):
    _, a, card = pairs
    path = kflex.npz.save(tmp_path / "sub" / "pairs.npz", a, card)
    assert kflex.npz.card_path(path).name == "pairs.card.json"
    assert not list(path.parent.glob("*.tmp"))  # nothing left of the atomic writes
    back, back_card = kflex.npz.load(path)
    assert set(back) == set(a)
    for name in a:
        assert np.array_equal(back[name], a[name]) and back[name].dtype == a[name].dtype, name
    assert back_card["sha256"] and back_card["file"] == "pairs.npz"
    assert back_card["params"] == card["params"]
    # a changed file no longer matches its card
    path.write_bytes(path.read_bytes() + b"\0")
    with pytest.raises(ValueError, match="SHA-256"):
        kflex.npz.load(path)
    with pytest.raises(ValueError, match=".npz"):
        kflex.npz.save(tmp_path / "pairs.bin", a, card)
    with pytest.raises(FileNotFoundError):
        kflex.npz.load(tmp_path / "missing.npz")
    json.loads(kflex.npz.card_path(path).read_text())


def test_npz_save_with_a_card_json_cannot_hold_keeps_the_earlier_set(tmp_path, pairs):
    _, a, card = pairs
    path = kflex.npz.save(tmp_path / "pairs.npz", a, card)
    before = (path.read_bytes(), kflex.npz.card_path(path).read_text())
    smaller = {name: v[:1] for name, v in a.items()}
    with pytest.raises(TypeError, match="card"):
        kflex.npz.save(path, smaller, {**card, "amplitudes": np.array([1.0, 2.0])})
    # neither file was touched: the earlier set still loads, as it was
    assert (path.read_bytes(), kflex.npz.card_path(path).read_text()) == before
    back, _ = kflex.npz.load(path)
    assert all(np.array_equal(back[name], a[name]) for name in a)
    assert not list(tmp_path.glob(".*.tmp"))


# ---- equal to Rust -----------------------------------------------------------


def test_datasets_equal_rust(golden):
    g = golden["datasets"]["kinematic"]
    arrays, card = kflex.KinematicDatasetConfig.from_dict(g["config"]).generate()
    for i, s in enumerate(g["sets"]):
        for name in ("theta_d_deg", "theta_d_rate_deg_per_s", "theta_a_deg", "theta_a_measured_deg"):
            assert arrays[name][i].tolist() == s[name], (i, name)
        assert arrays["seed"][i] == s["seed"]
    assert card == g["card"]
    g = golden["datasets"]["pairs"]
    a, card = kflex.ImagePairsConfig.from_dict(g["config"]).generate()
    assert a["x_b"].astype(np.uint8).ravel().tolist() == g["x_b"]
    assert a["x_r"].astype(np.uint8).ravel().tolist() == g["x_r"]
    for name in ("s", "band", "theta_b_deg", "translation_b_mm", "theta_r_deg", "translation_r_mm"):
        assert a[name].tolist() == g[name], name
    assert a["hard"].astype(np.uint8).tolist() == g["hard"]
    assert card == g["card"]
