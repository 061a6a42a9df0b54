//! The figures of a scenario run (`kflex-cli run --scenario … --out DIR`),
//! under `DIR/plots/`: per case, from its first repeat, the time series of
//! θ_d, θ_a and every estimate (`<case>_series`, the paper's Fig. 7) and
//! the hysteresis loops against θ_d (`<case>_loops`); per table, our RMSE
//! beside the paper's (`table_<T>_rmse`) and, for compensation tables, the
//! loop width beside the paper's maximum hysteresis (`table_<T>_width`).
//! Each as PNG and SVG.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::Result;
use kflex_control::{Case, CaseKind, EstimatorKind, ExperimentGrid, GridRun, ResultRow as Row};

use crate::plots::{
    BLACK_LINE, BLUE, BarGroup, BarPair, Bars, Curve, Figure, GREEN, GREY, Lines, ORANGE, PINK,
    Series, VERMILLION,
};
use kflex_control::safe_file_name;
use plotters::style::RGBColor;

/// An estimator's colour, the same in every figure.
fn colour(estimator: EstimatorKind) -> RGBColor {
    match estimator {
        EstimatorKind::None => GREY,
        EstimatorKind::Kbjae => BLUE,
        EstimatorKind::Ibjae => VERMILLION,
        EstimatorKind::Lbhjae => GREEN,
        EstimatorKind::LbhjaeAdaptive => PINK,
    }
}

/// At most this many samples of a series go into a figure (every k-th).
const MAX_POINTS: usize = 1600;

/// One estimator's part of a case's first repeat.
struct Member {
    estimator: EstimatorKind,
    /// θ_a of its run (an estimation case's estimators share one run).
    theta_a_deg: Vec<Option<f64>>,
    /// Its estimate, where it had one (`None` for the uncompensated plant).
    estimate_deg: Option<Vec<Option<f64>>>,
}

/// A case's first repeat, thinned to [`MAX_POINTS`].
#[derive(Default)]
struct CaseRun {
    time_s: Vec<f64>,
    theta_d_deg: Vec<f64>,
    members: Vec<Member>,
}

/// Keeps what the figures need from each case's first repeat as the runs end
/// (on whichever thread ran them).
pub struct Collector<'g> {
    grid: &'g ExperimentGrid,
    runs: Mutex<Vec<CaseRun>>,
}

impl<'g> Collector<'g> {
    pub fn new(grid: &'g ExperimentGrid) -> Self {
        Self {
            grid,
            runs: Mutex::new(grid.cases.iter().map(|_| CaseRun::default()).collect()),
        }
    }

    /// Takes `run` if it is its case's first repeat.
    pub fn take(&self, run: &GridRun<'_>) {
        if run.seed != self.grid.seed {
            return;
        }
        let Some(i) = self
            .grid
            .cases
            .iter()
            .position(|c| std::ptr::eq(c, run.case))
            .or_else(|| self.grid.cases.iter().position(|c| c == run.case))
        else {
            return;
        };
        let t = &run.trace.trace;
        let step = t.time_s.len().div_ceil(MAX_POINTS).max(1);
        let thin = |v: &[f64]| v.iter().step_by(step).copied().collect::<Vec<f64>>();
        let thin_opt = |v: &[Option<f64>]| v.iter().step_by(step).copied().collect::<Vec<_>>();
        let theta_a: Vec<Option<f64>> = thin(&t.theta_a_deg).into_iter().map(Some).collect();
        let Ok(mut runs) = self.runs.lock() else {
            return;
        };
        let case = &mut runs[i];
        if case.time_s.is_empty() {
            case.time_s = thin(&t.time_s);
            case.theta_d_deg = thin(&t.theta_d_deg);
        }
        for (k, &estimator) in run.estimators.iter().enumerate() {
            let estimate = (estimator != EstimatorKind::None)
                .then(|| run.estimates.get(k).map(|e| thin_opt(e)))
                .flatten();
            case.members.push(Member {
                estimator,
                theta_a_deg: theta_a.clone(),
                estimate_deg: estimate,
            });
        }
    }

    /// Draws every figure into `dir`; the paths written.
    pub fn write(self, dir: &Path, rows: &[Row]) -> Result<Vec<PathBuf>> {
        let grid = self.grid;
        let mut runs = self
            .runs
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let order = |e: &EstimatorKind| grid.estimators.iter().position(|g| g == e);
        let mut written = Vec::new();
        for (case, run) in grid.cases.iter().zip(runs.iter_mut()) {
            if run.time_s.is_empty() {
                continue;
            }
            run.members.sort_by_key(|m| order(&m.estimator));
            written.extend(case_figures(dir, case, run)?);
        }
        written.extend(table_figures(dir, grid, rows)?);
        Ok(written)
    }
}

/// How a case is named in a figure's title.
fn case_title(case: &Case) -> String {
    format!(
        "Table {} — sheath {}°, occlusion {}",
        case.table,
        case.sheath_deg,
        case.occlusion.name()
    )
}

