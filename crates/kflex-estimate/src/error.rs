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
