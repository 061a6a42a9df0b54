//! A kept `Segmenter` allocates nothing once it has seen a region of the
//! size (issue 9): a counting allocator around segmentations of frames that
//! differ in pose, background, tissue, noise, blur and tape, after one frame.
//! (Its own test binary: the allocator is global.)

#[path = "support/counting.rs"]
mod counting;

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{
    Background, Camera, FrameParams, Instrument, Occlusion, Roi, SceneRenderer, Tissue,
};

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn a_kept_segmenter_allocates_nothing_after_the_first_region() {
    let camera = Camera::default();
    let roi = Roi::paper(&camera).unwrap();
    let mut renderer = SceneRenderer::new();
    // frames rendered beforehand: the renderer is not under test
    let mut frames = Vec::new();
    for (k, background) in Background::ALL.into_iter().enumerate() {
        for (j, tissue) in [Tissue::Organ, Tissue::Grey, Tissue::White]
            .into_iter()
            .enumerate()
        {
            let shape = Instrument::kflex()
                .shape(
                    -60.0 + 40.0 * j as f64 + 5.0 * k as f64,
                    8.0 + 6.0 * k as f64,
                )
                .unwrap();
            let params = FrameParams {
                background,
                tissue,
                noise_std: 0.02 * j as f64,
                // blur 3 px makes the boundary step take its later passes
                blur_px: 1.5 * k as f64,
                occlusion: (j == 1).then(|| Occlusion::new(0.4, 0.5)),
                seed: k as u64,
                ..FrameParams::default()
            };
            frames.push(renderer.render(&camera, &shape, &params).unwrap());
        }
    }
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let first = &frames[0];
    segmenter
        .segment(&first.rgb, first.width, first.height, roi)
        .unwrap();
    let before = counting::allocations();
    let mut found = 0;
    for f in &frames {
        found += usize::from(segmenter.segment(&f.rgb, f.width, f.height, roi).is_ok());
    }
    let after = counting::allocations();
    assert!(
        found >= frames.len() - 1,
        "found {found} of {}",
        frames.len()
    );
    assert_eq!(
        after - before,
        0,
        "allocations in {} segmentations",
        frames.len()
    );
}
