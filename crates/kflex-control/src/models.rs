//! The trained models a grid's estimators load (cargo feature
//! `estimators`), from one directory: `kbjae.onnx` (KBJAE's MLP),
//! `scnn.onnx` (IBJAE's Siamese CNN) and `db/` (IBJAE's feature databases,
//! `kflex-cli build-db`). `assets/models/` is where kflex's own trained
//! models will ship.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use crate::closed_loop::AngleEstimator;
use crate::error::{ControlError, Result};
use crate::estimators::IbjaeAlone;
use crate::grid::EstimatorKind;
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, BandDatabase, DEFAULT_MIN_SILHOUETTE_IOU, HiddenPartGrids,
    Ibjae, KalmanParams, Kbjae, Lbhjae, ModelPool, PaperKalman, Scnn, SegmentParams,
    load_databases,
};
use kflex_model::{Camera, Instrument};

/// Where kflex's trained models ship, relative to the project's root.
pub const MODELS_DIR: &str = "assets/models";

/// A directory of trained models. The feature databases it loads are read
/// once per camera and shared by every estimator it makes (a grid makes
/// fresh estimators for each run), with the silhouette check's hidden-part
/// grids, each band's rendered once; a new `ModelDir` reads the files again.
/// The networks' sessions its estimators give back when dropped serve the
/// next ones it makes ([`ModelPool`]; the files are still read and checked
/// at each make).
#[derive(Debug, Clone)]
pub struct ModelDir {
    dir: PathBuf,
    /// The networks' sessions its estimators gave back, for the next ones.
    pool: Arc<ModelPool>,
    /// The databases loaded so far, with the camera they were checked against.
    loaded: Arc<Mutex<Vec<Loaded>>>,
}

/// Databases loaded by a [`ModelDir`], with the camera they were checked
/// against and their hidden-part grids.
type Loaded = (Camera, Arc<[BandDatabase]>, Arc<HiddenPartGrids>);

impl PartialEq for ModelDir {
    /// The same directory (whatever each has loaded).
    fn eq(&self, other: &Self) -> bool {
        self.dir == other.dir
    }
}

impl Eq for ModelDir {}

