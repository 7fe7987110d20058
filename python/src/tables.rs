//! MERL tables to and from NumPy.

use crate::convert::*;
use npf::loaders::MerlTable;
use numpy::PyArray4;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Read a MERL `.binary` table as a float64 array of shape (3, 90, 90, 180)
/// (channel, theta_h, theta_d, phi_d). Values are physical BRDF values (1/sr)
/// unless `raw`, which gives the file's stored values; a negative value marks
/// a missing cell. Raises OSError when the file cannot be read, ValueError
/// when it is not a MERL table.
#[pyfunction]
#[pyo3(signature = (path, raw = false))]
pub(crate) fn read_merl<'py>(
    py: Python<'py>,
    path: PathBuf,
    raw: bool,
) -> PyResult<Bound<'py, PyArray4<f64>>> {
    let table = py
        .allow_threads(|| MerlTable::read(&path))
        .map_err(load_error)?;
    table_to_numpy(py, &table, raw)
}

/// Write a (3, 90, 90, 180) table as a MERL `.binary` file, atomically.
/// Values are physical (1/sr) unless `raw`; negative values mark missing
/// cells. Refuses to replace an existing file unless `overwrite`.
#[pyfunction]
#[pyo3(signature = (path, table, raw = false, overwrite = false))]
pub(crate) fn write_merl(
    py: Python<'_>,
    path: PathBuf,
    table: &Bound<'_, PyAny>,
    raw: bool,
    overwrite: bool,
) -> PyResult<()> {
    let table = table_from_numpy(table, raw)?;
    py.allow_threads(|| table.write(&path, overwrite))
        .map_err(load_error)
}
