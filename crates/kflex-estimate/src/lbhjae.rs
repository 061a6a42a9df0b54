//! LBHJAE: KBJAE and IBJAE fused by a Kalman filter, as one estimator a
//! controller steps once per tick (cargo features `onnx` and `index`).

use kflex_model::{Bounds, Command, Num, Roi};

use crate::error::{EstimateError, Result};
use crate::fusion::{Estimate, Fusion, Measurements};
use crate::ibjae::{FrameReads, Ibjae, IbjaeReading, RgbView};
use crate::kbjae::Kbjae;

/// One tick of LBHJAE: the fused estimate and what each estimator read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LbhjaeEstimate {
    /// The fused estimate (θ̂, θ̂', covariance, what became of each reading).
    pub fused: Estimate,
    /// KBJAE's angle this tick, deg.
    pub kbjae_deg: f64,
    /// IBJAE's reading, `None` without a frame or with no instrument in it.
    pub ibjae: Option<IbjaeReading>,
}

/// The hybrid estimator: `step(command, dt, frame)` per control tick.
///
/// KBJAE runs every tick on the command sent to the plant. IBJAE runs when a
/// frame arrives (cameras are slower than control loops, and frames are
/// dropped): its database is chosen by the commanded translation and the
/// last fused bend ([`Ibjae::bands_for`]). Its per-frame uncertainty goes
/// to the filter with its angle (the paper's filter ignores it, the adaptive
/// one uses it).
pub struct Lbhjae {
    kbjae: Kbjae,
    ibjae: Ibjae,
    fusion: Box<dyn Fusion + Send>,
    started: bool,
    /// The bands of the frame being read (kept: a tick allocates nothing).
    bands: Vec<usize>,
    /// The last tick's estimate and readings.
    last: Option<LbhjaeEstimate>,
}

impl std::fmt::Debug for Lbhjae {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lbhjae")
            .field("kbjae", &self.kbjae)
            .field("ibjae", &self.ibjae)
            .field("estimate", &self.fusion.estimate())
            .finish_non_exhaustive()
    }
}

impl Lbhjae {
    /// Puts the three together.
    #[must_use]
    pub fn new(kbjae: Kbjae, ibjae: Ibjae, fusion: Box<dyn Fusion + Send>) -> Self {
        Self {
            kbjae,
            ibjae,
            fusion,
            started: false,
            bands: Vec::new(),
            last: None,
        }
    }

    /// Renders IBJAE's hidden-part silhouettes up front
    /// ([`Ibjae::prepare_hidden_parts`]), so that no later tick does.
    pub fn prepare_hidden_parts(&mut self) {
        self.ibjae.prepare_hidden_parts();
    }

    /// Whether no tick will render IBJAE's hidden-part silhouettes any more
    /// ([`Ibjae::hidden_parts_ready`]).
    #[must_use]
    pub fn hidden_parts_ready(&self) -> bool {
        self.ibjae.hidden_parts_ready()
    }

    /// The last tick's estimate and what each estimator read in it (as
    /// [`Lbhjae::step`] returned it); `None` before the first tick and
    /// after [`Lbhjae::reset`].
    #[must_use]
    pub fn last_estimate(&self) -> Option<LbhjaeEstimate> {
        self.last
    }

    /// The last fused bend, once there is one: IBJAE's hint for choosing
    /// its band ([`Ibjae::bands_for`]).
    fn hint(&self) -> Option<f64> {
        self.started.then(|| self.fusion.estimate().theta_hat_deg)
    }

    /// The window of the camera's image the next frame must cover, for a
    /// frame at `translation_mm` ([`Ibjae::window`] of the bands [`Lbhjae::step`]
    /// would read); `None` where no band holds the translation.
    #[must_use]
    pub fn frame_window(&self, translation_mm: f64) -> Option<Roi> {
        self.ibjae
            .window(&self.ibjae.bands_for(self.hint(), translation_mm))
    }

    /// One tick: the command sent to the plant this tick, `dt_s` after the
    /// last, and the camera's frame if one arrived.
    ///
    /// # Errors
    /// A non-finite command or a bad `dt_s`; with a frame, a translation no
    /// database of IBJAE holds ([`EstimateError::OutOfRange`] naming
    /// `translation_mm` and the databases' span, or
    /// [`EstimateError::NoBand`] for one in a gap between their bands); a
    /// frame whose regions do not fit it; faults of the models. The
    /// estimator is then unchanged. A frame
    /// with no instrument in it is no error: IBJAE's reading is missing.
    pub fn step(
        &mut self,
        command: Command,
        dt_s: f64,
        frame: Option<&RgbView>,
    ) -> Result<LbhjaeEstimate> {
        self.step_inner(command, None, dt_s, frame, None)
    }

