//! `kflex-cli render`: one frame of the camera simulator, for a person to look at.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use kflex_estimate::{SegmentParams, Segmentation, segment};
use kflex_model::{
    Background, Camera, Frame, FrameParams, Instrument, Intrinsics, Mask, Occlusion, Rasterizer,
    Roi, SceneRenderer, Tissue, WorkingRegions,
};

use crate::output::{encode_png, write_atomic_set};

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Bend θ, deg.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    theta: f64,
    /// Translation d out of the overtube, mm.
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true)]
    d: f64,
    /// Background: colon, stomach or larynx.
    #[arg(long, default_value = "colon")]
    background: String,
    /// Tissue colour: organ (the background's own), grey, pale, white, blue_green or yellow.
    #[arg(long, default_value = "organ")]
    tissue: String,
    /// Share of the visible instrument covered by red tape (0 for none).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    occlusion: f64,
    /// Where the tape sits along the instrument: 0 proximal … 1 ending at the tip (the paper's "distal").
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    occlusion_position: f64,
    /// Seed of the background and the sensor noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Frame number: fresh sensor noise over the same background.
    #[arg(long, default_value_t = 0)]
    frame: u64,
    /// Illumination gain.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    gain: f64,
    /// Sensor noise standard deviation on the [0, 1] image.
    #[arg(long, default_value_t = 0.01, allow_negative_numbers = true)]
    noise: f64,
    /// Gaussian blur, px.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    blur: f64,
    /// Render at 1920×1080 (the paper's camera) instead of 640×480.
    #[arg(long)]
    hd: bool,
    /// Folder for the PNG files.
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

/// The files `render` writes.
const RENDERED: [&str; 4] = [
    "frame.png",
    "silhouette_48.png",
    "instrument_mask.png",
    "occluder_mask.png",
];

