//! The reality gap: an instrument and a camera as they were built and
//! mounted, drawn from manufacturing and calibration tolerances around the
//! nominal (CAD) design.
//!
//! The paper's retrieval database is rendered from a CAD model while its
//! queries come from a real camera on a real robot; that gap is why IBJAE
//! needs a learned similarity and still errs by 2.99° unoccluded (its
//! Table V). kflex keeps the gap: the simulated robot's frames come from a
//! [`BuiltInstrument`] seen by an as-built [`Camera`]
//! ([`BuildTolerances::camera`]), the database from the nominal ones.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::camera::Camera;
use crate::error::Result;
use crate::instrument::{Instrument, InstrumentShape};
use crate::range::Bounds;

/// Standard deviations of an as-built instrument's and camera's deviations
/// from their nominal design. Every deviation is drawn independently
/// from a normal distribution of this standard deviation, clipped to ±3 σ.
///
/// The defaults, and why:
/// * **Links**: length and disc radius 1 % (±0.04 mm on a 4 mm link:
///   laser-cut and machined miniature parts with assembly play).
/// * **Curvature**: each link's share of the bend 15 % (tendon-driven
///   rolling joints bend unevenly: friction at each contact loads the
///   proximal contacts first).
/// * **Camera mounting**: 0.5° of rotation about each axis and 0.15 mm of
///   translation along each: what is left after a hand–eye calibration.
/// * **Intrinsics**: focal lengths 1 %, principal point 2 px, the division
///   coefficient 0.008 (5 % of the nominal −0.15): a checkerboard
///   calibration of a wide-angle endoscope.
///
/// Sized so that the plainest retrieval — the nearest raw 48×48 silhouette
/// of the nominal model (database every 0.5°), for as-built frames (drawn
/// per frame), unoccluded, exact masks — errs by 2–4° RMSE over
/// θ ∈ [0°, 50°] at d = 10 mm, the paper's operating range: it measures
/// 3.00° over 500 frames (0.56° with no gap), against the paper's IBJAE at
/// 2.99° unoccluded. With every size doubled it would be 7.2°, with half of
/// them 1.8°. `tools/reality_gap.sh` measures it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BuildTolerances {
    /// Relative standard deviation of each link's length.
    pub link_length: f64,
    /// Relative standard deviation of each link's disc radius.
    pub link_radius: f64,
    /// Relative standard deviation of each link's share of the bend.
    pub curvature: f64,
    /// Standard deviation of the camera's mounting rotation about each axis, deg.
    pub camera_rotation_deg: f64,
    /// Standard deviation of the camera's mounting offset along each axis, mm.
    pub camera_offset_mm: f64,
    /// Relative standard deviation of each focal length.
    pub focal: f64,
    /// Standard deviation of each principal-point coordinate, px (of the full frame).
    pub principal_px: f64,
    /// Standard deviation of the lens's division coefficient.
    pub division: f64,
}

impl Default for BuildTolerances {
    fn default() -> Self {
        Self {
            link_length: 0.01,
            link_radius: 0.01,
            curvature: 0.15,
            camera_rotation_deg: 0.5,
            camera_offset_mm: 0.15,
            focal: 0.01,
            principal_px: 2.0,
            division: 0.008,
        }
    }
}

impl BuildTolerances {
    /// No deviation: the as-built instrument and camera are the nominal ones.
    pub const NONE: BuildTolerances = BuildTolerances {
        link_length: 0.0,
        link_radius: 0.0,
        curvature: 0.0,
        camera_rotation_deg: 0.0,
        camera_offset_mm: 0.0,
        focal: 0.0,
        principal_px: 0.0,
        division: 0.0,
    };

