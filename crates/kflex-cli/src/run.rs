//! `kflex-cli run`: the hysteresis experiment of the paper's Table IX.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::parser::ValueSource;
use clap::{ArgMatches, Args, ValueEnum};
use kflex_control::{ControlError, GridRow, OpenLoopGrid, OpenLoopScenario};
use kflex_model::{AuroraNoise, JointModelKind, PlantConfig, Seating};
use serde::Serialize;

use crate::config;
use crate::output::{
    PEAK_LOSS_DEFINITION, PEAK_TO_PEAK_DEFINITION, WIDTH_DEFINITION, check_writable, paper_pm, pm,
    write_atomic,
};

/// Which joint-angle estimator closes the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Estimator {
    /// No compensation: the plant driven by the master command alone.
    None,
}

/// Which joint model computes the plant's angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum JointArg {
    /// Quasi-static analytic balance (fast).
    Analytic,
    /// rapier3d multibody chain.
    Rapier,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Joint-angle estimator in the loop without --scenario: `none` (the plant alone); the
    /// trained estimators run through --scenario and --estimators.
    #[arg(long, value_enum, default_value = "none")]
    estimator: Estimator,
    /// Sheath configurations, deg, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0,90,180,270",
        allow_negative_numbers = true
    )]
    sheath: Vec<f64>,
    /// Periods of the paper's input (25 sin(t) + 25 deg, 0.159 Hz) to evaluate.
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    periods: f64,
    /// Seeded repeats per configuration.
    #[arg(long, default_value_t = 3)]
    repeats: u32,
    /// Base seed: repeat r uses seed + r for its plant spread and its sensor noise.
    #[arg(long, default_value_t = 2020)]
    seed: u64,
    /// Control tick, s.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    dt: f64,
    /// Relative spread of the plant's physical parameters between repeats (the
    /// set-up's; the build's by a third of it), with each repeat's own tendon
    /// seating and homing of the drive (0: identical plants at rest).
    #[arg(long, default_value_t = 0.15, allow_negative_numbers = true)]
    spread: f64,
    /// Score the true angle instead of the Aurora-like measurement.
    #[arg(long)]
    no_noise: bool,
    /// Joint model of the plant.
    #[arg(long, value_enum, default_value = "analytic")]
    joint: JointArg,
    /// Plant configuration, TOML or JSON (by extension .toml or .json, else by
    /// content): fields of kflex_model::PlantConfig, missing fields take
    /// defaults. --sheath, --joint, --seed and the noise (--no-noise) replace
    /// the file's sheath_deg, joint_model, seed and noise, and a --spread
    /// above 0 its seating (drawn for each repeat); the run says so.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write DIR/results.json (with --scenario also DIR/results.csv and the
    /// figures in DIR/plots/). The directory is checked for writing before
    /// anything runs.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Run a grid of the paper's experiments (Tables V–X) from a scenario
    /// file (TOML, the fields of kflex-control's ExperimentGrid; those in
    /// assets/scenarios/), instead of the Table IX run the flags above set up.
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with_all = ["estimator", "periods", "dt", "spread", "no_noise", "joint", "config"]
    )]
    scenario: Option<PathBuf>,
    /// With --scenario: the estimators to run, comma separated (none, kbjae,
    /// ibjae, lbhjae, lbhjae-adaptive), replacing the file's.
    #[arg(long, value_delimiter = ',', requires = "scenario")]
    estimators: Option<Vec<String>>,
    /// With --scenario: threads running the grid's cases, 1 to 1024
    /// (default: one per core; the results are the same for any count).
    #[arg(long, requires = "scenario", value_parser = parse_jobs)]
    jobs: Option<usize>,
    /// With --scenario: a reduced grid for a fast look: each table's first
    /// and last case, one repeat, one period of the input.
    #[arg(long, requires = "scenario")]
    quick: bool,
    /// With --scenario: only the cases with these occlusions, comma
    /// separated (0%, 20%, 40%, 40% distal). --sheath given with --scenario
    /// likewise keeps the cases at those bends, and --seed and --repeats
    /// replace the file's.
    #[arg(long, value_delimiter = ',', requires = "scenario")]
    occlusion: Option<Vec<String>>,
    /// With --scenario: the trained models' directory (kbjae.onnx, scnn.onnx,
    /// db/ from `kflex-cli build-db`), where the estimators load them from.
    #[arg(long, value_name = "DIR", default_value = kflex_control::MODELS_DIR, requires = "scenario")]
    models: PathBuf,
    /// With --scenario and --out: write every run's MCAP log (joint states
    /// for Foxglove, the scenario and seed as metadata) to DIR/runs/, one
    /// per estimator of the run (about 0.8 MB per run of five periods).
    #[arg(long, requires_all = ["scenario", "out"])]
    mcap: bool,
    /// With --mcap: the logs also hold every frame the camera rendered for
    /// the estimators (the image, its 48×48 segmentation and where the
    /// window lies), for Foxglove and `kflex-cli replay`: about 50 MB per
    /// period of the input in each log, and an estimation run writes a log
    /// per estimator (estimators without frames log none).
    #[arg(long, requires = "mcap")]
    mcap_frames: bool,
    /// With --scenario and --out: write no figures (by default DIR/plots/
    /// gets each case's time series and loops and each table's summary, as
    /// PNG and SVG).
    #[arg(long, requires_all = ["scenario", "out"])]
    no_plots: bool,
    /// The flags above given on the command line (not defaulted), by id.
    #[arg(skip)]
    given: Vec<&'static str>,
}

