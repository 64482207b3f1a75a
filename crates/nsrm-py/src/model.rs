//! `nsrm.fit` and `nsrm.Model`: fitting on arrays, the model file, applying on the CPU fast
//! kernels or the GPU engine.

use crate::arrays;
use crate::errors;
use nsrm::gpu::{Engine, GpuError, GpuOptions};
use nsrm::{FastModel, FitOptions, FitWhite, FrameHighlights, HighlightMode, Kind, Model};
use nsrm::{Normalise, Objective, OutputSpace, Provenance, Ridge, Threads, TrainingSet};
use numpy::PyArrayDyn;
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::Mutex;

/// The default `max_pixels` of `apply`: the CLI's `--max-pixels` default (16384 × 16384).
const DEFAULT_MAX_PIXELS: u64 = nsrm_io::DEFAULT_MAX_PIXELS;

/// A fitted colour-correction model (camera RGB → CIE XYZ).
#[pyclass(name = "Model", module = "nsrm", frozen)]
pub(crate) struct PyModel {
    pub(crate) inner: Model,
    /// The camera RGB of the patches it was fitted on and their white's, when fitted here (the
    /// default training patches of `export`).
    pub(crate) training: Option<Training>,
}

/// Training patches' camera RGB and the white's.
#[derive(Clone)]
pub(crate) struct Training {
    pub(crate) rgb: Vec<[f64; 3]>,
    pub(crate) white_rgb: Option<[f64; 3]>,
}

impl PyModel {
    fn of(inner: Model) -> PyModel {
        PyModel {
            inner,
            training: None,
        }
    }
}

/// The white a `white=` argument names: an `(X, Y, Z)` sequence, or a string `nsrm::parse_white`
/// reads (`X,Y,Z`, `x,y`, an illuminant name such as `D65`).
pub(crate) fn white_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    if let Ok(s) = obj.extract::<String>() {
        return nsrm::parse_white(&s).map_err(|e| errors::input(format!("{what}: {e}")));
    }
    let v: Vec<f64> = obj
        .extract()
        .map_err(|_| errors::input(format!("{what}: expected (X, Y, Z) or a white's name")))?;
    match v[..] {
        [x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) && y > 0.0 => Ok([x, y, z]),
        _ => Err(errors::input(format!(
            "{what}: expected three finite numbers with Y > 0, got {v:?}"
        ))),
    }
}

/// A training set from arrays: `camera_rgb` and `xyz` `(N, 3)`, the XYZ's white.
pub(crate) fn training_set(
    camera_rgb: &Bound<'_, PyAny>,
    xyz: &Bound<'_, PyAny>,
    white: Option<&Bound<'_, PyAny>>,
    white_rgb: Option<&Bound<'_, PyAny>>,
    labels: Option<Vec<String>>,
) -> PyResult<TrainingSet> {
    let rgb = arrays::rows3(camera_rgb, "camera_rgb")?;
    let xyz = arrays::rows3(xyz, "xyz")?;
    if rgb.len() != xyz.len() {
        return Err(errors::input(format!(
            "camera_rgb has {} rows, xyz {}: they must match",
            rgb.len(),
            xyz.len()
        )));
    }
    let white = white.ok_or_else(|| {
        errors::input(
            "white is needed: the white the XYZ are relative to, as (X, Y, Z), \"x,y\" or an \
             illuminant name such as \"D65\" (nsrm fit --white); apply scales it to Y = 1",
        )
    })?;
    let white_xyz = white_arg(white, "white")?;
    let white_rgb = white_rgb
        .map(|w| {
            let v: Vec<f64> = w
                .extract()
                .map_err(|_| errors::input("white_rgb: expected (R, G, B)"))?;
            match v[..] {
                [r, g, b] if [r, g, b].iter().all(|v| v.is_finite()) => Ok([r, g, b]),
                _ => Err(errors::input("white_rgb: expected three finite numbers")),
            }
        })
        .transpose()?;
    let labels = match labels {
        Some(l) if l.len() != rgb.len() => {
            return Err(errors::input(format!(
                "labels: {} of them for {} patches",
                l.len(),
                rgb.len()
            )))
        }
        Some(l) => l,
        None => (1..=rgb.len()).map(|i| i.to_string()).collect(),
    };
    Ok(TrainingSet {
        labels,
        rgb,
        xyz,
        white_xyz,
        white_rgb,
        provenance: Provenance {
            source: "measured".into(),
            patches: Some("numpy arrays (nsrm Python bindings)".into()),
            ..Provenance::default()
        },
    })
}

