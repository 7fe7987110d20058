//! Model files: a documented, versioned JSON form and a compact binary form.
//!
//! JSON (`.json`): `{"format": "npf-model", "version": 1, "conventions":
//! {...}, "model": {...}, "fit": {...}}`. `model` holds the layout (the axis
//! of every factor), `diffuse` [3], `fresnel` [3][n_F] and `lobes`, each with
//! `s` [3], `d` [n_D] and `g` [n_G]; `conventions` spells out units and
//! formulas for a reader without this code (ignored when reading); `fit` is
//! optional provenance (source, options, objective, errors).
//!
//! Binary (`.npfb`), little-endian: magic `NPFB`, u16 version (1), u16
//! reserved (0), u8 layout kind (0 = isotropic 1-D tables), u8 lobes, then
//! for D, F, G: u8 axis kind (0 sqrt-angle, 1 uniform, 2 Catmull-Rom) and
//! u16 node count; u32 parameter count; then the parameters as f32 in
//! `Model::params` order (d, s per lobe, D per lobe, G per lobe, F_R, F_G,
//! F_B). 23 header bytes + 822 x 4 = 3,311 bytes for the default model. No
//! provenance: it is the form a renderer loads.
//!
//! Both forms hold the model's f32 parameters exactly, so writing and
//! reading gives back the same model bit for bit.

use crate::interp::Axis;
use crate::metrics::Metrics;
use crate::model::{Layout, Model};
use byteorder::{ByteOrder, LittleEndian as LE};
use npf_data_loaders::atomic::write_bytes_atomic;
use npf_data_loaders::LoadError;
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const FORMAT: &str = "npf-model";
pub const VERSION: u32 = 1;
const MAGIC: &[u8; 4] = b"NPFB";
const HEADER_BYTES: usize = 23;

/// How a model was made (stored in JSON files only).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FitInfo {
    pub source: String,
    pub npf_version: String,
    pub lobes: usize,
    pub weighting: String,
    pub epsilon: f64,
    pub max_theta_deg: f64,
    pub max_theta_h_deg: f64,
    /// Where D was constrained to be non-increasing (absent: a free tail).
    #[serde(default)]
    pub d_monotone_from_deg: Option<f64>,
    pub g_method: String,
    pub smooth_g: Option<f64>,
    pub sweeps: usize,
    pub converged: bool,
    pub objective: f64,
    pub seconds: f64,
    pub threads: usize,
    pub samples: usize,
    pub metrics: Option<Metrics>,
    /// Free-form notes (e.g. why this configuration was chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection: Option<serde_json::Value>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    pub model: Model,
    pub fit: Option<FitInfo>,
}

#[derive(Serialize, Deserialize)]
struct JsonFile {
    format: String,
    version: u32,
    #[serde(default)]
    conventions: serde_json::Value,
    model: Model,
    #[serde(default)]
    fit: Option<FitInfo>,
}

fn conventions() -> serde_json::Value {
    serde_json::json!({
        "formula": "rho_C(wi,wo) = d_C + sum_m s_C^m D^m(theta_h) F_C(theta_d) G^m(theta_i) G^m(theta_o) / (cos theta_i cos theta_o)",
        "units": "BRDF values in 1/sr (MERL's physical units); angles in radians",
        "frame": "local shading frame, normal +z; theta_h, theta_d: Rusinkiewicz half and difference angles",
        "channels": "R, G, B (MERL's linear RGB)",
        "axes": {
            "sqrt_angle": "n nodes, node k at theta = (k/n)^2 * pi/2; linear in sqrt(theta) between nodes; constant past the last node",
            "uniform": "n nodes, node k at theta = k/n * pi/2; linear between nodes; constant past the last node",
            "catmull_rom": "n control points at theta_k = k/(n-1) * pi/2; pbrt-v3 CatmullRomWeights (centred tangents, chord at the ends)"
        },
        "gauge": "max of G over constrained control points = 1; 2 pi * integral over theta_h <= 60 deg of D cos sin = 1; F_C(0) = 1",
        "below_horizon": "the BRDF is 0 when cos theta_i <= 0 or cos theta_o <= 0"
    })
}

#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    #[error(transparent)]
    Io(#[from] LoadError),
    #[error("{path}: {problem}")]
    Invalid { path: String, problem: String },
}

fn invalid(path: &Path, problem: impl Into<String>) -> ModelFileError {
    ModelFileError::Invalid {
        path: path.display().to_string(),
        problem: problem.into(),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    Json,
    Binary,
}

impl Form {
    pub fn of(path: &Path) -> Result<Form, ModelFileError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("json") => Ok(Form::Json),
            Some("npfb") => Ok(Form::Binary),
            _ => Err(invalid(
                path,
                "unknown model file extension (use .json or .npfb)",
            )),
        }
    }
}

pub fn to_json(file: &ModelFile) -> String {
    let j = JsonFile {
        format: FORMAT.into(),
        version: VERSION,
        conventions: conventions(),
        model: file.model.clone(),
        fit: file.fit.clone(),
    };
    serde_json::to_string_pretty(&j).expect("a model always serialises")
}

