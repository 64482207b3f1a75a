//! The studio's state: the frames opened (each with its reading settings, its reading and its
//! last fit) and what the API computes from them. Every number comes from the code the CLI runs:
//! the reading from [`CaptureOptions::read`] (as `chart extract`), the fit from `fit_with` on
//! the capture's training set (as `fit --capture`), the comparison from `evaluate_with` (as `eval
//! --capture`), the exports from the library's in-memory `render` functions (the bytes `export`
//! writes).
//!
//! Why one file (about 1,250 lines): the studio's state is one lock per frame, and every API answer
//! (reading, fit, comparison, previews, exports) is computed under it from the same settings; the
//! HTTP side is `http.rs`, the server `server.rs`, the requests and answers (typed) `wire.rs`, the
//! tests `session_tests.rs`.

use super::super::capture::{self, Capture, CaptureOptions};
use super::super::common::UsageError;
use super::http::{BadRequest, NotFound, Target};
use super::wire::{self, Comparison, Evaluated, FitAnswer, FitRequest, Flat, Named, PatchFit};
use super::wire::{Settings, State};
use anyhow::{bail, Context, Result};
use nsrm::gpu::{DeviceChoice, Engine, GpuOptions, Opened};
use nsrm::Kind;
use nsrm::{apply_mat3 as mat_apply, OutputSpace};
use nsrm::{delta_e00_xyz, output_matrix, srgb8, to_linear_srgb};
use nsrm::{evaluate_with, Protocol, Stats};
use nsrm::{fit_with, FitOptions, FitReport, FitWhite, Normalise, Objective, Ridge};
use nsrm::{Frame, Layout, Model};
use nsrm_chart::capture::{CaptureFrame, FlatField, ReadingOptions};
use nsrm_export::{render, Format, LutOptions};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

/// Frames held at once; opening another closes the oldest.
const MAX_OPEN: usize = 6;

/// The export formats the page offers: those the library's `Format::parse` knows (formats other
/// parts of nsrm add appear here once `parse` accepts them).
const FORMAT_CANDIDATES: [&str; 6] = ["clf", "cube", "ocio", "dcp", "icc", "icm"];

/// The built-in references (`--reference`).
fn references() -> Vec<&'static str> {
    nsrm_chart::reference::Reference::builtin_names()
}

pub(crate) struct Studio {
    pub(crate) token: String,
    pub(crate) port: u16,
    /// The frames named on the command line: the only paths the server reads besides uploads.
    pub(crate) files: Vec<PathBuf>,
    /// The per-run temporary directory: the only place the server writes.
    pub(crate) tmp: PathBuf,
    pub(crate) max_pixels: u64,
    /// Where corrected previews are computed (`--device`), and the engine once opened.
    device: DeviceChoice,
    engine: Mutex<Option<ServerDevice>>,
    frames: Mutex<Vec<(String, Arc<FrameSlot>)>>,
    next: AtomicU64,
    /// The handler slots (`--threads`).
    pub(crate) slots: super::server::Slots,
}

/// The server's device for corrected previews, opened on first use with the policy of `apply`:
/// `auto` takes a hardware GPU and else the CPU, `gpu` any adapter (or the preview fails),
/// `cpu` the CPU.
enum ServerDevice {
    Gpu(Box<Engine>),
    /// The CPU, and why (asked for, no adapter, only a software rasteriser).
    Cpu(String),
}

/// Where a corrected preview was computed: `gpu` or `cpu`, and the adapter or the reason.
pub(crate) struct Computed {
    pub(crate) device: &'static str,
    pub(crate) detail: String,
}

/// One open frame.
pub(crate) struct FrameSlot(Mutex<FrameState>);

impl FrameSlot {
    pub(crate) fn lock_state(&self) -> MutexGuard<'_, FrameState> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl FitRequest {
    /// The fit options the request names, checked as `fit` checks its flags.
    fn options(&self) -> Result<FitOptions> {
        let white_patch = self.white_patch.clone().filter(|s| !s.trim().is_empty());
        if white_patch.is_some() && !self.preserve_white && self.normalise == Normalise::Raw {
            bail!(UsageError(
                "--white-patch needs --preserve-white or --normalise white-balanced".into(),
            ));
        }
        Ok(FitOptions {
            objective: self.objective,
            preserve_white: self.preserve_white,
            white: white_patch.map_or(FitWhite::Perfect, FitWhite::Patch),
            ridge: self.ridge.unwrap_or(Ridge::None),
            normalise: self.normalise,
            // An explicit ridge of 0 means no ridge anywhere: not even the f32 guard's.
            f32_guard: self.ridge != Some(Ridge::None),
            f32_also: None,
        })
    }

    /// The variant flags as `fit`/`eval` take them.
    fn flags(&self) -> Vec<String> {
        let mut v = Vec::new();
        if self.objective != Objective::LeastSquares {
            v.push(format!("--objective {}", quote(&self.objective.name())));
        }
        if self.preserve_white {
            v.push("--preserve-white".into());
        }
        if let Some(p) = self.white_patch.as_deref().filter(|s| !s.trim().is_empty()) {
            v.push(format!("--white-patch {}", quote(p)));
        }
        if let Some(r) = &self.ridge {
            v.push(format!("--ridge {}", quote(&r.name_of())));
        }
        if self.normalise != Normalise::Raw {
            v.push(format!("--normalise {}", quote(self.normalise.name())));
        }
        v
    }
}

/// The last fit of a frame.
pub(crate) struct Fitted {
    pub(crate) request: FitRequest,
    pub(crate) model: Model,
    pub(crate) report: FitReport,
}

