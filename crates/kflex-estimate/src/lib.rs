//! # kflex-estimate — joint-angle estimation
//!
//! Image side of the paper's IBJAE: region-based segmentation of the endoscope
//! frame into the 48×48 binary image the Siamese CNN consumes ([`segment()`]).
//! The networks, the feature index and the Kalman fusion come with later issues.
#![warn(missing_docs)]

pub mod error;
pub mod segment;

pub use error::{EstimateError, Result};
pub use segment::{Roi, SegmentParams, Segmentation, Segmenter, segment};
