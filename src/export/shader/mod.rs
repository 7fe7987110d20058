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
mod sampler;

pub use brdf_explorer::brdf_explorer_with;
pub use c_header::c_header_with;
pub use glsl::{glsl_eval_with, glsl_with};
pub use sampler::SamplerTables;

use crate::model::{Model, ModelError};

/// Why a model could not be exported as source code.
#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    /// The model failed its validation (sizes, finite, non-negative).
    #[error("cannot export an invalid model: {0}")]
    InvalidModel(#[from] ModelError),
    /// The identifier prefix is not a valid GLSL/C identifier.
    #[error("bad shader prefix {0:?}: use 1 to 32 ASCII letters, digits or '_', starting with a letter, no \"__\" and not \"gl_\"")]
    BadPrefix(String),
    /// The model's diffuse form has no shader code yet.
    #[error("the shader exports support the Lambertian and separable diffuse forms only, this model's is {0} (refit with --diffuse lambert or separable, or export .bsdf, which tabulates Model::eval)")]
    DiffuseForm(&'static str),
    /// A model option the generated code does not express.
    #[error("the shader exports support separable masking without compensation only, this model has {0} (refit without --masking/--compensate, or export .bsdf, which tabulates Model::eval)")]
    Unsupported(&'static str),
}

/// Options shared by the three exports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShaderOptions {
    /// Prefix of every generated identifier (`npf` gives `npf_eval`, ...),
    /// so several materials can live in one program.
    pub prefix: String,
}

impl Default for ShaderOptions {
    fn default() -> Self {
        ShaderOptions {
            prefix: "npf".into(),
        }
    }
}

impl ShaderOptions {
    fn validate(&self) -> Result<(), ShaderError> {
        let p = &self.prefix;
        let ok = (1..=32).contains(&p.len())
            && p.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
            && p.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && !p.contains("__")
            && !p.ends_with('_')
            && !p.starts_with("gl_");
        if ok {
            Ok(())
        } else {
            Err(ShaderError::BadPrefix(p.clone()))
        }
    }
}

/// Checks the model and options, then builds the sampler tables every
/// export shares.
fn prepare(model: &Model, options: &ShaderOptions) -> Result<SamplerTables, ShaderError> {
    options.validate()?;
    model.validate()?;
    if !model.diffuse_form.is_lambert() && emit::separable_p(model).is_none() {
        return Err(ShaderError::DiffuseForm(model.diffuse_form.name()));
    }
    if !model.masking.is_separable() {
        return Err(ShaderError::Unsupported("height-correlated masking"));
    }
    if model.compensation.is_some() {
        return Err(ShaderError::Unsupported(
            "a multiple-scattering compensation term",
        ));
    }
    Ok(SamplerTables::new(model))
}

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