impl ModelDir {
    /// The models in `dir`.
    #[must_use]
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
            pool: ModelPool::new(),
            loaded: Arc::default(),
        }
    }

    /// The databases for `camera` and their hidden-part grids: loaded (and
    /// checked) on the first ask, shared after.
    fn databases_for(
        &self,
        camera: &Camera,
    ) -> Result<(Arc<[BandDatabase]>, Arc<HiddenPartGrids>)> {
        let loaded = || self.loaded.lock().unwrap_or_else(PoisonError::into_inner);
        let found = |kept: &[Loaded]| {
            kept.iter()
                .find(|(c, _, _)| c == camera)
                .map(|(_, bands, grids)| (Arc::clone(bands), Arc::clone(grids)))
        };
        if let Some(shared) = found(&loaded()) {
            return Ok(shared);
        }
        // read outside the lock; two threads asking at once may both read
        let bands: Arc<[BandDatabase]> = Arc::from(load_databases(&self.databases(), camera)?);
        // the databases are the nominal instrument's through `camera`
        let grids = HiddenPartGrids::new(camera, &Instrument::kflex(), Arc::clone(&bands))?;
        let mut kept = loaded();
        match found(&kept) {
            Some(first) => Ok(first),
            None => {
                kept.push((*camera, Arc::clone(&bands), Arc::clone(&grids)));
                Ok((bands, grids))
            }
        }
    }

    /// KBJAE's model file.
    #[must_use]
    pub fn kbjae(&self) -> PathBuf {
        self.dir.join("kbjae.onnx")
    }

    /// IBJAE's SCNN file.
    #[must_use]
    pub fn scnn(&self) -> PathBuf {
        self.dir.join("scnn.onnx")
    }

    /// IBJAE's database directory.
    #[must_use]
    pub fn databases(&self) -> PathBuf {
        self.dir.join("db")
    }

    /// The files `kind` needs that are not there.
    #[must_use]
    pub fn missing(&self, kind: EstimatorKind) -> Vec<PathBuf> {
        let (kbjae, ibjae) = match kind {
            EstimatorKind::None => (false, false),
            EstimatorKind::Kbjae => (true, false),
            EstimatorKind::Ibjae => (false, true),
            EstimatorKind::Lbhjae | EstimatorKind::LbhjaeAdaptive => (true, true),
        };
        let mut files = Vec::new();
        if kbjae {
            files.push(self.kbjae());
        }
        if ibjae {
            files.push(self.scnn());
            files.push(kflex_estimate::database_file(&self.databases(), 0));
        }
        files.retain(|f| !f.exists());
        files
    }

    fn ibjae(&self, camera: &Camera) -> Result<Ibjae> {
        let scnn = Scnn::load_pooled(&self.scnn(), 1, &self.pool)?;
        let (bands, grids) = self.databases_for(camera)?;
        Ok(Ibjae::new_shared(scnn, SegmentParams::default(), bands)?
            .with_shared_silhouette_check(&grids, DEFAULT_MIN_SILHOUETTE_IOU)?)
    }

    /// Makes each of `kinds` once (not `None`, which needs no model), so
    /// that a missing or damaged model fails before a grid's first run
    /// rather than after its first cases.
    ///
    /// # Errors
    /// As [`ModelDir::make`], for the first kind that fails.
    pub fn check(&self, kinds: &[EstimatorKind], camera: &Camera) -> Result<()> {
        for &kind in kinds.iter().filter(|&&k| k != EstimatorKind::None) {
            self.make(kind, camera)?;
        }
        Ok(())
    }

    /// A fresh estimator of `kind` on these models, for a run through the
    /// nominal `camera` (the one the databases were rendered through).
    ///
    /// # Errors
    /// [`ControlError::Unavailable`] naming the files that are missing;
    /// a model's or database's own error (damaged, built with another
    /// model or camera, no ONNX Runtime).
    pub fn make(&self, kind: EstimatorKind, camera: &Camera) -> Result<Box<dyn AngleEstimator>> {
        let missing = self.missing(kind);
        if !missing.is_empty() {
            let files: Vec<String> = missing.iter().map(|f| f.display().to_string()).collect();
            return Err(ControlError::Unavailable {
                what: format!(
                    "the estimator {} needs {}, which {} not there: kflex ships no trained \
                     models yet (training/README.md trains them, `kflex-cli build-db` builds \
                     the databases)",
                    kind.name(),
                    files.join(" and "),
                    if files.len() == 1 { "is" } else { "are" }
                ),
            });
        }
        let fusion = |adaptive: bool| -> Result<Box<dyn kflex_estimate::Fusion + Send>> {
            Ok(if adaptive {
                Box::new(AdaptiveKalman::new(AdaptiveParams::default())?)
            } else {
                Box::new(PaperKalman::new(KalmanParams::default())?)
            })
        };
        Ok(match kind {
            EstimatorKind::None => {
                return Err(ControlError::Unavailable {
                    what: "the uncompensated plant has no estimator to make".into(),
                });
            }
            EstimatorKind::Kbjae => Box::new(Kbjae::load_pooled(&self.kbjae(), &self.pool)?),
            EstimatorKind::Ibjae => Box::new(IbjaeAlone::new(self.ibjae(camera)?)),
            EstimatorKind::Lbhjae | EstimatorKind::LbhjaeAdaptive => Box::new(Lbhjae::new(
                Kbjae::load_pooled(&self.kbjae(), &self.pool)?,
                self.ibjae(camera)?,
                fusion(kind == EstimatorKind::LbhjaeAdaptive)?,
            )),
        })
    }
}
