//! ONNX Runtime and KBJAE on the small test models of
//! `tools/make_test_models.py` (the trained models come with issue 10).
//! Needs the runtime library: `make venv` installs it into `.venv`.
#![cfg(feature = "onnx")]

use std::path::{Path, PathBuf};

use kflex_estimate::onnx::{OnnxModel, onnxruntime_library};
use kflex_estimate::{CommandRate, EstimateError, KBJAE_INPUT, KBJAE_OUTPUT, Kbjae};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// A fresh folder of this test's own under the system's temporary directory.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("kflex-onnx-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn expected() -> (Vec<[f64; 2]>, Vec<f64>) {
    let text = std::fs::read_to_string(data("kbjae_test.expected.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let inputs = v["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()])
        .collect();
    let out = v["theta_error"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    (inputs, out)
}

#[test]
fn the_runtime_library_is_found_in_the_projects_venv() {
    let lib = onnxruntime_library().expect("make venv installs onnxruntime");
    let name = lib.file_name().unwrap().to_string_lossy().to_string();
    assert!(name.starts_with("libonnxruntime.so"), "{}", lib.display());
}

#[test]
fn kbjae_gives_the_networks_output_one_at_a_time_and_batched() {
    let (inputs, want) = expected();
    let mut k = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    assert_eq!(k.sha256().len(), 64);
    for (x, w) in inputs.iter().zip(&want) {
        let got = k.predict(x[0], x[1]).unwrap() - x[0];
        // the network runs in f32: its error is a few f32 ulps of its size
        assert!(
            (got - w).abs() <= 1e-5 * (1.0 + w.abs()),
            "{x:?}: {got} against {w}"
        );
    }
    let theta: Vec<f32> = inputs.iter().map(|x| x[0] as f32).collect();
    let rate: Vec<f32> = inputs.iter().map(|x| x[1] as f32).collect();
    let batch = k.errors(&theta, &rate).unwrap();
    for (g, w) in batch.iter().zip(&want) {
        assert!(
            (f64::from(*g) - w).abs() <= 1e-5 * (1.0 + w.abs()),
            "{g} against {w}"
        );
    }
    assert!(matches!(
        k.errors(&theta, &rate[1..]),
        Err(EstimateError::Length { .. })
    ));
}

#[test]
fn kbjae_differentiates_the_command_stream() {
    let mut k = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let mut probe = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    // first tick: no history, rate 0
    assert_eq!(
        k.step(10.0, 0.01).unwrap(),
        probe.predict(10.0, 0.0).unwrap()
    );
    // an irregular tick: the rate over its own dt
    assert_eq!(
        k.step(10.5, 0.02).unwrap(),
        probe.predict(10.5, 25.0).unwrap()
    );
    // a rejected tick changes nothing
    assert!(k.step(f64::NAN, 0.01).is_err());
    assert!(k.step(11.0, 0.0).is_err());
    assert_eq!(
        k.step(11.0, 0.01).unwrap(),
        probe.predict(11.0, 50.0).unwrap()
    );
    k.reset();
    assert_eq!(k.step(3.0, 0.01).unwrap(), probe.predict(3.0, 0.0).unwrap());
    let mut r = CommandRate::new();
    assert_eq!(r.step(1.0, 0.1).unwrap(), 0.0);
    assert!((r.step(2.0, 0.1).unwrap() - 10.0).abs() < 1e-12);
}

#[test]
fn kbjae_reads_a_given_rate_and_keeps_the_command_history() {
    let mut k = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let mut probe = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    // the rate given, not the commands' difference
    assert_eq!(
        k.step_with_rate(10.0, -7.0, 0.01).unwrap(),
        probe.predict(10.0, -7.0).unwrap()
    );
    // a rejected tick changes nothing: a NaN rate, a bad dt, values the
    // f32 network would read as infinite
    assert!(k.step_with_rate(10.5, f64::NAN, 0.01).is_err());
    assert!(k.step_with_rate(10.5, 3.0, -1.0).is_err());
    assert!(k.step_with_rate(10.5, 1e39, 0.01).is_err());
    assert!(k.step_with_rate(1e39, 3.0, 0.01).is_err());
    // a difference of commands that large, too (1e-40 s after the last)
    assert!(k.step(1e5, 1e-40).is_err());
    let e = probe.predict(0.0, 1e39).unwrap_err();
    assert_eq!(e.range().map(|r| r.name), Some("rate_deg_per_s"), "{e}");
    let e = probe.predict(-2e6, 0.0).unwrap_err();
    assert_eq!(e.range().map(|r| r.name), Some("theta_deg"), "{e}");
    // the history is the commands', so a difference step after it reads
    // the rate from 10.0
    assert_eq!(
        k.step(10.5, 0.01).unwrap(),
        probe.predict(10.5, 50.0).unwrap()
    );
}

