//! Bouc–Wen against an independent high-accuracy integration: scipy's
//! `solve_ivp` (DOP853, rtol 1e-11) of the time-domain ODE, stored as CSV by
//! `tools/golden/bouc_wen_golden.py` (which `tests/python` re-checks).
//! The operator is driven by the same input samples; it integrates in the input
//! increment, so this also checks that form against the time-domain one.

use kflex_model::{BoucWen, BoucWenParams};

struct Golden {
    params: BoucWenParams,
    x: Vec<f64>,
    z: Vec<f64>,
}

fn load(case: &str) -> Golden {
    let path = format!(
        "{}/tests/data/bouc_wen_{case}.csv",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut lines = text.lines();
    let header = lines.next().expect("parameter line");
    let value = |key: &str| -> f64 {
        let start = header
            .find(&format!("{key}="))
            .unwrap_or_else(|| panic!("{key} in {header}"))
            + key.len()
            + 1;
        let rest = &header[start..];
        let end = rest.find([',', ' ']).unwrap_or(rest.len());
        rest[..end].parse().unwrap_or_else(|e| panic!("{key}: {e}"))
    };
    let params = BoucWenParams {
        a: value("A"),
        beta: value("beta"),
        gamma: value("gamma"),
        n: value("n"),
        alpha: 0.0,
    };
    assert_eq!(lines.next(), Some("t,x,z"));
    let (mut x, mut z) = (Vec::new(), Vec::new());
    for line in lines.filter(|l| !l.trim().is_empty()) {
        let cols: Vec<f64> = line
            .split(',')
            .map(|c| c.trim().parse().expect("number"))
            .collect();
        x.push(cols[1]);
        z.push(cols[2]);
    }
    Golden { params, x, z }
}

fn max_error(case: &str) -> f64 {
    let g = load(case);
    let mut bw = BoucWen::new(g.params, g.x[0]).unwrap();
    assert_eq!(g.z[0], 0.0);
    g.x.iter()
        .zip(&g.z)
        .map(|(&x, &z)| (bw.advance(x).unwrap() - z).abs())
        .fold(0.0, f64::max)
}

#[test]
fn n1_cases_match_to_solver_precision() {
    // n = 1 is integrated exactly
    for case in ["n1_sym", "n1_small"] {
        let err = max_error(case);
        eprintln!("{case}: max abs error {err:e}");
        assert!(err < 1e-9, "{case}: max |z - golden| = {err:e}");
    }
}

#[test]
fn non_integer_and_quadratic_n_match_closely() {
    // other n: RK4 sub-steps of 0.4 % of the saturation length
    for case in ["n2", "n1p5_soft"] {
        let err = max_error(case);
        eprintln!("{case}: max abs error {err:e}");
        assert!(err < 1e-7, "{case}: max |z - golden| = {err:e}");
    }
}
