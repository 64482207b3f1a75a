//! `nsrm apply`: batch colour correction of camera raw files and linear EXR/TIFF frames.
//!
//! The batch executor (`--jobs` decode workers → one correction stage → `--jobs` encode workers)
//! is the library's [`nsrm_io::batch::execute`]; this file holds the command: its flags, the
//! plan, the correction step it hands the executor (the device opened, or the CPU mix of a
//! two-illuminant model's parts, or `--white as-shot`), the interrupt, the progress bar and log
//! drawn from the executor's events, and the summary. The tests are in `apply_tests.rs`.
//!
//! Why one file (about 1,150 lines): the flags (a third of it, each documented for `--help`),
//! the plan, the correction step and the report are one command's steps, and `nsrm farm` takes
//! the same flags apart (`farm_parts`, `settings_argv`); the batch pipeline itself (workers,
//! permits, the stop) is in the library since issue 41.

use super::common::UsageError;
use super::values;
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use nsrm::gpu::{DeviceChoice, GpuOptions};
use nsrm::Model;
use nsrm::OutputSpace;
use nsrm::{FastModel, Threads};
use nsrm::{FrameHighlights, Highlights};
use nsrm_io::batch::{self, Action, BatchPlan, Existing, PlanOptions, Shard};
use nsrm_io::batch::{Correct, CorrectError, Event, ExecOptions, FrameError, FrameOutcome};
use nsrm_io::batch::{ModelCorrector, Timing};
use nsrm_io::{
    self as fio, Decoded, ExrCompression, FileFormat, Limits, ReadOptions, WriteOptions,
};
use nsrm_output::Session;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    #[command(flatten)]
    device: values::DeviceArg,
    /// GPU adapter: a substring of its name (case-insensitive); default `NSRM_ADAPTER`, else the
    /// system's choice.
    #[arg(help_heading = "Run", long, value_name = "NAME")]
    adapter: Option<String>,
    /// Output directory (created if missing); default: beside each input.
    #[arg(short = 'o', long = "output", alias = "output-dir", value_name = "DIR")]
    output_dir: Option<PathBuf>,
    /// Appended to each output's name (before a trailing frame number: plate.0101.exr →
    /// plate_xyz.0101.exr). Default: `_` and the output space (`_xyz`, `_acescg`, …).
    #[arg(help_heading = "Outputs", long, value_name = "S")]
    suffix: Option<String>,
    /// Output file format: `exr` (float, or half with --half; keeps every channel and
    /// attribute of an EXR input) or `tiff` (32-bit float RGB/RGBA).
    #[arg(help_heading = "Outputs", long, value_enum, ignore_case = true, default_value_t = nsrm_io::FileFormat::Exr)]
    format: nsrm_io::FileFormat,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
    /// Skip inputs whose output already exists (for re-running a partly done batch).
    #[arg(help_heading = "Outputs", long, conflicts_with = "overwrite")]
    skip_existing: bool,
    /// Go on after a file fails (the run still exits with status 1); default: stop at the first.
    #[arg(help_heading = "Run", long)]
    continue_on_error: bool,
    /// Decode and encode workers (each holds a frame in memory); default: the number of CPUs.
    #[arg(help_heading = "Run", short = 'j', long, value_name = "N")]
    jobs: Option<usize>,
    /// Convert only the K-th of N slices of the sorted input list (K from 1: files i with
    /// i % N == K-1). With Slurm `--array=1-N`: `--shard $SLURM_ARRAY_TASK_ID/N`.
    #[arg(help_heading = "Run", long, value_name = "K/N")]
    shard: Option<String>,
    /// EXR layer holding the camera RGB: channels NAME.R, NAME.G, NAME.B (or a part NAME).
    #[arg(help_heading = "Inputs", long, value_name = "NAME")]
    layer: Option<String>,
    /// Write the corrected R, G, B as half floats (EXR only).
    #[arg(help_heading = "Outputs", long)]
    half: bool,
    /// EXR compression: `keep` (the input's if lossless, else zip; zip for TIFF and camera raw
    /// inputs), none, rle, zips, zip, piz. Noisy float data compresses little; `none` or `piz`
    /// encode fastest.
    #[arg(help_heading = "Outputs", long, value_enum, ignore_case = true, default_value_t = nsrm_io::ExrCompression::Keep)]
    compression: nsrm_io::ExrCompression,
    /// Deflate level (libdeflate's, 0-12) of ZIP and ZIPS outputs. The default, 1, is the
    /// fastest, and compresses noisy float data about as much as the higher levels do; 0
    /// stores the chunks raw.
    #[arg(help_heading = "Outputs", long, default_value_t = fio::DEFAULT_ZIP_LEVEL, value_name = "N",
          value_parser = clap::value_parser!(u8).range(0..=fio::MAX_ZIP_LEVEL as i64))]
    zip_level: u8,
    #[command(flatten)]
    output_space: super::values::OutputSpaceArg,
    /// The frames' white, for a two-illuminant model (or to white-balance a single one): a
    /// temperature in kelvin (Planckian below 4000 K, CIE daylight from 4000 K), x,y, or
    /// as-shot (each raw file's own as-shot neutral, its temperature by the DNG's fixed-point
    /// iteration; a frame without one fails) or as-shot:R,G,B (a neutral given). The output is
    /// that white's XYZ, adapted as --output-space says.
    #[arg(help_heading = "Colour", long, value_name = "WHITE")]
    white: Option<String>,
    /// Also write an 8-bit sRGB PNG of each frame here, for a quick look.
    #[arg(help_heading = "Outputs", long, value_name = "DIR")]
    preview: Option<PathBuf>,
    /// Print where the time went (decode, correct, encode; frames/s, Mpixel/s).
    #[arg(help_heading = "Run", long)]
    timing: bool,
    /// Print each input and its output, convert nothing.
    #[arg(help_heading = "Run", long)]
    dry_run: bool,
    #[command(flatten)]
    max_pixels: super::values::MaxPixelsArg,
    /// How camera raw inputs are demosaiced: mhc (Malvar-He-Cutler, full resolution), bilinear
    /// (LibRaw's), or half (one pixel per 2×2 CFA block: half width and height).
    #[arg(help_heading = "Inputs", long, value_enum, ignore_case = true, default_value_t = nsrm_io::Demosaic::Mhc)]
    demosaic: nsrm_io::Demosaic,
    /// Clipped highlights: clip (pixels at the sensor's clip level go to the corrected white of
    /// the brightest grey it records, blended in from 0.9 of the level, as RawTherapee and
    /// darktable do) or keep (the raw mapping: a blown window can turn cyan). Default: clip
    /// where the clip level is known (camera raw inputs: their white level; any input with
    /// --clip-level), else keep.
    #[arg(help_heading = "Colour", long, value_enum, ignore_case = true)]
    highlights: Option<nsrm::HighlightMode>,
    /// The level camera RGB clips at, every channel (for EXR, TIFF and JPEG inputs, which
    /// record none; given, it replaces a raw file's own white level).
    #[arg(help_heading = "Colour", long, value_name = "V")]
    clip_level: Option<f64>,
    /// Remove the nsrm temporary files (`.NAME.nsrm-PID-RANDOM.tmp`) found in the output
    /// directories, left by a run that was killed; without it they are only reported. Make sure
    /// no other nsrm is writing there.
    #[arg(help_heading = "Run", long)]
    remove_stale_temporaries: bool,
    /// Files (camera raw: DNG, CR2, CR3, NEF, ARW, …; linear EXR or TIFF), directories (their
    /// .exr/.tif/.tiff files) or glob patterns ('shots/*.exr').
    #[arg(required = true, value_name = "INPUT")]
    inputs: Vec<PathBuf>,
}

