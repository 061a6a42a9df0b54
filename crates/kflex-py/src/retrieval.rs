//! IBJAE's retrieval side and the whole estimators (kflex-estimate's
//! features `index` and `onnx`): the feature index, band databases, IBJAE
//! and LBHJAE.

use std::path::PathBuf;
use std::sync::{Mutex, PoisonError};

use kflex_estimate::{
    AdaptiveKalman, BandDatabase, DEFAULT_MIN_SILHOUETTE_IOU, FeatureIndex, Fusion, Ibjae,
    IbjaeReading, IndexParams, Kbjae, Lbhjae, Neighbour, PaperKalman, Pose, ProjectionDims,
    RgbView, Scnn, Search, SegmentParams, build_band_database,
};
use kflex_model::{Camera, Command, Instrument};
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::array;
use crate::camera::{PyCamera, PyInstrument, PyWorkingBand};
use crate::error::{Int, Result, type_error, unsigned, value_error};
use crate::fusion::{self, PyAdaptiveParams, PyEstimate, PyKalmanParams};
use crate::models::PyScnn;
use crate::segment::PySegmentParams;

/// A nearest neighbour: `index` (its row in the database), its pose
/// (`theta_deg`, `translation_mm`) and `distance_sq`, the squared L2
/// distance in feature units (float32 as computed; `distance` is its root).
#[pyclass(name = "Neighbour", module = "kflex", frozen)]
pub struct PyNeighbour {
    inner: Neighbour,
}

#[pymethods]
impl PyNeighbour {
    /// Row of the point in the database, from 0.
    #[getter]
    fn index(&self) -> usize {
        self.inner.index
    }

    /// Its bend, deg.
    #[getter]
    fn theta_deg(&self) -> f64 {
        self.inner.pose.theta_deg
    }

    /// Its translation, mm.
    #[getter]
    fn translation_mm(&self) -> f64 {
        self.inner.pose.translation_mm
    }

    /// Squared L2 distance from the query.
    #[getter]
    fn distance_sq(&self) -> f32 {
        self.inner.distance_sq
    }

    /// L2 distance from the query.
    #[getter]
    fn distance(&self) -> f32 {
        self.inner.distance()
    }

    fn __eq__(&self, other: &Self) -> bool {
        self.inner == other.inner
    }

    fn __repr__(&self) -> String {
        let n = &self.inner;
        format!(
            "Neighbour(index={}, theta_deg={}, translation_mm={}, distance_sq={})",
            n.index, n.pose.theta_deg, n.pose.translation_mm, n.distance_sq
        )
    }
}

/// IBJAE's database (kflex-estimate's `FeatureIndex`): N embeddings of
/// dimension D, each labelled with the pose it was rendered at, and their
/// exact nearest neighbour (the same answer as a linear scan, lowest index
/// among ties). Built with `FeatureIndex.build` or
/// `build_band_database`, kept on disk with `save` and `load`.
#[pyclass(name = "FeatureIndex", module = "kflex")]
pub struct PyFeatureIndex {
    pub(crate) inner: FeatureIndex,
}

impl PyFeatureIndex {
    /// The rows of `obj` as the index reads them: `D` columns (the index's
    /// dimension), and `rows` rows where it is given; `TypeError` naming both
    /// shapes otherwise.
    fn rows(
        &self,
        name: &str,
        obj: &Bound<'_, PyAny>,
        one_row_ok: bool,
        rows: Option<usize>,
    ) -> Result<Vec<f32>> {
        let (values, r, c) = array::rows_f32(name, obj, one_row_ok)?;
        let dim = self.inner.dim();
        if c != dim || rows.is_some_and(|n| n != r) {
            let wanted = match rows {
                Some(n) => format!("({dim},) or ({n}, {dim})"),
                None => format!("(N, {dim})"),
            };
            // the shape as given (a (5,) array is read as one row of 5)
            let given = obj
                .getattr("shape")
                .and_then(|shape| shape.str())
                .map_or_else(|_| format!("({r}, {c})"), |shape| shape.to_string());
            return Err(crate::error::type_error(format!(
                "{name}: expected shape {wanted} for an index of {dim} dimensions, got {given}"
            )));
        }
        Ok(values)
    }
}

