//! `kflex-cli run --scenario FILE`: a grid of the paper's experiments
//! (Tables V–X, kflex-control's `ExperimentGrid`) read from a scenario file,
//! run on several threads, printed beside the paper's figures and written as
//! `results.json` and `results.csv`.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use kflex_control::{EstimatorKind, ExperimentGrid, GridRun, OcclusionCase};
use kflex_model::Camera;
use serde::Serialize;

use kflex_control::ResultRow as Row;

use crate::figures::Collector;
use crate::output::{
    PEAK_LOSS_DEFINITION, PEAK_TO_PEAK_DEFINITION, WIDTH_DEFINITION, check_writable, paper_pm, pm,
    write_atomic_set,
};
use kflex_control::ModelDir;

/// An estimator by its name in scenario files.
pub fn estimator(name: &str) -> Result<EstimatorKind> {
    EstimatorKind::ALL
        .into_iter()
        .find(|k| k.name() == name)
        .with_context(|| {
            let names: Vec<&str> = EstimatorKind::ALL.iter().map(|k| k.name()).collect();
            format!("unknown estimator {name:?}: one of {}", names.join(", "))
        })
}

/// Reads a scenario file (TOML: the fields of `ExperimentGrid`; what it
/// leaves out keeps the paper's grid), and its text.
pub fn load(path: &Path) -> Result<(ExperimentGrid, String)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let grid = toml::from_str(&text)
        .with_context(|| format!("parsing the scenario {}", path.display()))?;
    Ok((grid, text))
}

/// How a scenario runs.
pub struct Options<'a> {
    /// Threads.
    pub jobs: usize,
    /// [`ExperimentGrid::quick`] instead of the whole grid.
    pub quick: bool,
    /// Where the results (and logs) go.
    pub out: Option<&'a PathBuf>,
    /// Every run's MCAP log to `out/runs/`.
    pub mcap: bool,
    /// The logs hold the rendered frames too.
    pub mcap_frames: bool,
    /// The figures to `out/plots/` (where a font is found).
    pub plots: bool,
    /// What the command line narrows or replaces.
    pub only: Only,
}

/// The flags that narrow a scenario's cases or replace its settings.
#[derive(Debug, Default)]
pub struct Only {
    /// Keep the cases at these bends, deg.
    pub sheath_deg: Option<Vec<f64>>,
    /// Keep the cases with these occlusions (their names).
    pub occlusion: Option<Vec<String>>,
    /// Replace the base seed.
    pub seed: Option<u64>,
    /// Replace the repeats.
    pub repeats: Option<u32>,
}

impl Only {
    /// Narrows and replaces `grid`'s; an occlusion name that is none of the
    /// grid's is an error naming the valid ones.
    fn apply(&self, grid: &mut ExperimentGrid) -> Result<()> {
        if grid.cases.is_empty() {
            bail!("the scenario lists no case ([[cases]] with table, kind, sheath_deg, occlusion)");
        }
        // what the file has, for a narrowing that leaves nothing
        let mut had_bends: Vec<f64> = grid.cases.iter().map(|c| c.sheath_deg).collect();
        had_bends.sort_by(f64::total_cmp);
        had_bends.dedup();
        let mut had_occlusions: Vec<&str> = grid.cases.iter().map(|c| c.occlusion.name()).collect();
        had_occlusions.sort_unstable();
        had_occlusions.dedup();
        let had = format!(
            "the scenario's cases are at sheath {} deg, occlusion {}",
            had_bends
                .iter()
                .map(|b| format!("{b}"))
                .collect::<Vec<_>>()
                .join(", "),
            had_occlusions.join(", ")
        );
        if let Some(names) = &self.occlusion {
            let valid = OcclusionCase::ALL.map(OcclusionCase::name);
            if let Some(bad) = names.iter().find(|n| !valid.contains(&n.as_str())) {
                bail!("--occlusion {bad:?}: one of {}", valid.join(", "));
            }
            grid.cases
                .retain(|c| names.iter().any(|n| n == c.occlusion.name()));
        }
        if let Some(bends) = &self.sheath_deg {
            // an angle that is none (NaN, infinite) is named, not left to
            // narrow the grid to nothing
            if let Some(bad) = bends.iter().find(|b| !b.is_finite()) {
                bail!("--sheath {bad}: a sheath angle in degrees");
            }
            grid.cases
                .retain(|c| bends.iter().any(|b| (b - c.sheath_deg).abs() < 1e-9));
        }
        if let Some(seed) = self.seed {
            grid.seed = seed;
        }
        if let Some(repeats) = self.repeats {
            grid.repeats = repeats;
        }
        if grid.cases.is_empty() {
            bail!("no case of the scenario is left by --sheath and --occlusion ({had})");
        }
        Ok(())
    }
}