impl RunArgs {
    /// The flags that replace a [`PlantConfig`] field: their ids.
    const OVERRIDING: [&'static str; 6] =
        ["sheath", "joint", "seed", "no_noise", "repeats", "spread"];

    /// The flags that only a scenario's grid reads, as clap names them.
    const SCENARIO_ONLY: [(&'static str, &'static str); 8] = [
        ("estimators", "--estimators"),
        ("jobs", "--jobs"),
        ("quick", "--quick"),
        ("occlusion", "--occlusion"),
        ("models", "--models"),
        ("mcap", "--mcap"),
        ("mcap_frames", "--mcap-frames"),
        ("no_plots", "--no-plots"),
    ];

    /// The flags given on the command line (`matches`, this subcommand's)
    /// that only work with `--scenario`, when it is not given. clap's own
    /// `requires` lets them through when a flag that conflicts with
    /// `--scenario` (`--periods`, say) is given too, and they would be
    /// ignored without a word.
    pub fn scenario_only_without_scenario(matches: &ArgMatches) -> Vec<&'static str> {
        if matches.value_source("scenario").is_some() {
            return Vec::new();
        }
        Self::SCENARIO_ONLY
            .into_iter()
            .filter(|(id, _)| matches.value_source(id) == Some(ValueSource::CommandLine))
            .map(|(_, flag)| flag)
            .collect()
    }

    /// Records which of the overriding flags `matches` (this subcommand's) got
    /// from the command line, for the run's notes.
    pub fn note_given(&mut self, matches: &ArgMatches) {
        self.given = Self::OVERRIDING
            .into_iter()
            .filter(|id| matches.value_source(id) == Some(ValueSource::CommandLine))
            .collect();
    }

    /// `--flag value`, with " (the default)" unless the flag was given.
    fn flag(&self, id: &str, shown: String) -> String {
        if self.given.contains(&id) {
            shown
        } else {
            format!("{shown} (the default)")
        }
    }

