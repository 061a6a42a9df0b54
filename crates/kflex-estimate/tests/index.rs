//! The feature index against brute force: identical answers (point, pose,
//! distance bits) on 10,000 queries of every kind, ties, narrow and wide
//! features, and the input errors. `cargo test -p kflex-estimate --features index`
#![cfg(feature = "index")]

#[path = "support/manifold.rs"]
mod manifold;

use kflex_estimate::{
    EstimateError, FeatureIndex, IndexParams, Neighbour, Pose, ProjectionDims, Search,
};
use manifold::{Manifold, random_points, rng};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

const D: usize = 256;

fn poses(n: usize) -> Vec<Pose> {
    (0..n)
        .map(|i| Pose {
            theta_deg: i as f64,
            translation_mm: -(i as f64),
        })
        .collect()
}

fn params(k: ProjectionDims, search: Search) -> IndexParams {
    IndexParams {
        projection_dims: k,
        search,
    }
}

/// Both ways to search the projected space: each must be exact.
const SEARCHES: [Search; 2] = [Search::Tree, Search::Scan];

/// The index over `features` searched each way, default projection.
fn both(features: &[f32], dim: usize, poses: &[Pose]) -> Vec<FeatureIndex> {
    SEARCHES
        .iter()
        .map(|&s| {
            let index =
                FeatureIndex::build(features, dim, poses, params(ProjectionDims::K8, s)).unwrap();
            assert_eq!(index.search_method(), s);
            index
        })
        .collect()
}

/// Asserts the index and the linear scan agree on every row of `queries`;
/// returns the mean number of full distances the index computed.
fn assert_exact(index: &FeatureIndex, queries: &[f32], what: &str) -> f64 {
    let mut work = 0;
    for (i, q) in queries.chunks_exact(index.dim()).enumerate() {
        let (fast, stats) = index.nearest_with_stats(q).expect("query");
        let slow = index.nearest_linear(q).expect("query");
        assert_eq!(fast, slow, "{what}: query {i}");
        assert_eq!(fast.distance_sq.to_bits(), slow.distance_sq.to_bits());
        work += stats.full_distances;
    }
    work as f64 / (queries.len() / index.dim()) as f64
}

/// Rows of `features` with Gaussian noise of `std` added.
fn perturbed(features: &[f32], std: f64, r: &mut impl Rng) -> Vec<f32> {
    features
        .iter()
        .map(|x| {
            let z: f64 = StandardNormal.sample(r);
            x + (std * z) as f32
        })
        .collect()
}

#[test]
fn identical_to_brute_force_on_ten_thousand_manifold_queries() {
    let mut r = rng(1);
    let surface = Manifold::new(D, manifold::DEFAULT_NOISE_STD, 7);
    let n = 2000;
    let (features, poses) = surface.sample(n, &mut r);
    let quarter = 2500;
    // the database points themselves (the first 2000, then 500 again)
    let own: Vec<f32> = features
        .iter()
        .chain(&features[..(quarter - n) * D])
        .copied()
        .collect();
    // the database points moved by noise like the rendering's
    let moved = perturbed(&own, manifold::DEFAULT_NOISE_STD, &mut r);
    // fresh frames: new poses on the surface, new noise
    let (fresh, _) = surface.sample(quarter, &mut r);
    // points off the surface, at its spread around its mean
    let off = random_points(quarter, D, 1.0 / (D as f64).sqrt(), &mut r);
    for index in both(&features, D, &poses) {
        let mut work = Vec::new();
        for (queries, what) in [
            (&own, "database"),
            (&moved, "perturbed"),
            (&fresh, "fresh"),
            (&off, "random"),
        ] {
            assert_eq!(queries.len(), quarter * D);
            work.push((what, assert_exact(&index, queries, what)));
        }
        // the point of the index: far fewer full distances than the 2000 of a scan
        for (what, w) in &work {
            if *what != "random" {
                assert!(*w < 200.0, "{what}: {w} full distances per query");
            }
        }
    }
}

#[test]
fn every_projection_width_is_exact() {
    let mut r = rng(2);
    let surface = Manifold::new(D, manifold::DEFAULT_NOISE_STD, 8);
    let (features, poses) = surface.sample(1000, &mut r);
    let (queries, _) = surface.sample(300, &mut r);
    for k in ProjectionDims::ALL {
        for search in SEARCHES {
            let index = FeatureIndex::build(&features, D, &poses, params(k, search)).unwrap();
            assert_eq!(index.projection_dims(), k);
            assert_exact(&index, &queries, "fresh");
            assert_exact(&index, &features[..300 * D], "database");
        }
    }
}

#[test]
fn identical_to_brute_force_on_random_data() {
    let mut r = rng(3);
    for (n, dim) in [(1000, 64), (500, 256), (300, 9)] {
        let features = random_points(n, dim, 1.0, &mut r);
        let queries = random_points(1000, dim, 1.0, &mut r);
        let moved = perturbed(&features[..200 * dim], 0.05, &mut r);
        for index in both(&features, dim, &poses(n)) {
            assert_exact(&index, &queries, "random");
            assert_exact(&index, &moved, "perturbed");
        }
    }
}