/// Runs the scenario: `estimators` replace the file's when given; the
/// estimators load their models from `models`.
pub fn run(
    path: &Path,
    estimators: Option<&[String]>,
    models: &ModelDir,
    options: Options<'_>,
) -> Result<()> {
    let Options {
        jobs,
        quick,
        out,
        mcap,
        mcap_frames,
        plots,
        only,
    } = options;
    let jobs = jobs.max(1);
    let logs_wanted = mcap && out.is_some();
    if let Some(dir) = out {
        check_writable(dir, &["results.json", "results.csv"])?;
    }
    if let Some(r) = only.repeats
        && !(1..=kflex_control::MAX_REPEATS).contains(&r)
    {
        bail!(
            "--repeats {r}: a scenario runs 1 to {} repeats",
            kflex_control::MAX_REPEATS
        );
    }
    let (mut grid, text) = load(path)?;
    let file = (grid.seed, grid.repeats, grid.estimators.clone());
    only.apply(&mut grid)?;
    if quick {
        grid = grid.quick();
        // an explicit --repeats stands against --quick's one
        if let Some(r) = only.repeats {
            grid.repeats = r;
        }
    }
    if let Some(names) = estimators {
        grid.estimators = names.iter().map(|n| estimator(n)).collect::<Result<_>>()?;
    }
    // what the flags replaced in the file, said in the header
    let names = |e: &[kflex_control::EstimatorKind]| {
        e.iter().map(|k| k.name()).collect::<Vec<_>>().join(",")
    };
    let mut notes = Vec::new();
    if only.seed.is_some() && grid.seed != file.0 {
        notes.push(format!("--seed {} overrides seed = {}", grid.seed, file.0));
    }
    if only.repeats.is_some() && grid.repeats != file.1 {
        notes.push(format!(
            "--repeats {} overrides repeats = {}",
            grid.repeats, file.1
        ));
    }
    if estimators.is_some() && grid.estimators != file.2 {
        notes.push(format!(
            "--estimators {} overrides estimators = [{}]",
            names(&grid.estimators),
            names(&file.2)
        ));
    }
    // frames are kept only for the logs
    grid.scenario.record_frames = logs_wanted && (mcap_frames || grid.scenario.record_frames);
    // every setting checked before any work; a value out of range that the
    // file set is named with its line
    grid.validate().map_err(|e| match e.line_in(&text) {
        Some(line) => anyhow::anyhow!("{}, line {line}: {e}", path.display()),
        None => anyhow::Error::new(e).context(format!("the scenario {}", path.display())),
    })?;
    // the runs render through the nominal camera (the databases' own)
    let camera = Camera::default();
    let make = |kind| models.make(kind, &camera);
    check_models(
        models,
        &grid.estimators,
        &camera,
        ", or run with --estimators none",
    )?;
    let total_cases = grid.cases.len();
    // one thread a job at most, as the grid runs them
    let jobs = jobs.min(grid.job_count().max(1));
    outln!(
        "kflex run — scenario {}{} ({total_cases} case{}, estimators {}, {} repeat{}, seeds {}.., {} period{} of the input, {jobs} thread{})",
        path.display(),
        if quick { ", quick" } else { "" },
        if total_cases == 1 { "" } else { "s" },
        grid.estimators
            .iter()
            .map(|e| e.name())
            .collect::<Vec<_>>()
            .join(", "),
        grid.repeats,
        if grid.repeats == 1 { "" } else { "s" },
        grid.seed,
        grid.scenario.motion.periods,
        if grid.scenario.motion.periods == 1.0 {
            ""
        } else {
            "s"
        },
        if jobs == 1 { "" } else { "s" },
    );
    for note in &notes {
        outln!("note: {note} from {}", path.display());
    }
    // a bar on a terminal, nothing where stderr is a file or a pipe
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "  [{elapsed_precise}] {bar:32} {pos}/{len} cases done (per estimator in the closed loop), about {eta} left",
        )
        .context("the progress bar's template")?,
    );
    let progress = |done: usize, total: usize| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    };
    crate::interrupt::install()?;
    let logs = match (mcap, out) {
        (true, Some(dir)) => {
            let logs = dir.join("runs");
            crate::output::make_dirs(&logs)
                .with_context(|| format!("creating {}", logs.display()))?;
            Some(logs)
        }
        _ => None,
    };
    // the figures need a font for their text: without one, say so up front
    // and their folder is made before any work, as the logs' is: one that
    // cannot be made (a file in its place) fails the command up front
    let figures = match (plots, out) {
        (true, Some(dir)) => match crate::plots::init_font() {
            Ok(_) => {
                let plots = dir.join("plots");
                crate::output::make_dirs(&plots)
                    .with_context(|| format!("creating {} for the figures", plots.display()))?;
                Some(Collector::new(&grid))
            }
            Err(why) => {
                errln!("kflex-cli: warning: no figures: {why}");
                None
            }
        },
        _ => None,
    };
    // the logs this run writes, to tell them from an earlier run's
    let written_logs = std::sync::Mutex::new(Vec::new());
    let on_run = |run: &GridRun<'_>| {
        if let Some(f) = &figures {
            f.take(run);
        }
        match &logs {
            Some(dir) => run.write_logs(dir).map(|paths| {
                written_logs
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .extend(paths);
            }),
            None => Ok(()),
        }
    };
    let records = grid.run_until(jobs, &make, &progress, &on_run, crate::interrupt::flag());
    bar.finish_and_clear();
    let records = records.with_context(|| format!("running the scenario {}", path.display()))?;
    // a stop asked for after the last run: still no result file
    if crate::interrupt::requested() {
        return Err(kflex_control::ControlError::Interrupted.into());
    }
    if let Some(dir) = &logs {
        outln!("wrote the runs' MCAP logs to {}", dir.display());
        let written = written_logs
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        note_earlier(dir, &["mcap"], &written, "MCAP logs");
    }
    let rows = records
        .iter()
        .map(|r| Row::of(r, &grid))
        .collect::<kflex_control::Result<Vec<_>>>()?;
    print_tables(&rows);
    if let Some(dir) = out {
        let json = serde_json::to_string_pretty(&Results {
            definitions: Definitions {
                max_hysteresis: WIDTH_DEFINITION,
                error_peak_to_peak: PEAK_TO_PEAK_DEFINITION,
                peak_loss: PEAK_LOSS_DEFINITION,
            },
            records: &rows,
        })
        .context("serialising results")?;
        // the two are one result: written together or not at all
        let paths = write_atomic_set(
            dir,
            &[
                ("results.json", format!("{json}\n").as_bytes()),
                ("results.csv", csv(&rows).as_bytes()),
            ],
        )?;
        outln!("\nwrote {}", paths[0].display());
        outln!("wrote {}", paths[1].display());
        if let Some(figures) = figures {
            // the results are written; a figure that fails still fails the
            // command (non-zero exit), saying what is there and what is not
            let plots = dir.join("plots");
            let written = figures.write(&plots, &rows).with_context(|| {
                format!(
                    "the results are written to {}, but not all the figures: \
                     {} may hold some of this run's beside an earlier run's",
                    dir.display(),
                    plots.display()
                )
            })?;
            outln!(
                "wrote {} figures (PNG and SVG) to {}",
                written.len() / 2,
                plots.display()
            );
            note_earlier(&plots, &["png", "svg"], &written, "figures");
        }
    }
    Ok(())
}