    /// One note per field of the configuration file that a flag replaces.
    fn override_notes(&self, path: &Path, file: &config::ConfigFile) -> Vec<String> {
        let sheaths = self
            .sheath
            .iter()
            .map(|&s| num(s))
            .collect::<Vec<_>>()
            .join(",");
        let joint = match self.joint {
            JointArg::Analytic => "analytic",
            JointArg::Rapier => "rapier",
        };
        let noise = if self.no_noise {
            "--no-noise".to_owned()
        } else {
            "the Aurora-like noise (the default; --no-noise for none)".to_owned()
        };
        [
            (
                "sheath_deg",
                self.flag("sheath", format!("--sheath {sheaths}")),
            ),
            (
                "joint_model",
                self.flag("joint", format!("--joint {joint}")),
            ),
            ("seed", self.flag("seed", format!("--seed {}", self.seed))),
            ("noise", noise),
        ]
        .into_iter()
        .map(|(field, by)| (field, by, ""))
        // a spread draws each repeat's seating (its friction states and
        // where the drive was homed); without one the file's seating stays
        .chain((self.spread > 0.0).then(|| {
            (
                "seating",
                self.flag("spread", format!("--spread {}", num(self.spread))),
                " (each repeat draws its own)",
            )
        }))
        .filter_map(|(field, by, why)| {
            file.fields.get(field).map(|value| {
                format!(
                    "note: {by} overrides {field} = {value} from {}{why}",
                    path.display()
                )
            })
        })
        .collect()
    }
}

/// A number for a message: plain for ordinary magnitudes, scientific for huge
/// and tiny ones (as kflex-model's range errors).
fn num(v: f64) -> String {
    let a = v.abs();
    if v.is_finite() && a != 0.0 && !(1e-6..1e15).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// One row of `results.json`. Field names are stable: later estimators extend, never rename.
#[derive(Debug, Serialize)]
struct Record {
    estimator: Estimator,
    sheath_deg: f64,
    occlusion: &'static str,
    rmse_deg: f64,
    rmse_std_deg: f64,
    max_hysteresis_deg: f64,
    max_hysteresis_std_deg: f64,
    error_peak_to_peak_deg: f64,
    error_peak_to_peak_std_deg: f64,
    peak_loss_deg: f64,
    peak_loss_std_deg: f64,
    paper_rmse_deg: Option<f64>,
    paper_rmse_std_deg: Option<f64>,
    paper_max_hysteresis_deg: Option<f64>,
    paper_max_hysteresis_std_deg: Option<f64>,
    repeats: u32,
    seeds: Vec<u64>,
    periods: f64,
    dt_s: f64,
    joint_model: JointModelKind,
    max_hysteresis_definition: &'static str,
    error_peak_to_peak_definition: &'static str,
    peak_loss_definition: &'static str,
}

/// The most threads `--jobs` may ask for.
const MAX_JOBS: usize = 1024;

/// `--jobs`: a thread count from 1 to [`MAX_JOBS`] (0 is no count of threads).
fn parse_jobs(text: &str) -> std::result::Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if (1..=MAX_JOBS).contains(&n) => Ok(n),
        _ => Err(format!("not a thread count from 1 to {MAX_JOBS}")),
    }
}

/// Whether the flag `id` was given on the command line.
fn self_given(args: &RunArgs, id: &str) -> bool {
    args.given.contains(&id)
}

