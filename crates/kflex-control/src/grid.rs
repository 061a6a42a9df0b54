//! The paper's closed-loop experiments as a grid of cases (Tables V–X):
//! which cases, which estimators, how many repeats; its scenario files are
//! TOML (`assets/scenarios/`).
//!
//! **Estimation cases** (Tables V–VII) run open loop (θ_c = θ_d) and score
//! each estimator's θ̂ against the plant's true angle. **Compensation
//! cases** (Tables VIII–X) close the loop with the compensator on each
//! estimator's θ̂ and score θ_a against θ_d (RMSE and the three readings of
//! the maximum hysteresis); the estimator `none` is the uncompensated plant.
//! Each repeat runs on its own perturbed plant (the open-loop grid's
//! spread), with the tracker's noise, its frames over the next background
//! in [`ExperimentGrid::backgrounds`]; the repeat's seed draws all of it,
//! so every estimator of a case meets the same plants, frames and losses.

use kflex_model::{AuroraNoise, Background, Bounds, Occlusion, Plant, PlantConfig};
use serde::{Deserialize, Serialize};

use crate::closed_loop::{
    AngleEstimator, ClosedLoopScenario, ClosedLoopTrace, TickDetails, estimation_rmse_deg,
};
use crate::error::{ControlError, Result};
use crate::experiment::{MAX_REPEATS, RunMetrics, check_seed};
use crate::metrics::MeanStd;

/// Tape over the instrument, as the paper names its cases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum OcclusionCase {
    /// No tape.
    #[serde(rename = "0%")]
    None,
    /// 20 % of the instrument in the working region, centred on it.
    #[serde(rename = "20%")]
    Middle20,
    /// 40 %, centred.
    #[serde(rename = "40%")]
    Middle40,
    /// 40 %, ending at the tool's tip.
    #[serde(rename = "40% distal")]
    Distal40,
}

impl OcclusionCase {
    /// Every case, in the paper's order.
    pub const ALL: [OcclusionCase; 4] = [
        OcclusionCase::None,
        OcclusionCase::Middle20,
        OcclusionCase::Middle40,
        OcclusionCase::Distal40,
    ];

    /// The tape it puts on the frames (its share measured in the working
    /// region of the frame's translation, see [`Occlusion`]).
    #[must_use]
    pub fn occlusion(self) -> Option<Occlusion> {
        match self {
            Self::None => None,
            Self::Middle20 => Some(Occlusion::new(0.2, 0.5)),
            Self::Middle40 => Some(Occlusion::new(0.4, 0.5)),
            Self::Distal40 => Some(Occlusion::new(0.4, 1.0)),
        }
    }

    /// The paper's name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "0%",
            Self::Middle20 => "20%",
            Self::Middle40 => "40%",
            Self::Distal40 => "40% distal",
        }
    }
}

/// What a case measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseKind {
    /// Open loop; each estimate's RMSE against the true angle.
    Estimation,
    /// Closed loop on each estimate; θ_a's RMSE and hysteresis against θ_d.
    Compensation,
}

impl CaseKind {
    /// Its name in scenario files and results.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Estimation => "estimation",
            Self::Compensation => "compensation",
        }
    }
}

/// The estimators of the paper's tables.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EstimatorKind {
    /// No estimate: the uncompensated plant (compensation cases only).
    None,
    /// KBJAE alone.
    Kbjae,
    /// IBJAE alone.
    Ibjae,
    /// LBHJAE with the paper's Kalman filter.
    Lbhjae,
    /// LBHJAE with kflex's adaptive filter.
    LbhjaeAdaptive,
}

impl EstimatorKind {
    /// Every estimator, in the paper's order (kflex's own last).
    pub const ALL: [EstimatorKind; 5] = [
        EstimatorKind::None,
        EstimatorKind::Kbjae,
        EstimatorKind::Ibjae,
        EstimatorKind::Lbhjae,
        EstimatorKind::LbhjaeAdaptive,
    ];

    /// Its name in scenario files and on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Kbjae => "kbjae",
            Self::Ibjae => "ibjae",
            Self::Lbhjae => "lbhjae",
            Self::LbhjaeAdaptive => "lbhjae-adaptive",
        }
    }
}

/// One case of the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// The paper's table it belongs to ("V" … "X").
    pub table: String,
    /// What it measures.
    pub kind: CaseKind,
    /// Sheath configuration, deg.
    pub sheath_deg: f64,
    /// Tape over the instrument.
    pub occlusion: OcclusionCase,
}

