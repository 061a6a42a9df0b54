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
    let temporary = |dir: &std::path::Path| {
        std::fs::read_dir(dir)
            .unwrap()
            .filter(|e| {
                e.as_ref()
                    .unwrap()
                    .file_name()
                    .to_string_lossy()
                    .ends_with(".tmp")
            })
            .count()
    };
    assert_eq!(temporary(&dir), 0);
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
    // the schema is JSON and names every field a message has, and every
    // message has the fields it requires
    let schema: serde_json::Value = serde_json::from_str(JOINT_STATE_SCHEMA).unwrap();
    for state in &got {
        let message = serde_json::to_value(state).unwrap();
        let keys = message.as_object().unwrap();
        for key in keys.keys() {
            assert!(schema["properties"].get(key).is_some(), "{key}");
        }
        for key in schema["required"].as_array().unwrap() {
            assert!(keys.contains_key(key.as_str().unwrap()), "{key}");
        }
    }
    // a stand-in camera's reading on the ticks a frame reached it
    assert!(got.iter().any(|s| s.details.ibjae_deg.is_some()));
    // a log from before the details reads with none, one from a later
    // version with a use this one does not name reads it as `other`
    let old: JointState = serde_json::from_value(serde_json::json!({
        "time_s": 0.01, "theta_d_deg": 1.0, "theta_d_rate_deg_per_s": 0.0, "theta_c_deg": 1.0,
        "theta_a_deg": 0.5, "theta_a_measured_deg": 0.5, "theta_hat_deg": null
    }))
    .unwrap();
    assert_eq!(old.details, kflex_control::TickDetails::default());
    let later: JointState = serde_json::from_value(serde_json::json!({
        "time_s": 0.01, "theta_d_deg": 1.0, "theta_d_rate_deg_per_s": 0.0, "theta_c_deg": 1.0,
        "theta_a_deg": 0.5, "theta_a_measured_deg": 0.5, "theta_hat_deg": 0.7,
        "ibjae_use": "discarded", "ibjae_deg": 3.0
    }))
    .unwrap();
    assert_eq!(
        later.details.ibjae_use,
        Some(kflex_control::ReadingUse::Other)
    );
    assert_eq!(later.details.ibjae_deg, Some(3.0));
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
    // an existing log is left as it was when a new one cannot be written:
    // a trace whose series disagree in length (its fields are public), or
    // a frame that does not fill its window, is refused before writing
    let good = dir.join("run.mcap");
    std::fs::write(&good, b"old").unwrap();
    let mut short = trace.clone();
    short.theta_c_deg.pop();
    let e = short.write_mcap(&good, &scenario, 1).unwrap_err();
    assert!(e.to_string().contains("ticks long"), "{e}");
    assert_eq!(std::fs::read(&good).unwrap(), b"old");
    let mut torn = trace.clone();
    torn.camera_frames.push(kflex_control::RecordedFrame {
        window: kflex_model::Roi {
            x0: 0,
            y0: 0,
            width: u32::MAX,
            height: u32::MAX,
        },
        rgb: vec![0; 26],
        captured_s: 0.0,
        arrives_s: 0.0,
        command: kflex_model::Command {
            theta_c_deg: 0.0,
            translation_mm: 10.0,
        },
        truth_theta_a_deg: 0.0,
    });
    let e = torn.write_mcap(&good, &scenario, 1).unwrap_err();
    assert!(e.to_string().contains("does not fill"), "{e}");
    assert_eq!(std::fs::read(&good).unwrap(), b"old");
    let entries = std::fs::read_dir(&dir).unwrap().count();
    assert_eq!(entries, 1, "nothing but the old log");
    std::fs::remove_dir_all(dir).unwrap();
}

/// Asks for the pixels of the paper's region every frame and estimates nothing.
struct Watcher;

impl kflex_control::AngleEstimator for Watcher {
    fn frame_request(&self, _command: kflex_model::Command) -> kflex_control::FrameRequest {
        kflex_control::FrameRequest::Pixels(
            kflex_model::Roi::paper(&kflex_model::Camera::default()).expect("the paper's region"),
        )
    }
    fn step(
        &mut self,
        _tick: &kflex_control::EstimatorTick<'_>,
    ) -> kflex_control::Result<Option<f64>> {
        Ok(None)
    }
    fn reset(&mut self) {}
}

