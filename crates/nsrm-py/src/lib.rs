//! Python bindings of `nsrm` (issue 39): the extension module `nsrm._nsrm`, which the Python
//! package `nsrm` (`python/nsrm/__init__.py` at the top of the repository) re-exports.
//!
//! Every function is a thin layer over the `nsrm` crate's public API: arrays are checked and
//! converted here ([`arrays`]), the work is done by the library with the GIL released, and the
//! library's errors become Python exceptions ([`errors`]) carrying its messages. No colour
//! maths lives here.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]

use pyo3::prelude::*;

mod arrays;
mod chart;
mod errors;
mod eval;
mod export;
mod frames;
mod model;

/// The native module: `nsrm._nsrm`.
#[pymodule]
fn _nsrm(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<model::PyModel>()?;
    m.add_function(wrap_pyfunction!(model::fit, m)?)?;
    m.add_function(wrap_pyfunction!(eval::eval_loo, m)?)?;
    m.add_function(wrap_pyfunction!(eval::delta_e00, m)?)?;
    m.add_function(wrap_pyfunction!(eval::builtin_training, m)?)?;
    m.add_function(wrap_pyfunction!(chart::read_chart, m)?)?;
    m.add_function(wrap_pyfunction!(export::export, m)?)?;
    m.add_function(wrap_pyfunction!(frames::read_frame, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
