//! The paper's estimators in the closed loop (cargo feature `estimators`):
//! KBJAE, IBJAE alone and LBHJAE as [`AngleEstimator`]s.
//!
//! KBJAE reads no frames. IBJAE and LBHJAE ask the camera for the window
//! their next reading needs ([`Ibjae::window`], [`Lbhjae::frame_window`]),
//! so the loop renders that window only. A frame that arrives late may
//! have been taken for a band the estimator no longer reads (its estimate
//! moved meanwhile); only the bands the frame's window holds are read, and
//! a frame that holds none is not used.
//!
//! KBJAE reads θ_c with the master's rate θ_d': the crate docs say why
//! ("KBJAE's input in the closed loop").

use kflex_estimate::{FrameReads, Ibjae, IbjaeReading, Kbjae, Lbhjae, LbhjaeEstimate, RgbView};
use kflex_model::{Command, Roi};

use crate::closed_loop::{
    AngleEstimator, CameraFrame, EstimatorTick, FrameRequest, ReadingUse, TickDetails,
};
use crate::error::Result;

/// The pixels of a frame as IBJAE reads them (camera coordinates), where
/// the frame carries an image.
fn view<'a>(frame: &CameraFrame<'a>) -> Result<Option<RgbView<'a>>> {
    match (frame.image, frame.window) {
        (Some(image), Some(window)) => Ok(Some(RgbView::window(
            &image.rgb,
            window,
            3 * image.width as usize,
        )?)),
        _ => Ok(None),
    }
}

fn request(window: Option<Roi>) -> FrameRequest {
    window.map_or(FrameRequest::None, FrameRequest::Pixels)
}

/// IBJAE's reading as [`TickDetails`] has it (the fusion's fields `None`).
fn reading_details(r: Option<&IbjaeReading>) -> TickDetails {
    TickDetails {
        ibjae_deg: r.map(|r| r.theta_deg),
        ibjae_sigma_deg: r.map(|r| r.sigma_deg),
        ibjae_silhouette_iou: r.and_then(|r| r.silhouette_iou),
        ibjae_occluded: r.map(|r| r.occluded),
        ibjae_consistent_deg: r.and_then(|r| r.consistent_deg),
        ..TickDetails::default()
    }
}

/// An LBHJAE tick as [`TickDetails`] has it.
fn lbhjae_details(e: &LbhjaeEstimate) -> TickDetails {
    let (kbjae_use, _) = ReadingUse::of(e.fused.kbjae);
    let (ibjae_use, ibjae_nis) = ReadingUse::of(e.fused.ibjae);
    TickDetails {
        theta_hat_sigma_deg: Some(e.fused.covariance[0][0])
            .filter(|v| v.is_finite())
            .map(|v| v.max(0.0).sqrt()),
        theta_hat_rate_deg_per_s: Some(e.fused.theta_hat_rate_deg_per_s),
        theta_hat_covariance: Some(e.fused.covariance),
        kbjae_deg: Some(e.kbjae_deg),
        kbjae_use: Some(kbjae_use),
        ibjae_use: Some(ibjae_use),
        ibjae_nis,
        ..reading_details(e.ibjae.as_ref())
    }
}

/// KBJAE alone: θ̂ = θ_c + the predicted hysteresis error θ̃(θ_c, θ_d'),
/// every tick (the crate docs say why the master's rate).
impl AngleEstimator for Kbjae {
    fn frame_request(&self, _command: Command) -> FrameRequest {
        FrameRequest::None
    }

    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        Ok(Some(Kbjae::step_with_rate(
            self,
            tick.command.theta_c_deg,
            tick.theta_d_rate_deg_per_s,
            tick.dt_s,
        )?))
    }

    fn reset(&mut self) {
        Kbjae::reset(self);
    }
}

/// IBJAE alone: the angle of the last frame it could read, held between
/// frames (none before the first).
#[derive(Debug)]
pub struct IbjaeAlone {
    ibjae: Ibjae,
    last: Option<f64>,
    /// This tick's reading, where it read a frame.
    read: Option<IbjaeReading>,
}

