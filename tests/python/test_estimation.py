"""The estimators from Python on the small test models that
tools/make_test_models.py writes (made afresh for the session, with this
Python's onnx and numpy): KBJAE and the SCNN against the float64 reference
outputs the tool writes beside them, one at a time and batched; the feature
index against a brute-force search and through its file; IBJAE and LBHJAE
end to end on rendered frames; and the errors: wrong shapes, missing or
damaged files, a model card that records another file, no ONNX Runtime."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import kflex
import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


class Models:
    def __init__(self, path: Path) -> None:
        self.path = path

    def __truediv__(self, name: str) -> Path:
        return self.path / name

    def expected(self, name: str) -> dict:
        return json.loads((self.path / f"{name}.expected.json").read_text())


@pytest.fixture(scope="session")
def models(tmp_path_factory: pytest.TempPathFactory) -> Models:
    out = tmp_path_factory.mktemp("models")
    tool = REPO_ROOT / "tools" / "make_test_models.py"
    subprocess.run([sys.executable, str(tool), "--out", str(out)], check=True, capture_output=True)
    return Models(out)


@pytest.fixture(scope="session")
def kbjae_path(models: Models) -> Path:
    return models / "kbjae_test.onnx"


# ---- KBJAE ---------------------------------------------------------------------


def test_kbjae_gives_the_networks_output_one_at_a_time_and_batched(kbjae_path: Path, models: Models) -> None:
    expected = models.expected("kbjae_test")
    x = np.array(expected["inputs"])
    want = np.array(expected["theta_error"])
    k = kflex.Kbjae.load(kbjae_path)
    assert len(k.sha256) == 64
    single = np.array([k.predict(t, r) - t for t, r in x])
    np.testing.assert_allclose(single, want, rtol=1e-5, atol=1e-5)
    batch = k.errors(x[:, 0], x[:, 1])
    assert batch.dtype == np.float32 and batch.shape == (len(x),)
    np.testing.assert_allclose(batch, want, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(batch, single, rtol=1e-5, atol=1e-5)
    # float32 inputs give the same errors
    assert np.array_equal(k.errors(x[:, 0].astype(np.float32), x[:, 1].astype(np.float32)), batch)


def test_kbjae_steps_differentiate_the_command(kbjae_path: Path) -> None:
    k, probe = kflex.Kbjae.load(kbjae_path), kflex.Kbjae.load(kbjae_path)
    assert k.step(10.0, 0.01) == probe.predict(10.0, 0.0)  # no history: rate 0
    assert k.step(10.5, 0.02) == probe.predict(10.5, 25.0)
    with pytest.raises(ValueError, match="theta_c_deg"):
        k.step(float("nan"), 0.01)
    with pytest.raises(kflex.RangeError) as e:
        k.step(11.0, 0.0)
    assert e.value.name == "dt_s"
    assert k.step(11.0, 0.01) == probe.predict(11.0, 50.0)  # the refused ticks changed nothing
    k.reset()
    theta = np.array([3.0, 3.5, 4.5, 4.0])
    angles = k.run(theta, 0.1)
    assert angles[0] == probe.predict(3.0, 0.0)
    assert angles[3] == probe.predict(4.0, -5.0)
    # a rate given (the master's, in a compensated loop) is read as given;
    # the history stays the commands'
    assert k.step(5.0, 0.1, rate_deg_per_s=-3.0) == probe.predict(5.0, -3.0)
    with pytest.raises(ValueError, match="rate_deg_per_s"):
        k.step(6.0, 0.1, rate_deg_per_s=float("inf"))
    assert k.step(6.0, 0.1) == probe.predict(6.0, 10.0)
    # a step's refusals name the step's own quantities: the command, and the
    # rate differenced from the commands where none was given
    with pytest.raises(kflex.RangeError) as e:
        k.step(1e308, 0.1)
    assert e.value.name == "theta_c_deg"
    with pytest.raises(kflex.RangeError) as e:
        k.step(1e5, 1e-6)
    assert e.value.name.startswith("the commands' rate"), e.value.name
    assert k.step(6.5, 0.1) == probe.predict(6.5, 5.0)  # both changed nothing
    # a run is all or nothing: a bad last command leaves the history as it was
    k.reset()
    k.step(1.0, 0.1)
    with pytest.raises(ValueError, match="theta_c_deg"):
        k.run(np.array([2.0, 3.0, np.nan]), 0.1)
    assert k.step(1.5, 0.1) == probe.predict(1.5, 5.0)  # from 1.0, not from 3.0
    # the batch checks the values as given, before float32 makes 1e39 infinite
    with pytest.raises(kflex.RangeError) as e:
        k.errors(np.array([1e39]), np.array([0.0]))
    assert e.value.name == "theta_deg"


def test_kbjae_refuses_bad_arrays(kbjae_path: Path) -> None:
    k = kflex.Kbjae.load(kbjae_path)
    with pytest.raises(TypeError, match="rates"):
        k.errors(np.zeros(4), np.zeros(3))
    with pytest.raises(TypeError, match=r"shape \[2, 2\]"):
        k.errors(np.zeros((2, 2)), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="rate_deg_per_s"):
        k.errors(np.zeros(2), np.array([0.0, np.inf]))
    assert k.errors(np.zeros(0), np.zeros(0)).shape == (0,)
    # values the f32 network would read as infinite
    with pytest.raises(ValueError, match="rate_deg_per_s"):
        k.predict(0.0, 1e39)
    with pytest.raises(ValueError, match="theta_deg"):
        k.predict(1e39, 0.0)


# ---- model files ---------------------------------------------------------------


def test_a_missing_model_is_a_file_not_found_error_naming_it(tmp_path: Path) -> None:
    missing = tmp_path / "nothing.onnx"
    with pytest.raises(FileNotFoundError, match="nothing.onnx"):
        kflex.Kbjae.load(missing)
    with pytest.raises(FileNotFoundError, match="nothing.onnx"):
        kflex.Scnn.load(str(missing))


def test_a_model_its_card_does_not_describe_is_refused(kbjae_path: Path, tmp_path: Path) -> None:
    model = tmp_path / "kbjae.onnx"
    shutil.copy(kbjae_path, model)
    kflex.Kbjae.load(model)  # no card: loads
    (tmp_path / "kbjae.card.json").write_text('{"sha256": "00ff"}')
    with pytest.raises(ValueError, match="00ff"):
        kflex.Kbjae.load(model)
    (tmp_path / "kbjae.card.json").write_text("not json")
    with pytest.raises(ValueError, match="card"):
        kflex.Kbjae.load(model)
    # the card the tool writes is right
    card = json.loads(kbjae_path.with_suffix(".card.json").read_text())
    assert kflex.Kbjae.load(kbjae_path).sha256 == card["sha256"]


def test_models_of_the_wrong_contract_and_damaged_files_are_refused(models: Models, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="theta_and_rate"):
        kflex.Kbjae.load(models / "renamed_test.onnx")
    with pytest.raises(ValueError, match="silhouette"):
        kflex.Scnn.load(models / "kbjae_test.onnx")
    truncated = tmp_path / "truncated.onnx"
    data = (models / "kbjae_test.onnx").read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises((RuntimeError, ValueError)):
        kflex.Kbjae.load(truncated)


def with_nan_weights(model: Path, out: Path) -> Path:
    """A copy of `model` whose first weight tensor is all NaN (a damaged file
    that still loads: the contract and the graph are intact)."""
    import onnx
    from onnx import numpy_helper

    proto = onnx.load(str(model))
    first = proto.graph.initializer[0]
    bad = np.full(numpy_helper.to_array(first).shape, np.nan, np.float32)
    first.CopyFrom(numpy_helper.from_array(bad, first.name))
    onnx.save(proto, str(out))
    return out


def test_a_model_that_answers_nan_is_a_runtime_error_not_a_number(models: Models, tmp_path: Path) -> None:
    k = kflex.Kbjae.load(with_nan_weights(models / "kbjae_test.onnx", tmp_path / "kbjae_nan.onnx"))
    for call in (
        lambda: k.predict(10.0, 1.0),
        lambda: k.errors(np.array([10.0, 20.0]), np.array([0.0, 1.0])),
        lambda: k.step(10.0, 0.01),
    ):
        with pytest.raises(RuntimeError, match="damaged"):
            call()
    scnn = kflex.Scnn.load(with_nan_weights(models / "scnn_test.onnx", tmp_path / "scnn_nan.onnx"))
    masks, _ = scnn_case(models)
    with pytest.raises(RuntimeError, match="damaged"):
        scnn.embed(masks)
    # one at a time too, every time (Python's embed goes through the batch
    # call, which keeps no embeddings: each call runs the model again)
    for _ in range(2):
        with pytest.raises(RuntimeError, match="damaged"):
            scnn.embed(masks[0])


def test_threads_may_share_one_model(models: Models, kbjae_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    masks, _ = scnn_case(models)
    scnn, k = kflex.Scnn.load(models / "scnn_test.onnx"), kflex.Kbjae.load(kbjae_path)
    theta, rate = np.linspace(0.0, 50.0, 64), np.linspace(-20.0, 20.0, 64)
    want = (scnn.embed(masks), k.errors(theta, rate), k.predict(12.0, 3.0))

    def work(_: int):
        return [(scnn.embed(masks), k.errors(theta, rate), k.predict(12.0, 3.0)) for _ in range(20)]

    # the calls take turns (they once raised "Already borrowed")
    with ThreadPoolExecutor(4) as pool:
        for results in pool.map(work, range(8)):
            for embedded, errors, predicted in results:
                assert np.array_equal(embedded, want[0])
                assert np.array_equal(errors, want[1])
                assert predicted == want[2]


def test_without_onnx_runtime_loading_raises_a_runtime_error_that_says_what_to_do(kbjae_path: Path) -> None:
    # its own process: the runtime is loaded once per process
    script = (
        "import kflex, sys\n"
        "try:\n"
        f"    kflex.Kbjae.load({str(kbjae_path)!r})\n"
        "except RuntimeError as e:\n"
        "    print(e)\n"
        "    sys.exit(0)\n"
        "sys.exit(3)\n"
    )
    env = dict(os.environ, ORT_DYLIB_PATH="/nonexistent/kflex/libonnxruntime.so.1.31.1")
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    for hint in ("ORT_DYLIB_PATH", "onnxruntime==1.31.1", "/nonexistent/kflex"):
        assert hint in done.stdout


def test_an_environment_that_is_not_activated_finds_its_own_runtime(kbjae_path: Path, tmp_path: Path) -> None:
    # no ORT_DYLIB_PATH, no VIRTUAL_ENV, no python3 with onnxruntime on PATH,
    # no .venv above the working directory: only the interpreter running
    # kflex knows where its onnxruntime is
    script = f"import kflex\nkflex.Kbjae.load({str(kbjae_path)!r})\nprint('loaded')\n"
    env = {k: v for k, v in os.environ.items() if k not in ("ORT_DYLIB_PATH", "VIRTUAL_ENV")}
    env["PATH"] = str(tmp_path)
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "loaded"


# ---- SCNN ----------------------------------------------------------------------


def scnn_case(models: Models) -> tuple[np.ndarray, np.ndarray]:
    expected = models.expected("scnn_test")
    masks = np.array([[c == "1" for c in m] for m in expected["masks"]]).reshape(-1, 48, 48)
    return masks, np.array(expected["embedding"])


def test_the_scnn_embeds_as_the_network_does(models: Models) -> None:
    masks, want = scnn_case(models)
    scnn = kflex.Scnn.load(models / "scnn_test.onnx")
    got = scnn.embed(masks)
    assert got.dtype == np.float32 and got.shape == (len(masks), 256)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-5)
    # one at a time, and in every accepted dtype, the same numbers
    for i, m in enumerate(masks):
        one = scnn.embed(m)
        assert one.shape == (256,)
        np.testing.assert_allclose(one, got[i], rtol=1e-6, atol=1e-6)
    assert np.array_equal(scnn.embed(masks.astype(np.uint8) * 255), got)
    assert np.array_equal(scnn.embed(masks.astype(np.float32)), got)
    assert not np.allclose(got[0], got[2], atol=1e-3)
    assert scnn.embed(np.zeros((0, 48, 48), bool)).shape == (0, 256)


def test_the_scnn_refuses_other_shapes_and_values(models: Models) -> None:
    scnn = kflex.Scnn.load(models / "scnn_test.onnx")
    with pytest.raises(TypeError, match=r"\(N, 48, 48\).*\[2, 32, 32\]"):
        scnn.embed(np.zeros((2, 32, 32), bool))
    with pytest.raises(TypeError, match="int64"):
        scnn.embed(np.zeros((48, 48), np.int64))
    with pytest.raises(ValueError, match="0.5"):
        scnn.embed(np.full((48, 48), 0.5, np.float32))


# ---- feature index -------------------------------------------------------------


def random_index(n: int = 400, dim: int = 32, seed: int = 0) -> tuple[kflex.FeatureIndex, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    features = rng.random((n, dim), dtype=np.float32)
    theta = np.linspace(0.0, 50.0, n)
    return kflex.FeatureIndex.build(features, theta, 10.0), features, theta


def test_the_index_finds_the_exact_nearest_neighbour() -> None:
    index, features, theta = random_index()
    assert (len(index), index.dim, index.projection_dims) == (400, 32, 8)
    assert np.array_equal(index.features, features)
    assert np.array_equal(index.theta_deg, theta) and (index.translation_mm == 10.0).all()
    rng = np.random.default_rng(1)
    queries = rng.random((50, 32), dtype=np.float32)
    brute = ((features[None, :, :].astype(np.float64) - queries[:, None, :]) ** 2).sum(axis=2)
    batch = index.nearest_batch(queries)
    assert batch["index"].dtype == np.int64
    assert np.array_equal(batch["index"], brute.argmin(axis=1))
    np.testing.assert_allclose(batch["distance_sq"], brute.min(axis=1), rtol=1e-5)
    assert np.array_equal(batch["theta_deg"], theta[batch["index"]])
    for q, i in zip(queries, batch["index"]):
        n = index.nearest(q)
        assert n == index.nearest_linear(q)
        assert n.index == i and n.theta_deg == theta[i] and n.translation_mm == 10.0
        assert n.distance == pytest.approx(np.sqrt(n.distance_sq))
    # a database point is its own nearest neighbour, at distance 0
    hit = index.nearest(features[123].astype(np.float64))
    assert (hit.index, hit.distance_sq) == (123, 0.0)
    # 400 points are scanned; the tree, asked for, gives the same answers
    assert index.search == "scan"
    tree = kflex.FeatureIndex.build(features, theta, 10.0, search="tree")
    assert tree.search == "tree"
    for key in ("index", "distance_sq"):
        assert np.array_equal(tree.nearest_batch(queries)[key], batch[key])


def test_the_index_file_keeps_everything(tmp_path: Path) -> None:
    index, _, _ = random_index(dim=16)
    index.set_metadata("scnn_sha256", "abc")
    path = tmp_path / "db.kfi"
    index.save(path)
    back = kflex.FeatureIndex.load(str(path))
    assert back.metadata == {"scnn_sha256": "abc"}
    assert np.array_equal(back.features, index.features)
    queries = np.random.default_rng(2).random((20, 16), dtype=np.float32)
    for key in ("index", "distance_sq", "theta_deg"):
        assert np.array_equal(back.nearest_batch(queries)[key], index.nearest_batch(queries)[key])
    with pytest.raises(FileNotFoundError):
        kflex.FeatureIndex.load(tmp_path / "none.kfi")
    damaged = bytearray(path.read_bytes())
    damaged[len(damaged) // 2] ^= 0xFF
    (tmp_path / "damaged.kfi").write_bytes(bytes(damaged))
    with pytest.raises(ValueError, match="damaged.kfi"):
        kflex.FeatureIndex.load(tmp_path / "damaged.kfi")


def test_the_index_refuses_bad_input() -> None:
    index, features, theta = random_index(n=50, dim=8)
    # the shape as given: a (7,) query was reported as "(1, 7)"
    with pytest.raises(TypeError, match=r"query: expected shape .* got \(7,\)"):
        index.nearest(np.zeros(7, np.float32))
    with pytest.raises(ValueError, match="component 3"):
        index.nearest(np.array([0, 0, 0, np.nan, 0, 0, 0, 0], np.float32))
    with pytest.raises(ValueError, match="query 2"):
        q = np.zeros((4, 8), np.float32)
        q[2, 0] = np.inf
        index.nearest_batch(q)
    with pytest.raises(TypeError, match="int64"):
        index.nearest(np.zeros(8, np.int64))
    with pytest.raises(ValueError, match="projection_dims"):
        kflex.FeatureIndex.build(features, theta, 0.0, projection_dims=5)
    with pytest.raises(ValueError, match="search"):
        kflex.FeatureIndex.build(features, theta, 0.0, search="kd")
    # a finite float64 beyond float32 is named as given, not as infinity
    big = features.astype(np.float64)
    big[3, 2] = 1e308
    with pytest.raises(ValueError, match=r"features\[3, 2\] = 1e308 does not fit float32"):
        kflex.FeatureIndex.build(big, theta)
    with pytest.raises(ValueError, match=r"query\[1\] = -1e300 does not fit float32"):
        index.nearest(np.array([0, -1e300, 0, 0, 0, 0, 0, 0], np.float64))
    many = np.random.default_rng(3).random((2049, 4), dtype=np.float32)
    with pytest.raises(ValueError, match="searched by scan"):
        kflex.FeatureIndex.build(many, np.zeros(2049), search="scan")
    assert kflex.FeatureIndex.build(many, np.zeros(2049)).search == "tree"
    with pytest.raises(TypeError, match="poses"):
        kflex.FeatureIndex.build(features, theta[:-1])
    with pytest.raises(ValueError, match="empty"):
        kflex.FeatureIndex.build(np.zeros((0, 8), np.float32), np.zeros(0))
    with pytest.raises(TypeError, match=r"\(N, D\)"):
        kflex.FeatureIndex.build(features[0], theta[:1])
    # queries have the index's dimensions, and a single query is one row
    with pytest.raises(TypeError, match=r"\(N, 8\)"):
        index.nearest_batch(np.zeros((4, 2), np.float32))
    with pytest.raises(TypeError, match=r"\(8,\) or \(1, 8\)"):
        index.nearest(np.zeros((2, 4), np.float32))
    assert len(index.nearest_batch(np.zeros((4, 8), np.float32))["index"]) == 4


# ---- IBJAE and LBHJAE ----------------------------------------------------------


@pytest.fixture(scope="module")
def camera() -> kflex.Camera:
    return kflex.Camera()


@pytest.fixture(scope="module")
def paper_db(models: Models, camera: kflex.Camera) -> kflex.FeatureIndex:
    """The paper's band (θ 0-50 deg at d = 10 mm, the paper's region), 1 deg steps."""
    band = kflex.WorkingBand(
        poses={"theta_deg": [0.0, 50.0], "translation_mm": [10.0, 10.0]}, roi=kflex.Roi.paper(camera)
    )
    scnn = kflex.Scnn.load(models / "scnn_test.onnx")
    db = kflex.build_band_database(scnn, camera, kflex.Instrument.kflex(), band, 1.0, 1.0)
    assert len(db) == 51 and db.dim == 256
    assert db.metadata["scnn_sha256"] == scnn.sha256
    assert np.array_equal(db.theta_deg, np.arange(51.0))
    return db


def frame(camera: kflex.Camera, theta_deg: float) -> np.ndarray:
    shape = kflex.Instrument.kflex().shape(theta_deg, 10.0)
    return kflex.SceneRenderer().render(camera, shape).rgb


def test_ibjae_reads_rendered_frames_near_their_pose(models, camera, paper_db) -> None:
    ibjae = kflex.Ibjae(models / "scnn_test.onnx", [paper_db])
    assert ibjae.bands[0].region == kflex.Roi.paper(camera)
    assert ibjae.bands_for(None, 10.0) == [0] and ibjae.bands_for(None, 30.0) == []
    for theta in (5.0, 17.0, 30.0, 44.0):
        r = ibjae.read(frame(camera, theta), [0])
        assert r is not None and r.band == 0 and r.translation_mm == 10.0
        assert r.sigma_deg >= 0.5
        # a random-weight test SCNN: near, not exact (as the Rust test holds it)
        assert abs(r.theta_deg - theta) <= 6.0, (theta, r)
    # a strided view of a frame reads as the packed frame
    rgb = frame(camera, 25.0)
    wide = np.zeros((rgb.shape[0], rgb.shape[1] * 2, 3), np.uint8)
    wide[:, ::2] = rgb
    assert not wide[:, ::2].flags.c_contiguous
    a, b = ibjae.read(rgb, [0]), ibjae.read(wide[:, ::2], [0])
    assert (a.theta_deg, a.distance) == (b.theta_deg, b.distance)


def test_ibjae_checks_its_readings_against_the_nominal_silhouette_with_a_camera(
    models, camera, paper_db
) -> None:
    plain = kflex.Ibjae(models / "scnn_test.onnx", [paper_db])
    checked = kflex.Ibjae(models / "scnn_test.onnx", [paper_db], camera=camera)
    occlusion = {"fraction": 0.4, "position": 0.5, "region": kflex.Roi.paper(camera).to_dict()}
    for theta in (5.0, 30.0):
        shape = kflex.Instrument.kflex().shape(theta, 10.0)
        clear = kflex.SceneRenderer().render(camera, shape).rgb
        taped = kflex.SceneRenderer().render(camera, shape, kflex.FrameParams(occlusion=occlusion)).rgb
        p, c = plain.read(clear, [0]), checked.read(clear, [0])
        assert p.silhouette_iou is None and "silhouette_iou=None" in repr(p)
        assert (c.theta_deg, c.distance, c.sigma_deg) == (p.theta_deg, p.distance, p.sigma_deg)
        assert 0.85 <= c.silhouette_iou <= 1.0, c
        t = checked.read(taped, [0])
        # tape over the middle 40 % of the instrument: the retrieved pose does
        # not explain the silhouette; the pose that explains what is visible,
        # with the rest hidden, is read instead
        assert t.silhouette_iou < 0.85 and t.occluded, t
        lo, hi = t.consistent_deg
        assert lo <= t.theta_deg <= hi and abs(t.theta_deg - theta) <= 3.0, t
        assert t.sigma_deg == 5.0 and 0.5 * (hi - lo) <= 5.0, t
        assert not c.occluded and c.consistent_deg is None and "occluded=False" in repr(c)


def test_the_silhouette_check_takes_its_instrument_and_its_least_iou(models, camera, paper_db) -> None:
    scnn = models / "scnn_test.onnx"
    default = kflex.Ibjae(scnn, [paper_db], camera=camera)
    strict = kflex.Ibjae(scnn, [paper_db], camera=camera, min_silhouette_iou=1.0)
    lenient = kflex.Ibjae(scnn, [paper_db], camera=camera, min_silhouette_iou=0.0)
    # the same geometry but jaws opened to 80 deg: its nominal silhouettes differ at the tip
    wide_jaws = kflex.Instrument(kflex.JointParams(), kflex.InstrumentParams(jaw_opening_deg=80.0), 2,
                                 kflex.TranslationParams())
    other = kflex.Ibjae(scnn, [paper_db], camera=camera, instrument=wide_jaws)
    occlusion = {"fraction": 0.4, "position": 0.5, "region": kflex.Roi.paper(camera).to_dict()}
    for theta in (5.0, 30.0):
        shape = kflex.Instrument.kflex().shape(theta, 10.0)
        clear = kflex.SceneRenderer().render(camera, shape).rgb
        taped = kflex.SceneRenderer().render(camera, shape, kflex.FrameParams(occlusion=occlusion)).rgb
        d, s, o = default.read(clear, [0]), strict.read(clear, [0]), other.read(clear, [0])
        # explained by the default's 0.85, not by an IoU of 1: the strict check
        # then takes a part as hidden, or flags the reading
        assert not d.occluded and d.sigma_deg < 45.0 and d.silhouette_iou < 1.0, d
        assert s.occluded or s.sigma_deg >= 45.0, (d, s)
        assert o.theta_deg == d.theta_deg and o.silhouette_iou < d.silhouette_iou, (o, d)
        t, lt = default.read(taped, [0]), lenient.read(taped, [0])
        # the default takes the tape as hiding part of the instrument; a least IoU of 0 flags nothing
        assert t.occluded and not lt.occluded and lt.sigma_deg < 45.0, (t, lt)
    with pytest.raises(kflex.RangeError, match="min_silhouette_iou"):
        kflex.Ibjae(scnn, [paper_db], camera=camera, min_silhouette_iou=1.5)
    for kwargs in ({"instrument": wide_jaws}, {"min_silhouette_iou": 0.5}):
        name = next(iter(kwargs))
        with pytest.raises(ValueError, match=f"{name} is for the silhouette check, which needs camera"):
            kflex.Ibjae(scnn, [paper_db], **kwargs)
        with pytest.raises(ValueError, match=f"{name} is for the silhouette check"):
            kflex.Lbhjae(models / "kbjae_test.onnx", scnn, [paper_db], kflex.KalmanParams(), **kwargs)
    kflex.Lbhjae(models / "kbjae_test.onnx", scnn, [paper_db], kflex.KalmanParams(), camera=camera,
                 instrument=wide_jaws, min_silhouette_iou=0.9)


def test_ibjae_gives_none_without_an_instrument_and_refuses_bad_frames(models, camera, paper_db) -> None:
    ibjae = kflex.Ibjae(models / "scnn_test.onnx", [paper_db])
    k = camera.intrinsics
    flat = np.empty((k.height, k.width, 3), np.uint8)
    flat[:] = (180, 90, 80)
    assert ibjae.read(flat, [0]) is None
    with pytest.raises(kflex.RangeError):
        ibjae.read(np.zeros((64, 64, 3), np.uint8), [0])
    with pytest.raises(TypeError, match="uint8"):
        ibjae.read(np.zeros((k.height, k.width, 3), np.float32), [0])
    # a band out of the list is a RangeError; a negative one is named as given
    with pytest.raises(kflex.RangeError, match="band"):
        ibjae.read(flat, [1])
    with pytest.raises(ValueError, match=re.escape("bands[1] = -1: must be a whole number from 0 to")):
        ibjae.read(flat, [0, -1])


def test_ibjae_refuses_a_database_from_another_scnn(models, paper_db) -> None:
    other = kflex.FeatureIndex.build(paper_db.features, paper_db.theta_deg, paper_db.translation_mm)
    for key, value in paper_db.metadata.items():
        other.set_metadata(key, value)
    other.set_metadata("scnn_sha256", "0000")
    with pytest.raises(ValueError, match="0000"):
        kflex.Ibjae(models / "scnn_test.onnx", [other])
    with pytest.raises(ValueError, match="at least one band database"):
        kflex.Ibjae(models / "scnn_test.onnx", [])
    bare = kflex.FeatureIndex.build(paper_db.features, paper_db.theta_deg)
    with pytest.raises(ValueError, match="metadata"):
        kflex.Ibjae(models / "scnn_test.onnx", [bare])
    # the database given is copied, and stays usable
    assert len(paper_db) == 51


def test_lbhjae_fuses_both_and_a_bad_tick_changes_nothing(models, camera, paper_db) -> None:
    def make() -> kflex.Lbhjae:
        return kflex.Lbhjae(
            models / "kbjae_test.onnx", models / "scnn_test.onnx", [paper_db], kflex.AdaptiveParams()
        )

    lb, twin = make(), make()
    kb = kflex.Kbjae.load(models / "kbjae_test.onnx")
    with_frames = 0
    for k in range(12):
        theta = 20.0 + 0.2 * k
        rgb = frame(camera, theta) if k % 3 == 0 else None
        e = lb.step(theta, 10.0, 0.01, rgb)
        assert np.isfinite(e.fused.theta_hat_deg)
        assert e.kbjae_deg == kb.step(theta, 0.01)  # KBJAE's angle is KBJAE's own
        assert (e.ibjae is not None) == (rgb is not None)
        if rgb is not None:
            with_frames += 1
            assert e.fused.ibjae in ("used", "gated")
        else:
            assert e.fused.ibjae == "missing"
        twin.step(theta, 10.0, 0.01, rgb)
    assert with_frames == 4
    with pytest.raises(ValueError, match="theta_c_deg"):
        lb.step(float("nan"), 10.0, 0.01)
    with pytest.raises(kflex.RangeError):
        lb.step(20.0, 10.0, -1.0)
    with pytest.raises(ValueError, match="rate_deg_per_s"):
        lb.step(20.0, 10.0, 0.01, rate_deg_per_s=float("nan"))
    a, b = lb.step(23.0, 10.0, 0.01), twin.step(23.0, 10.0, 0.01)
    assert (a.fused.theta_hat_deg, a.kbjae_deg) == (b.fused.theta_hat_deg, b.kbjae_deg)
    lb.reset()
    fresh = make()
    assert lb.step(5.0, 10.0, 0.01).fused.theta_hat_deg == fresh.step(5.0, 10.0, 0.01).fused.theta_hat_deg
    with pytest.raises(TypeError, match="fusion"):
        kflex.Lbhjae(models / "kbjae_test.onnx", models / "scnn_test.onnx", [paper_db], "adaptive")
    paper = kflex.Lbhjae(models / "kbjae_test.onnx", models / "scnn_test.onnx", [paper_db], kflex.KalmanParams())
    assert np.isfinite(paper.step(10.0, 10.0, 0.01).fused.theta_hat_deg)
    # KBJAE inside reads a rate given as given (the master's, closed loop)
    kb.reset()
    assert paper.step(11.0, 10.0, 0.01, rate_deg_per_s=-8.0).kbjae_deg == kb.predict(11.0, -8.0)


def test_run_experiment_tells_what_went_into_each_estimate(models, paper_db, tmp_path) -> None:
    """A grid's runs carry, per estimator, what went into its estimate each
    tick (``details``): LBHJAE's readings and uncertainty, IBJAE's reading on
    the ticks that read a frame, nothing beyond its estimate for KBJAE."""
    # a models directory of the test models, with the paper's band as its one database
    shutil.copy(models / "kbjae_test.onnx", tmp_path / "kbjae.onnx")
    shutil.copy(models / "scnn_test.onnx", tmp_path / "scnn.onnx")
    (tmp_path / "db").mkdir()
    paper_db.save(tmp_path / "db" / "band-000.kfdb")
    (tmp_path / "db" / "bands").write_text("1")
    grid = kflex.ExperimentGrid(
        cases=[{"table": "V", "kind": "estimation", "sheath_deg": 0.0, "occlusion": "0%"}],
        estimators=["kbjae", "ibjae", "lbhjae-adaptive"],
        repeats=1,
    )
    scenario = grid.scenario
    scenario["motion"]["periods"] = 0.5
    grid.scenario = scenario
    logs = tmp_path / "logs"
    (run,) = kflex.run_experiment(grid, models=tmp_path, jobs=1, mcap_dir=logs)["runs"]
    n = len(run["time_s"])
    floats = {
        "theta_hat_sigma_deg", "theta_hat_rate_deg_per_s", "kbjae_deg", "ibjae_deg", "ibjae_sigma_deg",
        "ibjae_silhouette_iou", "ibjae_nis",
    }
    flags = {"frame_arrived", "ibjae_occluded"}
    uses = {"kbjae_use", "ibjae_use"}
    assert set(run["details"]) == {"kbjae", "ibjae", "lbhjae-adaptive"}
    for d in run["details"].values():
        assert set(d) == floats | flags | uses | {"ibjae_consistent_deg", "theta_hat_covariance"}
        assert all(d[k].dtype == np.float64 and d[k].shape == (n,) for k in floats)
        assert all(d[k].dtype == np.bool_ and d[k].shape == (n,) for k in flags)
        assert all(d[k].dtype.kind == "U" and d[k].shape == (n,) for k in uses)
        assert d["ibjae_consistent_deg"].shape == (n, 2) and d["theta_hat_covariance"].shape == (n, 2, 2)
        # the loop's own: the same frames reach each estimator of the run
        np.testing.assert_array_equal(d["frame_arrived"], run["details"]["lbhjae-adaptive"]["frame_arrived"])

    fused = run["details"]["lbhjae-adaptive"]
    assert np.all(np.isfinite(fused["kbjae_deg"])) and np.all(fused["kbjae_use"] == "used")
    assert np.all(fused["theta_hat_sigma_deg"] > 0.0)
    cov = fused["theta_hat_covariance"]
    np.testing.assert_allclose(np.sqrt(cov[:, 0, 0]), fused["theta_hat_sigma_deg"], rtol=1e-12)
    np.testing.assert_array_equal(cov[:, 0, 1], cov[:, 1, 0])
    read = np.isfinite(fused["ibjae_deg"])
    # a 30 Hz camera over 100 Hz ticks; a reading only where a frame arrived
    assert 0.2 < read.mean() <= 0.34, read.mean()
    assert not read[~fused["frame_arrived"]].any()
    assert np.array_equal(np.isfinite(fused["ibjae_sigma_deg"]), read)
    assert set(fused["ibjae_use"][read]) <= {"used", "gated"}
    assert np.all(fused["ibjae_use"][~read] == "missing")
    assert np.array_equal(np.isfinite(fused["ibjae_nis"]), fused["ibjae_use"] == "gated")
    assert not fused["ibjae_occluded"].any() and np.isnan(fused["ibjae_consistent_deg"]).all()

    alone = run["details"]["ibjae"]
    seen = np.isfinite(alone["ibjae_deg"])
    assert seen.sum() > 20
    np.testing.assert_array_equal(alone["ibjae_deg"][seen], run["estimates"]["ibjae"][seen])
    assert np.isnan(alone["kbjae_deg"]).all() and np.all(alone["ibjae_use"] == "")

    kbjae = run["details"]["kbjae"]
    assert all(np.isnan(kbjae[k]).all() for k in floats)
    assert not kbjae["ibjae_occluded"].any() and np.all(kbjae["kbjae_use"] == "")
    # the run's MCAP log of LBHJAE says the same in its joint states
    import json

    from mcap.reader import make_reader

    (log,) = logs.glob("*lbhjae-adaptive*.mcap")
    with log.open("rb") as f:
        states = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=["/kflex/joint_states"])]
    assert len(states) == n

    def column(key: str) -> np.ndarray:
        return np.array([s.get(key, np.nan) for s in states], dtype=np.float64)

    for key in ("theta_hat_sigma_deg", "kbjae_deg", "ibjae_deg", "ibjae_sigma_deg", "ibjae_nis"):
        np.testing.assert_array_equal(column(key), fused[key], err_msg=key)
    assert [s.get("ibjae_use", "") for s in states] == list(fused["ibjae_use"])
    assert [s["frame_arrived"] for s in states] == list(fused["frame_arrived"])
    np.testing.assert_array_equal([s["theta_hat_covariance"] for s in states], fused["theta_hat_covariance"])
    # and without them
    (bare,) = kflex.run_experiment(grid, models=tmp_path, jobs=1, details=False)["runs"]
    assert "details" not in bare
    np.testing.assert_array_equal(bare["estimates"]["ibjae"], run["estimates"]["ibjae"])


def test_hidden_part_silhouettes_render_up_front(models, camera, paper_db) -> None:
    """With the silhouette check, the hidden-part search's silhouettes are
    rendered by the first read that needs them, or all at once by
    ``prepare_hidden_parts`` (for a loop with a deadline per tick)."""
    scnn = models / "scnn_test.onnx"
    assert kflex.Ibjae(scnn, [paper_db]).hidden_parts_ready  # no check, nothing to render
    ibjae = kflex.Ibjae(scnn, [paper_db], camera=camera)
    assert not ibjae.hidden_parts_ready
    ibjae.prepare_hidden_parts()
    assert ibjae.hidden_parts_ready
    lbhjae = kflex.Lbhjae(models / "kbjae_test.onnx", scnn, [paper_db], kflex.AdaptiveParams(), camera=camera)
    assert not lbhjae.hidden_parts_ready
    lbhjae.prepare_hidden_parts()
    assert lbhjae.hidden_parts_ready


def test_index_queries_writes_each_band_with_the_frames_of_its_poses(models: Models, camera, tmp_path) -> None:
    """tools/index_queries.py (the real queries of `tools/index_bench.py
    --database`): each band file present gets its own entries back, bit for
    bit, and the embeddings of the frames whose pose lies in that band; a
    band without its file is left out, and a database of another SCNN is
    refused."""
    scnn = kflex.Scnn.load(models / "scnn_test.onnx")
    bands = kflex.WorkingRegions.full(camera).bands
    db_dir = tmp_path / "db"
    db_dir.mkdir()
    kept = (12, 26)  # the two widest bands: most frames land in them
    for b in kept:
        index = kflex.build_band_database(scnn, camera, kflex.Instrument.kflex(), bands[b], 4.0, 4.0)
        index.save(db_dir / f"band-{b:03}.kfdb")
    out = tmp_path / "out"
    tool = REPO_ROOT / "tools" / "index_queries.py"
    args = ["--database", str(db_dir), "--scnn", str(models / "scnn_test.onnx"), "--out", str(out)]
    run = subprocess.run([sys.executable, str(tool), *args, "--frames", "300"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    assert report["frames"] == 300
    assert {b["band"] for b in report["bands"]} == set(kept)
    for b in report["bands"]:
        index = kflex.FeatureIndex.load(db_dir / f"band-{b['band']:03}.kfdb")
        here = Path(b["dir"])
        assert np.array_equal(np.load(here / "db.npy"), index.features)
        poses = np.load(here / "poses.npy")
        assert np.array_equal(poses[:, 0], index.theta_deg) and np.array_equal(poses[:, 1], index.translation_mm)
        queries = np.load(here / "queries.npy")
        assert queries.shape == (b["queries"], 256) and queries.dtype == np.float32
        assert np.all(np.isfinite(queries))
    # a band built with another network is refused, naming its file
    stale = kflex.FeatureIndex.load(db_dir / f"band-{kept[0]:03}.kfdb")
    stale.set_metadata("scnn_sha256", "0" * 64)
    stale.save(db_dir / f"band-{kept[0]:03}.kfdb")
    bad = subprocess.run([sys.executable, str(tool), *args, "--frames", "300"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert f"band-{kept[0]:03}.kfdb was built with another SCNN" in bad.stderr
