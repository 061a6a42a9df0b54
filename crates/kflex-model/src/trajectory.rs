//! Master-side command trajectories θ_d(t), all deterministic from a seed.
//!
//! Every trajectory gives the angle and its rate analytically, so the
//! velocity the paper's KBJAE takes as input is exact, not differenced.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::range::Bounds;

/// A commanded bending angle and its rate.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Sample {
    /// θ_d, deg.
    pub theta_d_deg: f64,
    /// dθ_d/dt, deg/s.
    pub theta_d_rate_deg_per_s: f64,
}

/// One sinusoid `offset + amplitude · sin(2π f t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sine {
    /// Amplitude, deg.
    pub amplitude_deg: f64,
    /// Offset, deg.
    pub offset_deg: f64,
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Phase, rad.
    pub phase_rad: f64,
}

impl Sine {
    /// The paper's test input: `θ_d(t) = 25 sin(t) + 25` deg at 0.159 Hz (≈ 1 rad/s).
    pub const PAPER: Sine = Sine {
        amplitude_deg: 25.0,
        offset_deg: 25.0,
        frequency_hz: 0.159,
        phase_rad: 0.0,
    };

    /// Period, s.
    #[must_use]
    pub fn period_s(&self) -> f64 {
        1.0 / self.frequency_hz
    }

    fn sample(&self, t: f64) -> Sample {
        let w = std::f64::consts::TAU * self.frequency_hz;
        // past about 10^15 rad the phase has lost a tenth of a radian to
        // rounding (and past f64's range it is infinite, whose sine is NaN):
        // there the time is taken modulo the period (exact in floating
        // point), which keeps the sample finite; below, the phase is the
        // plain product, as it always was
        let t = if (w * t).abs() < 1e15 {
            t
        } else {
            t.rem_euclid(self.period_s())
        };
        let (s, c) = (w * t + self.phase_rad).sin_cos();
        Sample {
            theta_d_deg: self.offset_deg + self.amplitude_deg * s,
            theta_d_rate_deg_per_s: self.amplitude_deg * w * c,
        }
    }
}

/// A trajectory, as data (serde-tagged by `kind`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Trajectory {
    /// One sinusoid (the paper's test input is [`Sine::PAPER`]).
    Sine(Sine),
    /// A sequence of raised-cosine cycles `θ = (A/2)(1 − cos 2πft)` from 0 to the
    /// peak `A` and back, several cycles per (amplitude, frequency) pair, one
    /// pair after the other: the shape of the paper's kinematic data set
    /// (Table III, "periodic signals of different amplitudes").
    PeriodicSet {
        /// (peak amplitude deg, frequency Hz) pairs, in order.
        legs: Vec<(f64, f64)>,
        /// Cycles of each pair.
        cycles_per_leg: u32,
    },
    /// Band-limited random, master-like motion within `[min_deg, max_deg]`:
    /// a sum of `components` sinusoids with random frequencies up to
    /// `cutoff_hz`, phases and 1/f amplitudes, scaled so it can never leave the range.
    BandLimited {
        /// Lower bound, deg.
        min_deg: f64,
        /// Upper bound, deg.
        max_deg: f64,
        /// Highest frequency, Hz.
        cutoff_hz: f64,
        /// Number of sinusoids.
        components: u32,
        /// Seed.
        seed: u64,
    },
    /// Steps between random levels in `[min_deg, max_deg]`, held `hold_s` each, smoothed over `ramp_s`.
    Steps {
        /// Lower bound, deg.
        min_deg: f64,
        /// Upper bound, deg.
        max_deg: f64,
        /// Time at each level, s.
        hold_s: f64,
        /// Raised-cosine ramp between levels, s (0 for ideal steps).
        ramp_s: f64,
        /// Seed.
        seed: u64,
    },
}

/// A trajectory ready to sample: validated, with its random draws made.
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectorySampler {
    kind: SamplerKind,
}

