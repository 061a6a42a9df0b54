//! The ends of the plant's parameter ranges that the tendon solve found
//! hard run the paper's protocol (what `kflex-cli run --periods 1
//! --repeats 1` runs: a perturbed repeat with the Aurora-like noise): the
//! floors at the paper's four sheath angles, with the configuration just
//! past them refused by name, the other ends at 270 deg. Values the ranges
//! accepted stopped at 270 deg with "the joint simulation diverged (tendon
//! element balance)", naming no parameter, until the tendon solve learnt to
//! solve the whole chain at once where shooting from the anchor is too
//! steep.

use kflex_control::{OpenLoopGrid, OpenLoopScenario};
use kflex_model::{Plant, PlantConfig};

/// One repeat of one period at each of the paper's sheath angles; every
/// row's figures finite.
fn runs(plant: PlantConfig, what: &str) {
    runs_at(plant, what, OpenLoopGrid::default().sheaths_deg);
}

/// One repeat of one period at 270 deg only (the slowest parameters; the
/// bend where the tendon solve is hardest).
fn runs_at_270(plant: PlantConfig, what: &str) {
    runs_at(plant, what, vec![270.0]);
}

/// One repeat of one period at each of `sheaths_deg`; every row's figures finite.
fn runs_at(plant: PlantConfig, what: &str, sheaths_deg: Vec<f64>) {
    let count = sheaths_deg.len();
    let grid = OpenLoopGrid {
        plant,
        scenario: OpenLoopScenario {
            periods: 1.0,
            ..OpenLoopScenario::default()
        },
        sheaths_deg,
        repeats: 1,
        ..OpenLoopGrid::default()
    };
    let rows = grid.run().unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(rows.len(), count, "{what}");
    for row in rows {
        assert!(
            row.rmse_deg.mean.is_finite() && row.max_hysteresis_deg.mean.is_finite(),
            "{what} at {} deg",
            row.sheath_deg
        );
    }
}

/// The pre-sliding displacement from 0.01 µm. The shooting tendon solve
/// alone stopped below 3 µm (at 1 µm its march from the anchor was too
/// steep for any `f64` tension to land the proximal end within 2.4 µm):
/// the floor was 3 µm until the whole chain was solved at once.
#[test]
fn the_smallest_presliding_runs_the_paper_protocol() {
    for presliding_mm in [1e-5, 1e-3] {
        let mut plant = PlantConfig::default();
        plant.sheath.presliding_mm = presliding_mm;
        runs(plant, &format!("presliding {presliding_mm} mm"));
    }
    let mut plant = PlantConfig::default();
    plant.sheath.presliding_mm = 0.9e-5;
    let e = Plant::new(plant).unwrap_err().to_string();
    assert!(e.contains("presliding_mm"), "{e}");
}

/// The softest tendon, 0.001 N/mm (a ten-thousandth of the default steel
/// one). The shooting solve alone stopped at 270 deg below 1 N/mm, the
/// floor until the whole chain was solved at once.
#[test]
fn the_softest_tendon_runs_the_paper_protocol() {
    let mut plant = PlantConfig::default();
    plant.sheath.tendon_stiffness_n_per_mm = 1e-3;
    runs(plant, "tendon 0.001 N/mm");
    plant.sheath.tendon_stiffness_n_per_mm = 0.9e-3;
    let e = Plant::new(plant).unwrap_err().to_string();
    assert!(e.contains("tendon_stiffness_n_per_mm"), "{e}");
}

/// The far ends of three ranges the shooting solve alone could not run:
/// 50 N of pretension and more (each element's friction stiffer than the
/// tendon beside it), paths that lengthen with the bend from +0.5 mm/rad,
/// a distal run of 0.001 N/mm. Each stopped with "diverged (tendon element
/// balance)".
#[test]
fn the_stiffest_friction_longest_path_and_softest_distal_run_the_protocol() {
    let mut plant = PlantConfig::default();
    plant.sheath.pretension_n = 1000.0;
    runs_at_270(plant, "pretension 1000 N");
    let mut plant = PlantConfig::default();
    plant.sheath.sheath_path_mm_per_rad = 1.0;
    runs_at_270(plant, "path +1 mm/rad");
    let mut plant = PlantConfig::default();
    plant.sheath.distal_stiffness_n_per_mm = 1e-3;
    runs_at_270(plant, "distal run 0.001 N/mm");
}
