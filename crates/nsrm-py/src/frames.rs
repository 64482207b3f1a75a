//! `nsrm.read_frame`: a frame file decoded to camera RGB, as `nsrm apply` decodes its inputs.

use crate::arrays;
use crate::errors;
use nsrm_io::{Decoded, Limits, ReadOptions};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use std::path::PathBuf;

/// Reads a linear EXR / TIFF or a camera raw file (demosaiced; DNG, CR2, CR3, NEF, ARW, …) as
/// `nsrm apply` does: `(height, width, 3)` float32 camera RGB (an EXR's or TIFF's alpha is
/// not returned).
#[pyfunction]
#[pyo3(signature = (path, *, demosaic="mhc", layer=None, max_pixels=nsrm_io::DEFAULT_MAX_PIXELS))]
pub(crate) fn read_frame<'py>(
    py: Python<'py>,
    path: PathBuf,
    demosaic: &str,
    layer: Option<String>,
    max_pixels: u64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let opts = ReadOptions {
        layer,
        limits: Limits { max_pixels },
        demosaic: crate::chart::demosaic_arg(demosaic)?,
    };
    let d = py.detach(|| Decoded::read(&path, &opts)).map_err(|e| {
        let usage = e.is_usage();
        errors::lib(e, usage)
    })?;
    let f = d.frame;
    let shape = [f.height, f.width, f.layout.channels()];
    arrays::out_f32(py, f.data, &shape)
}