pub fn run(args: &RunArgs) -> Result<()> {
    if let Some(path) = &args.scenario {
        return crate::grid::run(
            path,
            args.estimators.as_deref(),
            &kflex_control::ModelDir::new(&args.models),
            crate::grid::Options {
                jobs: args.jobs.unwrap_or_else(|| {
                    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
                }),
                quick: args.quick,
                out: args.out.as_ref(),
                mcap: args.mcap,
                mcap_frames: args.mcap_frames,
                plots: !args.no_plots,
                only: crate::grid::Only {
                    sheath_deg: self_given(args, "sheath").then(|| args.sheath.clone()),
                    occlusion: args.occlusion.clone(),
                    seed: self_given(args, "seed").then_some(args.seed),
                    repeats: self_given(args, "repeats").then_some(args.repeats),
                },
            },
        );
    }
    if args.sheath.is_empty() {
        bail!("--sheath needs at least one angle");
    }
    if let Some(dir) = &args.out {
        check_writable(dir, &["results.json"])?;
    }
    let (mut plant, notes) = match &args.config {
        Some(path) => {
            let file = config::load(path)?;
            let notes = args.override_notes(path, &file);
            // the file's values that stay, checked now and blamed on the
            // file (the ones the flags replace are not checked)
            let mut config = file.config;
            if args.spread > 0.0 {
                // each repeat draws its own seating: the file's is replaced
                // (the notes say so), so it is neither checked nor used
                config.seating = Seating::default();
            }
            let mut kept = config;
            kept.sheath_deg = 0.0;
            kept.noise = None;
            kept.validate()
                .with_context(|| format!("{}: the plant configuration", path.display()))?;
            (config, notes)
        }
        None => (PlantConfig::default(), Vec::new()),
    };
    plant.joint_model = match args.joint {
        JointArg::Analytic => JointModelKind::Analytic,
        JointArg::Rapier => JointModelKind::Rapier,
    };
    let grid = OpenLoopGrid {
        plant,
        scenario: OpenLoopScenario {
            periods: args.periods,
            dt_s: args.dt,
            ..OpenLoopScenario::default()
        },
        sheaths_deg: args.sheath.clone(),
        repeats: args.repeats,
        seed: args.seed,
        spread: args.spread,
        noise: (!args.no_noise).then(AuroraNoise::default),
    };
    let rows = grid.run().map_err(|e| explain(args, e))?;
    let records = rows
        .iter()
        .map(|row| record(args, row))
        .collect::<Result<Vec<_>>>()?;
    print_table(args, &notes, &records);
    if let Some(dir) = &args.out {
        let path = write_results(dir, &records)?;
        outln!("\nwrote {}", path.display());
    }
    Ok(())
}

/// The experiment's error, said in terms of the flag behind it where there is one.
fn explain(args: &RunArgs, err: ControlError) -> anyhow::Error {
    // a run too short, or sampled too coarsely, for the metrics
    let too_few = || {
        if args.periods < 1.0 {
            format!(
                "--periods {} is too short for a hysteresis loop (the command must rise and fall over the same angles): use --periods 1 or more",
                num(args.periods)
            )
        } else {
            let period_s = OpenLoopScenario::default().period_s;
            let samples = args.periods * period_s / args.dt;
            format!(
                "--dt {} s is too coarse for a hysteresis loop ({samples:.2} samples over --periods {} of {period_s:.2} s): use a --dt well below the period, e.g. the default 0.01",
                num(args.dt),
                num(args.periods)
            )
        }
    };
    let flag = match &err {
        ControlError::NotEnoughData {
            metric: "rmse" | "loop_width" | "error_peak_to_peak",
            ..
        } => Some(too_few()),
        _ => err.range().and_then(|r| match r.name {
            "periods" => Some(format!("--periods {}", num(args.periods))),
            "dt_s" => Some(format!("--dt {}", num(args.dt))),
            // fewer than one evaluated tick, or too many
            "periods * period_s / dt_s" if r.value < r.bounds.min => Some(too_few()),
            "periods * period_s / dt_s" => Some(format!(
                "--periods {} at --dt {} s asks for too many samples",
                num(args.periods),
                num(args.dt)
            )),
            "repeats" => Some(format!("--repeats {}", args.repeats)),
            "sheath_deg" => Some(format!("--sheath {}", num(r.value))),
            "rel_std" | "spread" => Some(format!("--spread {}", num(args.spread))),
            _ => None,
        }),
    };
    anyhow::Error::new(err).context(flag.unwrap_or_else(|| "running the experiment".to_owned()))
}

