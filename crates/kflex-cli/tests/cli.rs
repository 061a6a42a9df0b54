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
            "error_peak_to_peak_deg",
            "peak_loss_deg",
            "peak_loss_std_deg",
        ] {
            assert!(r.get(key).is_some(), "missing {key} in {r}");
        }
        // three readings of "maximum hysteresis": the loop width cannot exceed the
        // error's peak-to-peak by more than a 1-deg bin (the gap between the branches
        // at equal command is a difference of two errors)
        let width = r["max_hysteresis_deg"].as_f64().unwrap();
        let p2p = r["error_peak_to_peak_deg"].as_f64().unwrap();
        let loss = r["peak_loss_deg"].as_f64().unwrap();
        assert!(width > 0.0 && width <= p2p + 1.0, "{r}");
        assert!(
            loss > 0.0 && loss < 50.0,
            "the lagging joint falls short of the peak: {r}"
        );
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
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(
        leftovers.is_empty(),
        "temporary files left behind: {leftovers:?}"
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
        r#"{"sheath": {"friction_coefficient": 0.0, "drive_backlash_mm": 0.0}}"#,
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
        "--tissue",
        "yellow",
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
        (vec!["render", "--tissue", "purple", "--out", d], "purple"),
        (vec!["render", "--theta", "150", "--out", d], "theta_deg"),
        (vec!["render", "--d", "-5", "--out", d], "translation_mm"),
        (
            vec!["render", "--occlusion", "1.5", "--out", d],
            "occlusion.fraction",
        ),
        // checked without tape too
        (
            vec!["render", "--occlusion-position", "2", "--out", d],
            "--occlusion-position",
        ),
    ] {
        assert_refused(&args, needle);
    }
    // an --out that cannot be written fails before the rendering
    let file = dir.join("frame.png");
    let under = file.join("out");
    assert_refused(
        &["render", "--out", under.to_str().unwrap()],
        "cannot be written (checked before running)",
    );
}

/// A short run: one period, one repeat, one sheath angle, plus `args`.
fn short_run(args: &[&str]) -> Output {
    let mut all = vec!["run", "--periods", "1", "--repeats", "1", "--sheath", "0"];
    all.extend_from_slice(args);
    kflex(&all)
}

fn stdout_of(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn config_file_is_toml_or_json_by_extension_or_content() {
    let dir = scratch("formats");
    std::fs::create_dir_all(&dir).unwrap();
    let toml = "seed = 7\n\n[joint]\ncontact_stiffness_nmm_per_rad = 500.0\n\n[geometry]\nn_segments = 2\n";
    let json = r#"{"seed": 7, "joint": {"contact_stiffness_nmm_per_rad": 500.0}, "geometry": {"n_segments": 2}}"#;
    let mut rmse = Vec::new();
    for (name, text) in [
        ("plant.toml", toml),
        ("plant.json", json),
        ("plant-toml.cfg", toml), // by content
        ("plant-json.cfg", json),
        ("default.toml", ""), // an empty file: every field its default
    ] {
        let config = dir.join(name);
        std::fs::write(&config, text).unwrap();
        let out_dir = dir.join(format!("out-{name}"));
        stdout_of(&short_run(&[
            "--no-noise",
            "--spread",
            "0",
            "--config",
            config.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ]));
        rmse.push(results(&out_dir)[0]["rmse_deg"].as_f64().unwrap());
    }
    // the four spellings of one configuration agree, and it is not the default
    assert!(rmse[..4].iter().all(|&r| r == rmse[0]), "{rmse:?}");
    assert_ne!(rmse[0], rmse[4], "the stiffness was read: {rmse:?}");
}

#[test]
fn config_errors_name_the_file_the_line_and_the_field() {
    let dir = scratch("config-errors");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text, needles) in [
        (
            "typo.toml",
            "seed = 7\nfrictoin_coefficient = 0.1\n",
            &[
                "typo.toml",
                "line 2",
                "unknown field `frictoin_coefficient`",
            ][..],
        ),
        (
            "type.toml",
            "seed = 7\n\n[joint]\ncontact_stiffness_nmm_per_rad = \"stiff\"\n",
            &[
                "type.toml",
                "line 4",
                "field `joint.contact_stiffness_nmm_per_rad`",
                "invalid type",
            ][..],
        ),
        (
            "type.json",
            "{\"seed\": 7,\n \"geometry\": {\"n_segments\": \"two\"}}",
            &[
                "type.json",
                "line 2",
                "field `geometry.n_segments`",
                "invalid type",
            ][..],
        ),
        (
            "typo.json",
            "{\"seed\": 7,\n\n \"frictoin_coefficient\": 0.1}",
            &[
                "typo.json",
                "line 3",
                "unknown field `frictoin_coefficient`",
            ][..],
        ),
        (
            "syntax.toml",
            "seed = 7\nsheath_deg = \n",
            &["syntax.toml", "line 2"][..],
        ),
        (
            "syntax.json",
            "{\"seed\": 7,\n}",
            &["syntax.json", "line 2"][..],
        ),
    ] {
        let config = dir.join(name);
        std::fs::write(&config, text).unwrap();
        for needle in needles {
            assert_refused(&["run", "--config", config.to_str().unwrap()], needle);
        }
    }
}

