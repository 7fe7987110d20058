//! The renderer-facing BSDF interface, in pbrt-v4's shape, and its
//! implementations (see docs/sampling.md).
//!
//! Every direction is a unit vector in the local shading frame (normal +z),
//! and every function takes the outgoing (view) direction `wo` first, the
//! incident (light) direction `wi` second:
//!
//! - [`Bsdf::eval`]`(wo, wi)`: the BRDF value per channel (1/sr);
//! - [`Bsdf::sample`]`(wo, uc, u)`: a wi drawn for wo, with its pdf and the
//!   Monte Carlo weight f cos theta_i / pdf; `None` when nothing is drawn or
//!   the draw leaves the upper hemisphere (the mass it had is "lost": the
//!   pdf then integrates to 1 minus that mass over the hemisphere);
//! - [`Bsdf::pdf`]`(wo, wi)`: exactly the density `sample` draws wi with.
//!
//! Implementations: the factor model with its tabulated sampler
//! ([`NpfBxdf`]), the analytic GGX + Lambert baseline
//! ([`crate::microfacet::GgxParams`]), and a measured MERL table
//! ([`npf_data_loaders::MerlTable`], cosine-weighted sampling). The
//! renderer ([`crate::render`]), the comparison ([`crate::evaluation`]) and
//! the directional [`albedo`] take any of them.

mod anisotropic;
mod azimuth;
mod batch;
mod compensated;
mod draw4;
mod draw_geometry;
mod evaluated;
mod f64x2;
mod factor;
mod flat;
mod ggx;
mod hemisphere;
mod interface;
mod lanes;
mod lobe_tables;
mod measured;
mod quadrature;
mod rgl;
mod selection;
mod utia;

pub use anisotropic::{AnisoSampler, PHI_SUB, THETA_SUB};
pub use azimuth::PHI_CELLS;
pub use batch::{Directions, SampleBatch};
pub use compensated::Compensated;
pub use evaluated::EvaluatedModel;
pub use factor::NpfBxdf;
pub use flat::{acos, FlatEval, FLAT_LOBES};
#[cfg(test)]
pub(crate) use hemisphere::test_uniforms;
pub(crate) use hemisphere::{cosine_draw, cosine_pdf_for, reflect, reflect_up, unit};
pub use hemisphere::{cosine_hemisphere, cosine_hemisphere_pdf};
pub use interface::{Bsdf, BsdfError, BsdfSample, BxdfSample, Component};
pub use lobe_tables::{COVERAGE_SHARE, NEGLIGIBLE_CELL, SUBCELLS, VIEW_NODES};
pub use measured::InterpolatedMerl;
pub use quadrature::{albedo, half_vector_quadrature, to_merl, GL4_W, GL4_X};
pub use selection::SELECTION_FLOOR;
