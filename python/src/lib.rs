//! `robocal._robocal`: the Python module of robocal, a thin layer over the library. Every
//! number is computed by the library; this crate only converts between Python and Rust
//! values, picks the library's entry points as the command line does, and turns the
//! library's errors into Python exceptions carrying the file, line and field.

use pyo3::prelude::*;

mod calibrate;
mod compensate;
mod design;
mod errors;
mod model;
mod simulate;
mod tree;

/// The module `robocal._robocal`.
#[pymodule]
fn _robocal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<model::Model>()?;
    m.add_class::<calibrate::Calibration>()?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate_source, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::measurements_csv, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::table_csv, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::data_kind, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(compensate::compensate, m)?)?;
    m.add_function(wrap_pyfunction!(tree::calibrate_tree, m)?)?;
    m.add_function(wrap_pyfunction!(tree::evaluate_tree, m)?)?;
    m.add_function(wrap_pyfunction!(design::observability, m)?)?;
    m.add_function(wrap_pyfunction!(design::plan, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::studies, m)?)?;
    m.add_function(wrap_pyfunction!(model::presets, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