#[test]
fn flags_that_override_the_config_file_say_so() {
    let dir = scratch("overrides");
    std::fs::create_dir_all(&dir).unwrap();
    let config = dir.join("plant.toml");
    std::fs::write(
        &config,
        "sheath_deg = 45\nseed = 7\njoint_model = \"analytic\"\n",
    )
    .unwrap();
    let path = config.to_str().unwrap();
    let stdout = stdout_of(&short_run(&["--config", path]));
    for note in [
        format!("note: --sheath 0 overrides sheath_deg = 45 from {path}"),
        format!("note: --seed 2020 (the default) overrides seed = 7 from {path}"),
        format!(
            "note: --joint analytic (the default) overrides joint_model = \"analytic\" from {path}"
        ),
    ] {
        assert!(stdout.contains(&note), "{note}:\n{stdout}");
    }
    // the notes are in the header, before the table
    assert!(stdout.find("note:") < stdout.find("RMSE"), "{stdout}");
    // given flags are not called defaults
    let stdout = stdout_of(&short_run(&["--config", path, "--seed", "3"]));
    assert!(
        stdout.contains(&format!("note: --seed 3 overrides seed = 7 from {path}")),
        "{stdout}"
    );
    // JSON too, and the noise
    let config = dir.join("plant.json");
    std::fs::write(&config, r#"{"sheath_deg": 45, "noise": null}"#).unwrap();
    let path = config.to_str().unwrap();
    let stdout = stdout_of(&short_run(&["--config", path, "--no-noise"]));
    assert!(
        stdout.contains(&format!(
            "note: --sheath 0 overrides sheath_deg = 45 from {path}"
        )) && stdout.contains(&format!(
            "note: --no-noise overrides noise = null from {path}"
        )),
        "{stdout}"
    );
    // a spread draws each repeat's seating: the file's is replaced, and said
    let config = dir.join("seated.toml");
    std::fs::write(&config, "[seating]\nbacklash = 1.0\n").unwrap();
    let path = config.to_str().unwrap();
    let stdout = stdout_of(&short_run(&["--config", path]));
    assert!(
        stdout.contains("note: --spread 0.15 (the default) overrides seating = ")
            && stdout.contains(&format!("from {path} (each repeat draws its own)")),
        "{stdout}"
    );
    // without a spread the file's seating stays: no note
    let stdout = stdout_of(&short_run(&["--config", path, "--spread", "0"]));
    assert!(!stdout.contains("seating"), "{stdout}");
    // a spread given is not called the default
    let stdout = stdout_of(&short_run(&["--config", path, "--spread", "0.3"]));
    assert!(
        stdout.contains("note: --spread 0.3 overrides seating = "),
        "{stdout}"
    );
    // a seating the spread replaces is not checked; one that stays is
    let config = dir.join("bad-seating.toml");
    std::fs::write(&config, "[seating]\nbacklash = 5.0\n").unwrap();
    let path = config.to_str().unwrap();
    stdout_of(&short_run(&["--config", path]));
    let out = short_run(&["--config", path, "--spread", "0"]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("seating.backlash") && stderr.contains(path),
        "{stderr}"
    );
    // fields no flag replaces: no notes
    let config = dir.join("quiet.toml");
    std::fs::write(&config, "[geometry]\nn_segments = 2\n").unwrap();
    let stdout = stdout_of(&short_run(&["--config", config.to_str().unwrap()]));
    assert!(!stdout.contains("note:"), "{stdout}");
    // a value a flag replaces is not checked (nor blamed on the flag); one
    // that stays is, naming the file
    let config = dir.join("replaced.toml");
    std::fs::write(&config, "sheath_deg = 5000\n[noise]\ntheta_std_deg = -1\n").unwrap();
    let path = config.to_str().unwrap();
    let stdout = stdout_of(&short_run(&["--config", path]));
    assert!(
        stdout.contains(&format!(
            "note: --sheath 0 overrides sheath_deg = 5000 from {path}"
        )),
        "{stdout}"
    );
    let config = dir.join("kept.toml");
    std::fs::write(&config, "[sheath]\nfriction_coefficient = 5.0\n").unwrap();
    let path = config.to_str().unwrap();
    assert_refused(&["run", "--config", path], path);
    assert_refused(&["run", "--config", path], "friction_coefficient");
}

#[test]
fn too_short_or_too_coarse_runs_name_the_flag() {
    for (args, needles) in [
        (
            &["--periods", "0.01"][..],
            &[
                "--periods 0.01",
                "too short for a hysteresis loop",
                "--periods 1 or more",
            ][..],
        ),
        // so short that no sample is left
        (&["--periods", "0.0001"][..], &["--periods 0.0001"][..]),
        (
            &["--periods", "1", "--dt", "9"][..],
            &["--dt 9", "too coarse"][..],
        ),
        (&["--dt", "0"][..], &["--dt 0", "dt_s"][..]),
        (&["--dt", "11"][..], &["--dt 11"][..]),
        (
            &["--dt", "1e-9"][..],
            &["--dt 1e-9", "too many samples"][..],
        ),
        (&["--dt", "inf"][..], &["--dt inf"][..]),
    ] {
        let mut all = vec!["run", "--repeats", "1", "--sheath", "0"];
        all.extend_from_slice(args);
        for needle in needles {
            assert_refused(&all, needle);
        }
    }
}

#[test]
fn a_spread_outside_its_range_is_refused_naming_the_flag() {
    // it used to run as 0 (identical plants) for a negative or NaN spread
    for spread in ["-0.1", "NaN", "0.6"] {
        let out = short_run(&["--spread", spread]);
        assert!(!out.status.success(), "--spread {spread} was accepted");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("--spread {spread}")) && err.contains("[0, 0.5]"),
            "{err}"
        );
    }
}

/// `render --hd` segments in the working region of the HD camera itself.
#[test]
fn render_hd_segments_in_its_own_region() {
    let dir = scratch("render-hd");
    let d = dir.to_str().unwrap();
    let out = kflex(&["render", "--hd", "--out", d]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("segmentation: IoU"), "{stdout}");
    // the region named lies inside 1920×1080
    let line = stdout
        .lines()
        .find(|l| l.starts_with("region of interest"))
        .expect("region line");
    let nums: Vec<u32> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().unwrap())
        .collect();
    let [w, h, x0, y0] = nums[..] else {
        panic!("{line}")
    };
    assert!(x0 + w <= 1920 && y0 + h <= 1080, "{line}");
    assert!(dir.join("segmentation_48.png").exists());
}

/// A frame with nothing to segment: the frame is written (it is what was
/// asked), then a clear non-zero error naming the cause, not "no
/// instrument" with exit code 0; no segmentation file is left. Fully taped,
/// the renderer says so before the segmentation runs; under noise of σ 1
/// on the [0, 1] image the segmentation itself finds nothing. Rendered into
/// a folder that holds an earlier render's files, the failing render leaves
/// no segmentation of the earlier frame beside its own frame.
#[test]
fn a_frame_with_nothing_to_segment_is_an_error() {
    for (name, flag, value, cause) in [
        (
            "render-taped",
            "--occlusion",
            "1.0",
            "no visible instrument in the region of interest",
        ),
        (
            "render-noise",
            "--noise",
            "1",
            "segmentation: no instrument found",
        ),
    ] {
        let dir = scratch(name);
        let d = dir.to_str().unwrap();
        let earlier = kflex(&["render", "--out", d]);
        assert!(earlier.status.success(), "{name}: the earlier render");
        let earlier_frame = std::fs::read(dir.join("frame.png")).unwrap();
        for file in ["segmentation_roi.png", "segmentation_48.png"] {
            assert!(dir.join(file).exists(), "{name}: the earlier {file}");
        }
        assert_refused(&["render", flag, value, "--out", d], cause);
        let frame = std::fs::read(dir.join("frame.png")).unwrap();
        assert_ne!(
            frame, earlier_frame,
            "{name}: the failing render's frame is written"
        );
        for file in ["segmentation_roi.png", "segmentation_48.png"] {
            assert!(!dir.join(file).exists(), "{name}: {file}");
        }
        // no temporary file is left either
        for entry in std::fs::read_dir(&dir).unwrap() {
            let name = entry.unwrap().file_name();
            assert!(!name.to_string_lossy().contains(".tmp"), "{name:?}");
        }
    }
}

