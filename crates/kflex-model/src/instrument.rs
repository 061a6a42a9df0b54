//! The instrument's shape as it leaves the overtube, for a bend θ and a translation d.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::joint::JointParams;
use crate::range::Bounds;
use crate::workspace::{TranslationParams, check_pose};

/// Shape parameters beyond the joint's (which come from [`JointParams`]). Lengths in mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InstrumentParams {
    /// Centre of the instrument channel on the overtube face, (x, y), mm.
    pub channel_offset_mm: [f64; 2],
    /// Radius of the shaft between the channel and the joint, mm.
    pub shaft_radius_mm: f64,
    /// Radius of each gripper jaw, mm.
    pub jaw_radius_mm: f64,
    /// Opening angle between the jaws, deg.
    pub jaw_opening_deg: f64,
}

impl Default for InstrumentParams {
    fn default() -> Self {
        Self {
            channel_offset_mm: [0.0, 5.0],
            shaft_radius_mm: 2.0,
            jaw_radius_mm: 0.8,
            jaw_opening_deg: 30.0,
        }
    }
}

impl InstrumentParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range:
    /// `channel_offset_mm.x` or `.y` outside `[-100, 100]` mm,
    /// `shaft_radius_mm` or `jaw_radius_mm` outside `(0, 100)` mm,
    /// `jaw_opening_deg` outside `[0, 170]` deg (NaN is out of every range).
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(-100.0, 100.0).check("channel_offset_mm.x", self.channel_offset_mm[0])?;
        Bounds::closed(-100.0, 100.0).check("channel_offset_mm.y", self.channel_offset_mm[1])?;
        Bounds::open(0.0, 100.0).check("shaft_radius_mm", self.shaft_radius_mm)?;
        Bounds::open(0.0, 100.0).check("jaw_radius_mm", self.jaw_radius_mm)?;
        Bounds::closed(0.0, 170.0).check("jaw_opening_deg", self.jaw_opening_deg)?;
        Ok(())
    }
}

/// Which part of the instrument a capsule belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Part {
    /// The straight shaft out of the channel.
    Shaft,
    /// Link `j` of the bending joint, 0 proximal.
    Link(u8),
    /// Gripper jaw 0 or 1.
    Jaw(u8),
}

/// A capsule: all points within `radius_mm` of the segment `a_mm`–`b_mm` (overtube frame, mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Capsule {
    /// Proximal end of the axis, mm.
    pub a_mm: [f64; 3],
    /// Distal end of the axis, mm.
    pub b_mm: [f64; 3],
    /// Radius, mm.
    pub radius_mm: f64,
    /// Whether the proximal end is capped by a hemisphere (false where it sits inside the channel).
    pub cap_a: bool,
    /// Which part it is.
    pub part: Part,
}

/// The instrument's shape at one pose: capsules from the channel to the jaw tips.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InstrumentShape {
    /// Capsules, proximal first.
    pub capsules: Vec<Capsule>,
    /// The tool tip (mid-point between the jaw tips), overtube frame, mm.
    pub tip_mm: [f64; 3],
}

/// Builds shapes from (θ, d), checking both against the workspace.
///
/// One definition serves the rasterizer and the mechanics: the bending joint's
/// links are [`JointParams`]'s (`2n` links of `link_length_mm`, radius
/// `link_radius_mm`, equal contact angles `θ/2n` as in Eq. 1), the tool is
/// [`JointParams::tool_length_mm`] long. The shape is a set of capsules in the
/// **overtube frame**: origin at the centre of the overtube's distal face, `+z`
/// along the overtube (the view direction of the camera mounted there), `+y`
/// down in the image, `+x` right. The instrument channel exits the face at
/// [`InstrumentParams::channel_offset_mm`]; the instrument's shaft extends `d`
/// from it; the joint bends about `+y`, so positive θ swings the tip toward `+x`.
/// The gripper's two jaws open symmetrically in the plane across the bend.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instrument {
    /// Joint and tool dimensions (shared with the mechanics).
    pub joint: JointParams,
    /// Shape parameters.
    pub params: InstrumentParams,
    /// Segments of the bending joint `n`.
    pub n_segments: u32,
    /// Translation limits.
    pub translation: TranslationParams,
}

