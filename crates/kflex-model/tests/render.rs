//! Camera and silhouettes: projection of known points through the lens, the
//! ray caster against an independent one (parry's capsules and cylinders),
//! windows equal to crops, resolution of the 48×48 region of interest, and
//! bad input.

use kflex_model::{
    Camera, Ends, Instrument, InstrumentShape, Intrinsics, Lens, MAX_BODIES, Mask, ModelError,
    RangeError, Rasterizer, Roi,
};
use nalgebra::Point3;
use rapier3d::math::{Pose, Rotation, Vector as PVec};
use rapier3d::parry::query::{Ray, RayCast};
use rapier3d::parry::shape::{Capsule as ParryCapsule, Cylinder as ParryCylinder};

fn render(camera: &Camera, shape: &InstrumentShape) -> Mask {
    let k = camera.intrinsics;
    let mut mask = Mask::new(k.width, k.height).unwrap();
    Rasterizer::new()
        .silhouette(camera, shape, &mut mask)
        .unwrap();
    mask
}

/// The reference: a ray through every pixel centre (the camera's own ray,
/// lens included) against parry's capsules and cylinders (f32).
fn ray_cast(camera: &Camera, shape: &InstrumentShape) -> Mask {
    let k = camera.intrinsics;
    let to_cam = |p: [f64; 3]| {
        let q = camera.camera_from_overtube * Point3::from(p);
        PVec::new(q.x as f32, q.y as f32, q.z as f32)
    };
    let mut shapes: Vec<(Pose, Box<dyn RayCast>)> = Vec::new();
    for b in &shape.bodies {
        let (a, e) = (to_cam(b.a_mm), to_cam(b.b_mm));
        let r = b.radius_mm as f32;
        match b.ends {
            Ends::Round => shapes.push((Pose::IDENTITY, Box::new(ParryCapsule::new(a, e, r)))),
            // a flat body of no length (the shaft at d = 0) has no volume
            Ends::Flat if (e - a).length() < 1e-6 => {}
            Ends::Flat => {
                let axis = e - a;
                let pose = Pose::from_parts(
                    (a + e) * 0.5,
                    Rotation::from_rotation_arc(PVec::Y, axis.normalize()),
                );
                shapes.push((pose, Box::new(ParryCylinder::new(0.5 * axis.length(), r))));
            }
        }
    }
    let mut data = vec![0u8; (k.width * k.height) as usize];
    for y in 0..k.height {
        for x in 0..k.width {
            let d = camera.ray_direction(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let ray = Ray::new(PVec::ZERO, PVec::new(d[0] as f32, d[1] as f32, d[2] as f32));
            if shapes
                .iter()
                .any(|(pose, s)| s.cast_ray(pose, &ray, 1e4, true).is_some())
            {
                data[(y * k.width + x) as usize] = 1;
            }
        }
    }
    Mask::from_raw(k.width, k.height, data).unwrap()
}

/// A square region of interest around the joint and tool over bends `thetas` and translations `ds`.
fn roi(camera: &Camera, instrument: &Instrument, thetas: &[f64], ds: &[f64]) -> (f64, f64, f64) {
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for &theta in thetas {
        for &d in ds {
            let shape = instrument.shape(theta, d).unwrap();
            for c in &shape.bodies[1..] {
                for p in [c.a_mm, c.b_mm] {
                    let uv = camera.project(p).unwrap();
                    for i in 0..2 {
                        lo[i] = lo[i].min(uv[i]);
                        hi[i] = hi[i].max(uv[i]);
                    }
                }
            }
        }
    }
    let side = (hi[0] - lo[0]).max(hi[1] - lo[1]) * 1.2;
    (
        0.5 * (lo[0] + hi[0]) - 0.5 * side,
        0.5 * (lo[1] + hi[1]) - 0.5 * side,
        side,
    )
}

#[test]
fn projects_known_points() {
    let pinhole = Camera {
        lens: Lens::PINHOLE,
        ..Camera::default()
    };
    let k = pinhole.intrinsics;
    let on_axis = pinhole.project([0.0, 0.0, 30.0]).unwrap();
    assert!((on_axis[0] - k.cx).abs() < 1e-12 && (on_axis[1] - k.cy).abs() < 1e-12);
    let p = pinhole.project([3.0, -2.0, 20.0]).unwrap();
    assert!(
        (p[0] - (k.cx + k.fx * 0.15)).abs() < 1e-9 && (p[1] - (k.cy - k.fy * 0.1)).abs() < 1e-9
    );
    assert!(
        pinhole.project([0.0, 0.0, -1.0]).is_none(),
        "behind the camera"
    );
    // 100 deg horizontal field of view through a pinhole: 50 deg off-axis lands on the edge
    let edge = pinhole
        .project([50f64.to_radians().tan() * 10.0, 0.0, 10.0])
        .unwrap();
    assert!((edge[0] - f64::from(k.width)).abs() < 1e-9);
    // a region of interest maps its corner to (0, 0) and its far corner to (w, h)
    let r = k.region(100.0, 50.0, 200.0, 200.0, 48, 48).unwrap();
    for camera in [pinhole, Camera::default()] {
        let cam_r = camera.with_intrinsics(r);
        let d = camera.ray_direction(100.0, 50.0);
        let uv = cam_r.project([d[0] * 10.0, d[1] * 10.0, 10.0]).unwrap();
        assert!(uv[0].abs() < 1e-9 && uv[1].abs() < 1e-9, "{uv:?}");
    }
}

#[test]
fn the_lens_is_a_wide_angle_barrel_and_inverts_exactly() {
    let camera = Camera::default();
    let k = camera.intrinsics;
    // every pixel's ray projects back to the pixel
    for (u, v) in [
        (0.0, 0.0),
        (640.0, 480.0),
        (13.5, 401.2),
        (320.0, 240.0),
        (600.0, 20.0),
    ] {
        let d = camera.ray_direction(u, v);
        let back = camera.project([d[0] * 7.0, d[1] * 7.0, 7.0]).unwrap();
        assert!(
            (back[0] - u).abs() < 1e-9 && (back[1] - v).abs() < 1e-9,
            "({u}, {v}) → {back:?}"
        );
    }
    // the documented fields of view: 113 deg across, 132 deg on the diagonal
    let angle = |u: f64, v: f64| {
        let d = camera.ray_direction(u, v);
        d[0].hypot(d[1]).atan().to_degrees()
    };
    let across = angle(0.0, k.cy) + angle(f64::from(k.width), k.cy);
    let diagonal = 2.0 * angle(0.0, 0.0);
    assert!((across - 113.1).abs() < 0.1, "{across}");
    assert!((diagonal - 131.7).abs() < 0.1, "{diagonal}");
    // barrel: a point off-axis lands nearer the centre than through a pinhole
    let pinhole = Camera {
        lens: Lens::PINHOLE,
        ..camera
    };
    let (bent, straight) = (
        camera.project([8.0, 3.0, 10.0]).unwrap(),
        pinhole.project([8.0, 3.0, 10.0]).unwrap(),
    );
    assert!(bent[0] < straight[0] && bent[1] < straight[1] && bent[0] > k.cx);
    // vignetting: full light on the axis, 48 % in the corners
    assert!((camera.illumination(k.cx, k.cy) - 1.0).abs() < 1e-12);
    assert!((camera.illumination(0.0, 0.0) - 0.48).abs() < 0.005);
    // a lens that would fold the image over is refused, naming the coefficient
    let folded = Camera {
        lens: Lens {
            division: -0.5,
            vignetting: 0.0,
        },
        ..camera
    };
    match folded.validate() {
        Err(ModelError::OutOfRange(e)) => assert!(e.name.starts_with("lens.division"), "{e}"),
        other => panic!("{other:?}"),
    }
    // the nominal lens on intrinsics that move the principal point to the
    // image's edge: the lens is refused, and the error says that the
    // intrinsics set its limit (the user changed cx, not the lens)
    let edge = camera.with_intrinsics(Intrinsics { cx: 0.0, ..k });
    match edge.validate() {
        Err(ModelError::OutOfRange(e)) => {
            assert!(e.name.starts_with("lens.division"), "{e}");
            assert!(e.to_string().contains("principal point cx, cy"), "{e}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_window_is_exactly_the_crop_of_the_full_silhouette() {
    let camera = Camera::default();
    let instrument = Instrument::kflex();
    let mut raster = Rasterizer::new();
    for (theta, d) in [(30.0, 10.0), (-90.0, 0.0), (75.0, 25.0)] {
        let shape = instrument.shape(theta, d).unwrap();
        let full = render(&camera, &shape);
        for window in [
            Roi {
                x0: 0,
                y0: 0,
                width: 640,
                height: 480,
            },
            Roi {
                x0: 201,
                y0: 173,
                width: 97,
                height: 150,
            },
            Roi {
                x0: 600,
                y0: 470,
                width: 40,
                height: 10,
            },
            Roi {
                x0: 5,
                y0: 300,
                width: 1,
                height: 1,
            },
        ] {
            let mut part = Mask::new(window.width, window.height).unwrap();
            raster
                .silhouette_window(&camera, &shape, window, &mut part)
                .unwrap();
            assert_eq!(
                part,
                full.crop(window).unwrap(),
                "θ = {theta}, d = {d}, {window:?}"
            );
        }
    }
    // a window outside the image names the axis that fails
    let mut part = Mask::new(50, 50).unwrap();
    let outside = Roi {
        x0: 100,
        y0: 450,
        width: 50,
        height: 50,
    };
    let shape = instrument.shape(0.0, 10.0).unwrap();
    match raster.silhouette_window(&camera, &shape, outside, &mut part) {
        Err(ModelError::OutOfRange(e)) => assert_eq!(e.name, "roi.y0 + roi.height"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn silhouettes_match_an_independent_ray_cast() {
    let instrument = Instrument::kflex();
    let camera = Camera::default();
    let (x0, y0, side) = roi(
        &camera,
        &instrument,
        &[-10.0, 0.0, 25.0, 50.0, 60.0],
        &[5.0, 15.0],
    );
    let roi_camera = camera.with_intrinsics(
        camera
            .intrinsics
            .region(x0, y0, side, side, 48, 48)
            .unwrap(),
    );
    let hd = camera.with_intrinsics(Intrinsics::full_hd());
    let mut worst = [1.0f64; 3];
    for (theta, d) in [
        (0.0, 5.0),
        (25.0, 10.0),
        (50.0, 15.0),
        (-30.0, 8.0),
        (90.0, 20.0),
        (-90.0, 0.0),
        (90.0, 0.0),
        (-60.0, 40.0),
    ] {
        let shape = instrument.shape(theta, d).unwrap();
        for (i, cam) in [camera, roi_camera, hd].iter().enumerate() {
            if i == 2 && theta != 25.0 {
                continue; // one full-HD pose keeps the test quick
            }
            let ours = render(cam, &shape);
            let reference = ray_cast(cam, &shape);
            assert!(
                reference.count() > 20,
                "the instrument should be in view at θ={theta}, d={d}"
            );
            let iou = ours.iou(&reference).unwrap();
            worst[i] = worst[i].min(iou);
        }
    }
    eprintln!(
        "worst IoU: 640x480 {:.4}, 48x48 ROI {:.4}, 1920x1080 {:.4}",
        worst[0], worst[1], worst[2]
    );
    // exact hits on both sides: only f32 round-off in the reference differs
    assert!(
        worst.iter().all(|&w| w >= 0.995),
        "IoU below 0.995: {worst:?}"
    );
}

#[test]
fn one_degree_changes_the_48px_silhouette_across_the_working_range() {
    let instrument = Instrument::kflex();
    let camera = Camera::default();
    // the region the paper's working range (0–50 deg) covers at this translation
    let (x0, y0, side) = roi(
        &camera,
        &instrument,
        &[0.0, 10.0, 20.0, 30.0, 40.0, 51.0],
        &[10.0],
    );
    let roi_camera = camera.with_intrinsics(
        camera
            .intrinsics
            .region(x0, y0, side, side, 48, 48)
            .unwrap(),
    );
    let mut fewest = usize::MAX;
    for theta in 0..50 {
        let a = render(
            &roi_camera,
            &instrument.shape(f64::from(theta), 10.0).unwrap(),
        );
        let b = render(
            &roi_camera,
            &instrument.shape(f64::from(theta) + 1.0, 10.0).unwrap(),
        );
        let differing = a
            .data()
            .iter()
            .zip(b.data())
            .filter(|(x, y)| x != y)
            .count();
        fewest = fewest.min(differing);
        assert!(
            differing > 0,
            "θ = {theta} and {} give the same 48×48 silhouette",
            theta + 1
        );
    }
    eprintln!("fewest differing pixels between θ and θ+1 (48x48): {fewest}");
}

#[test]
fn rendering_is_deterministic() {
    let shape = Instrument::kflex().shape(33.0, 12.0).unwrap();
    let camera = Camera::default();
    assert_eq!(render(&camera, &shape), render(&camera, &shape));
}

/// The range error of `result`, which must be out of range (or out of the workspace).
fn range_of<T: std::fmt::Debug>(result: Result<T, ModelError>) -> RangeError {
    match result {
        Err(ref e) if e.range().is_some() => *e.range().unwrap(),
        other => panic!("expected a range error, got {other:?}"),
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let instrument = Instrument::kflex();
    match instrument.shape(130.0, 5.0) {
        Err(ModelError::OutOfWorkspace(e)) => {
            assert_eq!(
                (e.name, e.value, e.bounds.min, e.bounds.max),
                ("theta_deg", 130.0, -120.0, 120.0)
            );
        }
        other => panic!("{other:?}"),
    }
    match instrument.shape(10.0, 55.0) {
        Err(ModelError::OutOfWorkspace(e)) => {
            assert_eq!(
                (e.name, e.value, e.bounds.min, e.bounds.max),
                ("translation_mm", 55.0, 0.0, 40.0)
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        instrument.shape(f64::NAN, 5.0),
        Err(ModelError::NonFinite {
            name: "theta_deg",
            ..
        })
    ));
    let e = range_of(Mask::new(0, 10));
    assert_eq!((e.name, e.value, e.bounds.min), ("image width", 0.0, 1.0));
    let e = range_of(Mask::new(10, 20_000));
    assert_eq!(
        (e.name, e.value, e.bounds.max),
        ("image height", 20_000.0, 16384.0)
    );
    assert!(matches!(
        Mask::from_raw(4, 4, vec![0; 15]),
        Err(ModelError::ImageSize {
            expected: 16,
            got: 15,
            ..
        })
    ));
    let mut wrong = Mask::new(10, 10).unwrap();
    let shape = instrument.shape(10.0, 5.0).unwrap();
    assert!(matches!(
        Rasterizer::new().silhouette(&Camera::default(), &shape, &mut wrong),
        Err(ModelError::ImageSize {
            width: 640,
            height: 480,
            got: 100,
            ..
        })
    ));
    assert!(matches!(
        Mask::new(3, 3).unwrap().iou(&Mask::new(4, 3).unwrap()),
        Err(ModelError::ImageSize {
            width: 3,
            height: 3,
            expected: 9,
            got: 12,
            ..
        })
    ));
    let m = Mask::from_raw(3, 2, vec![1, 0, 1, 0, 1, 1]).unwrap();
    let window = |x0, y0, width, height| Roi {
        x0,
        y0,
        width,
        height,
    };
    assert_eq!(
        m.crop(window(1, 0, 2, 2)).unwrap(),
        Mask::from_raw(2, 2, vec![0, 1, 1, 1]).unwrap()
    );
    let e = range_of(m.crop(window(2, 0, 2, 1)));
    assert_eq!(
        (e.name, e.value, e.bounds.max),
        ("roi.x0 + roi.width", 4.0, 3.0),
        "window past the right edge"
    );
    let e = range_of(m.crop(window(0, 1, 1, 2)));
    assert_eq!(
        (e.name, e.value, e.bounds.max),
        ("roi.y0 + roi.height", 3.0, 2.0),
        "window past the bottom"
    );
    assert_eq!(
        range_of(m.crop(window(0, 0, 0, 1))).name,
        "roi.width",
        "empty window"
    );
    assert_eq!(
        range_of(Intrinsics::from_fov(0, 480, 90.0)).name,
        "image width"
    );
    let e = range_of(Intrinsics::from_fov(640, 480, 180.0));
    assert_eq!((e.name, e.value), ("hfov_deg", 180.0));
    // the instrument's public fields are checked before anything is sized
    // by them (u32::MAX segments asked for terabytes), and NaN is refused
    // rather than drawn as nothing
    let huge = Instrument {
        n_segments: u32::MAX,
        ..Instrument::kflex()
    };
    assert_eq!(range_of(huge.shape(0.0, 10.0)).name, "n_segments");
    let mut nan = Instrument::kflex();
    nan.joint.link_length_mm = f64::NAN;
    assert!(nan.shape(0.0, 10.0).is_err());
    let mut out = InstrumentShape::default();
    assert!(nan.shape_into(0.0, 10.0, &mut out).is_err());
    // cameras whose rays would all be infinite or NaN
    let mut far = Camera::default();
    far.intrinsics.fx = 1e-300;
    assert_eq!(range_of(far.validate()).name, "fx");
    let mut off = Camera::default();
    off.intrinsics.cx = 1e200;
    assert_eq!(range_of(off.validate()).name, "cx");
    let mut lost = Camera::default();
    lost.camera_from_overtube.translation.vector.x = f64::NAN;
    assert!(matches!(
        lost.validate(),
        Err(ModelError::NonFinite {
            name: "camera_from_overtube",
            ..
        })
    ));
    assert!(
        Rasterizer::new()
            .silhouette(&lost, &shape, &mut Mask::new(640, 480).unwrap())
            .is_err()
    );
    // the working regions check the camera they are cut for
    let poses = kflex_model::PoseRange {
        theta_deg: [0.0, 50.0],
        translation_mm: [10.0, 10.0],
    };
    assert!(Roi::for_workspace(&lost, &instrument, &poses, 4).is_err());
    assert_eq!(
        range_of(Roi::for_workspace(&far, &instrument, &poses, 4)).name,
        "fx"
    );
    // a shape built by hand with more bodies than a tile can name is refused
    // (its extra bodies were skipped, so the far ones went undrawn), by the
    // silhouettes and the scene alike
    let mut crowded = shape.clone();
    let last = *crowded.bodies.last().unwrap();
    crowded.bodies.resize(MAX_BODIES + 1, last);
    let camera = Camera::default();
    let mut mask = Mask::new(640, 480).unwrap();
    let e = range_of(Rasterizer::new().silhouette(&camera, &crowded, &mut mask));
    assert_eq!(
        (e.name, e.value),
        ("shape.bodies (count)", (MAX_BODIES + 1) as f64)
    );
    assert_eq!(mask.count(), 0, "nothing drawn");
    let e = range_of(kflex_model::SceneRenderer::new().render(
        &camera,
        &crowded,
        &kflex_model::FrameParams::default(),
    ));
    assert_eq!(e.name, "shape.bodies (count)");
    // as many as it can name still draw
    crowded.bodies.truncate(MAX_BODIES);
    Rasterizer::new()
        .silhouette(&camera, &crowded, &mut mask)
        .unwrap();
    assert!(mask.count() > 0);
}

#[test]
fn a_mask_refilled_row_by_row_equals_one_built_whole() {
    let data: Vec<u8> = (0..35).map(|i| [0, 1, 7][i % 3]).collect();
    let whole = Mask::from_raw(7, 5, data.clone()).unwrap();
    let mut m = Mask::new(40, 2).unwrap();
    m.set_row(1, &[1; 40]).unwrap();
    m.reshape(7, 5).unwrap();
    assert_eq!((m.width(), m.height(), m.count()), (7, 5, 0));
    for (y, row) in data.chunks(7).enumerate() {
        m.set_row(y as u32, row).unwrap();
    }
    // non-zero reads as set, stored as 1
    assert_eq!(m, whole);
    assert!(m.data().iter().all(|&v| v <= 1));
    let e = range_of(m.set_row(5, &[0; 7]));
    assert_eq!(
        (e.name, e.value, e.bounds.max, e.bounds.max_inclusive),
        ("mask row", 5.0, 5.0, false)
    );
    assert!(matches!(
        m.set_row(0, &[0; 6]),
        Err(ModelError::ImageSize {
            expected: 7,
            got: 6,
            ..
        })
    ));
    assert_eq!(range_of(m.reshape(0, 3)).name, "image width");
}

#[test]
fn a_shape_tells_its_pose() {
    let instrument = kflex_model::Instrument::kflex();
    for (theta, d) in [(0.0, 0.0), (30.0, 10.0), (-87.5, 23.25), (120.0, 40.0)] {
        let shape = instrument.shape(theta, d).unwrap();
        assert!((shape.translation_mm() - d).abs() < 1e-12, "{theta} {d}");
        assert!(
            (shape.bend_deg() - theta).abs() < 1e-9,
            "{theta} {d}: {}",
            shape.bend_deg()
        );
    }
    let empty = kflex_model::InstrumentShape::default();
    assert_eq!((empty.translation_mm(), empty.bend_deg()), (0.0, 0.0));
}