    /// [`Lbhjae::step`] with KBJAE's rate input given
    /// ([`Kbjae::step_with_rate`]): in a compensated loop, the master's θ_d'.
    ///
    /// # Errors
    /// As [`Lbhjae::step`], and a non-finite rate.
    pub fn step_with_rate(
        &mut self,
        command: Command,
        rate_deg_per_s: f64,
        dt_s: f64,
        frame: Option<&RgbView>,
    ) -> Result<LbhjaeEstimate> {
        self.step_inner(command, Some(rate_deg_per_s), dt_s, frame, None)
    }

    /// [`Lbhjae::step_with_rate`] for one of several estimators reading the
    /// same frame: IBJAE takes the bands another reader of the same models
    /// read in it from `reads`, and leaves its own there
    /// ([`Ibjae::read_sharing`]); the estimate is the one
    /// [`Lbhjae::step_with_rate`] gives.
    ///
    /// # Errors
    /// As [`Lbhjae::step_with_rate`].
    pub fn step_with_rate_sharing(
        &mut self,
        command: Command,
        rate_deg_per_s: f64,
        dt_s: f64,
        frame: Option<&RgbView>,
        reads: &mut FrameReads,
    ) -> Result<LbhjaeEstimate> {
        self.step_inner(command, Some(rate_deg_per_s), dt_s, frame, Some(reads))
    }

    fn step_inner(
        &mut self,
        command: Command,
        rate_deg_per_s: Option<f64>,
        dt_s: f64,
        frame: Option<&RgbView>,
        reads: Option<&mut FrameReads>,
    ) -> Result<LbhjaeEstimate> {
        // every check before anything moves
        crate::fusion::check_inputs(dt_s, &Measurements::default())?;
        for (name, value) in [
            ("theta_c_deg", command.theta_c_deg),
            ("translation_mm", command.translation_mm),
            ("rate_deg_per_s", rate_deg_per_s.unwrap_or(0.0)),
        ] {
            if !value.is_finite() {
                return Err(kflex_model::ModelError::NonFinite { name, value }.into());
            }
        }
        let ibjae = match frame {
            Some(frame) => {
                let hint = self.hint();
                self.ibjae
                    .bands_for_into(hint, command.translation_mm, &mut self.bands);
                if self.bands.is_empty() {
                    // no database holds the translation: an error, not a
                    // fusion that quietly goes on without IBJAE
                    return Err(self.no_band_error(command.translation_mm));
                }
                match reads {
                    Some(reads) => self.ibjae.read_sharing(frame, &self.bands, reads)?,
                    None => self.ibjae.read(frame, &self.bands)?,
                }
            }
            None => None,
        };
        // KBJAE's history moves only once the fusion has taken the tick
        let (kbjae_deg, history) = self
            .kbjae
            .answer(command.theta_c_deg, rate_deg_per_s, dt_s)?;
        let fused = self.fusion.step(
            dt_s,
            Measurements {
                kbjae_deg: Some(kbjae_deg),
                ibjae_deg: ibjae.map(|r| r.theta_deg),
                ibjae_sigma_deg: ibjae.map(|r| r.sigma_deg),
                ibjae_occluded: ibjae.is_some_and(|r| r.occluded),
            },
        )?;
        self.kbjae.keep(history);
        self.started = true;
        let estimate = LbhjaeEstimate {
            fused,
            kbjae_deg,
            ibjae,
        };
        self.last = Some(estimate);
        Ok(estimate)
    }

    /// The error for a translation no database of IBJAE holds: out of the
    /// span of their bands, or in a gap between them (databases chosen
    /// by hand), naming the translations they hold.
    fn no_band_error(&self, translation_mm: f64) -> EstimateError {
        let mut held: Vec<[f64; 2]> = self
            .ibjae
            .bands()
            .iter()
            .map(|b| b.band.poses.translation_mm)
            .collect();
        held.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        held.dedup();
        let (lo, hi) = held
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), [d0, d1]| {
                (lo.min(*d0), hi.max(*d1))
            });
        if let Err(e) = Bounds::closed(lo, hi).check(
            "translation_mm (the translations IBJAE's databases hold)",
            translation_mm,
        ) {
            return e.into();
        }
        let spans: Vec<String> = held
            .iter()
            .map(|[d0, d1]| {
                if d0 == d1 {
                    format!("{}", Num(*d0))
                } else {
                    format!("[{}, {}]", Num(*d0), Num(*d1))
                }
            })
            .collect();
        EstimateError::NoBand {
            translation_mm,
            held: spans.join(", "),
        }
    }

    /// Back to the start: no command history, the filter at its initial state.
    pub fn reset(&mut self) {
        self.kbjae.reset();
        self.fusion.reset();
        self.started = false;
        self.last = None;
    }
}
