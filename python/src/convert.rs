//! Errors and arrays at the boundary: library errors as Python exceptions,
//! NumPy arrays checked (dtype, shape, finite) and converted.

use npf::loaders::geometry::Vec3;
use npf::loaders::{LoadError, MerlTable};
use npf::modelfile::ModelFileError;
use numpy::ndarray::{Array1, Array2, Array4, ArrayView2, Axis as NdAxis};
use numpy::{
    IntoPyArray, PyArray4, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyOSError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

/// MERL table shape as numpy sees it: channel, theta_h, theta_d, phi_d.
pub(crate) const MERL_SHAPE: [usize; 4] = [
    3,
    MerlTable::RES_THETA_H,
    MerlTable::RES_THETA_D,
    MerlTable::RES_PHI_D,
];

/// Most fit threads accepted: more is a mistake, not a configuration.
pub(crate) const MAX_THREADS: usize = 1024;

/// Rows per rayon task: large enough that scheduling costs nothing next to
/// the kernels, small enough that two cores share a batch evenly.
pub(crate) const CHUNK: usize = 4096;

pub(crate) fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// File-system failures are `OSError` (with errno, so `FileNotFoundError`
/// and friends match); everything about a file's content is `ValueError`.
pub(crate) fn load_error(e: LoadError) -> PyErr {
    match &e {
        LoadError::Io { source, .. } => {
            let msg = e.to_string();
            match source.raw_os_error() {
                Some(errno) => PyOSError::new_err((errno, msg)),
                None => PyOSError::new_err(msg),
            }
        }
        LoadError::Exists { .. } => PyOSError::new_err((17, e.to_string())),
        // A directory (EISDIR, so IsADirectoryError matches), FIFO, device
        // or dangling link where a file was expected: a file-system matter.
        LoadError::NotRegular { kind, .. } => {
            let errno = if kind.contains("directory") { 21 } else { 22 };
            PyOSError::new_err((errno, e.to_string()))
        }
        _ => value_error(e.to_string()),
    }
}

pub(crate) fn model_file_error(e: ModelFileError) -> PyErr {
    match e {
        ModelFileError::Io(e) => load_error(e),
        other => value_error(other.to_string()),
    }
}

pub(crate) fn display_error(e: impl std::fmt::Display) -> PyErr {
    value_error(e.to_string())
}

/// Any float array (or nested sequence) as a float64 numpy array; other
/// dtypes are refused with `TypeError` rather than silently converted.
pub(crate) fn float_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    if let Ok(a) = obj.downcast::<PyArrayDyn<f64>>() {
        return Ok(a.clone());
    }
    let py = obj.py();
    let array = if let Ok(u) = obj.downcast::<PyUntypedArray>() {
        u.clone().into_any()
    } else {
        // A sequence (nested lists of numbers): numbers of any kind are
        // meant as floats; only numpy arrays have a dtype to check.
        let kwargs = PyDict::new(py);
        kwargs.set_item("dtype", "float64")?;
        py.import("numpy")?
            .call_method("asarray", (obj,), Some(&kwargs))
            .map_err(|_| {
                PyTypeError::new_err(format!(
                    "{name} must be a numpy array of floats (or a nested sequence of numbers)"
                ))
            })?
    };
    let u = array.downcast::<PyUntypedArray>()?;
    let kind = u.dtype().kind();
    if kind != b'f' {
        return Err(PyTypeError::new_err(format!(
            "{name} must hold floats (float32 or float64), got dtype {}",
            u.dtype()
        )));
    }
    let converted = u.call_method1("astype", ("float64",))?;
    Ok(converted.downcast::<PyArrayDyn<f64>>()?.clone())
}

/// Rows of an (N, k) float array (a single row of shape (k,) is N = 1),
/// copied out, every value finite.
pub(crate) fn rows<const K: usize>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<(Vec<[f64; K]>, bool)> {
    let a = float_array(obj, name)?;
    let ro = a.readonly();
    let v = ro.as_array();
    let (single, view): (bool, ArrayView2<f64>) = match v.ndim() {
        1 if v.len() == K => (
            true,
            v.into_shape_with_order((1, K)).map_err(display_error)?,
        ),
        2 if v.shape()[1] == K => (false, v.into_dimensionality().map_err(display_error)?),
        _ => {
            return Err(value_error(format!(
                "{name} must have shape (N, {K}), got {:?}",
                v.shape()
            )))
        }
    };
    let out: Vec<[f64; K]> = match view.as_slice() {
        // C-contiguous (what numpy makes by default): one pass over memory.
        Some(flat) => flat
            .chunks_exact(K)
            .map(|r| std::array::from_fn(|k| r[k]))
            .collect(),
        None => view
            .axis_iter(NdAxis(0))
            .map(|r| std::array::from_fn(|k| r[k]))
            .collect(),
    };
    if let Some(i) = out.iter().position(|r| r.iter().any(|x| !x.is_finite())) {
        return Err(value_error(format!(
            "{name} row {i} is not finite: {:?}",
            out[i]
        )));
    }
    Ok((out, single))
}

