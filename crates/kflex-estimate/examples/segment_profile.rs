//! A driver for profiling the segmentation (not a benchmark: the `segment`
//! bench times it). It segments the bench's frame in the paper's region of
//! interest with a kept `Segmenter`, after one segmentation that sizes its
//! buffers, so that a profiler counts the measured ones alone:
//!
//! ```text
//! cargo build --release -p kflex-estimate --example segment_profile
//! valgrind --tool=callgrind --dump-instr=no \
//!     --toggle-collect='segment_profile::measured' \
//!     target/release/examples/segment_profile 100
//! ```
//!
//! With a second argument, `colon`, `stomach` or `larynx`, it segments the
//! band IBJAE reads at the paper's d = 10 mm on that organ instead, as the
//! bench's `segment_band_10mm_*` and the grid do: a window rendered on its own.

use std::hint::black_box;

use kflex_estimate::{SegmentParams, Segmenter};
use kflex_model::{
    Background, Camera, Frame, FrameParams, Instrument, Roi, SceneRenderer, WorkingRegions,
};

/// `n` segmentations of `frame` in `roi`; the instrument pixels found, summed.
#[inline(never)]
fn measured(segmenter: &mut Segmenter, frame: &Frame, roi: Roi, n: usize) -> usize {
    (0..n)
        .map(|_| {
            segmenter
                .segment(&frame.rgb, frame.width, frame.height, roi)
                .map_or(0, |s| s.full.count())
        })
        .sum()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = std::env::args().nth(1).map_or(Ok(100), |a| a.parse())?;
    let camera = Camera::default();
    let shape = Instrument::kflex().shape(30.0, 10.0)?;
    let (frame, roi) = match std::env::args().nth(2).as_deref() {
        None => (
            SceneRenderer::new().render(&camera, &shape, &FrameParams::default())?,
            Roi::paper(&camera)?,
        ),
        Some(organ) => {
            let background: Background = organ.parse()?;
            let band = WorkingRegions::full(&camera)?.at(30.0, 10.0)?.roi;
            let params = FrameParams {
                background,
                ..FrameParams::default()
            };
            let f = SceneRenderer::new().render_window(&camera, &shape, &params, band)?;
            let whole = Roi::whole(f.width, f.height);
            (f, whole)
        }
    };
    let mut segmenter = Segmenter::new(SegmentParams::default())?;
    segmenter.segment(&frame.rgb, frame.width, frame.height, roi)?;
    println!("{}", black_box(measured(&mut segmenter, &frame, roi, n)));
    Ok(())
}