impl Case {
    /// The case in file names: `V_0deg_40pct-distal` (the table's name with
    /// every character but ASCII letters, digits, `-` and `.` made `_`).
    #[must_use]
    pub fn file_stem(&self) -> String {
        let occlusion = self.occlusion.name().replace('%', "pct").replace(' ', "-");
        format!(
            "{}_{}deg_{occlusion}",
            safe_file_name(&self.table),
            self.sheath_deg
        )
    }

    /// Whether `self` and `other` are the same run, whatever their tables:
    /// the same kind, sheath and tape (a grid runs it once for both).
    #[must_use]
    pub fn same_run(&self, other: &Case) -> bool {
        self.kind == other.kind
            && self.sheath_deg.to_bits() == other.sheath_deg.to_bits()
            && self.occlusion == other.occlusion
    }
}

/// The jobs grouped by run: each group the indices (in order, the first
/// the earliest) of the jobs whose cases are the same run
/// ([`Case::same_run`]) with the same estimators; groups in the order of
/// their first job.
fn same_runs(jobs: &[(&Case, Vec<EstimatorKind>)]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, (case, estimators)) in jobs.iter().enumerate() {
        let same = groups.iter_mut().find(|g| {
            let (first, theirs) = &jobs[g[0]];
            first.same_run(case) && theirs == estimators
        });
        match same {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// `name` with every character but ASCII letters, digits, `-` and `.` made `_`.
#[must_use]
pub fn safe_file_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// A grid of experiments, as a scenario file holds it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ExperimentGrid {
    /// The cases, in order.
    pub cases: Vec<Case>,
    /// The estimators run on every case (`none` only on compensation cases).
    pub estimators: Vec<EstimatorKind>,
    /// Repeats per case and estimator.
    pub repeats: u32,
    /// Base seed; repeat `r` uses `seed + r` (plant, noise, frames).
    pub seed: u64,
    /// Relative parameter spread between repeats' plants, `[0, 0.5]`.
    pub spread: f64,
    /// Backgrounds, one per repeat in turn.
    pub backgrounds: Vec<Background>,
    /// The tracker's noise on the measured angle; `None` for the true angle.
    pub noise: Option<AuroraNoise>,
    /// The nominal plant (its sheath, noise and seed are set per run).
    pub plant: PlantConfig,
    /// Motion, camera, frames and tolerances of every run; its compensator
    /// is used on compensation cases (and the default one where it has none).
    pub scenario: ClosedLoopScenario,
}

impl Default for ExperimentGrid {
    fn default() -> Self {
        Self::paper()
    }
}

/// One row of the results: a case and an estimator over the repeats.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The case.
    pub case: Case,
    /// The estimator.
    pub estimator: EstimatorKind,
    /// Estimation: θ̂ against the true θ_a; compensation: θ_a (measured)
    /// against θ_d; deg, over the repeats.
    pub rmse_deg: MeanStd,
    /// Compensation only: the loop width, the error's peak-to-peak and the
    /// peak loss over the repeats.
    pub hysteresis: Option<[MeanStd; 3]>,
    /// Each repeat's seed and background.
    pub repeats: Vec<(u64, Background)>,
}

impl ExperimentGrid {
    /// The paper's experiments: Tables V–VII (estimation) and VIII–X
    /// (compensation), every estimator, three repeats (seeds 2020–2022),
    /// colon, stomach and larynx in turn.
    #[must_use]
    pub fn paper() -> Self {
        use OcclusionCase::{Distal40, Middle20, Middle40, None as Clear};
        let mut cases = Vec::new();
        for (kind, tables) in [
            (CaseKind::Estimation, ["V", "VI", "VII"]),
            (CaseKind::Compensation, ["VIII", "IX", "X"]),
        ] {
            let [occ, sheath, both] = tables;
            let mut add = |table: &str, sheath_deg: f64, occlusion| {
                cases.push(Case {
                    table: table.to_string(),
                    kind,
                    sheath_deg,
                    occlusion,
                });
            };
            for o in [Clear, Middle20, Middle40, Distal40] {
                add(occ, 0.0, o);
            }
            for s in [0.0, 90.0, 180.0, 270.0] {
                add(sheath, s, Clear);
            }
            add(both, 270.0, Middle40);
            add(both, 180.0, Distal40);
            add(both, 270.0, Distal40);
        }
        Self {
            cases,
            estimators: vec![
                EstimatorKind::None,
                EstimatorKind::Kbjae,
                EstimatorKind::Ibjae,
                EstimatorKind::Lbhjae,
                EstimatorKind::LbhjaeAdaptive,
            ],
            repeats: 3,
            seed: 2020,
            spread: 0.15,
            backgrounds: Background::ALL.to_vec(),
            noise: Some(AuroraNoise::default()),
            plant: PlantConfig::default(),
            scenario: ClosedLoopScenario::default(),
        }
    }

