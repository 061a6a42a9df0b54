//! A query allocates nothing once kiddo's per-thread scratch exists: a
//! counting allocator around 1,000 queries, after one warm-up query.
//! (Its own test binary: the allocator is global.)
#![cfg(feature = "index")]

#[path = "support/manifold.rs"]
mod manifold;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use kflex_estimate::{FeatureIndex, IndexParams, Neighbour, ProjectionDims};
use manifold::{DEFAULT_NOISE_STD, Manifold, rng};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting calls.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn queries_allocate_nothing_after_the_first() {
    let surface = Manifold::new(256, DEFAULT_NOISE_STD, 5);
    let (features, poses) = surface.sample(3000, &mut rng(1));
    let (queries, _) = surface.sample(1000, &mut rng(2));
    for k in ProjectionDims::ALL {
        let index = FeatureIndex::build(&features, 256, &poses, IndexParams { projection_dims: k })
            .unwrap();
        let mut out = vec![Neighbour::default(); 1000];
        index.nearest(&queries[..256]).unwrap();
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        let mut sum = 0;
        for q in queries.chunks_exact(256) {
            sum += index.nearest(q).unwrap().index;
            sum += index.nearest_linear(q).unwrap().index;
        }
        index.nearest_batch_into(&queries, &mut out).unwrap();
        let after = ALLOCATIONS.load(Ordering::Relaxed);
        assert_eq!(after - before, 0, "K = {}: {sum}", k.get());
    }
}
