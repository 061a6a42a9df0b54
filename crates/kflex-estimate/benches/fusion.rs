//! One fusion tick, and (feature `onnx`) one KBJAE tick on the test model:
//! `cargo bench -p kflex-estimate --features onnx --bench fusion`.
//! The full estimation tick's goal (issue 11) is 1.5 ms with everything but
//! the two network calls within 20 % of it.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, Fusion, KalmanParams, Measurements, PaperKalman,
};

fn bench(c: &mut Criterion) {
    let m = Measurements {
        kbjae_deg: Some(20.0),
        ibjae_deg: Some(21.0),
        ibjae_sigma_deg: None,
        ibjae_occluded: false,
    };
    let mut paper = PaperKalman::new(KalmanParams::default()).expect("params");
    c.bench_function("fusion_paper_tick", |b| {
        b.iter(|| black_box(paper.step(0.01, black_box(m)).expect("step")))
    });
    let mut adaptive = AdaptiveKalman::new(AdaptiveParams::default()).expect("params");
    c.bench_function("fusion_adaptive_tick", |b| {
        b.iter(|| black_box(adaptive.step(0.01, black_box(m)).expect("step")))
    });
    #[cfg(feature = "onnx")]
    {
        let model =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kbjae_test.onnx");
        let mut kbjae = kflex_estimate::Kbjae::load(&model).expect("the test model");
        let mut theta = 0.0;
        c.bench_function("kbjae_tick_test_model", |b| {
            b.iter(|| {
                theta += 0.01;
                black_box(kbjae.step(black_box(theta), 0.01).expect("step"))
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