/// What happened to one input.
#[derive(Debug, Clone)]
enum Outcome {
    Converted,
    /// Being written when a signal came: its temporary removed, nothing committed.
    Aborted,
    Skipped(String),
    Failed(String),
}

/// The correction step handed to the executor: one engine, driven from one thread (the GPU
/// engine takes `&mut`).
enum Corrector {
    /// One model: the library's multi-threaded f32 CPU path (rebuilt when a frame's highlight
    /// policy differs) or the GPU engine.
    One(Box<ModelCorrector>),
    /// A two-illuminant model at a white between its illuminants: two models, outputs summed.
    Mix(Vec<FastModel>),
    /// `--white as-shot`: the model set combined for each frame's as-shot neutral (the parts
    /// kept per neutral seen), then as `Mix`.
    AsShot(Box<AsShot>),
}

/// The state of `--white as-shot`: the model set, the output space, the parts built for each
/// neutral seen so far and which of them the current frame uses.
struct AsShot {
    profile: nsrm::Profile,
    space: OutputSpace,
    built: Vec<([f32; 3], Vec<FastModel>)>,
    /// The models (in XYZ) of each built combination (for the highlight policy).
    xyz_parts: Vec<Vec<Model>>,
    current: usize,
}

/// The highlight policy run over a frame before models that are summed (each part would
/// otherwise see the policy with its own neutral).
fn prepass(policy: Option<Highlights>, f: &mut nsrm::Frame) {
    if let Some(h) = policy {
        match f.layout {
            nsrm::Layout::Rgb => h.to_f32().apply::<3>(&mut f.data),
            nsrm::Layout::Rgba => h.to_f32().apply::<4>(&mut f.data),
        }
    }
}

/// Sums the outputs of `parts` applied to the frame (one part: applied in place).
fn apply_sum(parts: &[FastModel], f: &mut nsrm::Frame) {
    let src = (parts.len() > 1).then(|| f.clone());
    let ch = f.layout.channels();
    for (i, p) in parts.iter().enumerate() {
        if i == 0 {
            p.apply(f, Threads::All);
            continue;
        }
        let mut g = src.clone().expect("kept for more than one part");
        p.apply(&mut g, Threads::All);
        for (a, b) in f.data.chunks_exact_mut(ch).zip(g.data.chunks_exact(ch)) {
            for k in 0..3 {
                a[k] += b[k];
            }
        }
    }
}

