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

/// Which part of the instrument a body belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Part {
    /// The straight shaft out of the channel.
    Shaft,
    /// Link `j` of the bending joint, 0 proximal: its disc and the piece of
    /// the backbone (tendons and spine) through it.
    Link(u8),
    /// The gripper's clevis: the housing behind the jaws and the pivot pin.
    Clevis,
    /// Gripper jaw 0 or 1.
    Jaw(u8),
}

/// How a body's ends are closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Ends {
    /// Hemispheres: a capsule.
    Round,
    /// Flat discs: a cylinder.
    Flat,
}

/// A body of revolution: all points within `radius_mm` of the segment
/// `a_mm`–`b_mm` (overtube frame, mm), its ends rounded (a capsule) or cut
/// flat (a cylinder).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Body {
    /// Proximal end of the axis, mm.
    pub a_mm: [f64; 3],
    /// Distal end of the axis, mm.
    pub b_mm: [f64; 3],
    /// Radius, mm.
    pub radius_mm: f64,
    /// Rounded or flat ends.
    pub ends: Ends,
    /// Which part it is.
    pub part: Part,
    /// Arc length along the instrument's centre line at `a_mm` and at
    /// `b_mm`, from the channel's exit, mm (what tape bands are placed by).
    pub arc_mm: [f64; 2],
}

/// The instrument's shape at one pose: bodies from the channel to the jaw tips.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct InstrumentShape {
    /// Bodies, proximal first.
    pub bodies: Vec<Body>,
    /// The tool tip (mid-point between the jaw tips), overtube frame, mm.
    pub tip_mm: [f64; 3],
}

impl InstrumentShape {
    /// The translation d the shape was built at: the arc length where its
    /// shaft ends, out of the channel (0 for a shape without a shaft).
    #[must_use]
    pub fn translation_mm(&self) -> f64 {
        self.bodies
            .iter()
            .find(|b| b.part == Part::Shaft)
            .map_or(0.0, |b| b.arc_mm[1])
    }

    /// The bend θ the shape shows, deg: the heading of its clevis (the tool
    /// past the joint) from the shaft's axis, in the plane it bends in (0 for
    /// a shape without a clevis).
    #[must_use]
    pub fn bend_deg(&self) -> f64 {
        self.bodies
            .iter()
            .find(|b| b.part == Part::Clevis)
            .map_or(0.0, |b| {
                (b.b_mm[0] - b.a_mm[0])
                    .atan2(b.b_mm[2] - b.a_mm[2])
                    .to_degrees()
            })
    }
}

/// Axial gap between neighbouring discs of the joint, as a share of a link's length.
const DISC_GAP: f64 = 0.2;
/// Radius of the backbone (tendons and spine) seen through the gaps, as a share of the links'.
const BACKBONE: f64 = 0.45;
/// Length of the clevis (jaw housing up to the pivot), as a share of the tool's length.
const CLEVIS: f64 = 0.3;
/// Radius of the clevis, as a share of the links'.
const CLEVIS_RADIUS: f64 = 0.8;
/// Radius and half-length of the pivot pin, as shares of the links' radius.
const PIN_RADIUS: f64 = 0.3;
const PIN_HALF_LENGTH: f64 = 0.9;
/// Where a jaw's heel ends, as a share of its length, and its tip's radius as a share of the heel's.
const JAW_HEEL: f64 = 0.5;
const JAW_TIP: f64 = 0.55;