/// The fit options as `nsrm fit`'s flags give them.
pub(crate) fn fit_options(
    objective: &str,
    preserve_white: bool,
    white_patch: Option<String>,
    ridge: Option<&Bound<'_, PyAny>>,
    normalise: &str,
) -> PyResult<FitOptions> {
    let objective = Objective::parse(objective).map_err(errors::model)?;
    let ridge_text = match ridge {
        None => None,
        Some(r) if r.is_none() => None,
        Some(r) => Some(match r.extract::<f64>() {
            Ok(v) => v.to_string(),
            Err(_) => r.extract::<String>().map_err(|_| {
                errors::input("ridge: expected a number ≥ 0, \"auto\" or \"auto-loo\"")
            })?,
        }),
    };
    let ridge = match &ridge_text {
        Some(s) => Ridge::parse(s).map_err(errors::model)?,
        None => Ridge::None,
    };
    let normalise = Normalise::parse(normalise).map_err(errors::model)?;
    Ok(FitOptions {
        objective,
        preserve_white,
        white: match white_patch {
            Some(l) => FitWhite::Patch(l),
            None => FitWhite::Perfect,
        },
        ridge,
        normalise,
        // As `nsrm fit --ridge 0`: an explicit zero means no ridge anywhere, not even the guard's.
        f32_guard: !(ridge_text.is_some() && ridge == Ridge::None),
        // The guard measures on the CPU kernel here; `nsrm fit` adds the GPU where one is open.
        f32_also: None,
    })
}

/// `white_patch` resolved to a full label (its number or name may be given).
pub(crate) fn resolved(opts: FitOptions, labels: &[String]) -> PyResult<FitOptions> {
    let mut o = opts;
    if let FitWhite::Patch(spec) = &o.white {
        let l = nsrm::resolve_patch(labels, spec)
            .map_err(|e| errors::input(format!("white_patch: {e}")))?;
        o.white = FitWhite::Patch(l);
    }
    Ok(o)
}

/// Fits a model on `camera_rgb` → `xyz` (`(N, 3)` arrays), as `nsrm fit` does.
#[pyfunction]
#[pyo3(signature = (camera_rgb, xyz, kind="nsrm", order=3, *, objective="ls", preserve_white=false,
    ridge=None, white=None, white_patch=None, white_rgb=None, normalise="raw", labels=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    py: Python<'_>,
    camera_rgb: &Bound<'_, PyAny>,
    xyz: &Bound<'_, PyAny>,
    kind: &str,
    order: u8,
    objective: &str,
    preserve_white: bool,
    ridge: Option<&Bound<'_, PyAny>>,
    white: Option<&Bound<'_, PyAny>>,
    white_patch: Option<String>,
    white_rgb: Option<&Bound<'_, PyAny>>,
    normalise: &str,
    labels: Option<Vec<String>>,
) -> PyResult<PyModel> {
    let kind = Kind::parse(kind).map_err(errors::model)?;
    let data = training_set(camera_rgb, xyz, white, white_rgb, labels)?;
    let opts = fit_options(objective, preserve_white, white_patch, ridge, normalise)?;
    let opts = resolved(opts, &data.labels)?;
    let fitted = py
        .detach(|| nsrm::fit_with(kind, order, &data, &opts))
        .map_err(errors::model)?;
    Ok(PyModel {
        inner: fitted.model,
        training: Some(Training {
            rgb: data.rgb,
            white_rgb: data.white_rgb,
        }),
    })
}

/// The GPU engine, opened on first use and kept (with the adapter name it was asked for).
static ENGINE: Mutex<Option<(Option<String>, Engine)>> = Mutex::new(None);