impl Corrector {
    fn open(device: DeviceChoice, adapter: Option<&str>, model: &Model) -> Result<Corrector> {
        let opts = GpuOptions {
            adapter: adapter.map(str::to_string),
            tile_pixels: None,
        };
        let opened = nsrm::gpu::open_device(device, &opts)
            .with_context(|| format!("--device {}", device.name()))?;
        Ok(match opened {
            nsrm::gpu::Opened::Gpu(e) => {
                if device == DeviceChoice::Auto {
                    eprintln!(
                        "nsrm apply: --device auto: correcting on the GPU {}",
                        e.adapter_name()
                    );
                }
                Corrector::One(Box::new(ModelCorrector::gpu(model.clone(), e)))
            }
            nsrm::gpu::Opened::Cpu(why) => {
                if device == DeviceChoice::Auto {
                    eprintln!(
                        "nsrm apply: --device auto: correcting on the CPU: {why}{}",
                        if matches!(why, nsrm::gpu::CpuReason::SoftwareOnly { .. }) {
                            " (--device gpu uses it anyway)"
                        } else {
                            ""
                        }
                    );
                }
                Corrector::One(Box::new(ModelCorrector::cpu(model.clone())))
            }
        })
    }
}

impl AsShot {
    /// Readies the model set combined for the as-shot neutral of `d` (an error when it has
    /// none); returns a line describing a white not seen before.
    fn prepare(&mut self, d: &Decoded) -> Result<Option<String>> {
        let neutral = d.camera().and_then(|c| c.as_shot_neutral);
        if let Some(i) = self.built.iter().position(|(n, _)| Some(*n) == neutral) {
            self.current = i;
            return Ok(None);
        }
        let c = super::white::for_as_shot(&self.profile, neutral)?;
        let parts = c
            .parts
            .iter()
            .map(|m| nsrm::output_model(m, self.space).map(|m| FastModel::new(&m)))
            .collect::<Result<Vec<_>, _>>()?;
        let line = format!(
            "nsrm apply: {}: as-shot {}",
            d.path.display(),
            super::white::describe(&self.profile, &c)
        );
        self.built
            .push((neutral.expect("checked by for_as_shot"), parts));
        self.xyz_parts.push(c.parts);
        self.current = self.built.len() - 1;
        Ok(Some(line))
    }
}

impl Correct for Corrector {
    fn describe(&self) -> String {
        match self {
            Corrector::One(c) => c.describe(),
            Corrector::Mix(f) => format!("CPU, {} models summed", f.len()),
            Corrector::AsShot(a) => format!(
                "CPU, {} combined for each frame's as-shot neutral",
                if a.profile.is_dual() {
                    "two models"
                } else {
                    "the model"
                }
            ),
        }
    }

    /// With `--white as-shot`, the model set combined for the frame's as-shot neutral.
    fn prepare(&mut self, d: &Decoded) -> Result<Option<String>, CorrectError> {
        let Corrector::AsShot(a) = self else {
            return Ok(None);
        };
        a.prepare(d)
            .map_err(|e| CorrectError::Other(format!("{e:#}")))
    }

    /// Corrects the frames of `d` (one model: the library's; summed models: the highlight
    /// policy of `h` run once before them).
    fn correct(&mut self, d: &mut Decoded, h: &FrameHighlights) -> Result<(), CorrectError> {
        let (parts, xyz_parts) = match self {
            Corrector::One(c) => return c.correct(d, h),
            Corrector::Mix(parts) => (&parts[..], None),
            Corrector::AsShot(a) => (
                &a.built[a.current].1[..],
                a.xyz_parts.get(a.current).map(Vec::as_slice),
            ),
        };
        let policy = h.policy(d.camera().and_then(|c| c.clip_level), xyz_parts)?;
        for f in d.frames_mut() {
            prepass(policy, f);
            apply_sum(parts, f)
        }
        Ok(())
    }
}

use super::outputs::STOP_SIGNALS;

/// Set by SIGINT, SIGTERM or SIGHUP (to the signal's number; the executor's stop flag with
/// it): no new file is started, frames being decoded or corrected are dropped, a frame being
/// written is aborted at its next buffer write (its temporary removed, nothing committed:
/// [`nsrm_output::AbortHandle::flag`]), this run's temporaries are removed, the summary is
/// printed and the exit status is 128 + the signal. Outputs committed before the signal stay. A
/// second signal ends the process at once.
#[derive(Clone)]
struct Interrupt {
    signal: Arc<AtomicUsize>,
    /// The executor's stop flag ([`ExecOptions::stop`]), set with `signal`.
    stop: Arc<AtomicBool>,
}

impl Interrupt {
    fn install(session: &Session) -> Result<Interrupt> {
        let signal = Arc::new(AtomicUsize::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let again = Arc::new(AtomicBool::new(false));
        for (sig, name) in STOP_SIGNALS {
            // Registered first, so it runs before the flag is set: only a second signal exits.
            signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, Arc::clone(&again))
                .and_then(|_| signal_hook::flag::register(sig, Arc::clone(&again)))
                .and_then(|_| {
                    signal_hook::flag::register_usize(sig, Arc::clone(&signal), sig as usize)
                })
                .and_then(|_| signal_hook::flag::register(sig, Arc::clone(&stop)))
                .and_then(|_| signal_hook::flag::register(sig, session.abort_handle().flag()))
                .with_context(|| format!("installing the {name} handler"))?;
        }
        Ok(Interrupt { signal, stop })
    }

