//! Renders every background with the paper's four occlusion cases into one
//! contact sheet: `cargo run -p kflex-model --example gallery -- OUT.png`.
use kflex_model::Camera;
use kflex_model::Instrument;
use kflex_model::{Background, FrameParams, Occlusion, SceneRenderer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "gallery.png".into());
    let camera = Camera::default();
    let shape = Instrument::kflex().shape(30.0, 10.0)?;
    let cases = [None, Some((0.2, 0.5)), Some((0.4, 0.5)), Some((0.4, 1.0))];
    let (tw, th) = (320u32, 240u32);
    let mut sheet = image::RgbImage::new(tw * 4, th * 3);
    let mut renderer = SceneRenderer::new();
    for (row, bg) in Background::ALL.iter().enumerate() {
        for (col, case) in cases.iter().enumerate() {
            let params = FrameParams {
                background: *bg,
                seed: 7,
                occlusion: case.map(|(fraction, position)| Occlusion { fraction, position }),
                ..FrameParams::default()
            };
            let f = renderer.render(&camera, &shape, &params)?;
            for y in 0..th {
                for x in 0..tw {
                    let i = 3 * ((2 * y) * f.width + 2 * x) as usize;
                    sheet.put_pixel(
                        col as u32 * tw + x,
                        row as u32 * th + y,
                        image::Rgb([f.rgb[i], f.rgb[i + 1], f.rgb[i + 2]]),
                    );
                }
            }
        }
    }
    sheet.save(&out)?;
    println!("wrote {out}");
    Ok(())
}
