//! Model files: a documented, versioned JSON form and a compact binary form.
//!
//! JSON (`.json`): `{"format": "npf-model", "version": 1, "conventions":
//! {...}, "model": {...}, "fit": {...}}`. `model` holds the layout (the grid
//! of every factor: its theta axis, plus `"phi": {"n": N}` for a 2-D table),
//! `diffuse` [3], `fresnel` [3][n_F] and `lobes`, each with `s` [3], `d`
//! [n_D] and `g` [n_G] (2-D tables row-major theta x phi); `conventions` spells out units and
//! formulas for a reader without this code (ignored when reading); `fit` is
//! optional provenance (source, options, objective, errors).
//!
//! Binary (`.npfb`), little-endian: magic `NPFB`, u16 version (1), u16
//! reserved (0), u8 layout kind, u8 lobes, then for D, F, G: u8 axis kind
//! (0 sqrt-angle, 1 uniform, 2 Catmull-Rom, 3 squared) and u16 theta node count, and
//! for layout kind 1 also u16 phi node count (0: a 1-D table); u32
//! parameter count; then the parameters as f32 in `Model::params` order (d,
//! s per lobe, D per lobe, G per lobe, F_R, F_G, F_B). Layout kind 0 (all
//! tables 1-D, the isotropic model) has 23 header bytes: 23 + 822 x 4 =
//! 3,311 bytes for the default model; kind 1 (some table 2-D) has 29. Files
//! of kind 0 are what earlier versions wrote, and isotropic models are still
//! written so. No provenance: it is the form a renderer loads.
//!
//! The diffuse form (`diffuse_form` in JSON, absent in older files: Lambert)
//! is the binary header's formerly reserved u16: 0 Lambert (no trailer, the
//! files earlier versions wrote), 1 energy-coupled, 2 Oren-Nayar, 3
//! separable; forms 1 to 3 append a trailer after the parameters: u32
//! count, then that many f32 (energy-coupled: E_R, E_G, E_B tables of n
//! values each, then the three averages, count = 3 n + 3; Oren-Nayar:
//! sigma, count = 1; separable: P's n >= 2 node values, count = n). Bit 0x100 of
//! that word marks height-correlated masking (`masking` in JSON); bit 0x200
//! a compensation term (`compensation`), whose own trailer block (u32
//! count, then E_R, E_G, E_B of n values, three averages, three scales:
//! 3 n + 6) follows the diffuse form's.
//!
//! Both forms hold the model's f32 parameters exactly, so writing and
//! reading gives back the same model bit for bit.
//!
//! Bounds: a model file is at most [`MAX_FILE_BYTES`] (checked before it is
//! read; only regular files are read, so a FIFO or `/dev/zero` is refused),
//! holds at most [`MAX_LOBES`] lobes and [`MAX_PARAMS`] parameters (checked
//! from the binary header before the parameters are allocated), and
//! [`write`] refuses a model or provenance it could not read back.

use crate::grid::{Axis, Grid, PhiAxis};
use crate::metrics::Metrics;
use crate::model::{Compensation, DiffuseForm, Layout, Masking, Model, ModelError};
use byteorder::{ByteOrder, LittleEndian as LE};
use npf_data_loaders::atomic::write_bytes_atomic;
use npf_data_loaders::LoadError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The JSON form's `format` value.
pub const FORMAT: &str = "npf-model";
/// The version both forms carry.
pub const VERSION: u32 = 1;
const MAGIC: &[u8; 4] = b"NPFB";
/// Header bytes of layout kind 0 (1-D tables).
const HEADER_BYTES: usize = 23;
/// Header bytes of layout kind 1 (grids with a phi axis).
const HEADER_BYTES_2D: usize = 29;

/// Largest model file read (64 MiB): the default model is 3.3 kB as
/// `.npfb` and about 40 kB as JSON, a model with [`MAX_PARAMS`] parameters
/// about 4 MB and 25 MB.
pub const MAX_FILE_BYTES: u64 = 64 << 20;
/// Most lobes a model file may hold (the solver fits at most 3).
pub const MAX_LOBES: usize = 8;
/// Most parameters a model file may hold (2^20; the anisotropic model has
/// 2,010). Bounds the memory and time of loading and of the sampling tables.
pub const MAX_PARAMS: usize = 1 << 20;

