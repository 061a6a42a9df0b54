//! IBJAE's feature databases on disk: built over a camera's working
//! regions, saved as a directory (all or nothing), loaded back with the
//! same answers, refused for another camera or when damaged.
#![cfg(all(feature = "onnx", feature = "index"))]

use std::path::{Path, PathBuf};

use kflex_estimate::{
    EstimateError, Ibjae, Scnn, SegmentParams, build_databases, check_database_dir, database_file,
    load_databases, save_databases,
};
use kflex_model::{Camera, Instrument, Intrinsics, WorkingRegions};

/// A file of `tests/data` (the small test models of `tools/make_test_models.py`).
fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kflex-db-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The default camera's databases on a coarse grid (10 deg × 8 mm).
fn databases(scnn: &mut Scnn, camera: &Camera) -> Vec<kflex_estimate::BandDatabase> {
    let regions = WorkingRegions::full(camera).unwrap();
    build_databases(scnn, camera, &Instrument::kflex(), &regions, 10.0, 8.0).unwrap()
}

#[test]
fn saved_databases_load_back_with_the_same_answers() {
    let camera = Camera::default();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let built = databases(&mut scnn, &camera);
    let regions = WorkingRegions::full(&camera).unwrap();
    assert_eq!(built.len(), regions.bands().len());
    let dir = scratch("roundtrip").join("db");
    save_databases(&dir, &built).unwrap();
    let loaded = load_databases(&dir, &camera).unwrap();
    assert_eq!(loaded.len(), built.len());
    for (a, b) in built.iter().zip(&loaded) {
        assert_eq!(a.band, b.band);
        assert_eq!(a.index.len(), b.index.len());
        assert_eq!(a.index.poses(), b.index.poses());
        // every entry finds itself, and a point between two finds the same in both
        let f = a.index.features();
        let dim = a.index.dim();
        for i in (0..a.index.len()).step_by(3) {
            let q = &f[i * dim..(i + 1) * dim];
            assert_eq!(a.index.nearest(q).unwrap(), b.index.nearest(q).unwrap());
            if i + 1 < a.index.len() {
                let mid: Vec<f32> = q
                    .iter()
                    .zip(&f[(i + 1) * dim..(i + 2) * dim])
                    .map(|(x, y)| 0.5 * (x + y))
                    .collect();
                assert_eq!(
                    a.index.nearest(&mid).unwrap(),
                    b.index.nearest(&mid).unwrap()
                );
            }
        }
    }
    // and IBJAE takes them
    Ibjae::new(scnn, SegmentParams::default(), loaded).unwrap();
}

#[test]
fn a_database_of_another_camera_or_a_damaged_one_is_refused() {
    let camera = Camera::default();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let built = databases(&mut scnn, &camera);
    let dir = scratch("refused").join("db");
    save_databases(&dir, &built).unwrap();
    // another focal length
    let mut k = Intrinsics::default();
    k.fx *= 1.01;
    let other = camera.with_intrinsics(k);
    match load_databases(&dir, &other) {
        Err(EstimateError::ModelMismatch {
            which: "camera",
            expected,
            found,
            ..
        }) => {
            assert_ne!(expected, found);
            assert!(found.contains("fx"), "{found}");
        }
        other => panic!("expected a camera mismatch, got {other:?}"),
    }
    // no databases at all
    let empty = scratch("empty");
    std::fs::create_dir_all(&empty).unwrap();
    match load_databases(&empty, &camera) {
        Err(EstimateError::Io { kind, path, .. }) => {
            assert_eq!(kind, std::io::ErrorKind::NotFound);
            assert_eq!(path, empty.join(kflex_estimate::MANIFEST));
        }
        other => panic!("expected not found, got {other:?}"),
    }
    // a band's file gone: an error naming it, not fewer bands
    let gone = database_file(&dir, 5);
    let kept = std::fs::read(&gone).unwrap();
    std::fs::remove_file(&gone).unwrap();
    match load_databases(&dir, &camera) {
        Err(EstimateError::Io { kind, path, .. }) => {
            assert_eq!(kind, std::io::ErrorKind::NotFound);
            assert_eq!(path, gone);
        }
        other => panic!("expected band 5 not found, got {other:?}"),
    }
    std::fs::write(&gone, kept).unwrap();
    assert_eq!(load_databases(&dir, &camera).unwrap().len(), built.len());
    // a flipped byte in the middle of band 1
    let file = database_file(&dir, 1);
    let mut bytes = std::fs::read(&file).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&file, bytes).unwrap();
    assert!(load_databases(&dir, &camera).is_err());
    // a manifest counting more bands than any directory holds is refused
    // before anything is sized by it
    let manifest = dir.join(kflex_estimate::MANIFEST);
    for count in ["1000000000000", "18446744073709551615", "0"] {
        std::fs::write(&manifest, count).unwrap();
        match load_databases(&dir, &camera) {
            Err(EstimateError::ModelFile { message, .. }) => {
                assert!(message.contains("not a count of bands"), "{message}");
            }
            other => panic!("{count}: expected a bad manifest, got {other:?}"),
        }
    }
}

