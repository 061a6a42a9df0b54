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

/// One branch of the Siamese CNN: embeds silhouettes for retrieval.
#[derive(Debug)]
pub struct Scnn {
    model: Pooled,
    /// The batch-1 input, reused (no allocation per embedding).
    input: Vec<f32>,
}

impl Scnn {
    /// Loads the SCNN's ONNX model (see [`SCNN_INPUT`], [`SCNN_OUTPUT`]) with
    /// `threads` intra-op threads (1 for batch-1 latency in a control loop).
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load(path: &Path, threads: usize) -> Result<Self> {
        Ok(Self {
            model: Pooled::alone(OnnxModel::load(path, SCNN_INPUT, SCNN_OUTPUT, threads)?),
            input: vec![0.0; PIXELS],
        })
    }

    /// [`Scnn::load`] through `pool`: a session of the same file and threads
    /// that the pool keeps, else a new one; it goes back to the pool when
    /// this is dropped.
    ///
    /// # Errors
    /// As [`OnnxModel::load`].
    pub fn load_pooled(path: &Path, threads: usize, pool: &Arc<ModelPool>) -> Result<Self> {
        Ok(Self {
            model: pool.load(path, SCNN_INPUT, SCNN_OUTPUT, threads)?,
            input: vec![0.0; PIXELS],
        })
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

    /// Embeds one 48×48 silhouette into `out`.
    ///
    /// # Errors
    /// [`EstimateError::Length`] for a mask that is not 48×48;
    /// [`EstimateError::Onnx`] when the model fails.
    pub fn embed(&mut self, mask: &Mask, out: &mut [f32; EMBEDDING_DIM]) -> Result<()> {
        fill(mask, &mut self.input)?;
        self.model.run(&self.input, 1, out)
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
        self.model.run(&input, masks.len(), &mut out)?;
        Ok(out)
    }
}

/// A 48×48 mask as the SCNN's input: 1.0 instrument, 0.0 background.
fn fill(mask: &Mask, out: &mut [f32]) -> Result<()> {
    if mask.width() != SCNN_SIDE || mask.height() != SCNN_SIDE {
        return Err(EstimateError::Length {
            what: "SCNN silhouette pixels (48×48)",
            expected: PIXELS,
            got: (mask.width() * mask.height()) as usize,
        });
    }
    for (o, &v) in out.iter_mut().zip(mask.data()) {
        *o = if v != 0 { 1.0 } else { 0.0 };
    }
    Ok(())
}