#[test]
fn a_model_with_other_names_is_refused_naming_both() {
    let e = Kbjae::load(&data("renamed_test.onnx")).unwrap_err();
    let EstimateError::ModelMismatch {
        which,
        expected,
        found,
        ..
    } = &e
    else {
        panic!("{e}");
    };
    assert_eq!(*which, "input");
    assert!(
        expected.contains("theta_and_rate") && found.starts_with("x "),
        "{e}"
    );
    // the same file is fine where its names are expected
    let spec = kflex_estimate::onnx::TensorSpec {
        name: "x",
        shape: &[-1, 2],
    };
    let mut m = OnnxModel::load(&data("renamed_test.onnx"), spec, KBJAE_OUTPUT, 1).unwrap();
    let mut out = [0.0f32; 2];
    m.run(&[25.0, 0.0, 30.0, 5.0], 2, &mut out).unwrap();
    assert!(matches!(
        m.run(&[25.0, 0.0, 30.0], 2, &mut out),
        Err(EstimateError::Length { .. })
    ));
}

#[test]
fn a_model_that_is_not_what_its_card_says_is_refused() {
    let dir = scratch("card");
    let model = dir.join("kbjae.onnx");
    std::fs::copy(data("kbjae_test.onnx"), &model).unwrap();
    // no card: loads
    Kbjae::load(&model).unwrap();
    std::fs::write(dir.join("kbjae.card.json"), r#"{"sha256": "00ff"}"#).unwrap();
    let e = Kbjae::load(&model).unwrap_err();
    assert!(
        matches!(&e, EstimateError::ModelChecksum { card, .. } if card == "00ff"),
        "{e}"
    );
    std::fs::write(dir.join("kbjae.card.json"), "not json").unwrap();
    assert!(matches!(
        Kbjae::load(&model),
        Err(EstimateError::ModelFile { .. })
    ));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn missing_truncated_and_corrupt_models_are_errors_not_panics() {
    let dir = scratch("bad");
    // a missing file keeps the operating system's kind (Python: FileNotFoundError)
    assert!(matches!(
        Kbjae::load(&dir.join("nothing.onnx")),
        Err(EstimateError::Io {
            kind: std::io::ErrorKind::NotFound,
            ..
        })
    ));
    let bytes = std::fs::read(data("kbjae_test.onnx")).unwrap();
    let cases: [(&str, Vec<u8>); 4] = [
        ("empty", Vec::new()),
        ("truncated", bytes[..bytes.len() / 2].to_vec()),
        (
            "garbage",
            (0..2000u32).map(|i| (i * 7919 % 251) as u8).collect(),
        ),
        ("flipped", {
            let mut b = bytes.clone();
            for i in (0..b.len()).step_by(37) {
                b[i] ^= 0x5a;
            }
            b
        }),
    ];
    for (name, content) in cases {
        let path = dir.join(format!("{name}.onnx"));
        std::fs::write(&path, content).unwrap();
        match OnnxModel::load(&path, KBJAE_INPUT, KBJAE_OUTPUT, 1) {
            Err(EstimateError::Onnx { .. } | EstimateError::ModelMismatch { .. }) => {}
            other => panic!("{name}: {other:?}"),
        }
    }
    std::fs::remove_dir_all(dir).unwrap();
}

fn scnn_expected() -> (Vec<kflex_model::Mask>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(data("scnn_test.expected.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let masks = v["masks"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            let bits: Vec<u8> = m.as_str().unwrap().bytes().map(|b| b - b'0').collect();
            kflex_model::Mask::from_raw(48, 48, bits).unwrap()
        })
        .collect();
    let embeddings = v["embedding"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            e.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect();
    (masks, embeddings)
}

#[test]
fn scnn_embeds_silhouettes_as_the_network_does() {
    use kflex_estimate::{EMBEDDING_DIM, Scnn};
    let (masks, want) = scnn_expected();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let mut one = [0.0f32; EMBEDDING_DIM];
    for (mask, w) in masks.iter().zip(&want) {
        scnn.embed(mask, &mut one).unwrap();
        for (g, w) in one.iter().zip(w) {
            assert!((f64::from(*g) - w).abs() < 1e-5, "{g} against {w}");
        }
    }
    let batch = scnn.embed_batch(&masks).unwrap();
    assert_eq!(batch.len(), masks.len() * EMBEDDING_DIM);
    for (g, w) in batch.iter().zip(want.iter().flatten()) {
        assert!((f64::from(*g) - w).abs() < 1e-5, "{g} against {w}");
    }
    // different silhouettes, different embeddings
    assert!(
        want[0]
            .iter()
            .zip(&want[2])
            .any(|(a, b)| (a - b).abs() > 1e-3)
    );
    let wrong = kflex_model::Mask::new(32, 32).unwrap();
    assert!(matches!(
        scnn.embed(&wrong, &mut one),
        Err(EstimateError::Length { .. })
    ));
    // a KBJAE model is not an SCNN
    assert!(matches!(
        Scnn::load(&data("kbjae_test.onnx"), 1),
        Err(EstimateError::ModelMismatch { .. })
    ));
}

/// A silhouette among the last 16 the network ran for takes the embedding
/// it gave, bit for bit, without running it again; one that differs by a
/// pixel (in the first word of its bits or the last), or that 16 newer ones
/// have pushed out, runs the network.
#[test]
fn a_repeated_silhouette_takes_the_embedding_the_network_gave_it() {
    use kflex_estimate::{EMBEDDING_DIM, Scnn};
    let (masks, _) = scnn_expected();
    let load = || Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let embed = |scnn: &mut Scnn, mask: &kflex_model::Mask| {
        let mut out = [0.0f32; EMBEDDING_DIM];
        scnn.embed(mask, &mut out).unwrap();
        out
    };
    let mut scnn = load();
    let a = embed(&mut scnn, &masks[0]);
    let b = embed(&mut scnn, &masks[1]);
    assert_eq!(scnn.model_runs(), 2);
    assert_eq!(embed(&mut scnn, &masks[0]), a);
    assert_eq!(embed(&mut scnn, &masks[1]), b);
    assert_eq!(scnn.model_runs(), 2, "the repeats ran the network");
    // what a fresh network gives it
    assert_eq!(embed(&mut load(), &masks[0]), a);
    // one pixel more, at the first free pixel and at the last, is another
    // silhouette
    for last in [false, true] {
        let mut bits = masks[0].data().to_vec();
        let free = |v: &u8| *v == 0;
        let k = if last {
            bits.iter().rposition(free)
        } else {
            bits.iter().position(free)
        }
        .unwrap();
        bits[k] = 1;
        let touched = kflex_model::Mask::from_raw(48, 48, bits).unwrap();
        let runs = scnn.model_runs();
        let t = embed(&mut scnn, &touched);
        assert_eq!(scnn.model_runs(), runs + 1, "pixel {k}");
        assert_eq!(embed(&mut load(), &touched), t);
    }
    // 16 remembered (a, b and the two touched ones, then 12 more): `a`, the
    // oldest, still among them; one more pushes it out
    let other = |k: usize| {
        let mut bits = vec![0u8; 48 * 48];
        bits[48 * 47 + k] = 1;
        kflex_model::Mask::from_raw(48, 48, bits).unwrap()
    };
    for k in 0..12 {
        embed(&mut scnn, &other(k));
    }
    assert_eq!(scnn.model_runs(), 16);
    assert_eq!(embed(&mut scnn, &masks[0]), a);
    assert_eq!(scnn.model_runs(), 16, "the oldest of 16 was forgotten");
    embed(&mut scnn, &other(12));
    assert_eq!(embed(&mut scnn, &masks[0]), a);
    assert_eq!(
        scnn.model_runs(),
        18,
        "the 17th did not push the oldest out"
    );
}

/// Networks made through a pool go back to it when dropped and serve the
/// next load of the same file, with the same outputs as a fresh load. A
/// file changed meanwhile (another SHA-256) or other threads are not served
/// by a kept session.
#[test]
fn a_pool_serves_a_kept_session_of_the_same_file_only() {
    use kflex_estimate::{ModelPool, Scnn};
    let dir = scratch("pool");
    let path = dir.join("kbjae.onnx");
    std::fs::copy(data("kbjae_test.onnx"), &path).unwrap();
    let (inputs, _) = expected();
    let outputs = |k: &mut Kbjae| -> Vec<f64> {
        inputs
            .iter()
            .map(|x| k.predict(x[0], x[1]).unwrap())
            .collect()
    };
    let fresh = outputs(&mut Kbjae::load(&path).unwrap());

    let pool = ModelPool::new();
    let first = Kbjae::load_pooled(&path, &pool).unwrap();
    let sha = first.sha256().to_string();
    assert_eq!(pool.kept(), 0);
    drop(first);
    assert_eq!(pool.kept(), 1);
    let mut again = Kbjae::load_pooled(&path, &pool).unwrap();
    assert_eq!(pool.kept(), 0, "the kept session serves the load");
    assert_eq!(outputs(&mut again), fresh);
    drop(again);

    // another network at the same path is loaded anew
    std::fs::copy(data("kbjae_backlash_test.onnx"), &path).unwrap();
    let other = Kbjae::load_pooled(&path, &pool).unwrap();
    assert_ne!(other.sha256(), sha);
    assert_eq!(pool.kept(), 1, "the kept session is not the file's now");
    drop(other);
    assert_eq!(pool.kept(), 2);

    // other threads are another session
    let scnn = data("scnn_test.onnx");
    drop(Scnn::load_pooled(&scnn, 1, &pool).unwrap());
    assert_eq!(pool.kept(), 3);
    let two = Scnn::load_pooled(&scnn, 2, &pool).unwrap();
    assert_eq!((two.threads(), pool.kept()), (2, 3));
    let one = Scnn::load_pooled(&scnn, 1, &pool).unwrap();
    assert_eq!((one.threads(), pool.kept()), (1, 2));
    drop((two, one));
    assert_eq!(pool.kept(), 4);
    let _ = std::fs::remove_dir_all(&dir);
}
