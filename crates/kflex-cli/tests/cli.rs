//! End-to-end: the `kflex-cli` binary as a user runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kflex(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kflex-cli"))
        .args(args)
        .output()
        .expect("kflex-cli runs")
}

/// Runs `kflex-cli args`, which must fail with an error naming `needle`, not a panic.
fn assert_refused(args: &[&str], needle: &str) {
    let out = kflex(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} should fail");
    assert!(
        stderr.contains(needle),
        "{args:?}: error should name {needle}: {stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kflex-cli-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn results(dir: &Path) -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(dir.join("results.json")).expect("results.json written");
    serde_json::from_str(&text).expect("results.json is JSON")
}

#[test]
fn run_writes_results_with_the_agreed_fields() {
    let dir = scratch("fields");
    let out = kflex(&[
        "run",
        "--periods",
        "2",
        "--repeats",
        "2",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("RMSE") && stdout.contains("21.90"),
        "table with the paper's figures:\n{stdout}"
    );
    let records = results(&dir);
    assert_eq!(records.len(), 4);
    for (r, sheath) in records.iter().zip([0.0, 90.0, 180.0, 270.0]) {
        for key in [
            "estimator",
            "sheath_deg",
            "occlusion",
            "rmse_deg",
            "rmse_std_deg",
            "max_hysteresis_deg",
            "max_hysteresis_std_deg",
        ] {
            assert!(r.get(key).is_some(), "missing {key} in {r}");
        }
        assert_eq!(r["estimator"], "none");
        assert_eq!(r["occlusion"], "0%");
        assert_eq!(r["sheath_deg"].as_f64(), Some(sheath));
        assert_eq!(r["seeds"].as_array().map(|s| s.len()), Some(2));
        let rmse = r["rmse_deg"].as_f64().unwrap();
        assert!(rmse.is_finite() && rmse > 1.0, "{r}");
        assert!(
            r["rmse_std_deg"].as_f64().unwrap() > 0.0,
            "repeats with spread should differ: {r}"
        );
    }
    let rmse: Vec<f64> = records
        .iter()
        .map(|r| r["rmse_deg"].as_f64().unwrap())
        .collect();
    assert!(
        rmse.windows(2).all(|w| w[1] > w[0]),
        "uncompensated error grows with the sheath bend: {rmse:?}"
    );
    assert!(
        !dir.join(".results.json.tmp").exists(),
        "no temporary file left behind"
    );
}

#[test]
fn same_seed_same_results_other_seed_other_results() {
    let (a, b, c) = (scratch("seed-a"), scratch("seed-b"), scratch("seed-c"));
    for (dir, seed) in [(&a, "7"), (&b, "7"), (&c, "8")] {
        let out = kflex(&[
            "run",
            "--sheath",
            "90",
            "--periods",
            "1",
            "--seed",
            seed,
            "--out",
            dir.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert_eq!(results(&a), results(&b));
    assert_ne!(results(&a)[0]["rmse_deg"], results(&c)[0]["rmse_deg"]);
}

#[test]
fn bad_input_is_a_clear_error_and_keeps_old_results() {
    let dir = scratch("bad");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("results.json"), "[\"previous\"]").unwrap();
    let d = dir.to_str().unwrap();
    for (args, needle) in [
        (vec!["run", "--periods", "-1", "--out", d], "periods"),
        (vec!["run", "--periods", "nan", "--out", d], "periods"),
        (vec!["run", "--sheath", "-90", "--out", d], "sheath_deg"),
        (vec!["run", "--dt", "0", "--out", d], "dt_s"),
        (vec!["run", "--repeats", "0", "--out", d], "repeats"),
        (vec!["run", "--estimator", "kbjae", "--out", d], "kbjae"),
        (
            vec!["run", "--config", "/nonexistent/plant.json", "--out", d],
            "/nonexistent/plant.json",
        ),
    ] {
        assert_refused(&args, needle);
    }
    assert_eq!(
        std::fs::read_to_string(dir.join("results.json")).unwrap(),
        "[\"previous\"]"
    );
}

#[test]
fn config_file_changes_the_plant() {
    let dir = scratch("config");
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("plant.json");
    // a frictionless sheath and no backlash: the loop nearly closes
    std::fs::write(
        &config,
        r#"{"sheath": {"friction_coefficient": 0.0, "coulomb_friction_n": 0.0, "drive_backlash_mm": 0.0}}"#,
    )
    .unwrap();
    let out = kflex(&[
        "run",
        "--sheath",
        "270",
        "--periods",
        "1",
        "--repeats",
        "1",
        "--no-noise",
        "--spread",
        "0",
        "--config",
        config.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let width = results(&dir)[0]["max_hysteresis_deg"].as_f64().unwrap();
    assert!(width < 1.0, "no friction, no loop: {width}");
    std::fs::write(&config, r#"{"sheath": {"friction_coefficient": -1.0}}"#).unwrap();
    let out = kflex(&["run", "--config", config.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("friction_coefficient"));
}

#[test]
fn render_writes_the_pngs_and_rejects_bad_input() {
    let dir = scratch("render");
    let d = dir.to_str().unwrap();
    let out = kflex(&[
        "render",
        "--theta",
        "30",
        "--d",
        "10",
        "--background",
        "stomach",
        "--occlusion",
        "0.4",
        "--out",
        d,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("IoU"));
    for name in [
        "frame.png",
        "silhouette_48.png",
        "instrument_mask.png",
        "occluder_mask.png",
        "segmentation_48.png",
    ] {
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(&bytes[1..4], b"PNG", "{name} is a PNG");
    }
    let leftovers = std::fs::read_dir(&dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".tmp.png")
        })
        .count();
    assert_eq!(leftovers, 0);
    for (args, needle) in [
        (vec!["render", "--background", "gut", "--out", d], "gut"),
        (vec!["render", "--theta", "150", "--out", d], "theta_deg"),
        (vec!["render", "--d", "-5", "--out", d], "translation_mm"),
        (
            vec!["render", "--occlusion", "1.5", "--out", d],
            "occlusion.fraction",
        ),
    ] {
        assert_refused(&args, needle);
    }
}
