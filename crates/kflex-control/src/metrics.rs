//! Metrics of the paper's experiments, defined once and used everywhere.

use serde::{Deserialize, Serialize};

use crate::error::{ControlError, Result};

/// Bin width in θ_d for the loop width, deg.
pub const LOOP_BIN_DEG: f64 = 1.0;

/// Root-mean-square of `actual − desired`.
///
/// # Errors
/// [`ControlError::NotEnoughData`] when the series are empty or of unequal
/// lengths; [`ControlError::NonFiniteSample`] for the first NaN or infinite
/// sample, indexed into `desired` followed by `actual`.
pub fn rmse(desired: &[f64], actual: &[f64]) -> Result<f64> {
    check_pair("rmse", desired, actual)?;
    let sum: f64 = desired
        .iter()
        .zip(actual)
        .map(|(d, a)| (a - d) * (a - d))
        .sum();
    Ok((sum / desired.len() as f64).sqrt())
}

/// `max e − min e` with `e = actual − desired`.
///
/// # Errors
/// [`ControlError::NotEnoughData`] when the series are empty or of unequal
/// lengths; [`ControlError::NonFiniteSample`] for the first NaN or infinite
/// sample, indexed into `desired` followed by `actual`.
pub fn error_peak_to_peak(desired: &[f64], actual: &[f64]) -> Result<f64> {
    check_pair("error_peak_to_peak", desired, actual)?;
    let (lo, hi) = desired
        .iter()
        .zip(actual)
        .map(|(d, a)| a - d)
        .fold((f64::MAX, f64::MIN), |(lo, hi), e| (lo.min(e), hi.max(e)));
    Ok(hi - lo)
}

/// Peak loss `max desired − max actual`: how far short of the command's
/// peak the output's peak falls (a third reading of the paper's "maximum
/// hysteresis size", reported beside the loop width).
///
/// # Errors
/// [`ControlError::NotEnoughData`] when the series are empty or of unequal
/// lengths; [`ControlError::NonFiniteSample`] for the first NaN or infinite
/// sample, indexed into `desired` followed by `actual`.
pub fn peak_loss(desired: &[f64], actual: &[f64]) -> Result<f64> {
    check_pair("peak_loss", desired, actual)?;
    let max = |v: &[f64]| v.iter().copied().fold(f64::MIN, f64::max);
    Ok(max(desired) - max(actual))
}

