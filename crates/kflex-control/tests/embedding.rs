//! A controller that embeds the estimators and the compensator compiles none
//! of the simulator's heavy dependencies (DESIGN: "The loop"): with default
//! features off, kflex-estimate and kflex-control build without rapier3d,
//! parry3d or image. Checked on the dependency graph cargo itself resolves.

use std::collections::BTreeSet;
use std::process::Command;

/// What the embedding path must not compile.
const SIMULATOR_ONLY: [&str; 3] = ["rapier3d", "parry3d", "image"];

/// The packages `package` compiles for the host (normal and build edges),
/// with `features` (`None`: default features off).
fn compiled(package: &str, features: Option<&str>) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(env!("CARGO_MANIFEST_DIR")).args([
        "tree",
        "--locked",
        "--package",
        package,
        "--edges",
        "normal,build",
        "--prefix",
        "none",
        "--format",
        "{p}",
    ]);
    match features {
        None => {
            cmd.arg("--no-default-features");
        }
        Some(f) => {
            cmd.args(["--features", f]);
        }
    }
    let out = cmd.output().expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        .collect()
}

#[test]
fn embedding_crates_build_without_the_simulator() {
    for package in ["kflex-estimate", "kflex-control"] {
        let deps = compiled(package, None);
        assert!(deps.contains("kflex-model"), "{package}: {deps:?}");
        for heavy in SIMULATOR_ONLY {
            assert!(
                !deps.contains(heavy),
                "{package} without default features compiles {heavy}"
            );
        }
    }
}

#[test]
fn the_multibody_feature_is_what_brings_rapier() {
    // the check above can fail: the same query sees rapier where it is asked for
    let with = compiled("kflex-control", Some("multibody"));
    assert!(with.contains("rapier3d") && with.contains("parry3d"));
    let model = compiled("kflex-model", Some("multibody"));
    assert!(model.contains("rapier3d"));
    // and image stays a development dependency of the model: never compiled for users
    assert!(!model.contains("image"));
}
