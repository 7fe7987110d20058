//! Loading and fitting: `npf.load`, `npf.from_json`, `npf.fit`.

use crate::convert::*;
use crate::model::*;
use npf::fit::{FitConfig, ModelKind};
use npf::loaders::{LoadError, MeasuredSamples, MerlTable, UtiaTable};
use npf::modelfile::{self, ModelFile};
use npf::samples::Weighting;
use npf::solver::{DiffuseKind, GMethod, SweepReport};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Read a model file (`.json` or `.npfb`). Raises OSError when it cannot be
/// read, ValueError when it is not a valid model file.
#[pyfunction]
pub(crate) fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyModel> {
    let file = py
        .allow_threads(|| modelfile::read(&path))
        .map_err(model_file_error)?;
    Ok(PyModel::new(file))
}

pub(crate) fn parse_name<T: serde::de::DeserializeOwned>(
    value: &str,
    what: &str,
    choices: &str,
) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(value.into()))
        .map_err(|_| value_error(format!("unknown {what} {value:?} (choose {choices})")))
}

/// The samples a fit reads: a path (MERL `.binary`; UTIA `.bin`) or a
/// numpy MERL-shaped table.
/// The samples to fit and, for a MERL input, its table (what the fit's
/// post-fit energy scale and error measures read, as in `npf fit`).
pub(crate) fn fit_samples(
    py: Python<'_>,
    input: &Bound<'_, PyAny>,
) -> PyResult<(MeasuredSamples, Option<MerlTable>)> {
    let (samples, merl) = if input.is_instance_of::<PyString>() || input.hasattr("__fspath__")? {
        let path: PathBuf = input.extract()?;
        let source = path.display().to_string();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        py.allow_threads(|| match ext.as_deref() {
            Some("binary") => MerlTable::read(&path).map(|t| (t.samples(&source), Some(t))),
            // Issue 12 (anisotropic fits) picks its layout here.
            Some("bin") => UtiaTable::read(&path).map(|t| (t.samples(&source), None)),
            _ => Err(LoadError::invalid(
                &path,
                "unknown table format (use a MERL .binary or a UTIA .bin file)",
            )),
        })
        .map_err(load_error)?
    } else {
        let table = table_from_numpy(input, false)?;
        py.allow_threads(|| (table.samples("<numpy table>"), Some(table)))
    };
    if samples.samples.is_empty() {
        return Err(value_error(format!(
            "{}: the table holds no valid samples (all cells missing)",
            samples.source
        )));
    }
    Ok((samples, merl))
}

pub(crate) fn report_dict<'py>(
    py: Python<'py>,
    part: usize,
    r: &SweepReport,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("part", part)?;
    d.set_item("sweep", r.sweep)?;
    d.set_item("objective", r.objective)?;
    d.set_item("rel_decrease", r.rel_decrease)?;
    d.set_item("elapsed", r.elapsed)?;
    d.set_item("extrapolated", r.extrapolated)?;
    d.set_item("revived", r.revived)?;
    d.set_item("smoothing_reverted", r.smoothing_reverted)?;
    Ok(d)
}

#[allow(clippy::too_many_arguments)]
/// Fit a model to a MERL `.binary` file, a UTIA `.bin` file, or a numpy
/// MERL-shaped table (float64 (3, 90, 90, 180), physical 1/sr, negative =
/// missing). Options left as None take npf's defaults (those of `npf fit`).
/// `progress`, if given, is called with a dict after every sweep (part,
/// sweep, objective, rel_decrease, elapsed, ...); an exception it raises is
/// re-raised once the fit ends. `energy_scale` (None: untrusted tables
/// only; True, False) is `npf fit --energy-scale`; `diffuse` is `npf fit
/// --diffuse` (lambert, energy-coupled, oren-nayar or separable). The GIL is released
/// while fitting.
#[pyfunction]
#[pyo3(signature = (table_or_path, lobes = 3, weighting = "compressive", *, model = "factor", nodes = 90,
    epsilon = None, max_theta = None, max_theta_h = None, max_sweeps = None, tol = None, g_method = None,
    smooth_g = None, d_monotone_from = None, accelerate = None, energy_scale = None, threads = 0,
    progress = None, diffuse = "lambert"))]
