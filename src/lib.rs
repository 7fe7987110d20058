#![warn(missing_docs)]
// `!(x > 0.0)` is how this crate refuses NaN together with a range (a
// NaN compares false): the negation is the point, not an oversight.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Per-channel and per-lobe loops index several parallel arrays with one
// index (channel c of value, weight and residual): the index says which.
#![allow(clippy::needless_range_loop)]
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
//! and PNG output. `docs/architecture.md` draws the data flow and says which
//! module holds each concept.
//!
//! # A tour in five steps
//!
//! Load a model and evaluate it (`wo` towards the viewer first, `wi`
//! towards the light, local frame with the normal on +z; values in 1/sr):
//!
//! ```
//! use npf::loaders::geometry::spherical;
//! use std::path::Path;
//!
//! let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/ggx-lambert.json");
//! let model = npf::modelfile::read(&path)?.model;
//! assert_eq!(model.param_count(), 822);
//! let (wo, wi) = (spherical(0.5, 0.0), spherical(0.5, std::f64::consts::PI));
//! let rgb = model.eval(wo, wi);
//! assert!(rgb.iter().all(|v| v.is_finite() && *v > 0.0));
//! // Below the horizon a BRDF is zero.
//! assert_eq!(model.eval(wo, [0.0, 0.6, -0.8]), [0.0; 3]);
//! # Ok::<(), npf::Error>(())
//! ```
//!
//! Importance-sample it through the [`bsdf::Bsdf`] interface; every draw
//! carries the exact density [`bsdf::Bsdf::pdf`] gives for its direction:
//!
//! ```
//! use npf::bsdf::{Bsdf, NpfBxdf};
//! use npf::loaders::geometry::spherical;
//! use std::path::Path;
//!
//! let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/ggx-lambert.npfb");
//! let bsdf = NpfBxdf::new(npf::modelfile::read(&path)?.model)?;
//! let wo = spherical(0.6, 0.3);
//! let s = Bsdf::sample(&bsdf, wo, 0.4, [0.25, 0.75]).expect("a draw above the surface");
//! let pdf = Bsdf::pdf(&bsdf, wo, s.wi);
//! assert!((s.pdf - pdf).abs() <= 1e-9 * pdf);
//! // The weight is f cos(theta_i) / pdf.
//! let f = Bsdf::eval(&bsdf, wo, s.wi);
//! assert!((s.weight[0] - f[0] * s.wi[2] / pdf).abs() <= 1e-9 * s.weight[0]);
//! # Ok::<(), npf::Error>(())
//! ```
//!
//! Fit a table: here a MERL table npf makes from a model with known factors
//! (a thinned copy keeps the example fast). The objective never rises:
//!
//! ```
//! use npf::fit::{fit_model, FitConfig};
//! use npf::model::Layout;
//!
//! let truth = npf::synth::known_factor_model(Layout::isotropic(90), &[0.2]);
//! let table = npf::reconstruct::to_merl(&truth);
//! let mut samples = table.samples("known factors");
//! samples.samples = samples.samples.into_iter().step_by(20).collect();
//! let config = FitConfig { lobes: 1, max_sweeps: 4, ..FitConfig::default() };
//! let (fit, _) = fit_model(&samples, &config, &mut |_, _| {})?;
//! let history: Vec<f64> = fit.history.iter().map(|r| r.objective).collect();
//! assert!(history.windows(2).all(|w| w[1] <= w[0]));
//! assert!(fit.objective < 1e-2 * fit.initial_objective);
//! # Ok::<(), npf::Error>(())
//! ```
//!
//! Write a model file and read it back: the file stores the parameters as
//! float32, exactly as the model holds them, so the round trip is exact:
//!
//! ```
//! use npf::model::Layout;
//! use npf::modelfile::{read, write, ModelFile};
//!
//! let model = npf::synth::known_factor_model(Layout::isotropic(45), &[0.1, 0.3]);
//! let dir = std::env::temp_dir().join(format!("npf-doctest-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! for name in ["m.json", "m.npfb"] {
//!     let path = dir.join(name);
//!     write(&path, &ModelFile { model: model.clone(), fit: None }, true)?;
//!     assert_eq!(read(&path)?.model, model);
//! }
//! std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Reconstruct a MERL table from a model: each cell holds the model's value
//! at the cell's node (MERL's half/difference parameterisation):
//!
//! ```
//! use npf::loaders::{geometry::Angles, MerlTable};
//! use npf::model::Layout;
//!
//! let model = npf::synth::known_factor_model(Layout::isotropic(90), &[0.15]);
//! let table = npf::reconstruct::to_merl(&model);
//! let (th, td, pd) = MerlTable::node_angles(20, 30, 45);
//! let a = Angles::from_half_diff(th, 0.0, td, pd);
//! let stored = table.lookup(th, td, pd).expect("a cell above the horizon");
//! let value = model.eval_angles(&a);
//! for c in 0..3 {
//!     // MERL stores values scaled per channel in float64: equal to rounding.
//!     assert!((stored[c] - value[c]).abs() <= 1e-6 * value[c]);
//! }
//! ```
//!
//! The layouts of both models are values: 822 parameters for three
//! isotropic lobes, 2010 for three anisotropic ones (D and G on 6 x 48
//! (theta, phi) grids):
//!
//! ```
//! use npf::model::Layout;
//! assert_eq!(Layout::isotropic(90).param_count(3), 822);
//! assert_eq!(Layout::anisotropic().param_count(3), 2010);
//! ```

pub mod auto;
pub mod baselines;
pub mod bsdf;
#[cfg(feature = "cli")]
pub mod cli;
pub mod coarse;
pub mod energy;
pub mod error;
pub mod evaluation;
pub mod export;
pub mod fit;
pub mod golden;
pub mod grid;
pub mod judge;
pub mod memory;
pub mod metrics;
pub mod microfacet;
pub mod model;
pub mod modelfile;
pub mod nnls;
pub mod phases;
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