pub fn render(args: &RenderArgs) -> Result<()> {
    let names: Vec<&str> = RENDERED
        .iter()
        .chain(SEGMENTATION_FILES.iter())
        .copied()
        .collect();
    crate::output::check_writable(&args.out, &names)?;
    let background: Background = args.background.parse()?;
    let tissue: Tissue = args.tissue.parse()?;
    let intrinsics = if args.hd {
        Intrinsics::full_hd()
    } else {
        Intrinsics::default()
    };
    let camera = Camera::default().with_intrinsics(intrinsics);
    let shape = Instrument::kflex().shape(args.theta, args.d)?;
    // the position is checked even without tape (FrameParams checks it with tape)
    kflex_model::Bounds::closed(0.0, 1.0)
        .check("occlusion_position", args.occlusion_position)
        .context("--occlusion-position")?;
    let occlusion =
        (args.occlusion != 0.0).then_some(Occlusion::new(args.occlusion, args.occlusion_position));
    let params = FrameParams {
        background,
        tissue,
        seed: args.seed,
        frame: args.frame,
        illumination_gain: args.gain,
        noise_std: args.noise,
        blur_px: args.blur,
        occlusion,
    };
    let frame = SceneRenderer::new().render(&camera, &shape, &params)?;
    // the working region of the pose's translation: where the joint and
    // gripper can be over its band of poses
    let regions = WorkingRegions::full(&camera)?;
    let covered = *regions.poses();
    let roi = regions
        .nearest(args.theta, args.d)
        .context("the camera has no working region")?
        .roi;
    if !covered.contains(args.theta, args.d) {
        let ([lo, hi], [d_lo, d_hi]) = (covered.theta_deg, covered.translation_mm);
        outln!(
            "note: the working regions of interest cover θ in [{lo}, {hi}] deg at d in [{d_lo}, {d_hi}] mm; \
             outside them the region may cut off part of the joint or gripper"
        );
    }
    let roi_camera = camera.with_intrinsics(roi.intrinsics(&intrinsics, 48, 48)?);
    let mut silhouette = Mask::new(48, 48)?;
    Rasterizer::new().silhouette(&roi_camera, &shape, &mut silhouette)?;

    // the segmentation first, then the files: every failure of the
    // segmentation is the command's failure (non-zero exit); the frame's
    // PNGs are written all the same, to look at, and the segmentation's
    // from an earlier render in the folder are removed, so that the folder
    // never holds a segmentation of another frame
    let segmented = segment_frame(&frame, roi, args.occlusion);
    // the frame's four files as one set: written together or not at all
    let rgb = encode_png(
        "frame.png",
        &frame.rgb,
        frame.width,
        frame.height,
        image::ExtendedColorType::Rgb8,
    )?;
    write_atomic_set(
        &args.out,
        &[
            (RENDERED[0], &rgb),
            (RENDERED[1], &mask_png(RENDERED[1], &silhouette)?),
            (RENDERED[2], &mask_png(RENDERED[2], &frame.instrument)?),
            (RENDERED[3], &mask_png(RENDERED[3], &frame.occluder)?),
        ],
    )?;
    let (seg, iou) = match segmented {
        Ok(done) => done,
        Err(e) => {
            for name in SEGMENTATION_FILES {
                let stale = args.out.join(name);
                match std::fs::remove_file(&stale) {
                    Ok(()) => errln!(
                        "removed {}: it held another frame's segmentation",
                        stale.display()
                    ),
                    Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
                    Err(err) => {
                        return Err(e.context(format!(
                            "and {} (another frame's segmentation) could not be removed: {err}",
                            stale.display()
                        )));
                    }
                }
            }
            return Err(e);
        }
    };
    outln!(
        "region of interest: {}×{} px at ({}, {})",
        roi.width,
        roi.height,
        roi.x0,
        roi.y0
    );
    // the segmentation's two files as one set too
    write_atomic_set(
        &args.out,
        &[
            (
                SEGMENTATION_FILES[0],
                &mask_png(SEGMENTATION_FILES[0], &seg.full)?,
            ),
            (
                SEGMENTATION_FILES[1],
                &mask_png(SEGMENTATION_FILES[1], &seg.small)?,
            ),
        ],
    )?;
    outln!("segmentation: IoU {iou:.3} with the visible instrument in the region of interest");
    outln!(
        "wrote frame.png, silhouette_48.png, instrument_mask.png, occluder_mask.png and the segmentation to {}",
        args.out.display()
    );
    Ok(())
}

/// The segmentation's files, at the region's resolution and at 48×48.
const SEGMENTATION_FILES: [&str; 2] = ["segmentation_roi.png", "segmentation_48.png"];

/// Segments `frame`'s region of interest `roi`: the segmentation and its IoU
/// with the visible instrument there, or why there is none.
fn segment_frame(frame: &Frame, roi: Roi, occlusion: f64) -> Result<(Segmentation, f64)> {
    roi.check_within(frame.width, frame.height)
        .with_context(|| {
            format!(
                "the region of interest {}×{} px at ({}, {}) does not fit the {}×{} frame",
                roi.width, roi.height, roi.x0, roi.y0, frame.width, frame.height
            )
        })?;
    let truth = frame.instrument.crop(roi)?;
    if truth.count() == 0 {
        bail!(
            "segmentation: nothing to segment: no visible instrument in the region of interest \
             {}×{} px at ({}, {}) (--occlusion {} covers {} px of it)",
            roi.width,
            roi.height,
            roi.x0,
            roi.y0,
            occlusion,
            frame.occluder.crop(roi)?.count()
        );
    }
    let seg = segment(
        &frame.rgb,
        frame.width,
        frame.height,
        roi,
        &SegmentParams::default(),
    )
    .context("segmentation")?;
    let iou = seg.full.iou(&truth)?;
    Ok((seg, iou))
}

/// A 0/1 mask as a black-and-white PNG, in memory (`name` for errors).
fn mask_png(name: &str, mask: &Mask) -> Result<Vec<u8>> {
    let gray: Vec<u8> = mask.data().iter().map(|&v| v * 255).collect();
    encode_png(
        name,
        &gray,
        mask.width(),
        mask.height(),
        image::ExtendedColorType::L8,
    )
}