#[test]
fn saving_replaces_the_whole_directory_and_keeps_other_files() {
    let camera = Camera::default();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let built = databases(&mut scnn, &camera);
    let dir = scratch("replace").join("db");
    save_databases(&dir, &built).unwrap();
    std::fs::write(dir.join("README.md"), "the databases of the shipped SCNN\n").unwrap();
    // fewer bands this time: the old ones beyond them must go
    save_databases(&dir, &built[..2]).unwrap();
    assert!(database_file(&dir, 1).exists());
    assert!(!database_file(&dir, 2).exists());
    assert_eq!(load_databases(&dir, &camera).unwrap().len(), 2);
    assert_eq!(
        std::fs::read_to_string(dir.join("README.md")).unwrap(),
        "the databases of the shipped SCNN\n"
    );
    // nothing left beside it
    let parent = dir.parent().unwrap();
    let names: Vec<String> = std::fs::read_dir(parent)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["db"]);
    // a directory inside, a file in its place, or no name of its own: refused
    let inside = dir.join("old-runs");
    std::fs::create_dir(&inside).unwrap();
    let invalid =
        |target: &std::path::Path, result: kflex_estimate::Result<()>, when: &str| match result {
            Err(EstimateError::Io { kind, .. }) => {
                assert_eq!(
                    kind,
                    std::io::ErrorKind::InvalidInput,
                    "{}",
                    target.display()
                );
            }
            other => panic!(
                "{}: expected refused {when}, got {other:?}",
                target.display()
            ),
        };
    let refused = |target: &std::path::Path, bands: &[kflex_estimate::BandDatabase]| {
        invalid(target, save_databases(target, bands), "");
    };
    // asked before the work (`check_database_dir`), each is refused the same
    let checked = |target: &std::path::Path| {
        invalid(target, check_database_dir(target), "up front");
    };
    refused(&dir, &built[..1]);
    checked(&dir);
    std::fs::remove_dir(&inside).unwrap();
    // a directory named like a database is a directory all the same (it
    // would have gone with the old databases, and what it held with it)
    let named = dir.join("archive.kfdb");
    std::fs::create_dir(&named).unwrap();
    std::fs::write(named.join("kept.txt"), "mine").unwrap();
    refused(&dir, &built[..1]);
    checked(&dir);
    assert_eq!(
        std::fs::read_to_string(named.join("kept.txt")).unwrap(),
        "mine"
    );
    std::fs::remove_dir_all(&named).unwrap();
    check_database_dir(&dir).unwrap();
    let file = parent.join("a-file");
    std::fs::write(&file, "not a directory").unwrap();
    refused(&file, &built[..1]);
    checked(&file);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "not a directory");
    std::fs::remove_file(&file).unwrap();
    refused(&dir.join(".."), &built[..1]);
    checked(&dir.join(".."));
    assert_eq!(load_databases(&dir, &camera).unwrap().len(), 2);
    // no bands is an error and leaves the directory as it was
    assert!(matches!(
        save_databases(&dir, &[]),
        Err(EstimateError::NoBandDatabase)
    ));
    assert_eq!(load_databases(&dir, &camera).unwrap().len(), 2);
}
