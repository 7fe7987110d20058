//! Sampling utilities, apart from any model (as pbrt keeps them): the
//! piecewise-constant 1-D distribution the factor model's sampler tabulates
//! its half vectors with, and the 2-D one of the anisotropic sampler. The sampler itself is [`crate::bsdf::NpfBxdf`]
//! (re-exported here with its types, where it used to live).

mod dist;
mod dist2d;

pub use crate::bsdf::{
    BsdfSample, BxdfSample, Component, NpfBxdf, GL4_W, GL4_X, SELECTION_FLOOR, SUBCELLS, VIEW_NODES,
};
pub use dist::PiecewiseConstant;
pub use dist2d::PiecewiseConstant2D;
