//! The working region of the camera: where the bending joint and the gripper
//! can appear. [`Roi::for_workspace`] projects them over every pose of a
//! [`PoseRange`] and takes the smallest box around them, so the region is
//! derived from the camera and the instrument, not typed in.
//! [`WorkingRegions`] splits a translation range into bands, each with its
//! own region, so that a far instrument is not a speck in a region sized for
//! a near one.

use serde::{Deserialize, Serialize};

use nalgebra::Point3;

use crate::camera::Camera;
use crate::error::{ModelError, Result};
use crate::instrument::{Instrument, InstrumentShape, Part};
use crate::range::{Bounds, RangeError};
use crate::raster;
use crate::roi::Roi;

/// The poses a working region must cover (see [`crate::Roi::for_workspace`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseRange {
    /// Bend θ from `[0]` to `[1]`, deg.
    pub theta_deg: [f64; 2],
    /// Translation d from `[0]` to `[1]`, mm.
    pub translation_mm: [f64; 2],
}

impl PoseRange {
    /// The paper's operating range: θ ∈ [0°, 50°] (its database and test
    /// input), at the 10 mm translation of its experiments.
    pub const PAPER: PoseRange = PoseRange {
        theta_deg: [0.0, 50.0],
        translation_mm: [10.0, 10.0],
    };

    /// The full range of the default camera and instrument: θ ∈ [−90°, 90°],
    /// d ∈ [8, 40] mm. The camera sits at the centre of the overtube's face
    /// (as the paper's does), 5 mm above the instrument's channel. Below
    /// d = 8 mm the bending joint starts beside the lens: its base falls
    /// below the frame's bottom edge and, bent to ±90°, the gripper leaves the
    /// frame's sides. So the default narrows the translation (the stage
    /// travels 0–40 mm) rather than move the camera off the overtube.
    pub const FULL: PoseRange = PoseRange {
        theta_deg: [-90.0, 90.0],
        translation_mm: [8.0, 40.0],
    };

    /// Whether the pose (bend `theta_deg`, translation `translation_mm`) lies
    /// in the range, ends included.
    #[must_use]
    pub fn contains(&self, theta_deg: f64, translation_mm: f64) -> bool {
        let [t0, t1] = self.theta_deg;
        let [d0, d1] = self.translation_mm;
        (t0..=t1).contains(&theta_deg) && (d0..=d1).contains(&translation_mm)
    }

    /// Checks the range against `instrument` (validated first) and returns
    /// the number of 1° bend and 1 mm translation steps that sample it.
    fn steps(&self, instrument: &Instrument) -> Result<(usize, usize)> {
        // a validated instrument bounds the poses (|θ| ≤ 170°, d ≤ 1 m), so
        // the sampling is at most 341 × 1001 poses before a pose out of the
        // workspace stops it
        instrument.validate()?;
        let [t0, t1] = self.theta_deg;
        let [d0, d1] = self.translation_mm;
        let any = Bounds::open(f64::NEG_INFINITY, f64::INFINITY);
        any.check("poses.theta_deg[0]", t0)?;
        any.check("poses.translation_mm[0]", d0)?;
        Bounds::closed(t0, f64::INFINITY).check("poses.theta_deg[1]", t1)?;
        Bounds::closed(d0, f64::INFINITY).check("poses.translation_mm[1]", d1)?;
        let reach = Bounds::closed(0.0, 2.0 * instrument.joint.max_theta_deg);
        reach.check("poses.theta_deg span", t1 - t0)?;
        Bounds::closed(0.0, instrument.translation.max_mm)
            .check("poses.translation_mm span", d1 - d0)?;
        Ok((
            ((t1 - t0).ceil() as usize).max(1),
            ((d1 - d0).ceil() as usize).max(1),
        ))
    }

    /// The `j`-th of `nd` translation samples, ends included.
    fn translation(&self, j: usize, nd: usize) -> f64 {
        let [d0, d1] = self.translation_mm;
        d0 + (d1 - d0) * j as f64 / nd as f64
    }
}

/// A box of pinhole directions `[x0, y0, x1, y1]`; `None` once something in
/// it reaches the camera's plane (no finite box holds it then).
type Extent = Option<[f64; 4]>;

/// The empty extent, which every union grows.
const EMPTY: Extent = Some([
    f64::INFINITY,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::NEG_INFINITY,
]);

