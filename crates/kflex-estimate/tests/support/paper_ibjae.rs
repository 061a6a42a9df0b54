//! IBJAE on the small test models (`tools/make_test_models.py`), over the
//! paper's band: θ 0–50° at d = 10 mm in the paper's region, its database
//! built from the nominal instrument on a 1° grid.

use std::path::{Path, PathBuf};

use kflex_estimate::{DEFAULT_MIN_SILHOUETTE_IOU, Ibjae, Scnn, SegmentParams, build_band_database};
use kflex_model::{Camera, Instrument, PoseRange, Roi, WorkingBand};

/// A file of `tests/data`.
pub fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// The paper's band: θ 0–50° at d = 10 mm in the paper's region.
pub fn paper_band(camera: &Camera) -> WorkingBand {
    WorkingBand {
        poses: PoseRange {
            theta_deg: [0.0, 50.0],
            translation_mm: [10.0, 10.0],
        },
        roi: Roi::paper(camera).unwrap(),
    }
}

/// IBJAE with the test SCNN and one database, the paper's band.
pub fn ibjae(camera: &Camera) -> Ibjae {
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let db = build_band_database(
        &mut scnn,
        camera,
        &Instrument::kflex(),
        &paper_band(camera),
        1.0,
        1.0,
    )
    .unwrap();
    assert_eq!(db.index.len(), 51);
    Ibjae::new(scnn, SegmentParams::default(), vec![db]).unwrap()
}

/// [`ibjae`] with the silhouette check of the nominal instrument at the
/// default least IoU.
pub fn checked_ibjae(camera: &Camera) -> Ibjae {
    ibjae(camera)
        .with_silhouette_check(camera, &Instrument::kflex(), DEFAULT_MIN_SILHOUETTE_IOU)
        .unwrap()
}
