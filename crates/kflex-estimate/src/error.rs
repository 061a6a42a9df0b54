//! The one error type of `kflex-estimate`.

use kflex_model::{ModelError, RangeError};
use thiserror::Error;

/// What can go wrong estimating the joint angle.
///
/// Out-of-range values arrive as [`RangeError`] (the quantity's name, the
/// value and its numeric bounds), directly or through [`ModelError`].
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum EstimateError {
    /// From the testbed model's shared types (image sizes, regions, parameters).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A parameter of this crate is outside its range.
    #[error(transparent)]
    OutOfRange(#[from] RangeError),
    /// The segmentation found no instrument (or too little of it to use).
    #[error(
        "no instrument found: {pixels} instrument pixels in the region of interest, at least {min} needed"
    )]
    NoInstrument {
        /// Instrument pixels found.
        pixels: usize,
        /// The least that counts as an instrument.
        min: usize,
    },
    /// An RGB buffer whose length does not match its dimensions.
    #[error("image buffer of {got} bytes does not match {width}×{height} RGB ({expected} bytes)")]
    ImageSize {
        /// Width, px.
        width: u32,
        /// Height, px.
        height: u32,
        /// Bytes expected.
        expected: usize,
        /// Bytes given.
        got: usize,
    },
    /// The ONNX Runtime library was found nowhere kflex looks.
    #[error(
        "ONNX Runtime library not found (looked at: {searched}); install the pinned wheel with `make venv` (or `pip install onnxruntime==1.31.1` into the active Python), or set ORT_DYLIB_PATH to its libonnxruntime.so.1.31.1"
    )]
    OnnxRuntimeMissing {
        /// Every place looked at, in order.
        searched: String,
    },
    /// ONNX Runtime failed on a model (loading, or running it).
    #[error("ONNX Runtime, {path}: {message}")]
    Onnx {
        /// The model file (or the runtime library).
        path: String,
        /// What ONNX Runtime said.
        message: String,
    },
    /// A model or model-card file that cannot be read or understood.
    #[error("{path}: {message}")]
    ModelFile {
        /// The file.
        path: String,
        /// What is wrong with it.
        message: String,
    },
    /// A model whose file is not the one its model card records.
    #[error("{path}: SHA-256 {file} does not match its model card's {card}")]
    ModelChecksum {
        /// The model file.
        path: String,
        /// The SHA-256 its card records.
        card: String,
        /// The SHA-256 of the file.
        file: String,
    },
    /// A model whose input or output is not what the estimator expects.
    #[error("{path}: {which} is {found}, expected {expected}")]
    ModelMismatch {
        /// The model file.
        path: String,
        /// `input` or `output`.
        which: &'static str,
        /// What the estimator expects (name, element type, shape; -1 dynamic).
        expected: String,
        /// What the model has.
        found: String,
    },
    /// A buffer whose length does not fit the batch.
    #[error("{what}: {got} values given, {expected} expected")]
    BufferSize {
        /// Which buffer.
        what: &'static str,
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
}

impl EstimateError {
    /// The range error behind this error (out of range or out of the
    /// workspace), whichever crate raised it.
    #[must_use]
    pub fn range(&self) -> Option<&RangeError> {
        match self {
            Self::OutOfRange(e) => Some(e),
            Self::Model(e) => e.range(),
            _ => None,
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, EstimateError>;
