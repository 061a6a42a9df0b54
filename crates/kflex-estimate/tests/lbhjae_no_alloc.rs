//! An LBHJAE tick allocates nothing in Rust once the first frame has been
//! read (the embedding API), the silhouette check included: a
//! counting allocator around ticks with and without frames, after warm-up
//! ticks. ONNX Runtime's own C++
//! allocations are not Rust's and are not counted. (Its own test binary:
//! the allocator is global.)
#![cfg(all(feature = "onnx", feature = "index"))]

#[path = "support/counting.rs"]
mod counting;
#[path = "support/paper_ibjae.rs"]
mod paper_ibjae;

use kflex_estimate::{AdaptiveKalman, AdaptiveParams, Fusion, Kbjae, Lbhjae, RgbView};
use kflex_model::{Camera, Command, FrameParams, Instrument, Occlusion, SceneRenderer};
use paper_ibjae::{checked_ibjae, data, paper_band};

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn an_lbhjae_tick_allocates_nothing_after_the_first_frames() {
    let camera = Camera::default();
    let ibjae = checked_ibjae(&camera);
    let kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
    let mut lbhjae = Lbhjae::new(kbjae, ibjae, fusion);
    // frames rendered beforehand: the renderer is not under test; the last
    // two under tape over the middle of the instrument, so that the check
    // reads a hidden part (its band's grid of silhouettes is rendered then)
    let mut renderer = SceneRenderer::new();
    let roi = paper_band(&camera).roi;
    let frames: Vec<_> = (0..6)
        .map(|k| {
            let shape = Instrument::kflex()
                .shape(10.0 + 5.0 * f64::from(k), 10.0)
                .unwrap();
            let params = FrameParams {
                occlusion: (k >= 4).then(|| Occlusion::new(0.4, 0.5).within(roi)),
                ..FrameParams::default()
            };
            renderer.render(&camera, &shape, &params).unwrap()
        })
        .collect();
    let views: Vec<RgbView> = frames
        .iter()
        .map(|f| RgbView::packed(&f.rgb, f.width, f.height).unwrap())
        .collect();
    let command = |k: usize| Command {
        theta_c_deg: 10.0 + 0.1 * k as f64,
        translation_mm: 10.0,
    };
    for (k, view) in views.iter().take(2).enumerate() {
        lbhjae.step(command(k), 0.01, Some(view)).unwrap();
        lbhjae.step(command(k), 0.01, None).unwrap();
    }
    let before = counting::allocations();
    let (mut read, mut hidden) = (0, 0);
    for k in 0..40 {
        let frame = (k % 10 == 0).then(|| &views[2 + (k / 10) % 4]);
        let e = lbhjae.step(command(k), 0.01, frame).unwrap();
        read += usize::from(e.ibjae.is_some());
        hidden += usize::from(e.ibjae.is_some_and(|r| r.occluded));
    }
    let after = counting::allocations();
    assert_eq!((read, hidden), (4, 2));
    assert_eq!(after - before, 0, "allocations in 40 ticks with 4 frames");
}