/// Builds shapes from (θ, d), checking both against the workspace.
///
/// One definition serves the ray caster and the mechanics: the bending joint's
/// links are [`JointParams`]'s (`2n` links of `link_length_mm`, radius
/// `link_radius_mm`, equal contact angles `θ/2n` as in Eq. 1), the tool is
/// [`JointParams::tool_length_mm`] long. The shape is a set of [`Body`]s in the
/// **overtube frame**: origin at the centre of the overtube's distal face, `+z`
/// along the overtube (the view direction of the camera mounted there), `+y`
/// down in the image, `+x` right. The instrument channel exits the face at
/// [`InstrumentParams::channel_offset_mm`]; the instrument's shaft extends `d`
/// from it; the joint bends about `+y`, so positive θ swings the tip toward `+x`.
/// The gripper's two jaws open symmetrically in the plane across the bend.
///
/// What a surgeon would recognise: each link is a disc (a flat-ended
/// cylinder) a fifth of a link shorter than the link, so neighbouring discs
/// leave a gap that opens on the outside of the bend, with the backbone
/// (tendons and spine, 0.45 of the links' radius) across it; the tool is a
/// clevis (0.3 of the tool's length) carrying a pivot pin, and two jaws that
/// taper from heel to tip, hinged at the pin.
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
    /// As [`Instrument::validate`] for a parameter out of its range (the
    /// fields are public); [`ModelError::NonFinite`] for a NaN or infinite `theta_deg` or
    /// `translation_mm`; [`ModelError::OutOfWorkspace`] naming `theta_deg` past
    /// the joint's hard stops `±joint.max_theta_deg`, or `translation_mm`
    /// outside the stage's travel `[translation.min_mm, translation.max_mm]`.
    ///
    /// [`ModelError::NonFinite`]: crate::ModelError::NonFinite
    /// [`ModelError::OutOfWorkspace`]: crate::ModelError::OutOfWorkspace
    pub fn shape(&self, theta_deg: f64, translation_mm: f64) -> Result<InstrumentShape> {
        let mut out = InstrumentShape::default();
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
        let two_n = 2 * self.n_segments as usize;
        let (l, r) = (self.joint.link_length_mm, self.joint.link_radius_mm);
        self.build(theta_deg, translation_mm, out, |_| {
            (l, r, 1.0 / two_n as f64)
        })
    }

    /// The shape at bend `theta_deg` and translation `translation_mm`, with
    /// link `j`'s length, radius and share of the bend from `link(j)` (the
    /// shares sum to 1).
    pub(crate) fn build(
        &self,
        theta_deg: f64,
        translation_mm: f64,
        out: &mut InstrumentShape,
        link: impl Fn(usize) -> (f64, f64, f64),
    ) -> Result<()> {
        // the fields are public: checked before anything is sized by them
        self.validate()?;
        check_pose(
            self.joint.max_theta_deg,
            &self.translation,
            "theta_deg",
            theta_deg,
            translation_mm,
        )?;
        let [ox, oy] = self.params.channel_offset_mm;
        let two_n = 2 * self.n_segments as usize;
        let theta = theta_deg.to_radians();
        let r = self.joint.link_radius_mm;
        out.bodies.clear();
        let mut p = [ox, oy, translation_mm];
        out.bodies.push(Body {
            a_mm: [ox, oy, 0.0],
            b_mm: p,
            radius_mm: self.params.shaft_radius_mm,
            ends: Ends::Flat,
            part: Part::Shaft,
            arc_mm: [0.0, translation_mm],
        });
        let along = |p: [f64; 3], dir: [f64; 3], t: f64| {
            [p[0] + t * dir[0], p[1] + t * dir[1], p[2] + t * dir[2]]
        };
        let mut arc = translation_mm;
        let mut heading = 0.0;
        for j in 0..two_n {
            let (l, r, share) = link(j);
            let gap = DISC_GAP * l;
            heading += theta * share;
            let dir = [heading.sin(), 0.0, heading.cos()];
            let next = along(p, dir, l);
            // the link's disc, short of its contacts by half a gap at each end
            out.bodies.push(Body {
                a_mm: along(p, dir, 0.5 * gap),
                b_mm: along(p, dir, l - 0.5 * gap),
                radius_mm: r,
                ends: Ends::Flat,
                part: Part::Link(j as u8),
                arc_mm: [arc + 0.5 * gap, arc + l - 0.5 * gap],
            });
            // the backbone through it, seen in the gaps
            out.bodies.push(Body {
                a_mm: p,
                b_mm: next,
                radius_mm: BACKBONE * r,
                ends: Ends::Round,
                part: Part::Link(j as u8),
                arc_mm: [arc, arc + l],
            });
            p = next;
            arc += l;
        }
        let (s, c) = heading.sin_cos();
        let h = [s, 0.0, c];
        let lt = self.joint.tool_length_mm;
        let (clevis, jaw) = (CLEVIS * lt, (1.0 - CLEVIS) * lt);
        let pivot = along(p, h, clevis);
        out.bodies.push(Body {
            a_mm: p,
            b_mm: pivot,
            radius_mm: CLEVIS_RADIUS * r,
            ends: Ends::Flat,
            part: Part::Clevis,
            arc_mm: [arc, arc + clevis],
        });
        // the pin, across the plane the jaws open in
        let pin = [c, 0.0, -s];
        let half_pin = PIN_HALF_LENGTH * r;
        out.bodies.push(Body {
            a_mm: along(pivot, pin, -half_pin),
            b_mm: along(pivot, pin, half_pin),
            radius_mm: PIN_RADIUS * r,
            ends: Ends::Flat,
            part: Part::Clevis,
            arc_mm: [arc + clevis, arc + clevis],
        });
        arc += clevis;
        let half = 0.5 * self.params.jaw_opening_deg.to_radians();
        let rj = self.params.jaw_radius_mm;
        for (k, side) in [(0u8, -1.0f64), (1, 1.0)] {
            let dir = [s * half.cos(), side * half.sin(), c * half.cos()];
            let mid = along(pivot, dir, JAW_HEEL * jaw);
            let end = along(pivot, dir, jaw);
            // a jaw tapers from its heel to its tip
            out.bodies.push(Body {
                a_mm: pivot,
                b_mm: mid,
                radius_mm: rj,
                ends: Ends::Round,
                part: Part::Jaw(k),
                arc_mm: [arc, arc + JAW_HEEL * jaw],
            });
            out.bodies.push(Body {
                a_mm: mid,
                b_mm: end,
                radius_mm: JAW_TIP * rj,
                ends: Ends::Round,
                part: Part::Jaw(k),
                arc_mm: [arc + JAW_HEEL * jaw, arc + jaw],
            });
        }
        out.tip_mm = along(pivot, h, jaw * half.cos());
        Ok(())
    }
}
