//! Segmentation against the rendered frames' ground truth.

use kflex_estimate::{EstimateError, Roi, SegmentParams, segment};
use kflex_model::Mask;
use kflex_model::camera::Camera;
use kflex_model::instrument::Instrument;
use kflex_model::scene::{Background, Frame, FrameParams, Occlusion, SceneRenderer};

const ROI: Roi = Roi {
    x0: 220,
    y0: 240,
    width: 220,
    height: 220,
};

fn crop(mask: &Mask, roi: Roi) -> Mask {
    mask.crop(roi.x0, roi.y0, roi.width, roi.height).unwrap()
}

fn render(theta: f64, params: FrameParams) -> Frame {
    let shape = Instrument::kflex().shape(theta, 10.0).unwrap();
    SceneRenderer::new()
        .render(&Camera::default(), &shape, &params)
        .unwrap()
}

#[test]
fn unoccluded_frames_segment_with_iou_at_least_0_9() {
    let mut ious = Vec::new();
    for bg in Background::ALL {
        for gain in [0.7, 1.0, 1.3] {
            for (i, theta) in [0.0, 25.0, 50.0].into_iter().enumerate() {
                let params = FrameParams {
                    background: bg,
                    seed: 11 + i as u64,
                    illumination_gain: gain,
                    ..FrameParams::default()
                };
                let f = render(theta, params);
                let seg =
                    segment(&f.rgb, f.width, f.height, ROI, &SegmentParams::default()).unwrap();
                let iou = seg.full.iou(&crop(&f.instrument, ROI)).unwrap();
                ious.push((iou, bg, gain, theta));
            }
        }
    }
    ious.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = ious.len();
    eprintln!(
        "IoU over {n} frames: min {:.3} ({:?}, gain {}, θ {}), median {:.3}, max {:.3}",
        ious[0].0,
        ious[0].1,
        ious[0].2,
        ious[0].3,
        ious[n / 2].0,
        ious[n - 1].0
    );
    assert!(ious[0].0 >= 0.9, "worst IoU {:?}", ious[0]);
}

#[test]
fn taped_part_is_lost_and_the_rest_found() {
    for (fraction, position) in [(0.2, 0.5), (0.4, 0.5), (0.4, 1.0)] {
        let params = FrameParams {
            occlusion: Some(Occlusion { fraction, position }),
            ..FrameParams::default()
        };
        let f = render(30.0, params);
        let seg = segment(&f.rgb, f.width, f.height, ROI, &SegmentParams::default()).unwrap();
        let visible = crop(&f.instrument, ROI);
        let tape = crop(&f.occluder, ROI);
        let iou = seg.full.iou(&visible).unwrap();
        let on_tape = seg
            .full
            .data()
            .iter()
            .zip(tape.data())
            .filter(|(s, t)| **s != 0 && **t != 0)
            .count();
        eprintln!(
            "tape {fraction} at {position}: IoU vs visible part {iou:.3}, {on_tape} px on the tape"
        );
        assert!(iou >= 0.85, "IoU against the visible part {iou}");
        assert!(
            on_tape * 50 < tape.count().max(1),
            "the red tape must not read as instrument"
        );
    }
}

#[test]
fn small_output_is_48_by_48_and_follows_the_angle() {
    let a = render(10.0, FrameParams::default());
    let b = render(40.0, FrameParams::default());
    let sa = segment(&a.rgb, a.width, a.height, ROI, &SegmentParams::default())
        .unwrap()
        .small;
    let sb = segment(&b.rgb, b.width, b.height, ROI, &SegmentParams::default())
        .unwrap()
        .small;
    assert_eq!((sa.width(), sa.height()), (48, 48));
    assert!(sa.count() > 20 && sb.count() > 20);
    assert!(
        sa.iou(&sb).unwrap() < 0.9,
        "10 and 40 deg should look different"
    );
}

#[test]
fn no_instrument_and_bad_buffers_are_errors() {
    let f = render(30.0, FrameParams::default());
    // the top-left corner holds only tissue
    let empty = Roi {
        x0: 0,
        y0: 0,
        width: 120,
        height: 120,
    };
    assert!(matches!(
        segment(&f.rgb, f.width, f.height, empty, &SegmentParams::default()),
        Err(EstimateError::NoInstrument { .. })
    ));
    assert!(matches!(
        segment(
            &f.rgb[..100],
            f.width,
            f.height,
            ROI,
            &SegmentParams::default()
        ),
        Err(EstimateError::ImageSize { .. })
    ));
    let outside = Roi {
        x0: 600,
        y0: 0,
        width: 100,
        height: 10,
    };
    assert!(matches!(
        segment(
            &f.rgb,
            f.width,
            f.height,
            outside,
            &SegmentParams::default()
        ),
        Err(EstimateError::InvalidParameter { .. })
    ));
    assert!(segment(&[], 0, 0, ROI, &SegmentParams::default()).is_err());
}