/// Says so when `dir` holds files (of extensions `exts`) that this run did
/// not write (`written`): an earlier run's into the same folder, which a
/// reader could take for this run's. They are left in place.
fn note_earlier(dir: &Path, exts: &[&str], written: &[PathBuf], what: &str) {
    let earlier = crate::output::files_besides(dir, exts, written);
    if let Some(first) = earlier.first() {
        let n = earlier.len();
        outln!(
            "note: {} also holds {n} file{} of {what} that this run did not write (from an \
             earlier run into this folder, such as {}); they are left as they were",
            dir.display(),
            if n == 1 { "" } else { "s" },
            first.file_name().map_or_else(
                || first.display().to_string(),
                |n| n.to_string_lossy().into_owned()
            ),
        );
    }
}

#[derive(Serialize)]
struct Definitions {
    max_hysteresis: &'static str,
    error_peak_to_peak: &'static str,
    peak_loss: &'static str,
}

#[derive(Serialize)]
struct Results<'a> {
    definitions: Definitions,
    records: &'a [Row],
}

/// The rows as CSV: one header line, the fields of `Row` in order, seeds and
/// backgrounds joined by `;`, an empty cell for a figure a row has none of.
fn csv(rows: &[Row]) -> String {
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| v.to_string());
    let mut s = String::from(
        "kind,table,estimator,sheath_deg,occlusion,rmse_deg,rmse_std_deg,max_hysteresis_deg,\
         max_hysteresis_std_deg,error_peak_to_peak_deg,error_peak_to_peak_std_deg,peak_loss_deg,\
         peak_loss_std_deg,paper_rmse_deg,paper_rmse_std_deg,paper_max_hysteresis_deg,\
         paper_max_hysteresis_std_deg,repeats,seeds,backgrounds,periods,dt_s\n",
    );
    for r in rows {
        let seeds: Vec<String> = r.seeds.iter().map(u64::to_string).collect();
        let cells = [
            r.kind.to_owned(),
            r.table.clone(),
            r.estimator.to_owned(),
            r.sheath_deg.to_string(),
            r.occlusion.to_owned(),
            r.rmse_deg.to_string(),
            r.rmse_std_deg.to_string(),
            opt(r.max_hysteresis_deg),
            opt(r.max_hysteresis_std_deg),
            opt(r.error_peak_to_peak_deg),
            opt(r.error_peak_to_peak_std_deg),
            opt(r.peak_loss_deg),
            opt(r.peak_loss_std_deg),
            opt(r.paper_rmse_deg),
            opt(r.paper_rmse_std_deg),
            opt(r.paper_max_hysteresis_deg),
            opt(r.paper_max_hysteresis_std_deg),
            r.repeats.to_string(),
            seeds.join(";"),
            r.backgrounds.join(";"),
            r.periods.to_string(),
            r.dt_s.to_string(),
        ];
        let cells: Vec<String> = cells.iter().map(|c| csv_cell(c)).collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

/// A CSV cell: quoted (its quotes doubled) where it holds a comma, a quote
/// or a line break (a scenario's table names are free text).
fn csv_cell(cell: &str) -> String {
    if cell.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", cell.replace('"', "\"\""))
    } else {
        cell.to_owned()
    }
}

