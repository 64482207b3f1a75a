//! `nsrm.read_chart`: a chart read in a photograph, as `nsrm chart extract` reads it.

use crate::arrays;
use crate::errors;
use nsrm_chart::capture::{read, CaptureFrame, FlatField, ReadingOptions};
use nsrm_chart::reference::Reference;
use nsrm_chart::ChartKind;
use nsrm_io::{Demosaic, Encoding, Limits, ReadOptions};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};

/// `corners=`: the CLI's `"X,Y X,Y X,Y X,Y"` or four `(x, y)` pairs.
fn corners_arg(obj: &Bound<'_, PyAny>) -> PyResult<[[f64; 2]; 4]> {
    if let Ok(s) = obj.extract::<String>() {
        return nsrm_chart::parse_corners(&s).map_err(|e| errors::input(format!("corners: {e}")));
    }
    let v: Vec<[f64; 2]> = obj
        .extract()
        .map_err(|_| errors::input("corners: expected \"X,Y X,Y X,Y X,Y\" or four (x, y) pairs"))?;
    let c: [[f64; 2]; 4] = v
        .try_into()
        .map_err(|_| errors::input("corners: expected four (x, y) pairs"))?;
    if c.iter().flatten().any(|v| !v.is_finite()) {
        return Err(errors::input("corners: not finite"));
    }
    Ok(c)
}

pub(crate) fn demosaic_arg(s: &str) -> PyResult<Demosaic> {
    Demosaic::ALL
        .iter()
        .find(|(_, n)| n.eq_ignore_ascii_case(s))
        .map(|(d, _)| *d)
        .ok_or_else(|| errors::input(format!("demosaic `{s}`: expected half, bilinear or mhc")))
}

fn encoding_arg(s: &str) -> PyResult<Encoding> {
    match s.to_ascii_lowercase().as_str() {
        "auto" => Ok(Encoding::Auto),
        "linear" => Ok(Encoding::Linear),
        "srgb" => Ok(Encoding::Srgb),
        _ => Err(errors::input(format!(
            "encoding `{s}`: expected auto, linear or srgb"
        ))),
    }
}

/// What `read_chart` reads: a file, or a frame from an array.
enum Source {
    File(PathBuf),
    Frame(nsrm::Frame),
}

/// An `(H, W, 3)` or `(H, W, 4)` float32/float64 array of linear camera RGB as a frame (alpha
/// dropped), its size checked against `max_pixels` before anything is copied.
fn frame_arg(obj: &Bound<'_, PyAny>, max_pixels: u64) -> PyResult<nsrm::Frame> {
    let px = arrays::pixels(obj, "path", max_pixels).map_err(|_| {
        errors::input(
            "path: expected a file path, or an (H, W, 3) or (H, W, 4) float32/float64 array of linear camera RGB",
        )
    })?;
    if px.shape.len() != 3 {
        return Err(errors::input(format!(
            "path: an array of shape {:?}: expected (H, W, 3) or (H, W, 4)",
            px.shape
        )));
    }
    let (w, h) = px.size();
    let data = px.to_vec();
    let rgb: Vec<f32> = if px.channels == 4 {
        data.chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect()
    } else {
        data
    };
    nsrm::Frame::from_data(w, h, nsrm::Layout::Rgb, rgb)
        .ok_or_else(|| errors::input("path: an empty array"))
}

fn capture_err(e: nsrm_chart::capture::CaptureError) -> PyErr {
    let usage = e.is_usage();
    errors::lib(e, usage)
}

