//! The feature-index database file: round trip, atomic save, and every kind
//! of bad file a typed error, never a panic (a proptest over random,
//! truncated and bit-flipped bytes). `cargo test -p kflex-estimate --features index`
#![cfg(feature = "index")]

#[path = "support/manifold.rs"]
mod manifold;

use std::path::PathBuf;

use kflex_estimate::index::FORMAT_VERSION;
use kflex_estimate::{EstimateError, FeatureIndex, IndexParams, ProjectionDims};
use manifold::{DEFAULT_NOISE_STD, Manifold, rng};
use proptest::prelude::*;

/// A fresh path under cargo's temporary directory for tests.
fn temp(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("index_file");
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn small_index(n: usize, dim: usize, k: ProjectionDims) -> FeatureIndex {
    let surface = Manifold::new(dim, DEFAULT_NOISE_STD, 3);
    let (features, poses) = surface.sample(n, &mut rng(n as u64));
    let mut index = FeatureIndex::build(
        &features,
        dim,
        &poses,
        IndexParams {
            projection_dims: k,
            ..IndexParams::default()
        },
    )
    .unwrap();
    index.set_metadata("model_sha256", "3f".repeat(32));
    index.set_metadata("camera", "v2 640×480, lens k1 = -0.28");
    index.set_metadata("grid", "theta -90..90 step 1 deg × d 8..40 step 1 mm");
    index
}

#[test]
fn save_then_load_gives_the_same_index() {
    for (n, dim, k) in [(500, 256, ProjectionDims::K8), (40, 5, ProjectionDims::K16)] {
        let index = small_index(n, dim, k);
        let path = temp(&format!("round_trip_{n}.kfi"));
        index.save(&path).unwrap();
        let loaded = FeatureIndex::load(&path).unwrap();
        assert_eq!(loaded.features(), index.features());
        assert_eq!(loaded.poses(), index.poses());
        assert_eq!(loaded.metadata(), index.metadata());
        assert_eq!(loaded.projection_dims(), k);
        assert_eq!(
            loaded.to_bytes(),
            index.to_bytes(),
            "byte-identical on re-save"
        );
        let (queries, _) = Manifold::new(dim, DEFAULT_NOISE_STD, 3).sample(200, &mut rng(99));
        for q in queries.chunks_exact(dim) {
            assert_eq!(loaded.nearest(q).unwrap(), index.nearest(q).unwrap());
        }
        // nothing but the file is left behind
        let leftovers: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
            .collect();
        assert!(leftovers.is_empty(), "{leftovers:?}");
    }
}

#[test]
fn save_replaces_a_file_whole_and_reports_a_bad_directory() {
    let path = temp("replace.kfi");
    small_index(30, 8, ProjectionDims::K8).save(&path).unwrap();
    let bigger = small_index(300, 8, ProjectionDims::K8);
    bigger.save(&path).unwrap();
    assert_eq!(FeatureIndex::load(&path).unwrap().len(), 300);

    let nowhere = temp("no/such/dir/index.kfi");
    match bigger.save(&nowhere) {
        Err(EstimateError::Io { path, kind, .. }) => {
            assert_eq!(path, nowhere);
            assert_eq!(kind, std::io::ErrorKind::NotFound);
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_files_are_typed_errors() {
    let missing = temp("missing.kfi");
    match FeatureIndex::load(&missing) {
        Err(
            e @ EstimateError::Io {
                kind: std::io::ErrorKind::NotFound,
                ..
            },
        ) => {
            assert!(e.to_string().contains("missing.kfi"), "{e}");
        }
        other => panic!("{other:?}"),
    }
    let good = small_index(50, 16, ProjectionDims::K12).to_bytes();
    let corrupt = |bytes: &[u8], needle: &str| match FeatureIndex::from_bytes(bytes) {
        Err(e @ EstimateError::IndexCorrupt { .. }) => {
            assert!(e.to_string().contains(needle), "{needle:?} not in {e}")
        }
        other => panic!("expected corrupt ({needle}), got {other:?}"),
    };
    corrupt(&[], "magic");
    corrupt(b"PNG\x89 not an index at all", "magic");
    corrupt(&good[..good.len() - 1], "truncated");
    corrupt(&good[..20], "truncated");
    corrupt(&[&good[..], &[0]].concat(), "trailing");
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    corrupt(&flipped, "checksum");

    // another version: named, whatever follows
    let mut v2 = good.clone();
    v2[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    match FeatureIndex::from_bytes(&v2) {
        Err(EstimateError::IndexVersion {
            found, supported, ..
        }) => {
            assert_eq!((found, supported), (FORMAT_VERSION + 1, FORMAT_VERSION));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_loaded_file_is_written_to_disk_whole() {
    let index = small_index(100, 32, ProjectionDims::K8);
    let path = temp("whole.kfi");
    index.save(&path).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), index.to_bytes());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = FeatureIndex::from_bytes(&bytes);
        let mut with_magic = b"KFLEXIDX".to_vec();
        with_magic.extend(&bytes);
        prop_assert!(FeatureIndex::from_bytes(&with_magic).is_err());
    }

    #[test]
    fn truncated_files_are_errors(cut in 0_usize..10_000) {
        let good = small_index(20, 16, ProjectionDims::K8).to_bytes();
        let cut = cut % good.len();
        prop_assert!(FeatureIndex::from_bytes(&good[..cut]).is_err());
    }

    #[test]
    fn flipped_bits_are_errors(flips in proptest::collection::vec(any::<(usize, u8)>(), 1..4)) {
        let good = small_index(20, 16, ProjectionDims::K8).to_bytes();
        let mut bad = good.clone();
        for (at, bit) in &flips {
            bad[at % good.len()] ^= 1 << (bit % 8);
        }
        if bad != good {
            prop_assert!(FeatureIndex::from_bytes(&bad).is_err());
        }
    }
}