    /// Checks the sizes.
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the first out of its range:
    /// `link_length`, `link_radius`, `curvature` and `focal` in [0, 0.1]
    /// (curvature [0, 0.3]: a 3 σ share stays positive), `camera_rotation_deg`
    /// in [0, 10], `camera_offset_mm` in [0, 5], `principal_px` in [0, 50],
    /// `division` in [0, 0.1].
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(0.0, 0.1).check("link_length", self.link_length)?;
        Bounds::closed(0.0, 0.1).check("link_radius", self.link_radius)?;
        Bounds::closed(0.0, 0.3).check("curvature", self.curvature)?;
        Bounds::closed(0.0, 10.0).check("camera_rotation_deg", self.camera_rotation_deg)?;
        Bounds::closed(0.0, 5.0).check("camera_offset_mm", self.camera_offset_mm)?;
        Bounds::closed(0.0, 0.1).check("focal", self.focal)?;
        Bounds::closed(0.0, 50.0).check("principal_px", self.principal_px)?;
        Bounds::closed(0.0, 0.1).check("division", self.division)?;
        Ok(())
    }

    /// `nominal` as built: each link's length, radius and share of the bend
    /// drawn with seed `seed`.
    ///
    /// # Errors
    /// As [`BuildTolerances::validate`] and [`Instrument::validate`].
    pub fn instrument(&self, nominal: &Instrument, seed: u64) -> Result<BuiltInstrument> {
        self.validate()?;
        nominal.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6275_696c_7400_0001);
        let two_n = 2 * nominal.n_segments as usize;
        let mut links = Vec::with_capacity(two_n);
        for _ in 0..two_n {
            let length = nominal.joint.link_length_mm * (1.0 + normal(&mut rng, self.link_length));
            let radius = nominal.joint.link_radius_mm * (1.0 + normal(&mut rng, self.link_radius));
            let weight = 1.0 + normal(&mut rng, self.curvature);
            links.push((length, radius, weight));
        }
        let total: f64 = links.iter().map(|l| l.2).sum();
        links.iter_mut().for_each(|l| l.2 /= total);
        Ok(BuiltInstrument {
            nominal: *nominal,
            links,
        })
    }

    /// `nominal` as mounted and calibrated: its pose, intrinsics and lens
    /// off by the tolerances, drawn with seed `seed`. The intrinsics'
    /// deviations are sized for the full frame and scale with a region's.
    ///
    /// # Errors
    /// As [`BuildTolerances::validate`] and [`Camera::validate`] (the lens's
    /// drawn coefficient is kept inside its valid range).
    pub fn camera(&self, nominal: &Camera, seed: u64) -> Result<Camera> {
        self.validate()?;
        nominal.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6361_6d65_7261_0002);
        let mut rot = || normal(&mut rng, self.camera_rotation_deg).to_radians();
        let rotation = UnitQuaternion::from_euler_angles(rot(), rot(), rot());
        let mut off = || normal(&mut rng, self.camera_offset_mm);
        let offset = Translation3::new(off(), off(), off());
        let mut out = *nominal;
        out.camera_from_overtube =
            Isometry3::from_parts(offset, rotation) * nominal.camera_from_overtube;
        let k = &mut out.intrinsics;
        k.fx *= 1.0 + normal(&mut rng, self.focal);
        k.fy *= 1.0 + normal(&mut rng, self.focal);
        k.cx += normal(&mut rng, self.principal_px);
        k.cy += normal(&mut rng, self.principal_px);
        let drawn = nominal.lens.division + normal(&mut rng, self.division);
        out.lens.division = drawn.min(0.0);
        if out.validate().is_err() {
            out.lens.division = nominal.lens.division;
        }
        out.validate()?;
        Ok(out)
    }
}

/// A normal deviate of standard deviation `sigma`, clipped to ±3 σ.
fn normal(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma <= 0.0 {
        return 0.0;
    }
    // Box–Muller from two uniforms in (0, 1]
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random::<f64>();
    let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
    sigma * z.clamp(-3.0, 3.0)
}

/// An instrument as built: the nominal design with each link's own length,
/// disc radius and share of the bend ([`BuildTolerances::instrument`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BuiltInstrument {
    /// The design it was built to.
    pub nominal: Instrument,
    /// Per link, proximal first: length (mm), disc radius (mm), share of the bend (summing to 1).
    pub links: Vec<(f64, f64, f64)>,
}

impl BuiltInstrument {
    /// The shape at bend `theta_deg` and translation `translation_mm`, as
    /// [`Instrument::shape`] with this instrument's links.
    ///
    /// # Errors
    /// As [`Instrument::shape`].
    pub fn shape(&self, theta_deg: f64, translation_mm: f64) -> Result<InstrumentShape> {
        let mut out = InstrumentShape::default();
        self.shape_into(theta_deg, translation_mm, &mut out)?;
        Ok(out)
    }

    /// [`BuiltInstrument::shape`] into an existing shape, reusing its allocation.
    ///
    /// # Errors
    /// As [`Instrument::shape`]; [`crate::ModelError::OutOfRange`] naming
    /// `links.len()` when there is not one entry per link (`2n`), or a link's
    /// length or radius outside `(0, 100]` mm or share of the bend outside
    /// `[0, 1]`.
    pub fn shape_into(
        &self,
        theta_deg: f64,
        translation_mm: f64,
        out: &mut InstrumentShape,
    ) -> Result<()> {
        let two_n = 2.0 * f64::from(self.nominal.n_segments);
        Bounds::closed(two_n, two_n).check("links.len()", self.links.len() as f64)?;
        // the links are public too: a NaN would draw nothing, silently
        for &(length, radius, share) in &self.links {
            Bounds::open_closed(0.0, 100.0).check("links length_mm", length)?;
            Bounds::open_closed(0.0, 100.0).check("links radius_mm", radius)?;
            Bounds::closed(0.0, 1.0).check("links share", share)?;
        }
        let links = &self.links;
        self.nominal.build(theta_deg, translation_mm, out, |j| {
            links[j.min(links.len() - 1)]
        })
    }
}