impl IbjaeAlone {
    /// IBJAE with no reading yet.
    #[must_use]
    pub fn new(ibjae: Ibjae) -> Self {
        Self {
            ibjae,
            last: None,
            read: None,
        }
    }

    /// The bands to read at `translation_mm`, given the last reading.
    fn bands(&self, translation_mm: f64) -> Vec<usize> {
        self.ibjae.bands_for(self.last, translation_mm)
    }

    /// A tick, sharing the frame's readings through `reads` where given.
    fn step_reading(
        &mut self,
        tick: &EstimatorTick<'_>,
        reads: Option<&mut FrameReads>,
    ) -> Result<Option<f64>> {
        self.read = None;
        let Some(frame) = &tick.frame else {
            return Ok(self.last);
        };
        let (Some(view), Some(window)) = (view(frame)?, frame.window) else {
            return Ok(self.last);
        };
        let mut bands = self.bands(frame.command.translation_mm);
        bands.retain(|&b| window.holds(&self.ibjae.bands()[b].band.roi));
        let reading = match reads {
            Some(reads) => self.ibjae.read_sharing(&view, &bands, reads)?,
            None => self.ibjae.read(&view, &bands)?,
        };
        if let Some(reading) = reading {
            self.last = Some(reading.theta_deg);
            self.read = Some(reading);
        }
        Ok(self.last)
    }
}

impl AngleEstimator for IbjaeAlone {
    fn frame_request(&self, command: Command) -> FrameRequest {
        request(self.ibjae.window(&self.bands(command.translation_mm)))
    }

    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        self.step_reading(tick, None)
    }

    fn step_sharing(
        &mut self,
        tick: &EstimatorTick<'_>,
        reads: &mut FrameReads,
    ) -> Result<Option<f64>> {
        self.step_reading(tick, Some(reads))
    }

    fn reset(&mut self) {
        self.last = None;
        self.read = None;
    }

    fn details(&self) -> TickDetails {
        reading_details(self.read.as_ref())
    }
}

/// LBHJAE: KBJAE every tick (on θ_c and the master's rate), IBJAE on each
/// usable frame, fused.
impl AngleEstimator for Lbhjae {
    fn frame_request(&self, command: Command) -> FrameRequest {
        request(self.frame_window(command.translation_mm))
    }

    fn step(&mut self, tick: &EstimatorTick<'_>) -> Result<Option<f64>> {
        lbhjae_tick(self, tick, None)
    }

    fn step_sharing(
        &mut self,
        tick: &EstimatorTick<'_>,
        reads: &mut FrameReads,
    ) -> Result<Option<f64>> {
        lbhjae_tick(self, tick, Some(reads))
    }

    fn reset(&mut self) {
        Lbhjae::reset(self);
    }

    fn details(&self) -> TickDetails {
        self.last_estimate()
            .map(|e| lbhjae_details(&e))
            .unwrap_or_default()
    }
}

/// An LBHJAE tick in the loop: the frame read where its window holds the
/// window the estimator needs now, sharing its readings through `reads`
/// where given.
fn lbhjae_tick(
    lbhjae: &mut Lbhjae,
    tick: &EstimatorTick<'_>,
    reads: Option<&mut FrameReads>,
) -> Result<Option<f64>> {
    let mut frame_view = None;
    if let Some(frame) = &tick.frame
        && let Some(v) = view(frame)?
    {
        let needed = lbhjae.frame_window(tick.command.translation_mm);
        if frame
            .window
            .zip(needed)
            .is_some_and(|(have, need)| have.holds(&need))
        {
            frame_view = Some(v);
        }
    }
    let (command, rate, dt) = (tick.command, tick.theta_d_rate_deg_per_s, tick.dt_s);
    let estimate = match reads {
        Some(reads) => {
            lbhjae.step_with_rate_sharing(command, rate, dt, frame_view.as_ref(), reads)?
        }
        None => lbhjae.step_with_rate(command, rate, dt, frame_view.as_ref())?,
    };
    Ok(Some(estimate.fused.theta_hat_deg))
}