fn union(a: Extent, b: Extent) -> Extent {
    a.zip(b).map(|(a, b)| {
        [
            a[0].min(b[0]),
            a[1].min(b[1]),
            a[2].max(b[2]),
            a[3].max(b[3]),
        ]
    })
}

/// The pinhole extent of the bending joint and gripper over the bends
/// `theta_deg` (in `nt` steps, ends included) at translation `d`.
///
/// Each body lies in the capsule of its radius, the convex hull of its two
/// end spheres; a pinhole maps that to the convex hull of their images,
/// whose box is where the planes through the centre of projection touch
/// them (`raster::pinhole_box`).
fn extent_at(
    camera: &Camera,
    instrument: &Instrument,
    [t0, t1]: [f64; 2],
    nt: usize,
    d: f64,
    shape: &mut InstrumentShape,
) -> Result<Extent> {
    let mut extent = EMPTY;
    for i in 0..=nt {
        let theta = t0 + (t1 - t0) * i as f64 / nt as f64;
        instrument.shape_into(theta, d, shape)?;
        for c in shape.bodies.iter().filter(|c| c.part != Part::Shaft) {
            for end in [c.a_mm, c.b_mm] {
                let centre = (camera.camera_from_overtube * Point3::from(end)).coords;
                extent = union(extent, raster::pinhole_box(centre, c.radius_mm));
            }
        }
    }
    Ok(extent)
}

/// The pixel region of `camera` that holds `extent` (the lens bends its box
/// of directions to a pixel box that holds everything in it,
/// `raster::image_box`), grown by `margin_px` on each side and clipped to
/// the image.
fn region_of(camera: &Camera, extent: Extent, margin_px: u32) -> Result<Roi> {
    // a sphere that reaches the camera's plane can cover any pixel
    let bbox = extent.map_or(
        [
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::INFINITY,
        ],
        |b| raster::image_box(camera, b),
    );
    let k = &camera.intrinsics;
    let (w, h) = (f64::from(k.width), f64::from(k.height));
    let m = f64::from(margin_px);
    let [u0, v0, u1, v1] = [
        (bbox[0] - m).max(0.0).floor(),
        (bbox[1] - m).max(0.0).floor(),
        (bbox[2] + m).min(w).ceil(),
        (bbox[3] + m).min(h).ceil(),
    ];
    if !(u1 > u0 && v1 > v0) {
        return Err(ModelError::NotInView {
            what: "the bending joint and gripper over this pose range",
        });
    }
    let roi = Roi {
        x0: u0 as u32,
        y0: v0 as u32,
        width: (u1 - u0) as u32,
        height: (v1 - v0) as u32,
    };
    roi.check_within(k.width, k.height)?;
    Ok(roi)
}

impl Roi {
    /// Margin of the working regions around the joint and gripper, px of the full frame.
    pub const WORKING_MARGIN_PX: u32 = 8;

    /// The working region of the paper's operating range
    /// ([`PoseRange::PAPER`]: θ ∈ [0°, 50°] at d = 10 mm): [`Roi::for_workspace`]
    /// of the K-FLEX instrument ([`Instrument::kflex`]) with
    /// [`Roi::WORKING_MARGIN_PX`]. For the full range see [`WorkingRegions`].
    ///
    /// # Errors
    /// As [`Roi::for_workspace`].
    pub fn paper(camera: &Camera) -> Result<Roi> {
        Self::for_workspace(
            camera,
            &Instrument::kflex(),
            &PoseRange::PAPER,
            Self::WORKING_MARGIN_PX,
        )
    }

