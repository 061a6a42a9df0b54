//! The segmentation stage of the loop allocates nothing once it has seen a
//! region of the size (DESIGN: one tick, no allocation).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::Camera;
use kflex_model::Instrument;
use kflex_model::Roi;
use kflex_model::{Background, FrameParams, Occlusion, SceneRenderer};

/// Counts the allocations this thread makes while `COUNTING` is set.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: forwards every call to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_frame_after_the_first_allocates_nothing() {
    let mut renderer = SceneRenderer::new();
    let camera = Camera::default();
    let roi = Roi::working(&camera).unwrap();
    let mut frame = |theta: f64, background: Background, occlusion: Option<Occlusion>| {
        let shape = Instrument::kflex().shape(theta, 10.0).unwrap();
        let params = FrameParams {
            background,
            occlusion,
            ..FrameParams::default()
        };
        renderer.render(&camera, &shape, &params).unwrap()
    };
    // the first frame: clean, small; the rest differ in angle, background and tape
    let first = frame(5.0, Background::Colon, None);
    let others = [
        frame(45.0, Background::Larynx, None),
        frame(25.0, Background::Stomach, None),
        frame(
            30.0,
            Background::Colon,
            Some(Occlusion {
                fraction: 0.4,
                position: 1.0,
            }),
        ),
    ];
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let reference = segmenter
        .segment(&first.rgb, first.width, first.height, roi)
        .unwrap()
        .small
        .count();
    assert!(reference > 20);
    for f in &others {
        COUNTING.with(|c| c.set(true));
        let pixels = segmenter
            .segment(&f.rgb, f.width, f.height, roi)
            .map(|s| s.small.count());
        COUNTING.with(|c| c.set(false));
        assert!(pixels.unwrap() > 20);
        assert_eq!(ALLOCATIONS.load(Ordering::Relaxed), 0, "allocations");
    }
}