#[test]
fn narrow_features_any_dimension() {
    let mut r = rng(4);
    for dim in [1, 2, 3, 7, 8, 12, 13, 16, 17] {
        let n = 400;
        let features = random_points(n, dim, 3.0, &mut r);
        for k in ProjectionDims::ALL {
            let queries = random_points(300, dim, 3.0, &mut r);
            for search in SEARCHES {
                let index = FeatureIndex::build(&features, dim, &poses(n), params(k, search));
                let index = index.unwrap();
                assert_exact(&index, &queries, "random");
                assert_exact(&index, &features, "database");
            }
        }
    }
}

#[test]
fn ties_go_to_the_lowest_index() {
    for search in SEARCHES {
        let build = |f: &[f32], dim: usize, n: usize| {
            FeatureIndex::build(f, dim, &poses(n), params(ProjectionDims::K8, search)).unwrap()
        };
        // duplicates: every query finds the first copy
        let mut r = rng(5);
        let base = random_points(50, D, 1.0, &mut r);
        let features: Vec<f32> = base.iter().chain(&base).chain(&base).copied().collect();
        let index = build(&features, D, 150);
        for i in 0..150 {
            let found = index.nearest(&features[i * D..][..D]).unwrap();
            assert_eq!(
                (found.index, found.distance_sq),
                (i % 50, 0.0),
                "{search:?}"
            );
        }
        assert_exact(&index, &random_points(200, D, 1.0, &mut r), "random");

        // equidistant points: ±e_j around the origin, queried at the origin
        let mut features = vec![0.0_f32; 2 * 8 * D];
        for j in 0..8 {
            features[(2 * j) * D + j] = 1.0;
            features[(2 * j + 1) * D + j] = -1.0;
        }
        let index = build(&features, D, 16);
        let found = index.nearest(&[0.0; D]).unwrap();
        assert_eq!((found.index, found.distance_sq), (0, 1.0), "{search:?}");
        assert_exact(&index, &random_points(200, D, 0.5, &mut r), "random");

        // one point repeated: index 0 always
        let same = vec![0.25_f32; 40 * 3];
        let index = build(&same, 3, 40);
        for q in [[0.25, 0.25, 0.25], [9.0, -1.0, 0.0]] {
            assert_eq!(index.nearest(&q).unwrap().index, 0, "{search:?}");
        }
    }
}

/// Sizes around the scan's blocks of 16 (a partial last block, one point,
/// exactly whole blocks) and on either side of where `Auto` changes from the
/// scan to the tree.
#[test]
fn every_size_is_exact_and_auto_picks_by_size() {
    let mut r = rng(10);
    for n in [1, 2, 15, 16, 17, 31, 33, 100] {
        let features = random_points(n, 24, 1.0, &mut r);
        let queries = random_points(100, 24, 1.0, &mut r);
        for index in both(&features, 24, &poses(n)) {
            assert_exact(&index, &queries, "random");
            assert_exact(&index, &features, "database");
        }
    }
    let max = Search::SCAN_MAX_POINTS;
    for (n, chosen) in [(max, Search::Scan), (max + 1, Search::Tree)] {
        let features = random_points(n, 4, 1.0, &mut r);
        let mut index =
            FeatureIndex::build(&features, 4, &poses(n), IndexParams::default()).unwrap();
        assert_eq!(index.search_method(), chosen, "{n} points");
        assert_exact(&index, &random_points(200, 4, 1.0, &mut r), "random");
        // the other way gives the same answers, where it is allowed
        let other = match chosen {
            Search::Scan => Search::Tree,
            _ => Search::Scan,
        };
        match index.set_search(other) {
            Ok(()) => {
                assert_eq!(index.search_method(), other);
                assert_exact(&index, &random_points(200, 4, 1.0, &mut r), "random");
            }
            Err(EstimateError::OutOfRange(e)) => {
                assert_eq!(n, max + 1);
                assert!(e.to_string().contains("searched by scan"), "{e}");
                // refused, the index searches as before
                assert_eq!(index.search_method(), chosen);
                assert_exact(&index, &random_points(50, 4, 1.0, &mut r), "random");
            }
            Err(e) => panic!("{e}"),
        }
    }
    // a scan over more points than it takes is refused when built
    let features = random_points(max + 1, 4, 1.0, &mut r);
    let refused = FeatureIndex::build(
        &features,
        4,
        &poses(max + 1),
        params(ProjectionDims::K8, Search::Scan),
    );
    assert!(matches!(refused, Err(EstimateError::OutOfRange(_))));
}

#[test]
fn a_single_point_is_always_the_answer() {
    for index in both(&[1.0, 2.0], 2, &poses(1)) {
        let found = index.nearest(&[4.0, 6.0]).unwrap();
        assert_eq!(
            found,
            Neighbour {
                index: 0,
                pose: poses(1)[0],
                distance_sq: 25.0
            }
        );
        assert_eq!(found.distance(), 5.0);
    }
}

