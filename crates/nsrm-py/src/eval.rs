//! `nsrm.eval_loo` (as `nsrm eval`), `nsrm.delta_e00` and `nsrm.builtin_training`.

use crate::arrays;
use crate::errors;
use crate::model::{fit_options, resolved, training_set};
use nsrm::{Kind, Protocol};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Leave-one-out (or in-sample) ΔE00 of `kind` at `order` on the patches, as `nsrm eval`: each
/// fold fitted exactly as solved (no f32 guard) unless `f32_guard`. Returns a dict: `mean`,
/// `median`, `p95`, `max`, `per_patch` (float64 array), `labels`, `terms`, `order`, `kind`.
#[pyfunction]
#[pyo3(signature = (camera_rgb, xyz, kind="nsrm", order=3, *, white=None, objective="ls",
    preserve_white=false, ridge=None, white_patch=None, white_rgb=None, normalise="raw",
    labels=None, in_sample=false, f32_guard=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn eval_loo<'py>(
    py: Python<'py>,
    camera_rgb: &Bound<'py, PyAny>,
    xyz: &Bound<'py, PyAny>,
    kind: &str,
    order: u8,
    white: Option<&Bound<'py, PyAny>>,
    objective: &str,
    preserve_white: bool,
    ridge: Option<&Bound<'py, PyAny>>,
    white_patch: Option<String>,
    white_rgb: Option<&Bound<'py, PyAny>>,
    normalise: &str,
    labels: Option<Vec<String>>,
    in_sample: bool,
    f32_guard: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = Kind::parse(kind).map_err(errors::model)?;
    let data = training_set(camera_rgb, xyz, white, white_rgb, labels)?;
    let mut opts = fit_options(objective, preserve_white, white_patch, ridge, normalise)?;
    opts = resolved(opts, &data.labels)?;
    opts.f32_guard = f32_guard;
    let protocol = if in_sample {
        Protocol::InSample
    } else {
        Protocol::LeaveOneOut
    };
    let r = py
        .detach(|| nsrm::evaluate_with(kind, order, &data, protocol, "", &opts))
        .map_err(errors::model)?;
    let d = PyDict::new(py);
    d.set_item("kind", kind.name())?;
    d.set_item("order", r.order)?;
    d.set_item("terms", r.terms)?;
    d.set_item("mean", r.stats.mean)?;
    d.set_item("median", r.stats.median)?;
    d.set_item("p95", r.stats.p95)?;
    d.set_item("max", r.stats.max)?;
    let per: Vec<f64> = r.per_patch.iter().map(|p| p.de00).collect();
    let n = per.len();
    d.set_item("per_patch", arrays::out_f64(py, per, &[n])?)?;
    let labels: Vec<String> = r.per_patch.into_iter().map(|p| p.label).collect();
    d.set_item("labels", labels)?;
    d.set_item("f32_unsafe_fits", r.f32_unsafe_fits)?;
    Ok(d)
}

/// CIEDE2000 ΔE00 between two `(..., 3)` Lab arrays (broadcast together as numpy does);
/// returns `(...)` float64.
#[pyfunction]
pub(crate) fn delta_e00<'py>(
    py: Python<'py>,
    lab1: &Bound<'py, PyAny>,
    lab2: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, numpy::PyArrayDyn<f64>>> {
    // numpy's broadcasting: (N, 3) against (3,), (N, 1, 3) against (M, 3), …
    let both = py
        .import("numpy")?
        .getattr("broadcast_arrays")?
        .call1((lab1, lab2))
        .map_err(|e| errors::input(format!("lab1, lab2: {e}")))?;
    let (a, sa) = arrays::triples(&both.get_item(0)?, "lab1")?;
    let (b, _) = arrays::triples(&both.get_item(1)?, "lab2")?;
    let out: Vec<f64> = py.detach(|| {
        a.chunks_exact(3)
            .zip(b.chunks_exact(3))
            .map(|(x, y)| nsrm::ciede2000([x[0], x[1], x[2]], [y[0], y[1], y[2]]))
            .collect()
    });
    arrays::out_f64(py, out, &sa[..sa.len() - 1])
}

/// A simulated training set from the built-in spectra (or CSV files of the same columns), as
/// `nsrm fit --camera … --illuminant … --reflectances … --patches …` makes: a dict of `labels`, `camera_rgb` `(N, 3)`,
/// `xyz` `(N, 3)` (perfect white Y = 100), `white_xyz`, `white_rgb`.
#[pyfunction]
#[pyo3(signature = (camera="nikon-d5100", illuminant="D65", chart="cc24", *, patches="all"))]
pub(crate) fn builtin_training<'py>(
    py: Python<'py>,
    camera: &str,
    illuminant: &str,
    chart: &str,
    patches: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let data = py
        .detach(|| nsrm::simulate_named(camera, illuminant, chart, &nsrm::Grid::default()))
        .map_err(|e| errors::lib(e, true))?
        .select(patches)
        .map_err(|e| errors::lib(e, true))?;
    let n = data.len();
    let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    let d = PyDict::new(py);
    d.set_item("labels", data.labels.clone())?;
    d.set_item("camera_rgb", arrays::out_f64(py, flat(&data.rgb), &[n, 3])?)?;
    d.set_item("xyz", arrays::out_f64(py, flat(&data.xyz), &[n, 3])?)?;
    d.set_item("white_xyz", data.white_xyz)?;
    d.set_item("white_rgb", data.white_rgb)?;
    Ok(d)
}
