//! Shader and C exports of a fitted model: the exact model as source code
//! a renderer compiles (docs/shader_export.md).
//!
//! - [`brdf_explorer`]: a Disney BRDF Explorer `analytic` `.brdf` file
//!   (`vec3 BRDF(L, V, N, X, Y)`, per-lobe switches and an exposure);
//! - [`glsl`]: standalone GLSL functions `eval`, `pdf` and `sample`;
//! - [`c_header`]: a dependency-free C99 header with the same three
//!   functions (`static inline`, tables `static const`).
//!
//! All three are written by one generator ([`emit`]): the model's own
//! tables, stored as f32 exactly as the model holds them, and the
//! interpolation of [`Model::eval`] (sqrt-angle D axis, uniform F axis,
//! Catmull-Rom G with pbrt's end conditions, the periodic phi axis of an
//! anisotropic layout, the node snap, the >= 0 clamp), spelled in the
//! common subset of GLSL and C. The C header computes in double and
//! matches `Model::eval` to rounding; GLSL computes in float.
//!
//! The exported sampler ([`sampler`]) is the mixture npf documents for its
//! own ([`crate::bsdf::NpfBxdf`]): cosine-weighted diffuse plus, per lobe,
//! half vectors from a piecewise-constant table in sin^2 theta_h
//! proportional to D, with view-dependent component probabilities from
//! each component's directional albedo; its pdf is the exact mixture pdf.

mod brdf_explorer;
mod c_header;
mod emit;
mod glsl;
mod prepare;
mod sampler;

pub use brdf_explorer::brdf_explorer_with;
pub use c_header::c_header_with;
pub use glsl::{glsl_eval_with, glsl_with};
pub use prepare::{ShaderError, ShaderOptions};
pub use sampler::SamplerTables;

use crate::model::Model;

/// The model as a BRDF Explorer analytic `.brdf` file (default options).
pub fn brdf_explorer(model: &Model) -> Result<String, ShaderError> {
    brdf_explorer_with(model, &ShaderOptions::default())
}

/// The model as standalone GLSL functions (default options).
pub fn glsl(model: &Model) -> Result<String, ShaderError> {
    glsl_with(model, &ShaderOptions::default())
}

/// The model as a C99 header (default options).
pub fn c_header(model: &Model) -> Result<String, ShaderError> {
    c_header_with(model, &ShaderOptions::default())
}
