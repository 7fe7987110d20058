//! `npf.Model`: a fitted model's evaluation, sampling, factors and exports.

use crate::convert::*;
use npf::bsdf::{self, Bsdf, BsdfSample, NpfBxdf};
use npf::loaders::geometry::Vec3;
use npf::model::Model as CoreModel;
use npf::modelfile::{self, ModelFile};
use numpy::ndarray::{Array1, Array2, Axis as NdAxis};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray4, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// A fitted npf model: the factor tables, its provenance, and npf's own
/// evaluator and importance sampler.
///
/// Directions are unit vectors in the local shading frame (normal +z), as
/// float arrays of shape (N, 3) (or (3,) for one direction); `wi` points
/// towards the light, `wo` towards the viewer (the convention of `npf eval`).
#[pyclass(module = "npf", name = "Model", frozen)]
pub(crate) struct PyModel {
    file: ModelFile,
    /// The sampler's tables, built on first use (sampling needs them,
    /// evaluation does not).
    bxdf: OnceLock<NpfBxdf>,
}

#[pymethods]
impl PyModel {
    /// Model(d, s, F, D, G)
    ///
    /// A model from its factors on the isotropic layout with n values per
    /// table: d (3,), s (lobes, 3), F (3, n), D (lobes, n), G (lobes, n);
    /// D on MERL's theta_h nodes, F on theta_d nodes, G Catmull-Rom control
    /// points (see `axes`). Values are stored as float32, as in model files.
    #[new]
    #[pyo3(signature = (d, s, F, D, G))]
    #[allow(non_snake_case)]
    fn py_new(
        d: &Bound<'_, PyAny>,
        s: &Bound<'_, PyAny>,
        F: &Bound<'_, PyAny>,
        D: &Bound<'_, PyAny>,
        G: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let (d, _) = rows::<3>(d, "d")?;
        let (s, _) = rows::<3>(s, "s")?;
        let table = |obj: &Bound<'_, PyAny>, name: &str| -> PyResult<Vec<Vec<f64>>> {
            let a = float_array(obj, name)?;
            let ro = a.readonly();
            let v = ro.as_array();
            if v.ndim() != 2 {
                return Err(value_error(format!(
                    "{name} must be 2-D (rows, n), got shape {:?}",
                    v.shape()
                )));
            }
            let out: Vec<Vec<f64>> = v
                .axis_iter(NdAxis(0))
                .map(|r| r.iter().copied().collect())
                .collect();
            if let Some(i) = out.iter().flatten().position(|x| !x.is_finite()) {
                return Err(value_error(format!("{name} value {i} is not finite")));
            }
            Ok(out)
        };
        let (f, dd, g) = (table(F, "F")?, table(D, "D")?, table(G, "G")?);
        if d.len() != 1 {
            return Err(value_error(format!(
                "d must have shape (3,), got {} rows",
                d.len()
            )));
        }
        if f.len() != 3 {
            return Err(value_error(format!(
                "F must have 3 rows (R, G, B), got {}",
                f.len()
            )));
        }
        let lobes = s.len();
        if dd.len() != lobes || g.len() != lobes {
            return Err(value_error(format!(
                "s, D and G need one row per lobe: {} scales, {} D rows, {} G rows",
                lobes,
                dd.len(),
                g.len()
            )));
        }
        let n = f[0].len();
        if !npf::fit::NODES.contains(&n) {
            return Err(value_error(format!(
                "tables must hold 4 to 90 values, got {n}"
            )));
        }
        for (name, t) in [("F", &f), ("D", &dd), ("G", &g)] {
            if let Some(r) = t.iter().find(|r| r.len() != n) {
                return Err(value_error(format!(
                    "every table needs the same number of values: F has {n}, {name} has {}",
                    r.len()
                )));
            }
        }
        let f32s = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
        let model = CoreModel {
            layout: npf::model::Layout::isotropic(n),
            diffuse: d[0].map(|x| x as f32),
            diffuse_form: Default::default(),
            masking: Default::default(),
            compensation: None,
            fresnel: [f32s(&f[0]), f32s(&f[1]), f32s(&f[2])],
            lobes: s
                .iter()
                .zip(&dd)
                .zip(&g)
                .map(|((s, d), g)| npf::model::Lobe {
                    s: s.map(|x| x as f32),
                    d: f32s(d),
                    g: f32s(g),
                })
                .collect(),
        };
        model.validate().map_err(display_error)?;
        Ok(PyModel::new(ModelFile { model, fit: None }))
    }

    /// Number of parameters the model stores (822 for the default
    /// three-lobe isotropic model).
    #[getter]
    fn num_parameters(&self) -> usize {
        self.model().param_count()
    }

    /// Number of specular lobes.
    #[getter]
    fn lobes(&self) -> usize {
        self.model().lobe_count()
    }

    /// Whether every factor table is 1-D (an isotropic model).
    #[getter]
    fn isotropic(&self) -> bool {
        self.model().layout.is_isotropic()
    }

    /// Lambertian term d_C (1/sr), shape (3,), read-only.
    #[getter]
    fn d<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        read_only(Array1::from_iter(self.model().diffuse.map(f64::from)).into_pyarray(py))
    }

    /// Per-lobe, per-channel scales s_C^m, shape (lobes, 3), read-only.
    #[getter]
    fn s<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let m = self.model();
        let flat = m.lobes.iter().flat_map(|l| l.s.map(f64::from)).collect();
        let a = Array2::from_shape_vec((m.lobe_count(), 3), flat).map_err(display_error)?;
        read_only(a.into_pyarray(py))
    }

    /// Fresnel tables F_C(theta_d), shape (3, n_F), read-only; nodes in
    /// `axes["F"]`.
    #[getter(F)]
    fn fresnel<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = self.model();
        factor_array(
            py,
            m.layout.f,
            m.fresnel.iter().map(|v| v.as_slice()).collect(),
        )
    }

    /// Distributions D^m(theta_h), shape (lobes, n_D) (or (lobes, n_theta,
    /// n_phi) for an anisotropic layout), read-only; nodes in `axes["D"]`.
    #[getter(D)]
    fn distribution<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = self.model();
        factor_array(
            py,
            m.layout.d,
            m.lobes.iter().map(|l| l.d.as_slice()).collect(),
        )
    }

    /// Shadowing G^m(theta) control points, shape (lobes, n_G) (or (lobes,
    /// n_theta, n_phi)), read-only; nodes in `axes["G"]`.
    #[getter(G)]
    fn shadowing<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = self.model();
        factor_array(
            py,
            m.layout.g,
            m.lobes.iter().map(|l| l.g.as_slice()).collect(),
        )
    }

    /// The factor tables' axes: for "D", "F" and "G" a dict with "name" (the
    /// angle the table is indexed by), "theta" (node angles, radians), "kind"
    /// (sqrt_angle, uniform, squared or catmull_rom), and "phi" for a 2-D table.
    #[getter]
    fn axes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let l = self.model().layout;
        let out = PyDict::new(py);
        for (key, name, grid) in [
            ("D", "theta_h", l.d),
            ("F", "theta_d", l.f),
            ("G", "theta", l.g),
        ] {
            let axis = PyDict::new(py);
            axis.set_item("name", name)?;
            let theta: Vec<f64> = (0..grid.n_theta()).map(|k| grid.theta.node(k)).collect();
            axis.set_item("theta", read_only(Array1::from(theta).into_pyarray(py))?)?;
            let kind = match grid.theta {
                npf::grid::Axis::SqrtAngle { .. } => "sqrt_angle",
                npf::grid::Axis::Uniform { .. } => "uniform",
                npf::grid::Axis::CatmullRom { .. } => "catmull_rom",
                npf::grid::Axis::Squared { .. } => "squared",
                npf::grid::Axis::Closed { .. } => "closed",
            };
            axis.set_item("kind", kind)?;
            if let Some(p) = grid.phi {
                let phi: Vec<f64> = (0..p.n).map(|k| p.node(k)).collect();
                axis.set_item("phi", read_only(Array1::from(phi).into_pyarray(py))?)?;
            }
            out.set_item(key, axis)?;
        }
        Ok(out)
    }

    /// The fit's provenance (options, objective, errors) as a dict, or None
    /// (a model read from `.npfb` carries none).
    #[getter]
    fn fit_info(&self, py: Python<'_>) -> PyResult<PyObject> {
        match &self.file.fit {
            Some(info) => json_to_py(py, &serde_json::to_value(info).map_err(display_error)?),
            None => Ok(py.None()),
        }
    }

    /// BRDF values (1/sr) per channel, shape (N, 3), for directions `wi`
    /// (towards the light) and `wo` (towards the viewer), each (N, 3); zero
    /// where either is at or below the horizon. The same values as `npf eval`.
    fn eval(
        &self,
        py: Python<'_>,
        wi: &Bound<'_, PyAny>,
        wo: &Bound<'_, PyAny>,
    ) -> PyResult<PyObject> {
        let (wi, s1) = directions(wi, "wi")?;
        let (wo, s2) = directions(wo, "wo")?;
        same_length(wi.len(), wo.len(), "wi and wo")?;
        let m = self.model();
        let v = py.allow_threads(|| par_zip(&wi, &wo, |wi, wo| m.eval(*wo, *wi)));
        rgb_array(py, v, s1 && s2)
    }

    /// Importance-sample incident directions for view directions `wo`
    /// (N, 3) with random numbers `u` in [0, 1): (N, 3) (component, then the
    /// direction) or (N, 2) (the first number picks the component and is
    /// reused). Returns `(wi, pdf, weight)`: wi (N, 3), pdf (N,) per solid
    /// angle (exactly `pdf(wo, wi)`), weight (N, 3) = f cos(theta_i) / pdf.
    /// Draws below the horizon carry pdf 0 and weight 0.
    fn sample(
        &self,
        py: Python<'_>,
        wo: &Bound<'_, PyAny>,
        u: &Bound<'_, PyAny>,
    ) -> PyResult<(PyObject, PyObject, PyObject)> {
        let (wo, s1) = directions(wo, "wo")?;
        // (N, 3) as is; (N, 2) padded with a NaN in front, which `draw`
        // reads as "pick the component with u1".
        let u: Vec<[f64; 3]> = match rows::<3>(u, "u") {
            Ok((u, _)) => u,
            Err(_) => rows::<2>(u, "u")
                .map_err(|_| {
                    value_error(format!(
                        "u must have shape (N, 2) or (N, 3) of finite floats, got {}",
                        describe(u)
                    ))
                })?
                .0
                .into_iter()
                .map(|r| [f64::NAN, r[0], r[1]])
                .collect(),
        };
        same_length(wo.len(), u.len(), "wo and u")?;
        // Straight into the three outputs (no intermediate draw list).
        type Outputs = (Vec<Vec3>, (Vec<f64>, Vec<[f64; 3]>));
        let (wi, (pdf, weight)): Outputs = py.allow_threads(|| {
            let b = self.bxdf()?;
            Ok::<_, PyErr>(
                wo.par_iter()
                    .zip(u.par_iter())
                    .with_min_len(CHUNK)
                    .map(|(wo, u)| {
                        let d = Self::draw(b, *wo, u);
                        (d.wi, (d.pdf, d.weight))
                    })
                    .unzip(),
            )
        })?;
        Ok((
            rgb_array(py, wi, s1)?,
            scalar_array(py, pdf, s1),
            rgb_array(py, weight, s1)?,
        ))
    }

    /// Density (per solid angle of wi) with which `sample` draws wi given
    /// wo, shape (N,); zero where either direction is at or below the horizon.
    fn pdf(
        &self,
        py: Python<'_>,
        wo: &Bound<'_, PyAny>,
        wi: &Bound<'_, PyAny>,
    ) -> PyResult<PyObject> {
        let (wo, s1) = directions(wo, "wo")?;
        let (wi, s2) = directions(wi, "wi")?;
        same_length(wi.len(), wo.len(), "wo and wi")?;
        let v = py.allow_threads(|| -> PyResult<Vec<f64>> {
            let b = self.bxdf()?;
            Ok(par_zip(&wo, &wi, |wo, wi| b.pdf(*wo, *wi)))
        })?;
        Ok(scalar_array(py, v, s1 && s2))
    }

    /// Directional albedo per channel, shape (N, 3): the integral of
    /// f(wo, wi) cos(theta_i) over the incident hemisphere, by npf's
    /// half-vector quadrature (the albedo `npf compare` reports).
    fn albedo(&self, py: Python<'_>, wo: &Bound<'_, PyAny>) -> PyResult<PyObject> {
        let (wo, single) = directions(wo, "wo")?;
        let m = self.model();
        let v = py.allow_threads(|| {
            wo.iter()
                .map(|w| {
                    if !(w[2] > 0.0) {
                        return [0.0; 3];
                    }
                    let r = w[0].hypot(w[1]);
                    let (cos, sin) = if r > 0.0 {
                        (w[0] / r, w[1] / r)
                    } else {
                        (1.0, 0.0)
                    };
                    bsdf::albedo(w[2].min(1.0).acos(), &Rotated { model: m, cos, sin })
                })
                .collect()
        });
        rgb_array(py, v, single)
    }

    /// The model tabulated as a MERL table: float64 (3, 90, 90, 180),
    /// physical values (1/sr), negative where the cell's node is below the
    /// horizon (as `npf reconstruct`).
    fn reconstruct<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray4<f64>>> {
        let m = self.model();
        let table = py.allow_threads(|| npf::reconstruct::to_merl(m));
        table_to_numpy(py, &table, false)
    }

    /// Write the model as `.json` (with provenance) or `.npfb` (compact
    /// binary), atomically; refuses to replace a file unless `overwrite`.
    #[pyo3(signature = (path, overwrite = false))]
    fn save(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<()> {
        py.allow_threads(|| modelfile::write(&path, &self.file, overwrite))
            .map_err(model_file_error)
    }

    /// Write the model in the format its extension names: `.json`, `.npfb`
    /// (model files) or `.binary` (a MERL table, as `reconstruct`).
    /// `npf.EXPORT_FORMATS` lists what this build supports.
    #[pyo3(signature = (path, overwrite = false))]
    fn export(&self, py: Python<'_>, path: PathBuf, overwrite: bool) -> PyResult<()> {
        py.allow_threads(|| export_to(&self.file, &path, overwrite))
    }

    /// One BRDF value for one direction pair, as floats: the Mitsuba
    /// plugin's scalar path (no arrays).
    fn _eval1(&self, wi: (f64, f64, f64), wo: (f64, f64, f64)) -> (f64, f64, f64) {
        let v = self.model().eval([wo.0, wo.1, wo.2], [wi.0, wi.1, wi.2]);
        (v[0], v[1], v[2])
    }

    /// One pdf value (the plugin's scalar path).
    fn _pdf1(&self, wo: (f64, f64, f64), wi: (f64, f64, f64)) -> PyResult<f64> {
        Ok(self.bxdf()?.pdf([wo.0, wo.1, wo.2], [wi.0, wi.1, wi.2]))
    }

    /// One draw (the plugin's scalar path): (wi, pdf, weight) as tuples.
    #[allow(clippy::type_complexity)]
    fn _sample1(
        &self,
        wo: (f64, f64, f64),
        u: (f64, f64, f64),
    ) -> PyResult<((f64, f64, f64), f64, (f64, f64, f64))> {
        let u = [u.0, u.1, u.2].map(|x| if x.is_finite() { x } else { 0.0 });
        let d = Self::draw(self.bxdf()?, [wo.0, wo.1, wo.2], &u);
        Ok((
            (d.wi[0], d.wi[1], d.wi[2]),
            d.pdf,
            (d.weight[0], d.weight[1], d.weight[2]),
        ))
    }

    /// Seconds the batched kernels alone take on already converted arrays
    /// (eval, sample, pdf; no numpy in or out): what examples/python_bench.py
    /// compares the public calls with, to measure the binding's overhead.
    fn _kernel_seconds(
        &self,
        py: Python<'_>,
        wi: &Bound<'_, PyAny>,
        wo: &Bound<'_, PyAny>,
        u: &Bound<'_, PyAny>,
    ) -> PyResult<(f64, f64, f64)> {
        let (wi, _) = directions(wi, "wi")?;
        let (wo, _) = directions(wo, "wo")?;
        let (u, _) = rows::<3>(u, "u")?;
        same_length(wi.len(), wo.len(), "wi and wo")?;
        same_length(wo.len(), u.len(), "wo and u")?;
        let m = self.model();
        py.allow_threads(|| {
            let b = self.bxdf()?;
            let time = |f: &dyn Fn() -> f64| {
                let t = std::time::Instant::now();
                std::hint::black_box(f());
                t.elapsed().as_secs_f64()
            };
            let e = time(&|| par_zip(&wi, &wo, |wi, wo| m.eval(*wo, *wi)).len() as f64);
            let s = time(&|| {
                par_zip(&wo, &u, |wo, u| Self::draw(b, *wo, u).pdf)
                    .iter()
                    .sum()
            });
            let p = time(&|| par_zip(&wo, &wi, |wo, wi| b.pdf(*wo, *wi)).iter().sum());
            Ok((e, s, p))
        })
    }

    fn __repr__(&self) -> String {
        let m = self.model();
        format!(
            "<npf.Model: {} lobe(s), {} parameters, {}>",
            m.lobe_count(),
            m.param_count(),
            if m.layout.is_isotropic() {
                "isotropic"
            } else {
                "anisotropic"
            }
        )
    }
}

