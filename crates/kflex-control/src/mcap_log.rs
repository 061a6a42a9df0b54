//! MCAP logs of closed-loop runs (cargo feature `mcap`), for Foxglove and
//! for re-reading a run.
//!
//! One channel, [`JOINT_STATES_TOPIC`], JSON-encoded with a `jsonschema`
//! schema ([`JOINT_STATE_SCHEMA`]): one message per evaluated tick with
//! θ_d, its rate, θ_c, the true and the measured θ_a and the estimate θ̂
//! (`null` before the estimator had one), logged at the tick's time. A
//! metadata record `kflex.run` holds the scenario (its JSON form) and the
//! run's seed. The file is written beside its path and renamed into place
//! when complete, so a log is never half-written.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use serde::Serialize;

use crate::closed_loop::{ClosedLoopScenario, ClosedLoopTrace};
use crate::error::{ControlError, Result};

/// The joint states' topic.
pub const JOINT_STATES_TOPIC: &str = "/kflex/joint_states";

/// The joint states' schema name.
pub const JOINT_STATE_SCHEMA_NAME: &str = "kflex.JointState";

/// The JSON schema of a joint-state message.
pub const JOINT_STATE_SCHEMA: &str = r#"{
  "title": "kflex.JointState",
  "description": "One control tick of a kflex closed-loop run; angles in degrees",
  "type": "object",
  "properties": {
    "time_s": {"type": "number", "description": "time since the start of evaluation, s"},
    "theta_d_deg": {"type": "number", "description": "desired angle"},
    "theta_d_rate_deg_per_s": {"type": "number", "description": "its rate, deg/s"},
    "theta_c_deg": {"type": "number", "description": "command sent to the plant"},
    "theta_a_deg": {"type": "number", "description": "true joint angle"},
    "theta_a_measured_deg": {"type": "number", "description": "joint angle as the tracker measured it"},
    "theta_hat_deg": {"type": ["number", "null"], "description": "the estimate; null before the estimator had one"}
  },
  "required": ["time_s", "theta_d_deg", "theta_d_rate_deg_per_s", "theta_c_deg", "theta_a_deg", "theta_a_measured_deg", "theta_hat_deg"]
}"#;

/// One message of [`JOINT_STATES_TOPIC`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct JointState {
    /// Time since the start of evaluation, s.
    pub time_s: f64,
    /// θ_d, deg.
    pub theta_d_deg: f64,
    /// dθ_d/dt, deg/s.
    pub theta_d_rate_deg_per_s: f64,
    /// θ_c, deg.
    pub theta_c_deg: f64,
    /// True θ_a, deg.
    pub theta_a_deg: f64,
    /// Measured θ_a, deg.
    pub theta_a_measured_deg: f64,
    /// θ̂, deg; `None` before the estimator had one.
    pub theta_hat_deg: Option<f64>,
}

fn log_error(path: &Path, e: impl std::fmt::Display) -> ControlError {
    ControlError::Log {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

impl ClosedLoopTrace {
    /// The joint states of every evaluated tick, in order.
    pub fn joint_states(&self) -> impl Iterator<Item = JointState> + '_ {
        let t = &self.trace;
        (0..t.time_s.len()).map(move |k| JointState {
            time_s: t.time_s[k],
            theta_d_deg: t.theta_d_deg[k],
            theta_d_rate_deg_per_s: t.theta_d_rate_deg_per_s[k],
            theta_c_deg: self.theta_c_deg[k],
            theta_a_deg: t.theta_a_deg[k],
            theta_a_measured_deg: t.theta_a_measured_deg[k],
            theta_hat_deg: self.theta_hat_deg[k],
        })
    }

    /// Writes this run as an MCAP log at `path` (see the module docs):
    /// the joint states and, as metadata, `scenario` and `seed`.
    ///
    /// # Errors
    /// [`ControlError::Log`] naming the path when the file cannot be
    /// written (nothing is left at `path` then), or a time that does not fit
    /// the log's nanoseconds.
    pub fn write_mcap(&self, path: &Path, scenario: &ClosedLoopScenario, seed: u64) -> Result<()> {
        let tmp = path.with_extension("mcap.tmp");
        let written = self.write_mcap_to(&tmp, scenario, seed);
        match written.and_then(|()| std::fs::rename(&tmp, path).map_err(|e| log_error(path, e))) {
            Ok(()) => Ok(()),
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e)
            }
        }
    }

    fn write_mcap_to(&self, path: &Path, scenario: &ClosedLoopScenario, seed: u64) -> Result<()> {
        let err = |e: &dyn std::fmt::Display| log_error(path, e);
        let file = std::fs::File::create(path).map_err(|e| err(&e))?;
        let mut out = mcap::Writer::with_options(
            BufWriter::new(file),
            mcap::WriteOptions::new()
                .compression(None)
                .library(concat!("kflex-control ", env!("CARGO_PKG_VERSION"))),
        )
        .map_err(|e| err(&e))?;
        let schema = out
            .add_schema(
                JOINT_STATE_SCHEMA_NAME,
                "jsonschema",
                JOINT_STATE_SCHEMA.as_bytes(),
            )
            .map_err(|e| err(&e))?;
        let channel = out
            .add_channel(schema, JOINT_STATES_TOPIC, "json", &BTreeMap::new())
            .map_err(|e| err(&e))?;
        let scenario_json = serde_json::to_string(scenario).map_err(|e| err(&e))?;
        out.write_metadata(&mcap::records::Metadata {
            name: "kflex.run".into(),
            metadata: BTreeMap::from([
                ("scenario".to_string(), scenario_json),
                ("seed".to_string(), seed.to_string()),
            ]),
        })
        .map_err(|e| err(&e))?;
        let mut data = Vec::new();
        for (k, state) in self.joint_states().enumerate() {
            // to the nearest nanosecond (2.01 s is 2,010,000,000 ns)
            let ns = (state.time_s * 1e9).round();
            if !(0.0..1.8e19).contains(&ns) {
                return Err(err(&format!(
                    "time {} s does not fit the log",
                    state.time_s
                )));
            }
            data.clear();
            serde_json::to_writer(&mut data, &state).map_err(|e| err(&e))?;
            let header = mcap::records::MessageHeader {
                channel_id: channel,
                sequence: u32::try_from(k).unwrap_or(u32::MAX),
                log_time: ns as u64,
                publish_time: ns as u64,
            };
            out.write_to_known_channel(&header, &data)
                .map_err(|e| err(&e))?;
        }
        out.finish().map_err(|e| err(&e))?;
        let file = out.into_inner().into_inner().map_err(|e| err(&e.error()))?;
        file.sync_all().map_err(|e| err(&e))
    }
}
