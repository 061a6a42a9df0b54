//! The one error type of `kflex-estimate`.

use std::path::PathBuf;

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
    /// A model card, or a feature database's metadata, that cannot be
    /// understood (a file that cannot be read is [`EstimateError::Io`]).
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
    /// A buffer (feature vectors, poses, a query, an output slice) whose
    /// length does not fit the shape it is given with.
    #[error("{what}: expected {expected} values, got {got}")]
    Length {
        /// Which buffer, and the shape it must have.
        what: &'static str,
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A feature vector, a query or a pose holds NaN or an infinity.
    #[error("{what} {index} is not finite: component {component} is {value}")]
    NonFinite {
        /// Which input (`"feature vector"`, `"query"`, `"pose"`).
        what: &'static str,
        /// Which vector (its row), counted from 0.
        index: usize,
        /// Which component of it, counted from 0.
        component: usize,
        /// The value found.
        value: f64,
    },
    /// A feature index with no points: there is no nearest neighbour to return.
    #[error("the feature index is empty: at least one feature vector is needed")]
    EmptyIndex,
    /// IBJAE given no band database to read frames against.
    #[error(
        "IBJAE needs at least one band database, got none (`kflex-cli build-db` makes \
         them; a model directory keeps them in db/)"
    )]
    NoBandDatabase,
    /// A frame at a translation that lies within the span of IBJAE's
    /// databases but in no band of theirs (databases chosen with a gap).
    #[error(
        "translation_mm = {} lies in no band of IBJAE's databases (they hold the \
         translations {held} mm): give the databases of that translation",
        kflex_model::Num(*.translation_mm)
    )]
    NoBand {
        /// The translation asked for, mm.
        translation_mm: f64,
        /// The translations the databases hold, as text.
        held: String,
    },
    /// Reading or writing a file failed (missing, no permission, disk full).
    /// `kind` tells a missing file ([`std::io::ErrorKind::NotFound`]) from the rest.
    #[error("{}: {message}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What kind of failure, as the operating system reported it.
        kind: std::io::ErrorKind,
        /// The operating system's message.
        message: String,
    },
    /// A feature-index file that is not one, or is damaged: wrong magic bytes,
    /// truncated, a checksum that does not match, values out of place.
    #[error("{}: not a valid kflex feature-index file: {reason}", .path.display())]
    IndexCorrupt {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A feature-index file written in a format version this build cannot read.
    #[error(
        "{}: feature-index file format version {found}; this build reads version {supported} (rebuild the database)",
        .path.display()
    )]
    IndexVersion {
        /// The file.
        path: PathBuf,
        /// The version the file declares.
        found: u32,
        /// The version this build reads.
        supported: u32,
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

impl EstimateError {
    /// An [`EstimateError::Io`] for `path` from `err`.
    #[cfg(any(feature = "index", feature = "onnx"))]
    pub(crate) fn io(path: &std::path::Path, err: &std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            kind: err.kind(),
            message: err.to_string(),
        }
    }
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, EstimateError>;
