//! `npf._npf`: the Python extension module behind the `npf` package.
//!
//! A thin layer over the npf library: every array is checked here (dtype,
//! shape, finite values) before any work, batched work runs on rayon with
//! the GIL released, and the library's errors become `ValueError` (bad
//! content) or `OSError` (the file system) carrying the library's message.
//! The Python package (`python/npf/`) re-exports this module and adds the
//! Mitsuba plugin; the stubs are in `python/npf/_npf.pyi`.

// `!(x > 0.0)` is deliberate: it also rejects NaN (as in npf::bsdf).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod convert;
mod fitting;
mod model;
mod tables;

use fitting::{fit, from_json, load};
use model::{PyModel, EXPORT_FORMATS};
use pyo3::prelude::*;
use tables::{read_merl, write_merl};

/// npf's compiled core (see the `npf` package).
#[pymodule]
fn _npf(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyModel>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(from_json, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(read_merl, m)?)?;
    m.add_function(wrap_pyfunction!(write_merl, m)?)?;
    m.add(
        "EXPORT_FORMATS",
        EXPORT_FORMATS
            .iter()
            .map(|e| format!(".{e}"))
            .collect::<Vec<_>>(),
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