/// How a model was made (stored in JSON files only).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FitInfo {
    /// The fitted data's source.
    pub source: String,
    /// The npf version that fitted it.
    pub npf_version: String,
    /// Specular lobes.
    pub lobes: usize,
    /// Residual weighting name.
    pub weighting: String,
    /// The compressive weighting's floor.
    pub epsilon: f64,
    /// Grazing cut-off (degrees).
    pub max_theta_deg: f64,
    /// D half-angle limit (degrees).
    pub max_theta_h_deg: f64,
    /// Where D was constrained to be non-increasing (absent: a free tail).
    #[serde(default)]
    pub d_monotone_from_deg: Option<f64>,
    /// G update method name.
    pub g_method: String,
    /// G smoothing width, if any.
    pub smooth_g: Option<f64>,
    /// Sweeps run.
    pub sweeps: usize,
    /// Whether the fit converged.
    pub converged: bool,
    /// Final objective.
    pub objective: f64,
    /// Fit wall time.
    pub seconds: f64,
    /// Threads used.
    pub threads: usize,
    /// Samples fitted.
    pub samples: usize,
    /// Fit errors, if measured.
    pub metrics: Option<Metrics>,
    /// Free-form notes (e.g. why this configuration was chosen).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub selection: Option<serde_json::Value>,
}

/// A model with its optional provenance.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// The model.
    pub model: Model,
    /// How it was made (JSON files only).
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
        "formula": "rho_C(wi,wo) = d_C b_C(wi,wo) + sum_m s_C^m D^m(theta_h) F_C(theta_d) G^m(theta_i) G^m(theta_o) / (cos theta_i cos theta_o)",
        "units": "BRDF values in 1/sr (MERL's physical units); angles in radians",
        "frame": "local shading frame, normal +z; theta_h, theta_d: Rusinkiewicz half and difference angles",
        "channels": "R, G, B (MERL's linear RGB)",
        "axes": {
            "sqrt_angle": "n nodes, node k at theta = (k/n)^2 * pi/2; linear in sqrt(theta) between nodes; constant past the last node",
            "uniform": "n nodes, node k at theta = k/n * pi/2; linear between nodes; constant past the last node",
            "squared": "n nodes, node k at theta = (k/(n-1))^2 * (n-1)/n * pi/2 (uniform's span, squared spacing); linear in sqrt(theta) between nodes; constant past the last node",
            "catmull_rom": "n control points at theta_k = k/(n-1) * pi/2; pbrt-v3 CatmullRomWeights (centred tangents, chord at the ends)",
            "phi": "optional periodic azimuth axis of a 2-D table: n nodes at phi_k = 2 pi k / n, linear, wrapping; the table is row-major theta x phi; D reads (theta_h, phi_h), G (theta, phi) of each direction, F (theta_d, phi_d)"
        },
        "gauge": "max of G over constrained control points = 1; 2 pi * integral over theta_h <= 60 deg of D cos sin = 1; F_C(0) = 1",
        "diffuse_form": "b_C: lambert 1; energy-coupled (1 - E_C(theta_i)) (1 - E_C(theta_o)) / (1 - average_C), E_C linear on uniform theta nodes over [0, pi/2]; oren-nayar A + B max(0, cos(phi_i - phi_o)) sin(max theta) tan(min theta), A = 1 - sigma^2 / (2 (sigma^2 + 0.33)), B = 0.45 sigma^2 / (sigma^2 + 0.09); separable P(theta_i) P(theta_o), P (shared by the channels) linear on n uniform theta nodes spanning [0, pi/2] inclusively; absent: lambert",
        "masking": "separable (absent): G^m(theta_i) G^m(theta_o); height-correlated: G2 = Gi Go / (Gi + Go - Gi Go) with Gi, Go the tabulated G clamped to [0, 1], in place of the product",
        "compensation": "optional Kulla-Conty term added to rho: scale_C (1 - E_C(theta_i)) (1 - E_C(theta_o)) / (1 - average_C), E_C linear on uniform theta nodes over [0, pi/2]",
        "below_horizon": "the BRDF is 0 when cos theta_i <= 0 or cos theta_o <= 0"
    })
}