pub(crate) struct FrameState {
    pub(crate) id: String,
    /// The file read: a listed file, or the upload's copy in the temporary directory.
    pub(crate) path: PathBuf,
    /// How the command line names the frame (the listed path, or the uploaded file's name).
    pub(crate) shown: String,
    pub(crate) uploaded: bool,
    pub(crate) width: usize,
    pub(crate) height: usize,
    pub(crate) preview_png: Vec<u8>,
    /// Frame pixels per preview pixel.
    pub(crate) preview_scale: usize,
    /// The frame box-filtered to the preview's size (linear camera RGB), for corrected previews.
    pub(crate) small: Frame,
    /// The decoded frame (read and hashed once; every reading is taken from it) and the EXR
    /// layer it was decoded with.
    frame: Arc<CaptureFrame>,
    frame_layer: Option<String>,
    /// The decoded flat frame last used (`flat` setting of a listed file), by the setting.
    flat_cache: Option<(Flat, Arc<Frame>)>,
    /// An uploaded flat frame (its file name and pixels): the `upload` flat setting.
    flat_upload: Option<(String, Arc<Frame>)>,
    /// An uploaded reference file (its file name and the server's copy): the `upload` reference
    /// setting.
    reference_upload: Option<(String, PathBuf)>,
    pub(crate) settings: Settings,
    pub(crate) capture: Option<Capture>,
    pub(crate) error: Option<String>,
    pub(crate) fitted: Option<Fitted>,
    max_pixels: u64,
    files: Vec<PathBuf>,
}

