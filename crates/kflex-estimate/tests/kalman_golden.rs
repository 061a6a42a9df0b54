//! The paper's filter against filterpy's `KalmanFilter` on the same sequences
//! (`tools/golden/kalman_golden.py` writes `tests/data/kalman_*.csv`; pytest
//! checks that the stored files are what filterpy computes).

use kflex_estimate::{FilterRate, Fusion, KalmanParams, Measurements, PaperKalman, SensorUse};

struct Row {
    z1: Option<f64>,
    z2: Option<f64>,
    state: [f64; 5],
}

fn read(name: &str) -> Vec<Row> {
    let path = format!(
        "{}/tests/data/kalman_{name}.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .skip(1)
        .map(|line| {
            let cells: Vec<Option<f64>> = line
                .split(',')
                .map(|c| (!c.is_empty()).then(|| c.parse().expect("a number")))
                .collect();
            let v = |i: usize| cells[i].expect("state columns are never empty");
            Row {
                z1: cells[1],
                z2: cells[2],
                state: [v(3), v(4), v(5), v(6), v(7)],
            }
        })
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + b.abs())
}

fn check(name: &str, params: KalmanParams, tick_s: f64) {
    let rows = read(name);
    assert!(rows.len() >= 500, "{name}: {} rows", rows.len());
    let mut kf = PaperKalman::new(params).unwrap();
    let mut held = 0;
    for (i, row) in rows.iter().enumerate() {
        let e = kf
            .step(
                tick_s,
                Measurements {
                    kbjae_deg: row.z1,
                    ibjae_deg: row.z2,
                    ibjae_sigma_deg: None,
                    ibjae_occluded: false,
                },
            )
            .unwrap();
        let got = [
            e.theta_hat_deg,
            e.theta_hat_rate_deg_per_s,
            e.covariance[0][0],
            e.covariance[0][1],
            e.covariance[1][1],
        ];
        for (g, want) in got.iter().zip(&row.state) {
            assert!(
                close(*g, *want),
                "{name} tick {i}: {got:?} against filterpy {:?}",
                row.state
            );
        }
        assert_eq!(e.covariance[0][1], e.covariance[1][0]);
        match e.ibjae {
            SensorUse::Held => held += 1,
            SensorUse::Used => assert!(row.z2.is_some()),
            SensorUse::Missing => assert!(row.z2.is_none()),
            other => panic!("{other:?}"),
        }
    }
    if params.rate == FilterRate::AsWritten {
        assert_eq!(
            held,
            rows.len() - rows.len() / 10,
            "{name}: steps every 10th tick"
        );
    } else {
        assert_eq!(held, 0);
    }
}

#[test]
fn paper_filter_as_run_equals_filterpy() {
    check("paper_as_run", KalmanParams::default(), 0.01);
}

#[test]
fn a_looser_filter_equals_filterpy() {
    let params = KalmanParams {
        model_dt_s: 0.05,
        sigma_a: 2.0,
        sigma_z_deg: [1.5, 3.0],
        ..KalmanParams::default()
    };
    check("loose_as_run", params, 0.02);
}

#[test]
fn paper_filter_as_written_equals_filterpy_stepped_every_tenth_tick() {
    let params = KalmanParams {
        rate: FilterRate::AsWritten,
        ..KalmanParams::default()
    };
    check("paper_as_written", params, 0.01);
}