#[test]
fn batch_matches_single_queries() {
    let mut r = rng(6);
    let surface = Manifold::new(32, 0.01, 9);
    let (features, p) = surface.sample(300, &mut r);
    let index = FeatureIndex::build(&features, 32, &p, IndexParams::default()).unwrap();
    let (queries, _) = surface.sample(50, &mut r);
    let batch = index.nearest_batch(&queries).unwrap();
    for (q, b) in queries.chunks_exact(32).zip(&batch) {
        assert_eq!(index.nearest(q).unwrap(), *b);
    }
    let mut out = vec![Neighbour::default(); 49];
    assert!(matches!(
        index.nearest_batch_into(&queries, &mut out),
        Err(EstimateError::Length {
            expected: 50,
            got: 49,
            ..
        })
    ));
    assert!(matches!(
        index.nearest_batch(&queries[..33]),
        Err(EstimateError::Length { .. })
    ));
    // a bad row is named, and nothing is written
    let mut bad = queries.clone();
    bad[3 * 32 + 5] = f32::NAN;
    let mut out = vec![Neighbour::default(); 50];
    match index.nearest_batch_into(&bad, &mut out) {
        Err(EstimateError::NonFinite {
            what: "query",
            index: 3,
            component: 5,
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
    assert!(out.iter().all(|n| *n == Neighbour::default()));
}

#[test]
fn bad_input_is_a_typed_error() {
    let p = IndexParams::default();
    let build = |f: &[f32], dim: usize, n: usize| FeatureIndex::build(f, dim, &poses(n), p);
    assert!(matches!(build(&[], 4, 0), Err(EstimateError::EmptyIndex)));
    assert!(matches!(
        build(&[1.0; 4], 0, 1),
        Err(EstimateError::OutOfRange(e)) if e.name == "feature dimension"
    ));
    assert!(matches!(
        build(&[1.0; 7], 4, 2),
        Err(EstimateError::Length { got: 7, .. })
    ));
    assert!(matches!(
        build(&[1.0; 8], 4, 3),
        Err(EstimateError::Length {
            expected: 2,
            got: 3,
            ..
        })
    ));
    let mut f = [1.0_f32; 8];
    f[6] = f32::INFINITY;
    assert!(matches!(
        build(&f, 4, 2),
        Err(EstimateError::NonFinite {
            what: "feature vector",
            index: 1,
            component: 2,
            ..
        })
    ));
    f[6] = 1e16;
    assert!(matches!(
        build(&f, 4, 2),
        Err(EstimateError::OutOfRange(e)) if e.value == 1e16_f32 as f64
    ));
    let mut bad_pose = poses(2);
    bad_pose[1].translation_mm = f64::NAN;
    assert!(matches!(
        FeatureIndex::build(&[1.0; 8], 4, &bad_pose, p),
        Err(EstimateError::NonFinite {
            what: "pose",
            index: 1,
            component: 1,
            ..
        })
    ));

    let index = build(&[1.0; 8], 4, 2).unwrap();
    assert!(!index.is_empty());
    for q in [&[1.0_f32; 3][..], &[1.0; 5]] {
        for result in [index.nearest(q), index.nearest_linear(q)] {
            assert!(matches!(
                result,
                Err(EstimateError::Length { expected: 4, .. })
            ));
        }
    }
    for v in [f32::NAN, f32::NEG_INFINITY] {
        let q = [0.0, v, 0.0, 0.0];
        for result in [index.nearest(&q), index.nearest_linear(&q)] {
            assert!(matches!(
                result,
                Err(EstimateError::NonFinite {
                    what: "query",
                    component: 1,
                    ..
                })
            ));
        }
    }
    assert!(matches!(
        index.nearest(&[0.0, 0.0, -3e15, 0.0]),
        Err(EstimateError::OutOfRange(_))
    ));
    // errors carry a message a person can act on
    let e = index.nearest(&[1.0; 3]).unwrap_err().to_string();
    assert!(e.contains("expected 4") && e.contains("got 3"), "{e}");
}

#[test]
fn extreme_magnitudes_stay_exact() {
    // values near the limit: distances near f32's top, still finite
    let mut r = rng(7);
    for scale in [1e-30, 1e-12, 1e12, 1e15] {
        let features: Vec<f32> = random_points(200, 16, 0.3, &mut r)
            .iter()
            .map(|x| (f64::from(*x) * scale).clamp(-1e15, 1e15) as f32)
            .collect();
        let queries: Vec<f32> = random_points(200, 16, 0.3, &mut r)
            .iter()
            .map(|x| (f64::from(*x) * scale).clamp(-1e15, 1e15) as f32)
            .collect();
        for index in both(&features, 16, &poses(200)) {
            assert_exact(&index, &queries, "scaled");
        }
    }
}