/// Why a model file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// Reading or writing failed.
    #[error(transparent)]
    Io(#[from] LoadError),
    /// The file is not a model file of a supported form.
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: String,
        /// What is wrong.
        problem: String,
    },
    /// The file holds a model that is not valid.
    #[error("{path}: {source}")]
    Model {
        /// The file.
        path: String,
        /// What is wrong with the model.
        source: ModelError,
    },
}

fn bad_model(path: &Path, source: ModelError) -> ModelFileError {
    ModelFileError::Model {
        path: path.display().to_string(),
        source,
    }
}

fn invalid(path: &Path, problem: impl Into<String>) -> ModelFileError {
    ModelFileError::Invalid {
        path: path.display().to_string(),
        problem: problem.into(),
    }
}

/// The two file forms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Form {
    /// `.json`: documented, with provenance.
    Json,
    /// `.npfb`: compact binary.
    Binary,
}

impl Form {
    /// The form an extension names.
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

/// The JSON form.
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

/// Parse the JSON form (`path` is for messages).
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
    j.model.validate().map_err(|e| bad_model(path, e))?;
    check_size(path, j.model.layout, j.model.lobes.len())?;
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
        Axis::Squared { n } => (3, n as u16),
        Axis::Closed { n } => (4, n as u16),
    }
}

fn axis_from(code: u8, n: u16) -> Option<Axis> {
    let n = n as usize;
    match code {
        0 => Some(Axis::SqrtAngle { n }),
        1 => Some(Axis::Uniform { n }),
        2 => Some(Axis::CatmullRom { n }),
        3 => Some(Axis::Squared { n }),
        4 => Some(Axis::Closed { n }),
        _ => None,
    }
}

/// The binary form (layout kind 0 for an isotropic layout, 1 otherwise).
pub fn to_binary(model: &Model) -> Vec<u8> {
    let params = model.params();
    let l = model.layout;
    let flat = l.is_isotropic();
    let (header, per) = if flat {
        (HEADER_BYTES, 3)
    } else {
        (HEADER_BYTES_2D, 5)
    };
    let mut out = vec![0u8; header + 4 * params.len()];
    out[0..4].copy_from_slice(MAGIC);
    LE::write_u16(&mut out[4..6], VERSION as u16);
    out[8] = if flat { 0 } else { 1 };
    out[9] = model.lobes.len() as u8;
    for (i, g) in [l.d, l.f, l.g].into_iter().enumerate() {
        let at = 10 + per * i;
        let (code, n) = axis_code(g.theta);
        out[at] = code;
        LE::write_u16(&mut out[at + 1..at + 3], n);
        if !flat {
            LE::write_u16(&mut out[at + 3..at + 5], g.phi.map_or(0, |p| p.n as u16));
        }
    }
    LE::write_u32(&mut out[header - 4..header], params.len() as u32);
    LE::write_f32_into(&params, &mut out[header..]);
    let (code, extra): (u16, Vec<f32>) = match &model.diffuse_form {
        DiffuseForm::Lambert => (0, Vec::new()),
        DiffuseForm::EnergyCoupled { albedo, average } => {
            (1, albedo.iter().flatten().chain(average).copied().collect())
        }
        DiffuseForm::OrenNayar { sigma } => (2, vec![*sigma]),
        DiffuseForm::Separable { p } => (3, p.clone()),
    };
    let mut flags = code;
    if !model.masking.is_separable() {
        flags |= HEIGHT_CORRELATED;
    }
    LE::write_u16(&mut out[6..8], flags);
    let mut block = |values: &[f32]| {
        let at = out.len();
        out.resize(at + 4 + 4 * values.len(), 0);
        LE::write_u32(&mut out[at..at + 4], values.len() as u32);
        LE::write_f32_into(values, &mut out[at + 4..]);
    };
    if code != 0 {
        block(&extra);
    }
    if let Some(k) = &model.compensation {
        let v: Vec<f32> = k
            .albedo
            .iter()
            .flatten()
            .chain(&k.average)
            .chain(&k.scale)
            .copied()
            .collect();
        block(&v);
        flags |= COMPENSATED;
        LE::write_u16(&mut out[6..8], flags);
    }
    out
}

/// Bit of the binary header's form word: height-correlated masking.
const HEIGHT_CORRELATED: u16 = 0x100;
/// Bit of the binary header's form word: a compensation trailer follows.
const COMPENSATED: u16 = 0x200;

