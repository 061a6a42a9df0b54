//! Segmentation time. `cargo bench -p kflex-estimate --bench segment`
//! Goals: the working region of interest ≤ 0.2 ms on the nominal frame
//! (camera v2; also timed, with no goal, on a frame with noise σ 0.1, the
//! robustness goals' worst); whole
//! 640×480 frame ≤ 1 ms median, 1920×1080 ≤ 5 ms (issue 3).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use kflex_estimate::{SegmentParams, Segmenter, segment};
use kflex_model::Instrument;
use kflex_model::Roi;
use kflex_model::{Camera, Intrinsics};
use kflex_model::{FrameParams, SceneRenderer};

fn bench(c: &mut Criterion) {
    let shape = Instrument::kflex().shape(30.0, 10.0).expect("shape");
    {
        let camera = Camera::default();
        let f = SceneRenderer::new()
            .render(&camera, &shape, &FrameParams::default())
            .expect("frame");
        let roi = Roi::paper(&camera).expect("working region");
        let mut segmenter = Segmenter::new(SegmentParams::default()).expect("params");
        c.bench_function("segment_working_roi", |b| {
            b.iter(|| {
                black_box(
                    segmenter
                        .segment(&f.rgb, f.width, f.height, roi)
                        .expect("segment")
                        .small
                        .count(),
                )
            })
        });
        // under the noise of the robustness goals (σ 0.1): every merged
        // region's dark channels are read back through the sensor's
        // clipping at 0 (most channels lie under 4 σ)
        let noisy = SceneRenderer::new()
            .render(
                &camera,
                &shape,
                &FrameParams {
                    noise_std: 0.1,
                    ..FrameParams::default()
                },
            )
            .expect("frame");
        c.bench_function("segment_working_roi_noise_0.1", |b| {
            b.iter(|| {
                black_box(
                    segmenter
                        .segment(&noisy.rgb, noisy.width, noisy.height, roi)
                        .expect("segment")
                        .small
                        .count(),
                )
            })
        });
    }
    for (name, intrinsics) in [
        ("segment_640x480", Intrinsics::default()),
        ("segment_1920x1080", Intrinsics::full_hd()),
    ] {
        let camera = Camera::default().with_intrinsics(intrinsics);
        let f = SceneRenderer::new()
            .render(&camera, &shape, &FrameParams::default())
            .expect("frame");
        let roi = Roi {
            x0: 0,
            y0: 0,
            width: f.width,
            height: f.height,
        };
        // the loop's way: one Segmenter kept from frame to frame
        let mut segmenter = Segmenter::new(SegmentParams::default()).expect("params");
        c.bench_function(name, |b| {
            b.iter(|| {
                black_box(
                    segmenter
                        .segment(&f.rgb, f.width, f.height, roi)
                        .expect("segment")
                        .small
                        .count(),
                )
            })
        });
        // one-off: `segment`, allocating its working memory every call
        c.bench_function(&format!("{name}_one_off"), |b| {
            b.iter(|| {
                black_box(
                    segment(&f.rgb, f.width, f.height, roi, &SegmentParams::default())
                        .expect("segment")
                        .small
                        .count(),
                )
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
