//! The stages of the control loop allocate nothing per tick once set up
//! (DESIGN: one tick, no allocation): the plant, whether it accepts or
//! rejects a command, the segmentation once it has seen a region of the
//! size, the fusion filters and the compensator. Later stages join this file.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{
    Background, Camera, Command, FrameParams, Instrument, ModelError, Occlusion, Plant,
    PlantConfig, Roi, SceneRenderer,
};

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

/// Allocations made by `f` on this thread.
fn allocations<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    COUNTING.with(|c| c.set(true));
    let out = f();
    COUNTING.with(|c| c.set(false));
    (out, ALLOCATIONS.load(Ordering::Relaxed) - before)
}

#[test]
fn plant_steps_allocate_nothing_accepted_or_rejected() {
    let mut plant = Plant::new(PlantConfig {
        sheath_deg: 180.0,
        ..PlantConfig::default()
    })
    .unwrap();
    let command = |theta_c_deg, translation_mm| Command {
        theta_c_deg,
        translation_mm,
    };
    for k in 0..200 {
        let theta = 25.0 * (f64::from(k) * 0.05).sin() + 25.0;
        let (state, n) = allocations(|| plant.step(command(theta, 10.0), 0.01));
        assert!(state.unwrap().theta_a_deg.is_finite());
        assert_eq!(n, 0, "accepted step {k} allocated");
    }
    let before = *plant.state();
    for (bad, dt) in [
        (command(f64::NAN, 10.0), 0.01),
        (command(300.0, 10.0), 0.01),
        (command(20.0, -5.0), 0.01),
        (command(20.0, 10.0), -1.0),
    ] {
        let (result, n) = allocations(|| plant.step(bad, dt));
        assert!(matches!(
            result,
            Err(ModelError::NonFinite { .. }
                | ModelError::OutOfWorkspace(_)
                | ModelError::OutOfRange(_))
        ));
        assert_eq!(n, 0, "rejected step {bad:?} dt {dt} allocated");
        assert_eq!(*plant.state(), before);
    }
}

#[test]
fn a_frame_after_the_first_allocates_nothing() {
    let mut renderer = SceneRenderer::new();
    let camera = Camera::default();
    let roi = Roi::paper(&camera).unwrap();
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
        frame(30.0, Background::Colon, Some(Occlusion::new(0.4, 1.0))),
    ];
    let mut segmenter = Segmenter::new(SegmentParams::default()).unwrap();
    let reference = segmenter
        .segment(&first.rgb, first.width, first.height, roi)
        .unwrap()
        .small
        .count();
    assert!(reference > 20);
    for f in &others {
        let (pixels, n) = allocations(|| {
            segmenter
                .segment(&f.rgb, f.width, f.height, roi)
                .map(|s| s.small.count())
        });
        assert!(pixels.unwrap() > 20);
        assert_eq!(n, 0, "allocations");
    }
}

#[test]
fn fusion_steps_allocate_nothing_accepted_or_rejected() {
    use kflex_estimate::{
        AdaptiveKalman, AdaptiveParams, FilterRate, Fusion, KalmanParams, Measurements, PaperKalman,
    };
    let mut filters: Vec<Box<dyn Fusion>> = vec![
        Box::new(PaperKalman::new(KalmanParams::default()).unwrap()),
        Box::new(
            PaperKalman::new(KalmanParams {
                rate: FilterRate::AsWritten,
                ..KalmanParams::default()
            })
            .unwrap(),
        ),
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).unwrap()),
    ];
    for f in &mut filters {
        for k in 0..300 {
            let theta = 25.0 * (f64::from(k) * 0.01).sin() + 25.0;
            let m = Measurements {
                kbjae_deg: Some(theta + 2.0),
                // a camera frame every third tick, an outlier now and then
                ibjae_deg: (k % 3 == 0).then_some(if k % 51 == 0 { 80.0 } else { theta }),
                ibjae_sigma_deg: (k % 2 == 0).then_some(2.5),
                ibjae_occluded: false,
            };
            let (e, n) = allocations(|| f.step(0.01, m));
            assert!(e.unwrap().theta_hat_deg.is_finite());
            assert_eq!(n, 0, "step {k} allocated");
        }
        let bad = Measurements {
            kbjae_deg: Some(f64::NAN),
            ..Measurements::default()
        };
        let (e, n) = allocations(|| f.step(0.01, bad));
        assert!(e.is_err());
        assert_eq!(n, 0, "a rejected step allocated");
    }
}

#[test]
fn compensator_steps_allocate_nothing_even_when_faulted() {
    use kflex_control::{BacklashTerm, Compensator, CompensatorConfig};
    for backlash_term in [
        BacklashTerm::Off,
        BacklashTerm::PidCorrection,
        BacklashTerm::TotalCorrection,
    ] {
        let mut comp = Compensator::new(CompensatorConfig {
            backlash_term,
            ..CompensatorConfig::default()
        })
        .unwrap();
        for k in 0..400 {
            let theta_d = 25.0 * (f64::from(k) * 0.01).sin() + 25.0;
            // every third tick an estimate, and now and then a bad input or a
            // long gap that trips the watchdog
            let theta_hat = match k {
                _ if (100..140).contains(&k) => None,
                _ if k % 37 == 0 => Some(f64::NAN),
                _ => (k % 3 == 0).then_some(theta_d - 2.0),
            };
            let dt = if k % 53 == 0 { -1.0 } else { 0.01 };
            let theta_d = if k % 71 == 0 { f64::NAN } else { theta_d };
            let (out, n) = allocations(|| comp.step(theta_d, theta_hat, dt));
            assert!(out.theta_c_deg.is_finite());
            assert_eq!(
                n, 0,
                "{backlash_term:?} step {k} allocated ({:?})",
                out.fault
            );
        }
    }
}
