//! A contact sheet of the clinical backgrounds with the paper's four occlusion
//! cases and four poses: `cargo run --release -p kflex-model --example gallery -- OUT.png`
//! (`make gallery` writes `assets/gallery.png`).
//!
//! Two rows per background (colon, stomach, larynx; seeds 7 and 8), four
//! tiles of 213 × 160 per row (each a 3 × 3 average of a 640 × 480 frame).
//! Columns are the occlusion cases — none, 20 % middle, 40 % middle, 40 %
//! distal — and the poses (θ, d) are a Latin square over them, so each
//! background shows every occlusion and every pose: the first row
//! (30°, 10 mm), (−90°, 8 mm), (90°, 20 mm), (0°, 35 mm), the second the
//! same poses shifted by two columns: ±90° and the ends of the working
//! range's translations (`PoseRange::FULL`, 8–40 mm) among them.
use kflex_model::Camera;
use kflex_model::Instrument;
use kflex_model::{Background, FrameParams, Occlusion, SceneRenderer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "gallery.png".into());
    let camera = Camera::default();
    let poses = [(30.0, 10.0), (-90.0, 8.0), (90.0, 20.0), (0.0, 35.0)];
    let cases = [None, Some((0.2, 0.5)), Some((0.4, 0.5)), Some((0.4, 1.0))];
    // each tile a 3 × 3 box average of the 640 × 480 frame
    let (tw, th) = (213u32, 160u32);
    let mut sheet = image::RgbImage::new(tw * 4, th * 6);
    let mut renderer = SceneRenderer::new();
    for (b, bg) in Background::ALL.iter().enumerate() {
        for (half, seed) in [7u64, 8].into_iter().enumerate() {
            let row = 2 * b + half;
            for (col, case) in cases.iter().enumerate() {
                let (theta, d) = poses[(col + 2 * half) % poses.len()];
                let shape = Instrument::kflex().shape(theta, d)?;
                let params = FrameParams {
                    background: *bg,
                    seed,
                    occlusion: case.map(|(fraction, position)| Occlusion::new(fraction, position)),
                    // without sensor noise: the sheet shows the scene (and stays small as a PNG)
                    noise_std: 0.0,
                    ..FrameParams::default()
                };
                let f = renderer.render(&camera, &shape, &params)?;
                let at =
                    |x: u32, y: u32, k: usize| u16::from(f.rgb[3 * (y * f.width + x) as usize + k]);
                for y in 0..th {
                    for x in 0..tw {
                        let px = std::array::from_fn(|k| {
                            let mut s = 0;
                            for dy in 0..3 {
                                for dx in 0..3 {
                                    s += at(3 * x + dx, 3 * y + dy, k);
                                }
                            }
                            ((s + 4) / 9) as u8
                        });
                        sheet.put_pixel(col as u32 * tw + x, row as u32 * th + y, image::Rgb(px));
                    }
                }
            }
        }
    }
    sheet.save(&out)?;
    println!("wrote {out}");
    // background synthesis: a fresh renderer's first frame less a cached one
    let shape = Instrument::kflex().shape(30.0, 10.0)?;
    for (w, h) in [(640u32, 480u32), (1920, 1080)] {
        let cam = camera.with_intrinsics(kflex_model::Intrinsics::from_fov(w, h, 100.0)?);
        for bg in Background::ALL {
            let params = FrameParams {
                background: bg,
                ..FrameParams::default()
            };
            let mut r = SceneRenderer::new();
            let t0 = std::time::Instant::now();
            r.render(&cam, &shape, &params)?;
            let first = t0.elapsed();
            let t1 = std::time::Instant::now();
            r.render(&cam, &shape, &params)?;
            let cached = t1.elapsed();
            println!(
                "{bg:?} {w}x{h}: background {:.1} ms",
                (first.as_secs_f64() - cached.as_secs_f64()) * 1e3
            );
        }
    }
    Ok(())
}
