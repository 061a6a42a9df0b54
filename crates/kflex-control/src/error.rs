//! The one error type of `kflex-control`.

use kflex_estimate::EstimateError;
use kflex_model::{ModelError, RangeError};
use thiserror::Error;

/// What can go wrong running experiments or computing metrics.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ControlError {
    /// The plant or a trajectory refused its input.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// An estimation stage failed (e.g. the segmentation found no
    /// instrument in any frame drawn for a data set's query).
    #[error(transparent)]
    Estimate(#[from] EstimateError),
    /// A worker thread of a data-set generator stopped without a result.
    #[error("{message}")]
    Worker {
        /// What happened.
        message: String,
    },
    /// Something a run needs is not there (e.g. the trained model of an
    /// estimator a grid names).
    #[error("{what}")]
    Unavailable {
        /// What is missing, and what to do.
        what: String,
    },
    /// The user asked the run to stop (e.g. Ctrl-C, seen by a grid's
    /// `on_run`): nothing after the runs in progress was started.
    #[error("interrupted")]
    Interrupted,
    /// A log file could not be written.
    #[error("{path}: {message}")]
    Log {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
    /// A setting of this crate is outside its range.
    #[error(transparent)]
    OutOfRange(#[from] RangeError),
    /// Two cases of a grid would share their logs' and figures' names
    /// ([`crate::Case::file_stem`], compared without case, as some file
    /// systems do): the same sheath and occlusion, and table names that
    /// are the same in file names.
    #[error(
        "cases {first} and {second} (counting from 1) would share the file name {stem} \
         (file names keep letters, digits, - and . of a table's name and ignore case): \
         give them table names that differ there (a table holds one kind of experiment)"
    )]
    SharedCaseName {
        /// The first case's place in the grid, from 1.
        first: usize,
        /// The second's.
        second: usize,
        /// The name both would have.
        stem: String,
    },
    /// A value of one of a grid's cases out of its range.
    #[error("case {case} ({stem}): {error}")]
    CaseOutOfRange {
        /// The case's place in the grid, from 1.
        case: usize,
        /// The case, as its files are named.
        stem: String,
        /// The value and its range.
        error: RangeError,
    },
    /// A grid's base seed so large that a repeat's (`seed + r`) would wrap
    /// past the largest 64-bit seed to 0.
    #[error(
        "seed = {seed} with {repeats} repeats: repeat r runs on seed + r, which would \
         pass {max_seed}, the largest seed; give a seed of at most {largest_base}",
        max_seed = u64::MAX
    )]
    SeedOverflow {
        /// The base seed given.
        seed: u64,
        /// The repeats.
        repeats: u32,
        /// The largest base seed those repeats allow.
        largest_base: u64,
    },
    /// An estimator that gave no estimate on any evaluated tick of an
    /// estimation run, so that its error cannot be measured.
    #[error(
        "{estimator} gave no estimate in case {case} (seed {seed}): no camera frame reached \
         it, or none showed the instrument (see the scenario's camera.drop_probability \
         and camera.latency_s)"
    )]
    NoEstimate {
        /// The estimator's name.
        estimator: &'static str,
        /// The case, as its files are named.
        case: String,
        /// The repeat's seed.
        seed: u64,
    },
    /// A metric needs data it was not given.
    #[error("{metric} needs {needed}, got {got}")]
    NotEnoughData {
        /// Which metric.
        metric: &'static str,
        /// What it needs, in words.
        needed: &'static str,
        /// How much it got.
        got: usize,
    },
    /// A series handed to a metric holds a NaN or an infinity.
    #[error("{metric}: sample {index} is not finite ({value})")]
    NonFiniteSample {
        /// Which metric.
        metric: &'static str,
        /// Index of the first bad sample (counting the first series, then the second).
        index: usize,
        /// Its value.
        value: f64,
    },
}

impl ControlError {
    /// The range error behind this error (out of range or out of the
    /// workspace), whichever crate raised it.
    #[must_use]
    pub fn range(&self) -> Option<&RangeError> {
        match self {
            Self::OutOfRange(e) | Self::CaseOutOfRange { error: e, .. } => Some(e),
            Self::Model(e) => e.range(),
            Self::Estimate(e) => e.range(),
            _ => None,
        }
    }

    /// The line (counted from 1) of a TOML file's `text` that sets the
    /// value this error finds out of range: the one line of the form
    /// `key = value` with the error's field as its key and the error's
    /// value as its value. `None` for another error, or where no line or
    /// more than one fits (a value written inline, or one a program set).
    ///
    /// ```
    /// use kflex_control::ExperimentGrid;
    /// let text = "repeats = 0\n[scenario.motion]\nperiods = 1.0\n";
    /// let grid: ExperimentGrid = toml::from_str(text).unwrap();
    /// let e = grid.validate().unwrap_err();
    /// assert_eq!(e.line_in(text), Some(1));
    /// ```
    #[must_use]
    pub fn line_in(&self, text: &str) -> Option<usize> {
        let range = self.range()?;
        // "periods", or the last part of a dotted name ("lens.division")
        let key = range.name.split_whitespace().next()?.rsplit('.').next()?;
        let mut lines = text.lines().enumerate().filter(|(_, line)| {
            let Some(rest) = line.trim_start().strip_prefix(key) else {
                return false;
            };
            let Some(value) = rest.trim_start().strip_prefix('=') else {
                return false;
            };
            let value = value
                .split('#')
                .next()
                .unwrap_or("")
                .trim()
                .replace('_', "");
            value.parse::<f64>().ok() == Some(range.value)
        });
        let (at, _) = lines.next()?;
        lines.next().is_none().then_some(at + 1)
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, ControlError>;