    /// The cases of one table ("V" … "X") of [`ExperimentGrid::paper`].
    #[must_use]
    pub fn paper_table(table: &str) -> Self {
        let mut grid = Self::paper();
        grid.cases.retain(|c| c.table == table);
        grid
    }

    /// A reduced grid for a fast look: of each table's cases the first and
    /// the last, one repeat, at most one period of the input (its pre-roll
    /// kept).
    #[must_use]
    pub fn quick(&self) -> Self {
        let mut cases: Vec<Case> = Vec::new();
        for (i, c) in self.cases.iter().enumerate() {
            let first = !cases.iter().any(|k| k.table == c.table);
            let last = !self.cases[i + 1..].iter().any(|k| k.table == c.table);
            if first || last {
                cases.push(c.clone());
            }
        }
        let mut grid = Self {
            cases,
            repeats: 1,
            ..self.clone()
        };
        grid.scenario.motion.periods = grid.scenario.motion.periods.min(1.0);
        grid
    }

    /// Checks every setting before any run.
    ///
    /// # Errors
    /// [`ControlError::OutOfRange`] naming `repeats` (`[1,`
    /// [`MAX_REPEATS`]`]`) or `spread` (`[0, 0.5]`);
    /// [`ControlError::CaseOutOfRange`] naming a case whose `sheath_deg`
    /// lies outside `[0, max]` (`max`: the nominal plant's
    /// [`kflex_model::SheathParams::max_sheath_deg`], at most 3600);
    /// [`ControlError::NotEnoughData`] for no cases, estimators or
    /// backgrounds, or nothing to run (estimation cases with `none` alone);
    /// [`ControlError::SharedCaseName`] for two cases that differ in their
    /// kind alone, or not at all (their logs and figures would share names);
    /// [`ControlError::SeedOverflow`] for a `seed` whose repeats would pass
    /// the largest seed; as [`ClosedLoopScenario::validate`].
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(1.0, f64::from(MAX_REPEATS)).check("repeats", f64::from(self.repeats))?;
        check_seed(self.seed, self.repeats)?;
        Bounds::closed(0.0, 0.5).check("spread", self.spread)?;
        for (what, n) in [
            ("at least one case", self.cases.len()),
            ("at least one estimator", self.estimators.len()),
            ("at least one background", self.backgrounds.len()),
        ] {
            if n == 0 {
                return Err(ControlError::NotEnoughData {
                    metric: "experiment grid",
                    needed: what,
                    got: 0,
                });
            }
        }
        // the nominal plant's limit (its sheath's friction bounds the wrap),
        // the plant checked first (a bad sheath parameter is named itself,
        // not as a case's bend outside [0, NaN]); the case counted from 1
        // in the grid as it runs (after any narrowing)
        self.plant.validate()?;
        let max_sheath_deg = self.plant.sheath.max_sheath_deg();
        for (i, c) in self.cases.iter().enumerate() {
            Bounds::closed(0.0, max_sheath_deg)
                .check("sheath_deg", c.sheath_deg)
                .map_err(|error| ControlError::CaseOutOfRange {
                    case: i + 1,
                    stem: c.file_stem(),
                    error,
                })?;
        }
        let mut stems: std::collections::HashMap<String, usize> = std::collections::HashMap::new();
        for (i, c) in self.cases.iter().enumerate() {
            let stem = c.file_stem();
            if let Some(&first) = stems.get(&stem.to_lowercase()) {
                return Err(ControlError::SharedCaseName {
                    first: first + 1,
                    second: i + 1,
                    stem,
                });
            }
            stems.insert(stem.to_lowercase(), i);
        }
        // "none" runs in compensation cases only
        let runnable = self.cases.iter().any(|c| {
            c.kind == CaseKind::Compensation
                || self.estimators.iter().any(|&e| e != EstimatorKind::None)
        });
        if !runnable {
            return Err(ControlError::NotEnoughData {
                metric: "experiment grid",
                needed: "a run (nothing to run: its cases are estimation cases and its only \
                         estimator is none, the uncompensated plant, which runs in \
                         compensation cases only)",
                got: 0,
            });
        }
        self.scenario.validate()
    }

    /// The runs of `cases` (one case, or several tables' copies of it:
    /// [`Case::same_run`]), one per repeat, the plant drawn from the
    /// repeat's seed; estimators made by `make` (called once per estimator
    /// and run). An estimation case runs open loop, so its estimators share
    /// each run ([`Fanout`]: the same plant, frames and losses); a
    /// compensation case gets one estimator, `None` being the uncompensated
    /// plant. Each run is handed to `on_run` once per case; for each case,
    /// one record per estimator, in `estimators`' order.
    fn run_case(
        &self,
        cases: &[&Case],
        estimators: &[EstimatorKind],
        make: &MakeEstimator<'_>,
        on_run: &OnRun<'_>,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<Vec<Vec<Record>>> {
        // the cases are one run (`Case::same_run`): the first one's
        let Some(&case) = cases.first() else {
            return Ok(Vec::new());
        };
        let mut scenario = self.scenario.clone();
        scenario.frames.occlusion = case.occlusion.occlusion();
        scenario.compensator = match (case.kind, estimators) {
            (CaseKind::Compensation, [e]) if *e != EstimatorKind::None => {
                Some(scenario.compensator.unwrap_or_default())
            }
            _ => None,
        };
        let n = estimators.len();
        let (mut rmse, mut metrics) = (vec![Vec::new(); n], Vec::new());
        let mut repeats = Vec::new();
        for r in 0..self.repeats {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                return Err(ControlError::Interrupted);
            }
            let seed = self.seed.wrapping_add(u64::from(r));
            let background = self.backgrounds[r as usize % self.backgrounds.len()];
            scenario.frames.background = background;
            // the case's sheath, noise and seed replace the plant's before
            // anything checks it (as `OpenLoopGrid` does)
            let mut base = self.plant;
            base.sheath_deg = case.sheath_deg;
            base.noise = self.noise;
            base.seed = seed;
            let mut plant = Plant::new(base.perturbed(seed, self.spread)?)?;
            let members = estimators
                .iter()
                .map(|&kind| match kind {
                    // the uncompensated plant: a loop with no estimate and no compensator
                    EstimatorKind::None => Ok(make_none()),
                    kind => make(kind),
                })
                .collect::<Result<Vec<_>>>()?;
            let mut all = Fanout::new(members);
            let trace: ClosedLoopTrace = scenario.run(&mut plant, &mut all, seed)?;
            // each estimator's estimates over the evaluated ticks
            let evaluated = trace.theta_hat_deg.len();
            let estimates: Vec<&[Option<f64>]> = all
                .hats
                .iter()
                .map(|h| &h[h.len().saturating_sub(evaluated)..])
                .collect();
            let details: Vec<&[TickDetails]> = all
                .details
                .iter()
                .map(|d| &d[d.len().saturating_sub(evaluated)..])
                .collect();
            for &case in cases {
                on_run(&GridRun {
                    case,
                    seed,
                    background,
                    scenario: &scenario,
                    estimators,
                    estimates: &estimates,
                    details: &details,
                    trace: &trace,
                })?;
            }
            match case.kind {
                CaseKind::Estimation => {
                    for ((out, estimate), &kind) in rmse.iter_mut().zip(&estimates).zip(estimators)
                    {
                        let r = estimation_rmse_deg(&trace.trace.theta_a_deg, estimate);
                        out.push(r.map_err(|e| match e {
                            ControlError::NotEnoughData { .. } => ControlError::NoEstimate {
                                estimator: kind.name(),
                                case: case.file_stem(),
                                seed,
                            },
                            e => e,
                        })?);
                    }
                }
                CaseKind::Compensation => {
                    let m: RunMetrics = trace.trace.metrics()?;
                    rmse[0].push(m.rmse_deg);
                    metrics.push(m);
                }
            }
            repeats.push((seed, background));
        }
        let pick =
            |f: fn(&RunMetrics) -> f64| MeanStd::of(&metrics.iter().map(f).collect::<Vec<_>>());
        let hysteresis = match case.kind {
            CaseKind::Estimation => None,
            CaseKind::Compensation => Some([
                pick(|m| m.max_hysteresis_deg)?,
                pick(|m| m.error_peak_to_peak_deg)?,
                pick(|m| m.peak_loss_deg)?,
            ]),
        };
        let records = estimators
            .iter()
            .zip(&rmse)
            .map(|(&estimator, rmse)| {
                Ok(Record {
                    case: case.clone(),
                    estimator,
                    rmse_deg: MeanStd::of(rmse)?,
                    hysteresis,
                    repeats: repeats.clone(),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        // each case its own records, the same figures under its own table
        Ok(cases
            .iter()
            .map(|&c| {
                records
                    .iter()
                    .map(|r| Record {
                        case: c.clone(),
                        ..r.clone()
                    })
                    .collect()
            })
            .collect())
    }

    /// Runs every case with every estimator (an estimator named twice runs
    /// once) on `jobs` threads (at least one; the records come in the grid's
    /// order whatever the count, and are the same); `make` builds a fresh estimator of a kind for each run
    /// (the paper's are loaded from their model files; see the feature
    /// `estimators`). An estimation case's estimators share its runs (the
    /// issue: all estimators on the same run), and a case that several
    /// tables hold runs once for all of them ([`ExperimentGrid::job_count`]).
    /// `progress` is called as jobs finish (an estimation case, or a
    /// compensation case with one estimator; the copies of a case finish
    /// with it) with the count of jobs done and their total, which counts
    /// the copies.
    ///
    /// # Errors
    /// Every setting is checked first ([`ExperimentGrid::validate`]); then a
    /// failure stops the grid (runs already started finish), and the first
    /// failure in the grid's order is returned: `make`'s error, a run's
    /// ([`ClosedLoopScenario::run`]) or its metrics' (an estimation run's
    /// estimator without a single estimate is [`ControlError::NoEstimate`]).
    pub fn run(
        &self,
        jobs: usize,
        make: &MakeEstimator<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Vec<Record>> {
        self.run_with(jobs, make, progress, &|_| Ok(()))
    }

    /// [`ExperimentGrid::run`], handing every run to `on_run` as it ends
    /// (on the thread that ran it; to log or plot it): its case, seed,
    /// scenario, trace and each estimator's estimates.
    ///
    /// # Errors
    /// As [`ExperimentGrid::run`], and `on_run`'s error, which stops the
    /// grid as a failed run does.
    pub fn run_with(
        &self,
        jobs: usize,
        make: &MakeEstimator<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
        on_run: &OnRun<'_>,
    ) -> Result<Vec<Record>> {
        let never = std::sync::atomic::AtomicBool::new(false);
        self.run_until(jobs, make, progress, on_run, &never)
    }

    /// How many jobs the grid runs: an estimation case is one (its
    /// estimators share each run), a compensation case one per estimator;
    /// an estimator named twice runs once, and cases of several tables that
    /// are the same run (the paper's Tables V and VI both hold the straight
    /// sheath without tape) run once for all of them. A run on more threads
    /// than this leaves the rest idle.
    #[must_use]
    pub fn job_count(&self) -> usize {
        let jobs = self.jobs();
        same_runs(&jobs).len()
    }

    /// The jobs: each case with the estimators on its runs.
    fn jobs(&self) -> Vec<(&Case, Vec<EstimatorKind>)> {
        // an estimator named twice runs once
        let mut estimators: Vec<EstimatorKind> = Vec::new();
        for &e in &self.estimators {
            if !estimators.contains(&e) {
                estimators.push(e);
            }
        }
        let estimating: Vec<EstimatorKind> = estimators
            .iter()
            .copied()
            .filter(|&e| e != EstimatorKind::None)
            .collect();
        self.cases
            .iter()
            .flat_map(|c| match c.kind {
                CaseKind::Estimation => vec![(c, estimating.clone())],
                CaseKind::Compensation => estimators.iter().map(|&e| (c, vec![e])).collect(),
            })
            .filter(|(_, e)| !e.is_empty())
            .collect()
    }

    /// [`ExperimentGrid::run_with`], stopping when `stop` is set (e.g. by a
    /// Ctrl-C handler): the runs in progress finish, no further run starts,
    /// and the grid returns [`ControlError::Interrupted`].
    ///
    /// # Errors
    /// As [`ExperimentGrid::run_with`]; [`ControlError::Interrupted`].
    pub fn run_until(
        &self,
        jobs: usize,
        make: &MakeEstimator<'_>,
        progress: &(dyn Fn(usize, usize) + Sync),
        on_run: &OnRun<'_>,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<Vec<Record>> {
        use std::sync::Mutex;
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        self.validate()?;
        let pairs = self.jobs();
        // the jobs that are one run, run once: their indices in `pairs`
        let runs = same_runs(&pairs);
        let results: Mutex<Vec<Option<Result<Vec<Record>>>>> =
            Mutex::new((0..pairs.len()).map(|_| None).collect());
        let (next, done, failed) = (
            AtomicUsize::new(0),
            AtomicUsize::new(0),
            AtomicBool::new(false),
        );
        let worker = || {
            loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= runs.len() || failed.load(Ordering::Relaxed) {
                    return;
                }
                let members = &runs[k];
                let cases: Vec<&Case> = members.iter().map(|&i| pairs[i].0).collect();
                let estimators = &pairs[members[0]].1;
                let result = self.run_case(&cases, estimators, make, on_run, stop);
                failed.fetch_or(result.is_err(), Ordering::Relaxed);
                if let Ok(mut r) = results.lock() {
                    match result {
                        Ok(records) => {
                            for (&i, records) in members.iter().zip(records) {
                                r[i] = Some(Ok(records));
                            }
                        }
                        // the error in the first member's place (the
                        // grid's order returns it before the others)
                        Err(e) => r[members[0]] = Some(Err(e)),
                    }
                }
                let finished = done.fetch_add(members.len(), Ordering::Relaxed) + members.len();
                progress(finished, pairs.len());
            }
        };
        let jobs = jobs.clamp(1, runs.len().max(1));
        if jobs == 1 {
            worker();
        } else {
            std::thread::scope(|scope| {
                for _ in 0..jobs {
                    scope.spawn(worker);
                }
            });
        }
        let results = results.into_inner().map_err(|_| ControlError::Worker {
            message: "an experiment thread panicked".into(),
        })?;
        if stop.load(Ordering::Relaxed) {
            return Err(ControlError::Interrupted);
        }
        let mut out = Vec::with_capacity(results.len());
        for r in results {
            match r {
                Some(r) => out.extend(r?),
                // not run: an earlier failure stopped the grid
                None => continue,
            }
        }
        Ok(out)
    }
}

/// Builds a fresh estimator of a kind for one run (shared by the grid's threads).
pub type MakeEstimator<'a> = dyn Fn(EstimatorKind) -> Result<Box<dyn AngleEstimator>> + Sync + 'a;

/// Called with every run of a grid as it ends ([`ExperimentGrid::run_with`]).
pub type OnRun<'a> = dyn Fn(&GridRun<'_>) -> Result<()> + Sync + 'a;

/// One run of a grid: a case, a repeat, and what came of it.
#[derive(Debug)]
pub struct GridRun<'a> {
    /// The case.
    pub case: &'a Case,
    /// The repeat's seed (plant, noise, frames).
    pub seed: u64,
    /// The repeat's background.
    pub background: Background,
    /// The scenario as run: the grid's, with the case's tape and, for a
    /// compensation run with an estimator, the compensator.
    pub scenario: &'a ClosedLoopScenario,
    /// The estimators on the run: several on an estimation run (they share
    /// it), one on a compensation run (`None`: the uncompensated plant).
    pub estimators: &'a [EstimatorKind],
    /// Each estimator's estimate after every evaluated tick, deg (`None`
    /// before it had one), aligned with `trace`.
    pub estimates: &'a [&'a [Option<f64>]],
    /// What went into each estimator's estimate after every evaluated tick
    /// ([`AngleEstimator::details`]), aligned with `estimates`.
    pub details: &'a [&'a [TickDetails]],
    /// The run; its `theta_hat_deg` is the first estimator's.
    pub trace: &'a ClosedLoopTrace,
}

