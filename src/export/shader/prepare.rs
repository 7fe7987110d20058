//! What a shader export is asked for, and the checks every export makes
//! before any code is written.

use super::sampler::{separable_p, SamplerTables};
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

impl Default for ShaderOptions {
    fn default() -> Self {
        ShaderOptions {
            prefix: "npf".into(),
        }
    }
}

/// Checks the model and options, then builds the sampler tables every
/// export shares.
pub(super) fn prepare(
    model: &Model,
    options: &ShaderOptions,
) -> Result<SamplerTables, ShaderError> {
    options.validate()?;
    model.validate()?;
    if !model.diffuse_form.is_lambert() && separable_p(model).is_none() {
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