/// The diffuse form of a binary file's code and trailer.
fn diffuse_from(code: u16, extra: &[f32], path: &Path) -> Result<DiffuseForm, ModelFileError> {
    match code {
        1 if extra.len() >= 9 && extra.len() % 3 == 0 => {
            let n = (extra.len() - 3) / 3;
            Ok(DiffuseForm::EnergyCoupled {
                albedo: std::array::from_fn(|c| extra[c * n..(c + 1) * n].to_vec()),
                average: [extra[3 * n], extra[3 * n + 1], extra[3 * n + 2]],
            })
        }
        2 if extra.len() == 1 => Ok(DiffuseForm::OrenNayar { sigma: extra[0] }),
        3 if extra.len() >= 2 => Ok(DiffuseForm::Separable { p: extra.to_vec() }),
        1..=3 => Err(invalid(
            path,
            format!(
                "diffuse form {code} with a trailer of {} values",
                extra.len()
            ),
        )),
        _ => Err(invalid(path, format!("unknown diffuse form {code}"))),
    }
}

/// Parse the binary form (`path` is for messages).
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
    let (header, per) = match bytes[8] {
        0 => (HEADER_BYTES, 3),
        1 => (HEADER_BYTES_2D, 5),
        k => {
            return Err(invalid(path, format!("layout kind {k} is not supported")));
        }
    };
    if bytes.len() < header {
        return Err(invalid(path, "shorter than the header"));
    }
    let lobes = bytes[9] as usize;
    let mut grids = [Grid::line(Axis::Uniform { n: 0 }); 3];
    for (i, grid) in grids.iter_mut().enumerate() {
        let at = 10 + per * i;
        let theta = axis_from(bytes[at], LE::read_u16(&bytes[at + 1..at + 3]))
            .ok_or_else(|| invalid(path, format!("unknown axis kind {}", bytes[at])))?;
        let n_phi = if per == 5 {
            LE::read_u16(&bytes[at + 3..at + 5]) as usize
        } else {
            0
        };
        *grid = Grid {
            theta,
            phi: (n_phi > 0).then_some(PhiAxis { n: n_phi }),
        };
    }
    let layout = Layout {
        d: grids[0],
        f: grids[1],
        g: grids[2],
    };
    check_size(path, layout, lobes)?;
    let count = LE::read_u32(&bytes[header - 4..header]) as usize;
    let mut expected = header as u64 + 4 * count as u64;
    let flags = LE::read_u16(&bytes[6..8]);
    if flags & !(0xff | HEIGHT_CORRELATED | COMPENSATED) != 0 {
        return Err(invalid(
            path,
            format!("unknown model form flags {flags:#x}"),
        ));
    }
    let code = flags & 0xff;
    // The trailer blocks: the diffuse form's (if not Lambert), then the
    // compensation term's (if flagged); each u32 count, then f32 values.
    let mut blocks: Vec<Vec<f32>> = Vec::new();
    for _ in 0..(code != 0) as usize + (flags & COMPENSATED != 0) as usize {
        let at = expected as usize;
        if bytes.len() < at + 4 {
            return Err(invalid(
                path,
                "diffuse-form or compensation trailer missing (truncated file)",
            ));
        }
        let n = LE::read_u32(&bytes[at..at + 4]) as usize;
        if n > MAX_PARAMS {
            return Err(invalid(path, format!("model trailer of {n} values")));
        }
        expected += 4 + 4 * n as u64;
        if bytes.len() as u64 >= expected {
            let mut v = vec![0f32; n];
            LE::read_f32_into(&bytes[at + 4..expected as usize], &mut v);
            blocks.push(v);
        }
    }
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
    LE::read_f32_into(&bytes[header..header + 4 * count], &mut params);
    let mut model = Model::from_params(layout, lobes, &params).map_err(|e| bad_model(path, e))?;
    let mut blocks = blocks.into_iter();
    if code != 0 {
        let extra = blocks.next().unwrap_or_default();
        model.diffuse_form = diffuse_from(code, &extra, path)?;
    }
    if flags & HEIGHT_CORRELATED != 0 {
        model.masking = Masking::HeightCorrelated;
    }
    if flags & COMPENSATED != 0 {
        let v = blocks.next().unwrap_or_default();
        if v.len() < 12 || v.len() % 3 != 0 {
            return Err(invalid(
                path,
                format!("compensation trailer of {} values", v.len()),
            ));
        }
        let n = (v.len() - 6) / 3;
        model.compensation = Some(Compensation {
            albedo: std::array::from_fn(|c| v[c * n..(c + 1) * n].to_vec()),
            average: [v[3 * n], v[3 * n + 1], v[3 * n + 2]],
            scale: [v[3 * n + 3], v[3 * n + 4], v[3 * n + 5]],
        });
    }
    if flags != 0 {
        model.validate().map_err(|e| bad_model(path, e))?;
    }
    Ok(model)
}