/// A case's time series and loops.
fn case_figures(dir: &Path, case: &Case, run: &CaseRun) -> Result<Vec<PathBuf>> {
    let stem = case.file_stem();
    let theta_d: Vec<Option<f64>> = run.theta_d_deg.iter().copied().map(Some).collect();
    // (name, colour, values) of every line after θ_d
    let mut lines: Vec<(String, RGBColor, &[Option<f64>])> = Vec::new();
    match case.kind {
        CaseKind::Estimation => {
            if let Some(first) = run.members.first() {
                lines.push(("θ_a (true)".to_owned(), ORANGE, &first.theta_a_deg));
            }
            for m in &run.members {
                if let Some(e) = &m.estimate_deg {
                    lines.push((
                        format!("{} estimate", m.estimator.name()),
                        colour(m.estimator),
                        e,
                    ));
                }
            }
        }
        CaseKind::Compensation => {
            for m in &run.members {
                lines.push((
                    format!("θ_a with {}", m.estimator.name()),
                    colour(m.estimator),
                    &m.theta_a_deg,
                ));
            }
        }
    }
    let kind = match case.kind {
        CaseKind::Estimation => "estimation",
        CaseKind::Compensation => "compensation",
    };
    let mut series = vec![Series {
        name: "θ_d (command)".to_owned(),
        colour: BLACK_LINE,
        values: &theta_d,
    }];
    series.extend(lines.iter().map(|(name, colour, values)| Series {
        name: name.clone(),
        colour: *colour,
        values,
    }));
    let mut written = Lines::time_series(
        format!("{} ({kind}, first repeat)", case_title(case)),
        &run.time_s,
        series,
    )
    .write(dir, &format!("{stem}_series"))?;
    let loops = Lines {
        title: format!("{} — against the command", case_title(case)),
        x_desc: "θ_d (deg)",
        y_desc: "angle (deg)",
        curves: lines
            .iter()
            .map(|(name, colour, values)| Curve {
                name: name.clone(),
                colour: *colour,
                x: &run.theta_d_deg,
                y: values,
            })
            .collect(),
        diagonal: true,
    };
    written.extend(loops.write(dir, &format!("{stem}_loops"))?);
    Ok(written)
}

/// Each table's summary bars.
fn table_figures(dir: &Path, grid: &ExperimentGrid, rows: &[Row]) -> Result<Vec<PathBuf>> {
    let mut tables: Vec<&str> = Vec::new();
    for c in &grid.cases {
        if !tables.contains(&c.table.as_str()) {
            tables.push(&c.table);
        }
    }
    let mut written = Vec::new();
    for table in tables {
        let these: Vec<&Row> = rows.iter().filter(|r| r.table == table).collect();
        if these.is_empty() {
            // e.g. an estimation table run with `none` alone: nothing to draw
            continue;
        }
        // the table's estimators, in the grid's order
        let members: Vec<&'static str> = grid
            .estimators
            .iter()
            .map(|e| e.name())
            .filter(|name| these.iter().any(|r| r.estimator == *name))
            .collect();
        let cases: Vec<&Case> = grid.cases.iter().filter(|c| c.table == table).collect();
        let compensation = cases.iter().any(|c| c.kind == CaseKind::Compensation);
        let group = |case: &Case, figure: fn(&Row) -> BarPair| BarGroup {
            label: format!("{}°, {}", case.sheath_deg, case.occlusion.name()),
            bars: members
                .iter()
                .map(|m| {
                    these
                        .iter()
                        .find(|r| {
                            r.estimator == *m
                                && r.sheath_deg == case.sheath_deg
                                && r.occlusion == case.occlusion.name()
                        })
                        .map_or((None, None), |r| figure(r))
                })
                .collect(),
        };
        let names: Vec<(String, RGBColor)> = grid
            .estimators
            .iter()
            .filter(|e| members.contains(&e.name()))
            .map(|&e| (e.name().to_owned(), colour(e)))
            .collect();
        let what = if compensation {
            "RMSE of θ_a against θ_d"
        } else {
            "RMSE of each estimate against θ_a"
        };
        let rmse = Bars {
            title: format!("Table {table}: {what}, ours (solid) and the paper's (pale)"),
            y_desc: "RMSE (deg)",
            members: names.clone(),
            groups: cases
                .iter()
                .map(|c| {
                    group(c, |r| {
                        (
                            Some((r.rmse_deg, r.rmse_std_deg)),
                            r.paper_rmse_deg.zip(r.paper_rmse_std_deg),
                        )
                    })
                })
                .collect(),
        };
        let stem = format!("table_{}", safe_file_name(table));
        written.extend(rmse.write(dir, &format!("{stem}_rmse"))?);
        if compensation {
            let width = Bars {
                title: format!(
                    "Table {table}: maximum hysteresis (loop width), ours (solid) and the paper's (pale)"
                ),
                y_desc: "loop width (deg)",
                members: names,
                groups: cases
                    .iter()
                    .map(|c| {
                        group(c, |r| {
                            (
                                r.max_hysteresis_deg.zip(r.max_hysteresis_std_deg),
                                r.paper_max_hysteresis_deg
                                    .zip(r.paper_max_hysteresis_std_deg),
                            )
                        })
                    })
                    .collect(),
            };
            written.extend(width.write(dir, &format!("{stem}_width"))?);
        }
    }
    Ok(written)
}