fn record(args: &RunArgs, row: &GridRow) -> Result<Record> {
    let (paper_rmse, paper_width) =
        kflex_control::paper_figure("IX", "none", row.sheath_deg, "0%")?;
    Ok(Record {
        estimator: args.estimator,
        sheath_deg: row.sheath_deg,
        occlusion: "0%",
        rmse_deg: row.rmse_deg.mean,
        rmse_std_deg: row.rmse_deg.std,
        max_hysteresis_deg: row.max_hysteresis_deg.mean,
        max_hysteresis_std_deg: row.max_hysteresis_deg.std,
        error_peak_to_peak_deg: row.error_peak_to_peak_deg.mean,
        error_peak_to_peak_std_deg: row.error_peak_to_peak_deg.std,
        peak_loss_deg: row.peak_loss_deg.mean,
        peak_loss_std_deg: row.peak_loss_deg.std,
        paper_rmse_deg: paper_rmse.map(|p| p.mean),
        paper_rmse_std_deg: paper_rmse.map(|p| p.std),
        paper_max_hysteresis_deg: paper_width.map(|p| p.mean),
        paper_max_hysteresis_std_deg: paper_width.map(|p| p.std),
        repeats: args.repeats,
        seeds: row.seeds.clone(),
        periods: args.periods,
        dt_s: args.dt,
        joint_model: row.joint_model,
        max_hysteresis_definition: WIDTH_DEFINITION,
        error_peak_to_peak_definition: PEAK_TO_PEAK_DEFINITION,
        peak_loss_definition: PEAK_LOSS_DEFINITION,
    })
}

fn print_table(args: &RunArgs, notes: &[String], records: &[Record]) {
    let seeds_last = args
        .seed
        .wrapping_add(u64::from(args.repeats.saturating_sub(1)));
    outln!(
        "kflex run — estimator {:?}, input 25 sin(t) + 25 deg at 0.159 Hz, {} periods, {} repeats (seeds {}..={}), {:?} joint, {}",
        args.estimator,
        args.periods,
        args.repeats,
        args.seed,
        seeds_last,
        args.joint,
        if args.no_noise {
            "true angle"
        } else {
            "Aurora-like measurement"
        }
    );
    for note in notes {
        outln!("{note}");
    }
    outln!(
        "Paper: Baek et al., RA-L 2020, Table IX ('None' row). Maximum hysteresis = loop width (see docs).\n"
    );
    outln!(
        "{:>7} | {:^31} | {:^31}",
        "sheath",
        "RMSE (deg)",
        "max. hysteresis (deg)"
    );
    outln!(
        "{:>7} | {:^15} {:^15} | {:^15} {:^15}",
        "(deg)",
        "kflex",
        "paper",
        "kflex",
        "paper"
    );
    outln!("{}", "-".repeat(73));
    for r in records {
        outln!(
            "{:>7} | {:>15} {:>15} | {:>15} {:>15}",
            r.sheath_deg,
            pm(r.rmse_deg, r.rmse_std_deg),
            paper_pm(r.paper_rmse_deg, r.paper_rmse_std_deg),
            pm(r.max_hysteresis_deg, r.max_hysteresis_std_deg),
            paper_pm(r.paper_max_hysteresis_deg, r.paper_max_hysteresis_std_deg),
        );
    }
    outln!(
        "\nThe other readings of 'maximum hysteresis' (kflex; the paper's figures are the loop width's above):"
    );
    outln!(
        "{:>7} | {:^15} {:^15}",
        "sheath",
        "error p-to-p",
        "peak loss"
    );
    for r in records {
        outln!(
            "{:>7} | {:>15} {:>15}",
            r.sheath_deg,
            pm(r.error_peak_to_peak_deg, r.error_peak_to_peak_std_deg),
            pm(r.peak_loss_deg, r.peak_loss_std_deg),
        );
    }
}

/// Writes `dir/results.json` atomically (see [`write_atomic`]).
fn write_results(dir: &Path, records: &[Record]) -> Result<PathBuf> {
    let json = serde_json::to_string_pretty(records).context("serialising results")?;
    write_atomic(dir, "results.json", &json)
}