#[cfg(feature = "mcap")]
impl GridRun<'_> {
    /// Writes the run's MCAP logs into `dir`, one per estimator on it (an
    /// estimation run's estimators share it; each log carries its own
    /// estimate as θ̂): `V_0deg_40pct-distal_kbjae_seed2020.mcap`. The
    /// paths written, in the run's estimator order.
    ///
    /// # Errors
    /// As [`ClosedLoopTrace::write_mcap`].
    pub fn write_logs(&self, dir: &std::path::Path) -> Result<Vec<std::path::PathBuf>> {
        let mut written = Vec::with_capacity(self.estimators.len());
        for (i, &estimator) in self.estimators.iter().enumerate() {
            let path = dir.join(format!(
                "{}_{}_seed{}.mcap",
                self.case.file_stem(),
                estimator.name(),
                self.seed
            ));
            let estimate = self.estimates.get(i).copied().unwrap_or(&[]);
            let details = self.details.get(i).copied().unwrap_or(&[]);
            self.trace.write_mcap_with_estimate(
                &path,
                self.scenario,
                self.seed,
                estimate,
                details,
            )?;
            written.push(path);
        }
        Ok(written)
    }
}

/// Several estimators on one run: every tick goes to each, the camera
/// renders what the most demanding of them asks for (the union of their
/// windows), and each one's estimates are kept. The loop's θ̂ is the first
/// one's (an estimation run has no compensator to use it). Their IBJAE
/// readers read each band of a frame once between them
/// ([`AngleEstimator::step_sharing`]).
struct Fanout {
    members: Vec<Box<dyn AngleEstimator>>,
    /// Each member's estimate after every tick, pre-roll included.
    hats: Vec<Vec<Option<f64>>>,
    /// Each member's details after every tick, pre-roll included.
    details: Vec<Vec<TickDetails>>,
    /// This tick's IBJAE readings, shared by the members.
    #[cfg(feature = "estimators")]
    reads: kflex_estimate::FrameReads,
}

