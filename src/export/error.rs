//! Why an export failed.

use super::shader;
use npf_data_loaders::LoadError;

/// Why a model could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The extension names no export format.
    #[error("unknown export format {0:?} (use .bsdf, .binary, .brdf, .glsl or .h)")]
    UnknownFormat(String),
    /// A shader or header export failed.
    #[error(transparent)]
    Shader(#[from] shader::ShaderError),
    /// An option out of range.
    #[error("{0}")]
    Option(String),
    /// The model is not valid.
    #[error("invalid model: {0}")]
    Model(String),
    /// Writing the file.
    #[error(transparent)]
    Write(#[from] LoadError),
}