#[test]
fn recorded_frames_go_into_the_log_as_images_silhouettes_and_placements() {
    use kflex_control::{
        CAMERA_FRAMES_TOPIC, CameraFrameInfo, IMAGE_TOPIC, RAW_IMAGE_SCHEMA_NAME, SILHOUETTE_TOPIC,
        base64_decode,
    };
    let scenario = ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 0.5,
            pre_roll_s: 0.5,
            ..OpenLoopScenario::default()
        },
        camera: kflex_control::CameraTiming {
            latency_s: 0.05,
            drop_probability: 0.2,
            ..kflex_control::CameraTiming::default()
        },
        compensator: None,
        record_frames: true,
        ..ClosedLoopScenario::default()
    };
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let trace = scenario.run(&mut plant, &mut Watcher, 5).unwrap();
    let frames = &trace.camera_frames;
    // 30 frames/s over half a period (3.1 s), a fifth of them lost, none
    // from the pre-roll
    assert!((60..=85).contains(&frames.len()), "{}", frames.len());
    assert!(frames.iter().all(|f| f.captured_s > 0.0));
    assert!(frames.windows(2).all(|w| w[0].captured_s < w[1].captured_s));
    assert!(
        frames
            .iter()
            .all(|f| (f.arrives_s - f.captured_s - 0.05).abs() < 1e-9)
    );
    // the same run without recording keeps nothing, and runs the same
    let quiet = ClosedLoopScenario {
        record_frames: false,
        ..scenario.clone()
    };
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let untraced = quiet.run(&mut plant, &mut Watcher, 5).unwrap();
    assert!(untraced.camera_frames.is_empty());
    assert_eq!(untraced.trace, trace.trace);

    let dir = temp_dir("frames");
    let path = dir.join("run.mcap");
    trace.write_mcap(&path, &scenario, 5).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let (mut images, mut silhouettes, mut infos, mut ticks) = (0, 0, 0, 0);
    let mut last_time = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let m = message.unwrap();
        assert!(m.log_time >= last_time, "messages in time order");
        last_time = m.log_time;
        let json: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
        let topic = m.channel.topic.as_str();
        if topic == JOINT_STATES_TOPIC {
            ticks += 1;
            continue;
        }
        let i = m.sequence as usize;
        let f = &frames[i];
        assert_eq!(m.log_time, (f.captured_s * 1e9).round() as u64, "{topic}");
        match topic {
            t if t == IMAGE_TOPIC => {
                assert_eq!(
                    m.channel.schema.as_ref().unwrap().name,
                    RAW_IMAGE_SCHEMA_NAME
                );
                assert_eq!(json["encoding"], "rgb8");
                assert_eq!(json["width"], f.window.width);
                assert_eq!(json["step"], 3 * f.window.width);
                let data = base64_decode(json["data"].as_str().unwrap()).unwrap();
                assert!(data == f.rgb, "frame {i}'s pixels");
                images += 1;
            }
            t if t == SILHOUETTE_TOPIC => {
                assert_eq!(json["encoding"], "mono8");
                assert_eq!(
                    (json["width"].as_u64(), json["height"].as_u64()),
                    (Some(48), Some(48))
                );
                let data = base64_decode(json["data"].as_str().unwrap()).unwrap();
                assert_eq!(data.len(), 48 * 48);
                assert!(data.iter().all(|&v| v == 0 || v == 255));
                // the instrument is in every frame of the region
                let on = data.iter().filter(|&&v| v == 255).count();
                assert!(on > 48, "frame {i}: {on} instrument pixels");
                silhouettes += 1;
            }
            t if t == CAMERA_FRAMES_TOPIC => {
                let info: CameraFrameInfo = serde_json::from_value(json).unwrap();
                assert_eq!(info.window.x0, f.window.x0);
                assert_eq!(info.window.height, f.window.height);
                assert!((info.arrives_s - f.arrives_s).abs() < 1e-12);
                // serde_json's default parsing may miss the last bit
                let truth = info.truth_theta_a_deg.unwrap();
                assert!((truth - f.truth_theta_a_deg).abs() < 1e-12);
                infos += 1;
            }
            other => panic!("unexpected topic {other}"),
        }
    }
    assert_eq!(ticks, trace.trace.time_s.len());
    assert_eq!(
        (images, silhouettes, infos),
        (frames.len(), frames.len(), frames.len())
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// An estimator of the pixels: θ_c plus a tenth of the last frame's mean
/// green level (held between frames), so its estimate depends on every
/// frame it was handed and on every command.
#[derive(Default)]
struct GreenMeter {
    green: Option<f64>,
}

impl kflex_control::AngleEstimator for GreenMeter {
    fn frame_request(&self, _command: kflex_model::Command) -> kflex_control::FrameRequest {
        Watcher.frame_request(_command)
    }
    fn step(
        &mut self,
        tick: &kflex_control::EstimatorTick<'_>,
    ) -> kflex_control::Result<Option<f64>> {
        if let Some(image) = tick.frame.and_then(|f| f.image) {
            let g: u64 = image
                .rgb
                .iter()
                .skip(1)
                .step_by(3)
                .map(|&v| u64::from(v))
                .sum();
            self.green = Some(g as f64 / (image.rgb.len() / 3) as f64);
        }
        Ok(self.green.map(|g| tick.command.theta_c_deg + 0.1 * g))
    }
    fn reset(&mut self) {
        self.green = None;
    }
}

#[test]
fn a_replay_over_the_read_log_gives_the_runs_estimates() {
    let scenario = ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 0.3,
            pre_roll_s: 0.5,
            ..OpenLoopScenario::default()
        },
        camera: kflex_control::CameraTiming {
            latency_s: 0.045,
            drop_probability: 0.3,
            ..kflex_control::CameraTiming::default()
        },
        compensator: None,
        record_frames: true,
        ..ClosedLoopScenario::default()
    };
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let trace = scenario
        .run(&mut plant, &mut GreenMeter::default(), 9)
        .unwrap();
    let dir = temp_dir("replay");
    let path = dir.join("run.mcap");
    trace.write_mcap(&path, &scenario, 9).unwrap();
    let log = kflex_control::read_mcap(&path).unwrap();
    assert_eq!(log.seed, Some(9));
    assert_eq!(log.scenario.as_ref(), Some(&scenario));
    assert_eq!(log.states.len(), trace.trace.time_s.len());
    assert_eq!(log.frames.len(), trace.camera_frames.len());
    for (read, kept) in log.frames.iter().zip(&trace.camera_frames) {
        assert_eq!(read.window, kept.window);
        assert!(read.rgb == kept.rgb);
        assert!((read.arrives_s - kept.arrives_s).abs() < 1e-12);
    }
    let ticks = log.replay_ticks(scenario.motion.translation_mm);
    let replayed = scenario
        .replay(&mut GreenMeter::default(), &ticks, &log.frames)
        .unwrap();
    // from the first recorded frame's arrival on, the same estimates (before
    // it the run held a pre-roll frame, which the log does not keep)
    let first = log.frames[0].arrives_s;
    let mut compared = 0;
    for ((state, r), t) in log.states.iter().zip(&replayed).zip(&trace.theta_hat_deg) {
        if state.time_s + 1e-9 >= first {
            let (r, t) = (r.unwrap(), t.unwrap());
            assert!(
                (r - t).abs() < 1e-9,
                "at {} s: {r} against {t}",
                state.time_s
            );
            compared += 1;
        }
    }
    assert!(compared > 150, "{compared}");
    // with the details: the same estimates, and the frames reach the
    // estimator on the ticks they reached it in the run (a run's log says
    // which), lost ones included
    let (again, details) = scenario
        .replay_with_details(&mut GreenMeter::default(), &ticks, &log.frames)
        .unwrap();
    assert_eq!(again, replayed);
    assert_eq!(details.len(), log.states.len());
    let arrived = |d: &kflex_control::TickDetails| d.frame_arrived.unwrap();
    for (state, d) in log.states.iter().zip(&details) {
        if state.time_s + 1e-9 >= first {
            assert_eq!(arrived(d), arrived(&state.details), "at {} s", state.time_s);
        }
    }
    // (the frames still in flight at the end never arrive: with 45 ms of
    // latency at 30 frames/s, at most two)
    let n = details.iter().filter(|d| arrived(d)).count();
    assert!(n + 2 >= log.frames.len() && n <= log.frames.len(), "{n}");
    // a frame that does not fill its window is refused, not read past
    let mut broken = log.frames.clone();
    broken[0].rgb.pop();
    let e = scenario
        .replay(&mut GreenMeter::default(), &ticks, &broken)
        .unwrap_err();
    assert!(e.to_string().contains("does not fill"), "{e}");
    // nor is one whose window is wider than any image (its byte count
    // would overflow a smaller integer)
    let mut wide = log.frames.clone();
    wide[0].window.width = kflex_model::MAX_IMAGE_SIDE + 1;
    let e = scenario
        .replay(&mut GreenMeter::default(), &ticks, &wide)
        .unwrap_err();
    assert!(e.to_string().contains("does not fill"), "{e}");
    // a file that is not a log: an error naming it
    std::fs::write(dir.join("not.mcap"), b"hello").unwrap();
    let e = kflex_control::read_mcap(&dir.join("not.mcap")).unwrap_err();
    assert!(e.to_string().contains("not.mcap"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_log_from_elsewhere_is_read_on_its_joint_states_clock() {
    use kflex_control::{IMAGE_TOPIC, read_mcap};
    use std::collections::BTreeMap;
    // a writer with an epoch clock, ticks from t = 0, images without
    // placements and every sequence number 0
    let dir = temp_dir("elsewhere");
    let path = dir.join("other.mcap");
    let epoch: u64 = 1_700_000_000_000_000_000;
    let write = |path: &std::path::Path, duplicate: bool| {
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let mut out = mcap::Writer::new(file).unwrap();
        let states = out
            .add_schema(
                JOINT_STATE_SCHEMA_NAME,
                "jsonschema",
                JOINT_STATE_SCHEMA.as_bytes(),
            )
            .unwrap();
        let states = out
            .add_channel(states, JOINT_STATES_TOPIC, "json", &BTreeMap::new())
            .unwrap();
        let images = out
            .add_schema("foxglove.RawImage", "jsonschema", b"{}")
            .unwrap();
        let images = out
            .add_channel(images, IMAGE_TOPIC, "json", &BTreeMap::new())
            .unwrap();
        let header = |channel_id, ns: u64| mcap::records::MessageHeader {
            channel_id,
            sequence: 0,
            log_time: ns,
            publish_time: ns,
        };
        for k in 0..50u64 {
            let state = JointState {
                time_s: k as f64 * 0.01,
                theta_d_deg: 10.0,
                theta_d_rate_deg_per_s: 0.0,
                theta_c_deg: 10.0 + k as f64,
                theta_a_deg: 9.0,
                theta_a_measured_deg: 9.0,
                theta_hat_deg: None,
                details: kflex_control::TickDetails::default(),
            };
            out.write_to_known_channel(
                &header(states, epoch + k * 10_000_000),
                &serde_json::to_vec(&state).unwrap(),
            )
            .unwrap();
        }
        // two 2×1 images, at 0.105 s and 0.305 s on the writer's clock
        let mut times = vec![105_000_000u64, 305_000_000];
        if duplicate {
            times.push(305_000_000);
        }
        for t in times {
            let image = serde_json::json!({
                "timestamp": {"sec": 0, "nsec": 0}, "frame_id": "cam", "width": 2, "height": 1,
                "encoding": "rgb8", "step": 6, "data": "AAECAwQF"
            });
            out.write_to_known_channel(
                &header(images, epoch + t),
                &serde_json::to_vec(&image).unwrap(),
            )
            .unwrap();
        }
        out.finish().unwrap();
    };
    write(&path, false);
    let log = read_mcap(&path).unwrap();
    assert!(log.scenario.is_none());
    assert_eq!(log.states.len(), 50);
    assert_eq!(log.frames.len(), 2, "sequence numbers 0 do not overwrite");
    for (f, t) in log.frames.iter().zip([0.105, 0.305]) {
        assert!(
            (f.arrives_s - t).abs() < 1e-9,
            "{} against {t}",
            f.arrives_s
        );
        assert_eq!(f.window, kflex_model::Roi::whole(2, 1));
        assert_eq!(f.rgb, [0, 1, 2, 3, 4, 5]);
        // the command of the tick before it
        let tick = (t / 0.01).floor();
        assert!((f.command.theta_c_deg - (10.0 + tick)).abs() < 1e-9);
        assert!(
            f.truth_theta_a_deg.is_nan(),
            "no ground truth in such a log"
        );
    }
    // two images with the same time and sequence: refused, naming them
    let twice = dir.join("twice.mcap");
    write(&twice, true);
    let e = read_mcap(&twice).unwrap_err().to_string();
    assert!(
        e.contains("twice.mcap") && e.contains("share log time"),
        "{e}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

/// Records the master's θ_d and rate of every tick it is handed.
#[derive(Default)]
struct MasterLog {
    seen: Vec<(f64, f64)>,
}

impl kflex_control::AngleEstimator for MasterLog {
    fn frame_request(&self, _command: kflex_model::Command) -> kflex_control::FrameRequest {
        kflex_control::FrameRequest::None
    }
    fn step(
        &mut self,
        tick: &kflex_control::EstimatorTick<'_>,
    ) -> kflex_control::Result<Option<f64>> {
        self.seen
            .push((tick.theta_d_deg, tick.theta_d_rate_deg_per_s));
        Ok(Some(tick.command.theta_c_deg))
    }
    fn reset(&mut self) {
        self.seen.clear();
    }
}

#[test]
fn a_replay_hands_the_estimator_the_masters_command_as_the_run_did() {
    // compensated, so that θ_c and θ_d differ
    let scenario = ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 0.3,
            pre_roll_s: 0.5,
            ..OpenLoopScenario::default()
        },
        ..ClosedLoopScenario::default()
    };
    assert!(scenario.compensator.is_some());
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let mut run = MasterLog::default();
    let trace = scenario.run(&mut plant, &mut run, 3).unwrap();
    let differs = trace
        .theta_c_deg
        .iter()
        .zip(&trace.trace.theta_d_deg)
        .filter(|(c, d)| (*c - *d).abs() > 0.1)
        .count();
    assert!(differs > 10, "{differs}");
    let path = temp_dir("replay_master").join("run.mcap");
    trace.write_mcap(&path, &scenario, 3).unwrap();
    let log = kflex_control::read_mcap(&path).unwrap();
    let mut replayed = MasterLog::default();
    scenario
        .replay(
            &mut replayed,
            &log.replay_ticks(scenario.motion.translation_mm),
            &log.frames,
        )
        .unwrap();
    // every tick, the pre-roll's included: the same θ_d and rate
    assert_eq!(replayed.seen.len(), run.seen.len());
    for (k, (r, s)) in replayed.seen.iter().zip(&run.seen).enumerate() {
        assert!(
            (r.0 - s.0).abs() < 1e-9 && (r.1 - s.1).abs() < 1e-6,
            "tick {k}: {r:?} against {s:?}"
        );
    }
    // and the evaluated ticks' rates are the trajectory's
    let evaluated = &run.seen[run.seen.len() - trace.trace.time_s.len()..];
    for (s, rate) in evaluated.iter().zip(&trace.trace.theta_d_rate_deg_per_s) {
        assert_eq!(s.1, *rate);
    }
}

/// A log holding what no run can have written is refused, naming the
/// record and the field: an angle past a full turn (its square overflowed
/// the replay table's RMSE to inf), a scenario whose translation no stage
/// allows (LBHJAE read no frame). A frame placed past any image (its
/// estimator read nothing and said nothing) is refused by the writer, and
/// by a replay handed it directly, as are NaN ticks and commands.
#[test]
fn a_log_no_run_can_have_written_is_refused_naming_what() {
    let scenario = ClosedLoopScenario {
        motion: OpenLoopScenario {
            periods: 0.1,
            pre_roll_s: 0.2,
            ..OpenLoopScenario::default()
        },
        compensator: None,
        record_frames: true,
        ..ClosedLoopScenario::default()
    };
    let mut plant = Plant::new(PlantConfig::default()).unwrap();
    let trace = scenario.run(&mut plant, &mut Watcher, 4).unwrap();
    assert!(!trace.camera_frames.is_empty());
    let dir = temp_dir("refused");
    let read =
        |name: &str, trace: &kflex_control::ClosedLoopTrace, scenario: &ClosedLoopScenario| {
            let path = dir.join(name);
            trace.write_mcap(&path, scenario, 4).unwrap();
            kflex_control::read_mcap(&path)
        };
    let good = read("good.mcap", &trace, &scenario).unwrap();

    // the writer refuses an angle past a full turn; the reader refuses it
    // in a log from elsewhere, and reads a θ_d or θ̂ past it (a trajectory
    // may command past the stops, an estimate may err as far)
    let mut far_angle = trace.clone();
    far_angle.trace.theta_a_deg[2] = 1e308;
    let e = far_angle
        .write_mcap(&dir.join("angle.mcap"), &scenario, 4)
        .unwrap_err()
        .to_string();
    assert!(e.contains("theta_a_deg = 1e308"), "{e}");
    let state = |theta_d_deg: f64, theta_a_deg: f64, theta_hat_deg: f64| JointState {
        time_s: 0.0,
        theta_d_deg,
        theta_d_rate_deg_per_s: 0.0,
        theta_c_deg: 10.0,
        theta_a_deg,
        theta_a_measured_deg: 9.0,
        theta_hat_deg: Some(theta_hat_deg),
        details: kflex_control::TickDetails::default(),
    };
    let elsewhere_at = |name: &str, states: &[JointState], time_s: &dyn Fn(usize) -> f64| {
        let path = dir.join(name);
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut out = mcap::Writer::new(file).unwrap();
        let schema = out
            .add_schema(
                JOINT_STATE_SCHEMA_NAME,
                "jsonschema",
                JOINT_STATE_SCHEMA.as_bytes(),
            )
            .unwrap();
        let channel = out
            .add_channel(
                schema,
                JOINT_STATES_TOPIC,
                "json",
                &std::collections::BTreeMap::new(),
            )
            .unwrap();
        for (k, s) in states.iter().enumerate() {
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: k as u32,
                log_time: k as u64 * 10_000_000,
                publish_time: k as u64 * 10_000_000,
            };
            let state = JointState {
                time_s: time_s(k),
                ..*s
            };
            out.write_to_known_channel(&header, &serde_json::to_vec(&state).unwrap())
                .unwrap();
        }
        out.finish().unwrap();
        kflex_control::read_mcap(&path)
    };
    let elsewhere =
        |name: &str, states: &[JointState]| elsewhere_at(name, states, &|k| k as f64 * 0.01);
    // ticks that share a time (it replayed them, each "0.01 s"; the
    // reader orders the joint states by time, so none can go back)
    for (name, times) in [
        ("same.mcap", [0.01, 0.01, 0.01]),
        ("twice.mcap", [0.0, 0.01, 0.01]),
    ] {
        let e = elsewhere_at(name, &[state(10.0, 9.0, 9.0); 3], &|k| times[k])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains("does not come after the one before it"),
            "{e}"
        );
    }
    let e = elsewhere(
        "angle.mcap",
        &[state(10.0, 9.0, 9.0), state(10.0, 1e308, 9.0)],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("angle.mcap")
            && e.contains("joint state 1")
            && e.contains("theta_a_deg = 1e308"),
        "{e}"
    );
    let far = elsewhere(
        "far.mcap",
        &[state(400.0, 9.0, -500.0), state(720.0, 9.0, 9.0)],
    )
    .unwrap();
    assert_eq!(far.states.len(), 2);

    // the writer refuses such a frame as the reader does
    let mut far_window = trace.clone();
    far_window.camera_frames[0].window.x0 = 4_000_000_000;
    let e = far_window
        .write_mcap(&dir.join("window.mcap"), &scenario, 4)
        .unwrap_err()
        .to_string();
    assert!(e.contains("reaches past"), "{e}");

    let mut far_stage = scenario.clone();
    far_stage.motion.translation_mm = 1e308;
    let e = read("stage.mcap", &trace, &far_stage)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scenario metadata") && e.contains("translation_mm = 1e308"),
        "{e}"
    );

    // handed to a replay directly
    let mut ticks = good.replay_ticks(scenario.motion.translation_mm);
    ticks[1].theta_d_deg = f64::NAN;
    let e = scenario
        .replay(&mut Watcher, &ticks, &good.frames)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("replay tick 1") && e.contains("theta_d_deg NaN"),
        "{e}"
    );
    let ticks = good.replay_ticks(scenario.motion.translation_mm);
    let mut frames = good.frames.clone();
    frames[0].command.translation_mm = f64::INFINITY;
    let e = scenario
        .replay(&mut Watcher, &ticks, &frames)
        .unwrap_err()
        .to_string();
    assert!(e.contains("translation_mm = inf"), "{e}");
    let mut frames = good.frames.clone();
    frames[0].window.x0 = 4_000_000_000;
    let e = scenario
        .replay(&mut Watcher, &ticks, &frames)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("window at (4000000000, ") && e.contains("reaches past"),
        "{e}"
    );
    assert!(scenario.replay(&mut Watcher, &ticks, &good.frames).is_ok());
}
