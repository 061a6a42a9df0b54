//! The working region of the camera: where the bending joint and the gripper
//! can appear. [`Roi::for_workspace`] projects them over every pose of a
//! [`PoseRange`] and takes the smallest square around them, so the region
//! is derived from the camera and the instrument, not typed in.

use serde::{Deserialize, Serialize};

use nalgebra::Point3;

use crate::camera::Camera;
use crate::error::{ModelError, Result};
use crate::instrument::{Instrument, InstrumentShape, Part};
use crate::range::Bounds;
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

    /// Whether the pose (bend `theta_deg`, translation `translation_mm`) lies
    /// in the range, ends included.
    #[must_use]
    pub fn contains(&self, theta_deg: f64, translation_mm: f64) -> bool {
        let [t0, t1] = self.theta_deg;
        let [d0, d1] = self.translation_mm;
        (t0..=t1).contains(&theta_deg) && (d0..=d1).contains(&translation_mm)
    }
}

impl Roi {
    /// Margin of [`Roi::working`] around the joint and gripper, px of the full frame.
    pub const WORKING_MARGIN_PX: u32 = 8;

    /// The poses [`Roi::working`] covers.
    pub const WORKING_POSES: PoseRange = PoseRange::PAPER;

    /// The default working region of `camera`: [`Roi::for_workspace`] of the
    /// K-FLEX instrument ([`Instrument::kflex`]) over
    /// [`Roi::WORKING_POSES`] (the paper's), with [`Roi::WORKING_MARGIN_PX`].
    ///
    /// # Errors
    /// As [`Roi::for_workspace`].
    pub fn working(camera: &Camera) -> Result<Roi> {
        Self::for_workspace(
            camera,
            &Instrument::kflex(),
            &Self::WORKING_POSES,
            Self::WORKING_MARGIN_PX,
        )
    }

    /// The smallest square region of `camera`'s image that contains the
    /// bending joint and the gripper for every pose in `poses`, plus
    /// `margin_px` on each side, clipped to the image. Where that box is
    /// wider than the image's shorter side, the square is that side and
    /// holds the middle of the box.
    ///
    /// The poses are sampled every 1° of bend and every 1 mm of translation
    /// (ends included). Each body lies in the capsule of its radius, the
    /// convex hull of its two end spheres; a pinhole maps that to the convex
    /// hull of their images, whose box is where the planes through the centre
    /// of projection touch them; the lens then bends that box of directions
    /// to a pixel box that holds everything in it (`raster::image_box`). Between
    /// samples a pose moves the tip by well under a pixel at the default
    /// camera, which the margin absorbs.
    ///
    /// # Examples
    /// ```
    /// use kflex_model::{Camera, Instrument, PoseRange, Roi};
    /// let camera = Camera::default();
    /// let roi = Roi::for_workspace(&camera, &Instrument::kflex(), &PoseRange::PAPER, 4)?;
    /// assert_eq!(roi.width, roi.height);
    /// roi.check_within(camera.intrinsics.width, camera.intrinsics.height)?;
    /// # Ok::<(), kflex_model::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// [`ModelError::OutOfWorkspace`] when a pose lies outside the
    /// instrument's workspace; [`ModelError::OutOfRange`] for an instrument
    /// parameter out of its range, or a reversed, non-finite or too wide pose
    /// range (a span past the workspace's); [`ModelError::NotInView`] when the
    /// distal part never comes into the image.
    pub fn for_workspace(
        camera: &Camera,
        instrument: &Instrument,
        poses: &PoseRange,
        margin_px: u32,
    ) -> Result<Roi> {
        // a validated instrument bounds the poses (|θ| ≤ 170°, d ≤ 1 m), so
        // the sampling below is at most 341 × 1001 poses before a pose out
        // of the workspace stops it
        instrument.validate()?;
        let [t0, t1] = poses.theta_deg;
        let [d0, d1] = poses.translation_mm;
        let any = Bounds::open(f64::NEG_INFINITY, f64::INFINITY);
        any.check("poses.theta_deg[0]", t0)?;
        any.check("poses.translation_mm[0]", d0)?;
        Bounds::closed(t0, f64::INFINITY).check("poses.theta_deg[1]", t1)?;
        Bounds::closed(d0, f64::INFINITY).check("poses.translation_mm[1]", d1)?;
        let reach = Bounds::closed(0.0, 2.0 * instrument.joint.max_theta_deg);
        reach.check("poses.theta_deg span", t1 - t0)?;
        Bounds::closed(0.0, instrument.translation.max_mm)
            .check("poses.translation_mm span", d1 - d0)?;
        let nt = ((t1 - t0).ceil() as usize).max(1);
        let nd = ((d1 - d0).ceil() as usize).max(1);
        let mut shape = InstrumentShape::default();
        // the union of the end spheres' pinhole boxes (a body lies inside the
        // capsule of its radius); `None` once a sphere reaches the camera's plane
        let mut pinhole = Some([
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ]);
        for i in 0..=nt {
            let theta = t0 + (t1 - t0) * i as f64 / nt as f64;
            for j in 0..=nd {
                let d = d0 + (d1 - d0) * j as f64 / nd as f64;
                instrument.shape_into(theta, d, &mut shape)?;
                for c in shape.bodies.iter().filter(|c| c.part != Part::Shaft) {
                    for end in [c.a_mm, c.b_mm] {
                        let centre = (camera.camera_from_overtube * Point3::from(end)).coords;
                        pinhole =
                            pinhole
                                .zip(raster::pinhole_box(centre, c.radius_mm))
                                .map(|(b, s)| {
                                    [
                                        b[0].min(s[0]),
                                        b[1].min(s[1]),
                                        b[2].max(s[2]),
                                        b[3].max(s[3]),
                                    ]
                                });
                    }
                }
            }
        }
        // a sphere that reaches the camera's plane can cover any pixel
        let bbox = pinhole.map_or(
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
            (bbox[0] - m).max(0.0),
            (bbox[1] - m).max(0.0),
            (bbox[2] + m).min(w),
            (bbox[3] + m).min(h),
        ];
        if !(u1 > u0 && v1 > v0) {
            return Err(ModelError::NotInView {
                what: "the bending joint and gripper over this pose range",
            });
        }
        // square it, centred on the box, shifted (not cut) to stay inside the
        // image; a box wider than the image's shorter side is cut to that side
        let side = (u1 - u0).max(v1 - v0).ceil().min(w.min(h));
        let place = |lo: f64, hi: f64, limit: f64| {
            (0.5 * (lo + hi - side)).clamp(0.0, limit - side).floor()
        };
        let (x0, y0) = (place(u0, u1, w), place(v0, v1, h));
        let roi = Roi {
            x0: x0 as u32,
            y0: y0 as u32,
            width: side as u32,
            height: side as u32,
        };
        roi.check_within(k.width, k.height)?;
        Ok(roi)
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
}
