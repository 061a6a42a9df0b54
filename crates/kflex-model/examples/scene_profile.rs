//! A driver for profiling the shaded frames (not a benchmark: the `scene`
//! bench times them). It renders what the bench renders, the pose changing
//! every frame, after two frames that fill the renderer's caches, so that a
//! profiler can count one function's frames alone:
//!
//! ```text
//! cargo build --release -p kflex-model --example scene_profile
//! valgrind --tool=callgrind --dump-instr=no \
//!     --toggle-collect='scene_profile::measured' \
//!     target/release/examples/scene_profile full 10
//! ```
//!
//! `scene_profile full|roi FRAMES [check]`: the full 640×480 frame with 40 %
//! distal tape, or the paper's region of interest alone (`render_window`);
//! `check` prints a checksum of every pixel and mask of the frames.
//! `scene_profile golden`: one checksum per frame over a matrix of
//! backgrounds, tissues, gains, noise, blur, tape, poses, windows and two
//! cameras, to compare a change's frames with the code before it.

use kflex_model::{
    Background, Camera, Frame, FrameParams, Instrument, Intrinsics, Occlusion, Roi, SceneRenderer,
    Tissue,
};

/// What every frame of a run shares.
struct Run {
    renderer: SceneRenderer,
    camera: Camera,
    instrument: Instrument,
    params: FrameParams,
    window: Option<Roi>,
    theta: f64,
}

/// FNV-1a of the frame's bytes, into `sum`.
#[inline(never)]
fn checksum(f: &Frame, sum: &mut u64) {
    for b in f
        .rgb
        .iter()
        .chain(f.instrument.data())
        .chain(f.occluder.data())
    {
        *sum = (*sum ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3);
    }
}

/// `frames` frames, the bend moving 0.37° a frame as in the bench; their
/// checksum into `sum` unless `sum` is `None`.
#[inline(always)]
fn frames(run: &mut Run, frames: usize, mut sum: Option<&mut u64>) {
    for _ in 0..frames {
        run.theta = (run.theta + 0.37) % 50.0;
        let shape = run.instrument.shape(run.theta, 10.0).expect("shape");
        let frame = match run.window {
            Some(r) => run
                .renderer
                .render_window(&run.camera, &shape, &run.params, r),
            None => run.renderer.render(&run.camera, &shape, &run.params),
        }
        .expect("frame");
        if let Some(sum) = sum.as_deref_mut() {
            checksum(&frame, sum);
        }
    }
}

/// The frames before the counted ones (the caches filled).
#[inline(never)]
fn warm(run: &mut Run, n: usize) {
    frames(run, n, None);
}

/// The counted frames.
#[inline(never)]
fn measured(run: &mut Run, n: usize, sum: Option<&mut u64>) {
    frames(run, n, sum);
}

/// Checksums of frames over a matrix of parameters, windows and cameras.
fn golden() {
    let instrument = Instrument::kflex();
    let cameras = [
        Camera::default(),
        Camera::default().with_intrinsics(Intrinsics::from_fov(333, 211, 90.0).expect("k")),
    ];
    let mut renderer = SceneRenderer::new();
    let mut total = 0xcbf2_9ce4_8422_2325u64;
    let cases = [
        (
            Background::Colon,
            Tissue::Organ,
            1.0,
            0.01,
            0.0,
            Some(Occlusion::new(0.4, 1.0)),
        ),
        (
            Background::Stomach,
            Tissue::Grey,
            1.7,
            0.05,
            0.0,
            Some(Occlusion::new(0.2, 0.5)),
        ),
        (Background::Larynx, Tissue::White, 0.6, 0.0, 0.0, None),
        (
            Background::Colon,
            Tissue::BlueGreen,
            1.0,
            0.02,
            1.3,
            Some(Occlusion::new(0.3, 0.0)),
        ),
        (Background::Stomach, Tissue::Organ, 1.0, 0.01, 0.0, None),
    ];
    for (ci, camera) in cameras.iter().enumerate() {
        let k = camera.intrinsics;
        let windows = [
            Roi::whole(k.width, k.height),
            Roi {
                x0: 3,
                y0: 5,
                width: k.width / 2 + 7,
                height: k.height / 3 + 1,
            },
            Roi {
                x0: k.width / 3,
                y0: k.height / 4,
                width: k.width / 2,
                height: k.height / 2,
            },
            Roi {
                x0: 1,
                y0: 1,
                width: 1,
                height: 1,
            },
            Roi {
                x0: k.width - 5,
                y0: k.height - 6,
                width: 5,
                height: 6,
            },
        ];
        for (case, &(background, tissue, gain, noise, blur, occlusion)) in cases.iter().enumerate()
        {
            for (theta, d, frame) in [
                (-40.0, 12.0, 0u64),
                (5.0, 9.0, 3),
                (33.0, 25.0, 7),
                (80.0, 38.0, 1),
            ] {
                let shape = instrument.shape(theta, d).expect("shape");
                let params = FrameParams {
                    background,
                    tissue,
                    seed: case as u64,
                    frame,
                    illumination_gain: gain,
                    noise_std: noise,
                    blur_px: blur,
                    occlusion,
                };
                for (wi, w) in windows.iter().enumerate() {
                    let f = renderer
                        .render_window(camera, &shape, &params, *w)
                        .expect("frame");
                    let mut sum = 0xcbf2_9ce4_8422_2325u64;
                    checksum(&f, &mut sum);
                    total = (total ^ sum).wrapping_mul(0x100_0000_01b3);
                    println!("camera {ci} case {case} theta {theta} window {wi}: {sum:016x}");
                }
            }
        }
    }
    println!("total {total:016x}");
}

fn main() {
    let mut args = std::env::args().skip(1);
    let mode = args.next().unwrap_or_else(|| "full".into());
    if mode == "golden" {
        golden();
        return;
    }
    let n: usize = args.next().map_or(20, |s| s.parse().expect("frames"));
    let check = args.next().as_deref() == Some("check");
    let camera = Camera::default();
    let roi = Roi::paper(&camera).expect("working region");
    let (occlusion, window) = if mode == "roi" {
        (Occlusion::new(0.4, 1.0).within(roi), Some(roi))
    } else {
        (Occlusion::new(0.4, 1.0), None)
    };
    let mut run = Run {
        renderer: SceneRenderer::new(),
        camera,
        instrument: Instrument::kflex(),
        params: FrameParams {
            occlusion: Some(occlusion),
            ..FrameParams::default()
        },
        window,
        theta: 0.0,
    };
    warm(&mut run, 2);
    // the byte-by-byte checksum takes about as long as a frame: only when asked
    let mut sum = 0xcbf2_9ce4_8422_2325u64;
    measured(&mut run, n, check.then_some(&mut sum));
    if check {
        println!("{mode} {n} frames checksum {sum:016x}");
    } else {
        println!("{mode} {n} frames");
    }
}
