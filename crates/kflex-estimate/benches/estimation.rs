//! The full estimation tick from a 640×480 RGB frame and its stages (issue
//! 11: ≤ 1.5 ms median on one core, everything but the two network calls
//! ≤ 20 % of it):
//! `tools/estimation_bench.sh` (writes paper-size models with random
//! weights, Table I's SCNN and Table II's MLP, then runs this bench on
//! them). Without `KFLEX_BENCH_MODELS` it times the small test models.

use std::hint::black_box;
use std::path::PathBuf;

use criterion::{Criterion, criterion_group, criterion_main};
use kflex_estimate::{
    AdaptiveKalman, AdaptiveParams, EMBEDDING_DIM, Fusion, Ibjae, Kbjae, Lbhjae, Measurements,
    RgbView, Scnn, SegmentParams, Segmenter, build_band_database,
};
use kflex_model::{Camera, Command, FrameParams, Instrument, SceneRenderer, WorkingRegions};

fn models() -> (PathBuf, PathBuf) {
    match std::env::var_os("KFLEX_BENCH_MODELS") {
        Some(dir) => {
            let dir = PathBuf::from(dir);
            (dir.join("scnn_table1.onnx"), dir.join("kbjae_table2.onnx"))
        }
        None => {
            let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data");
            (dir.join("scnn_test.onnx"), dir.join("kbjae_test.onnx"))
        }
    }
}

fn bench(c: &mut Criterion) {
    let (scnn_path, kbjae_path) = models();
    let camera = Camera::default();
    let regions = WorkingRegions::full(&camera).expect("regions");
    let (theta, d) = (30.0, 12.0);
    let band = *regions.at(theta, d).expect("a band");
    let mut scnn = Scnn::load(&scnn_path, 1).expect("SCNN model");
    // a database over the band at 1 deg x 1 mm
    let db = build_band_database(&mut scnn, &camera, &Instrument::kflex(), &band, 1.0, 1.0)
        .expect("database");
    eprintln!(
        "database: {} silhouettes, band θ {:?} d {:?}, region {}×{} px",
        db.index.len(),
        band.poses.theta_deg,
        band.poses.translation_mm,
        band.roi.width,
        band.roi.height
    );
    let shape = Instrument::kflex().shape(theta, d).expect("shape");
    let frame = SceneRenderer::new()
        .render(&camera, &shape, &FrameParams::default())
        .expect("frame");
    let view = RgbView::packed(&frame.rgb, frame.width, frame.height).expect("view");

    // the stages one by one
    let mut segmenter = Segmenter::new(SegmentParams::default()).expect("params");
    let roi = band.roi;
    c.bench_function("stage_segment_band_region", |b| {
        b.iter(|| {
            black_box(
                segmenter
                    .segment(&frame.rgb, frame.width, frame.height, roi)
                    .expect("segment")
                    .small
                    .count(),
            )
        })
    });
    let small = segmenter
        .segment(&frame.rgb, frame.width, frame.height, roi)
        .expect("segment")
        .small
        .clone();
    let mut embedding = [0.0f32; EMBEDDING_DIM];
    c.bench_function("stage_scnn_batch1", |b| {
        b.iter(|| {
            scnn.embed(black_box(&small), &mut embedding)
                .expect("embed")
        })
    });
    scnn.embed(&small, &mut embedding).expect("embed");
    c.bench_function("stage_retrieval", |b| {
        b.iter(|| black_box(db.index.nearest(black_box(&embedding)).expect("query")))
    });
    c.bench_function("stage_retrieval_linear_scan", |b| {
        b.iter(|| {
            black_box(
                db.index
                    .nearest_linear(black_box(&embedding))
                    .expect("query"),
            )
        })
    });
    let mut kbjae = Kbjae::load(&kbjae_path).expect("KBJAE model");
    let mut t = theta;
    c.bench_function("stage_kbjae", |b| {
        b.iter(|| {
            t += 1e-3;
            black_box(kbjae.step(black_box(t), 0.01).expect("kbjae"))
        })
    });
    let mut fusion = AdaptiveKalman::new(AdaptiveParams::default()).expect("params");
    let m = Measurements {
        kbjae_deg: Some(theta),
        ibjae_deg: Some(theta + 0.5),
        ibjae_sigma_deg: Some(1.0),
        ibjae_occluded: false,
    };
    c.bench_function("stage_kalman", |b| {
        b.iter(|| black_box(fusion.step(0.01, black_box(m)).expect("fusion")))
    });

    // the whole tick
    let ibjae = Ibjae::new(scnn, SegmentParams::default(), vec![db]).expect("ibjae");
    let fusion: Box<dyn Fusion + Send> =
        Box::new(AdaptiveKalman::new(AdaptiveParams::default()).expect("params"));
    let mut lbhjae = Lbhjae::new(kbjae, ibjae, fusion);
    let command = Command {
        theta_c_deg: theta,
        translation_mm: d,
    };
    c.bench_function("full_tick_640x480", |b| {
        b.iter(|| black_box(lbhjae.step(command, 0.01, Some(&view)).expect("tick")))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
