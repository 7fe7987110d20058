//! Models in the files renderers read, the format chosen by the output's
//! extension (see docs/export.md):
//!
//! - `.bsdf`: the RGL tensor file of Mitsuba 3's `measured` plugin and
//!   pbrt-v4's `MeasuredBxDF` ([`rgl`]);
//! - `.binary`: the MERL table ([`crate::reconstruct::to_merl`]);
//! - `.brdf`, `.glsl`, `.h`: shader and header exports (not built yet:
//!   [`ExportError::Unsupported`]).
//!
//! Every file is written atomically, and never over an existing file
//! unless asked to.

pub mod rgl;

use crate::model::Model;
use npf_data_loaders::LoadError;
use std::path::Path;

pub use rgl::RglOptions;

/// An export format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// RGL `.bsdf` tensor file.
    Rgl,
    /// MERL `.binary` table.
    Merl,
    /// BRDF Explorer `.brdf` analytic file.
    BrdfExplorer,
    /// Standalone GLSL function (`.glsl`).
    Glsl,
    /// Dependency-free C header (`.h`).
    CHeader,
}

/// Why a model could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The extension names no export format.
    #[error("unknown export format {0:?} (use .bsdf, .binary, .brdf, .glsl or .h)")]
    UnknownFormat(String),
    /// A format npf knows but does not write yet.
    #[error("export to .{0} is not supported yet")]
    Unsupported(String),
    /// The format has no layout for anisotropic models yet.
    #[error("the .bsdf export supports isotropic models only")]
    Anisotropic,
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

impl Format {
    /// The format of an output path, from its extension (case-insensitive).
    pub fn of(path: &Path) -> Result<Self, ExportError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        Ok(match ext.as_str() {
            "bsdf" => Format::Rgl,
            "binary" => Format::Merl,
            "brdf" => Format::BrdfExplorer,
            "glsl" => Format::Glsl,
            "h" => Format::CHeader,
            _ => return Err(ExportError::UnknownFormat(ext)),
        })
    }
}

/// Options of every format (each reads its own).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExportOptions {
    /// Resolutions and colour layout of `.bsdf` files.
    pub rgl: RglOptions,
}

/// Writes `model` to `path` in the format its extension names, atomically
/// (never over an existing file unless `overwrite`). Returns the file's
/// size in bytes.
pub fn export(
    model: &Model,
    path: &Path,
    opts: &ExportOptions,
    overwrite: bool,
) -> Result<u64, ExportError> {
    match Format::of(path)? {
        Format::Rgl => Ok(rgl::to_tensor_file(model, &opts.rgl)?.write(path, overwrite)?),
        Format::Merl => {
            model.validate().map_err(|e| ExportError::Model(e.to_string()))?;
            crate::reconstruct::to_merl(model).write(path, overwrite)?;
            Ok(npf_data_loaders::MerlTable::FILE_BYTES)
        }
        Format::BrdfExplorer => Err(ExportError::Unsupported("brdf".into())),
        Format::Glsl => Err(ExportError::Unsupported("glsl".into())),
        Format::CHeader => Err(ExportError::Unsupported("h".into())),
    }
}
