//! npf: fit measured BRDFs with the shared-factor non-parametric microfacet model.
//!
//! Data flow, one module per concept:
//! `npf_data_loaders` (formats) → [`samples`] (weights, stencils) → [`model`]
//! → [`solver`] (AWLS) → [`modelfile`] (export) / [`sampling`] (renderers).
//! [`fit`] is the front door (one [`fit::FitConfig`], every model kind);
//! [`Error`] gathers the library's typed errors. [`energy`] holds the
//! energy-compensation toolkit.
//!
//! Built with `--no-default-features` this is the library alone; the default
//! `cli` feature adds the `npf` program (`cli`), its progress bars, charts
//! and PNG output.

pub mod baselines;
pub mod bsdf;
#[cfg(feature = "cli")]
pub mod cli;
pub mod energy;
pub mod error;
pub mod evaluation;
pub mod fit;
pub mod golden;
pub mod grid;
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
pub mod synth_aniso;

pub use error::{Error, Result};
pub use npf_data_loaders as loaders;
