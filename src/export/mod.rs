//! Models in the files renderers read, the format chosen by the output's
//! extension (see docs/export.md):
//!
//! - `.bsdf`: the RGL tensor file of Mitsuba 3's `measured` plugin and
//!   pbrt-v4's `MeasuredBxDF` ([`rgl`]);
//! - `.binary`: the MERL table ([`crate::reconstruct::to_merl`]);
//! - `.brdf`, `.glsl`, `.h`: a BRDF Explorer analytic file, a standalone
//!   GLSL function and a dependency-free C header ([`shader`]).
//!
//! Every file is written atomically, and never over an existing file
//! unless asked to.

mod error;
pub mod rgl;
pub mod shader;

use crate::model::Model;
use std::path::Path;

pub use error::ExportError;
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
            model
                .validate()
                .map_err(|e| ExportError::Model(e.to_string()))?;
            crate::reconstruct::to_merl(model).write(path, overwrite)?;
            Ok(npf_data_loaders::MerlTable::FILE_BYTES)
        }
        Format::BrdfExplorer => write_text(path, &shader::brdf_explorer(model)?, overwrite),
        Format::Glsl => write_text(path, &shader::glsl(model)?, overwrite),
        Format::CHeader => write_text(path, &shader::c_header(model)?, overwrite),
    }
}

