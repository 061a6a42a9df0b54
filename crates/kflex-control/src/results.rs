//! The grid's results as rows: the fields of `kflex-cli run --scenario`'s
//! `results.json` and of `kflex.run_experiment`'s records, with the paper's
//! figures beside ours (cargo feature `paper`).

use serde::Serialize;

use crate::error::Result;
use crate::grid::{CaseKind, ExperimentGrid, Record};
use crate::metrics::MeanStd;
use crate::paper::{PaperFigure, paper_figure};

/// One row of `results.json` and `results.csv`. Field names are stable:
/// later versions extend, never rename.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResultRow {
    /// "estimation" or "compensation".
    pub kind: &'static str,
    /// The paper's table ("V" … "X"), or a scenario's own name.
    pub table: String,
    /// The estimator's name ("none", "kbjae", …).
    pub estimator: &'static str,
    /// The sheath's bend, deg.
    pub sheath_deg: f64,
    /// "0%", "20%", "40%" or "40% distal".
    pub occlusion: &'static str,
    /// RMSE, mean over the repeats, deg. Estimation: the estimate against
    /// the true angle; compensation: the measured angle against θ_d.
    pub rmse_deg: f64,
    /// Its standard deviation over the repeats (n − 1), deg.
    pub rmse_std_deg: f64,
    /// Compensation: the loop width (the calibrated reading of the maximum
    /// hysteresis), deg.
    pub max_hysteresis_deg: Option<f64>,
    /// Its standard deviation, deg.
    pub max_hysteresis_std_deg: Option<f64>,
    /// Compensation: max e − min e, deg.
    pub error_peak_to_peak_deg: Option<f64>,
    /// Its standard deviation, deg.
    pub error_peak_to_peak_std_deg: Option<f64>,
    /// Compensation: max θ_d − max θ_a, deg.
    pub peak_loss_deg: Option<f64>,
    /// Its standard deviation, deg.
    pub peak_loss_std_deg: Option<f64>,
    /// The paper's RMSE for the case and estimator, where it has one, deg.
    pub paper_rmse_deg: Option<f64>,
    /// Its ±, deg.
    pub paper_rmse_std_deg: Option<f64>,
    /// The paper's maximum hysteresis (compensation), deg.
    pub paper_max_hysteresis_deg: Option<f64>,
    /// Its ±, deg.
    pub paper_max_hysteresis_std_deg: Option<f64>,
    /// Repeats run.
    pub repeats: usize,
    /// Each repeat's seed.
    pub seeds: Vec<u64>,
    /// Each repeat's background.
    pub backgrounds: Vec<String>,
    /// Periods of the input evaluated.
    pub periods: f64,
    /// The control tick, s.
    pub dt_s: f64,
}

impl ResultRow {
    /// The row of `record`, a record of `grid`, with the paper's figures
    /// beside it where the paper has them.
    ///
    /// # Errors
    /// As [`paper_figure`].
    pub fn of(record: &Record, grid: &ExperimentGrid) -> Result<ResultRow> {
        let case = &record.case;
        // the paper's tables V–VII are estimation, VIII–X compensation: a
        // case of the other kind has no paper figure
        let estimation_table = matches!(case.table.as_str(), "V" | "VI" | "VII");
        let (paper_rmse, paper_width) = if estimation_table == (case.kind == CaseKind::Estimation) {
            paper_figure(
                &case.table,
                record.estimator.name(),
                case.sheath_deg,
                case.occlusion.name(),
            )?
        } else {
            (None, None)
        };
        let h = |i: usize, f: fn(&MeanStd) -> f64| record.hysteresis.as_ref().map(|h| f(&h[i]));
        Ok(ResultRow {
            kind: case.kind.name(),
            table: case.table.clone(),
            estimator: record.estimator.name(),
            sheath_deg: case.sheath_deg,
            occlusion: case.occlusion.name(),
            rmse_deg: record.rmse_deg.mean,
            rmse_std_deg: record.rmse_deg.std,
            max_hysteresis_deg: h(0, |m| m.mean),
            max_hysteresis_std_deg: h(0, |m| m.std),
            error_peak_to_peak_deg: h(1, |m| m.mean),
            error_peak_to_peak_std_deg: h(1, |m| m.std),
            peak_loss_deg: h(2, |m| m.mean),
            peak_loss_std_deg: h(2, |m| m.std),
            paper_rmse_deg: paper_rmse.map(|f| f.mean),
            paper_rmse_std_deg: paper_rmse.map(|f| f.std),
            // the paper reports the maximum hysteresis of compensation runs only
            paper_max_hysteresis_deg: paper_width
                .filter(|_| case.kind == CaseKind::Compensation)
                .map(|f: PaperFigure| f.mean),
            paper_max_hysteresis_std_deg: paper_width
                .filter(|_| case.kind == CaseKind::Compensation)
                .map(|f: PaperFigure| f.std),
            repeats: record.repeats.len(),
            seeds: record.repeats.iter().map(|r| r.0).collect(),
            backgrounds: record
                .repeats
                .iter()
                .map(|r| r.1.name().to_owned())
                .collect(),
            periods: grid.scenario.motion.periods,
            dt_s: grid.scenario.motion.dt_s,
        })
    }
}