/// Runs `kflex-cli run --scenario FILE ARGS… --out DIR`, which must succeed.
fn run_scenario(file: &str, args: &[&str], out_dir: &str) -> Output {
    let mut all = vec!["run", "--scenario", file];
    all.extend_from_slice(args);
    all.extend_from_slice(&["--out", out_dir]);
    let out = kflex(&all);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A small scenario: Table IX at 90 deg and Table VIII at 40 % tape, one
/// period, two repeats.
const SMALL_SCENARIO: &str = r#"
estimators = ["none"]
repeats = 2
seed = 7

[[cases]]
table = "IX"
kind = "compensation"
sheath_deg = 90.0
occlusion = "0%"

[[cases]]
table = "VIII"
kind = "compensation"
sheath_deg = 0.0
occlusion = "40%"

[scenario.motion]
periods = 1.0
"#;

fn scenario_file(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("small.toml");
    std::fs::write(&path, SMALL_SCENARIO).unwrap();
    path
}

/// A value out of range in a scenario file is named with the file's line
/// that sets it, before any work (no output folder is made).
#[test]
fn a_value_out_of_range_names_its_line_in_the_scenario() {
    let dir = scratch("range-line");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.toml");
    let out = dir.join("out");
    let scenario = |repeats: &str, sheath: &str, periods: &str| {
        format!(
            "repeats = {repeats}\n[[cases]]\ntable = \"IX\"\nkind = \"compensation\"\n\
             sheath_deg = {sheath}\nocclusion = \"0%\"\n[scenario.motion]\nperiods = {periods} # one\n"
        )
    };
    for (text, needle) in [
        (
            scenario("0", "90.0", "1.0"),
            "bad.toml, line 1: repeats = 0",
        ),
        (
            scenario("1", "90.0", "-1.0"),
            "bad.toml, line 8: periods = -1",
        ),
        (
            scenario("1", "50_000.0", "1.0"),
            "bad.toml, line 5: case 1 (IX_50000deg_0pct): sheath_deg = 50000",
        ),
    ] {
        std::fs::write(&file, text).unwrap();
        let args = [
            "run",
            "--scenario",
            file.to_str().unwrap(),
            "--estimators",
            "none",
            "--out",
            out.to_str().unwrap(),
        ];
        assert_refused(&args, needle);
        assert!(!out.exists(), "{} made", out.display());
    }
}

/// A rerun into the same folder says which logs and figures there are not
/// its own (an earlier run's, of other cases), and leaves them.
#[test]
fn a_rerun_names_the_files_an_earlier_run_left() {
    let dir = scratch("rerun");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let (f, o) = (file.to_str().unwrap(), out_dir.to_str().unwrap());
    let first = stdout_of(&run_scenario(f, &["--mcap"], o));
    assert!(!first.contains("did not write"), "{first}");
    let earlier = out_dir.join("runs").join("VI_90deg_0pct_none_seed7.mcap");
    std::fs::write(&earlier, b"an earlier run's log").unwrap();
    let figures = out_dir.join("plots");
    let figure = figures.join("table_VI_rmse.svg");
    if figures.is_dir() {
        std::fs::write(&figure, b"<svg/>").unwrap();
    }
    let again = stdout_of(&run_scenario(f, &["--mcap"], o));
    assert!(
        again.contains("also holds 1 file of MCAP logs that this run did not write")
            && again.contains("VI_90deg_0pct_none_seed7.mcap"),
        "{again}"
    );
    assert_eq!(std::fs::read(&earlier).unwrap(), b"an earlier run's log");
    if figures.is_dir() {
        assert!(
            again.contains("1 file of figures") && again.contains("table_VI_rmse.svg"),
            "{again}"
        );
        assert!(figure.exists());
    }
}

#[test]
fn a_scenario_runs_its_grid_and_writes_json_and_csv() {
    let dir = scratch("scenario");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let out = run_scenario(file.to_str().unwrap(), &[], out_dir.to_str().unwrap());
    let stdout = stdout_of(&out);
    assert!(
        stdout.contains("Table IX") && stdout.contains("Table VIII"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let records = json["records"].as_array().unwrap();
    assert_eq!(records.len(), 2);
    let (ix, viii) = (&records[0], &records[1]);
    for (r, table, sheath, occlusion, paper_rmse) in [
        (ix, "IX", 90.0, "0%", 9.95),
        (viii, "VIII", 0.0, "40%", 7.84),
    ] {
        assert_eq!(r["kind"], "compensation");
        assert_eq!(r["table"], table);
        assert_eq!(r["estimator"], "none");
        assert_eq!(r["sheath_deg"], sheath);
        assert_eq!(r["occlusion"], occlusion);
        assert_eq!(r["paper_rmse_deg"], paper_rmse);
        assert_eq!(r["seeds"], serde_json::json!([7, 8]));
        assert_eq!(r["periods"], 1.0);
        for key in [
            "rmse_deg",
            "max_hysteresis_deg",
            "error_peak_to_peak_deg",
            "peak_loss_deg",
        ] {
            let v = r[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v > 0.0, "{table} {key}: {v}");
        }
    }
    assert!(
        json["definitions"]["max_hysteresis"]
            .as_str()
            .unwrap()
            .contains("loop width")
    );
    // the CSV holds the same rows
    let csv = std::fs::read_to_string(out_dir.join("results.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3, "{csv}");
    let header: Vec<&str> = lines[0].split(',').collect();
    let rmse_col = header.iter().position(|h| *h == "rmse_deg").unwrap();
    for (line, r) in lines[1..].iter().zip(records) {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), header.len(), "{line}");
        assert_eq!(
            cells[rmse_col].parse::<f64>().unwrap(),
            r["rmse_deg"].as_f64().unwrap()
        );
    }
    // the scenario's Table IX case is the Table IX run the flags set up
    let legacy_dir = dir.join("legacy");
    let out = kflex(&[
        "run",
        "--sheath",
        "90",
        "--periods",
        "1",
        "--repeats",
        "2",
        "--seed",
        "7",
        "--out",
        legacy_dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let legacy = results(&legacy_dir);
    for key in ["rmse_deg", "rmse_std_deg", "max_hysteresis_deg"] {
        assert_eq!(legacy[0][key], ix[key], "{key}");
    }
}

#[test]
fn a_scenario_gives_the_same_results_on_any_number_of_threads() {
    let dir = scratch("scenario-jobs");
    let file = scenario_file(&dir);
    let json = |jobs: &str| {
        let out_dir = dir.join(format!("out-{jobs}"));
        run_scenario(
            file.to_str().unwrap(),
            &["--jobs", jobs],
            out_dir.to_str().unwrap(),
        );
        std::fs::read_to_string(out_dir.join("results.json")).unwrap()
    };
    assert_eq!(json("1"), json("3"));
}

#[test]
fn a_scenario_naming_what_cannot_run_is_refused_before_any_run() {
    let dir = scratch("scenario-refused");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let path = file.to_str().unwrap();
    let out = out_dir.to_str().unwrap();
    // no trained models in the directory given
    let no_models = dir.join("no-models");
    let no_models = no_models.to_str().unwrap();
    for (estimators, needs) in [
        ("none,kbjae", "kbjae.onnx"),
        ("ibjae", "scnn.onnx"),
        ("lbhjae-adaptive", "band-000.kfdb"),
    ] {
        assert_refused(
            &[
                "run",
                "--scenario",
                path,
                "--estimators",
                estimators,
                "--models",
                no_models,
                "--out",
                out,
            ],
            needs,
        );
    }
    assert!(!out_dir.join("results.json").exists());
    // a model that is there but damaged: its own error, not a request for
    // the --models the user gave
    let damaged = dir.join("damaged-models");
    std::fs::create_dir_all(&damaged).unwrap();
    std::fs::write(damaged.join("kbjae.onnx"), b"not a network").unwrap();
    let out = kflex(&[
        "run",
        "--scenario",
        path,
        "--estimators",
        "kbjae",
        "--models",
        damaged.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("the trained models") && !stderr.contains("give the directory"),
        "{stderr}"
    );
    assert_refused(
        &["run", "--scenario", path, "--estimators", "kalman"],
        "unknown estimator \"kalman\"",
    );
    // the flags of the Table IX run do not mix with a scenario
    assert_refused(&["run", "--scenario", path, "--periods", "2"], "--periods");
    assert_refused(
        &["run", "--scenario", path, "--occlusion", "30%"],
        "--occlusion \"30%\"",
    );
    assert_refused(
        &["run", "--scenario", path, "--sheath", "45"],
        "no case of the scenario is left",
    );
    // and it says what the file has (SMALL_SCENARIO: 90 deg at 0 %, 0 deg at 40 %)
    assert_refused(
        &["run", "--scenario", path, "--sheath", "45"],
        "cases are at sheath 0, 90 deg, occlusion 0%, 40%",
    );
    let empty = dir.join("empty.toml");
    std::fs::write(&empty, "estimators = [\"none\"]\ncases = []\n").unwrap();
    assert_refused(
        &["run", "--scenario", empty.to_str().unwrap()],
        "the scenario lists no case",
    );
    for (bad, shown) in [("nan", "NaN"), ("inf", "inf")] {
        assert_refused(
            &["run", "--scenario", path, "--sheath", bad],
            &format!("--sheath {shown}: a sheath angle in degrees"),
        );
    }
    assert_refused(&["run", "--jobs", "2"], "--scenario");
    for jobs in ["0", "1025", "two"] {
        assert_refused(
            &["run", "--scenario", path, "--jobs", jobs],
            "not a thread count from 1 to 1024",
        );
    }
    assert_refused(&["run", "--scenario", path, "--mcap"], "--out");
    assert_refused(
        &["run", "--scenario", "/nonexistent/kflex.toml"],
        "/nonexistent/kflex.toml",
    );
    // a field the grid does not have, named with its line
    std::fs::write(dir.join("bad.toml"), "repeats = 2\nrepaets = 3\n").unwrap();
    assert_refused(
        &["run", "--scenario", dir.join("bad.toml").to_str().unwrap()],
        "repaets",
    );
}

/// The small test models of `tools/make_test_models.py` as a models
/// directory, its databases built by `kflex-cli build-db` on a coarse grid.
fn test_models(dir: &Path) -> PathBuf {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../kflex-estimate/tests/data");
    let models = dir.join("models");
    std::fs::create_dir_all(&models).unwrap();
    std::fs::copy(data.join("kbjae_test.onnx"), models.join("kbjae.onnx")).unwrap();
    std::fs::copy(data.join("scnn_test.onnx"), models.join("scnn.onnx")).unwrap();
    let out = kflex(&[
        "build-db",
        "--scnn",
        models.join("scnn.onnx").to_str().unwrap(),
        "--out",
        models.join("db").to_str().unwrap(),
        "--theta-step",
        "5",
        "--d-step",
        "8",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout_of(&out).contains("wrote 28 databases"),
        "{}",
        stdout_of(&out)
    );
    models
}

#[test]
fn every_estimator_runs_in_a_scenario_on_models_from_a_directory() {
    let dir = scratch("models");
    let models = test_models(&dir);
    let file = dir.join("all.toml");
    std::fs::write(
        &file,
        r#"
estimators = ["none", "kbjae", "ibjae", "lbhjae", "lbhjae-adaptive"]
repeats = 1
[[cases]]
table = "V"
kind = "estimation"
sheath_deg = 0.0
occlusion = "20%"
[[cases]]
table = "IX"
kind = "compensation"
sheath_deg = 90.0
occlusion = "0%"
[scenario.motion]
periods = 1.0
"#,
    )
    .unwrap();
    let out_dir = dir.join("out");
    run_scenario(
        file.to_str().unwrap(),
        &["--models", models.to_str().unwrap(), "--mcap"],
        out_dir.to_str().unwrap(),
    );
    // a log per estimator of each run, each with a message per evaluated tick
    let mut logs: Vec<String> = std::fs::read_dir(out_dir.join("runs"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    logs.sort();
    assert_eq!(
        logs,
        [
            "IX_90deg_0pct_ibjae_seed2020.mcap",
            "IX_90deg_0pct_kbjae_seed2020.mcap",
            "IX_90deg_0pct_lbhjae-adaptive_seed2020.mcap",
            "IX_90deg_0pct_lbhjae_seed2020.mcap",
            "IX_90deg_0pct_none_seed2020.mcap",
            "V_0deg_20pct_ibjae_seed2020.mcap",
            "V_0deg_20pct_kbjae_seed2020.mcap",
            "V_0deg_20pct_lbhjae-adaptive_seed2020.mcap",
            "V_0deg_20pct_lbhjae_seed2020.mcap",
        ]
    );
    let estimates = |name: &str| -> Vec<Option<f64>> {
        let bytes = std::fs::read(out_dir.join("runs").join(name)).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                assert_eq!(m.channel.topic, "/kflex/joint_states");
                let state: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
                state["theta_hat_deg"].as_f64()
            })
            .collect()
    };
    let (kbjae, ibjae) = (
        estimates("V_0deg_20pct_kbjae_seed2020.mcap"),
        estimates("V_0deg_20pct_ibjae_seed2020.mcap"),
    );
    // one period of the input (1 / 0.159 Hz = 6.29 s) at 10 ms ticks
    assert_eq!(kbjae.len(), ibjae.len());
    assert_eq!(kbjae.len(), 629);
    assert_ne!(
        kbjae, ibjae,
        "each log carries its own estimator's estimate"
    );
    assert!(
        estimates("IX_90deg_0pct_none_seed2020.mcap")
            .iter()
            .all(Option::is_none)
    );
    let text = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let records = json["records"].as_array().unwrap();
    let rows: Vec<String> = records
        .iter()
        .map(|r| {
            let rmse = r["rmse_deg"].as_f64().unwrap_or(f64::NAN);
            assert!(rmse.is_finite() && rmse > 0.0, "{r}");
            format!("{} {} {}", r["kind"], r["table"], r["estimator"]).replace('"', "")
        })
        .collect();
    assert_eq!(
        rows,
        [
            "estimation V kbjae",
            "estimation V ibjae",
            "estimation V lbhjae",
            "estimation V lbhjae-adaptive",
            "compensation IX none",
            "compensation IX kbjae",
            "compensation IX ibjae",
            "compensation IX lbhjae",
            "compensation IX lbhjae-adaptive",
        ]
    );
    // a closed loop on an estimate is not the uncompensated plant
    assert_ne!(records[4]["rmse_deg"], records[5]["rmse_deg"]);
}

#[test]
fn build_db_refuses_a_missing_model_and_bad_steps() {
    let dir = scratch("build-db");
    let out = dir.join("db");
    let out = out.to_str().unwrap();
    assert_refused(
        &["build-db", "--scnn", "/nonexistent/scnn.onnx", "--out", out],
        "/nonexistent/scnn.onnx",
    );
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../kflex-estimate/tests/data");
    let scnn = data.join("scnn_test.onnx");
    let scnn = scnn.to_str().unwrap();
    // bad steps, each named; one so fine the grid would not fit in memory
    for (step, needle) in [
        (["--theta-step", "0"], "theta_step_deg"),
        (["--d-step", "-1"], "translation_step_mm"),
        (["--theta-step", "1e-9"], "--theta-step 1e-9 deg"),
        (["--theta-step", "1e-300"], "poses in the band's grid"),
    ] {
        let mut args = vec!["build-db", "--scnn", scnn, "--out", out];
        args.extend(step);
        assert_refused(&args, needle);
    }
    assert!(!Path::new(out).exists());
    // an --out that cannot take the databases is refused before any work
    // (the model is not even loaded)
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    assert_refused(
        &[
            "build-db",
            "--scnn",
            "/nonexistent/scnn.onnx",
            "--out",
            file.to_str().unwrap(),
        ],
        "not a directory",
    );
    let under = file.join("db");
    assert_refused(
        &[
            "build-db",
            "--scnn",
            "/nonexistent/scnn.onnx",
            "--out",
            under.to_str().unwrap(),
        ],
        "--out",
    );
}

#[test]
fn quick_runs_each_tables_first_and_last_case_once() {
    let dir = scratch("quick");
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenarios/paper.toml");
    let out = run_scenario(
        scenario.to_str().unwrap(),
        &["--estimators", "none", "--quick", "--jobs", "1"],
        dir.to_str().unwrap(),
    );
    assert!(stdout_of(&out).contains(", quick"), "{}", stdout_of(&out));
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let cases: Vec<String> = json["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert_eq!(r["repeats"], 1);
            assert_eq!(r["periods"], 1.0);
            format!("{} {} {}", r["table"], r["sheath_deg"], r["occlusion"]).replace('"', "")
        })
        .collect();
    // the uncompensated plant runs in the compensation tables only
    assert_eq!(
        cases,
        [
            "VIII 0.0 0%",
            "VIII 0.0 40% distal",
            "IX 0.0 0%",
            "IX 270.0 0%",
            "X 270.0 40%",
            "X 270.0 40% distal",
        ]
    );
}

#[test]
fn flags_that_replace_a_scenarios_settings_say_so_and_stand_against_quick() {
    let dir = scratch("scenario-flags");
    let scenario =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenarios/table_ix.toml");
    let scenario = scenario.to_str().unwrap();
    let out = run_scenario(
        scenario,
        &[
            "--estimators",
            "none",
            "--quick",
            "--repeats",
            "2",
            "--seed",
            "5",
            "--jobs",
            "64",
        ],
        dir.to_str().unwrap(),
    );
    let stdout = stdout_of(&out);
    for note in [
        format!("note: --seed 5 overrides seed = 2020 from {scenario}"),
        format!("note: --repeats 2 overrides repeats = 3 from {scenario}"),
        "note: --estimators none overrides estimators = [".to_string(),
        // one thread a job: table IX's first and last case, "none" alone
        "2 repeats, seeds 5.., 1 period of the input, 2 threads)".to_string(),
    ] {
        assert!(stdout.contains(&note), "{note}:\n{stdout}");
    }
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let records = json["records"].as_array().unwrap();
    assert_eq!(records.len(), 2);
    assert!(records.iter().all(|r| r["repeats"] == 2), "{records:?}");
    assert_refused(
        &[
            "run",
            "--scenario",
            scenario,
            "--estimators",
            "none",
            "--repeats",
            "0",
        ],
        "--repeats 0",
    );
}

#[test]
fn a_scenarios_own_tables_get_no_paper_figure_and_quoted_csv_cells() {
    let dir = scratch("own-tables");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("own.toml");
    std::fs::write(
        &file,
        r#"
estimators = ["none", "none"]
repeats = 1
[[cases]]
table = "V"
kind = "compensation"
sheath_deg = 0.0
occlusion = "0%"
[[cases]]
table = "mine, \"bent\""
kind = "compensation"
sheath_deg = 45.0
occlusion = "0%"
[scenario.motion]
periods = 1.0
"#,
    )
    .unwrap();
    let out_dir = dir.join("out");
    run_scenario(file.to_str().unwrap(), &[], out_dir.to_str().unwrap());
    let text = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let records = json["records"].as_array().unwrap();
    // "none" named twice runs once; Table V is estimation, so a compensation
    // case labelled V has no paper figure
    assert_eq!(records.len(), 2);
    assert!(records[0]["paper_rmse_deg"].is_null(), "{}", records[0]);
    assert_eq!(records[1]["table"], "mine, \"bent\"");
    let csv = std::fs::read_to_string(out_dir.join("results.csv")).unwrap();
    let line = csv.lines().nth(2).unwrap();
    assert!(
        line.starts_with("compensation,\"mine, \"\"bent\"\"\",none,45,"),
        "{line}"
    );
    // an estimation-only scenario with only the uncompensated plant: nothing to run
    let v = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenarios/table_v.toml");
    assert_refused(
        &[
            "run",
            "--scenario",
            v.to_str().unwrap(),
            "--estimators",
            "none",
        ],
        "nothing to run",
    );
}

#[test]
fn sheath_occlusion_seed_and_repeats_narrow_a_scenario() {
    let dir = scratch("narrow");
    let scenario = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/scenarios/paper.toml");
    run_scenario(
        scenario.to_str().unwrap(),
        &[
            "--estimators",
            "none",
            "--sheath",
            "270",
            "--occlusion",
            "0%,40%",
            "--seed",
            "5",
            "--repeats",
            "1",
            "--quick",
        ],
        dir.to_str().unwrap(),
    );
    let text = std::fs::read_to_string(dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let cases: Vec<String> = json["records"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert_eq!(r["seeds"], serde_json::json!([5]));
            format!("{} {} {}", r["table"], r["sheath_deg"], r["occlusion"]).replace('"', "")
        })
        .collect();
    assert_eq!(cases, ["IX 270.0 0%", "X 270.0 40%"]);
}

/// The heights of a summary SVG's filled bars (`<rect … height=…>` at full
/// or pale opacity in `fill`), in drawing order.
fn bar_heights(svg: &str, fill: &str) -> Vec<(f64, bool)> {
    svg.split("<rect ")
        .skip(1)
        .filter(|r| r.contains(&format!("fill=\"{fill}\"")))
        .map(|r| {
            let attr = |name: &str| -> f64 {
                let start = r.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
                r[start..].split('"').next().unwrap().parse().unwrap()
            };
            (attr("height"), attr("opacity") < 1.0)
        })
        // the legend's swatches are 12 px high
        .filter(|(h, _)| *h != 12.0)
        .collect()
}

#[test]
fn a_scenario_draws_each_case_and_table_as_png_and_svg() {
    let dir = scratch("plots");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let out = run_scenario(file.to_str().unwrap(), &[], out_dir.to_str().unwrap());
    assert!(
        stdout_of(&out).contains("wrote 8 figures"),
        "{}",
        stdout_of(&out)
    );
    let plots = out_dir.join("plots");
    let mut names: Vec<String> = std::fs::read_dir(&plots)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    let mut expected: Vec<String> = [
        "IX_90deg_0pct_loops",
        "IX_90deg_0pct_series",
        "VIII_0deg_40pct_loops",
        "VIII_0deg_40pct_series",
        "table_IX_rmse",
        "table_IX_width",
        "table_VIII_rmse",
        "table_VIII_width",
    ]
    .iter()
    .flat_map(|s| [format!("{s}.png"), format!("{s}.svg")])
    .collect();
    expected.sort();
    assert_eq!(names, expected, "no temporary file is left either");
    // a time series: the command in black and the uncompensated joint in
    // the "none" grey, on a white page
    let png = image::open(plots.join("IX_90deg_0pct_series.png"))
        .unwrap()
        .to_rgb8();
    assert_eq!(png.dimensions(), (960, 600));
    let count = |rgb: [u8; 3]| png.pixels().filter(|p| p.0 == rgb).count();
    assert!(count([255, 255, 255]) > 960 * 600 / 2);
    assert!(count([0, 0, 0]) > 1000, "the command's line");
    assert!(count([120, 120, 120]) > 1000, "the joint's line");
    let svg = std::fs::read_to_string(plots.join("IX_90deg_0pct_series.svg")).unwrap();
    assert!(svg.contains("θ_a with none") && svg.contains("Table IX — sheath 90°"));
    // the width summary: our bar and the paper's, their heights in the
    // ratio of the figures in results.json (to a pixel)
    let text = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let record = &json["records"][0];
    let (ours, paper) = (
        record["max_hysteresis_deg"].as_f64().unwrap(),
        record["paper_max_hysteresis_deg"].as_f64().unwrap(),
    );
    let svg = std::fs::read_to_string(plots.join("table_IX_width.svg")).unwrap();
    let bars = bar_heights(&svg, "#787878");
    assert_eq!(bars.len(), 2, "{bars:?}");
    assert!(!bars[0].1 && bars[1].1, "ours solid, then the paper's pale");
    let drawn = bars[0].0 / bars[1].0;
    assert!(
        (drawn - ours / paper).abs() < 1.5 / bars[1].0.min(bars[0].0) * drawn,
        "bars {bars:?} against {ours} and {paper}"
    );
}

/// A refused argument leaves no empty output folder behind (the folder was
/// made before the arguments were checked); a folder that was there, or
/// holds anything, stays.
#[test]
fn a_refused_argument_leaves_no_empty_output_folder() {
    let dir = scratch("refused-out");
    let nested = dir.join("a").join("b");
    let d = nested.to_str().unwrap();
    assert_refused(&["run", "--periods", "0", "--out", d], "periods");
    assert!(!dir.exists(), "{} left behind", dir.display());
    assert_refused(&["render", "--theta", "1000", "--out", d], "theta");
    assert!(!dir.exists(), "{} left behind", dir.display());
    // a scenario run refused for its models leaves no folder either (its
    // logs' and figures' folders, made later, are recorded as made too)
    let file = scenario_file(&std::env::temp_dir().join(format!(
        "kflex-cli-test-{}-refused-out-scenario",
        std::process::id()
    )));
    assert_refused(
        &[
            "run",
            "--scenario",
            file.to_str().unwrap(),
            "--estimators",
            "kbjae",
            "--models",
            dir.join("no-models").to_str().unwrap(),
            "--mcap",
            "--out",
            d,
        ],
        "kbjae.onnx",
    );
    assert!(!dir.exists(), "{} left behind", dir.display());
    // a folder that was there stays, even empty and reached through a
    // folder the command made ("x/../e/new", x made, e there before)
    let base = scratch("refused-out-base");
    let kept = base.join("e");
    std::fs::create_dir_all(&kept).unwrap();
    let through = base.join("x").join("..").join("e").join("new");
    assert_refused(
        &["run", "--periods", "0", "--out", through.to_str().unwrap()],
        "periods",
    );
    assert!(kept.is_dir(), "{} removed", kept.display());
    assert!(!base.join("x").exists() && !kept.join("new").exists());
    // a folder that was there stays, with what it holds
    std::fs::create_dir_all(&nested).unwrap();
    std::fs::write(nested.join("keep.txt"), b"kept").unwrap();
    assert_refused(&["run", "--periods", "0", "--out", d], "periods");
    assert_eq!(std::fs::read(nested.join("keep.txt")).unwrap(), b"kept");
}

/// A figure that cannot be written after the results are (a folder, not
/// empty, where its PNG goes) fails the command with a non-zero exit that
/// says the results are written and the figures are not, rather than a
/// warning and exit 0 beside an earlier run's figures.
#[test]
fn a_figure_that_fails_after_the_results_fails_the_command() {
    let dir = scratch("figure-blocked");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let blocked = out_dir.join("plots").join("table_IX_rmse.png");
    std::fs::create_dir_all(blocked.join("inside")).unwrap();
    let out = kflex(&[
        "run",
        "--scenario",
        file.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains("the results are written") && stderr.contains("not all the figures"),
        "{stderr}"
    );
    assert!(out_dir.join("results.json").is_file());
    assert!(out_dir.join("results.csv").is_file());
    assert!(
        blocked.join("inside").is_dir(),
        "the folder in the way is left alone"
    );
}

/// A figures folder that cannot be made (a file in its place) fails the
/// command before any run, and leaves no results beside an earlier run's
/// figures (it warned, exited 0 and wrote the results).
#[test]
fn a_figures_folder_that_cannot_be_made_fails_before_any_work() {
    let dir = scratch("plots-file");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("plots"), b"not a folder").unwrap();
    assert_refused(
        &[
            "run",
            "--scenario",
            file.to_str().unwrap(),
            "--out",
            out_dir.to_str().unwrap(),
        ],
        "for the figures",
    );
    assert!(!out_dir.join("results.json").exists());
    assert!(!out_dir.join("results.csv").exists());
}

#[test]
fn figures_are_skipped_on_request_or_without_a_font_and_the_results_stay() {
    let dir = scratch("no-plots");
    let file = scenario_file(&dir);
    let out_dir = dir.join("off");
    run_scenario(
        file.to_str().unwrap(),
        &["--no-plots"],
        out_dir.to_str().unwrap(),
    );
    assert!(out_dir.join("results.json").exists());
    assert!(!out_dir.join("plots").exists());
    // a font that is not there: a warning saying what to do, and the results
    let out_dir = dir.join("nofont");
    let out = Command::new(env!("CARGO_BIN_EXE_kflex-cli"))
        .args(["run", "--scenario", file.to_str().unwrap(), "--out"])
        .arg(&out_dir)
        .env("KFLEX_FONT", dir.join("missing.ttf"))
        .output()
        .unwrap();
    assert!(out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("warning: no figures") && stderr.contains("KFLEX_FONT"),
        "{stderr}"
    );
    assert!(out_dir.join("results.json").exists());
    assert!(!out_dir.join("plots").exists());
    // --no-plots means nothing without --out
    assert_refused(
        &["run", "--scenario", file.to_str().unwrap(), "--no-plots"],
        "--out",
    );
}

#[test]
fn ctrl_c_stops_a_grid_cleanly_leaving_whole_logs_and_no_results() {
    let dir = scratch("interrupt");
    let models = test_models(&dir);
    let file = dir.join("long.toml");
    // IBJAE renders a frame every 33 ms of the loop: about 0.3 s a run, 10 s in all
    std::fs::write(
        &file,
        r#"
estimators = ["ibjae"]
repeats = 30
[[cases]]
table = "IX"
kind = "compensation"
sheath_deg = 0.0
occlusion = "0%"
[scenario.motion]
periods = 1.0
"#,
    )
    .unwrap();
    let out_dir = dir.join("out");
    let runs = out_dir.join("runs");
    let child = Command::new(env!("CARGO_BIN_EXE_kflex-cli"))
        .args(["run", "--scenario", file.to_str().unwrap()])
        .args([
            "--models",
            models.to_str().unwrap(),
            "--jobs",
            "1",
            "--mcap",
        ])
        .arg("--out")
        .arg(&out_dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let logs = |ext: &str| -> Vec<PathBuf> {
        std::fs::read_dir(&runs)
            .map(|d| {
                d.map(|e| e.unwrap().path())
                    .filter(|p| p.to_string_lossy().ends_with(ext))
                    .collect()
            })
            .unwrap_or_default()
    };
    let start = std::time::Instant::now();
    while logs(".mcap").is_empty() {
        assert!(start.elapsed().as_secs() < 60, "no log after a minute");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let interrupted_at = std::time::Instant::now();
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let stopped_after = interrupted_at.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted"), "{stderr}");
    // the run in progress finishes, nothing after it starts
    assert!(stopped_after.as_secs_f64() < 5.0, "{stopped_after:?}");
    let written = logs(".mcap");
    assert!(!written.is_empty() && written.len() < 30, "{written:?}");
    assert!(logs(".tmp").is_empty());
    for log in &written {
        let bytes = std::fs::read(log).unwrap();
        let messages = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.map(|_| ()))
            .collect::<Result<Vec<()>, _>>();
        assert_eq!(messages.map(|m| m.len()).ok(), Some(629), "{log:?}");
    }
    assert!(!out_dir.join("results.json").exists());
    assert!(!out_dir.join("results.csv").exists());
}

#[test]
fn an_unwritable_output_directory_fails_before_any_run() {
    let dir = scratch("unwritable");
    std::fs::create_dir_all(&dir).unwrap();
    let file = scenario_file(&dir);
    // a file where a directory of the path should be
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, "not a directory").unwrap();
    let below = blocker.join("out");
    // the file itself as the output folder, and a folder below it
    for out_dir in [&blocker, &below] {
        for args in [
            vec!["run", "--scenario", file.to_str().unwrap()],
            vec!["run", "--sheath", "0"],
        ] {
            let mut all = args.clone();
            all.extend(["--out", out_dir.to_str().unwrap()]);
            let out = kflex(&all);
            assert!(!out.status.success());
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                stderr.contains("cannot be written (checked before running)")
                    && stderr.contains(out_dir.to_str().unwrap())
                    && !stderr.contains("panicked"),
                "{stderr}"
            );
            // the cause said plainly (it read "File exists (os error 17)")
            let said = format!("{} is a file, not a folder", blocker.display());
            assert!(stderr.contains(&said), "{stderr}");
            // no table printed: nothing ran
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(!stdout.contains("RMSE"), "{stdout}");
        }
    }
    assert_eq!(
        std::fs::read_to_string(&blocker).unwrap(),
        "not a directory"
    );
}

/// A table row of `kflex-cli replay`: the RMSE printed for `name`.
fn replayed_rmse(stdout: &str, name: &str) -> f64 {
    stdout
        .lines()
        .find_map(|l| {
            let (label, rest) = l.split_once('|')?;
            (label.trim() == name).then(|| rest.split_whitespace().next()?.parse().ok())?
        })
        .unwrap_or_else(|| panic!("no row {name} in\n{stdout}"))
}

#[test]
fn replay_runs_the_estimators_again_over_a_logged_runs_frames() {
    let dir = scratch("replay");
    let models = test_models(&dir);
    let file = dir.join("est.toml");
    std::fs::write(
        &file,
        r#"
estimators = ["kbjae", "ibjae", "lbhjae"]
repeats = 1
[[cases]]
table = "V"
kind = "estimation"
sheath_deg = 0.0
occlusion = "0%"
[[cases]]
table = "V"
kind = "estimation"
sheath_deg = 0.0
occlusion = "40%"
[scenario.motion]
periods = 1.0
"#,
    )
    .unwrap();
    let out_dir = dir.join("out");
    let models = models.to_str().unwrap();
    run_scenario(
        file.to_str().unwrap(),
        &["--models", models, "--mcap", "--mcap-frames", "--no-plots"],
        out_dir.to_str().unwrap(),
    );
    let text = std::fs::read_to_string(out_dir.join("results.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let recorded = |name: &str| {
        json["records"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["estimator"] == name && r["occlusion"] == "0%")
            .unwrap()["rmse_deg"]
            .as_f64()
            .unwrap()
    };
    // `kflex-cli replay` of the log of case `stem` with `estimators`
    let replay = |stem: &str, estimators: &str| {
        let log = out_dir.join(format!("runs/{stem}_ibjae_seed2020.mcap"));
        stdout_of(&kflex(&[
            "replay",
            log.to_str().unwrap(),
            "--models",
            models,
            "--estimators",
            estimators,
        ]))
    };
    let log = out_dir.join("runs/V_0deg_0pct_ibjae_seed2020.mcap");
    let stdout = replay("V_0deg_0pct", "kbjae,ibjae,lbhjae");
    // a period (6.29 s) of 10 ms ticks, at 30 frames/s
    assert!(
        stdout.contains("(629 ticks of 0.01 s, 188 frames, seed 2020)"),
        "{stdout}"
    );
    // KBJAE reads commands only, and the pre-roll is replayed as it ran
    assert!(
        (replayed_rmse(&stdout, "kbjae") - recorded("kbjae")).abs() < 1e-3,
        "{stdout}"
    );
    // the frame-based ones differ only before the first logged frame (the
    // log holds the evaluated part's frames, not the pre-roll's)
    for name in ["ibjae", "lbhjae"] {
        let (r, t) = (replayed_rmse(&stdout, name), recorded(name));
        assert!(
            (r / t - 1.0).abs() < 0.02,
            "{name}: {r} against {t}\n{stdout}"
        );
    }
    // the log's own estimate is IBJAE's
    assert!((replayed_rmse(&stdout, "as logged") - recorded("ibjae")).abs() < 1e-3);
    // what became of the frames: KBJAE reads none; IBJAE and LBHJAE read
    // the same frames (most of the 188: a random-weight SCNN, no tape), and
    // LBHJAE's filter used or gated each; the log says the same of IBJAE's
    let columns = |stdout: &str, name: &str| -> Vec<String> {
        let line = stdout
            .lines()
            .find(|l| l.split('|').next().is_some_and(|c| c.trim() == name))
            .unwrap_or_else(|| panic!("no row {name} in\n{stdout}"));
        line.split('|')
            .nth(2)
            .unwrap()
            .split_whitespace()
            .map(String::from)
            .collect()
    };
    let row = |name: &str| columns(&stdout, name);
    assert_eq!(row("kbjae"), ["-", "-", "-", "-"], "{stdout}");
    let (ibjae, lbhjae) = (row("ibjae"), row("lbhjae"));
    let read: usize = ibjae[0].parse().unwrap();
    assert!(read > 150 && read <= 188, "{stdout}");
    assert_eq!(&ibjae[2..], ["-", "-"], "{stdout}");
    // (the replay's first reading may pick another band: its hint did not
    // come from the pre-roll's frames)
    let logged: usize = row("as logged")[0].parse().unwrap();
    assert!(logged.abs_diff(read) <= 2, "{stdout}");
    assert_eq!(row("as logged")[2..], ["-", "-"], "{stdout}");
    let n = |s: &String| s.parse::<usize>().unwrap();
    assert_eq!(n(&lbhjae[2]) + n(&lbhjae[3]), n(&lbhjae[0]), "{stdout}");
    // readings with a hidden part: few without tape, as the log has them
    let clean_hidden = n(&ibjae[1]);
    assert!(clean_hidden < read / 4, "{stdout}");
    assert!(
        n(&row("as logged")[1]).abs_diff(clean_hidden) <= 2,
        "{stdout}"
    );
    // under the middle tape IBJAE reads a hidden part in most frames, the
    // replay as the log (LBHJAE's IBJAE reads the same frames)
    let taped_stdout = replay("V_0deg_40pct", "ibjae,lbhjae");
    let (ibjae, logged) = (
        columns(&taped_stdout, "ibjae"),
        columns(&taped_stdout, "as logged"),
    );
    let hidden = n(&ibjae[1]);
    assert!(
        hidden > n(&ibjae[0]) / 2 && hidden > clean_hidden + 50,
        "{taped_stdout}"
    );
    assert!(n(&logged[1]).abs_diff(hidden) <= 2, "{taped_stdout}");
    assert!(
        n(&columns(&taped_stdout, "lbhjae")[1]).abs_diff(hidden) <= 2,
        "{taped_stdout}"
    );
    // a log without frames replays, saying camera-based estimators see none
    std::fs::create_dir_all(dir.join("plain")).unwrap();
    run_scenario(
        file.to_str().unwrap(),
        &[
            "--models",
            models,
            "--mcap",
            "--no-plots",
            "--estimators",
            "kbjae",
        ],
        dir.join("plain").to_str().unwrap(),
    );
    let plain = dir.join("plain/runs/V_0deg_0pct_kbjae_seed2020.mcap");
    let out = kflex(&["replay", plain.to_str().unwrap(), "--models", models]);
    let stdout = stdout_of(&out);
    assert!(stdout.contains("no camera frames"), "{stdout}");
    assert!((replayed_rmse(&stdout, "kbjae") - recorded("kbjae")).abs() < 1e-3);
    // bad input: a missing log, a file that is not one, "none"
    let missing = dir.join("missing.mcap");
    assert_refused(
        &["replay", missing.to_str().unwrap(), "--models", models],
        "missing.mcap",
    );
    let junk = dir.join("junk.mcap");
    std::fs::write(&junk, b"not a log").unwrap();
    assert_refused(
        &["replay", junk.to_str().unwrap(), "--models", models],
        "junk.mcap",
    );
    assert_refused(
        &["replay", log.to_str().unwrap(), "--estimators", "none"],
        "estimates nothing",
    );
    // the frames take some 50 MB a log
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `kflex-cli run … | head -1`: the reader leaves before the tables are
/// printed. The run carries on and writes its results, without a panic.
#[test]
fn a_closed_standard_output_does_not_stop_a_run() {
    use std::process::Stdio;
    let dir = scratch("closed-stdout");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_kflex-cli"))
        .args(["run", "--scenario"])
        .arg(&file)
        .arg("--out")
        .arg(&out_dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("kflex-cli runs");
    // the reading end closed before the first line is written
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("kflex-cli ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "{stderr}");
    let text = std::fs::read_to_string(out_dir.join("results.json")).expect("results.json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("results.json is JSON");
    assert_eq!(
        json["records"].as_array().map(Vec::len),
        Some(2),
        "both cases' records written"
    );
}

/// The grid's flags without `--scenario` are a usage error, also beside a
/// flag that conflicts with `--scenario` (clap's own check lets them through
/// then, and the run ignored them: `--estimators kbjae` ran the plant alone).
#[test]
fn flags_of_the_grid_without_a_scenario_are_refused() {
    for args in [
        vec!["run", "--periods", "1", "--estimators", "kbjae"],
        vec!["run", "--periods", "1", "--quick"],
        vec!["run", "--dt", "0.01", "--models", "/nonexistent"],
        vec!["run", "--spread", "0.1", "--jobs", "2"],
    ] {
        let out = kflex(&args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("--scenario"), "{args:?}: {stderr}");
        let flag = args[3];
        assert!(
            stderr.contains(flag),
            "{args:?} should name {flag}: {stderr}"
        );
    }
}

/// A folder where a result file goes is refused before any work (it was
/// found only when the results were written, after the whole grid).
#[test]
fn a_folder_in_place_of_a_result_file_is_refused_before_any_run() {
    let dir = scratch("folder-in-place");
    let file = scenario_file(&dir);
    let out_dir = dir.join("out");
    for (args, name) in [
        (
            vec!["run", "--scenario", file.to_str().unwrap()],
            "results.csv",
        ),
        (vec!["run", "--sheath", "0"], "results.json"),
        (vec!["render", "--theta", "20", "--d", "10"], "frame.png"),
    ] {
        let _ = std::fs::remove_dir_all(&out_dir);
        std::fs::create_dir_all(out_dir.join(name)).unwrap();
        let mut all = args.clone();
        all.extend(["--out", out_dir.to_str().unwrap()]);
        let out = kflex(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?}");
        assert!(
            stderr.contains(&format!("{name} is there and is not a file"))
                && stderr.contains("checked before running"),
            "{stderr}"
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            !stdout.contains("RMSE") && !stdout.contains("IoU"),
            "{stdout}"
        );
    }
}