    /// The smallest region (a box, not necessarily square) of `camera`'s
    /// image that contains the bending joint and the gripper for every pose
    /// in `poses`, plus `margin_px` on each side, clipped to the image.
    /// IBJAE resamples it to 48×48 whatever its shape, so a wide, short
    /// sweep keeps its detail across.
    ///
    /// The poses are sampled every 1° of bend and every 1 mm of translation
    /// (ends included). Each body lies in the capsule of its radius, the
    /// convex hull of its two end spheres; a pinhole maps that to the convex
    /// hull of their images, whose box is where the planes through the centre
    /// of projection touch them; the lens then bends that box of directions
    /// to a pixel box that holds everything in it (`raster::image_box`).
    /// Between two translation samples a distal body only slides along the
    /// camera's axis, so it stays inside the hull of its end spheres at the
    /// two samples: the translation sampling loses nothing. Between bend
    /// samples the tip moves by well under a pixel at the default camera,
    /// which the margin absorbs.
    ///
    /// # Examples
    /// ```
    /// use kflex_model::{Camera, Instrument, PoseRange, Roi};
    /// let camera = Camera::default();
    /// let roi = Roi::for_workspace(&camera, &Instrument::kflex(), &PoseRange::PAPER, 4)?;
    /// roi.check_within(camera.intrinsics.width, camera.intrinsics.height)?;
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// [`ModelError::OutOfWorkspace`] when a pose lies outside the
    /// instrument's workspace; [`ModelError::OutOfRange`] for an instrument
    /// parameter out of its range, or a reversed, non-finite or too wide pose
    /// range (a span past the workspace's); [`ModelError::NotInView`] when the
    /// distal part never comes into the image; as [`Camera::validate`] for a
    /// bad camera.
    pub fn for_workspace(
        camera: &Camera,
        instrument: &Instrument,
        poses: &PoseRange,
        margin_px: u32,
    ) -> Result<Roi> {
        camera.validate()?;
        let (nt, nd) = poses.steps(instrument)?;
        let mut shape = InstrumentShape::default();
        let mut extent = EMPTY;
        for j in 0..=nd {
            let d = poses.translation(j, nd);
            let e = extent_at(camera, instrument, poses.theta_deg, nt, d, &mut shape)?;
            extent = union(extent, e);
        }
        region_of(camera, extent, margin_px)
    }
}

/// One band of [`WorkingRegions`]: a part of the bends and a band of
/// translations, and the region that holds the joint and gripper over them.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorkingBand {
    /// The poses of the band.
    pub poses: PoseRange,
    /// The region that holds the joint and gripper over the band's poses.
    pub roi: Roi,
}

/// How [`WorkingRegions::for_workspace`] cuts a pose range into bands.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Banding {
    /// Margin around the joint and gripper, px of the full frame.
    pub margin_px: u32,
    /// A band of translations is as long as its region stays at most this
    /// many times, each side, the region of each translation in it (≥ 1).
    pub growth: f64,
    /// Parts the bend range is cut into, of equal span (1–16).
    pub theta_parts: u32,
    /// Each part reaches this far into its neighbours, deg (≥ 0): a pose
    /// near a cut lies well inside some part.
    pub theta_overlap_deg: f64,
}

impl Default for Banding {
    /// 8 px margin, growth 1.15, two halves of the bend range overlapping by
    /// 10° on each side of their cut.
    fn default() -> Self {
        Self {
            margin_px: Roi::WORKING_MARGIN_PX,
            growth: 1.15,
            theta_parts: 2,
            theta_overlap_deg: 10.0,
        }
    }
}

impl Banding {
    /// Checks the fields.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the first field out of its range:
    /// `growth` in [1, 1e6], `theta_parts` in [1, 16], `theta_overlap_deg` in
    /// [0, 360].
    pub fn validate(&self) -> Result<()> {
        Bounds::closed(1.0, 1e6).check("growth", self.growth)?;
        Bounds::closed(1.0, 16.0).check("theta_parts", f64::from(self.theta_parts))?;
        Bounds::closed(0.0, 360.0).check("theta_overlap_deg", self.theta_overlap_deg)?;
        Ok(())
    }
}

/// Working regions over a pose range, one per band of it.
///
/// The instrument's image shrinks as it moves away from the camera: at the
/// default camera the joint and gripper's sweep over ±90° is 540 px wide at
/// d = 10 mm and 258 px at 40 mm. One region for the whole range is sized by
/// the nearest pose, and a far instrument becomes a few cells of IBJAE's
/// 48×48 image. So the translations are cut into bands, each as long as it
/// can be while its region is at most [`Banding::growth`] times (each side)
/// the region of any single translation in it: short bands near the camera,
/// long ones far away. And a sweep over ±90° spreads 180° of bend over 48
/// columns, where sub-cell coincidences leave a few adjacent 1° bends with
/// identical silhouettes; so the bends are cut too, by default into two
/// halves that overlap by 10° around straight. An estimator reads the band of
/// the robot's translation and its current bend ([`WorkingRegions::at`]), or
/// every band holding the translation, and keeps a database per band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkingRegions {
    poses: PoseRange,
    bands: Vec<WorkingBand>,
}