#[derive(Debug, Clone, PartialEq)]
enum SamplerKind {
    Sine(Sine),
    PeriodicSet {
        legs: Vec<(f64, f64, f64)>,
        cycles: f64,
    }, // (amp, freq, start time)
    Sum {
        offset: f64,
        parts: Vec<Sine>,
    },
    Steps {
        levels: Vec<f64>,
        hold: f64,
        ramp: f64,
    },
}

const STEP_LEVELS: usize = 4096;

impl Trajectory {
    /// The paper's test input.
    #[must_use]
    pub fn paper() -> Self {
        Trajectory::Sine(Sine::PAPER)
    }

    /// Validates and prepares for sampling.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range
    /// (NaN is out of every range):
    /// * `Sine`: `amplitude_deg` outside `[0, 360]`, `offset_deg` outside
    ///   `[-360, 360]`, `frequency_hz` outside `(0, 1000)`; and
    ///   [`ModelError::NonFinite`] for a NaN or infinite `phase_rad`;
    /// * `PeriodicSet`: `legs.len()` for no legs, `cycles_per_leg` outside
    ///   `[1, 1e6]`, a leg's `leg amplitude_deg` outside `[0, 360]` or
    ///   `leg frequency_hz` outside `[1e-6, 1000)` (a slower leg's cycles
    ///   would last an infinite time);
    /// * `BandLimited`: `min_deg` outside `[-360, 360]`, `max_deg` outside
    ///   `[min_deg, 360]`, `cutoff_hz` outside `[1e-6, 1000)`, `components`
    ///   outside `[1, 1024]`;
    /// * `Steps`: `min_deg` and `max_deg` as for `BandLimited`, `hold_s`
    ///   outside `(0, 1e6)`, `ramp_s` outside `[0, hold_s]` or in `(0, 1e-6)`.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    pub fn sampler(&self) -> Result<TrajectorySampler> {
        let kind = match self {
            Trajectory::Sine(s) => {
                Bounds::closed(0.0, 360.0).check("amplitude_deg", s.amplitude_deg)?;
                Bounds::closed(-360.0, 360.0).check("offset_deg", s.offset_deg)?;
                Bounds::open(0.0, 1e3).check("frequency_hz", s.frequency_hz)?;
                crate::error::finite("phase_rad", s.phase_rad)?;
                SamplerKind::Sine(*s)
            }
            Trajectory::PeriodicSet {
                legs,
                cycles_per_leg,
            } => {
                Bounds::closed_open(1.0, f64::INFINITY).check("legs.len()", legs.len() as f64)?;
                Bounds::closed(1.0, 1e6).check("cycles_per_leg", f64::from(*cycles_per_leg))?;
                let mut t0 = 0.0;
                let mut out = Vec::with_capacity(legs.len());
                for &(amp, f) in legs {
                    Bounds::closed(0.0, 360.0).check("leg amplitude_deg", amp)?;
                    Bounds::closed_open(1e-6, 1e3).check("leg frequency_hz", f)?;
                    out.push((amp, f, t0));
                    t0 += f64::from(*cycles_per_leg) / f;
                }
                SamplerKind::PeriodicSet {
                    legs: out,
                    cycles: f64::from(*cycles_per_leg),
                }
            }
            Trajectory::BandLimited {
                min_deg,
                max_deg,
                cutoff_hz,
                components,
                seed,
            } => {
                let (lo, hi) = range(*min_deg, *max_deg)?;
                // at least 1e-6 Hz: far lower, the 1/f amplitudes overflow
                Bounds::closed_open(1e-6, 1e3).check("cutoff_hz", *cutoff_hz)?;
                Bounds::closed(1.0, 1024.0).check("components", f64::from(*components))?;
                let mut rng = ChaCha8Rng::seed_from_u64(*seed);
                let mut parts: Vec<Sine> = (0..*components)
                    .map(|_| {
                        let f = cutoff_hz * rng.random_range(0.05..=1.0);
                        Sine {
                            amplitude_deg: 1.0 / f,
                            offset_deg: 0.0,
                            frequency_hz: f,
                            phase_rad: rng.random_range(0.0..std::f64::consts::TAU),
                        }
                    })
                    .collect();
                let total: f64 = parts.iter().map(|p| p.amplitude_deg).sum();
                let scale = 0.5 * (hi - lo) / total;
                for p in &mut parts {
                    p.amplitude_deg *= scale;
                }
                SamplerKind::Sum {
                    offset: 0.5 * (lo + hi),
                    parts,
                }
            }
            Trajectory::Steps {
                min_deg,
                max_deg,
                hold_s,
                ramp_s,
                seed,
            } => {
                let (lo, hi) = range(*min_deg, *max_deg)?;
                Bounds::open(0.0, 1e6).check("hold_s", *hold_s)?;
                Bounds::closed(0.0, *hold_s).check("ramp_s", *ramp_s)?;
                // a ramp is none or at least a microsecond (the rate divides by it)
                if *ramp_s > 0.0 && *ramp_s < 1e-6 {
                    Bounds::closed(1e-6, *hold_s).check("ramp_s", *ramp_s)?;
                }
                let mut rng = ChaCha8Rng::seed_from_u64(*seed);
                let levels = (0..STEP_LEVELS)
                    .map(|_| rng.random_range(lo..=hi))
                    .collect();
                SamplerKind::Steps {
                    levels,
                    hold: *hold_s,
                    ramp: *ramp_s,
                }
            }
        };
        Ok(TrajectorySampler { kind })
    }
}