    /// The signal received, if any: its name and the exit status it gives.
    fn received(&self) -> Option<(&'static str, u8)> {
        let n = self.signal.load(Ordering::SeqCst);
        STOP_SIGNALS
            .iter()
            .find(|(sig, _)| *sig as usize == n)
            .map(|(sig, name)| (*name, (128 + sig) as u8))
    }

    fn stopped(&self) -> bool {
        self.signal.load(Ordering::SeqCst) != 0
    }
}

/// Everything `apply` needs from its flags, checked before any file is touched.
struct Request {
    space: OutputSpace,
    format: FileFormat,
    compression: ExrCompression,
    device: DeviceChoice,
    shard: Option<Shard>,
    suffix: String,
    existing: Existing,
}

fn parse_request(a: &Args) -> Result<Request> {
    let space = a.output_space.output_space;
    let format = a.format;
    let compression = a.compression;
    if a.half && format != FileFormat::Exr {
        return Err(UsageError("--half applies to EXR output only".into()).into());
    }
    let device = a.device.device;
    if a.jobs == Some(0) {
        return Err(UsageError("--jobs must be at least 1".into()).into());
    }
    if let Some(v) = a
        .clip_level
        .filter(|v| !(v.is_finite() && *v > 0.0 && *v <= f32::MAX as f64))
    {
        return Err(UsageError(format!("--clip-level {v}: a level is finite and above 0")).into());
    }
    let shard = a
        .shard
        .as_deref()
        .map(Shard::parse)
        .transpose()
        .context("--shard")?;
    let suffix = a
        .suffix
        .clone()
        .unwrap_or_else(|| format!("_{}", space.name()));
    batch::validate_suffix(&suffix).context("--suffix")?;
    let existing = if a.overwrite.overwrite {
        Existing::Overwrite
    } else if a.skip_existing {
        Existing::Skip
    } else {
        Existing::Refuse
    };
    Ok(Request {
        space,
        format,
        compression,
        device,
        shard,
        suffix,
        existing,
    })
}

