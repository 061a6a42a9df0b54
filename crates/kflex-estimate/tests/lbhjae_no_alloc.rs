//! An LBHJAE tick allocates nothing in Rust once the first frame has been
//! read (the embedding API): a counting allocator around ticks with
//! and without frames, after warm-up ticks. ONNX Runtime's own C++
//! allocations are not Rust's and are not counted. (Its own test binary:
//! the allocator is global.)
#![cfg(all(feature = "onnx", feature = "index"))]

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, Fusion, Ibjae, Kbjae, Lbhjae, RgbView, Scnn, SegmentParams,
    build_band_database,
};
use kflex_model::{
    Camera, Command, FrameParams, Instrument, PoseRange, Roi, SceneRenderer, WorkingBand,
};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

#[test]
fn an_lbhjae_tick_allocates_nothing_after_the_first_frames() {
    let camera = Camera::default();
    let band = WorkingBand {
        poses: PoseRange {
            theta_deg: [0.0, 50.0],
            translation_mm: [10.0, 10.0],
        },
        roi: Roi::paper(&camera).unwrap(),
    };
    let mut scnn = Scnn::load(&data("scnn_test.onnx"), 1).unwrap();
    let db =
        build_band_database(&mut scnn, &camera, &Instrument::kflex(), &band, 1.0, 1.0).unwrap();
    let ibjae = Ibjae::new(scnn, SegmentParams::default(), vec![db]).unwrap();
    let kbjae = Kbjae::load(&data("kbjae_test.onnx")).unwrap();
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap());
    let mut lbhjae = Lbhjae::new(kbjae, ibjae, fusion);
    // frames rendered beforehand: the renderer is not under test
    let mut renderer = SceneRenderer::new();
    let frames: Vec<_> = (0..6)
        .map(|k| {
            let shape = Instrument::kflex()
                .shape(10.0 + 5.0 * f64::from(k), 10.0)
                .unwrap();
            renderer
                .render(&camera, &shape, &FrameParams::default())
                .unwrap()
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
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    let mut read = 0;
    for k in 0..40 {
        let frame = (k % 10 == 0).then(|| &views[2 + (k / 10) % 4]);
        let e = lbhjae.step(command(k), 0.01, frame).unwrap();
        read += usize::from(e.ibjae.is_some());
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(read, 4);
    assert_eq!(after - before, 0, "allocations in 40 ticks with 4 frames");
}
