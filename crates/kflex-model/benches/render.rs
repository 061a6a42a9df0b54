//! Silhouette throughput. `cargo bench -p kflex-model --bench render`
//! Goal (camera v2): ≥ 30,000 48×48 silhouettes per second on one core.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use kflex_model::Camera;
use kflex_model::Instrument;
use kflex_model::{Mask, Rasterizer, Roi};

fn silhouettes(c: &mut Criterion) {
    let instrument = Instrument::kflex();
    let camera = Camera::default();
    // a 48×48 region of interest around the working range, as IBJAE uses
    let working = Roi::paper(&camera).expect("working region");
    let roi = camera.with_intrinsics(working.intrinsics(&camera.intrinsics, 48, 48).expect("roi"));
    let mut shape = instrument.shape(0.0, 10.0).expect("shape");
    let mut raster = Rasterizer::new();
    let mut mask = Mask::new(48, 48).expect("mask");
    let mut theta = 0.0;
    c.bench_function("silhouette_48x48", |b| {
        b.iter(|| {
            theta = (theta + 0.37) % 50.0;
            instrument
                .shape_into(theta, 10.0, &mut shape)
                .expect("shape");
            mask.clear();
            raster.silhouette(&roi, &shape, &mut mask).expect("render");
            black_box(mask.count())
        })
    });
    let mut full = Mask::new(640, 480).expect("mask");
    c.bench_function("silhouette_640x480", |b| {
        b.iter(|| {
            theta = (theta + 0.37) % 50.0;
            instrument
                .shape_into(theta, 10.0, &mut shape)
                .expect("shape");
            full.clear();
            raster
                .silhouette(&camera, &shape, &mut full)
                .expect("render");
            black_box(full.count())
        })
    });
}

criterion_group!(benches, silhouettes);
criterion_main!(benches);
