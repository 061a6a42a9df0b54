//! IBJAE's Siamese CNN (the paper's Table I): a 48×48 silhouette to a
//! 256-dimensional embedding, through ONNX Runtime (cargo feature `onnx`).

use std::path::Path;
use std::sync::Arc;

use kflex_model::Mask;

use crate::error::{EstimateError, Result};
use crate::onnx::{ModelPool, OnnxModel, Pooled, TensorSpec};

/// Side of the silhouettes the SCNN takes, px.
pub const SCNN_SIDE: u32 = 48;

/// Length of the SCNN's embedding.
pub const EMBEDDING_DIM: usize = 256;

/// The SCNN's input: `[batch, 1, 48, 48]` `f32`, 1 for instrument, 0 for
/// background (the segmentation's 48×48 mask, row-major).
pub const SCNN_INPUT: TensorSpec = TensorSpec {
    name: "silhouette",
    shape: &[-1, 1, 48, 48],
};

/// The SCNN's output: `[batch, 256]`, each in `(0, 1)` (a sigmoid layer).
pub const SCNN_OUTPUT: TensorSpec = TensorSpec {
    name: "embedding",
    shape: &[-1, 256],
};

const PIXELS: usize = (SCNN_SIDE * SCNN_SIDE) as usize;

/// A 48×48 silhouette's pixels as bits, row-major, 64 a word.
pub(crate) type Bits = [u64; BITS_WORDS];
pub(crate) const BITS_WORDS: usize = PIXELS / 64;
const _: () = assert!(PIXELS.is_multiple_of(64), "whole words of bits");

/// A 48×48 mask's pixels as bits (a larger mask's first 48×48).
pub(crate) fn bits_of(mask: &Mask) -> Bits {
    let mut b = [0u64; BITS_WORDS];
    for (i, &v) in mask.data().iter().enumerate().take(64 * BITS_WORDS) {
        b[i / 64] |= u64::from(v != 0) << (i % 64);
    }
    b
}

/// How many silhouettes [`Scnn::embed`] remembers.
const RECENT: usize = 16;

/// The embeddings of the last [`RECENT`] silhouettes that [`Scnn::embed`]
/// ran the model for, by their bits, the oldest replaced first. In a
/// control loop the camera shows the same silhouette again and again while
/// the joint rests (the dead zone after each reversal: on `kflex-cli run
/// --quick` with the trial models, 3,232 of 6,500 embeddings repeat one of
/// them), and the model is a pure function of its input, so a repeat takes
/// the embedding the model gave.
#[derive(Debug)]
struct Recent {
    /// Each silhouette's bits and the model's embedding of it.
    entries: Vec<(Bits, [f32; EMBEDDING_DIM])>,
    /// The entry the next new silhouette replaces once all are taken.
    oldest: usize,
}

impl Recent {
    fn get(&self, key: &Bits) -> Option<&[f32; EMBEDDING_DIM]> {
        self.entries.iter().find(|(k, _)| k == key).map(|(_, e)| e)
    }

    fn insert(&mut self, key: Bits, embedding: &[f32; EMBEDDING_DIM]) {
        if self.entries.len() < RECENT {
            self.entries.push((key, *embedding));
        } else if let Some(entry) = self.entries.get_mut(self.oldest) {
            *entry = (key, *embedding);
            self.oldest = (self.oldest + 1) % RECENT;
        }
    }
}

/// One branch of the Siamese CNN: embeds silhouettes for retrieval.
#[derive(Debug)]
pub struct Scnn {
    model: Pooled,
    /// The batch-1 input, reused (no allocation per embedding).
    input: Vec<f32>,
    recent: Recent,
    runs: u64,
}

impl Scnn {
    /// Loads the SCNN's ONNX model (see [`SCNN_INPUT`], [`SCNN_OUTPUT`]) with
    /// `threads` intra-op threads (1 for batch-1 latency in a control loop).
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load(path: &Path, threads: usize) -> Result<Self> {
        Ok(Self::new(Pooled::alone(OnnxModel::load(
            path,
            SCNN_INPUT,
            SCNN_OUTPUT,
            threads,
        )?)))
    }

    /// [`Scnn::load`] through `pool`: a session of the same file and threads
    /// that the pool keeps, else a new one; it goes back to the pool when
    /// this is dropped.
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load_pooled(path: &Path, threads: usize, pool: &Arc<ModelPool>) -> Result<Self> {
        Ok(Self::new(pool.load(
            path,
            SCNN_INPUT,
            SCNN_OUTPUT,
            threads,
        )?))
    }

    fn new(model: Pooled) -> Self {
        Self {
            model,
            input: vec![0.0; PIXELS],
            recent: Recent {
                entries: Vec::with_capacity(RECENT),
                oldest: 0,
            },
            runs: 0,
        }
    }

    /// How many times this SCNN has run its model: each [`Scnn::embed`]
    /// whose silhouette was not among the recent ones, each
    /// [`Scnn::embed_batch`].
    #[must_use]
    pub fn model_runs(&self) -> u64 {
        self.runs
    }

    /// The model file's SHA-256 (a feature database records it).
    #[must_use]
    pub fn sha256(&self) -> &str {
        self.model.sha256()
    }

    /// The intra-op threads it was loaded with.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.model.threads()
    }

    /// Embeds one 48×48 silhouette into `out`. A silhouette equal to one of
    /// the last 16 this ran the model for takes the embedding the model gave
    /// it, without running the model again (the same values: the model is a
    /// pure function of its input); no allocation.
    ///
    /// # Errors
    /// [`EstimateError::Length`] for a mask that is not 48×48;
    /// [`EstimateError::Onnx`] when the model fails.
    pub fn embed(&mut self, mask: &Mask, out: &mut [f32; EMBEDDING_DIM]) -> Result<()> {
        check_side(mask)?;
        let key = bits_of(mask);
        if let Some(known) = self.recent.get(&key) {
            *out = *known;
            return Ok(());
        }
        fill(mask, &mut self.input)?;
        self.runs += 1;
        self.model.run(&self.input, 1, out)?;
        self.recent.insert(key, out);
        Ok(())
    }

    /// Embeds many silhouettes in one model call: `masks.len() × 256` values,
    /// one embedding after the other.
    ///
    /// # Errors
    /// As [`Scnn::embed`].
    pub fn embed_batch(&mut self, masks: &[Mask]) -> Result<Vec<f32>> {
        let mut input = vec![0.0f32; masks.len() * PIXELS];
        for (mask, chunk) in masks.iter().zip(input.chunks_exact_mut(PIXELS)) {
            fill(mask, chunk)?;
        }
        let mut out = vec![0.0f32; masks.len() * EMBEDDING_DIM];
        self.runs += 1;
        self.model.run(&input, masks.len(), &mut out)?;
        Ok(out)
    }
}

/// [`EstimateError::Length`] for a mask that is not 48×48.
fn check_side(mask: &Mask) -> Result<()> {
    if mask.width() != SCNN_SIDE || mask.height() != SCNN_SIDE {
        return Err(EstimateError::Length {
            what: "SCNN silhouette pixels (48×48)",
            expected: PIXELS,
            got: (mask.width() * mask.height()) as usize,
        });
    }
    Ok(())
}

/// A 48×48 mask as the SCNN's input: 1.0 instrument, 0.0 background.
fn fill(mask: &Mask, out: &mut [f32]) -> Result<()> {
    check_side(mask)?;
    for (o, &v) in out.iter_mut().zip(mask.data()) {
        *o = if v != 0 { 1.0 } else { 0.0 };
    }
    Ok(())
}