fn random_hex(bytes: usize) -> Result<String> {
    let mut b = vec![0u8; bytes];
    getrandom::fill(&mut b).map_err(|e| anyhow::anyhow!("the system's random source: {e}"))?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

impl Studio {
    pub(crate) fn new(
        files: Vec<PathBuf>,
        port: u16,
        max_pixels: u64,
        device: DeviceChoice,
        threads: usize,
    ) -> Result<Studio> {
        let token = random_hex(16)?;
        let tmp = std::env::temp_dir().join(format!(
            "nsrm-studio-{}-{}",
            std::process::id(),
            random_hex(4)?
        ));
        let mut b = std::fs::DirBuilder::new();
        #[cfg(unix)]
        {
            use std::os::unix::fs::DirBuilderExt;
            b.mode(0o700);
        }
        b.create(&tmp)
            .with_context(|| format!("creating the temporary directory {}", tmp.display()))?;
        Ok(Studio {
            token,
            port,
            files,
            tmp,
            max_pixels,
            device,
            engine: Mutex::new(None),
            frames: Mutex::new(Vec::new()),
            next: AtomicU64::new(1),
            slots: super::server::Slots::new(threads),
        })
    }

    /// Removes the temporary directory (on exit).
    pub(crate) fn cleanup(&self) {
        let _ = std::fs::remove_dir_all(&self.tmp);
    }

    /// The largest upload: a frame at the pixel limit as 4 channels of f32, plus headers.
    pub(crate) fn max_upload_bytes(&self) -> u64 {
        self.max_pixels.saturating_mul(16).saturating_add(1 << 20)
    }

    pub(crate) fn new_id(&self) -> String {
        format!("f{}", self.next.fetch_add(1, Ordering::SeqCst))
    }

    /// A fresh id and its directory for an upload.
    pub(crate) fn new_upload_dir(&self) -> Result<(PathBuf, String)> {
        let id = self.new_id();
        let dir = self.tmp.join(&id);
        std::fs::create_dir(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok((dir, id))
    }

    /// A fresh directory for a file uploaded for frame `id`, a flat frame or a reference (`what`;
    /// removed with the frame).
    pub(crate) fn new_frame_dir(&self, id: &str, what: &str) -> Result<PathBuf> {
        let dir = self.tmp.join(id).join(format!(
            "{what}-{}",
            self.next.fetch_add(1, Ordering::SeqCst)
        ));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(dir)
    }

    pub(crate) fn info(&self) -> wire::Info {
        wire::Info {
            version: env!("CARGO_PKG_VERSION"),
            files: (self.files.iter().enumerate())
                .map(|(index, p)| wire::ListedFile {
                    index,
                    name: p.display().to_string(),
                })
                .collect(),
            charts: nsrm_chart::ChartKind::ALL.map(|k| k.name()).to_vec(),
            references: references(),
            formats: formats(),
            spaces: OutputSpace::ALL.iter().map(|(_, n)| *n).collect(),
            kinds: Kind::ALL.map(Kind::name).to_vec(),
            max_pixels: self.max_pixels,
            max_upload_bytes: self.max_upload_bytes(),
            server_device: self.device.name(),
        }
    }

    /// Applies `model` to `frame` on the server's device (opened on first use); where it ran.
    pub(crate) fn correct(&self, model: &Model, frame: &mut Frame) -> Result<Computed> {
        let mut dev = self.engine.lock().unwrap_or_else(|e| e.into_inner());
        if dev.is_none() {
            let opts = GpuOptions {
                adapter: None,
                tile_pixels: None,
            };
            *dev = Some(match nsrm::gpu::open_device(self.device, &opts) {
                Ok(Opened::Gpu(e)) => ServerDevice::Gpu(e),
                Ok(Opened::Cpu(why)) => ServerDevice::Cpu(why.to_string()),
                // `gpu` asked for and none opened: said on every preview, tried again next time.
                Err(e) => bail!("the server's GPU: {e}"),
            });
        }
        match dev.as_mut() {
            Some(ServerDevice::Gpu(e)) => {
                // Under `auto` a GPU that fails falls back to the CPU (for this preview and the
                // rest of the run, saying why); under `gpu` its failure is the answer.
                let keep = (self.device == DeviceChoice::Auto).then(|| frame.clone());
                match e.apply(model, frame) {
                    Ok(()) => Ok(Computed {
                        device: "gpu",
                        detail: e.adapter_name(),
                    }),
                    Err(err) => match keep {
                        None => bail!("the server's GPU: {err}"),
                        Some(original) => {
                            let why = format!(
                                "the GPU {} failed ({err}); the CPU corrects instead",
                                e.adapter_name()
                            );
                            eprintln!("nsrm studio: {why}");
                            *frame = original;
                            model.apply_frame(frame);
                            *dev = Some(ServerDevice::Cpu(why.clone()));
                            Ok(Computed {
                                device: "cpu",
                                detail: why,
                            })
                        }
                    },
                }
            }
            Some(ServerDevice::Cpu(why)) => {
                model.apply_frame(frame);
                Ok(Computed {
                    device: "cpu",
                    detail: why.clone(),
                })
            }
            None => bail!("the server's device was not opened"),
        }
    }

    pub(crate) fn frame(&self, id: &str) -> Result<Arc<FrameSlot>> {
        let frames = self.frames.lock().unwrap_or_else(|e| e.into_inner());
        frames
            .iter()
            .find(|(i, _)| i == id)
            .map(|(_, f)| Arc::clone(f))
            .ok_or_else(|| {
                NotFound(format!(
                    "no open frame `{id}` (closed, or the studio was restarted): open it again"
                ))
                .into()
            })
    }

    pub(crate) fn close(&self, id: &str) -> Result<()> {
        let mut frames = self.frames.lock().unwrap_or_else(|e| e.into_inner());
        let i = frames
            .iter()
            .position(|(i, _)| i == id)
            .ok_or_else(|| NotFound(format!("no open frame `{id}`")))?;
        frames.remove(i);
        let _ = std::fs::remove_dir_all(self.tmp.join(id));
        Ok(())
    }

    /// Opens `path` (read as `chart extract` reads it) under `id`, reads its chart with the
    /// default settings, and returns its state.
    pub(crate) fn open(&self, id: String, path: PathBuf, uploaded: bool) -> Result<State> {
        let r = self.open_inner(&id, path, uploaded);
        if r.is_err() && uploaded {
            let _ = std::fs::remove_dir_all(self.tmp.join(&id));
        }
        let slot = r?;
        let state = slot.lock_state().state();
        let mut frames = self.frames.lock().unwrap_or_else(|e| e.into_inner());
        while frames.len() >= MAX_OPEN {
            let (old, _) = frames.remove(0);
            let _ = std::fs::remove_dir_all(self.tmp.join(&old));
        }
        frames.push((id, slot));
        Ok(state)
    }

    fn open_inner(&self, id: &str, path: PathBuf, uploaded: bool) -> Result<Arc<FrameSlot>> {
        // Read as the chart is read: one pixel per 2×2 block of a raw frame, a camera JPEG/PNG
        // decoded with the sRGB transfer function. Decoded and hashed once: every reading of
        // the chart (a corner drag, an exclusion) is taken from this frame.
        let decoded = open_frame(&path, None, self.max_pixels)?;
        let frame = decoded.frame();
        let img = nsrm_chart::overlay::picture(frame, None);
        let scale = frame.width.div_ceil(img.width().max(1) as usize).max(1);
        let preview_png = nsrm_chart::overlay::encode(&img)?;
        let small = downsample(frame, scale);
        let shown = if uploaded {
            path.file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        } else {
            path.display().to_string()
        };
        let mut st = FrameState {
            id: id.to_string(),
            path,
            shown,
            uploaded,
            width: frame.width,
            height: frame.height,
            preview_png,
            preview_scale: scale,
            small,
            frame: decoded,
            frame_layer: None,
            flat_cache: None,
            flat_upload: None,
            reference_upload: None,
            settings: Settings::default(),
            capture: None,
            error: None,
            fitted: None,
            max_pixels: self.max_pixels,
            files: self.files.clone(),
        };
        st.read();
        // Shown white-balanced as the overlay is: on the chart's neutrals once it is read (the
        // grey world of the frame until then, or when no chart is found).
        if let Some(c) = &st.capture {
            let img = nsrm_chart::overlay::picture(st.frame.frame(), Some(&c.extraction));
            st.preview_png = nsrm_chart::overlay::encode(&img)?;
        }
        Ok(Arc::new(FrameSlot(Mutex::new(st))))
    }
}

fn formats() -> Vec<&'static str> {
    FORMAT_CANDIDATES
        .iter()
        .copied()
        .filter(|f| Format::parse(f).is_some())
        .collect()
}

/// Decodes `path` as `chart extract` reads it by default (raw: half; JPEG/PNG: sRGB-decoded),
/// with a message for the page when it cannot.
fn open_frame(path: &Path, layer: Option<String>, max_pixels: u64) -> Result<Arc<CaptureFrame>> {
    CaptureFrame::open(
        path,
        &nsrm_io::ReadOptions {
            layer,
            limits: nsrm_io::Limits { max_pixels },
            demosaic: nsrm_io::Demosaic::Half,
        },
        nsrm_io::display::Encoding::Auto,
    )
    .map(Arc::new)
    .map_err(|e| {
        BadRequest(format!(
            "{}: not a frame nsrm can read: {e}",
            path.file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        ))
        .into()
    })
}

/// `frame` box-filtered by `s` (RGB).
fn downsample(frame: &Frame, s: usize) -> Frame {
    let s = s.max(1);
    let (w, h) = ((frame.width / s).max(1), (frame.height / s).max(1));
    let ch = frame.layout.channels();
    let mut data = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0.0f64; 3];
            let mut n = 0.0;
            for yy in y * s..((y + 1) * s).min(frame.height) {
                for xx in x * s..((x + 1) * s).min(frame.width) {
                    let p = &frame.data[(yy * frame.width + xx) * ch..][..3];
                    for c in 0..3 {
                        acc[c] += p[c] as f64;
                    }
                    n += 1.0;
                }
            }
            let n = f64::max(n, 1.0);
            data.extend(acc.iter().map(|v| (v / n) as f32));
        }
    }
    Frame::from_data(w, h, Layout::Rgb, data).unwrap_or_else(|| Frame::new(1, 1, Layout::Rgb))
}