#[pymethods]
impl PyFeatureIndex {
    /// Builds the index: `features` an (N, D) float32 or float64 array
    /// (float64 rounded to float32), `theta_deg` the N bends (deg),
    /// `translation_mm` a number or the N translations (mm; None: 0),
    /// `projection_dims` the principal axes the search uses (8, 12 or 16),
    /// `search` how it finds candidates there: "tree" (kiddo's k-d tree),
    /// "scan" (every projected point in one pass; at most 2,048 points) or
    /// "auto" (the scan up to 2,048 points, the tree above); the answers
    /// are the same exact neighbours whichever is chosen.
    /// Raises `TypeError` for arrays of other shapes, `ValueError` for
    /// NaN or infinite values, no features, another `projection_dims` or
    /// `search`, or "scan" on more points.
    #[staticmethod]
    #[pyo3(signature = (features, theta_deg, translation_mm = None, projection_dims = 8, search = "auto"))]
    fn build(
        py: Python<'_>,
        features: &Bound<'_, PyAny>,
        theta_deg: &Bound<'_, PyAny>,
        translation_mm: Option<&Bound<'_, PyAny>>,
        projection_dims: Int,
        search: &str,
    ) -> Result<Self> {
        let search = match search {
            "auto" => Search::Auto,
            "tree" => Search::Tree,
            "scan" => Search::Scan,
            other => {
                return Err(value_error(format!(
                    "search = {other:?}: must be \"auto\", \"tree\" or \"scan\""
                )));
            }
        };
        let (features, _, dim) = array::rows_f32("features", features, false)?;
        let theta = array::series("theta_deg", theta_deg)?;
        let translation = match translation_mm {
            Some(d) => array::broadcast("translation_mm", d, theta.len())?,
            None => vec![0.0; theta.len()],
        };
        let poses: Vec<Pose> = theta
            .iter()
            .zip(&translation)
            .map(|(&theta_deg, &translation_mm)| Pose {
                theta_deg,
                translation_mm,
            })
            .collect();
        let params = IndexParams {
            // a negative or too-large int is refused as any other count
            projection_dims: usize::try_from(projection_dims)
                .ok()
                .and_then(ProjectionDims::from_count)
                .ok_or_else(|| {
                    value_error(format!(
                        "projection_dims = {projection_dims}: must be 8, 12 or 16"
                    ))
                })?,
            search,
        };
        Ok(Self {
            inner: py.detach(|| FeatureIndex::build(&features, dim, &poses, params))?,
        })
    }

