//! Training data for the paper's learned estimators, generated on the
//! testbed: the kinematic set D^k of KBJAE ([`KinematicDatasetConfig`]) and
//! the image-pair set D^I of IBJAE's Siamese CNN ([`ImagePairsConfig`]),
//! with the nominal silhouette database IBJAE retrieves from
//! ([`ImagePairsConfig::database`]).
//!
//! Every data set is a pure function of its configuration and its seed:
//! each item draws from its own random stream (the seed, a tag per kind of
//! draw, and the item's index), so the result does not depend on the number
//! of threads that made it, nor on their order. Each comes with a
//! [`DatasetCard`]: the seed, the arrays' shapes, their ranges, the
//! generator's version, kflex's version and the configuration itself.

mod image;
mod kinematic;

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::{ControlError, Result};

pub use image::{ImageDatabase, ImagePairs, ImagePairsConfig};
pub use kinematic::{KinematicDataset, KinematicDatasetConfig, KinematicSet, KinematicSetSpec};

/// What a data set file holds and how it was made: written beside each file
/// (`NAME.card.json` for `NAME.npz`) so that the data can be made again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetCard<P> {
    /// Which data set: `"kinematic"`, `"image_pairs"` or `"image_database"`.
    pub kind: String,
    /// The function that made it.
    pub generator: String,
    /// Version of that generator: raised whenever the same configuration
    /// and seed would give different data.
    pub generator_version: u32,
    /// Version of the kflex crates that made it.
    pub kflex_version: String,
    /// The seed every draw derives from.
    pub seed: u64,
    /// Shape of each array, by name.
    pub sizes: BTreeMap<String, Vec<usize>>,
    /// `[min, max]` of each numeric array, by name (units in the names).
    pub ranges: BTreeMap<String, [f64; 2]>,
    /// Counts that describe the content (e.g. positives, hard negatives,
    /// segmentation failures redrawn).
    pub stats: BTreeMap<String, f64>,
    /// The exact configuration (its serde form).
    pub params: P,
}

impl<P> DatasetCard<P> {
    fn new(kind: &str, generator: &str, generator_version: u32, seed: u64, params: P) -> Self {
        Self {
            kind: kind.to_owned(),
            generator: generator.to_owned(),
            generator_version,
            kflex_version: env!("CARGO_PKG_VERSION").to_owned(),
            seed,
            sizes: BTreeMap::new(),
            ranges: BTreeMap::new(),
            stats: BTreeMap::new(),
            params,
        }
    }

    /// Records `values`' range under `name` (nothing for an empty series).
    fn range(&mut self, name: &str, values: impl IntoIterator<Item = f64>) {
        let (lo, hi) = values
            .into_iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        if lo <= hi {
            self.ranges.insert(name.to_owned(), [lo, hi]);
        }
    }
}

/// The random stream of item `index` for draws of kind `tag`: independent
/// of every other (seed, tag, index).
pub(crate) fn stream(seed: u64, tag: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ tag);
    rng.set_stream(index);
    rng
}

/// The most worker threads a data set is made on, whatever is asked.
pub const MAX_THREADS: usize = 256;

/// The worker threads to use: `threads`, or every core for 0; at most one a
/// job and [`MAX_THREADS`].
fn thread_count(threads: usize, jobs: usize) -> usize {
    let all = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    let wanted = if threads == 0 { all } else { threads };
    wanted.clamp(1, jobs.clamp(1, MAX_THREADS))
}

/// `job(i, state)` for every `i` in `0..jobs`, over `threads` worker
/// threads (0: every core), each with its own `state` from `init`; the
/// results in job order. Jobs are handed out one at a time, so the result
/// is the same whatever the thread count as long as each job depends on its
/// index only.
///
/// # Errors
/// The first error (in job order) of the jobs that ran: after an error the
/// workers take no new jobs. [`ControlError::Worker`] when a worker panicked.
pub(crate) fn parallel<S, T, I, F>(jobs: usize, threads: usize, init: I, job: F) -> Result<Vec<T>>
where
    T: Send,
    I: Fn() -> Result<S> + Sync,
    F: Fn(usize, &mut S) -> Result<T> + Sync,
{
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let work = || -> Vec<(usize, Result<T>)> {
        let mut done = Vec::new();
        let mut state = match init() {
            Ok(s) => s,
            Err(e) => {
                failed.store(true, Ordering::Relaxed);
                return vec![(0, Err(e))];
            }
        };
        while !failed.load(Ordering::Relaxed) {
            let i = next.fetch_add(1, Ordering::Relaxed);
            if i >= jobs {
                break;
            }
            let out = job(i, &mut state);
            if out.is_err() {
                failed.store(true, Ordering::Relaxed);
            }
            done.push((i, out));
        }
        done
    };
    let workers = thread_count(threads, jobs);
    let mut all: Vec<(usize, Result<T>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers).map(|_| scope.spawn(work)).collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    vec![(
                        0,
                        Err(ControlError::Worker {
                            message: "a data-generation worker panicked".to_owned(),
                        }),
                    )]
                })
            })
            .collect::<Vec<_>>()
            .into_iter()
            .flatten()
            .collect()
    });
    all.sort_by_key(|(i, _)| *i);
    let mut out = Vec::with_capacity(jobs);
    for (_, r) in all {
        out.push(r?); // in job order: the first error is the lowest job's
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn parallel_results_are_in_job_order_whatever_the_threads() {
        let job = |i: usize, _: &mut ()| -> Result<u64> { Ok(stream(7, 1, i as u64).random()) };
        let one = parallel(50, 1, || Ok(()), job).unwrap();
        let three = parallel(50, 3, || Ok(()), job).unwrap();
        assert_eq!(one, three);
        assert_eq!(one.len(), 50);
        // distinct streams
        assert_ne!(one[0], one[1]);
    }

    #[test]
    fn parallel_reports_the_first_failing_job() {
        let job = |i: usize, _: &mut ()| -> Result<usize> {
            if i >= 5 {
                Err(ControlError::NotEnoughData {
                    metric: "test",
                    needed: "i < 5",
                    got: i,
                })
            } else {
                Ok(i)
            }
        };
        let err = parallel(40, 1, || Ok(()), job).unwrap_err();
        assert!(matches!(err, ControlError::NotEnoughData { got: 5, .. }));
    }
}