fn range(lo: f64, hi: f64) -> Result<(f64, f64)> {
    Bounds::closed(-360.0, 360.0).check("min_deg", lo)?;
    Bounds::closed(lo, 360.0).check("max_deg", hi)?;
    Ok((lo, hi))
}

impl TrajectorySampler {
    /// θ_d and its rate at time `t` (s). Times before 0, and NaN or infinite
    /// times, give the sample at 0 (value and rate).
    #[must_use]
    pub fn sample(&self, t: f64) -> Sample {
        let t = if t.is_finite() { t.max(0.0) } else { 0.0 };
        match &self.kind {
            SamplerKind::Sine(s) => s.sample(t),
            SamplerKind::PeriodicSet { legs, cycles } => {
                let idx = legs.iter().rposition(|leg| leg.2 <= t).unwrap_or(0);
                let (amp, f, t0) = legs[idx];
                let local = t - t0;
                if local > cycles / f {
                    return Sample::default(); // after the last leg: at rest at 0
                }
                let w = std::f64::consts::TAU * f;
                Sample {
                    theta_d_deg: 0.5 * amp * (1.0 - (w * local).cos()),
                    theta_d_rate_deg_per_s: 0.5 * amp * w * (w * local).sin(),
                }
            }
            SamplerKind::Sum { offset, parts } => parts.iter().fold(
                Sample {
                    theta_d_deg: *offset,
                    theta_d_rate_deg_per_s: 0.0,
                },
                |acc, p| {
                    let s = p.sample(t);
                    Sample {
                        theta_d_deg: acc.theta_d_deg + s.theta_d_deg,
                        theta_d_rate_deg_per_s: acc.theta_d_rate_deg_per_s
                            + s.theta_d_rate_deg_per_s,
                    }
                },
            ),
            SamplerKind::Steps { levels, hold, ramp } => {
                let k = ((t / hold) as usize).min(levels.len() - 1);
                let into = t - k as f64 * hold;
                let to = levels[k];
                let from = if k == 0 { to } else { levels[k - 1] };
                if *ramp > 0.0 && into < *ramp {
                    let u = into / ramp;
                    let w = 0.5 * (1.0 - (std::f64::consts::PI * u).cos());
                    let dw = 0.5 * std::f64::consts::PI * (std::f64::consts::PI * u).sin() / ramp;
                    Sample {
                        theta_d_deg: from + (to - from) * w,
                        theta_d_rate_deg_per_s: (to - from) * dw,
                    }
                } else {
                    Sample {
                        theta_d_deg: to,
                        theta_d_rate_deg_per_s: 0.0,
                    }
                }
            }
        }
    }