/// `nsrm apply`: plan (every path checked, nothing written yet) → run (the pipeline, stopped
/// cleanly by a signal) → report (the summary and the exit status).
pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let req = parse_request(&a)?;
    let (mut parts, as_shot) = match super::white::models_for_apply(&a.model, a.white.as_deref())? {
        super::white::ApplyModels::Fixed(parts) => (parts, None),
        // The first model stands for the set where one is needed before a frame is read (the
        // camera it was fitted on; the preview matrix, which does not depend on the white).
        super::white::ApplyModels::PerFrame(p) => (vec![p.models()[0].clone()], Some(p)),
    };
    let model = parts.remove(0);
    let out_model = nsrm::output_model(&model, req.space)?;
    let extra: Vec<Model> = parts
        .iter()
        .map(|m| nsrm::output_model(m, req.space))
        .collect::<Result<_, _>>()?;

    // Plan.
    let all = batch::expand_inputs(&a.inputs)?;
    let plan = batch::plan_batch(
        &all,
        &PlanOptions {
            out_dir: a.output_dir.as_deref(),
            suffix: &req.suffix,
            format: req.format,
            preview_dir: a.preview.as_deref(),
            existing: req.existing,
            shard: req.shard,
            create_dirs: !a.dry_run,
        },
    )
    .context("planning the outputs (--suffix, -o, --preview, --overwrite)")?;
    let scope = plan.scope();
    report_stale(&plan, a.remove_stale_temporaries && !a.dry_run);
    if a.dry_run {
        println!("# {scope}; model {}", a.model.display());
        for line in dry_run_lines(&plan) {
            println!("{line}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    if plan.jobs.is_empty() {
        eprintln!("nsrm apply: nothing to do ({scope})");
        return Ok(ExitCode::SUCCESS);
    }
    let session = open_session(&a, &plan)?;

    // Run.
    let interrupt = Interrupt::install(&session)?;
    let mut outcomes = planned_outcomes(&plan);
    let early_failure = outcomes
        .iter()
        .any(|o| matches!(o, Some(Outcome::Failed(_))));
    let start = Instant::now();
    let mut timing = Timing::default();
    let mut corrector_name = String::new();
    if (!early_failure || a.continue_on_error) && !interrupt.stopped() {
        let mut corrector = open_corrector(&req, &a, &out_model, &extra, as_shot.as_ref())?;
        corrector_name = corrector.describe();
        let todo = plan.to_convert().len();
        log_device(todo, &corrector_name);
        let opts = ExecOptions {
            sink: &session,
            highlights: frame_highlights(&a, &model, &parts),
            read: read_options(&a),
            write: write_options(&a, &req),
            to_srgb: nsrm::to_linear_srgb(model.white_xyz(), req.space),
            workers: workers(a.jobs, todo),
            continue_on_error: a.continue_on_error,
            stop: &interrupt.stop,
        };
        let done;
        (done, timing) = execute(&plan, &mut corrector, &opts, &out_model);
        for (i, o) in done {
            outcomes[i] = Some(o);
        }
    }
    let wall = start.elapsed();
    let removed = session.remove_temporaries();

    // Report.
    let tally = Tally::of(&outcomes);
    let signal = interrupt.received();
    let corrector = if corrector_name.is_empty() {
        "no correction run".to_string()
    } else {
        corrector_name
    };
    let half = if a.half { " half" } else { "" };
    let output = format!("{} {}{half}", req.space.name(), req.format.name());
    eprintln!(
        "{}",
        tally.summary(signal.map(|s| s.0), &scope, &corrector, &output)
    );
    for (j, o) in plan.jobs.iter().zip(&outcomes) {
        match o {
            Some(Outcome::Failed(why)) => eprintln!("  failed: {}", naming(&j.input, why)),
            Some(Outcome::Skipped(why)) => eprintln!("  skipped: {}", naming(&j.input, why)),
            _ => {}
        }
    }
    if let Some(line) = tally.stop_note(signal.map(|s| s.0), removed) {
        eprintln!("{line}");
    }
    if a.timing {
        print_timing(&timing, wall);
    }
    Ok(match signal {
        Some((_, status)) => ExitCode::from(status),
        None if tally.failed > 0 => ExitCode::from(1),
        None => ExitCode::SUCCESS,
    })
}

/// What `--highlights` and `--clip-level` make of each frame, for `model` and the `parts` summed
/// with it (in XYZ).
fn frame_highlights(a: &Args, model: &Model, parts: &[Model]) -> FrameHighlights {
    let all: Vec<&Model> = std::iter::once(model).chain(parts).collect();
    FrameHighlights::new(a.highlights, a.clip_level, &all)
}

/// Without a terminal, says the device opened, so that a log's reader (a farm task's) sees it
/// before the first frame.
fn log_device(frames: usize, corrector: &str) {
    if !std::io::stderr().is_terminal() {
        eprintln!("nsrm apply: correcting {frames} frame(s) on the {corrector}");
    }
}

/// The correction step: the device asked for; for a two-illuminant model between its
/// illuminants the CPU mix of its models (`extra`, folded like `out_model`); with `--white
/// as-shot` the set (`as_shot`) combined per frame. The GPU runs one model: asked for with a
/// mix, it says the CPU runs it instead.
fn open_corrector(
    req: &Request,
    a: &Args,
    out_model: &Model,
    extra: &[Model],
    as_shot: Option<&nsrm::Profile>,
) -> Result<Corrector> {
    let mixed = if let Some(profile) = as_shot {
        Corrector::AsShot(Box::new(AsShot {
            profile: profile.clone(),
            space: req.space,
            built: Vec::new(),
            xyz_parts: Vec::new(),
            current: 0,
        }))
    } else if extra.is_empty() {
        return Corrector::open(req.device, a.adapter.as_deref(), out_model);
    } else {
        let mut v = vec![FastModel::new(out_model)];
        v.extend(extra.iter().map(FastModel::new));
        Corrector::Mix(v)
    };
    if req.device == DeviceChoice::Gpu {
        // Said, not silent: mixing two models is CPU-only.
        eprintln!(
            "nsrm apply: warning: --device gpu: {} runs on the CPU (the GPU path applies one \
             model; mixing two is CPU-only)",
            if as_shot.is_some() {
                "--white as-shot"
            } else {
                "a two-illuminant model at a white between its lights"
            }
        );
    }
    Ok(mixed)
}

/// What `--dry-run` prints for each job: `input -> output (+ preview)`, and why it would be
/// skipped or fail.
fn dry_run_lines(plan: &BatchPlan) -> Vec<String> {
    plan.jobs
        .iter()
        .map(|j| {
            let what = match &j.action {
                Action::Convert => String::new(),
                Action::Skip(why) => format!("  # skip: {why}"),
                Action::Fail(why) => format!("  # would fail: {}", refusal(why)),
            };
            match &j.preview {
                Some(p) => format!(
                    "{} -> {} (+ {}){what}",
                    j.input.display(),
                    j.output.display(),
                    p.display()
                ),
                None => format!("{} -> {}{what}", j.input.display(), j.output.display()),
            }
        })
        .collect()
}

/// The run's output session: the plan compared the outputs with the frames; the session adds
/// the model and declares every output and preview to be written.
fn open_session(a: &Args, plan: &BatchPlan) -> Result<Session> {
    let mut session = Session::new(a.overwrite.overwrite);
    session.input(&a.model)?;
    for j in plan
        .jobs
        .iter()
        .filter(|j| matches!(j.action, Action::Convert))
    {
        session.output(&j.output)?;
        if let Some(p) = &j.preview {
            session.output(p)?;
        }
    }
    Ok(session)
}

/// Each job's outcome known before anything runs (skipped, refused); `None` for those to
/// convert.
fn planned_outcomes(plan: &BatchPlan) -> Vec<Option<Outcome>> {
    plan.jobs
        .iter()
        .map(|j| match &j.action {
            Action::Convert => None,
            Action::Skip(why) => Some(Outcome::Skipped(why.clone())),
            Action::Fail(why) => Some(Outcome::Failed(refusal(why))),
        })
        .collect()
}

fn read_options(a: &Args) -> ReadOptions {
    ReadOptions {
        layer: a.layer.clone(),
        limits: Limits {
            max_pixels: a.max_pixels.max_pixels,
        },
        demosaic: a.demosaic,
    }
}

fn write_options(a: &Args, req: &Request) -> WriteOptions {
    WriteOptions {
        format: req.format,
        half: a.half,
        compression: req.compression,
        space: req.space,
        zip_level: a.zip_level,
    }
}

/// Reader/writer threads: `--jobs`, else the machine's parallelism; at least 1 and no more
/// than the frames to convert.
fn workers(jobs: Option<usize>, frames: usize) -> usize {
    let n = jobs.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(2)
    });
    n.min(frames).max(1)
}

