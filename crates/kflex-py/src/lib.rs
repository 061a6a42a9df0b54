//! # kflex-py — the Python module `kflex`
//!
//! Thin pyo3 wrappers over the kflex crates, numpy arrays in and out; no
//! logic of their own. Names follow the Rust API (`Plant.step`,
//! `SceneRenderer.render`, `Segmenter.segment`, …), units are in the names.
//! The module is built by maturin as `kflex._kflex` and re-exported by the
//! pure-Python package `kflex` (`python/kflex/__init__.py`, with `.pyi`
//! stubs and a `py.typed` marker).
//!
//! * Parameter types (`PlantConfig`, `SheathParams`, `FrameParams`, `Roi`,
//!   …) are the Rust serde structs: keyword construction, fields by name,
//!   `to_dict`/`from_dict` in the JSON form `kflex-cli run --config` reads
//!   (`value.rs`).
//! * Whole runs are one call with the loop in Rust (`Plant.run` over an
//!   array of commands, `OpenLoopScenario.run` over a trajectory).
//! * Errors become Python exceptions in one place (`error.rs`): `RangeError`
//!   (a `ValueError` with the bounds), `ValueError`, `TypeError`,
//!   `RuntimeError`.
//! * Training data (`KinematicDatasetConfig.generate`,
//!   `ImagePairsConfig.generate`, `ImagePairsConfig.database`) comes back
//!   as a `dict` of numpy arrays and the data set's card; the pure-Python
//!   `kflex.npz` writes them to `.npz` files with their cards, atomically.
//! * Long calls (runs, rendering, silhouettes, segmentation, working
//!   regions, data sets) let go of the interpreter (`Python::detach`); their array
//!   inputs are copied first (`array.rs`).
//!
//! * Control and estimation: the compensator (`compensator.rs`), the ONNX
//!   estimators KBJAE and the SCNN (`models.rs`), and the feature index,
//!   band databases, IBJAE and LBHJAE (`retrieval.rs`; kflex-estimate's
//!   features `onnx` and `index`). ONNX Runtime is loaded when the first
//!   model is, from the onnxruntime wheel; without it, loading raises
//!   `RuntimeError`.
//!
//! kflex-model is used without default features: no rapier3d, the analytic
//! joint only (the default joint); `joint_model = "rapier"` raises
//! `RuntimeError`.

mod array;
mod camera;
mod closed_loop;
mod compensator;
mod dataset;
mod error;
mod experiment;
mod fusion;
mod kinematics;
mod models;
mod plant;
mod render;
mod retrieval;
mod segment;
mod value;

use pyo3::prelude::*;

#[pymodule]
fn _kflex(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("RangeError", py.get_type::<error::PyRangeError>())?;
    m.add(
        "NoInstrumentError",
        py.get_type::<error::PyNoInstrumentError>(),
    )?;
    m.add_class::<plant::PyPlantConfig>()?;
    m.add_class::<plant::PySheathParams>()?;
    m.add_class::<plant::PyJointParams>()?;
    m.add_class::<plant::PySeating>()?;
    m.add_class::<plant::PyTranslationParams>()?;
    m.add_class::<plant::PyAuroraNoise>()?;
    m.add_class::<plant::PyCommand>()?;
    m.add_class::<plant::PyPlantState>()?;
    m.add_class::<plant::PyPlant>()?;
    m.add_class::<plant::PySine>()?;
    m.add_class::<plant::PyTrajectory>()?;
    m.add_class::<plant::PyOpenLoopScenario>()?;
    m.add_class::<plant::PyTrace>()?;
    m.add_class::<kinematics::PyTendonGeometry>()?;
    m.add_class::<camera::PyIntrinsics>()?;
    m.add_class::<camera::PyLens>()?;
    m.add_class::<camera::PyCamera>()?;
    m.add_class::<camera::PyRoi>()?;
    m.add_class::<camera::PyPoseRange>()?;
    m.add_class::<camera::PyBanding>()?;
    m.add_class::<camera::PyWorkingBand>()?;
    m.add_class::<camera::PyWorkingRegions>()?;
    m.add_class::<camera::PyInstrument>()?;
    m.add_class::<camera::PyInstrumentParams>()?;
    m.add_class::<camera::PyInstrumentShape>()?;
    m.add_class::<camera::PyBuildTolerances>()?;
    m.add_class::<camera::PyBuiltInstrument>()?;
    m.add_class::<render::PyFrameParams>()?;
    m.add_class::<render::PyOcclusion>()?;
    m.add_class::<render::PyFrame>()?;
    m.add_class::<render::PySceneRenderer>()?;
    m.add_class::<render::PyRasterizer>()?;
    m.add_class::<segment::PySegmentParams>()?;
    m.add_class::<segment::PySegmentation>()?;
    m.add_class::<segment::PySegmenter>()?;
    m.add_class::<fusion::PyKalmanParams>()?;
    m.add_class::<fusion::PyAdaptiveParams>()?;
    m.add_class::<fusion::PyEstimate>()?;
    m.add_class::<fusion::PyPaperKalman>()?;
    m.add_class::<fusion::PyAdaptiveKalman>()?;
    m.add_function(wrap_pyfunction!(segment::segment, m)?)?;
    m.add_class::<dataset::PyKinematicSetSpec>()?;
    m.add_class::<dataset::PyKinematicDatasetConfig>()?;
    m.add_class::<dataset::PyImagePairsConfig>()?;
    m.add_class::<compensator::PyCompensatorConfig>()?;
    m.add_class::<compensator::PyTerms>()?;
    m.add_class::<compensator::PyFault>()?;
    m.add_class::<compensator::PyCompensatorOutput>()?;
    m.add_class::<compensator::PyCompensator>()?;
    m.add_class::<closed_loop::PyNoisyTruth>()?;
    m.add_class::<closed_loop::PyClosedLoopScenario>()?;
    m.add_class::<closed_loop::PyClosedLoopTrace>()?;
    m.add_class::<experiment::PyExperimentGrid>()?;
    m.add_function(wrap_pyfunction!(experiment::run_experiment, m)?)?;
    m.add_class::<models::PyKbjae>()?;
    m.add_class::<models::PyScnn>()?;
    m.add_class::<retrieval::PyNeighbour>()?;
    m.add_class::<retrieval::PyFeatureIndex>()?;
    m.add_class::<retrieval::PyIbjaeReading>()?;
    m.add_class::<retrieval::PyIbjae>()?;
    m.add_class::<retrieval::PyLbhjaeEstimate>()?;
    m.add_class::<retrieval::PyLbhjae>()?;
    m.add_function(wrap_pyfunction!(retrieval::build_band_database_py, m)?)?;
    m.add_function(wrap_pyfunction!(models::prefer_onnxruntime_package, m)?)?;
    Ok(())
}