/// Refuse a layout beyond [`MAX_LOBES`] or [`MAX_PARAMS`].
fn check_size(path: &Path, layout: Layout, lobes: usize) -> Result<(), ModelFileError> {
    if lobes > MAX_LOBES {
        return Err(invalid(
            path,
            format!("{lobes} lobes, more than the {MAX_LOBES} a model file may hold"),
        ));
    }
    // Saturating: a crafted header may not overflow the count.
    let n = |g: Grid| g.n_theta().saturating_mul(g.n_phi().max(1));
    let params = 3usize
        .saturating_add(3 * lobes)
        .saturating_add(lobes.saturating_mul(n(layout.d).saturating_add(n(layout.g))))
        .saturating_add(3usize.saturating_mul(n(layout.f)));
    if params > MAX_PARAMS {
        return Err(invalid(
            path,
            format!("the layout has {params} parameters, more than the {MAX_PARAMS} a model file may hold"),
        ));
    }
    Ok(())
}

/// Read a model file of either form (chosen by extension): a regular file
/// of at most [`MAX_FILE_BYTES`]; a file of another known kind (a MERL or
/// UTIA table, a directory...) is named in the error.
pub fn read(path: &Path) -> Result<ModelFile, ModelFileError> {
    let form = Form::of(path)?;
    let what = match form {
        Form::Json => "an npf model (JSON)",
        Form::Binary => "an npf binary model (.npfb)",
    };
    let bytes = npf_data_loaders::sniff::read_bounded(path, MAX_FILE_BYTES, what).map_err(|e| {
        match e {
            // Name what an oversized file is, if it is a known kind (a MERL
            // table, most likely).
            LoadError::TooLarge { .. } => match npf_data_loaders::sniff::describe(path) {
                found
                    if !found.starts_with("a binary file") && !found.starts_with("a text file") =>
                {
                    LoadError::WrongFormat {
                        path: path.to_path_buf(),
                        expected: what,
                        found,
                    }
                }
                _ => e,
            },
            e => e,
        }
    })?;
    let looks_wrong = match form {
        Form::Json => !bytes
            .iter()
            .find(|b| !b.is_ascii_whitespace())
            .is_some_and(|&b| b == b'{'),
        Form::Binary => !bytes.starts_with(MAGIC),
    };
    if looks_wrong && !bytes.is_empty() {
        let found = npf_data_loaders::sniff::describe(path);
        if !found.starts_with("a text file") && !found.starts_with("a binary file") {
            return Err(LoadError::WrongFormat {
                path: path.to_path_buf(),
                expected: what,
                found,
            }
            .into());
        }
    }
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
///
/// Refuses (writing nothing) a model that does not validate (for example
/// non-finite parameters) or provenance that JSON cannot hold (non-finite
/// numbers would be written as `null`): the bytes are parsed back first,
/// so every file written can be read.
pub fn write(path: &Path, file: &ModelFile, overwrite: bool) -> Result<(), ModelFileError> {
    file.model.validate().map_err(|e| bad_model(path, e))?;
    let form = Form::of(path)?;
    let bytes = match form {
        Form::Json => to_json(file).into_bytes(),
        Form::Binary => to_binary(&file.model),
    };
    let back = match form {
        Form::Json => from_json(std::str::from_utf8(&bytes).unwrap_or(""), path).map(|_| ()),
        Form::Binary => from_binary(&bytes, path).map(|_| ()),
    };
    back.map_err(|e| {
        invalid(
            path,
            format!("refusing to write a model file that could not be read back: {e}"),
        )
    })?;
    Ok(write_bytes_atomic(path, overwrite, &bytes)?)
}