/// The outcomes of a run, counted.
#[derive(Debug, Default, PartialEq, Eq)]
struct Tally {
    converted: usize,
    skipped: usize,
    failed: usize,
    aborted: usize,
    not_attempted: usize,
}

impl Tally {
    fn of(outcomes: &[Option<Outcome>]) -> Tally {
        let mut t = Tally::default();
        for o in outcomes {
            match o {
                Some(Outcome::Converted) => t.converted += 1,
                Some(Outcome::Skipped(_)) => t.skipped += 1,
                Some(Outcome::Failed(_)) => t.failed += 1,
                Some(Outcome::Aborted) => t.aborted += 1,
                None => t.not_attempted += 1,
            }
        }
        t
    }

    /// The summary line: interrupted by which signal, the counts, and what ran.
    fn summary(&self, signal: Option<&str>, scope: &str, corrector: &str, output: &str) -> String {
        let Tally {
            converted,
            skipped,
            failed,
            aborted,
            not_attempted,
        } = self;
        format!(
            "nsrm apply: {}{converted} converted, {skipped} skipped, {failed} failed{}{} ({scope}; {corrector}; output {output})",
            match signal {
                Some(name) => format!("interrupted by {name}: "),
                None => String::new(),
            },
            if *aborted > 0 {
                format!(", {aborted} aborted while being written")
            } else {
                String::new()
            },
            if *not_attempted > 0 {
                format!(", {not_attempted} not attempted")
            } else {
                String::new()
            },
        )
    }

    /// Why frames were left: a signal (and the temporaries removed), or the first failure
    /// without `--continue-on-error`.
    fn stop_note(&self, signal: Option<&str>, removed: usize) -> Option<String> {
        let Tally {
            aborted,
            not_attempted,
            ..
        } = self;
        if let Some(name) = signal {
            Some(format!(
                "  stopped by {name}: {not_attempted} not attempted, {aborted} aborted while being written (nothing of them committed); {removed} temporary file(s) of this run removed"
            ))
        } else if *not_attempted > 0 {
            Some(format!(
                "  {not_attempted} not attempted: stopped after the first failure (pass --continue-on-error to go on)"
            ))
        } else {
            None
        }
    }
}

/// `input: why`, or `why` alone when it already starts with the input's name.
fn naming(input: &Path, why: &str) -> String {
    let name = input.display().to_string();
    if why.starts_with(&name) {
        why.to_string()
    } else {
        format!("{name}: {why}")
    }
}

/// Reports nsrm temporaries found in the output directories (a killed run's), or removes them
/// when asked.
fn report_stale(plan: &BatchPlan, remove: bool) {
    let stale = super::outputs::stale_temporaries(plan);
    let n = stale.len();
    if n == 0 {
        return;
    }
    if remove {
        let mut removed = 0;
        for p in &stale {
            match std::fs::remove_file(p) {
                Ok(()) => removed += 1,
                Err(e) => eprintln!("nsrm apply: cannot remove {}: {e}", p.display()),
            }
        }
        eprintln!(
            "nsrm apply: removed {removed} stale nsrm temporary file(s) (--remove-stale-temporaries)"
        );
        return;
    }
    eprintln!(
        "nsrm apply: warning: {n} nsrm temporary file(s) in the output directories, left by a run \
         that was killed or being written by another one now; kept (remove them with \
         --remove-stale-temporaries once no other nsrm writes there):"
    );
    for p in stale.iter().take(10) {
        eprintln!("  {}", p.display());
    }
    if n > 10 {
        eprintln!("  … and {} more", n - 10);
    }
}

fn progress_bar(n: usize) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::with_draw_target(Some(n as u64), ProgressDrawTarget::stderr());
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} frames  {msg}  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    pb.enable_steady_tick(Duration::from_millis(200));
    pb
}

