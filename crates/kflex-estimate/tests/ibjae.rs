//! IBJAE and LBHJAE end to end on the small test models
//! (`tools/make_test_models.py`): a band database built from the nominal
//! instrument, frames rendered and segmented, the SCNN and the index.
#![cfg(all(feature = "onnx", feature = "index"))]

#[path = "support/paper_ibjae.rs"]
mod paper_ibjae;

use paper_ibjae::{data, ibjae, paper_band};

use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, EstimateError, Fusion, Ibjae, Kbjae, Lbhjae, RgbView, Scnn,
    SegmentParams, build_band_database,
};
use kflex_model::{Camera, Command, FrameParams, Instrument, Roi, SceneRenderer};

#[test]
fn ibjae_reads_rendered_frames_near_their_pose() {
    let camera = Camera::default();
    let mut ibjae = ibjae(&camera);
    let mut renderer = SceneRenderer::new();
    let mut worst: f64 = 0.0;
    for theta in [5.0, 17.0, 30.0, 44.0] {
        let shape = Instrument::kflex().shape(theta, 10.0).unwrap();
        let f = renderer
            .render(&camera, &shape, &FrameParams::default())
            .unwrap();
        let view = RgbView::packed(&f.rgb, f.width, f.height).unwrap();
        let r = ibjae.read(&view, &[0]).unwrap().expect("an instrument");
        assert_eq!(r.translation_mm, 10.0);
        assert!(r.sigma_deg >= 0.5 && r.distance.is_finite(), "{r:?}");
        worst = worst.max((r.theta_deg - theta).abs());
    }
    // a random-weight test SCNN: the angle is near, not exact
    assert!(worst <= 6.0, "worst error {worst} deg");
}

#[test]
fn a_padded_frame_reads_as_the_packed_one_and_bad_views_are_refused() {
    let camera = Camera::default();
    let mut ibjae = ibjae(&camera);
    let shape = Instrument::kflex().shape(25.0, 10.0).unwrap();
    let f = SceneRenderer::new()
        .render(&camera, &shape, &FrameParams::default())
        .unwrap();
    let packed = ibjae
        .read(&RgbView::packed(&f.rgb, f.width, f.height).unwrap(), &[0])
        .unwrap();
    let stride = 3 * f.width as usize + 16;
    let mut padded = vec![0u8; stride * f.height as usize];
    for y in 0..f.height as usize {
        let row = 3 * f.width as usize;
        padded[y * stride..y * stride + row].copy_from_slice(&f.rgb[y * row..(y + 1) * row]);
    }
    let view = RgbView::new(&padded, f.width, f.height, stride).unwrap();
    assert_eq!(ibjae.read(&view, &[0]).unwrap(), packed);
    assert!(matches!(
        RgbView::new(&f.rgb[..100], f.width, f.height, 3 * f.width as usize),
        Err(EstimateError::ImageSize { .. })
    ));
    assert!(matches!(
        RgbView::new(&f.rgb, f.width, f.height, 2),
        Err(EstimateError::ImageSize { .. })
    ));
    // a frame too small for the band's region
    let tiny = vec![0u8; 3 * 64 * 64];
    assert!(
        ibjae
            .read(&RgbView::packed(&tiny, 64, 64).unwrap(), &[0])
            .is_err()
    );
}

#[test]
fn no_instrument_is_no_reading_never_a_made_up_angle() {
    let camera = Camera::default();
    let mut ibjae = ibjae(&camera);
    let k = camera.intrinsics;
    // flat tissue colour: nothing to segment
    let rgb: Vec<u8> = (0..k.width * k.height)
        .flat_map(|_| [180u8, 90, 80])
        .collect();
    let view = RgbView::packed(&rgb, k.width, k.height).unwrap();
    assert_eq!(ibjae.read(&view, &[0]).unwrap(), None);
}

#[test]
fn a_band_past_the_databases_is_an_error_not_no_reading() {
    let camera = Camera::default();
    let mut ibjae = ibjae(&camera);
    let k = camera.intrinsics;
    let rgb = vec![128u8; (3 * k.width * k.height) as usize];
    let view = RgbView::packed(&rgb, k.width, k.height).unwrap();
    let e = ibjae.read(&view, &[0, 7]).unwrap_err();
    assert!(
        matches!(e, EstimateError::OutOfRange(ref r) if r.name == "band"),
        "{e}"
    );
}

#[test]
fn band_metadata_out_of_range_is_refused_naming_the_key() {
    let camera = Camera::default();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let db = build_band_database(
        &mut scnn,
        &camera,
        &Instrument::kflex(),
        &paper_band(&camera),
        10.0,
        1.0,
    )
    .unwrap();
    let bytes = db.index.to_bytes();
    for (key, value) in [
        ("roi", "-1,0,10,10"),
        ("roi", "0.5,0,10,10"),
        ("roi", "0,0,0,10"),
        ("band", "50,0,10,10"),
        ("grid", "0,1"),
        ("distance_per_deg", "-2"),
    ] {
        let mut index = kflex_estimate::FeatureIndex::from_bytes(&bytes).unwrap();
        index.set_metadata(key, value);
        let e = kflex_estimate::BandDatabase::from_index(index).unwrap_err();
        assert!(e.to_string().contains(key), "{key}={value}: {e}");
    }
}

