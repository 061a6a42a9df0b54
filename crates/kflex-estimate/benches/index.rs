//! Feature-index query time, batch 1, on one core: the exact index against
//! the linear scan at N = 1k, 6k, 10k and 100k synthetic 256-d embeddings
//! (`tests/support/manifold.rs`). `cargo bench -p kflex-estimate --features index --bench index`
//! For scipy's cKDTree and faiss's IndexFlatL2 on the same data: `tools/index_bench.py`.

#[path = "../tests/support/manifold.rs"]
mod manifold;

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use kflex_estimate::{FeatureIndex, IndexParams};
use manifold::{DEFAULT_NOISE_STD, Manifold, rng};

const D: usize = 256;

fn bench(c: &mut Criterion) {
    let surface = Manifold::new(D, DEFAULT_NOISE_STD, 7);
    let mut group = c.benchmark_group("index_query");
    for n in [1_000, 6_000, 10_000, 100_000] {
        let mut r = rng(1);
        let (features, poses) = surface.sample(n, &mut r);
        let (queries, _) = surface.sample(256, &mut r);
        let index =
            FeatureIndex::build(&features, D, &poses, IndexParams::default()).expect("index");
        let rows: Vec<&[f32]> = queries.chunks_exact(D).collect();
        let mut i = 0;
        group.bench_with_input(BenchmarkId::new("exact_index", n), &n, |b, _| {
            b.iter(|| {
                i = (i + 1) % rows.len();
                black_box(index.nearest(black_box(rows[i])).expect("query").index)
            })
        });
        group.bench_with_input(BenchmarkId::new("linear_scan", n), &n, |b, _| {
            b.iter(|| {
                i = (i + 1) % rows.len();
                black_box(
                    index
                        .nearest_linear(black_box(rows[i]))
                        .expect("query")
                        .index,
                )
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
