#![warn(missing_docs)]
//! File formats in, sample sets out.
//!
//! Each format module reads a measured BRDF file into a table that keeps the
//! file's own values (so writing it back is byte-identical), and turns the
//! table into a [`MeasuredSamples`]: the valid measurements with their
//! directions, in physical units (1/sr). Everything model-specific (weights,
//! interpolation stencils) is built from that set by the `npf` crate.

pub mod atomic;
pub mod detect;
pub mod error;
pub mod geometry;
pub mod merl;
mod planar;
pub mod rgl;
pub mod rgl_brdf;
pub mod rgl_warp;
pub mod samples;
pub mod sniff;
pub mod spectrum;
pub mod utia;

pub use detect::{Format, Table};
pub use error::LoadError;
pub use merl::{MerlSamples, MerlTable};
pub use rgl::TensorFile;
pub use samples::{MeasuredSample, MeasuredSamples};
pub use utia::UtiaTable;