impl WorkingRegions {
    /// The default camera's working regions: [`WorkingRegions::for_workspace`]
    /// of the K-FLEX instrument over [`PoseRange::FULL`] with the default
    /// [`Banding`].
    ///
    /// # Errors
    /// As [`WorkingRegions::for_workspace`].
    pub fn full(camera: &Camera) -> Result<WorkingRegions> {
        Self::for_workspace(
            camera,
            &Instrument::kflex(),
            &PoseRange::FULL,
            &Banding::default(),
        )
    }

    /// Bands of `poses`: the bend range cut into `banding.theta_parts`
    /// overlapping parts, each part's translations (on their 1 mm samples)
    /// cut into bands as long as the band's region ([`Roi::for_workspace`]
    /// over its poses) stays at most `banding.growth` times, each side, the
    /// region of each translation sample in it (a band spans at least one
    /// sample step). Adjacent bands of a part share their boundary
    /// translation.
    ///
    /// # Examples
    /// ```
    /// use kflex_model::{Camera, WorkingRegions};
    /// let regions = WorkingRegions::full(&Camera::default())?;
    /// let near = regions.at(30.0, 10.0)?.roi;
    /// let far = regions.at(30.0, 40.0)?.roi;
    /// assert!(far.width < near.width && far.height < near.height);
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Roi::for_workspace`] and [`Banding::validate`].
    pub fn for_workspace(
        camera: &Camera,
        instrument: &Instrument,
        poses: &PoseRange,
        banding: &Banding,
    ) -> Result<WorkingRegions> {
        camera.validate()?;
        banding.validate()?;
        poses.steps(instrument)?;
        let [t0, t1] = poses.theta_deg;
        let n = banding.theta_parts;
        let span = (t1 - t0) / f64::from(n);
        let mut bands = Vec::new();
        for i in 0..n {
            let part = [
                (t0 + span * f64::from(i) - banding.theta_overlap_deg).max(t0),
                (t0 + span * f64::from(i + 1) + banding.theta_overlap_deg).min(t1),
            ];
            let part = PoseRange {
                theta_deg: part,
                ..*poses
            };
            band_translations(camera, instrument, &part, banding, &mut bands)?;
        }
        Ok(WorkingRegions {
            poses: *poses,
            bands,
        })
    }

    /// The poses the regions cover.
    #[must_use]
    pub fn poses(&self) -> &PoseRange {
        &self.poses
    }

    /// The bands: by part of the bend range, each part's nearest first.
    #[must_use]
    pub fn bands(&self) -> &[WorkingBand] {
        &self.bands
    }

    /// The band for the pose (`theta_deg`, `translation_mm`): among the bands
    /// that hold it, the one where the bend lies farthest inside its part,
    /// and of those the farther translation band (at a boundary shared by two
    /// bands, the one whose region is the smaller).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `theta_deg` or `translation_mm`
    /// when it lies outside the range (a NaN lies outside every range).
    pub fn at(&self, theta_deg: f64, translation_mm: f64) -> Result<&WorkingBand> {
        let [t0, t1] = self.poses.theta_deg;
        let [d0, d1] = self.poses.translation_mm;
        Bounds::closed(t0, t1).check("theta_deg", theta_deg)?;
        Bounds::closed(d0, d1).check("translation_mm", translation_mm)?;
        let room = |b: &WorkingBand| {
            let [lo, hi] = b.poses.theta_deg;
            // ends of the whole range are no cut: room is unbounded there
            let below = if lo <= t0 {
                f64::INFINITY
            } else {
                theta_deg - lo
            };
            let above = if hi >= t1 {
                f64::INFINITY
            } else {
                hi - theta_deg
            };
            below.min(above)
        };
        let mut best: Option<&WorkingBand> = None;
        for b in self
            .bands
            .iter()
            .filter(|b| b.poses.contains(theta_deg, translation_mm))
        {
            let better = best.is_none_or(|x| {
                (room(b), b.poses.translation_mm[0]) > (room(x), x.poses.translation_mm[0])
            });
            if better {
                best = Some(b);
            }
        }
        best.ok_or(ModelError::OutOfRange(RangeError {
            name: "translation_mm",
            value: translation_mm,
            bounds: Bounds::closed(d0, d1),
        }))
    }

    /// [`WorkingRegions::at`] for the pose clamped into the range (a NaN
    /// taken as the range's start).
    #[must_use]
    pub fn nearest(&self, theta_deg: f64, translation_mm: f64) -> Option<&WorkingBand> {
        // (a range read from a file may be reversed or NaN: no clamp panics)
        let clamp = |x: f64, [lo, hi]: [f64; 2]| {
            if x.is_nan() || lo.is_nan() || hi.is_nan() || lo > hi {
                lo
            } else {
                x.clamp(lo, hi)
            }
        };
        self.at(
            clamp(theta_deg, self.poses.theta_deg),
            clamp(translation_mm, self.poses.translation_mm),
        )
        .ok()
    }
}

/// Appends to `bands` the translation bands of `part` (see
/// [`WorkingRegions::for_workspace`]).
fn band_translations(
    camera: &Camera,
    instrument: &Instrument,
    part: &PoseRange,
    banding: &Banding,
    bands: &mut Vec<WorkingBand>,
) -> Result<()> {
    let (nt, nd) = part.steps(instrument)?;
    let margin = banding.margin_px;
    let mut shape = InstrumentShape::default();
    let extents = (0..=nd)
        .map(|j| {
            let d = part.translation(j, nd);
            extent_at(camera, instrument, part.theta_deg, nt, d, &mut shape)
        })
        .collect::<Result<Vec<_>>>()?;
    // the region each sample needs alone; `None` where it is never in view
    let alone: Vec<Option<Roi>> = extents
        .iter()
        .map(|&e| region_of(camera, e, margin).ok())
        .collect();
    let fits = |band: &Roi, k: usize| {
        alone[k].is_some_and(|r| {
            f64::from(band.width) <= banding.growth * f64::from(r.width)
                && f64::from(band.height) <= banding.growth * f64::from(r.height)
        })
    };
    let mut start = 0;
    loop {
        let mut end = (start + 1).min(nd);
        let mut extent = union(extents[start], extents[end]);
        let mut roi = region_of(camera, extent, margin)?;
        while end < nd {
            let wider = union(extent, extents[end + 1]);
            let Ok(r) = region_of(camera, wider, margin) else {
                break;
            };
            if !(start..=end + 1).all(|k| fits(&r, k)) {
                break;
            }
            (end, extent, roi) = (end + 1, wider, r);
        }
        bands.push(WorkingBand {
            poses: PoseRange {
                translation_mm: [part.translation(start, nd), part.translation(end, nd)],
                ..*part
            },
            roi,
        });
        if end >= nd {
            return Ok(());
        }
        start = end;
    }
}

/// Pixel box of a sphere (centre in the overtube frame, mm) seen by
/// `camera`; `None` if any of it reaches the camera's plane.
#[cfg(test)]
fn sphere_extent(camera: &Camera, centre_mm: [f64; 3], radius_mm: f64) -> Option<[f64; 4]> {
    let c = (camera.camera_from_overtube * Point3::from(centre_mm)).coords;
    raster::pinhole_box(c, radius_mm).map(|b| raster::image_box(camera, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mask::Mask;
    use crate::raster::Rasterizer;

    #[test]
    fn sphere_extent_bounds_its_rasterised_image() {
        let pinhole = Camera {
            lens: crate::camera::Lens::PINHOLE,
            ..Camera::default()
        };
        // centred, off-axis, and cut by the image's left edge; through a
        // pinhole (a tight box) and the default lens (a box of directions
        // bent by it: it holds the image, less tightly off-axis)
        for (camera, centre) in [[0.0, 5.0, 20.0], [12.0, -6.0, 15.0], [-14.0, 9.0, 12.0]]
            .into_iter()
            .flat_map(|c| [(pinhole, c), (Camera::default(), c)])
        {
            let [u0, v0, u1, v1] = sphere_extent(&camera, centre, 1.5).unwrap();
            let shape = InstrumentShape {
                bodies: vec![crate::instrument::Body {
                    a_mm: centre,
                    b_mm: centre,
                    radius_mm: 1.5,
                    ends: crate::instrument::Ends::Round,
                    part: Part::Jaw(0),
                    arc_mm: [0.0, 0.0],
                }],
                tip_mm: centre,
            };
            let mut mask = Mask::new(640, 480).unwrap();
            Rasterizer::new()
                .silhouette(&camera, &shape, &mut mask)
                .unwrap();
            assert!(mask.count() > 10);
            for y in 0..480 {
                for x in 0..640 {
                    if mask.get(x, y) {
                        let (u, v) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                        assert!(
                            u >= u0 && u <= u1 && v >= v0 && v <= v1,
                            "{centre:?} ({x}, {y})"
                        );
                    }
                }
            }
            // and it is tight: no more than a pixel past the drawn pixels, where they are not cut
            let xs: Vec<u32> = (0..640)
                .filter(|&x| (0..480).any(|y| mask.get(x, y)))
                .collect();
            let right = f64::from(*xs.last().unwrap() + 1);
            let slack = if camera.lens == pinhole.lens {
                1.5
            } else {
                12.0
            };
            assert!(
                u1 - right < slack && (xs[0] == 0 || f64::from(xs[0]) - u0 < slack),
                "{centre:?}: box {u0:.1}–{u1:.1}, drawn {}–{right}",
                xs[0]
            );
        }
    }

    #[test]
    fn working_region_contains_every_distal_silhouette_of_the_range() {
        let camera = Camera::default();
        let instrument = Instrument::kflex();
        let roi = Roi::for_workspace(&camera, &instrument, &PoseRange::PAPER, 2).unwrap();
        let mut raster = Rasterizer::new();
        let mut mask = Mask::new(640, 480).unwrap();
        for theta in [0.0, 0.5, 17.3, 33.0, 49.5, 50.0] {
            let mut shape = instrument.shape(theta, 10.0).unwrap();
            shape.bodies.retain(|c| c.part != Part::Shaft);
            mask.clear();
            raster.silhouette(&camera, &shape, &mut mask).unwrap();
            let inside = mask.crop(roi).unwrap().count();
            assert_eq!(
                inside,
                mask.count(),
                "θ = {theta}: distal pixels outside {roi:?}"
            );
        }
    }

    #[test]
    fn bad_pose_ranges_name_what_failed() {
        let camera = Camera::default();
        let reversed = PoseRange {
            theta_deg: [50.0, 0.0],
            ..PoseRange::PAPER
        };
        match Roi::for_workspace(&camera, &Instrument::kflex(), &reversed, 0) {
            Err(ModelError::OutOfRange(e)) => {
                assert_eq!(
                    (e.name, e.value, e.bounds.min),
                    ("poses.theta_deg[1]", 0.0, 50.0)
                );
            }
            other => panic!("{other:?}"),
        }
        let nan = PoseRange {
            translation_mm: [f64::NAN, 10.0],
            ..PoseRange::PAPER
        };
        match Roi::for_workspace(&camera, &Instrument::kflex(), &nan, 0) {
            Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, "poses.translation_mm[0]"),
            other => panic!("{other:?}"),
        }
        let paper = PoseRange::PAPER;
        assert!(paper.contains(0.0, 10.0) && paper.contains(50.0, 10.0));
        assert!(!paper.contains(-0.1, 10.0) && !paper.contains(30.0, 10.5));
        assert!(!paper.contains(f64::NAN, 10.0));
        let huge = PoseRange {
            theta_deg: [-1e308, 1e308],
            ..PoseRange::PAPER
        };
        match Roi::for_workspace(&camera, &Instrument::kflex(), &huge, 0) {
            Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, "poses.theta_deg span"),
            other => panic!("{other:?}"),
        }
        // an instrument built by hand is checked, not trusted
        let mut wild = Instrument::kflex();
        wild.joint.max_theta_deg = 1e9;
        match Roi::for_workspace(&camera, &wild, &PoseRange::PAPER, 0) {
            Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, "max_theta_deg"),
            other => panic!("{other:?}"),
        }
        let past = PoseRange {
            theta_deg: [0.0, 200.0],
            ..PoseRange::PAPER
        };
        assert!(matches!(
            Roi::for_workspace(&camera, &Instrument::kflex(), &past, 0),
            Err(ModelError::OutOfWorkspace(e)) if e.name == "theta_deg" && e.value > 120.0
        ));
    }

    /// Identical adjacent 1° silhouettes (48×48, in the band the pose is
    /// read in) over the band's bends at translation `d`, and the mean share
    /// of the silhouette's pixels the bend and gripper make.
    fn resolution(regions: &WorkingRegions, part: [f64; 2], d: f64) -> (usize, f64) {
        let camera = Camera::default();
        let instrument = Instrument::kflex();
        let band = regions
            .bands()
            .iter()
            .rfind(|b| b.poses.theta_deg == part && b.poses.contains(part[0], d))
            .unwrap();
        let small =
            camera.with_intrinsics(band.roi.intrinsics(&camera.intrinsics, 48, 48).unwrap());
        let mut raster = Rasterizer::new();
        let mut last = Mask::new(48, 48).unwrap();
        let mut now = Mask::new(48, 48).unwrap();
        let mut distal = Mask::new(48, 48).unwrap();
        let (mut identical, mut share) = (0, 0.0);
        let n = (part[1] - part[0]).round() as usize;
        for j in 0..=n {
            let mut shape = instrument.shape(part[0] + j as f64, d).unwrap();
            now.clear();
            raster.silhouette(&small, &shape, &mut now).unwrap();
            identical += usize::from(j > 0 && now == last);
            std::mem::swap(&mut now, &mut last);
            shape.bodies.retain(|c| c.part != Part::Shaft);
            distal.clear();
            raster.silhouette(&small, &shape, &mut distal).unwrap();
            share += distal.count() as f64 / last.count() as f64;
        }
        (identical, share / (n + 1) as f64)
    }

    #[test]
    fn the_full_range_resolves_every_degree_and_shows_the_joint() {
        let regions = WorkingRegions::full(&Camera::default()).unwrap();
        assert_eq!(regions.poses(), &PoseRange::FULL);
        let parts = [[-90.0, 10.0], [-10.0, 90.0]];
        for b in regions.bands() {
            assert!(parts.contains(&b.poses.theta_deg), "{b:?}");
        }
        // the issue's goals: adjacent 1° steps distinct at every d ≤ 20 mm
        // (measured: distinct at every d of the range but 26 mm, where one
        // pair is identical), and the bend and gripper at least 40 % of the
        // silhouette at the mid-range d (measured 60–73 % at every d)
        for part in parts {
            for d in (8..=20).map(f64::from).chain([12.5]) {
                let (identical, share) = resolution(&regions, part, d);
                assert_eq!(identical, 0, "θ {part:?}, d = {d}");
                assert!(share >= 0.55, "θ {part:?}, d = {d}: share {share}");
            }
            let (identical, share) = resolution(&regions, part, 24.0);
            assert!(identical <= 1 && share >= 0.55, "{identical} {share}");
        }
        // one region for the whole range resolves far less: its far poses
        // are specks (the reason for the bands)
        let one = WorkingRegions::for_workspace(
            &Camera::default(),
            &Instrument::kflex(),
            &PoseRange::FULL,
            &Banding {
                growth: 1e6,
                theta_parts: 1,
                ..Banding::default()
            },
        )
        .unwrap();
        assert_eq!(one.bands().len(), 1);
        let (identical, share) = resolution(&one, [-90.0, 90.0], 30.0);
        assert!(identical > 20 && share < 0.2, "{identical} {share}");
    }

    #[test]
    fn every_band_holds_its_joint_and_gripper() {
        let camera = Camera::default();
        let instrument = Instrument::kflex();
        let regions = WorkingRegions::full(&camera).unwrap();
        let mut raster = Rasterizer::new();
        let mut mask = Mask::new(640, 480).unwrap();
        // every band's poses on a grid: θ every 2° and d every mm, each
        // range's ends included
        let grid = |lo: f64, hi: f64, step: f64| {
            let n = ((hi - lo) / step).ceil() as usize;
            (0..=n).map(move |k| (lo + step * k as f64).min(hi))
        };
        for b in regions.bands() {
            let ([t0, t1], [d0, d1]) = (b.poses.theta_deg, b.poses.translation_mm);
            let poses: Vec<(f64, f64)> = grid(t0, t1, 2.0)
                .flat_map(|theta| grid(d0, d1, 1.0).map(move |d| (theta, d)))
                .collect();
            for (theta, d) in poses {
                let mut shape = instrument.shape(theta, d).unwrap();
                shape.bodies.retain(|c| c.part != Part::Shaft);
                mask.clear();
                raster.silhouette(&camera, &shape, &mut mask).unwrap();
                assert!(mask.count() > 0);
                assert_eq!(
                    mask.crop(b.roi).unwrap().count(),
                    mask.count(),
                    "θ {theta}, d {d}: {b:?}"
                );
            }
        }
        // the bands of a part tile its translations, sharing their ends, and
        // shrink with distance
        for part in regions
            .bands()
            .chunk_by(|a, b| a.poses.theta_deg == b.poses.theta_deg)
        {
            assert_eq!(part[0].poses.translation_mm[0], 8.0);
            assert_eq!(part[part.len() - 1].poses.translation_mm[1], 40.0);
            for w in part.windows(2) {
                assert_eq!(w[0].poses.translation_mm[1], w[1].poses.translation_mm[0]);
                assert!(w[1].roi.width <= w[0].roi.width && w[1].roi.height < w[0].roi.height);
            }
        }
    }

    #[test]
    fn the_full_range_starts_where_the_joint_enters_the_frame() {
        // with no margin: at 8 mm the joint and gripper over ±90° stay off the
        // frame's edges, at 7 mm they reach them (PoseRange::FULL's docs)
        let camera = Camera::default();
        let at = |d: f64| {
            let poses = PoseRange {
                theta_deg: [-90.0, 90.0],
                translation_mm: [d, d],
            };
            Roi::for_workspace(&camera, &Instrument::kflex(), &poses, 0).unwrap()
        };
        let inside = |r: Roi| r.x0 > 0 && r.y0 > 0 && r.x0 + r.width < 640 && r.y0 + r.height < 480;
        assert!(inside(at(PoseRange::FULL.translation_mm[0])));
        assert!(!inside(at(7.0)));
    }

    #[test]
    fn a_pose_is_read_in_the_band_where_it_lies_deepest() {
        let regions = WorkingRegions::full(&Camera::default()).unwrap();
        let right = regions.at(30.0, 10.0).unwrap();
        assert_eq!(right.poses.theta_deg, [-10.0, 90.0]);
        assert_eq!(
            regions.at(-30.0, 10.0).unwrap().poses.theta_deg,
            [-90.0, 10.0]
        );
        assert_eq!(
            regions.at(-5.0, 10.0).unwrap().poses.theta_deg,
            [-90.0, 10.0]
        );
        assert_eq!(
            regions.at(5.0, 10.0).unwrap().poses.theta_deg,
            [-10.0, 90.0]
        );
        for (theta, d) in [(30.0, 10.0), (-90.0, 8.0), (90.0, 40.0), (0.0, 23.3)] {
            assert!(regions.at(theta, d).unwrap().poses.contains(theta, d));
        }
        // at a boundary shared by two bands, the farther (smaller) one
        let b = regions.at(30.0, 10.0).unwrap();
        assert_eq!(b.poses.translation_mm, [10.0, 11.0]);
        // outside the range: an error naming what is out, or the nearest band
        for (theta, d, name) in [
            (0.0, 7.9, "translation_mm"),
            (95.0, 10.0, "theta_deg"),
            (f64::NAN, 10.0, "theta_deg"),
        ] {
            match regions.at(theta, d) {
                Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, name),
                other => panic!("{other:?}"),
            }
        }
        assert_eq!(regions.nearest(120.0, 3.0), regions.at(90.0, 8.0).ok());
        assert_eq!(
            regions.nearest(f64::NAN, f64::NAN),
            regions.at(-90.0, 8.0).ok()
        );
        // regions read from a file may carry a reversed range: no panic
        let reversed: WorkingRegions = serde_json::from_str(
            r#"{"poses":{"theta_deg":[1,0],"translation_mm":[0,1]},"bands":[]}"#,
        )
        .unwrap();
        assert_eq!(reversed.nearest(0.5, 0.5), None);
        // bad banding is refused, by name
        for (banding, name) in [
            (
                Banding {
                    growth: 0.9,
                    ..Banding::default()
                },
                "growth",
            ),
            (
                Banding {
                    theta_parts: 0,
                    ..Banding::default()
                },
                "theta_parts",
            ),
            (
                Banding {
                    theta_overlap_deg: f64::NAN,
                    ..Banding::default()
                },
                "theta_overlap_deg",
            ),
        ] {
            match WorkingRegions::for_workspace(
                &Camera::default(),
                &Instrument::kflex(),
                &PoseRange::FULL,
                &banding,
            ) {
                Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, name),
                other => panic!("{other:?}"),
            }
        }
    }
}