pub fn from_json(text: &str, path: &Path) -> Result<ModelFile, ModelFileError> {
    let j: JsonFile = serde_json::from_str(text)
        .map_err(|e| invalid(path, format!("not a valid npf model JSON file: {e}")))?;
    if j.format != FORMAT {
        return Err(invalid(
            path,
            format!("format is {:?}, expected {FORMAT:?}", j.format),
        ));
    }
    if j.version != VERSION {
        return Err(invalid(
            path,
            format!(
                "model file version {} is not supported (this npf reads {VERSION})",
                j.version
            ),
        ));
    }
    j.model.validate().map_err(|e| invalid(path, e))?;
    Ok(ModelFile {
        model: j.model,
        fit: j.fit,
    })
}

fn axis_code(a: Axis) -> (u8, u16) {
    match a {
        Axis::SqrtAngle { n } => (0, n as u16),
        Axis::Uniform { n } => (1, n as u16),
        Axis::CatmullRom { n } => (2, n as u16),
    }
}

fn axis_from(code: u8, n: u16) -> Option<Axis> {
    let n = n as usize;
    match code {
        0 => Some(Axis::SqrtAngle { n }),
        1 => Some(Axis::Uniform { n }),
        2 => Some(Axis::CatmullRom { n }),
        _ => None,
    }
}

pub fn to_binary(model: &Model) -> Vec<u8> {
    let params = model.params();
    let mut out = vec![0u8; HEADER_BYTES + 4 * params.len()];
    out[0..4].copy_from_slice(MAGIC);
    LE::write_u16(&mut out[4..6], VERSION as u16);
    out[8] = 0;
    out[9] = model.lobes.len() as u8;
    for (i, a) in [model.layout.d, model.layout.f, model.layout.g]
        .into_iter()
        .enumerate()
    {
        let (code, n) = axis_code(a);
        out[10 + 3 * i] = code;
        LE::write_u16(&mut out[11 + 3 * i..13 + 3 * i], n);
    }
    LE::write_u32(&mut out[19..23], params.len() as u32);
    LE::write_f32_into(&params, &mut out[HEADER_BYTES..]);
    out
}

pub fn from_binary(bytes: &[u8], path: &Path) -> Result<Model, ModelFileError> {
    if bytes.len() < HEADER_BYTES || &bytes[0..4] != MAGIC {
        return Err(invalid(
            path,
            "not an npf binary model (bad magic or shorter than the header)",
        ));
    }
    let version = LE::read_u16(&bytes[4..6]);
    if version as u32 != VERSION {
        return Err(invalid(
            path,
            format!("binary model version {version} is not supported (this npf reads {VERSION})"),
        ));
    }
    if bytes[8] != 0 {
        return Err(invalid(
            path,
            format!("layout kind {} is not supported", bytes[8]),
        ));
    }
    let lobes = bytes[9] as usize;
    let mut axes = [Axis::Uniform { n: 0 }; 3];
    for (i, axis) in axes.iter_mut().enumerate() {
        *axis = axis_from(
            bytes[10 + 3 * i],
            LE::read_u16(&bytes[11 + 3 * i..13 + 3 * i]),
        )
        .ok_or_else(|| invalid(path, format!("unknown axis kind {}", bytes[10 + 3 * i])))?;
    }
    let layout = Layout {
        d: axes[0],
        f: axes[1],
        g: axes[2],
    };
    let count = LE::read_u32(&bytes[19..23]) as usize;
    let expected = HEADER_BYTES as u64 + 4 * count as u64;
    if bytes.len() as u64 != expected {
        return Err(invalid(
            path,
            format!(
                "{} bytes, the header promises {expected} (truncated or padded file)",
                bytes.len()
            ),
        ));
    }
    let mut params = vec![0f32; count];
    LE::read_f32_into(&bytes[HEADER_BYTES..], &mut params);
    Model::from_params(layout, lobes, &params).map_err(|e| invalid(path, e))
}

/// Read a model file of either form (chosen by extension).
pub fn read(path: &Path) -> Result<ModelFile, ModelFileError> {
    let form = Form::of(path)?;
    let bytes = std::fs::read(path).map_err(|e| LoadError::io(path, e))?;
    match form {
        Form::Json => {
            let text = std::str::from_utf8(&bytes).map_err(|_| invalid(path, "not UTF-8 text"))?;
            from_json(text, path)
        }
        Form::Binary => Ok(ModelFile {
            model: from_binary(&bytes, path)?,
            fit: None,
        }),
    }
}

/// Write a model file atomically, in the form its extension names.
pub fn write(path: &Path, file: &ModelFile, overwrite: bool) -> Result<(), ModelFileError> {
    let bytes = match Form::of(path)? {
        Form::Json => to_json(file).into_bytes(),
        Form::Binary => to_binary(&file.model),
    };
    Ok(write_bytes_atomic(path, overwrite, &bytes)?)
}