    /// Length of a natural experiment on this trajectory, s, where it has one
    /// (the periodic set's total length); `None` for unbounded trajectories.
    #[must_use]
    pub fn natural_duration_s(&self) -> Option<f64> {
        match &self.kind {
            SamplerKind::PeriodicSet { legs, cycles } => {
                legs.last().map(|&(_, f, t0)| t0 + cycles / f)
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::expect_range;

    fn check_rate(s: &TrajectorySampler, t: f64) {
        let h = 1e-6;
        let num = (s.sample(t + h).theta_d_deg - s.sample(t - h).theta_d_deg) / (2.0 * h);
        let ana = s.sample(t).theta_d_rate_deg_per_s;
        assert!(
            (num - ana).abs() < 1e-3 * (1.0 + ana.abs()),
            "t={t}: {num} vs {ana}"
        );
    }

    #[test]
    fn paper_input_is_25_sin_t_plus_25() {
        let s = Trajectory::paper().sampler().unwrap();
        for t in [0.0, 0.5, 1.7, 10.0] {
            let expected = 25.0 * (std::f64::consts::TAU * 0.159 * t).sin() + 25.0;
            assert!((s.sample(t).theta_d_deg - expected).abs() < 1e-12);
            // 0.159 Hz is 1 rad/s to within 0.1%
            assert!((s.sample(t).theta_d_deg - (25.0 * t.sin() + 25.0)).abs() < 0.1 * (1.0 + t));
            check_rate(&s, t + 0.1);
        }
    }

    #[test]
    fn band_limited_stays_in_range_and_is_seeded() {
        let traj = Trajectory::BandLimited {
            min_deg: 0.0,
            max_deg: 50.0,
            cutoff_hz: 0.5,
            components: 12,
            seed: 7,
        };
        let s = traj.sampler().unwrap();
        let again = traj.sampler().unwrap();
        let other = Trajectory::BandLimited {
            min_deg: 0.0,
            max_deg: 50.0,
            cutoff_hz: 0.5,
            components: 12,
            seed: 8,
        }
        .sampler()
        .unwrap();
        let mut lo = f64::MAX;
        let mut hi = f64::MIN;
        let mut differs = false;
        for k in 0..20000 {
            let t = k as f64 * 0.01;
            let v = s.sample(t).theta_d_deg;
            assert_eq!(v, again.sample(t).theta_d_deg);
            differs |= (v - other.sample(t).theta_d_deg).abs() > 1.0;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        assert!(lo >= 0.0 && hi <= 50.0, "[{lo}, {hi}]");
        assert!(hi - lo > 15.0, "should use the range: [{lo}, {hi}]");
        assert!(differs);
        check_rate(&s, 3.3);
    }

    #[test]
    fn periodic_set_peaks_at_each_amplitude() {
        let traj = Trajectory::PeriodicSet {
            legs: vec![(35.0, 0.2), (45.0, 0.1)],
            cycles_per_leg: 2,
        };
        let s = traj.sampler().unwrap();
        assert_eq!(s.natural_duration_s(), Some(2.0 / 0.2 + 2.0 / 0.1));
        assert!((s.sample(2.5).theta_d_deg - 35.0).abs() < 1e-9); // first peak of leg 1
        assert!((s.sample(10.0 + 5.0).theta_d_deg - 45.0).abs() < 1e-9); // first peak of leg 2
        assert!(s.sample(10.0).theta_d_deg.abs() < 1e-9);
        check_rate(&s, 1.3);
    }

    #[test]
    fn steps_hold_levels_and_ramp() {
        let traj = Trajectory::Steps {
            min_deg: 0.0,
            max_deg: 50.0,
            hold_s: 2.0,
            ramp_s: 0.5,
            seed: 1,
        };
        let s = traj.sampler().unwrap();
        let a = s.sample(1.0).theta_d_deg;
        let b = s.sample(3.9).theta_d_deg;
        assert_eq!(s.sample(1.9).theta_d_deg, a);
        assert!((0.0..=50.0).contains(&a) && (0.0..=50.0).contains(&b));
        let mid = s.sample(2.25).theta_d_deg;
        assert!((mid - 0.5 * (a + b)).abs() < 1e-9);
        check_rate(&s, 2.2);
    }

    #[test]
    fn rejects_bad_specs() {
        let e = expect_range(
            Trajectory::Sine(Sine {
                frequency_hz: 0.0,
                ..Sine::PAPER
            })
            .sampler(),
            "frequency_hz",
        );
        assert_eq!(
            (e.value, e.bounds.min, e.bounds.min_inclusive),
            (0.0, 0.0, false)
        );
        let e = expect_range(
            Trajectory::PeriodicSet {
                legs: vec![],
                cycles_per_leg: 1,
            }
            .sampler(),
            "legs.len()",
        );
        assert_eq!(e.value, 0.0);
        let bad = Trajectory::BandLimited {
            min_deg: 10.0,
            max_deg: 0.0,
            cutoff_hz: 1.0,
            components: 3,
            seed: 0,
        };
        let e = expect_range(bad.sampler(), "max_deg");
        assert_eq!((e.value, e.bounds.min), (0.0, 10.0));
        let bad = Trajectory::Steps {
            min_deg: 0.0,
            max_deg: 1.0,
            hold_s: 1.0,
            ramp_s: 2.0,
            seed: 0,
        };
        let e = expect_range(bad.sampler(), "ramp_s");
        assert_eq!((e.value, e.bounds.max), (2.0, 1.0));
        // values whose arithmetic overflows to infinite or NaN commands
        let bad = Trajectory::BandLimited {
            min_deg: 0.0,
            max_deg: 10.0,
            cutoff_hz: 1e-308,
            components: 64,
            seed: 0,
        };
        expect_range(bad.sampler(), "cutoff_hz");
        let bad = Trajectory::Steps {
            min_deg: 0.0,
            max_deg: 1.0,
            hold_s: 1.0,
            ramp_s: 1e-309,
            seed: 0,
        };
        expect_range(bad.sampler(), "ramp_s");
        // a leg so slow that its cycles' duration is infinite
        let slow = Trajectory::PeriodicSet {
            legs: vec![(10.0, 0.1), (10.0, 1e-320)],
            cycles_per_leg: 2,
        };
        let e = expect_range(slow.sampler(), "leg frequency_hz");
        assert_eq!(e.bounds.min, 1e-6);
        let slowest = Trajectory::PeriodicSet {
            legs: vec![(10.0, 1e-6)],
            cycles_per_leg: 1_000_000,
        };
        let duration = slowest.sampler().unwrap().natural_duration_s().unwrap();
        assert!(duration.is_finite() && duration > 0.0);
    }

    /// Every finite time gives a finite command: a sine's phase `2πft`
    /// overflowed to infinity at t = 1e308 (1 Hz), whose sine is NaN.
    #[test]
    fn a_far_time_gives_a_finite_command() {
        let kinds = [
            Trajectory::Sine(Sine {
                frequency_hz: 1.0,
                ..Sine::PAPER
            }),
            Trajectory::BandLimited {
                min_deg: 0.0,
                max_deg: 50.0,
                cutoff_hz: 2.0,
                components: 8,
                seed: 3,
            },
            Trajectory::Steps {
                min_deg: 0.0,
                max_deg: 50.0,
                hold_s: 1.0,
                ramp_s: 0.5,
                seed: 3,
            },
            Trajectory::PeriodicSet {
                legs: vec![(35.0, 0.2)],
                cycles_per_leg: 2,
            },
        ];
        for kind in kinds {
            let sampler = kind.sampler().unwrap();
            for t in [1e15, 1e20, 1e300, 1e308, f64::MAX] {
                let s = sampler.sample(t);
                assert!(
                    s.theta_d_deg.is_finite() && s.theta_d_rate_deg_per_s.is_finite(),
                    "{kind:?} at {t}: {s:?}"
                );
                assert!(
                    (-360.0..=360.0).contains(&s.theta_d_deg),
                    "{kind:?} at {t}: {s:?}"
                );
            }
        }
        // below 1e15 rad of phase the sample is the plain product's, as before
        let sine = Sine::PAPER;
        let t = 1.0e6;
        let w = std::f64::consts::TAU * sine.frequency_hz;
        assert_eq!(
            sine.sample(t).theta_d_deg,
            sine.offset_deg + sine.amplitude_deg * (w * t).sin()
        );
    }
}