/// Writes generated source text atomically; returns its size in bytes.
fn write_text(path: &Path, text: &str, overwrite: bool) -> Result<u64, ExportError> {
    npf_data_loaders::atomic::write_bytes_atomic(path, overwrite, text.as_bytes())?;
    Ok(text.len() as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Layout;
    use crate::synth::known_factor_model;
    use npf_data_loaders::LoadError;
    use npf_data_loaders::TensorFile;

    fn small() -> ExportOptions {
        ExportOptions {
            rgl: RglOptions {
                theta_i: 5,
                samples: 8,
                vndf: 8,
                ndf: 32,
                phi_i: 5,
                broad: rgl::BROAD_FLOOR,
                spectral: false,
            },
        }
    }

    fn shape(t: &TensorFile, name: &str) -> Vec<usize> {
        t.get(name)
            .unwrap_or_else(|| panic!("no field {name}"))
            .shape
            .clone()
    }

    #[test]
    fn format_follows_the_extension() {
        assert_eq!(Format::of(Path::new("a/b.BSDF")).unwrap(), Format::Rgl);
        assert_eq!(Format::of(Path::new("b.binary")).unwrap(), Format::Merl);
        assert_eq!(Format::of(Path::new("b.h")).unwrap(), Format::CHeader);
        assert!(matches!(
            Format::of(Path::new("b.json")),
            Err(ExportError::UnknownFormat(_))
        ));
        assert!(matches!(
            Format::of(Path::new("b")),
            Err(ExportError::UnknownFormat(_))
        ));
    }

    #[test]
    fn bsdf_file_obeys_the_readers_shape_rules_and_refuses_to_overwrite() {
        let model = known_factor_model(Layout::isotropic(90), &[0.1, 0.4]);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.bsdf");
        let bytes = export(&model, &p, &small(), false).unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().len(), bytes);
        let t = TensorFile::read(&p).unwrap();
        assert_eq!(shape(&t, "phi_i"), [1]);
        assert_eq!(shape(&t, "theta_i"), [5]);
        assert_eq!(shape(&t, "vndf"), [1, 5, 8, 8]);
        assert_eq!(shape(&t, "luminance"), [1, 5, 8, 8]);
        assert_eq!(shape(&t, "rgb"), [1, 5, 3, 8, 8]);
        assert_eq!(shape(&t, "ndf"), [2, 32]);
        assert_eq!(t.get("jacobian").unwrap().as_u8(), Some(&[1u8][..]));
        assert!(t.get("wavelengths").is_none());
        let theta = t.get("theta_i").unwrap().as_f32().unwrap();
        assert!(theta.windows(2).all(|w| w[0] < w[1]) && theta[4] < std::f32::consts::FRAC_PI_2);
        for name in ["ndf", "sigma", "vndf", "luminance", "rgb"] {
            let v = t.get(name).unwrap().as_f32().unwrap();
            assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{name}");
        }
        // No luminance slice is all zero (the warp normalises by its integral).
        let lum = t.get("luminance").unwrap().as_f32().unwrap();
        assert!(lum.chunks(64).all(|s| s.iter().any(|&x| x > 0.0)));
        // The proxy NDF has unit projected area, so sigma(0) = 1 and
        // sigma(theta) >= cos(theta) (the integral of D (m . wi) over all m
        // is cos theta_i).
        let sigma = t.get("sigma").unwrap().as_f32().unwrap();
        assert!((sigma[0] - 1.0).abs() < 0.01, "{}", sigma[0]);
        for (k, &s) in sigma[..32].iter().enumerate() {
            let th = (k as f64 / 31.0).powi(2) * std::f64::consts::FRAC_PI_2;
            assert!(s as f64 >= th.cos() - 0.01, "{k} {s}");
        }
        let e = export(&model, &p, &small(), false).unwrap_err();
        assert!(
            matches!(e, ExportError::Write(LoadError::Exists { .. })),
            "{e}"
        );
        export(&model, &p, &small(), true).unwrap();
    }

    #[test]
    fn spectral_layout_has_spectra_and_wavelengths() {
        let model = known_factor_model(Layout::isotropic(90), &[0.2]);
        let mut opts = small();
        opts.rgl.spectral = true;
        let t = rgl::to_tensor_file(&model, &opts.rgl).unwrap();
        assert!(t.get("rgb").is_none());
        assert_eq!(shape(&t, "spectra"), [1, 5, 10, 8, 8]);
        let wl = t.get("wavelengths").unwrap().as_f32().unwrap();
        assert!(wl.len() == 10 && wl.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn anisotropic_layout_covers_phi_i_over_two_pi() {
        let model = known_factor_model(Layout::anisotropic(), &[0.3]);
        let t = rgl::to_tensor_file(&model, &small().rgl).unwrap();
        let phi = t.get("phi_i").unwrap().as_f32().unwrap();
        assert_eq!(phi.len(), 5);
        assert!((phi[0] + std::f32::consts::PI).abs() < 1e-6);
        assert!((phi[4] - std::f32::consts::PI).abs() < 1e-6);
        assert_eq!(shape(&t, "rgb"), [5, 5, 3, 8, 8]);
        assert_eq!(shape(&t, "ndf"), [rgl::ANISO_PHI_ROWS, 32]);
        // phi_i = -pi and pi are the same direction: equal end slices.
        let rgb = t.get("rgb").unwrap().as_f32().unwrap();
        let slice = 5 * 3 * 64;
        let (first, last) = (&rgb[..slice], &rgb[4 * slice..]);
        let worst = first
            .iter()
            .zip(last)
            .map(|(a, b)| (a - b).abs() / a.abs().max(1e-3))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-3, "{worst}");
        let sigma = t.get("sigma").unwrap().as_f32().unwrap();
        assert!(sigma.iter().step_by(32).all(|s| (s - 1.0).abs() < 0.01));
    }

    #[test]
    fn merl_export_is_the_reconstruction() {
        let model = known_factor_model(Layout::isotropic(90), &[0.2]);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.binary");
        export(&model, &p, &small(), false).unwrap();
        let back = npf_data_loaders::MerlTable::read(&p).unwrap();
        assert_eq!(
            back.to_bytes(),
            crate::reconstruct::to_merl(&model).to_bytes()
        );
    }

    #[test]
    fn shader_formats_write_their_generators_text() {
        let dir = tempfile::tempdir().unwrap();
        let iso = known_factor_model(Layout::isotropic(90), &[0.2]);
        for (name, text) in [
            ("m.brdf", shader::brdf_explorer(&iso).unwrap()),
            ("m.glsl", shader::glsl(&iso).unwrap()),
            ("m.h", shader::c_header(&iso).unwrap()),
        ] {
            let path = dir.path().join(name);
            let size = export(&iso, &path, &small(), false).unwrap();
            assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
            assert_eq!(size, text.len() as u64);
            // Never over an existing file unless asked to.
            assert!(export(&iso, &path, &small(), false).is_err());
        }
    }

    #[test]
    fn refusals_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let iso = known_factor_model(Layout::isotropic(90), &[0.2]);
        assert!(matches!(
            export(&iso, &dir.path().join("m.txt"), &small(), false),
            Err(ExportError::UnknownFormat(_))
        ));
        let mut bad = small();
        bad.rgl.samples = 1;
        assert!(matches!(
            export(&iso, &dir.path().join("b.bsdf"), &bad, false),
            Err(ExportError::Option(_))
        ));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