/// One table per paper table, in the grid's order.
fn print_tables(rows: &[Row]) {
    let mut tables: Vec<&str> = Vec::new();
    for r in rows {
        if !tables.contains(&r.table.as_str()) {
            tables.push(&r.table);
        }
    }
    for table in tables {
        let these: Vec<&Row> = rows.iter().filter(|r| r.table == table).collect();
        let compensation = these.iter().any(|r| r.kind == "compensation");
        outln!(
            "\nTable {table} — {}",
            if compensation {
                "closed loop: RMSE of the measured angle against θ_d, and the maximum hysteresis (loop width)"
            } else {
                "estimation: RMSE of each estimate against the true angle"
            }
        );
        out!(
            "{:>7} {:>11} {:>16} | {:>15} {:>15}",
            "sheath",
            "occlusion",
            "estimator",
            "RMSE kflex",
            "RMSE paper"
        );
        if compensation {
            out!(" | {:>15} {:>15}", "width kflex", "width paper");
        }
        outln!();
        for r in these {
            out!(
                "{:>7} {:>11} {:>16} | {:>15} {:>15}",
                r.sheath_deg,
                r.occlusion,
                r.estimator,
                pm(r.rmse_deg, r.rmse_std_deg),
                paper_pm(r.paper_rmse_deg, r.paper_rmse_std_deg),
            );
            if compensation {
                let kflex = match (r.max_hysteresis_deg, r.max_hysteresis_std_deg) {
                    (Some(m), Some(s)) => pm(m, s),
                    _ => format!("{:>13}", "—"),
                };
                out!(
                    " | {kflex:>15} {:>15}",
                    paper_pm(r.paper_max_hysteresis_deg, r.paper_max_hysteresis_std_deg)
                );
            }
            outln!();
        }
    }
}

/// [`ModelDir::check`], said for the command line: where a file is missing,
/// what to give (`--models`, and `or` after it); where a model or database
/// is there but damaged or of another model or camera, its own error alone
/// (the directory was given, and holds the wrong thing).
pub(crate) fn check_models(
    models: &ModelDir,
    kinds: &[kflex_control::EstimatorKind],
    camera: &Camera,
    or: &str,
) -> Result<()> {
    models.check(kinds, camera).map_err(|e| {
        let missing = matches!(e, kflex_control::ControlError::Unavailable { .. });
        let e = anyhow::Error::new(e);
        if missing {
            e.context(format!(
                "give the directory that holds the trained models with --models{or}"
            ))
        } else {
            e.context("the trained models")
        }
    })
}
