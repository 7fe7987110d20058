//! npf: fit measured BRDFs with the shared-factor non-parametric microfacet model.
//!
//! Data flow, one module per concept:
//! `npf_data_loaders` (formats) → [`samples`] (weights, stencils) → [`model`]
//! → [`solver`] (AWLS) → [`modelfile`] (export) / [`sampling`] (renderers).
//! [`energy`] holds the energy-compensation toolkit.

pub mod baselines;
pub mod bsdf;
pub mod charts;
pub mod cli;
pub mod energy;
pub mod evaluation;
pub mod golden;
pub mod interp;
pub mod metrics;
pub mod microfacet;
pub mod model;
pub mod modelfile;
pub mod nnls;
pub mod reconstruct;
pub mod render;
pub mod samples;
pub mod sampling;
pub mod selection;
pub mod solver;
pub mod stability;
pub mod synth;

pub use npf_data_loaders as loaders;