#[test]
fn a_database_from_another_scnn_is_refused() {
    let camera = Camera::default();
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let mut db = build_band_database(
        &mut scnn,
        &camera,
        &Instrument::kflex(),
        &paper_band(&camera),
        5.0,
        1.0,
    )
    .unwrap();
    db.index.set_metadata("scnn_sha256", "0000");
    let e = Ibjae::new(scnn, SegmentParams::default(), vec![db]).unwrap_err();
    assert!(matches!(e, EstimateError::ModelMismatch { .. }), "{e}");
    assert!(e.to_string().contains("0000"), "{e}");
}

#[test]
fn lbhjae_fuses_both_and_runs_without_frames() {
    let camera = Camera::default();
    let kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
    let mut lbhjae = Lbhjae::new(kbjae, ibjae(&camera), fusion);
    let mut renderer = SceneRenderer::new();
    let mut with_frames = 0;
    for k in 0..30 {
        let theta = 20.0 + 0.2 * f64::from(k);
        let command = Command {
            theta_c_deg: theta,
            translation_mm: 10.0,
        };
        let frame = (k % 3 == 0).then(|| {
            let shape = Instrument::kflex().shape(theta, 10.0).unwrap();
            renderer
                .render(&camera, &shape, &FrameParams::default())
                .unwrap()
        });
        let view = frame
            .as_ref()
            .map(|f| RgbView::packed(&f.rgb, f.width, f.height).unwrap());
        let e = lbhjae.step(command, 0.01, view.as_ref()).unwrap();
        assert!(e.fused.theta_hat_deg.is_finite());
        with_frames += usize::from(e.ibjae.is_some());
    }
    assert_eq!(with_frames, 10);
    // a bad tick changes nothing
    let before = format!("{lbhjae:?}");
    let bad = Command {
        theta_c_deg: f64::NAN,
        translation_mm: 10.0,
    };
    let e = lbhjae.step(bad, 0.01, None).unwrap_err();
    assert!(e.to_string().contains("theta_c_deg"), "{e}");
    assert!(
        lbhjae
            .step(
                Command {
                    theta_c_deg: 20.0,
                    translation_mm: 10.0
                },
                -1.0,
                None
            )
            .is_err()
    );
    let good = Command {
        theta_c_deg: 20.0,
        translation_mm: 10.0,
    };
    let e = lbhjae
        .step_with_rate(good, f64::INFINITY, 0.01, None)
        .unwrap_err();
    assert!(e.to_string().contains("rate_deg_per_s"), "{e}");
    assert_eq!(format!("{lbhjae:?}"), before);
    // KBJAE inside reads the rate given: a frameless tick's KBJAE reading is
    // its own model's at that rate
    let mut probe = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let e = lbhjae.step_with_rate(good, -12.0, 0.01, None).unwrap();
    assert_eq!(e.kbjae_deg, probe.predict(20.0, -12.0).unwrap());
}

#[test]
fn a_window_of_the_image_reads_as_the_whole_frame() {
    // the closed loop renders only the window IBJAE reads
    let camera = Camera::default();
    let mut ibjae = ibjae(&camera);
    let roi = paper_band(&camera).roi;
    assert_eq!(ibjae.window(&[0]), Some(roi));
    assert_eq!(ibjae.window(&[]), None);
    assert_eq!(ibjae.window(&[7]), None);
    let mut renderer = SceneRenderer::new();
    let shape = Instrument::kflex().shape(23.0, 10.0).unwrap();
    let params = FrameParams::default();
    let full = renderer.render(&camera, &shape, &params).unwrap();
    let whole = ibjae
        .read(
            &RgbView::packed(&full.rgb, full.width, full.height).unwrap(),
            &[0],
        )
        .unwrap();
    // the band's region exactly, and a window with room around it
    let around = Roi {
        x0: roi.x0 - 7,
        y0: roi.y0 - 3,
        width: roi.width + 20,
        height: roi.height + 9,
    };
    for window in [roi, around] {
        let part = renderer
            .render_window(&camera, &shape, &params, window)
            .unwrap();
        let view = RgbView::window(&part.rgb, window, 3 * window.width as usize).unwrap();
        assert_eq!(ibjae.read(&view, &[0]).unwrap(), whole, "{window:?}");
    }
    // a window that misses part of the region is refused, naming the edge
    for (window, edge) in [
        (
            Roi {
                x0: roi.x0 + 1,
                ..roi
            },
            "roi.x0",
        ),
        (
            Roi {
                y0: roi.y0 + 1,
                ..roi
            },
            "roi.y0",
        ),
        (
            Roi {
                width: roi.width - 1,
                ..roi
            },
            "roi.x0 + roi.width",
        ),
        (
            Roi {
                height: roi.height - 1,
                ..roi
            },
            "roi.y0 + roi.height",
        ),
    ] {
        let data = vec![0u8; 3 * window.area() as usize];
        let view = RgbView::window(&data, window, 3 * window.width as usize).unwrap();
        let e = ibjae.read(&view, &[0]).unwrap_err();
        assert_eq!(e.range().map(|r| r.name), Some(edge), "{e}");
    }
}

#[test]
fn lbhjae_names_the_window_its_next_frame_must_cover() {
    let camera = Camera::default();
    let kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
    let lbhjae = Lbhjae::new(kbjae, ibjae(&camera), fusion);
    assert_eq!(lbhjae.frame_window(10.0), Some(paper_band(&camera).roi));
    // no band holds 30 mm: no frame to read
    assert_eq!(lbhjae.frame_window(30.0), None);
}