/// A word for a POSIX shell: as it is when safe, else in single quotes.
pub(crate) fn quote(s: &str) -> String {
    if !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "._/:,=+-@%".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// sRGB 8-bit of an XYZ (white Y = 100 relative to `white`), for swatches.
fn xyz_srgb8(xyz: [f64; 3], white: [f64; 3]) -> [u8; 3] {
    let m = output_matrix(white, OutputSpace::LinearSrgb);
    mat_apply(&m, xyz).map(srgb8)
}

fn parse_space(s: &str) -> Result<OutputSpace> {
    OutputSpace::parse(s).ok_or_else(|| {
        BadRequest(format!(
            "output space `{s}`: one of {}",
            OutputSpace::ALL
                .iter()
                .map(|(_, n)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ))
        .into()
    })
}

/// A request never names a file: the reference is one of the built-ins or `upload` (a file
/// uploaded for this frame), the reference white a number triple or pair, `D50` or an
/// illuminant's built-in name. (Refused before anything is looked up, so that the answer tells
/// nothing of the files on this machine.)
fn check_no_path(s: &Settings) -> Result<()> {
    if let Some(r) = s.reference.as_deref().filter(|r| !r.trim().is_empty()) {
        let r = r.trim();
        let builtin = references();
        if r != "upload" && !builtin.iter().any(|b| b.eq_ignore_ascii_case(r)) {
            bail!(BadRequest(format!(
                "reference: one of {}, or upload (a reference file uploaded for this frame; the page reads no file a request names)",
                builtin.join(", ")
            )));
        }
    }
    if let Some(w) = s
        .reference_white
        .as_deref()
        .filter(|w| !w.trim().is_empty())
    {
        let w = w.trim();
        let numbers = w.contains(',')
            && w.split(',')
                .all(|p| p.trim().parse::<f64>().is_ok_and(f64::is_finite));
        if !numbers && !w.eq_ignore_ascii_case("d50") && !nsrm::Illuminant::is_builtin(w) {
            bail!(BadRequest(
                "reference white: X,Y,Z, x,y, D50 or a built-in illuminant's name (the page reads no file a request names)".into()
            ));
        }
    }
    Ok(())
}

impl FrameState {
    /// The capture options these settings name (the CLI's flags, checked the same way).
    fn options(&self) -> Result<CaptureOptions> {
        let s = &self.settings;
        check_no_path(s)?;
        let flat = match s.flat {
            None | Some(Flat::None) => None,
            Some(Flat::Neutrals) => Some("neutrals".to_string()),
            Some(Flat::Upload) => Some(
                self.flat_upload
                    .as_ref()
                    .map(|(name, _)| name.clone())
                    .ok_or_else(|| BadRequest("flat `upload`: no flat frame uploaded".into()))?,
            ),
            Some(Flat::File(i)) => {
                let p = self
                    .files
                    .get(i)
                    .ok_or_else(|| BadRequest(format!("flat `file:{i}`: no listed file {i}")))?;
                Some(p.display().to_string())
            }
        };
        if let Some(c) = &s.corners {
            if c.iter().flatten().any(|v| !v.is_finite()) {
                bail!(BadRequest("corners: not finite numbers".into()));
            }
        }
        let reference = match s.reference.as_deref().map(str::trim) {
            None | Some("") => None,
            Some("upload") => Some(
                self.reference_upload
                    .as_ref()
                    .map(|(_, p)| p.display().to_string())
                    .ok_or_else(|| {
                        BadRequest("reference `upload`: no reference file uploaded".into())
                    })?,
            ),
            Some(r) => Some(r.to_string()),
        };
        Ok(CaptureOptions {
            chart: Some(s.chart.into()),
            reference,
            reference_white: s.reference_white.clone().filter(|r| !r.trim().is_empty()),
            corners: s.corners.map(corners_text),
            layer: s.layer.clone().filter(|r| !r.trim().is_empty()),
            white_level: s.white_level,
            flat,
            encoding: capture::EncodingArg::Auto,
            demosaic: nsrm_io::Demosaic::Half,
            max_pixels: crate::values::MaxPixelsArg {
                max_pixels: self.max_pixels,
            },
        })
    }

    /// Reads the chart with the current settings (as `chart extract` does), from the decoded
    /// frame.
    fn read(&mut self) {
        self.fitted = None;
        match self.read_inner() {
            Ok(c) => {
                self.capture = Some(c);
                self.error = None;
            }
            Err(e) => {
                self.capture = None;
                self.error = Some(explain_for_page(e));
            }
        }
    }

    fn read_inner(&mut self) -> Result<Capture> {
        let o = self.options()?;
        let reference = o.the_reference()?;
        let layer = o.layer.clone();
        if layer != self.frame_layer {
            // Another EXR layer: the only setting that needs the file decoded again.
            self.frame = open_frame(&self.path, layer.clone(), self.max_pixels)?;
            self.frame_layer = layer;
        }
        let flat = match self.settings.flat {
            None | Some(Flat::None) => None,
            Some(Flat::Upload) => self
                .flat_upload
                .as_ref()
                .map(|(_, ff)| FlatField::Frame(ff)),
            Some(Flat::Neutrals) => Some(FlatField::Neutrals),
            Some(file @ Flat::File(_)) => {
                if self.flat_cache.as_ref().is_none_or(|(k, _)| *k != file) {
                    self.flat_cache = None;
                    let ff = o.flat_frame()?.ok_or_else(|| {
                        BadRequest(format!(
                            "flat `{}`: not a flat frame",
                            o.flat.as_deref().unwrap_or_default()
                        ))
                    })?;
                    self.flat_cache = Some((file, Arc::new(ff)));
                }
                self.flat_cache.as_ref().map(|(_, ff)| FlatField::Frame(ff))
            }
        };
        let opts = ReadingOptions {
            corners: self.settings.corners,
            white_level: self.settings.white_level,
            flat,
        };
        Ok(nsrm_chart::capture::read(&self.frame, &reference, &opts)?)
    }

    /// An uploaded reference file (read as `--reference` reads one, for the frame's chart and
    /// reference white) becomes the reference → a new reading. A file nsrm cannot read as a
    /// reference is refused, named by its upload name (never the server's path).
    pub(crate) fn set_reference_upload(&mut self, path: &Path) -> Result<()> {
        let name = path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut o = self.options()?;
        o.reference = Some(path.display().to_string());
        if let Err(e) = o.the_reference() {
            let why = format!("{e:#}").replace(&path.display().to_string(), &name);
            bail!(BadRequest(format!(
                "{name}: not a reference nsrm can read for this chart: {why}"
            )));
        }
        self.reference_upload = Some((name, path.to_path_buf()));
        self.settings.reference = Some("upload".into());
        self.read();
        Ok(())
    }

    /// An uploaded flat frame (decoded as `--flat` reads one) becomes the flat field → a new
    /// reading.
    pub(crate) fn set_flat_upload(&mut self, path: &Path) -> Result<()> {
        let name = path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let ff = nsrm_io::read_frame(
            path,
            &nsrm_io::ReadOptions {
                limits: nsrm_io::Limits {
                    max_pixels: self.max_pixels,
                },
                demosaic: nsrm_io::Demosaic::Half,
                ..Default::default()
            },
        )
        .map_err(|e| BadRequest(format!("{name}: not a flat frame nsrm can read: {e}")))?;
        self.flat_upload = Some((name, Arc::new(ff)));
        self.settings.flat = Some(Flat::Upload);
        self.read();
        Ok(())
    }

    /// New settings → a new reading.
    pub(crate) fn set_reading(&mut self, _studio: &Studio, body: Value) -> Result<()> {
        let s: Settings = serde_json::from_value(body)
            .map_err(|e| BadRequest(format!("reading settings: {e}")))?;
        if s.exclude.len() > 10_000 {
            bail!(BadRequest("exclude: too many labels".into()));
        }
        let old = std::mem::replace(&mut self.settings, s);
        if let Err(e) = self.options() {
            self.settings = old;
            return Err(e);
        }
        self.read();
        if let Some(c) = &self.capture {
            for l in &self.settings.exclude {
                if !c.extraction.patches.iter().any(|p| &p.label == l) {
                    bail!(BadRequest(format!("exclude: no patch `{l}` on this chart")));
                }
            }
        }
        Ok(())
    }

    /// Usable patches minus those excluded by hand, as a `--patches` spec (`all` when none is).
    fn patches_spec(&self, c: &Capture) -> String {
        let ex = &self.settings.exclude;
        let usable: Vec<&str> = c
            .extraction
            .patches
            .iter()
            .filter(|p| p.usable())
            .map(|p| p.label.as_str())
            .collect();
        if !usable.iter().any(|l| ex.iter().any(|e| e == l)) {
            return "all".into();
        }
        usable
            .into_iter()
            .filter(|l| !ex.iter().any(|e| e == l))
            .collect::<Vec<_>>()
            .join(",")
    }

    fn capture(&self) -> Result<&Capture> {
        self.capture.as_ref().ok_or_else(|| {
            BadRequest(format!(
                "no reading of the chart yet: {}",
                self.error.as_deref().unwrap_or("not read")
            ))
            .into()
        })
    }

    fn fitted(&self) -> Result<&Fitted> {
        self.fitted
            .as_ref()
            .ok_or_else(|| BadRequest("fit a model first".into()).into())
    }

    /// The frame's state as the page shows it.
    pub(crate) fn state(&self) -> State {
        State {
            id: self.id.clone(),
            name: self.shown.clone(),
            source: if self.uploaded { "upload" } else { "file" },
            width: self.width,
            height: self.height,
            preview: wire::Preview {
                url: format!("/api/frames/{}/preview.png", self.id),
                scale: self.preview_scale,
            },
            settings: self.settings.clone(),
            error: self.error.clone(),
            reading: self.capture.as_ref().map(|c| c.report()),
            patches_spec: self.capture.as_ref().map(|c| self.patches_spec(c)),
            flat_upload: self.flat_upload.as_ref().map(|(name, _)| name.clone()),
            reference_upload: self.reference_upload.as_ref().map(|(name, _)| name.clone()),
            fitted: self.fitted.as_ref().map(|f| wire::FittedBrief {
                kind: f.model.kind().to_string(),
                order: f.model.order(),
                report: f.report.clone(),
            }),
            command: self.command_text("clf", "xyz"),
        }
    }

    pub(crate) fn overlay_png(&self) -> Result<Vec<u8>> {
        let c = self.capture()?;
        let sw = self.fitted.as_ref().map(|f| capture::swatches(c, &f.model));
        let img = nsrm_chart::overlay::render(
            c.frame.frame(),
            Some(&c.extraction),
            &[],
            sw.as_deref().map(|s| (s, c.reference.white)),
        );
        Ok(nsrm_chart::overlay::encode(&img)?)
    }

    /// Fits as `fit --capture` does; the model file's text, its report and its errors.
    pub(crate) fn fit(&mut self, body: Value) -> Result<FitAnswer> {
        let req: FitRequest =
            serde_json::from_value(body).map_err(|e| BadRequest(format!("fit request: {e}")))?;
        let kind = req.kind;
        if !(1..=4).contains(&req.order) {
            bail!(UsageError(format!(
                "order {} is out of range (1..4)",
                req.order
            )));
        }
        let opts = req.options()?;
        if opts.normalise == Normalise::WhiteBalanced && kind != Kind::Nsrm {
            bail!(UsageError(format!(
                "normalise white-balanced is defined for NSRM only, not {kind}"
            )));
        }
        let c = self.capture()?;
        let spec = self.patches_spec(c);
        let data = c.training_set().select(&spec)?;
        let fitted = fit_with(kind, req.order, &data, &opts).with_context(|| {
            format!(
                "fitting {kind} order {} on {} patches",
                req.order,
                data.len()
            )
        })?;
        let white = c.reference.white;
        let mut de = Vec::with_capacity(data.len());
        let patches: Vec<PatchFit> = data
            .labels
            .iter()
            .zip(&data.rgb)
            .zip(&data.xyz)
            .map(|((l, rgb), xyz)| {
                let out = fitted.apply_f64(*rgb);
                let d = delta_e00_xyz(out, *xyz, data.white_xyz);
                de.push(d);
                PatchFit {
                    label: l.clone(),
                    rgb: *rgb,
                    reference_xyz: *xyz,
                    corrected_xyz: out,
                    reference_srgb8: xyz_srgb8(*xyz, white),
                    corrected_srgb8: xyz_srgb8(out, white),
                    de00: d,
                }
            })
            .collect();
        let stats = Stats::of(&de);
        let model_text = fitted.model.to_json();
        let model: Value = serde_json::from_str(&model_text)?;
        let (order, terms) = (fitted.model.order(), fitted.model.len_terms());
        self.fitted = Some(Fitted {
            request: req,
            model: fitted.model,
            report: fitted.report.clone(),
        });
        Ok(FitAnswer {
            model,
            kind: kind.to_string(),
            order,
            terms,
            report: fitted.report,
            n_patches: data.len(),
            patches_spec: spec,
            in_sample: stats,
            patches,
            command: self.command_text("clf", "xyz"),
        })
    }

    /// Leave-one-out and in-sample ΔE00 of every kind and order with the request's variant (as
    /// `eval --capture … --orders 1-4` and with `--in-sample`), and the best by leave-one-out
    /// mean.
    ///
    /// In two steps so that the frame is not held while the models are evaluated (seconds to
    /// minutes on an SG): [`compare_plan`](Self::compare_plan) takes what the comparison needs
    /// under the frame's lock, [`ComparePlan::run`] computes without it.
    pub(crate) fn compare_plan(&self, body: Value) -> Result<ComparePlan> {
        let req: FitRequest = serde_json::from_value(body)
            .map_err(|e| BadRequest(format!("compare request: {e}")))?;
        let custom = req.options()?;
        let c = self.capture()?;
        let data = c.training_set().select(&self.patches_spec(c))?;
        let command_head = format!(
            "nsrm eval --capture {} {}{}",
            quote(&self.shown),
            self.capture_flags().join(" "),
            self.patches_flag(&req.flags()),
        );
        Ok(ComparePlan {
            custom,
            data,
            command_head,
        })
    }
}

/// A comparison of every kind and order, ready to run without the frame's lock.
pub(crate) struct ComparePlan {
    custom: nsrm::FitOptions,
    data: nsrm::TrainingSet,
    command_head: String,
}

impl ComparePlan {
    pub(crate) fn run(self) -> Comparison {
        let ComparePlan {
            custom,
            data,
            command_head,
        } = self;
        let mut best: Option<wire::Best> = None;
        // The orders each kind could be fitted at (leave-one-out), for the command lines.
        let mut fitted_orders: Vec<(Kind, Vec<u8>)> = Vec::new();
        let mut evaluate = |protocol: Protocol| {
            let mut results: Vec<Evaluated> = Vec::new();
            for kind in Kind::ALL {
                let mut done = Vec::new();
                let mut ok_orders = Vec::new();
                for order in 1..=4u8 {
                    let eff = kind.effective_order(order);
                    if done.contains(&eff) {
                        continue;
                    }
                    done.push(eff);
                    let mut o = custom.clone();
                    if kind != Kind::Nsrm {
                        o.normalise = Normalise::Raw;
                    }
                    // As `nsrm eval`: the paper's method, the fits as solved.
                    o.f32_guard = false;
                    match evaluate_with(kind, order, &data, protocol, "capture", &o) {
                        Ok(r) => {
                            if protocol == Protocol::LeaveOneOut
                                && best.as_ref().is_none_or(|b| r.stats.mean < b.mean)
                            {
                                best = Some(wire::Best {
                                    model: r.model.clone(),
                                    order: r.order,
                                    mean: r.stats.mean,
                                });
                            }
                            ok_orders.push(eff);
                            results.push(Evaluated::Done(r));
                        }
                        Err(e) => results.push(Evaluated::Failed {
                            model: kind.name().into(),
                            order: eff,
                            error: e.to_string(),
                        }),
                    }
                }
                if protocol == Protocol::LeaveOneOut && !ok_orders.is_empty() {
                    fitted_orders.push((kind, ok_orders));
                }
            }
            results
        };
        let leave_one_out = evaluate(Protocol::LeaveOneOut);
        let in_sample = evaluate(Protocol::InSample);
        let lines: Vec<String> = fitted_orders
            .iter()
            .map(|(kind, orders)| {
                format!(
                    "{command_head} --kinds {} --orders {} --json",
                    kind.name(),
                    orders
                        .iter()
                        .map(|o| o.to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                )
            })
            .collect();
        Comparison {
            leave_one_out,
            in_sample,
            best,
            n_patches: data.len(),
            command: lines.join("\n"),
        }
    }
}

impl FrameState {
    /// ` --patches … --variant-flags` for `fit`/`eval`.
    fn patches_flag(&self, variant: &[String]) -> String {
        let mut s = String::new();
        if let Some(c) = &self.capture {
            let spec = self.patches_spec(c);
            if spec != "all" {
                s.push_str(&format!(" --patches {}", quote(&spec)));
            }
        }
        for f in variant {
            s.push(' ');
            s.push_str(f);
        }
        s
    }

    /// `model` with the highlight policy `apply` gives this frame by default: clipped to white
    /// at a camera raw file's clip level, kept in other frames (no level known).
    fn with_highlights(&self, model: &Model) -> Result<Model> {
        let clip = self.frame.camera().and_then(|c| c.clip_level);
        let h = nsrm::FrameHighlights::new(None, None, &[model]);
        Ok(model.clone().with_policy(h.policy(clip, None)?))
    }

    /// The corrected preview in `space` (sRGB PNG), computed on the server's device (`--device`),
    /// and where it was computed.
    pub(crate) fn corrected_png(
        &self,
        studio: &Studio,
        space: &str,
    ) -> Result<(Vec<u8>, Computed)> {
        let space = parse_space(space)?;
        let f = self.fitted()?;
        let out = nsrm::output_model(&self.with_highlights(&f.model)?, space)?;
        let mut frame = self.small.clone();
        let computed = studio.correct(&out, &mut frame)?;
        let png =
            nsrm_io::preview::encode_png(&frame, &to_linear_srgb(f.model.white_xyz(), space))?;
        Ok((png, computed))
    }

    /// The generated WGSL (the model with `space` folded in, as `export-shader --lang wgsl
    /// --layout rgb --output-space`) and the matrix from `space` to linear sRGB.
    pub(crate) fn wgsl(&self, space: &str) -> Result<wire::Shader> {
        let space = parse_space(space)?;
        let f = self.fitted()?;
        let out = nsrm::output_model(&self.with_highlights(&f.model)?, space)?;
        let wgsl = nsrm::gpu::baked_wgsl(&out, Layout::Rgb);
        Ok(wire::Shader {
            wgsl,
            to_linear_srgb: to_linear_srgb(f.model.white_xyz(), space),
            width: self.small.width,
            height: self.small.height,
            workgroup_size: 256,
        })
    }

    /// The preview-size linear frame as little-endian f32 RGB.
    pub(crate) fn preview_pixels(&self) -> (Vec<u8>, usize, usize) {
        let mut b = Vec::with_capacity(self.small.data.len() * 4);
        for v in &self.small.data {
            b.extend_from_slice(&v.to_le_bytes());
        }
        (b, self.small.width, self.small.height)
    }

    pub(crate) fn model_json(&self) -> Result<String> {
        Ok(self.fitted()?.model.to_json())
    }

    pub(crate) fn patches_csv(&self) -> Result<String> {
        let c = self.capture()?;
        Ok(c.to_csv())
    }

    /// Exports the last fit as `export --model model.json --training patches.csv` does: the
    /// file's bytes and its name.
    pub(crate) fn export(&self, t: &Target) -> Result<(Vec<u8>, String)> {
        let fname = t.param("format").unwrap_or("clf");
        let format = Format::parse(fname).ok_or_else(|| {
            BadRequest(format!("format `{fname}`: one of {}", formats().join(", ")))
        })?;
        let space = parse_space(t.param("space").unwrap_or("xyz"))?;
        let mut options = LutOptions::default();
        if let Some(n) = t.param("lut_size") {
            options.size = n
                .parse()
                .map_err(|_| BadRequest(format!("lut_size `{n}`: a whole number")))?;
        }
        if let Err(e) = options.check() {
            bail!(BadRequest(format!("lut_size: {e}")));
        }
        let f = self.fitted()?;
        let c = self.capture()?;
        // The training patches `chart extract -o patches.csv` writes (every usable patch; the
        // CSV's numbers are exact decimal round trips).
        let training = c.extraction.training_set(&c.reference);
        let name = format!("model.{}", format.name());
        // Built in memory by the library, as the CLI's `export` builds it before writing.
        let bytes = if format == Format::Dcp {
            // As `export --format dcp` does for a one-illuminant model file: the model as a
            // profile, its training patches, the default map and stops, no accuracy limit.
            let profile = nsrm::Profile::single(f.model.clone())?;
            let t = nsrm_export::dcp::DcpTraining {
                rgb: training.rgb.clone(),
                white_rgb: training.white_rgb,
            };
            let dcp = nsrm_export::dcp::DcpOptions::default();
            nsrm_export::dcp::render(&profile, &[t], dcp, options.stops, None)?.0
        } else if format == Format::Icc {
            // As `export --format icc` does: the LUT size asked for, the default stops.
            let icc = nsrm_export::icc::IccOptions {
                size: options.size,
                lo: nsrm_export::icc::DEFAULT_LO,
            };
            nsrm_export::icc::render(&f.model, icc, &training.rgb, None)?.0
        } else {
            // The file the page downloads (for OCIO, the config; its CLF is named in it).
            let out = Path::new(&name);
            let r = render(&f.model, format, space, options, &training.rgb, None, out)?;
            r.files
                .into_iter()
                .find(|(p, _)| p == out)
                .map(|(_, b)| b)
                .ok_or_else(|| anyhow::anyhow!("the export wrote no {name}"))?
        };
        Ok((bytes, name))
    }

    /// The capture flags of the current settings.
    fn capture_flags(&self) -> Vec<String> {
        let s = &self.settings;
        let mut v = vec![format!("--chart {}", s.chart.name())];
        match s.reference.as_deref().map(str::trim) {
            None | Some("") => {}
            Some("upload") => {
                if let Some((name, _)) = &self.reference_upload {
                    v.push(format!("--reference {}", quote(name)));
                }
            }
            Some(r) => v.push(format!("--reference {}", quote(r))),
        }
        if let Some(r) = s
            .reference_white
            .as_deref()
            .filter(|r| !r.trim().is_empty())
        {
            v.push(format!("--reference-white {}", quote(r)));
        }
        if let Some(c) = s.corners {
            v.push(format!("--corners {}", quote(&corners_text(c))));
        }
        if let Some(l) = s.layer.as_deref().filter(|r| !r.trim().is_empty()) {
            v.push(format!("--layer {}", quote(l)));
        }
        if let Some(w) = s.white_level {
            v.push(format!("--white-level {w}"));
        }
        if let Ok(o) = self.options() {
            if let Some(f) = o.flat {
                v.push(format!("--flat {}", quote(&f)));
            }
        }
        if self.max_pixels != nsrm_io::DEFAULT_MAX_PIXELS {
            v.push(format!("--max-pixels {}", self.max_pixels));
        }
        v
    }

    /// The command lines that reproduce this session with the CLI.
    pub(crate) fn command(&self, t: &Target) -> String {
        self.command_text(
            t.param("format").unwrap_or("clf"),
            t.param("space").unwrap_or("xyz"),
        )
    }

    fn command_text(&self, format: &str, space: &str) -> String {
        let frame = quote(&self.shown);
        let cap = self.capture_flags().join(" ");
        let mut lines = vec![format!(
            "nsrm chart extract {frame} {cap} -o patches.csv --json reading.json --overlay overlay.png"
        )];
        if let Some(f) = &self.fitted {
            let m = &f.request;
            let kind = m.kind.name();
            lines.push(format!(
                "nsrm fit --capture {frame} {cap}{} --kind {kind} --order {} -o model.json",
                self.patches_flag(&m.flags()),
                m.order
            ));
            let fmt = Format::parse(format).map(|f| f.name()).unwrap_or("clf");
            let sp = OutputSpace::parse(space).map(|s| s.name()).unwrap_or("xyz");
            lines.push(format!(
                "nsrm export --model model.json --training patches.csv --format {fmt} --output-space {sp} -o model.{fmt}"
            ));
        }
        lines.join("\n")
    }
}

/// An error as the page shows it: the page's way out (drag the corners, pick a setting) where the
/// CLI's hint would name a flag.
pub(crate) fn explain_for_page(e: anyhow::Error) -> String {
    use nsrm_io::{Concern, Param};
    let page_remedy = |p: Param| {
        match p {
        Param::Corners => Some(
            "drag the four numbered corners onto the outer corners of the patch grid (1 = the first patch's corner, then clockwise)",
        ),
        Param::Reflectances | Param::ReferenceWhite => Some("pick another reference"),
        Param::Flat => Some("pick another flat field"),
        Param::WhitePatch => Some("name a neutral patch as the white patch"),
        Param::MaxPixels => Some(
            "the frame is over the studio's pixel limit: restart the studio with a higher limit if the frame is genuine",
        ),
        _ => None,
    }
    };
    let text = match e.chain().find_map(super::super::errors::concern) {
        Some(Concern::Remedy(p)) | Some(Concern::Value(p)) if page_remedy(p).is_some() => {
            format!("{e:#}. Way out: {}.", page_remedy(p).unwrap_or_default())
        }
        _ => format!("{e:#}"),
    };
    unflag(&text)
}

/// The page's words for a message that names a CLI flag: `--white-patch` → `white patch` (the
/// page's controls are named as the flags are, without the dashes).
pub(crate) fn unflag(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find("--") {
        let after = &rest[i + 2..];
        if after.starts_with(|c: char| c.is_ascii_lowercase()) {
            out.push_str(&rest[..i]);
            let end = after
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '-'))
                .unwrap_or(after.len());
            out.push_str(&after[..end].replace('-', " "));
            rest = &after[end..];
        } else {
            out.push_str(&rest[..i + 2]);
            rest = after;
        }
    }
    out.push_str(rest);
    out
}

/// `--corners` text of four points, each number written so it reads back exactly.
fn corners_text(c: [[f64; 2]; 4]) -> String {
    c.iter()
        .map(|p| format!("{},{}", p[0], p[1]))
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
#[path = "session_tests.rs"]
mod tests;