    /// Reads a database file. Raises `FileNotFoundError` (or another
    /// `OSError`) when it cannot be read, `ValueError` when it is damaged
    /// or of another format version.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> Result<Self> {
        Ok(Self {
            inner: py.detach(|| FeatureIndex::load(&path))?,
        })
    }

    /// Writes the database file (features, poses, projection, metadata;
    /// versioned and checksummed). Raises `OSError` when it cannot.
    fn save(&self, py: Python<'_>, path: PathBuf) -> Result<()> {
        let index = &self.inner;
        Ok(py.detach(|| index.save(&path))?)
    }

    /// The exact nearest neighbour of `query` (D values, float32 or
    /// float64). Raises `TypeError` for another shape, `ValueError` for a
    /// NaN or infinite component.
    fn nearest(&self, query: &Bound<'_, PyAny>) -> Result<PyNeighbour> {
        let query = self.rows("query", query, true, Some(1))?;
        Ok(PyNeighbour {
            inner: self.inner.nearest(&query)?,
        })
    }

    /// The nearest neighbour by a plain linear scan: the reference
    /// `nearest` equals.
    fn nearest_linear(&self, query: &Bound<'_, PyAny>) -> Result<PyNeighbour> {
        let query = self.rows("query", query, true, Some(1))?;
        Ok(PyNeighbour {
            inner: self.inner.nearest_linear(&query)?,
        })
    }

    /// `nearest` for each row of `queries` (an (M, D) array), without the
    /// interpreter lock. Returns a `dict` of arrays, one row per query:
    /// `index` (int64), `theta_deg`, `translation_mm` (float64),
    /// `distance_sq` (float32). Raises as `nearest`, naming the first bad row.
    fn nearest_batch<'py>(
        &self,
        py: Python<'py>,
        queries: &Bound<'py, PyAny>,
    ) -> Result<Bound<'py, PyDict>> {
        let queries = self.rows("queries", queries, false, None)?;
        let index = &self.inner;
        let found = py.detach(|| index.nearest_batch(&queries))?;
        let d = PyDict::new(py);
        let rows: Vec<i64> = found.iter().map(|n| n.index as i64).collect();
        d.set_item("index", rows.into_pyarray(py))?;
        let col =
            |f: fn(&Neighbour) -> f64| array::column(py, found.iter().map(f).collect::<Vec<f64>>());
        d.set_item("theta_deg", col(|n| n.pose.theta_deg))?;
        d.set_item("translation_mm", col(|n| n.pose.translation_mm))?;
        let dist: Vec<f32> = found.iter().map(|n| n.distance_sq).collect();
        d.set_item("distance_sq", dist.into_pyarray(py))?;
        Ok(d)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// D, the dimension of the features and of a query.
    #[getter]
    fn dim(&self) -> usize {
        self.inner.dim()
    }

    /// K, the principal axes the tree is built over.
    #[getter]
    fn projection_dims(&self) -> usize {
        self.inner.projection_dims().get()
    }

    /// How queries search: "tree" or "scan" (what "auto" chose).
    #[getter]
    fn search(&self) -> &'static str {
        match self.inner.search_method() {
            Search::Scan => "scan",
            _ => "tree",
        }
    }

    /// A copy of the features, (N, D) float32.
    #[getter]
    fn features<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        Array2::from_shape_vec(
            (self.inner.len(), self.inner.dim()),
            self.inner.features().to_vec(),
        )
        .expect("an index holds N rows of D features")
        .into_pyarray(py)
        .into_any()
    }

    /// The poses' bends, deg (float64, one per feature vector).
    #[getter]
    fn theta_deg<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(py, self.inner.poses().iter().map(|p| p.theta_deg).collect())
    }

    /// The poses' translations, mm (float64, one per feature vector).
    #[getter]
    fn translation_mm<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        array::column(
            py,
            self.inner
                .poses()
                .iter()
                .map(|p| p.translation_mm)
                .collect(),
        )
    }

    /// A copy of the metadata saved with the index (`dict` of `str`).
    #[getter]
    fn metadata(&self) -> std::collections::BTreeMap<String, String> {
        self.inner.metadata().clone()
    }

    /// Sets metadata `key` to `value`.
    fn set_metadata(&mut self, key: String, value: String) {
        self.inner.set_metadata(key, value);
    }

    fn __repr__(&self) -> String {
        format!(
            "FeatureIndex(len={}, dim={}, projection_dims={})",
            self.inner.len(),
            self.inner.dim(),
            self.inner.projection_dims().get()
        )
    }
}

/// Renders, embeds and indexes the nominal `instrument`'s silhouettes over
/// one working `band` (kflex-estimate's `build_band_database`): θ every
/// `theta_step_deg`, d every `translation_step_mm`, as `camera` sees them
/// through the band's region. Returns the band's `FeatureIndex`, whose
/// metadata hold what IBJAE needs (the SCNN's SHA-256, the region, the
/// band, the grid, the distance per degree). Raises `RangeError` for a step
/// outside (0, 90] deg or (0, 100] mm. Runs without the interpreter lock.
#[pyfunction(name = "build_band_database")]
pub(crate) fn build_band_database_py(
    py: Python<'_>,
    scnn: PyRef<'_, PyScnn>,
    camera: PyRef<'_, PyCamera>,
    instrument: PyRef<'_, PyInstrument>,
    band: PyWorkingBand,
    theta_step_deg: f64,
    translation_step_mm: f64,
) -> Result<PyFeatureIndex> {
    let (camera, instrument) = (camera.inner, instrument.inner);
    let scnn = &scnn.inner;
    let db = py.detach(|| {
        build_band_database(
            &mut scnn.lock().unwrap_or_else(PoisonError::into_inner),
            &camera,
            &instrument,
            &band.inner,
            theta_step_deg,
            translation_step_mm,
        )
    })?;
    Ok(PyFeatureIndex { inner: db.index })
}