impl Fanout {
    fn new(members: Vec<Box<dyn AngleEstimator>>) -> Self {
        let hats = vec![Vec::new(); members.len()];
        let details = vec![Vec::new(); members.len()];
        Self {
            members,
            hats,
            details,
            #[cfg(feature = "estimators")]
            reads: kflex_estimate::FrameReads::new(),
        }
    }
}

impl AngleEstimator for Fanout {
    fn frame_request(&self, command: kflex_model::Command) -> crate::FrameRequest {
        use crate::FrameRequest::{None as NoFrames, Pixels, Timing};
        self.members
            .iter()
            .map(|m| m.frame_request(command))
            .fold(NoFrames, |a, b| match (a, b) {
                (Pixels(x), Pixels(y)) => Pixels(x.union(&y)),
                (Pixels(x), _) | (_, Pixels(x)) => Pixels(x),
                (Timing, _) | (_, Timing) => Timing,
                _ => NoFrames,
            })
    }

    fn step(&mut self, tick: &crate::EstimatorTick<'_>) -> Result<Option<f64>> {
        #[cfg(feature = "estimators")]
        self.reads.clear();
        for ((m, hats), details) in self
            .members
            .iter_mut()
            .zip(&mut self.hats)
            .zip(&mut self.details)
        {
            #[cfg(feature = "estimators")]
            let hat = m.step_sharing(tick, &mut self.reads)?;
            #[cfg(not(feature = "estimators"))]
            let hat = m.step(tick)?;
            hats.push(hat);
            details.push(m.details().with_frame(tick.frame.is_some()));
        }
        Ok(self.hats.first().and_then(|h| h.last().copied().flatten()))
    }

    fn reset(&mut self) {
        for ((m, hats), details) in self
            .members
            .iter_mut()
            .zip(&mut self.hats)
            .zip(&mut self.details)
        {
            m.reset();
            hats.clear();
            details.clear();
        }
    }

    fn details(&self) -> TickDetails {
        self.details
            .first()
            .and_then(|d| d.last().copied())
            .unwrap_or_default()
    }
}

/// The estimator of the uncompensated plant: it asks for no frames and has
/// no estimate (its runs have no compensator).
fn make_none() -> Box<dyn AngleEstimator> {
    struct NoEstimate;
    impl AngleEstimator for NoEstimate {
        fn frame_request(&self, _command: kflex_model::Command) -> crate::FrameRequest {
            crate::FrameRequest::None
        }
        fn step(&mut self, _tick: &crate::EstimatorTick<'_>) -> Result<Option<f64>> {
            Ok(None)
        }
        fn reset(&mut self) {}
    }
    Box::new(NoEstimate)
}