fn gpu_apply(
    model: &Model,
    frame: &mut nsrm::Frame,
    adapter: Option<String>,
) -> Result<(), String> {
    let mut slot = ENGINE.lock().unwrap_or_else(|p| p.into_inner());
    if slot.as_ref().is_none_or(|(a, _)| *a != adapter) {
        *slot = None;
        let opts = GpuOptions {
            adapter: adapter.clone(),
            tile_pixels: None,
        };
        let engine = Engine::new(&opts).map_err(|e| match e {
            GpuError::NoAdapter { .. } | GpuError::AdapterNotFound { .. } => format!("gpu:{e}"),
            other => other.to_string(),
        })?;
        *slot = Some((adapter, engine));
    }
    let (_, engine) = slot.as_mut().expect("opened above");
    engine.apply(model, frame).map_err(|e| e.to_string())
}

#[pymethods]
impl PyModel {
    /// Reads a model file (the JSON `nsrm fit` writes).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<PyModel> {
        Model::load(&path).map(PyModel::of).map_err(errors::model)
    }

    /// Parses a model document (the JSON text of a model file).
    #[staticmethod]
    #[pyo3(signature = (text, origin="<string>"))]
    fn from_json(text: &str, origin: &str) -> PyResult<PyModel> {
        Model::from_json(text, origin)
            .map(PyModel::of)
            .map_err(errors::model)
    }

    /// The model file's JSON text.
    fn to_json(&self) -> String {
        self.inner.to_json()
    }

    /// Writes the model file (the JSON `nsrm apply` reads), through a temporary file in the
    /// same directory renamed over `path`.
    #[pyo3(signature = (path, overwrite=true))]
    fn save(&self, path: PathBuf, overwrite: bool) -> PyResult<()> {
        let err =
            |e: std::io::Error| errors::NsrmError::new_err(format!("{}: {e}", path.display()));
        if !overwrite && path.exists() {
            return Err(errors::input(format!(
                "{}: exists (overwrite=False)",
                path.display()
            )));
        }
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let mut tmp = tempfile::NamedTempFile::new_in(&dir).map_err(err)?;
        std::io::Write::write_all(&mut tmp, self.inner.to_json().as_bytes()).map_err(err)?;
        tmp.persist(&path).map_err(|e| err(e.error))?;
        Ok(())
    }

    /// `"lrm"`, `"prm"`, `"rprm"` or `"nsrm"`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind().name()
    }

    /// The order (LRM: 1).
    #[getter]
    fn order(&self) -> u8 {
        self.inner.order()
    }

    /// The terms' names, in the order of the matrix's columns.
    #[getter]
    fn terms(&self) -> Vec<String> {
        self.inner.term_names()
    }

    /// The coefficient matrix, `(3, L)` float64 (rows X, Y, Z; columns as `terms`).
    #[getter]
    fn matrix<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = self.inner.matrix().to_vec();
        let l = m.len() / 3;
        arrays::out_f64(py, m, &[3, l])
    }

    /// The XYZ of the training white (the model's outputs are divided by its Y).
    #[getter]
    fn white_xyz(&self) -> (f64, f64, f64) {
        let [x, y, z] = self.inner.white_xyz();
        (x, y, z)
    }

    /// The camera RGB gains applied before the terms (1, 1, 1 unless fitted white-balanced).
    #[getter]
    fn input_gains(&self) -> (f64, f64, f64) {
        let [r, g, b] = self.inner.input_gains();
        (r, g, b)
    }

    /// The training patches' labels.
    #[getter]
    fn patches(&self) -> Vec<String> {
        self.inner.patches().to_vec()
    }

    /// The fit's report (objective, ridge λ, in-sample ΔE00, f32 error, …) as a dict, or None.
    #[getter]
    fn fit_report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(r) = self.inner.fit_report() else {
            return Ok(None);
        };
        let text =
            serde_json::to_string(r).map_err(|e| errors::NsrmError::new_err(e.to_string()))?;
        Ok(Some(py.import("json")?.getattr("loads")?.call1((text,))?))
    }

    /// Corrects pixels: `rgb` is `(..., 3)` or `(..., 4)` float32 / float64 linear camera RGB
    /// (alpha untouched); returns float32 of the same shape, as `nsrm apply` writes (into
    /// `out`, a C-contiguous float32 array of that shape other than `rgb`, when given).
    #[pyo3(signature = (rgb, device="cpu", *, output_space="xyz", highlights=None,
        clip_level=None, adapter=None, max_pixels=DEFAULT_MAX_PIXELS, out=None))]
    #[allow(clippy::too_many_arguments)]
    fn apply<'py>(
        &self,
        py: Python<'py>,
        rgb: &Bound<'py, PyAny>,
        device: &str,
        output_space: &str,
        highlights: Option<&str>,
        clip_level: Option<f64>,
        adapter: Option<String>,
        max_pixels: u64,
        out: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let space = OutputSpace::parse(output_space).ok_or_else(|| {
            errors::input(format!(
                "output_space `{output_space}`: expected xyz, linear-srgb, acescg or aces2065-1"
            ))
        })?;
        let mode = highlights
            .map(|h| {
                HighlightMode::parse(h).ok_or_else(|| {
                    errors::input(format!("highlights `{h}`: expected clip or keep"))
                })
            })
            .transpose()?;
        let gpu = match device.to_ascii_lowercase().as_str() {
            "cpu" => false,
            "gpu" => true,
            _ => {
                return Err(errors::input(format!(
                    "device `{device}`: expected cpu or gpu"
                )))
            }
        };
        // As `nsrm apply`: the model with the output space folded in, the highlight policy of
        // the XYZ model for the frame's clip level (arrays record none: `clip_level` gives it).
        let in_space = nsrm::output_model(&self.inner, space).map_err(errors::model)?;
        let policy = FrameHighlights::new(mode, clip_level, &[&self.inner])
            .policy(None, None)
            .map_err(errors::model)?;
        let model = in_space.with_policy(policy);
        let px = arrays::pixels(rgb, "rgb", max_pixels)?;
        let (w, h) = px.size();
        let layout = px.layout();
        let out = out.map(|o| arrays::out_array(&o, &px.shape)).transpose()?;
        if !gpu {
            if let Some(src) = px.contiguous_f32() {
                // Read where numpy keeps it, written into the output: no copy of the input.
                let src = src.as_slice().map_err(|e| errors::input(e.to_string()))?;
                let fast = FastModel::new(&model);
                let run = |dst: &mut [f32]| {
                    py.detach(|| fast.apply_slices(src, dst, layout, Threads::All))
                        .map_err(|e| errors::lib(e, true))
                };
                return match out {
                    Some(o) => {
                        run(arrays::writable(&o)?.as_slice_mut().expect("C-contiguous"))?;
                        Ok(o)
                    }
                    None => {
                        let mut dst = vec![0.0f32; src.len()];
                        run(&mut dst)?;
                        arrays::out_f32(py, dst, &px.shape)
                    }
                };
            }
        }
        let mut frame = nsrm::Frame::from_data(w, h, layout, px.to_vec())
            .ok_or_else(|| errors::input("rgb: size does not match its shape"))?;
        if gpu {
            py.detach(|| gpu_apply(&model, &mut frame, adapter))
                .map_err(|e| match e.strip_prefix("gpu:") {
                    Some(m) => errors::gpu(m.to_string()),
                    None => errors::NsrmError::new_err(e),
                })?;
        } else {
            py.detach(|| FastModel::new(&model).apply(&mut frame, Threads::All));
        }
        match out {
            Some(o) => {
                arrays::writable(&o)?
                    .as_slice_mut()
                    .expect("C-contiguous")
                    .copy_from_slice(&frame.data);
                Ok(o)
            }
            None => arrays::out_f32(py, frame.data, &px.shape),
        }
    }

    /// The f64 reference (`Model::apply_f64`, pixel by pixel, in XYZ): `(..., 3)` → float64.
    fn apply_f64<'py>(
        &self,
        py: Python<'py>,
        rgb: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let (v, shape) = arrays::triples(rgb, "rgb")?;
        let m = &self.inner;
        let out: Vec<f64> = py.detach(|| {
            v.chunks_exact(3)
                .flat_map(|c| m.apply_f64([c[0], c[1], c[2]]))
                .collect()
        });
        arrays::out_f64(py, out, &shape)
    }

    fn __repr__(&self) -> String {
        format!(
            "nsrm.Model(kind={:?}, order={}, terms={})",
            self.inner.kind().name(),
            self.inner.order(),
            self.inner.len_terms()
        )
    }
}
