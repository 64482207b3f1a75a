//! The exceptions: `nsrm.NsrmError` (the base of every error the library reports),
//! `nsrm.InputError` (also a `ValueError`: a bad argument or array) and `nsrm.GpuUnavailableError`
//! (also a `RuntimeError`: no GPU adapter could be opened).

use pyo3::exceptions::{PyException, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

pyo3::create_exception!(
    nsrm,
    NsrmError,
    PyException,
    "The base of every error nsrm raises; its message is the library's."
);

static INPUT_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static GPU_ERROR: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// A class named `name` deriving from `NsrmError` and `other` (made with `type()`, as a
/// Python `class name(NsrmError, other)` statement would).
fn subclass<'py>(
    py: Python<'py>,
    name: &str,
    other: Bound<'py, PyType>,
    doc: &str,
) -> PyResult<Bound<'py, PyType>> {
    let ns = PyDict::new(py);
    ns.set_item("__module__", "nsrm")?;
    ns.set_item("__doc__", doc)?;
    let bases = PyTuple::new(py, [py.get_type::<NsrmError>(), other])?;
    let t = py
        .import("builtins")?
        .getattr("type")?
        .call1((name, bases, ns))?;
    Ok(t.cast_into::<PyType>()?)
}

fn input_error(py: Python<'_>) -> PyResult<&Py<PyType>> {
    INPUT_ERROR.get_or_try_init(py, || {
        subclass(
            py,
            "InputError",
            py.get_type::<PyValueError>(),
            "A bad argument or array (wrong shape, dtype, size, or a number out of range).",
        )
        .map(Bound::unbind)
    })
}

fn gpu_error(py: Python<'_>) -> PyResult<&Py<PyType>> {
    GPU_ERROR.get_or_try_init(py, || {
        subclass(
            py,
            "GpuUnavailableError",
            py.get_type::<PyRuntimeError>(),
            "device=\"gpu\" was asked for and no GPU adapter could be opened.",
        )
        .map(Bound::unbind)
    })
}

/// Adds the exception classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("NsrmError", py.get_type::<NsrmError>())?;
    m.add("InputError", input_error(py)?.bind(py))?;
    m.add("GpuUnavailableError", gpu_error(py)?.bind(py))?;
    Ok(())
}

/// An `InputError` with `msg`.
pub(crate) fn input(msg: impl Into<String>) -> PyErr {
    let msg = msg.into();
    Python::attach(|py| match input_error(py) {
        Ok(t) => PyErr::from_type(t.bind(py).clone(), msg),
        Err(e) => e,
    })
}

/// A `GpuUnavailableError` with `msg`.
pub(crate) fn gpu(msg: impl Into<String>) -> PyErr {
    let msg = msg.into();
    Python::attach(|py| match gpu_error(py) {
        Ok(t) => PyErr::from_type(t.bind(py).clone(), msg),
        Err(e) => e,
    })
}

/// A library error: an `InputError` when the library says it is the caller's (a usage error),
/// else an `NsrmError`. The message is the error and its sources, as the CLI prints them.
pub(crate) fn lib(err: impl std::error::Error + 'static, usage: bool) -> PyErr {
    let mut msg = err.to_string();
    let mut src = err.source();
    while let Some(e) = src {
        let s = e.to_string();
        if !msg.contains(&s) {
            msg.push_str(": ");
            msg.push_str(&s);
        }
        src = e.source();
    }
    if usage {
        input(msg)
    } else {
        NsrmError::new_err(msg)
    }
}

/// [`lib`] for the model errors (usage as [`nsrm::ModelError::is_usage`] says).
pub(crate) fn model(err: nsrm::ModelError) -> PyErr {
    let usage = err.is_usage();
    lib(err, usage)
}