/// Runs the plan's frames through the library's executor, drawing the progress bar (on a
/// terminal) or the progress log (else) and the warnings from its events; returns each started
/// frame's outcome and the timing.
fn execute(
    plan: &BatchPlan,
    corrector: &mut Corrector,
    opts: &ExecOptions<'_>,
    model: &Model,
) -> (Vec<(usize, Outcome)>, Timing) {
    let todo = plan.to_convert().len();
    let pb = progress_bar(todo);
    // Without a terminal, a log line per finished frame (at most one a second).
    let log = (!std::io::stderr().is_terminal())
        .then(|| crate::progress::ProgressLog::new(todo, Duration::from_secs(1)));
    let logged = |i: usize, ok: bool, pixels: usize| {
        if let Some(log) = &log {
            let name = plan.jobs[i].output.file_name().unwrap_or_default();
            if let Some(line) = log.frame(ok, pixels as u64, &name.to_string_lossy()) {
                eprintln!("{line}");
            }
        }
    };
    let fitted_on = model
        .provenance()
        .capture
        .as_ref()
        .and_then(|c| c.camera.clone());
    let warned = Mutex::new(std::collections::HashSet::new());
    let on_event = |e: Event<'_>| match e {
        Event::Camera { input, camera, .. } => {
            let Some(fitted) = &fitted_on else { return };
            let mut warned = warned.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(w) = camera_warning(fitted, camera, input, &mut warned) {
                pb.suspend(|| eprintln!("{w}"));
            }
        }
        Event::Note { text, .. } => pb.suspend(|| eprintln!("{text}")),
        Event::Done {
            index,
            pixels,
            pixels_per_second,
            ..
        } => {
            pb.set_message(format!("{:.1} Mpixel/s", pixels_per_second / 1e6));
            pb.inc(1);
            logged(index, true, pixels);
        }
        Event::Failed { index, error, .. } => {
            let why = failure_text(error);
            pb.suspend(|| eprintln!("nsrm apply: failed: {why}"));
            pb.inc(1);
            logged(index, false, 0);
        }
        _ => {}
    };
    let run = batch::execute(plan, corrector, opts, &on_event);
    pb.finish_and_clear();
    let outcomes = run
        .outcomes
        .into_iter()
        .map(|(i, o)| {
            let o = match o {
                FrameOutcome::Converted { .. } => Outcome::Converted,
                FrameOutcome::Aborted => Outcome::Aborted,
                FrameOutcome::Failed(e) => Outcome::Failed(failure_text(&e)),
            };
            (i, o)
        })
        .collect();
    (outcomes, run.timing)
}

/// A frame's failure as the summary and the log word it: the flag at fault or the hint
/// (`common::explain`), the corrector's causes joined.
fn failure_text(e: &FrameError) -> String {
    use super::common::{error_chain, explain_line};
    match e {
        FrameError::Read(e) | FrameError::Write(e) => explain_line(e),
        FrameError::Prepare { input, source } => {
            format!("{}: {}", input.display(), error_chain(source))
        }
        FrameError::Correct { input, source } => {
            let flags = match source {
                CorrectError::Highlights(_) => "--highlights, --clip-level: ",
                _ => "",
            };
            format!(
                "{}: correcting: {flags}{}",
                input.display(),
                error_chain(source)
            )
        }
    }
}

/// The warning for a frame from camera `cam` when the model was fitted on `fitted`: once per
/// camera (`warned` holds those warned about), none for the same camera (any case).
fn camera_warning(
    fitted: &str,
    cam: &str,
    path: &Path,
    warned: &mut std::collections::HashSet<String>,
) -> Option<String> {
    if cam.eq_ignore_ascii_case(fitted) || !warned.insert(cam.to_string()) {
        return None;
    }
    Some(format!(
        "warning: {} comes from a {cam}, but the model was fitted on a {fitted}: \
         its colours will be off unless the sensors match",
        path.display()
    ))
}

fn print_timing(t: &Timing, wall: Duration) {
    let w = wall.as_secs_f64().max(1e-9);
    eprintln!(
        "timing: wall {:.3} s; decode {:.3} s, correct {:.3} s, encode {:.3} s (decode and encode summed over workers; the stages overlap)",
        w,
        t.decode.as_secs_f64(),
        t.correct.as_secs_f64(),
        t.encode.as_secs_f64()
    );
    eprintln!(
        "timing: {} frames, {:.2} Mpixel: {:.2} frames/s, {:.2} Mpixel/s (correction alone {:.1} Mpixel/s)",
        t.frames,
        t.pixels as f64 / 1e6,
        t.frames as f64 / w,
        t.pixels as f64 / 1e6 / w,
        t.pixels as f64 / 1e6 / t.correct.as_secs_f64().max(1e-9)
    );
    if let Some(kib) = peak_rss_kib() {
        eprintln!("timing: peak RSS {:.1} MiB (VmHWM)", kib as f64 / 1024.0);
    }
}

/// This process's peak resident set (`VmHWM` of /proc/self/status), where the system has it.
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A plan's refusal with the flags that change it.
fn refusal(r: &batch::Refusal) -> String {
    match r {
        batch::Refusal::NotRegular { .. } => format!("{r}, even with --overwrite"),
        batch::Refusal::Exists(_) => {
            format!("{r}: pass --overwrite to replace it, or --skip-existing")
        }
        batch::Refusal::PreviewExists(_) => format!("{r}: pass --overwrite to replace it"),
    }
}

/// `apply`'s options as `nsrm farm` takes them apart: the paths (which a farm maps to the
/// workers' mounts), the per-run policies a farm task sets itself, and the rest as words.
pub(super) struct FarmParts<'a> {
    pub(crate) model: &'a mut PathBuf,
    pub(crate) output_dir: &'a mut Option<PathBuf>,
    pub(crate) preview: &'a mut Option<PathBuf>,
    pub(crate) inputs: &'a mut Vec<PathBuf>,
    pub(crate) continue_on_error: &'a mut bool,
    /// `--overwrite` (for `nsrm farm`'s job files: replace them).
    pub(crate) overwrite: bool,
    /// Set when one of `--skip-existing`, `--shard`, `--dry-run`,
    /// `--remove-stale-temporaries` was given (a farm task decides those itself).
    pub(crate) policy_flag: Option<&'static str>,
}

