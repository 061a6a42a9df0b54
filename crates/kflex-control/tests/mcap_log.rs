//! A closed-loop run's MCAP log, read back with the `mcap` crate's reader.
#![cfg(feature = "mcap")]

use kflex_control::{
    ClosedLoopScenario, JOINT_STATE_SCHEMA, JOINT_STATE_SCHEMA_NAME, JOINT_STATES_TOPIC,
    JointState, NoisyTruth, OpenLoopScenario,
};
use kflex_model::{Plant, PlantConfig};

fn run() -> (ClosedLoopScenario, kflex_control::ClosedLoopTrace) {
    let scenario = ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 1.0,
            pre_roll_s: 0.5,
            ..OpenLoopScenario::default()
        },
        ..ClosedLoopScenario::default()
    };
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let mut estimator = NoisyTruth::new(1.0, 2).unwrap();
    let trace = scenario.run(&mut plant, &mut estimator, 17).unwrap();
    (scenario, trace)
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("kflex-mcap-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_log_holds_every_tick_and_the_scenario() {
    let (scenario, trace) = run();
    let dir = temp_dir("ok");
    let path = dir.join("run.mcap");
    trace.write_mcap(&path, &scenario, 17).unwrap();
    assert!(!path.with_extension("mcap.tmp").exists());
    let bytes = std::fs::read(&path).unwrap();
    let expected: Vec<JointState> = trace.joint_states().collect();
    assert_eq!(expected.len(), trace.trace.time_s.len());
    let mut got = Vec::new();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let m = message.unwrap();
        assert_eq!(m.channel.topic, JOINT_STATES_TOPIC);
        assert_eq!(m.channel.message_encoding, "json");
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(
            (schema.name.as_str(), schema.encoding.as_str()),
            (JOINT_STATE_SCHEMA_NAME, "jsonschema")
        );
        assert_eq!(schema.data.as_ref(), JOINT_STATE_SCHEMA.as_bytes());
        let state: JointState = serde_json::from_slice(&m.data).unwrap();
        assert_eq!(m.log_time, (state.time_s * 1e9).round() as u64);
        got.push(state);
    }
    // serde_json's default float parsing may differ from the written value
    // in the last bit; the log holds the shortest exact decimal
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(&expected) {
        let pairs = [
            (g.time_s, e.time_s),
            (g.theta_d_deg, e.theta_d_deg),
            (g.theta_d_rate_deg_per_s, e.theta_d_rate_deg_per_s),
            (g.theta_c_deg, e.theta_c_deg),
            (g.theta_a_deg, e.theta_a_deg),
            (g.theta_a_measured_deg, e.theta_a_measured_deg),
        ];
        assert!(pairs.iter().all(|&(a, b)| near(a, b)), "{g:?} {e:?}");
        match (g.theta_hat_deg, e.theta_hat_deg) {
            (Some(a), Some(b)) => assert!(near(a, b)),
            (None, None) => {}
            other => panic!("{other:?}"),
        }
    }
    // the first ticks have no estimate yet (null), later ones do
    assert!(got.iter().any(|s| s.theta_hat_deg.is_some()));
    // the schema is JSON and names every field a message has
    let schema: serde_json::Value = serde_json::from_str(JOINT_STATE_SCHEMA).unwrap();
    let message = serde_json::to_value(got[0]).unwrap();
    for key in message.as_object().unwrap().keys() {
        assert!(schema["properties"].get(key).is_some(), "{key}");
    }
    // the scenario and the seed, as metadata
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(summary.metadata_indexes.len(), 1);
    let meta = mcap::read::metadata(&bytes, &summary.metadata_indexes[0]).unwrap();
    assert_eq!(meta.name, "kflex.run");
    assert_eq!(meta.metadata["seed"], "17");
    let back: ClosedLoopScenario = serde_json::from_str(&meta.metadata["scenario"]).unwrap();
    assert_eq!(back, scenario);
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn an_unwritable_log_is_an_error_naming_it_and_leaves_nothing() {
    let (scenario, trace) = run();
    let dir = temp_dir("bad");
    let path = dir.join("missing/run.mcap");
    let e = trace.write_mcap(&path, &scenario, 1).unwrap_err();
    assert!(e.to_string().contains("missing"), "{e}");
    assert!(!path.exists());
    // an existing log is left as it was when a new one cannot be written
    let good = dir.join("run.mcap");
    std::fs::write(&good, b"old").unwrap();
    std::fs::create_dir(dir.join("run.mcap.tmp")).unwrap();
    assert!(trace.write_mcap(&good, &scenario, 1).is_err());
    assert_eq!(std::fs::read(&good).unwrap(), b"old");
    std::fs::remove_dir_all(dir).unwrap();
}
