//! The one error type of `kflex-estimate`.

use thiserror::Error;

/// What can go wrong estimating the joint angle.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EstimateError {
    /// From the testbed model (bad sizes, parameters).
    #[error(transparent)]
    Model(#[from] kflex_model::ModelError),
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
    /// An image buffer whose size does not match its dimensions.
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
    /// A region of interest outside the image, or a parameter out of range.
    #[error("{name} = {value} is out of range: must be in {range}")]
    InvalidParameter {
        /// Which.
        name: &'static str,
        /// The value.
        value: f64,
        /// Valid range, in words.
        range: String,
    },
}

/// Result alias for this crate.
pub type Result<T> = std::result::Result<T, EstimateError>;