/// Hysteresis loop width (kflex's reading of the paper's "maximum hysteresis
/// size"), deg: the largest gap, at equal command, between the mean output on
/// the falling branch and on the rising branch, with the samples binned by
/// `desired` in bins of [`LOOP_BIN_DEG`]. A pure gain error or a constant
/// offset has width 0; a backlash of half-width `b` has width `2b`.
/// `rate` is the command's rate; samples with zero rate belong to neither branch.
///
/// # Errors
/// [`ControlError::NotEnoughData`] when the series are empty or of unequal
/// lengths, or when no bin holds both rising and falling samples;
/// [`ControlError::NonFiniteSample`] for the first NaN or infinite sample,
/// indexed into `desired` followed by `actual` (then, checked separately,
/// `desired` followed by `rate`).
///
/// * **RMSE**: `sqrt(mean((θ_a − θ_d)²))` over the evaluated samples.
/// * **Maximum hysteresis size** (the paper's Tables VIII–IX): the paper calls
///   it "the peak-to-peak error between the desired input and the measured
///   output", but its own Table IX (RMSE 21.9 deg, maximum hysteresis 18.4 deg
///   at 270 deg) rules out `max |θ_a − θ_d|`, which can never be below the
///   RMSE. kflex reads it as the **width of the hysteresis loop**: the largest
///   gap, at equal command θ_d, between the output on the falling branch
///   (θ_d decreasing) and on the rising branch (θ_d increasing). Computed by
///   binning the samples by θ_d (bins of [`LOOP_BIN_DEG`]), averaging θ_a in
///   each bin separately for rising and falling samples (by the sign of the
///   command's rate, which is exact), and taking the largest absolute
///   difference over the bins that have both. A pure gain error or a constant
///   offset has width 0; a backlash of half-width `b` has width `2b`.
/// * **Error peak-to-peak**, `max e − min e`, is reported beside it so the
///   literal reading can be compared too.
pub fn loop_width(desired: &[f64], rate: &[f64], actual: &[f64]) -> Result<f64> {
    check_pair("loop_width", desired, actual)?;
    check_pair("loop_width", desired, rate)?;
    let (lo, hi) = desired
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    // counted in f64 first: a span of 1e19 deg must not wrap the count
    let bins = ((hi - lo) / LOOP_BIN_DEG).floor().clamp(0.0, 99_999.0) as usize + 1;
    // (sum, count) for rising and falling in each bin
    let mut rising = vec![(0.0f64, 0u32); bins];
    let mut falling = vec![(0.0f64, 0u32); bins];
    for ((&d, &r), &a) in desired.iter().zip(rate).zip(actual) {
        let k = (((d - lo) / LOOP_BIN_DEG) as usize).min(bins - 1);
        let slot = if r > 0.0 {
            &mut rising[k]
        } else if r < 0.0 {
            &mut falling[k]
        } else {
            continue;
        };
        slot.0 += a;
        slot.1 += 1;
    }
    let widths: Vec<f64> = rising
        .iter()
        .zip(&falling)
        .filter(|(r, f)| r.1 > 0 && f.1 > 0)
        .map(|(r, f)| (f.0 / f64::from(f.1) - r.0 / f64::from(r.1)).abs())
        .collect();
    if widths.is_empty() {
        return Err(ControlError::NotEnoughData {
            metric: "loop_width",
            needed: "rising and falling samples at some common command angle",
            got: 0,
        });
    }
    Ok(widths.into_iter().fold(0.0, f64::max))
}

fn check_pair(metric: &'static str, a: &[f64], b: &[f64]) -> Result<()> {
    if a.is_empty() || a.len() != b.len() {
        return Err(ControlError::NotEnoughData {
            metric,
            needed: "two non-empty series of equal length",
            got: a.len().min(b.len()),
        });
    }
    if let Some((index, &value)) = a.iter().chain(b).enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(ControlError::NonFiniteSample {
            metric,
            index,
            value,
        });
    }
    Ok(())
}

/// Mean and sample standard deviation (n − 1; 0 for a single value).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MeanStd {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub std: f64,
}