/// Band databases from indexes (copies that search as the originals do: an
/// index stays usable in Python).
fn band_databases(databases: &[&FeatureIndex]) -> kflex_estimate::Result<Vec<BandDatabase>> {
    databases
        .iter()
        .map(|d| {
            let mut copy = FeatureIndex::from_bytes(&d.to_bytes())?;
            copy.set_search(d.search_method())?;
            BandDatabase::from_index(copy)
        })
        .collect()
}

/// IBJAE's silhouette check as the Python constructors take it: the
/// nominal `camera` the databases were rendered through (no check without
/// it), the `instrument` (`None`: `Instrument.kflex()`) and the least IoU
/// `min_iou` (`None`: [`DEFAULT_MIN_SILHOUETTE_IOU`]).
struct CheckArgs {
    camera: Option<Camera>,
    instrument: Option<Instrument>,
    min_iou: Option<f64>,
}

impl CheckArgs {
    fn new(
        camera: Option<PyRef<'_, PyCamera>>,
        instrument: Option<PyRef<'_, PyInstrument>>,
        min_iou: Option<f64>,
    ) -> Self {
        Self {
            camera: camera.map(|c| c.inner),
            instrument: instrument.map(|i| i.inner),
            min_iou,
        }
    }
}

/// IBJAE over `databases` with the SCNN at `scnn` (a path); with a camera
/// in `check`, each reading is checked against the nominal silhouette of
/// its pose.
fn load_ibjae(
    py: Python<'_>,
    scnn: PathBuf,
    databases: &[PyRef<'_, PyFeatureIndex>],
    segment: Option<PySegmentParams>,
    threads: usize,
    check: CheckArgs,
) -> Result<Ibjae> {
    if check.camera.is_none() {
        let given = [
            check.instrument.is_some().then_some("instrument"),
            check.min_iou.is_some().then_some("min_silhouette_iou"),
        ];
        if let Some(name) = given.into_iter().flatten().next() {
            return Err(value_error(format!(
                "{name} is for the silhouette check, which needs camera (the nominal camera \
                 the databases were rendered through)"
            )));
        }
    }
    let segment = segment.map_or_else(SegmentParams::default, |p| p.inner);
    // the databases are copied without the interpreter lock (a full range's
    // are some 100 MB); the borrows of the Python objects stay held
    let indexes: Vec<&FeatureIndex> = databases.iter().map(|d| &d.inner).collect();
    Ok(py.detach(|| {
        let bands = band_databases(&indexes)?;
        let ibjae = Ibjae::new(Scnn::load(&scnn, threads)?, segment, bands)?;
        match check.camera {
            Some(c) => ibjae.with_silhouette_check(
                &c,
                &check.instrument.unwrap_or_else(Instrument::kflex),
                check.min_iou.unwrap_or(DEFAULT_MIN_SILHOUETTE_IOU),
            ),
            None => Ok(ibjae),
        }
    })?)
}

/// What IBJAE read from one frame: the database pose read (`theta_deg`,
/// `translation_mm`: the nearest silhouette's, or with `occluded` the one
/// that explains the visible pixels), its feature `distance`, `sigma_deg`
/// (the reading's uncertainty: that distance in degrees of bend, at least
/// half the grid's step; at least 45 where the silhouette check finds the
/// reading unexplained; 5 with `occluded`), `band` (which database
/// answered), `silhouette_iou` (with the check: the IoU between the
/// segmented silhouette and the nominal one of the pose read; else `None`),
/// `occluded` (with the check: the retrieved pose did not explain the
/// silhouette, and the pose read is the grid's that explains the visible
/// pixels with the rest of the instrument hidden, the visible part pinning
/// the bend to ±5 deg) and `consistent_deg` (with `occluded`: the lowest and
/// highest bend as consistent with the visible pixels).
#[pyclass(name = "IbjaeReading", module = "kflex", frozen, get_all)]
pub struct PyIbjaeReading {
    /// Bend, deg.
    theta_deg: f64,
    /// Translation, mm.
    translation_mm: f64,
    /// Feature distance (L2).
    distance: f64,
    /// Uncertainty, deg.
    sigma_deg: f64,
    /// Position of the database in the list IBJAE was given.
    band: usize,
    /// IoU with the nominal silhouette of the pose read (with the check).
    silhouette_iou: Option<f64>,
    /// Whether the pose read takes part of the instrument as hidden.
    occluded: bool,
    /// With `occluded`: the lowest and highest bend consistent with the
    /// visible pixels, deg.
    consistent_deg: Option<[f64; 2]>,
}

#[pymethods]
impl PyIbjaeReading {
    fn __repr__(&self) -> String {
        format!(
            "IbjaeReading(theta_deg={}, translation_mm={}, distance={}, sigma_deg={}, band={}, \
             silhouette_iou={}, occluded={})",
            self.theta_deg,
            self.translation_mm,
            self.distance,
            self.sigma_deg,
            self.band,
            self.silhouette_iou
                .map_or_else(|| "None".to_string(), |v| v.to_string()),
            if self.occluded { "True" } else { "False" }
        )
    }
}

impl From<IbjaeReading> for PyIbjaeReading {
    fn from(r: IbjaeReading) -> Self {
        Self {
            theta_deg: r.theta_deg,
            translation_mm: r.translation_mm,
            distance: r.distance,
            sigma_deg: r.sigma_deg,
            band: r.band,
            silhouette_iou: r.silhouette_iou,
            occluded: r.occluded,
            consistent_deg: r.consistent_deg,
        }
    }
}

/// IBJAE (kflex-estimate's `Ibjae`): segmentation, SCNN embedding and
/// retrieval over one database per working band.
#[pyclass(name = "Ibjae", module = "kflex")]
pub struct PyIbjae {
    inner: Ibjae,
}

#[pymethods]
impl PyIbjae {
    /// IBJAE with the SCNN model at `scnn` (a path, loaded with `threads`
    /// intra-op threads) over `databases` (`FeatureIndex`es as
    /// `build_band_database` makes them, or loaded from their files; each is
    /// copied) and the segmentation thresholds `segment`. Raises
    /// `ValueError` when a database was embedded by another SCNN, there are
    /// none, or one lacks the metadata IBJAE needs (or has it out of range),
    /// and as `Scnn.load`. With `camera` (the nominal camera the databases
    /// were rendered through) each reading is checked against the nominal
    /// silhouette of `instrument` (default `Instrument.kflex()`) in the pose
    /// it reads (`silhouette_iou`; under `min_silhouette_iou`, default 0.85,
    /// a pose with a hidden part is read instead where one explains the
    /// visible pixels, `occluded`, else its `sigma_deg` is at least 45).
    /// Raises `RangeError` for
    /// `min_silhouette_iou` outside [0, 1], `ValueError` for `instrument` or
    /// `min_silhouette_iou` without `camera`.
    #[new]
    #[pyo3(signature = (
        scnn, databases, segment = None, threads = 1, camera = None, instrument = None,
        min_silhouette_iou = None
    ))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn py_new(
        py: Python<'_>,
        scnn: PathBuf,
        databases: Vec<PyRef<'_, PyFeatureIndex>>,
        segment: Option<PySegmentParams>,
        threads: Int,
        camera: Option<PyRef<'_, PyCamera>>,
        instrument: Option<PyRef<'_, PyInstrument>>,
        min_silhouette_iou: Option<f64>,
    ) -> Result<Self> {
        let check = CheckArgs::new(camera, instrument, min_silhouette_iou);
        Ok(Self {
            inner: load_ibjae(
                py,
                scnn,
                &databases,
                segment,
                unsigned("threads", threads)?,
                check,
            )?,
        })
    }

    /// The working bands of the databases, in order.
    #[getter]
    fn bands(&self) -> Vec<PyWorkingBand> {
        self.inner.bands().iter().map(|b| b.band.into()).collect()
    }

    /// The databases to ask for a frame at `translation_mm`: those whose
    /// band holds it and, given a bend `theta_hint_deg`, the one holding it
    /// deepest inside. Raises `ValueError` for a value that is not finite.
    #[pyo3(signature = (theta_hint_deg, translation_mm))]
    fn bands_for(&self, theta_hint_deg: Option<f64>, translation_mm: f64) -> Result<Vec<usize>> {
        crate::camera::finite(
            ["theta_hint_deg", "translation_mm"],
            [theta_hint_deg.unwrap_or(0.0), translation_mm],
        )?;
        Ok(self.inner.bands_for(theta_hint_deg, translation_mm))
    }

    /// Reads the joint from `rgb` (an H×W×3 uint8 frame, any strides) with
    /// the databases `bands`; None when no instrument is found in any of
    /// their regions. Raises `TypeError` for another frame dtype or shape,
    /// `RangeError` for a region outside the frame. Runs without the
    /// interpreter lock.
    fn read(
        &mut self,
        py: Python<'_>,
        rgb: &Bound<'_, PyAny>,
        bands: Vec<Int>,
    ) -> Result<Option<PyIbjaeReading>> {
        let bands = bands
            .into_iter()
            .enumerate()
            .map(|(i, band)| unsigned(&format!("bands[{i}]"), band))
            .collect::<Result<Vec<usize>>>()?;
        let (rgb, width, height) = array::rgb(rgb)?;
        let ibjae = &mut self.inner;
        let reading = py.detach(|| ibjae.read(&RgbView::packed(&rgb, width, height)?, &bands))?;
        Ok(reading.map(Into::into))
    }

    /// Renders now the nominal silhouettes the silhouette check's
    /// hidden-part search needs, which a read otherwise renders the first
    /// time a band needs them (kflex-estimate's
    /// `Ibjae::prepare_hidden_parts`). Runs without the interpreter lock.
    fn prepare_hidden_parts(&mut self, py: Python<'_>) {
        let ibjae = &mut self.inner;
        py.detach(|| ibjae.prepare_hidden_parts());
    }

    /// Whether no read will render nominal silhouettes any more (every
    /// band's are rendered, or there is no silhouette check).
    #[getter]
    fn hidden_parts_ready(&self) -> bool {
        self.inner.hidden_parts_ready()
    }
}