impl PyModel {
    pub(crate) fn new(file: ModelFile) -> Self {
        PyModel {
            file,
            bxdf: OnceLock::new(),
        }
    }

    fn model(&self) -> &CoreModel {
        &self.file.model
    }

    fn bxdf(&self) -> PyResult<&NpfBxdf> {
        if let Some(b) = self.bxdf.get() {
            return Ok(b);
        }
        let b = NpfBxdf::new(self.file.model.clone()).map_err(display_error)?;
        Ok(self.bxdf.get_or_init(|| b))
    }

    /// The draw for one view direction: `u` is (component, u1, u2), or
    /// (NaN, u1, u2) with the component picked by u1 and u1 rescaled within
    /// it (one number does both jobs, stratification intact).
    fn draw(b: &NpfBxdf, wo: Vec3, u: &[f64; 3]) -> BsdfSample {
        let clamp = |x: f64| x.clamp(0.0, 1.0 - f64::EPSILON / 2.0);
        if !u[0].is_nan() {
            return b.sample(wo, clamp(u[0]), [clamp(u[1]), clamp(u[2])]);
        }
        let (u0, u1) = (clamp(u[1]), clamp(u[2]));
        let probs = b.selection_probabilities(wo);
        let mut acc = 0.0;
        let mut rescaled = u0;
        for &p in &probs {
            if p <= 0.0 {
                continue;
            }
            if u0 < acc + p {
                rescaled = ((u0 - acc) / p).clamp(0.0, 1.0 - f64::EPSILON / 2.0);
                break;
            }
            acc += p;
        }
        b.sample(wo, u0, [rescaled, u1])
    }
}