pub(crate) fn fit(
    py: Python<'_>,
    table_or_path: &Bound<'_, PyAny>,
    lobes: usize,
    weighting: &str,
    model: &str,
    nodes: usize,
    epsilon: Option<f64>,
    max_theta: Option<f64>,
    max_theta_h: Option<f64>,
    max_sweeps: Option<usize>,
    tol: Option<f64>,
    g_method: Option<&str>,
    smooth_g: Option<f64>,
    d_monotone_from: Option<f64>,
    accelerate: Option<bool>,
    energy_scale: Option<bool>,
    threads: usize,
    progress: Option<PyObject>,
    diffuse: &str,
) -> PyResult<PyModel> {
    let d = FitConfig::default();
    let config = FitConfig {
        model: parse_name::<ModelKind>(model, "model", "factor, independent-g or ggx")?,
        lobes,
        nodes,
        weighting: parse_name::<Weighting>(
            weighting,
            "weighting",
            "compressive, cosine-l2 or uniform",
        )?,
        epsilon: epsilon.unwrap_or(d.epsilon),
        max_theta: max_theta.unwrap_or(d.max_theta),
        max_theta_h: max_theta_h.unwrap_or(d.max_theta_h),
        max_sweeps: max_sweeps.unwrap_or(d.max_sweeps),
        tol: tol.unwrap_or(d.tol),
        g_method: match g_method {
            Some(g) => parse_name::<GMethod>(g, "g_method", "cubic, golden or fixed")?,
            None => d.g_method,
        },
        smooth_g: smooth_g.or(d.smooth_g),
        d_monotone_from: d_monotone_from.or(d.d_monotone_from),
        accelerate: accelerate.unwrap_or(d.accelerate),
        threads,
        diffuse: parse_name::<DiffuseKind>(
            diffuse,
            "diffuse",
            "lambert, energy-coupled, oren-nayar or separable",
        )?,
        coarse: d.coarse.clone(),
        coarse_tol: d.coarse_tol,
        gauss_newton: d.gauss_newton,
        energy_scale,
        // The remaining options (grazing taper, masking, compensation) at
        // the library's defaults.
        ..d
    };
    for (name, v) in [
        ("epsilon", config.epsilon),
        ("max_theta", config.max_theta),
        ("max_theta_h", config.max_theta_h),
        ("tol", config.tol),
    ] {
        if !v.is_finite() {
            return Err(value_error(format!(
                "{name} must be a finite number, got {v}"
            )));
        }
    }
    if let Some(cb) = &progress {
        if !cb.bind(py).is_callable() {
            return Err(PyTypeError::new_err(
                "progress must be a callable (it receives each sweep's report dict)",
            ));
        }
    }
    if threads > MAX_THREADS {
        return Err(value_error(format!(
            "threads must be 0 (all cores) to {MAX_THREADS}, got {threads}"
        )));
    }
    if config.model == ModelKind::Auto {
        return Err(value_error(
            "model \"auto\" is not in the Python package yet: use `npf fit --model auto`",
        ));
    }
    // Checked before reading the input, so a bad option costs nothing.
    config.validate().map_err(display_error)?;
    let (samples, merl) = fit_samples(py, table_or_path)?;
    let callback_error: Mutex<Option<PyErr>> = Mutex::new(None);
    let fitted = py.allow_threads(|| {
        let mut observer = |part: usize, r: &SweepReport| {
            let Some(cb) = &progress else { return };
            Python::with_gil(|py| {
                let mut slot = callback_error.lock().unwrap_or_else(|p| p.into_inner());
                if slot.is_some() {
                    return;
                }
                let result = report_dict(py, part, r).and_then(|d| cb.call1(py, (d,)).map(drop));
                if let Err(e) = result.and_then(|_| py.check_signals()) {
                    *slot = Some(e);
                }
            });
        };
        match merl {
            Some(t) => npf::fit::fit_owned(
                samples,
                || Ok(npf::loaders::Table::Merl(t)),
                &config,
                &mut observer,
            ),
            None => npf::fit::fit(&samples, &config, &mut observer),
        }
    });
    if let Some(e) = callback_error
        .into_inner()
        .unwrap_or_else(|p| p.into_inner())
    {
        return Err(e);
    }
    let fitted = fitted.map_err(display_error)?;
    Ok(PyModel::new(ModelFile {
        model: fitted.result.model,
        fit: Some(fitted.info),
    }))
}

/// A model from the text of a `.json` model file.
#[pyfunction]
pub(crate) fn from_json(text: &str) -> PyResult<PyModel> {
    modelfile::from_json(text, Path::new("<string>"))
        .map(PyModel::new)
        .map_err(model_file_error)
}
