//! `nsrm.export`: a model as CLF, `.cube`, an OpenColorIO config, a DNG camera profile or an ICC
//! profile, through the library's exporters (as `nsrm export`).

use crate::errors;
use crate::model::{PyModel, Training};
use nsrm::{Model, OutputSpace, Profile, TrainingSet};
use nsrm_export::nodes::Interpolation;
use nsrm_export::shader::ShaderLang;
use nsrm_export::{ExportError, Format, LutOptions};
use nsrm_output::Session;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

fn export_err(e: ExportError) -> PyErr {
    let usage = e.is_usage();
    errors::lib(e, usage)
}

/// The training patches to measure the export on: given, kept from the fit, recorded in the
/// model file (a chart capture), or re-simulated from its provenance (as `nsrm export` does).
fn training(model: &PyModel, given: Option<Vec<[f64; 3]>>) -> PyResult<Training> {
    if let Some(rgb) = given {
        if rgb.iter().flatten().any(|v| !v.is_finite()) || rgb.is_empty() {
            return Err(errors::input(
                "training_rgb: expected finite (N, 3) values, N ≥ 1",
            ));
        }
        return Ok(Training {
            rgb,
            white_rgb: model.training.as_ref().and_then(|t| t.white_rgb),
        });
    }
    if let Some(t) = &model.training {
        return Ok(t.clone());
    }
    let m: &Model = &model.inner;
    let p = m.provenance();
    if let Some(t) = TrainingSet::recorded(p, m.patches()) {
        return Ok(Training {
            rgb: t.rgb,
            white_rgb: t.white_rgb,
        });
    }
    let (Some(camera), Some(ill), Some(refl)) = (&p.camera, &p.illuminant, &p.reflectances) else {
        return Err(errors::input(
            "the model names no spectra to re-simulate its training patches from: pass training_rgb",
        ));
    };
    let strip = |s: &str| s.strip_prefix("builtin:").unwrap_or(s).to_string();
    let grid = nsrm::Grid::parse(p.grid.as_deref().unwrap_or("400:700:10"))
        .map_err(|e| errors::lib(e, true))?;
    let data = nsrm::simulate_named(&strip(camera), &strip(ill), &strip(refl), &grid)
        .map_err(|e| errors::lib(e, false))?
        .select(p.patches.as_deref().unwrap_or("all"))
        .map_err(|e| errors::lib(e, false))?;
    if data.labels != m.patches() {
        return Err(errors::input(
            "the patches re-simulated from the model's provenance are not its training patches: pass training_rgb",
        ));
    }
    Ok(Training {
        rgb: data.rgb,
        white_rgb: data.white_rgb,
    })
}

fn stops_arg(stops: Option<(f64, f64)>, default: [f64; 2]) -> [f64; 2] {
    stops.map_or(default, |(a, b)| [a, b])
}