/// Any BSDF seen from a view azimuth rotated to phi = 0, so the albedo
/// quadrature (which places wo in the xz plane) serves any view direction
/// of an anisotropic model too.
pub(crate) struct Rotated<'a> {
    model: &'a CoreModel,
    cos: f64,
    sin: f64,
}

impl Bsdf for Rotated<'_> {
    fn eval(&self, wo: Vec3, wi: Vec3) -> [f64; 3] {
        self.model.eval(self.back(wo), self.back(wi))
    }
    fn sample(&self, _wo: Vec3, _uc: f64, _u: [f64; 2]) -> Option<BsdfSample> {
        None
    }
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f64 {
        0.0
    }
}

impl Rotated<'_> {
    fn back(&self, v: Vec3) -> Vec3 {
        [
            self.cos * v[0] - self.sin * v[1],
            self.sin * v[0] + self.cos * v[1],
            v[2],
        ]
    }
}

/// Export formats of [`PyModel::export`], by extension. The `.bsdf` export
/// of issue 13 joins here: one more arm in `export_to`.
pub(crate) const EXPORT_FORMATS: &[&str] = &["json", "npfb", "binary", "bsdf", "brdf", "glsl", "h"];

pub(crate) fn export_to(file: &ModelFile, path: &Path, overwrite: bool) -> PyResult<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "json" | "npfb" => modelfile::write(path, file, overwrite).map_err(model_file_error),
        "binary" => npf::reconstruct::to_merl(&file.model)
            .write(path, overwrite)
            .map_err(load_error),
        // The renderer exports (RGL tensor file, BRDF Explorer, GLSL, C
        // header) at npf export's default resolutions.
        "bsdf" | "brdf" | "glsl" | "h" => npf::export::export(
            &file.model,
            path,
            &npf::export::ExportOptions::default(),
            overwrite,
        )
        .map(|_| ())
        .map_err(|e| match e {
            npf::export::ExportError::Write(l) => load_error(l),
            other => value_error(format!("{}: {other}", path.display())),
        }),
        _ => Err(value_error(format!(
            "{}: unknown export format (supported: {})",
            path.display(),
            EXPORT_FORMATS
                .iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

pub(crate) fn json_to_py(py: Python<'_>, v: &serde_json::Value) -> PyResult<PyObject> {
    let text = serde_json::to_string(v).map_err(display_error)?;
    Ok(py.import("json")?.call_method1("loads", (text,))?.unbind())
}

/// One factor as an array: D and G per lobe (lobes, n) or (lobes, n_theta,
/// n_phi) for 2-D tables.
pub(crate) fn factor_array<'py>(
    py: Python<'py>,
    grid: npf::grid::Grid,
    tables: Vec<&[f32]>,
) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = tables
        .iter()
        .flat_map(|t| t.iter().map(|&v| v as f64))
        .collect();
    let n = tables.len();
    let a = match grid.phi {
        None => numpy::ndarray::Array::from_shape_vec(vec![n, grid.len()], flat),
        Some(p) => numpy::ndarray::Array::from_shape_vec(vec![n, grid.n_theta(), p.n], flat),
    }
    .map_err(display_error)?;
    Ok(read_only(a.into_pyarray(py))?.into_any())
}

pub(crate) fn describe(obj: &Bound<'_, PyAny>) -> String {
    obj.getattr("shape")
        .map(|s| format!("shape {s}"))
        .unwrap_or_else(|_| "a non-array".into())
}