impl MeanStd {
    /// Of a non-empty list.
    ///
    /// # Errors
    /// [`ControlError::NotEnoughData`] for an empty list;
    /// [`ControlError::NonFiniteSample`] for the first NaN or infinite value
    /// (a table's mean is never NaN).
    pub fn of(values: &[f64]) -> Result<Self> {
        if values.is_empty() {
            return Err(ControlError::NotEnoughData {
                metric: "mean",
                needed: "at least one value",
                got: 0,
            });
        }
        if let Some((index, &value)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(ControlError::NonFiniteSample {
                metric: "mean",
                index,
                value,
            });
        }
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let std = if values.len() > 1 {
            (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Ok(Self { mean, std })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kflex_model::Play;

    fn sine(n: usize) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        (
            t.iter().map(|t| 25.0 * t.sin() + 25.0).collect(),
            t.iter().map(|t| 25.0 * t.cos()).collect(),
        )
    }

    #[test]
    fn backlash_loop_is_twice_the_half_width() {
        let (d, r) = sine(3000);
        let mut play = Play::new(4.0, 25.0).unwrap();
        let a: Vec<f64> = d.iter().map(|&x| play.advance(x).unwrap()).collect();
        let w = loop_width(&d, &r, &a).unwrap();
        assert!((w - 8.0).abs() < 0.05, "{w}");
        // RMSE of a saturated backlash is close to its half-width, peak-to-peak to 2b
        assert!((error_peak_to_peak(&d, &a).unwrap() - 8.0).abs() < 1e-9);
        let e = rmse(&d, &a).unwrap();
        assert!(e > 3.0 && e < 4.0, "{e}");
    }

    #[test]
    fn gain_and_offset_have_no_loop_but_do_have_error() {
        let (d, r) = sine(3000);
        let a: Vec<f64> = d.iter().map(|x| 0.7 * x - 3.0).collect();
        let w = loop_width(&d, &r, &a).unwrap();
        assert!(w < 0.7 * LOOP_BIN_DEG, "{w}");
        assert!(rmse(&d, &a).unwrap() > 5.0);
        assert!(error_peak_to_peak(&d, &a).unwrap() > 14.0);
        // the output peaks where the command does, at 0.7 · 50 − 3 = 32
        let top = d.iter().copied().fold(f64::MIN, f64::max);
        assert!((peak_loss(&d, &a).unwrap() - (top - (0.7 * top - 3.0))).abs() < 1e-12);
    }

    #[test]
    fn peak_loss_compares_the_peaks_wherever_they_fall() {
        // the command peaks at 50, the output at 42 later in the run:
        // 8 short, whatever the lag between the peaks
        let d = [0.0, 25.0, 50.0, 25.0, 0.0, 10.0];
        let a = [0.0, 5.0, 30.0, 42.0, 20.0, 3.0];
        assert_eq!(peak_loss(&d, &a).unwrap(), 8.0);
        // an output that overshoots the command's peak loses a negative amount
        assert_eq!(
            peak_loss(&d, &[0.0, 0.0, 55.0, 0.0, 0.0, 0.0]).unwrap(),
            -5.0
        );
        assert!(matches!(
            peak_loss(&d, &[0.0; 5]),
            Err(ControlError::NotEnoughData {
                metric: "peak_loss",
                ..
            })
        ));
    }

    #[test]
    fn rmse_of_constant_error() {
        assert!((rmse(&[1.0, 2.0, 3.0], &[3.0, 4.0, 5.0]).unwrap() - 2.0).abs() < 1e-15);
    }

    #[test]
    fn bad_inputs_are_errors() {
        // a span too wide to count its bins is an error, not a panic (no
        // bin has both branches here)
        assert!(matches!(
            loop_width(&[0.0, 2e19], &[1.0, -1.0], &[0.0, 0.0]),
            Err(ControlError::NotEnoughData {
                metric: "loop_width",
                ..
            })
        ));
        assert!(matches!(
            rmse(&[], &[]),
            Err(ControlError::NotEnoughData {
                metric: "rmse",
                got: 0,
                ..
            })
        ));
        assert!(matches!(
            rmse(&[1.0], &[1.0, 2.0]),
            Err(ControlError::NotEnoughData {
                metric: "rmse",
                got: 1,
                ..
            })
        ));
        assert!(matches!(
            rmse(&[1.0, 2.0], &[1.0, f64::NAN]),
            Err(ControlError::NonFiniteSample { metric: "rmse", index: 3, value }) if value.is_nan()
        ));
        // monotone command: no falling branch
        assert!(matches!(
            loop_width(&[1.0, 2.0], &[1.0, 1.0], &[1.0, 2.0]),
            Err(ControlError::NotEnoughData {
                metric: "loop_width",
                got: 0,
                ..
            })
        ));
        assert!(matches!(
            MeanStd::of(&[]),
            Err(ControlError::NotEnoughData {
                metric: "mean",
                got: 0,
                ..
            })
        ));
        assert!(matches!(
            MeanStd::of(&[1.0, f64::NAN, f64::INFINITY]),
            Err(ControlError::NonFiniteSample {
                metric: "mean",
                index: 1,
                ..
            })
        ));
        let m = MeanStd::of(&[1.0, 3.0]).unwrap();
        assert_eq!(m.mean, 2.0);
        assert!((m.std - 2f64.sqrt()).abs() < 1e-15);
    }
}