impl Args {
    pub(super) fn farm_parts(&mut self) -> FarmParts<'_> {
        let policy_flag = [
            (self.skip_existing, "--skip-existing"),
            (self.shard.is_some(), "--shard"),
            (self.dry_run, "--dry-run"),
            (self.remove_stale_temporaries, "--remove-stale-temporaries"),
        ]
        .into_iter()
        .find(|(set, _)| *set)
        .map(|(_, f)| f);
        FarmParts {
            model: &mut self.model,
            output_dir: &mut self.output_dir,
            preview: &mut self.preview,
            inputs: &mut self.inputs,
            continue_on_error: &mut self.continue_on_error,
            overwrite: self.overwrite.overwrite,
            policy_flag,
        }
    }

    /// The conversion settings as `apply` words (no paths, no per-run policy): parsing them
    /// back with the paths gives the same conversion.
    pub(super) fn settings_argv(&self) -> Vec<String> {
        fn name(v: impl clap::ValueEnum) -> String {
            v.to_possible_value()
                .map(|p| p.get_name().to_string())
                .unwrap_or_default()
        }
        let mut w: Vec<String> = vec![
            "--device".into(),
            name(self.device.device),
            "--format".into(),
            name(self.format),
            "--compression".into(),
            name(self.compression),
            "--zip-level".into(),
            self.zip_level.to_string(),
            "--output-space".into(),
            name(self.output_space.output_space),
            "--max-pixels".into(),
            self.max_pixels.max_pixels.to_string(),
        ];
        let mut opt = |flag: &str, v: &Option<String>| {
            if let Some(v) = v {
                w.push(format!("{flag}={v}"));
            }
        };
        opt("--adapter", &self.adapter);
        opt("--suffix", &self.suffix);
        opt("--layer", &self.layer);
        opt("--jobs", &self.jobs.map(|j| j.to_string()));
        opt("--highlights", &self.highlights.map(name));
        opt("--clip-level", &self.clip_level.map(|v| v.to_string()));
        opt("--white", &self.white);
        opt(
            "--demosaic",
            &(self.demosaic != nsrm_io::Demosaic::Mhc).then(|| name(self.demosaic)),
        );
        for (set, flag) in [
            (self.half, "--half"),
            (self.continue_on_error, "--continue-on-error"),
            (self.timing, "--timing"),
        ] {
            if set {
                w.push(flag.into());
            }
        }
        w
    }

    /// The batch planned as a farm task sees it: shard `shard` of every input, existing
    /// outputs marked to skip (the task decides whether they are finished), directories created.
    pub(super) fn farm_plan(&self, inputs: &[PathBuf], shard: Shard) -> Result<BatchPlan> {
        let req = parse_request(self)?;
        Ok(batch::plan_batch(
            inputs,
            &PlanOptions {
                out_dir: self.output_dir.as_deref(),
                suffix: &req.suffix,
                format: req.format,
                preview_dir: self.preview.as_deref(),
                existing: Existing::Skip,
                shard: Some(shard),
                create_dirs: true,
            },
        )?)
    }

    /// A farm task's conversion of its unfinished `inputs` with these settings (parsed once
    /// from its job's words): `apply` of those inputs, replacing what is there when `replace`.
    pub(super) fn farm_convert(mut self, inputs: Vec<PathBuf>, replace: bool) -> Result<ExitCode> {
        self.inputs = inputs;
        self.overwrite.overwrite = replace;
        run(self)
    }

    /// The pixel limit and layer a frame is read with (for a farm task's full read of an
    /// output it finds).
    pub(super) fn farm_read_options(&self) -> ReadOptions {
        ReadOptions {
            layer: self.layer.clone(),
            limits: Limits {
                max_pixels: self.max_pixels.max_pixels,
            },
            demosaic: self.demosaic,
        }
    }
}

#[cfg(test)]
mod farm_tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        a: Args,
    }

    #[test]
    fn settings_words_parse_back_to_the_same_settings() {
        for given in [
            vec!["--model", "m.json", "x.exr"],
            vec![
                "--model",
                "m.json",
                "-o",
                "out",
                "--half",
                "--suffix",
                "_a b",
                "--layer",
                "cam",
                "--jobs",
                "3",
                "--output-space",
                "acescg",
                "--compression",
                "piz",
                "--zip-level",
                "7",
                "--device",
                "cpu",
                "--adapter",
                "lava",
                "--max-pixels",
                "99",
                "--continue-on-error",
                "--timing",
                "--format",
                "exr",
                "--white",
                "as-shot",
                "--demosaic",
                "half",
                "--highlights",
                "clip",
                "--clip-level",
                "0.5",
                "x.exr",
            ],
        ] {
            let a = Cmd::try_parse_from(std::iter::once("apply").chain(given.clone()))
                .unwrap()
                .a;
            let mut again: Vec<String> = vec!["apply".into(), "--model".into(), "m.json".into()];
            if a.output_dir.is_some() {
                again.extend(["-o".into(), "out".into()]);
            }
            again.extend(a.settings_argv());
            again.push("x.exr".into());
            let b = Cmd::try_parse_from(&again).unwrap().a;
            assert_eq!(format!("{:?}", a), format!("{:?}", b), "{given:?}");
        }
    }
}

#[cfg(test)]
#[path = "apply_tests.rs"]
mod tests;