impl Instrument {
    /// Validated instrument.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first parameter out of its range:
    /// of `joint` ([`JointParams::validate`]), of `params`
    /// ([`InstrumentParams::validate`]), `n_segments` outside `[1, 16]`, or of
    /// `translation` ([`TranslationParams::validate`]), checked in that order.
    ///
    /// [`ModelError::OutOfRange`]: crate::ModelError::OutOfRange
    pub fn new(
        joint: JointParams,
        params: InstrumentParams,
        n_segments: u32,
        translation: TranslationParams,
    ) -> Result<Self> {
        let out = Self {
            joint,
            params,
            n_segments,
            translation,
        };
        out.validate()?;
        Ok(out)
    }

    /// Checks every parameter (the fields are public, so an instrument can
    /// be built without [`Instrument::new`]).
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the first parameter out of its
    /// range (the joint's, the shape's, `n_segments` in [1, 16], the
    /// translation stage's).
    pub fn validate(&self) -> Result<()> {
        self.joint.validate()?;
        self.params.validate()?;
        Bounds::closed(1.0, 16.0).check("n_segments", f64::from(self.n_segments))?;
        self.translation.validate()?;
        Ok(())
    }

    /// The default K-FLEX-scale instrument (the plant's defaults).
    #[must_use]
    pub fn kflex() -> Self {
        Self {
            joint: JointParams::default(),
            params: InstrumentParams::default(),
            n_segments: 2,
            translation: TranslationParams::default(),
        }
    }

    /// The shape at bend `theta_deg` and translation `translation_mm`.
    ///
    /// # Errors
    /// [`ModelError::NonFinite`] for a NaN or infinite `theta_deg` or
    /// `translation_mm`; [`ModelError::OutOfWorkspace`] naming `theta_deg` past
    /// the joint's hard stops `±joint.max_theta_deg`, or `translation_mm`
    /// outside the stage's travel `[translation.min_mm, translation.max_mm]`.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    /// [`ModelError::OutOfWorkspace`]: crate::ModelError::OutOfWorkspace
    pub fn shape(&self, theta_deg: f64, translation_mm: f64) -> Result<InstrumentShape> {
        let mut out = InstrumentShape {
            capsules: Vec::with_capacity(2 * self.n_segments as usize + 3),
            tip_mm: [0.0; 3],
        };
        self.shape_into(theta_deg, translation_mm, &mut out)?;
        Ok(out)
    }

    /// [`Instrument::shape`] into an existing shape, reusing its allocation.
    ///
    /// # Errors
    /// As [`Instrument::shape`]; `out` is then left unchanged.
    pub fn shape_into(
        &self,
        theta_deg: f64,
        translation_mm: f64,
        out: &mut InstrumentShape,
    ) -> Result<()> {
        check_pose(
            self.joint.max_theta_deg,
            &self.translation,
            "theta_deg",
            theta_deg,
            translation_mm,
        )?;
        let [ox, oy] = self.params.channel_offset_mm;
        let two_n = 2 * self.n_segments as usize;
        let phi = theta_deg.to_radians() / two_n as f64;
        let l = self.joint.link_length_mm;
        out.capsules.clear();
        let mut p = [ox, oy, translation_mm];
        out.capsules.push(Capsule {
            a_mm: [ox, oy, 0.0],
            b_mm: p,
            radius_mm: self.params.shaft_radius_mm,
            cap_a: false,
            part: Part::Shaft,
        });
        let mut heading = 0.0;
        for j in 0..two_n {
            heading += phi;
            let next = [p[0] + l * heading.sin(), p[1], p[2] + l * heading.cos()];
            out.capsules.push(Capsule {
                a_mm: p,
                b_mm: next,
                radius_mm: self.joint.link_radius_mm,
                cap_a: true,
                part: Part::Link(j as u8),
            });
            p = next;
        }
        let half = 0.5 * self.params.jaw_opening_deg.to_radians();
        let lt = self.joint.tool_length_mm;
        let (s, c) = heading.sin_cos();
        for (k, side) in [(0u8, -1.0f64), (1, 1.0)] {
            let dir = [s * half.cos(), side * half.sin(), c * half.cos()];
            let end = [p[0] + lt * dir[0], p[1] + lt * dir[1], p[2] + lt * dir[2]];
            out.capsules.push(Capsule {
                a_mm: p,
                b_mm: end,
                radius_mm: self.params.jaw_radius_mm,
                cap_a: true,
                part: Part::Jaw(k),
            });
        }
        out.tip_mm = [p[0] + lt * half.cos() * s, p[1], p[2] + lt * half.cos() * c];
        Ok(())
    }
}
