//! A query allocates nothing once kiddo's per-thread scratch exists: a
//! counting allocator around 1,000 queries, after one warm-up query.
//! (Its own test binary: the allocator is global.)
#![cfg(feature = "index")]

#[path = "support/counting.rs"]
mod counting;
#[path = "support/manifold.rs"]
mod manifold;

use kflex_estimate::{FeatureIndex, IndexParams, Neighbour, ProjectionDims, Search};
use manifold::{DEFAULT_NOISE_STD, Manifold, rng};

#[global_allocator]
static GLOBAL: counting::Counting = counting::Counting;

#[test]
fn queries_allocate_nothing_after_the_first() {
    let surface = Manifold::new(256, DEFAULT_NOISE_STD, 5);
    let (features, poses) = surface.sample(2000, &mut rng(1));
    let (queries, _) = surface.sample(1000, &mut rng(2));
    for (k, search) in ProjectionDims::ALL
        .into_iter()
        .flat_map(|k| [(k, Search::Tree), (k, Search::Scan)])
    {
        let params = IndexParams {
            projection_dims: k,
            search,
        };
        let index = FeatureIndex::build(&features, 256, &poses, params).unwrap();
        let mut out = vec![Neighbour::default(); 1000];
        index.nearest(&queries[..256]).unwrap();
        let before = counting::allocations();
        let mut sum = 0;
        for q in queries.chunks_exact(256) {
            sum += index.nearest(q).unwrap().index;
            sum += index.nearest_linear(q).unwrap().index;
        }
        index.nearest_batch_into(&queries, &mut out).unwrap();
        let after = counting::allocations();
        assert_eq!(after - before, 0, "K = {}, {search:?}: {sum}", k.get());
    }
}
