//! IBJAE's image-pair set D^I and its database: labels, balance, hard
//! negatives, determinism whatever the thread count, errors.

use kflex_control::{ControlError, ImagePairsConfig};
use kflex_model::{Camera, PoseRange, WorkingRegions};

const PIXELS: usize = 48 * 48;

fn small(pairs: usize) -> ImagePairsConfig {
    ImagePairsConfig {
        pairs,
        block: 4,
        ..ImagePairsConfig::default()
    }
}

#[test]
fn pairs_are_balanced_labelled_by_grid_cell_and_have_hard_negatives() {
    let config = small(64);
    let p = config.generate(0).unwrap();
    assert_eq!(p.x_b.len(), 64 * PIXELS);
    assert_eq!(p.x_r.len(), 64 * PIXELS);
    assert_eq!(p.s.iter().filter(|&&s| s == 1).count(), 32);
    let regions = WorkingRegions::full(&Camera::default()).unwrap();
    for i in 0..64 {
        let dt = (p.theta_b_deg[i] - p.theta_r_deg[i]).abs();
        let dd = (p.translation_b_mm[i] - p.translation_r_mm[i]).abs();
        let same = dt <= config.theta_step_deg / 2.0 + 1e-9
            && dd <= config.translation_step_mm / 2.0 + 1e-9;
        assert_eq!(p.s[i] == 1, same, "pair {i}: Δθ {dt}, Δd {dd}");
        assert!(PoseRange::FULL.contains(p.theta_b_deg[i], p.translation_b_mm[i]));
        // the query is read in its own band
        let band = regions.at(p.theta_b_deg[i], p.translation_b_mm[i]).unwrap();
        assert_eq!(band, &regions.bands()[p.band[i] as usize]);
        // both silhouettes show something, and x^b is binary
        let x_b = &p.x_b[i * PIXELS..(i + 1) * PIXELS];
        let x_r = &p.x_r[i * PIXELS..(i + 1) * PIXELS];
        assert!(x_b.iter().all(|&v| v <= 1) && x_b.contains(&1), "pair {i}");
        assert!(x_r.contains(&1), "pair {i}");
        if p.hard[i] == 1 {
            assert_eq!(p.s[i], 0);
            assert_eq!(p.translation_r_mm[i], p.translation_b_mm[i].round());
            let off = (p.theta_r_deg[i] - p.theta_b_deg[i].round()).abs();
            assert!((2.0..=5.0).contains(&off), "hard offset {off}");
        }
    }
    // pairs 2q and 2q + 1 share the query's frame
    assert_eq!(p.x_b[..PIXELS], p.x_b[PIXELS..2 * PIXELS]);
    assert_eq!(p.query[..4], [0, 0, 1, 1]);
    let hard = p.hard.iter().filter(|&&h| h == 1).count();
    assert!((8..=24).contains(&hard), "hard negatives {hard} of 32");
    assert_eq!(p.card.stats["hard_negatives"], hard as f64);
    assert_eq!(p.card.sizes["x_b"], [64, 48, 48]);
    // the silhouettes of a positive pair agree far more than a negative's
    let agree = |i: usize| {
        p.x_b[i * PIXELS..(i + 1) * PIXELS]
            .iter()
            .zip(&p.x_r[i * PIXELS..(i + 1) * PIXELS])
            .filter(|(a, b)| a == b)
            .count() as f64
    };
    let mean = |s: u8| {
        let idx: Vec<usize> = (0..64).filter(|&i| p.s[i] == s && p.hard[i] == 0).collect();
        idx.iter().map(|&i| agree(i)).sum::<f64>() / idx.len() as f64
    };
    assert!(mean(1) > mean(0), "{} vs {}", mean(1), mean(0));
}

#[test]
fn same_seed_same_pairs_whatever_the_threads() {
    let a = small(24).generate(1).unwrap();
    let b = small(24).generate(2).unwrap();
    assert_eq!(a, b);
    let c = ImagePairsConfig {
        seed: 7,
        ..small(24)
    }
    .generate(2)
    .unwrap();
    assert_ne!(a.theta_b_deg, c.theta_b_deg);
}

#[test]
fn the_database_covers_every_band_on_the_grid() {
    let config = ImagePairsConfig {
        poses: PoseRange {
            theta_deg: [0.0, 20.0],
            translation_mm: [10.0, 12.0],
        },
        ..small(2)
    };
    let db = config.database(0).unwrap();
    let n = db.theta_deg.len();
    assert_eq!(db.masks.len(), n * PIXELS);
    assert!(
        db.theta_deg
            .iter()
            .all(|t| t.fract() == 0.0 && (0.0..=20.0).contains(t))
    );
    // two overlapping halves of the bend range, each over d = 10, 11, 12 (or its bands)
    assert!(n >= 21 * 3, "{n}");
    assert_eq!(db.card.sizes["masks"], [n, 48, 48]);
    assert_eq!(db, config.database(1).unwrap());
}

#[test]
fn bad_settings_are_refused() {
    let err = small(3).generate(1).unwrap_err();
    assert!(
        matches!(err, ControlError::NotEnoughData { got: 3, .. }),
        "{err:?}"
    );
    let bad = ImagePairsConfig {
        theta_step_deg: 2.0,
        ..small(2)
    };
    assert_eq!(
        bad.generate(1).unwrap_err().range().unwrap().name,
        "theta_step_deg"
    );
    let bad = ImagePairsConfig {
        hard_offset_deg: [5.0, 2.0],
        ..small(2)
    };
    assert_eq!(
        bad.validate().unwrap_err().range().unwrap().name,
        "hard_offset_deg"
    );
    let bad = ImagePairsConfig {
        backgrounds: vec![],
        ..small(2)
    };
    assert_eq!(
        bad.validate().unwrap_err().range().unwrap().name,
        "backgrounds.len()"
    );
}