/// Unit directions: rows of an (N, 3) array, normalised; a zero-length row
/// has no direction and is refused.
pub(crate) fn directions(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<Vec3>, bool)> {
    let (mut v, single) = rows::<3>(obj, name)?;
    for (i, d) in v.iter_mut().enumerate() {
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(len > 1e-300) {
            return Err(value_error(format!("{name} row {i} has zero length")));
        }
        if (len - 1.0).abs() > 1e-15 {
            *d = d.map(|x| x / len);
        }
    }
    Ok((v, single))
}

pub(crate) fn same_length(a: usize, b: usize, what: &str) -> PyResult<()> {
    if a == b {
        Ok(())
    } else {
        Err(value_error(format!(
            "{what} have different lengths: {a} and {b}"
        )))
    }
}

/// An (N, 3) result, or (3,) when the input was one direction.
pub(crate) fn rgb_array(py: Python<'_>, v: Vec<[f64; 3]>, single: bool) -> PyResult<PyObject> {
    let a = Array2::from(v);
    if single {
        Ok(a.row(0).to_owned().into_pyarray(py).into_any().unbind())
    } else {
        Ok(a.into_pyarray(py).into_any().unbind())
    }
}

pub(crate) fn scalar_array(py: Python<'_>, v: Vec<f64>, single: bool) -> PyObject {
    if single {
        v[0].into_pyobject(py).expect("a float").into_any().unbind()
    } else {
        Array1::from(v).into_pyarray(py).into_any().unbind()
    }
}

pub(crate) fn read_only<'py, T>(a: Bound<'py, T>) -> PyResult<Bound<'py, T>> {
    a.as_any().getattr("flags")?.setattr("writeable", false)?;
    Ok(a)
}

/// Runs `f` on every pair of elements in parallel (an indexed collect:
/// results are written in place).
pub(crate) fn par_zip<A: Sync, B: Sync, U: Send>(
    a: &[A],
    b: &[B],
    f: impl Fn(&A, &B) -> U + Sync,
) -> Vec<U> {
    a.par_iter()
        .zip(b.par_iter())
        .with_min_len(CHUNK)
        .map(|(a, b)| f(a, b))
        .collect()
}

pub(crate) fn table_to_numpy<'py>(
    py: Python<'py>,
    table: &MerlTable,
    raw: bool,
) -> PyResult<Bound<'py, PyArray4<f64>>> {
    let data: Vec<f64> = if raw {
        table.raw().to_vec()
    } else {
        table
            .raw()
            .chunks(MerlTable::CELLS)
            .zip(MerlTable::SCALE)
            .flat_map(|(c, s)| c.iter().map(move |v| v * s))
            .collect()
    };
    let a = Array4::from_shape_vec(MERL_SHAPE, data).map_err(display_error)?;
    Ok(a.into_pyarray(py))
}

/// A (3, 90, 90, 180) numpy table (physical 1/sr unless `raw`; negative
/// marks a missing cell) as a MERL table; NaN and infinities are refused.
pub(crate) fn table_from_numpy(obj: &Bound<'_, PyAny>, raw: bool) -> PyResult<MerlTable> {
    let a = float_array(obj, "table")?;
    let ro = a.readonly();
    let v = ro.as_array();
    if v.shape() != MERL_SHAPE {
        return Err(value_error(format!(
            "a MERL table has shape (3, 90, 90, 180) (channel, theta_h, theta_d, phi_d), got {:?}",
            v.shape()
        )));
    }
    let mut data = Vec::with_capacity(3 * MerlTable::CELLS);
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            let (c, cell) = (i / MerlTable::CELLS, i % MerlTable::CELLS);
            return Err(value_error(format!(
                "table value is NaN or infinite (channel {c}, cell {cell})"
            )));
        }
        data.push(if raw {
            *x
        } else {
            x / MerlTable::SCALE[i / MerlTable::CELLS]
        });
    }
    Ok(MerlTable::from_raw(data))
}
