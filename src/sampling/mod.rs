//! Importance sampling of fitted models for renderers (see docs/sampling.md).
//!
//! [`NpfBxdf`] wraps a [`Model`](crate::model::Model) with tables built once:
//! per specular lobe a piecewise-constant distribution of the half vector in
//! `t = sin^2 theta_h` proportional to `D^m(theta_h)` (so the half-vector
//! density per solid angle is proportional to `D^m cos theta_h`), and the
//! lobe-selection probabilities at 16 view angles. It offers pbrt-style
//! `eval`, `sample` and `pdf` in the local shading frame (normal +z).

mod bxdf;
mod dist;

pub use bxdf::{
    BxdfSample, Component, NpfBxdf, GL4_W, GL4_X, SELECTION_FLOOR, SUBCELLS, VIEW_NODES,
};
pub use dist::PiecewiseConstant;
