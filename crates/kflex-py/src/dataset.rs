//! The training data sets (kflex-control's `dataset`): configurations as
//! parameter classes, `generate` returning numpy arrays and the data set's
//! card. The generators run in Rust, over threads, without the interpreter
//! lock.

use kflex_control::{
    DatasetCard, ImageDatabase, ImagePairs, ImagePairsConfig, KinematicDataset,
    KinematicDatasetConfig, KinematicSetSpec,
};
use numpy::IntoPyArray;
use numpy::ndarray::{Array1, Array2, Array3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::Serialize;

use crate::error::{Int, Result, unsigned};
use crate::value::{self, serde_class};

/// Side of IBJAE's silhouettes, px.
const SIDE: usize = 48;

serde_class!(
    /// One periodic signal of KBJAE's data set D^k (kflex-control's
    /// `KinematicSetSpec`): `amplitude_deg` (the peak A: θ_d =
    /// (A/2)(1 − cos 2πft) sweeps [0, A] deg), `frequency_hz`, `train`
    /// (else held out). All three are required.
    PyKinematicSetSpec, "KinematicSetSpec", KinematicSetSpec, {}
);

serde_class!(
    /// How to make KBJAE's data set D^k (kflex-control's
    /// `KinematicDatasetConfig`): `sets` (a list of `KinematicSetSpec`;
    /// default the paper's 12: peaks 35–85 deg train, 30–80 held out, at
    /// 0.159 Hz), `samples_per_set` (50,000), `dt_s` (0.01), `warmup_cycles`,
    /// `plant` (nominal `PlantConfig`, straight sheath), `spread` (0.15),
    /// `noise` (`AuroraNoise` or None), `translation_mm`, `seed` (set i
    /// uses seed + i).
    PyKinematicDatasetConfig, "KinematicDatasetConfig", KinematicDatasetConfig, {
        /// Checks the settings; raises `RangeError`.
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }

        /// Makes D^k over `threads` threads (0: every core), deterministic
        /// in the configuration whatever `threads`. Returns `(arrays,
        /// card)`: `theta_d_deg`, `theta_d_rate_deg_per_s`, `theta_a_deg`
        /// (true), `theta_a_measured_deg` (float64, sets × samples);
        /// `amplitude_deg`, `frequency_hz` (float64), `train` (bool), `seed`
        /// (uint64), one per set; and the data set's card (a `dict`).
        #[pyo3(signature = (threads = 0))]
        fn generate<'py>(&self, py: Python<'py>, threads: Int) -> Result<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
            let threads = unsigned("threads", threads)?;
            let config = self.inner.clone();
            let data = py.detach(|| config.generate(threads))?;
            kinematic_arrays(py, data)
        }
    }
);

serde_class!(
    /// How to make IBJAE's image-pair set D^I (kflex-control's
    /// `ImagePairsConfig`): `pairs` (even; 100,000), `seed`, `poses`
    /// (`PoseRange`, the full range), `theta_step_deg` and
    /// `translation_step_mm` (the database grid; S = 1 within half a step),
    /// `hard_share`, `hard_offset_deg` ([min, max]), `tolerances`
    /// (`BuildTolerances`), `backgrounds`, `tissues`, `background_seeds`,
    /// `block`, `illumination_gain`, `noise_std`, `blur_px` ([min, max]
    /// each), `blur_share`, `segment` (`SegmentParams`), `max_attempts`.
    PyImagePairsConfig, "ImagePairsConfig", ImagePairsConfig, {
        /// Checks the settings; raises `RangeError` (or `ValueError` for an
        /// odd `pairs`).
        fn validate(&self) -> Result<()> {
            Ok(self.inner.validate()?)
        }

        /// Makes D^I over `threads` threads (0: every core), deterministic
        /// in the configuration whatever `threads`. Returns `(arrays,
        /// card)`: `x_b`, `x_r` (bool, pairs × 48 × 48: the segmented
        /// as-built frame, the nominal silhouette), `s` (uint8, 1 for the
        /// same grid cell), `hard` (bool), `query` and `band` (int64),
        /// `theta_b_deg`, `translation_b_mm`, `theta_r_deg`,
        /// `translation_r_mm` (float64); and the card (a `dict`).
        #[pyo3(signature = (threads = 0))]
        fn generate<'py>(&self, py: Python<'py>, threads: Int) -> Result<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
            let threads = unsigned("threads", threads)?;
            let config = self.inner.clone();
            let pairs = py.detach(|| config.generate(threads))?;
            pair_arrays(py, pairs)
        }

        /// The nominal silhouette database IBJAE retrieves from: every grid
        /// pose of every band, in the band's region. Returns `(arrays,
        /// card)`: `masks` (bool, entries × 48 × 48), `theta_deg`,
        /// `translation_mm` (float64), `band` (int64); and the card.
        #[pyo3(signature = (threads = 0))]
        fn database<'py>(&self, py: Python<'py>, threads: Int) -> Result<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
            let threads = unsigned("threads", threads)?;
            let config = self.inner.clone();
            let db = py.detach(|| config.database(threads))?;
            database_arrays(py, db)
        }
    }
);