/// Writes `model` as `format` (`clf`, `cube`, `ocio`, `dcp` or `icc`) to `path`, measuring
/// its error against the model on the training patches and a dense in-gamut set, as `nsrm
/// export`; or as code (`dctl`, or a compute shader in `wgsl`, `glsl`, `hlsl`, `msl`, `spirv`
/// for `layout` `rgb` / `rgba`), the model exactly, as `nsrm export-shader`. Returns a dict:
/// `files`, `max_de00` and `summary` (the error report's line; `None` for code).
#[pyfunction]
#[pyo3(signature = (model, format, path, *, output_space="xyz", lut_size=65, shaper_size=65536,
    stops=None, interpolation="tetrahedral", dcp_map=(600, 55), max_de00=None, training_rgb=None,
    overwrite=true, layout="rgb"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn export<'py>(
    py: Python<'py>,
    model: &PyModel,
    format: &str,
    path: PathBuf,
    output_space: &str,
    lut_size: usize,
    shaper_size: usize,
    stops: Option<(f64, f64)>,
    interpolation: &str,
    dcp_map: (usize, usize),
    max_de00: Option<f64>,
    training_rgb: Option<&Bound<'py, PyAny>>,
    overwrite: bool,
    layout: &str,
) -> PyResult<Bound<'py, PyDict>> {
    if format.eq_ignore_ascii_case("dctl") || ShaderLang::parse(format).is_some() {
        return code(py, model, format, path, output_space, layout, overwrite);
    }
    let fmt = Format::parse(format).ok_or_else(|| {
        errors::input(format!(
            "format `{format}`: expected clf, cube, ocio, dcp, icc, dctl, wgsl, glsl, hlsl, msl or spirv"
        ))
    })?;
    let given = training_rgb
        .map(|t| crate::arrays::rows3(t, "training_rgb"))
        .transpose()?;
    let t = training(model, given)?;
    let m = model.inner.clone();
    let session = Session::new(overwrite);
    let mut unit = session.unit();
    let write_err = |e: nsrm_output::WriteError| {
        let usage = e.is_usage();
        errors::lib(e, usage)
    };
    // Refused before the (slower) build when a file exists and may not be replaced: the
    // output, and for OCIO the CLF written beside it.
    let companion = nsrm_export::companion_path(fmt, &path).map_err(export_err)?;
    for p in std::iter::once(&path).chain(&companion) {
        unit.check_clobber(p).map_err(write_err)?;
    }
    let d = PyDict::new(py);
    let (files, report): (Vec<(PathBuf, Vec<u8>)>, _) = match fmt {
        Format::Icc => {
            let opts = nsrm_export::icc::IccOptions {
                size: lut_size,
                lo: stops_arg(stops, [nsrm_export::icc::DEFAULT_LO, 0.0])[0],
            };
            opts.check()
                .map_err(|e| errors::input(format!("lut_size/stops: {e}")))?;
            let (bytes, w) = py
                .detach(|| nsrm_export::icc::render(&m, opts, &t.rgb, max_de00))
                .map_err(export_err)?;
            (vec![(path.clone(), bytes)], w.report)
        }
        Format::Dcp => {
            let opts = nsrm_export::dcp::DcpOptions {
                hue_divisions: dcp_map.0,
                sat_divisions: dcp_map.1,
            };
            opts.check()
                .map_err(|e| errors::input(format!("dcp_map: {e}")))?;
            let profile = Profile::single(m).map_err(errors::model)?;
            let training = [nsrm_export::dcp::DcpTraining {
                rgb: t.rgb,
                white_rgb: t.white_rgb,
            }];
            let stops = stops_arg(stops, [-6.0, 4.0]);
            let (bytes, w) = py
                .detach(|| nsrm_export::dcp::render(&profile, &training, opts, stops, max_de00))
                .map_err(export_err)?;
            (vec![(path.clone(), bytes)], w.report)
        }
        _ => {
            let space = OutputSpace::parse(output_space).ok_or_else(|| {
                errors::input(format!(
                    "output_space `{output_space}`: expected xyz, linear-srgb, acescg or aces2065-1"
                ))
            })?;
            let interpolation = match interpolation.to_ascii_lowercase().as_str() {
                "tetrahedral" => Interpolation::Tetrahedral,
                "trilinear" => Interpolation::Trilinear,
                _ => {
                    return Err(errors::input(format!(
                        "interpolation `{interpolation}`: expected tetrahedral or trilinear"
                    )))
                }
            };
            let options = LutOptions {
                size: lut_size,
                stops: stops_arg(stops, [-6.0, 4.0]),
                shaper_size,
                interpolation,
            };
            options
                .check()
                .map_err(|e| errors::input(format!("lut_size/shaper_size/stops: {e}")))?;
            let w = py
                .detach(|| nsrm_export::render(&m, fmt, space, options, &t.rgb, max_de00, &path))
                .map_err(export_err)?;
            (w.files, w.report)
        }
    };
    for (p, bytes) in &files {
        unit.write_bytes(p, bytes).map_err(write_err)?;
    }
    unit.commit().map_err(write_err)?;
    let files: Vec<PathBuf> = files.into_iter().map(|(p, _)| p).collect();
    d.set_item("files", files)?;
    d.set_item("max_de00", report.max())?;
    d.set_item("summary", report.summary())?;
    Ok(d)
}

/// `export(format="dctl" | a shader language)`: the model with the output space folded in, as
/// `nsrm export-shader` writes it.
fn code<'py>(
    py: Python<'py>,
    model: &PyModel,
    format: &str,
    path: PathBuf,
    output_space: &str,
    layout: &str,
    overwrite: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let space = OutputSpace::parse(output_space).ok_or_else(|| {
        errors::input(format!(
            "output_space `{output_space}`: expected xyz, linear-srgb, acescg or aces2065-1"
        ))
    })?;
    let layout = nsrm::Layout::parse(layout)
        .ok_or_else(|| errors::input(format!("layout `{layout}`: expected rgb or rgba")))?;
    let m = &model.inner;
    let folded = nsrm::output_model(m, space).map_err(errors::model)?;
    let bytes = match ShaderLang::parse(format) {
        Some(lang) => nsrm_export::shader::export(&folded, layout, lang).map_err(|e| {
            let usage = e.is_usage();
            errors::lib(e, usage)
        })?,
        None => {
            let header = vec![
                format!(
                    "nsrm DCTL: {} to {} ({}), scene-linear, training white at Y = 1 (as nsrm apply --output-space {})",
                    nsrm_export::camera_space_name(m),
                    space.name(),
                    space.interop_id(),
                    space.name()
                ),
                nsrm_export::provenance_line(m),
            ];
            nsrm_export::dctl::generate(&folded, &header)
                .map_err(export_err)?
                .into_bytes()
        }
    };
    Session::new(overwrite)
        .write_bytes(&path, &bytes)
        .map_err(|e| {
            let usage = e.is_usage();
            errors::lib(e, usage)
        })?;
    let d = PyDict::new(py);
    d.set_item("files", vec![path])?;
    d.set_item("max_de00", py.None())?;
    d.set_item("summary", py.None())?;
    Ok(d)
}