/// The chart in the frame at `path` (camera raw, linear EXR / TIFF, or JPEG / PNG), or in an
/// `(H, W, 3 | 4)` array of linear camera RGB, read as `nsrm chart extract` reads it. Returns a dict: `labels`, `camera_rgb` `(N, 3)`, `xyz`
/// `(N, 3)` (reference, perfect white Y = 100), `std`, `count`, `flags` (per patch, empty when
/// usable), `usable` (bool), `corners` `(4, 2)` (pixels, first patch's corner first, clockwise),
/// `white_xyz` (the reference's white), `training` (the usable patches as
/// `builtin_training` returns them), `csv` (the file `chart extract -o` writes), `report` (the
/// `--json` report).
#[pyfunction]
#[pyo3(signature = (path, chart="cc24", *, reference=None, reference_white=None, corners=None,
    white_level=None, flat=None, encoding="auto", demosaic="half", layer=None,
    max_pixels=nsrm_io::DEFAULT_MAX_PIXELS))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn read_chart<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
    chart: &str,
    reference: Option<String>,
    reference_white: Option<&Bound<'py, PyAny>>,
    corners: Option<&Bound<'py, PyAny>>,
    white_level: Option<f64>,
    flat: Option<String>,
    encoding: &str,
    demosaic: &str,
    layer: Option<String>,
    max_pixels: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let kind = ChartKind::parse(chart).map_err(|e| errors::lib(e, true))?;
    let white = reference_white
        .map(|w| crate::model::white_arg(w, "reference_white"))
        .transpose()?;
    let spec = reference.unwrap_or_else(|| kind.default_reference().to_string());
    let corners = corners.map(corners_arg).transpose()?;
    let read_opts = ReadOptions {
        layer,
        limits: Limits { max_pixels },
        demosaic: demosaic_arg(demosaic)?,
    };
    let encoding = encoding_arg(encoding)?;
    // A file (str or os.PathLike), or an (H, W, 3 | 4) array of linear camera RGB.
    let source = match path.extract::<PathBuf>() {
        Ok(p) => Source::File(p),
        Err(_) => Source::Frame(frame_arg(path, max_pixels)?),
    };
    let cap = py.detach(|| -> Result<_, PyErr> {
        let reference = Reference::load(&spec, kind, white).map_err(|e| errors::lib(e, true))?;
        let frame = std::sync::Arc::new(match source {
            Source::File(p) => CaptureFrame::open(&p, &read_opts, encoding).map_err(capture_err)?,
            Source::Frame(f) => CaptureFrame::from_frame(f, "array"),
        });
        let flat_frame = match flat.as_deref() {
            None => None,
            Some(s) if s.eq_ignore_ascii_case("neutrals") => None,
            Some(f) => Some(
                nsrm_io::display::read_chart_frame(Path::new(f), &read_opts, encoding)
                    .map_err(|e| {
                        let usage = e.is_usage();
                        errors::lib(e, usage)
                    })?
                    .frame,
            ),
        };
        let flat = match (&flat, &flat_frame) {
            (_, Some(f)) => Some(FlatField::Frame(f)),
            (Some(_), None) => Some(FlatField::Neutrals),
            (None, None) => None,
        };
        let opts = ReadingOptions {
            corners,
            white_level,
            flat,
        };
        read(&frame, &reference, &opts).map_err(capture_err)
    })?;
    let patches = &cap.extraction.patches;
    let n = patches.len();
    let flat3 = |f: &dyn Fn(&nsrm_chart::extract::PatchReading) -> [f64; 3]| {
        patches.iter().flat_map(f).collect::<Vec<f64>>()
    };
    let d = PyDict::new(py);
    d.set_item(
        "labels",
        patches.iter().map(|p| p.label.clone()).collect::<Vec<_>>(),
    )?;
    d.set_item(
        "camera_rgb",
        arrays::out_f64(py, flat3(&|p| p.rgb), &[n, 3])?,
    )?;
    d.set_item("xyz", arrays::out_f64(py, flat3(&|p| p.xyz), &[n, 3])?)?;
    d.set_item("std", arrays::out_f64(py, flat3(&|p| p.std), &[n, 3])?)?;
    d.set_item("count", patches.iter().map(|p| p.count).collect::<Vec<_>>())?;
    d.set_item(
        "flags",
        patches
            .iter()
            .map(|p| p.flags.iter().map(|f| f.name()).collect::<Vec<_>>())
            .collect::<Vec<_>>(),
    )?;
    d.set_item(
        "usable",
        patches.iter().map(|p| p.usable()).collect::<Vec<_>>(),
    )?;
    d.set_item("white_xyz", cap.reference.white)?;
    let report = cap.report();
    let json = py.import("json")?.getattr("loads")?;
    let report = json.call1((report.to_string(),))?;
    let np = py.import("numpy")?;
    d.set_item(
        "corners",
        np.getattr("asarray")?
            .call1((report.get_item("corners")?, "float64"))?,
    )?;
    d.set_item("report", report)?;
    d.set_item("csv", cap.to_csv())?;
    let t = cap.training_set();
    let m = t.len();
    let tr = PyDict::new(py);
    tr.set_item("labels", t.labels.clone())?;
    let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    tr.set_item("camera_rgb", arrays::out_f64(py, flat(&t.rgb), &[m, 3])?)?;
    tr.set_item("xyz", arrays::out_f64(py, flat(&t.xyz), &[m, 3])?)?;
    tr.set_item("white_xyz", t.white_xyz)?;
    tr.set_item("white_rgb", t.white_rgb)?;
    d.set_item("training", tr)?;
    Ok(d)
}