/// One tick of LBHJAE: `fused` (the filter's `Estimate`), `kbjae_deg`
/// (KBJAE's angle this tick) and `ibjae` (IBJAE's `IbjaeReading`, None
/// without a frame or with no instrument in it).
#[pyclass(name = "LbhjaeEstimate", module = "kflex", frozen, get_all)]
pub struct PyLbhjaeEstimate {
    /// The fused estimate.
    fused: Py<PyEstimate>,
    /// KBJAE's angle, deg.
    kbjae_deg: f64,
    /// IBJAE's reading, if any.
    ibjae: Option<Py<PyIbjaeReading>>,
}

/// LBHJAE (kflex-estimate's `Lbhjae`): KBJAE every tick, IBJAE when a frame
/// arrives, fused by a Kalman filter.
#[pyclass(name = "Lbhjae", module = "kflex")]
pub struct PyLbhjae {
    // a Mutex only to make the boxed filter `Sync`, as a Python class must
    // be; `&mut self` reaches it without locking
    pub(crate) inner: Mutex<Lbhjae>,
}

#[pymethods]
impl PyLbhjae {
    /// LBHJAE from KBJAE's model at `kbjae` and IBJAE's SCNN at `scnn`
    /// (paths), IBJAE's `databases` (as for `Ibjae`), and the fusion
    /// filter's parameters `fusion`: `KalmanParams` for the paper's filter,
    /// `AdaptiveParams` for the adaptive one. Raises as `Kbjae.load` and
    /// `Ibjae`, `RangeError` for a filter parameter out of range; `camera`,
    /// `instrument` and `min_silhouette_iou` as for `Ibjae` (the silhouette
    /// check).
    #[new]
    #[pyo3(signature = (
        kbjae, scnn, databases, fusion, segment = None, camera = None, instrument = None,
        min_silhouette_iou = None
    ))]
    #[allow(clippy::too_many_arguments)] // Python's keyword arguments
    fn py_new(
        py: Python<'_>,
        kbjae: PathBuf,
        scnn: PathBuf,
        databases: Vec<PyRef<'_, PyFeatureIndex>>,
        fusion: &Bound<'_, PyAny>,
        segment: Option<PySegmentParams>,
        camera: Option<PyRef<'_, PyCamera>>,
        instrument: Option<PyRef<'_, PyInstrument>>,
        min_silhouette_iou: Option<f64>,
    ) -> Result<Self> {
        let check = CheckArgs::new(camera, instrument, min_silhouette_iou);
        let filter: Box<dyn Fusion + Send> = if let Ok(p) = fusion.extract::<PyKalmanParams>() {
            Box::new(PaperKalman::new(p.inner)?)
        } else if let Ok(p) = fusion.extract::<PyAdaptiveParams>() {
            Box::new(AdaptiveKalman::new(p.inner)?)
        } else {
            return Err(type_error(format!(
                "fusion: expected KalmanParams or AdaptiveParams, got {}",
                fusion.get_type().name()?
            )));
        };
        let ibjae = load_ibjae(py, scnn, &databases, segment, 1, check)?;
        let kbjae = py.detach(|| Kbjae::load(&kbjae))?;
        Ok(Self {
            inner: Mutex::new(Lbhjae::new(kbjae, ibjae, filter)),
        })
    }

    /// One tick: the command sent to the plant (`theta_c_deg` deg,
    /// `translation_mm` mm), `dt_s` after the last, and the camera's frame
    /// `rgb` (H×W×3 uint8) if one arrived. Raises `ValueError` for a
    /// non-finite command, `RangeError` for `dt_s`, `TypeError` or
    /// `RangeError` for a frame the regions do not fit; with a frame,
    /// `RangeError` for a translation outside those the databases hold and
    /// `ValueError` for one in a gap between their bands; the estimator is
    /// then unchanged. Runs without the interpreter lock.
    ///
    /// `rate_deg_per_s`: KBJAE's rate input; in a compensated loop, the
    /// master's θ_d' (what kflex's closed loop gives it: the compensator's
    /// corrections make θ_c's own rate wiggle). `None`: θ_c's backward
    /// difference.
    #[pyo3(signature = (theta_c_deg, translation_mm, dt_s, rgb = None, rate_deg_per_s = None))]
    fn step(
        &mut self,
        py: Python<'_>,
        theta_c_deg: f64,
        translation_mm: f64,
        dt_s: f64,
        rgb: Option<&Bound<'_, PyAny>>,
        rate_deg_per_s: Option<f64>,
    ) -> Result<PyLbhjaeEstimate> {
        let rgb = rgb.filter(|o| !o.is_none()).map(array::rgb).transpose()?;
        let lbhjae = self.inner.get_mut().unwrap_or_else(PoisonError::into_inner);
        let command = Command {
            theta_c_deg,
            translation_mm,
        };
        let e = py.detach(|| {
            let view = rgb
                .as_ref()
                .map(|(data, w, h)| RgbView::packed(data, *w, *h))
                .transpose()?;
            match rate_deg_per_s {
                Some(rate) => lbhjae.step_with_rate(command, rate, dt_s, view.as_ref()),
                None => lbhjae.step(command, dt_s, view.as_ref()),
            }
        })?;
        Ok(PyLbhjaeEstimate {
            fused: Py::new(py, fusion::estimate(py, &e.fused))?,
            kbjae_deg: e.kbjae_deg,
            ibjae: e
                .ibjae
                .map(|r| Py::new(py, PyIbjaeReading::from(r)))
                .transpose()?,
        })
    }

    /// Back to the start: no command history, the filter at its initial state.
    fn reset(&mut self) {
        self.inner
            .get_mut()
            .unwrap_or_else(PoisonError::into_inner)
            .reset();
    }

    /// Renders IBJAE's hidden-part silhouettes up front (as
    /// `Ibjae.prepare_hidden_parts`), so that no later step does. Runs
    /// without the interpreter lock.
    fn prepare_hidden_parts(&mut self, py: Python<'_>) {
        let lbhjae = self.inner.get_mut().unwrap_or_else(PoisonError::into_inner);
        py.detach(|| lbhjae.prepare_hidden_parts());
    }

    /// Whether no step will render IBJAE's hidden-part silhouettes any more.
    #[getter]
    fn hidden_parts_ready(&self) -> bool {
        self.inner
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .hidden_parts_ready()
    }
}