fn card<'py, P: Serialize>(py: Python<'py>, card: &DatasetCard<P>) -> Result<Bound<'py, PyAny>> {
    Ok(value::to_py(py, &value::to_value(card)?)?)
}

fn floats<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyAny> {
    v.into_pyarray(py).into_any()
}

fn flags<'py>(py: Python<'py>, v: &[u8]) -> Bound<'py, PyAny> {
    Array1::from_iter(v.iter().map(|&x| x != 0))
        .into_pyarray(py)
        .into_any()
}

fn indices<'py>(py: Python<'py>, v: &[u32]) -> Bound<'py, PyAny> {
    Array1::from_iter(v.iter().map(|&x| i64::from(x)))
        .into_pyarray(py)
        .into_any()
}

/// `n × 48 × 48` bool silhouettes from their bytes.
fn silhouettes<'py>(py: Python<'py>, bytes: &[u8]) -> Bound<'py, PyAny> {
    let n = bytes.len() / (SIDE * SIDE);
    let values = bytes.iter().map(|&x| x != 0).collect();
    Array3::from_shape_vec((n, SIDE, SIDE), values)
        .expect("silhouettes are 48 x 48 bytes each")
        .into_pyarray(py)
        .into_any()
}

fn kinematic_arrays(
    py: Python<'_>,
    data: KinematicDataset,
) -> Result<(Bound<'_, PyDict>, Bound<'_, PyAny>)> {
    let out = PyDict::new(py);
    let rows = data.sets.len();
    let cols = data.sets.first().map_or(0, |s| s.theta_d_deg.len());
    let matrix = |f: fn(&kflex_control::KinematicSet) -> &Vec<f64>| {
        let values = data
            .sets
            .iter()
            .flat_map(|s| f(s).iter().copied())
            .collect();
        Array2::from_shape_vec((rows, cols), values).expect("every set has samples_per_set samples")
    };
    out.set_item("theta_d_deg", matrix(|s| &s.theta_d_deg).into_pyarray(py))?;
    out.set_item(
        "theta_d_rate_deg_per_s",
        matrix(|s| &s.theta_d_rate_deg_per_s).into_pyarray(py),
    )?;
    out.set_item("theta_a_deg", matrix(|s| &s.theta_a_deg).into_pyarray(py))?;
    out.set_item(
        "theta_a_measured_deg",
        matrix(|s| &s.theta_a_measured_deg).into_pyarray(py),
    )?;
    let specs = data.sets.iter().map(|s| s.spec);
    out.set_item(
        "amplitude_deg",
        floats(py, specs.clone().map(|s| s.amplitude_deg).collect()),
    )?;
    out.set_item(
        "frequency_hz",
        floats(py, specs.clone().map(|s| s.frequency_hz).collect()),
    )?;
    out.set_item(
        "train",
        Array1::from_iter(specs.map(|s| s.train)).into_pyarray(py),
    )?;
    out.set_item(
        "seed",
        Array1::from_iter(data.sets.iter().map(|s| s.seed)).into_pyarray(py),
    )?;
    let card = card(py, &data.card)?;
    Ok((out, card))
}

fn pair_arrays(py: Python<'_>, p: ImagePairs) -> Result<(Bound<'_, PyDict>, Bound<'_, PyAny>)> {
    let out = PyDict::new(py);
    out.set_item("x_b", silhouettes(py, &p.x_b))?;
    out.set_item("x_r", silhouettes(py, &p.x_r))?;
    out.set_item("s", p.s.clone().into_pyarray(py))?;
    out.set_item("hard", flags(py, &p.hard))?;
    out.set_item("query", indices(py, &p.query))?;
    out.set_item("band", indices(py, &p.band))?;
    let card = card(py, &p.card)?;
    out.set_item("theta_b_deg", floats(py, p.theta_b_deg))?;
    out.set_item("translation_b_mm", floats(py, p.translation_b_mm))?;
    out.set_item("theta_r_deg", floats(py, p.theta_r_deg))?;
    out.set_item("translation_r_mm", floats(py, p.translation_r_mm))?;
    Ok((out, card))
}

fn database_arrays(
    py: Python<'_>,
    db: ImageDatabase,
) -> Result<(Bound<'_, PyDict>, Bound<'_, PyAny>)> {
    let out = PyDict::new(py);
    out.set_item("masks", silhouettes(py, &db.masks))?;
    out.set_item("band", indices(py, &db.band))?;
    let card = card(py, &db.card)?;
    out.set_item("theta_deg", floats(py, db.theta_deg))?;
    out.set_item("translation_mm", floats(py, db.translation_mm))?;
    Ok((out, card))
}
