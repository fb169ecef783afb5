//! 3D face recognition with Fisherfaces on range images (paper sections 3–4), used to measure
//! what gallery augmentation by expression synthesis buys.
//!
//! * [`range_image`] — resample a face on a fixed grid centred on the nose tip (Z only),
//!   elliptic mask, hole filling.
//! * [`fisherfaces`] — PCA to M − c, LDA to c − 1 (eqs. 1–9); Eigenfaces fallback; distances.
//! * [`expression_weights`] — weights of the range-image samples from the synthetic
//!   expressions' spread (ours: the regions expressions move count less).
//! * [`cmc`] — Cumulative Match Characteristic, rank-1/rank-5, per probe kind.
//! * [`pose`] — pose normalisation: the registration's rigid fit to detected feature points,
//!   a 6-DOF surface refinement, and the older landmark-free rotation about the nose tip aligning the
//!   upper face to a reference range image (ICP along z).
//! * [`plot`] — CMC curves as PNG (plotters, bitmap backend).
//! * [`protocol`] — the GavabDB protocol behind `facesynth evaluate`.

pub mod cmc;
pub mod dataset;
pub mod expression_weights;
pub mod fisherfaces;
pub mod plot;
pub mod pose;
pub mod protocol;
pub mod range_image;
pub mod sample;

pub use expression_weights::ExpressionWeightParams;
pub use fisherfaces::{FisherModel, FisherParams, Method, Metric};
pub use protocol::{Evaluation, PoseSource, ProtocolParams, Report, evaluate};
pub use range_image::{RangeImage, RangeImageParams, range_image};
