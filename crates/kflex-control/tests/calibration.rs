//! The shipped defaults reproduce Table IX's uncompensated row within the
//! calibration's tolerances: RMSE ±20 % and maximum hysteresis size (the
//! loop width) ±30 % at 0, 90 and 180 deg; ±25 % and ±40 % at 270 deg, on
//! the nominal plant and as the shipped protocol's mean over three perturbed
//! repeats.

use kflex_control::OpenLoopGrid;

const RMSE: [f64; 4] = [7.84, 9.95, 16.6, 21.9];
const WIDTH: [f64; 4] = [9.23, 15.1, 18.3, 18.4];
const RMSE_TOL: [f64; 4] = [0.20, 0.20, 0.20, 0.25];
const WIDTH_TOL: [f64; 4] = [0.30, 0.30, 0.30, 0.40];

fn check(grid: OpenLoopGrid, width_tol: [f64; 4]) {
    let rows = grid.run().unwrap();
    for (i, row) in rows.iter().enumerate() {
        let (r, w) = (row.rmse_deg.mean, row.max_hysteresis_deg.mean);
        assert!(
            (r / RMSE[i] - 1.0).abs() <= RMSE_TOL[i],
            "sheath {}: RMSE {r:.2} vs paper {}",
            row.sheath_deg,
            RMSE[i]
        );
        assert!(
            (w / WIDTH[i] - 1.0).abs() <= width_tol[i],
            "sheath {}: width {w:.2} vs paper {}",
            row.sheath_deg,
            WIDTH[i]
        );
    }
    // and the RMSE's ordering the paper shows: it grows with the bend
    assert!(
        rows.windows(2)
            .all(|w| w[1].rmse_deg.mean > w[0].rmse_deg.mean)
    );
    // the paper's widths grow too (9.2 to 18.4 deg); the plant's loops are
    // wider at every bend than straight (CALIBRATION.md: they grow at every
    // 15 deg up to 180 deg, then stay within 10 % of their largest;
    // `plant_fidelity.rs` checks that)
    for k in 1..4 {
        assert!(rows[k].max_hysteresis_deg.mean > rows[0].max_hysteresis_deg.mean);
    }
}

#[test]
fn nominal_plant_matches_table_ix_none_row() {
    check(
        OpenLoopGrid {
            repeats: 1,
            spread: 0.0,
            noise: None,
            ..OpenLoopGrid::default()
        },
        WIDTH_TOL,
    );
}

#[test]
fn the_cli_protocol_matches_table_ix_none_row() {
    // what `kflex-cli run` does by default: three repeats with spread and Aurora-like noise
    check(OpenLoopGrid::default(), WIDTH_TOL);
}
