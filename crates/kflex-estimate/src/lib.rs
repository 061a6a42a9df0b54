//! # kflex-estimate — joint-angle estimation
//!
//! What a controller embeds to know where the joint is. Today: the image side
//! of the paper's IBJAE, the region-based segmentation of an endoscope frame
//! into the 48×48 binary image the Siamese CNN consumes ([`Segmenter`], and
//! the one-off [`segment()`]). KBJAE, IBJAE's retrieval and the Kalman fusion
//! (LBHJAE) come with the estimation issue, ONNX Runtime and the k-d index
//! behind cargo features of their own.
//!
//! This crate depends on `kflex-model` without its default features: it uses
//! only the shared types ([`kflex_model::Mask`], [`kflex_model::Roi`], the
//! range check), so it compiles none of the simulator's heavy dependencies
//! (rapier3d, parry3d, image).
//!
//! How the segmentation holds up under gain, noise, blur, tint, specular light
//! and tissue colours: `SEGMENTATION.md` beside this crate's `Cargo.toml`.
//!
//! ## Feature index (cargo feature `index`, off by default)
//!
//! [`FeatureIndex`] (module [`index`]) is IBJAE's database: SCNN embeddings
//! (f32, 256-d, any dimension works) labelled with the [`Pose`] (θ deg, d mm)
//! they were rendered at. [`FeatureIndex::nearest`] returns the exact nearest
//! neighbour (squared L2 distance, lowest index among ties), through a kiddo
//! k-d tree over the features' leading principal axes and a pruning bound
//! kept safe against f32 rounding: the same answer as
//! [`FeatureIndex::nearest_linear`], 24–30× faster at 6,000–10,000 points,
//! allocating nothing per query. [`FeatureIndex::save`] and
//! [`FeatureIndex::load`] write and read the versioned, checksummed database
//! file (with free-form metadata: the model's SHA-256, camera and grid); a
//! missing, truncated, corrupt or other-version file is a typed error. The
//! feature pulls in `kiddo` (without its threads) and `nalgebra` (which
//! `kflex-model` already uses).
#![warn(missing_docs)]

mod error;
#[cfg(feature = "index")]
pub mod index;
mod segment;

pub use error::{EstimateError, Result};
#[cfg(feature = "index")]
pub use index::{FeatureIndex, IndexParams, Neighbour, Pose, ProjectionDims, SearchStats};
/// The shared types this crate's API takes and returns.
pub use kflex_model::{Bounds, Mask, RangeError, Roi};
pub use segment::{SegmentParams, Segmentation, Segmenter, segment};
