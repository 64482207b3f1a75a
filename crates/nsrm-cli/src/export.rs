//! `nsrm export`: a model as a CLF, a `.cube` or an OpenColorIO v2 config (with its CLF), with
//! the file's measured approximation error against the exact model.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::Model;
use nsrm::TrainingSet;
use nsrm_export::{render, ExportError, Format, LutOptions};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// clf (Academy/SMPTE Common LUT Format v3), cube (Resolve/OCIO .cube: 1D shaper + 3D LUT) or
    /// ocio (an OpenColorIO v2 config, with its CLF written beside it as `<stem>.clf`), dcp (a DNG
    /// camera profile for Lightroom/ACR and RawTherapee; one or two illuminants) or icc (an ICC v2
    /// input profile: camera RGB → PCS XYZ D50; matrix/TRC for LRM, shaper + CLUT otherwise).
    #[arg(long, value_enum, ignore_case = true)]
    format: nsrm_export::Format,
    #[command(flatten)]
    output_space: super::values::OutputSpaceArg,
    /// Lattice points per axis of the 3D LUT (PRM, RPRM, NSRM; and every .cube; the ICC CLUT), 2..129.
    #[arg(long, default_value_t = 65, value_name = "N")]
    lut_size: usize,
    /// Entries of the .cube 1D shaper, 2..65536.
    #[arg(long, default_value_t = 65536, value_name = "N")]
    shaper_size: usize,
    /// The 3D LUT interpolation, declared in the CLF and measured: tetrahedral (OpenColorIO's
    /// best; what `ocioconvert --lut` uses for .cube) or trilinear (Resolve's default for .cube).
    #[arg(long, value_enum, ignore_case = true, default_value_t = nsrm_export::nodes::Interpolation::Tetrahedral)]
    interpolation: nsrm_export::nodes::Interpolation,
    /// The LUT's accurate range, log2 of camera units (training white G = 1): LO:HI (default
    /// -6:4). icc: log2 of device units, where the model's white has its largest channel at 1 and
    /// an ICC CLUT has no headroom above it: LO:0 (default -6:0).
    #[arg(long, value_name = "LO:HI", allow_hyphen_values = true)]
    stops: Option<String>,
    /// dcp: the hue/saturation map's divisions, HUExSAT (one value division), e.g. 90x30.
    #[arg(long, default_value = "600x55", value_name = "HxS")]
    dcp_map: String,
    /// Refuse the export (and write nothing) if its measured max ΔE00 exceeds X.
    #[arg(long, value_name = "X")]
    max_de00: Option<f64>,
    /// The training patches, to measure the error on (and, with the dense in-gamut set, to build
    /// it from): a measured CSV as for `nsrm fit --training`. Default: re-simulated from the model
    /// file's provenance (camera, illuminant, reflectances, grid, patches).
    #[arg(long, value_name = "FILE")]
    training: Option<PathBuf>,
    #[command(flatten)]
    white: super::common::WhiteArg,
    /// Where to write the file (for ocio: the config).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

/// Max ΔE00 of an export above which it is flagged as poor (a visible departure from the model).
const POOR_EXPORT_DE00: f64 = 5.0;

/// The range given by --stops, or `default`.
fn stops_or(a: &Args, default: [f64; 2]) -> Result<[f64; 2]> {
    a.stops.as_deref().map_or(Ok(default), parse_stops)
}

fn parse_stops(s: &str) -> Result<[f64; 2]> {
    let bad = || UsageError(format!("--stops `{s}`: expected LO:HI, e.g. -6:4"));
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let lo: f64 = a.trim().parse().map_err(|_| bad())?;
    let hi: f64 = b.trim().parse().map_err(|_| bad())?;
    Ok([lo, hi])
}

/// The training patches: `--training`, or re-simulated from the model's provenance.
fn training_set(a: &Args, model: &Model) -> Result<TrainingSet> {
    if let Some(path) = &a.training {
        return super::common::read_measured(path, a.white.get()?);
    }
    let p = model.provenance();
    if let Some(t) = TrainingSet::recorded(p, model.patches()) {
        return Ok(t);
    }
    let (Some(camera), Some(ill), Some(refl)) = (&p.camera, &p.illuminant, &p.reflectances) else {
        return Err(UsageError(no_training_message(&a.model, p)).into());
    };
    let strip = |s: &str| s.strip_prefix("builtin:").unwrap_or(s).to_string();
    let grid = nsrm::Grid::parse(p.grid.as_deref().unwrap_or("400:700:10"))?;
    let data = nsrm::simulate_named(&strip(camera), &strip(ill), &strip(refl), &grid)
        .with_context(|| {
            "re-simulating the training patches from the model's provenance (pass --training FILE to give them)".to_string()
        })?;
    let data = data.select(p.patches.as_deref().unwrap_or("all"))?;
    if data.labels != model.patches() {
        return Err(anyhow::anyhow!(
            "the patches re-simulated from the model's provenance ({}) are not the model's {} training patches; pass --training FILE",
            data.len(),
            model.patches().len()
        ));
    }
    Ok(data)
}

/// What to do when a model file neither carries its training patches nor names spectra to
/// re-simulate them from: the file to pass and the command that writes it.
fn no_training_message(model: &std::path::Path, p: &nsrm::Provenance) -> String {
    match &p.capture {
        Some(c) => format!(
            "{}: the model was fitted on the chart in {} but its file does not carry the patches (written before models did); pass --training PATCHES.csv, the file `nsrm chart extract {} --chart {} -o PATCHES.csv` writes (or re-fit with `nsrm calibrate {} -o DIR`, whose model carries them)",
            model.display(),
            c.frame,
            c.frame,
            c.chart,
            c.frame
        ),
        None => format!(
            "{}: the model's provenance names no spectra to re-simulate its training patches from; pass --training FILE, the measured patches CSV it was fitted on (`nsrm chart extract FRAME --chart cc24 -o FILE` writes one from a chart photograph)",
            model.display()
        ),
    }
}

fn parse_map(s: &str) -> Result<nsrm_export::dcp::DcpOptions> {
    let bad = || UsageError(format!("--dcp-map `{s}`: expected HUExSAT, e.g. 90x30"));
    let (h, sat) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let o = nsrm_export::dcp::DcpOptions {
        hue_divisions: h.trim().parse().map_err(|_| bad())?,
        sat_divisions: sat.trim().parse().map_err(|_| bad())?,
    };
    o.check()
        .map_err(|e| UsageError(format!("--dcp-map: {e}")))?;
    Ok(o)
}

/// `--format dcp`: one or two illuminants, from the model file as it is.
fn run_dcp(a: &Args, stops: [f64; 2]) -> Result<ExitCode> {
    use nsrm::Profile;
    use nsrm_export::dcp::{render, DcpTraining};
    let opts = parse_map(&a.dcp_map)?;
    let mut inputs = vec![a.model.as_path()];
    inputs.extend(a.training.as_deref());
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &[a.output.as_path()])?;
    let profile = Profile::load(&a.model)?;
    if a.training.is_some() && profile.is_dual() {
        return Err(UsageError(
            "--training gives one model's patches; a two-illuminant model's are re-simulated from its provenance".into(),
        )
        .into());
    }
    let mut training = Vec::new();
    for m in profile.models() {
        let d = training_set(a, m)?;
        training.push(DcpTraining {
            rgb: d.rgb,
            white_rgb: d.white_rgb,
        });
    }
    let mut unit = session.unit();
    let w = match render(&profile, &training, opts, stops, a.max_de00) {
        Ok((bytes, w)) => {
            unit.write_bytes(&a.output, &bytes)?;
            w
        }
        Err(e @ ExportError::TooInaccurate { limit, .. }) => {
            return Err(e).context(format!("--max-de00 {limit}"))
        }
        Err(e) => return Err(e).with_context(|| format!("exporting {} as dcp", a.model.display())),
    };
    unit.commit()?;
    let m = &profile.models()[0];
    eprintln!(
        "{} order {} → DNG camera profile ({}; hue/saturation map {}×{}×1): {}",
        m.kind(),
        m.order(),
        w.illuminants.join(" + "),
        w.hue_divisions,
        w.sat_divisions,
        a.output.display()
    );
    for (i, miss) in w.white_miss.iter().enumerate() {
        if let Some(d) = miss {
            if *d > 0.01 {
                eprintln!(
                    "nsrm export: model {}'s own white is off by {d:.3} ΔE00 (a DCP maps the neutral exactly to D50, so it differs from the model there by that much); fit with --preserve-white to remove it",
                    i + 1
                );
            }
        }
    }
    println!(
        "approximation error (DNG profile pipeline vs the model re-balanced for the white, as apply --white runs it; D50; at {}): {}",
        w.whites.join(", "),
        w.rebalanced.summary()
    );
    if let Some(u) = &w.unbalanced {
        println!(
            "approximation error (a raw file white-balanced by the training white vs the model as apply runs it without --white; D50; the white included): {}",
            u.summary()
        );
    }
    println!(
        "reported error (the worse of the above; what --max-de00 holds): {}; overall max {:.4} ΔE00",
        w.report.summary(),
        w.report.max()
    );
    Ok(ExitCode::SUCCESS)
}

/// `--format icc`: one model, one illuminant.
fn run_icc(a: &Args) -> Result<ExitCode> {
    use nsrm_export::icc::{render, IccOptions};
    let [lo, hi] = stops_or(a, [nsrm_export::icc::DEFAULT_LO, 0.0])?;
    if hi != 0.0 {
        return Err(UsageError(format!(
            "--stops {lo}:{hi}: an ICC CLUT has no headroom above its white (the white's largest channel is device 1.0), so HI must be 0"
        ))
        .into());
    }
    let opts = IccOptions {
        size: a.lut_size,
        lo,
    };
    if let Err(e) = opts.check() {
        return Err(UsageError(format!("--lut-size/--stops: {e}")).into());
    }
    if let Some(x) = a.max_de00 {
        if !(x.is_finite() && x >= 0.0) {
            return Err(
                UsageError(format!("--max-de00 {x}: expected a non-negative number")).into(),
            );
        }
    }
    let mut inputs = vec![a.model.as_path()];
    inputs.extend(a.training.as_deref());
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &[a.output.as_path()])?;
    let model = Model::load(&a.model)?;
    let data = training_set(a, &model)?;
    let mut unit = session.unit();
    let w = match render(&model, opts, &data.rgb, a.max_de00) {
        Ok((bytes, w)) => {
            unit.write_bytes(&a.output, &bytes)?;
            w
        }
        Err(e @ ExportError::TooInaccurate { limit, .. }) => {
            return Err(e).context(format!("--max-de00 {limit}"))
        }
        Err(e) => return Err(e).with_context(|| format!("exporting {} as icc", a.model.display())),
    };
    unit.commit()?;
    let what = match w.clut_size {
        None => "matrix/TRC".to_string(),
        Some(n) => format!("A2B0 lut16: shaper + {n}³ CLUT"),
    };
    eprintln!(
        "{} order {} → ICC v2 input profile ({what}, {} bytes): {}",
        model.kind(),
        model.order(),
        w.bytes,
        a.output.display()
    );
    let d = w.device_white;
    eprintln!(
        "device values: camera RGB / {:.6}; the model's white is device ({:.4}, {:.4}, {:.4}) → PCS D50 (Y = 1); covered: 2^{}..2^0 of that scale, brighter clips (an ICC CLUT has no headroom above its white)",
        w.scale, d[0], d[1], d[2], w.lo
    );
    println!(
        "approximation error (the profile through Little CMS vs the model, PCS D50): {}",
        w.report.summary()
    );
    if w.report.out_of_range > 0 {
        eprintln!(
            "({} dense samples left out: a channel outside the covered range, or an output brighter than the PCS can carry)",
            w.report.out_of_range
        );
    }
    let worst = w.report.max();
    if worst > POOR_EXPORT_DE00 {
        eprintln!(
            "warning: the profile's max ΔE00 is {worst:.1} (over {POOR_EXPORT_DE00}): it departs visibly from the model somewhere in its range (a PRM can leave the PCS at dark exposures); narrow --stops, or set --max-de00 to refuse such exports"
        );
    }
    Ok(ExitCode::SUCCESS)
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let format = a.format;
    if format == Format::Icc {
        return run_icc(&a);
    }
    if format == Format::Dcp {
        let stops = stops_or(&a, [-6.0, 4.0])?;
        if let Some(x) = a.max_de00 {
            if !(x.is_finite() && x >= 0.0) {
                return Err(
                    UsageError(format!("--max-de00 {x}: expected a non-negative number")).into(),
                );
            }
        }
        return run_dcp(&a, stops);
    }
    let space = a.output_space.output_space;
    let options = LutOptions {
        size: a.lut_size,
        stops: stops_or(&a, [-6.0, 4.0])?,
        shaper_size: a.shaper_size,
        interpolation: a.interpolation,
    };
    if let Err(e) = options.check() {
        return Err(UsageError(format!("--lut-size/--shaper-size/--stops: {e}")).into());
    }
    if let Some(x) = a.max_de00 {
        if !(x.is_finite() && x >= 0.0) {
            return Err(
                UsageError(format!("--max-de00 {x}: expected a non-negative number")).into(),
            );
        }
    }
    let companion = nsrm_export::companion_path(format, &a.output)?;
    let mut inputs = vec![a.model.as_path()];
    inputs.extend(a.training.as_deref());
    let mut outputs = vec![a.output.as_path()];
    outputs.extend(companion.as_deref());
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &outputs)?;
    let model = Model::load(&a.model)?;
    let data = training_set(&a, &model)?;
    let mut unit = session.unit();
    let written = match render(
        &model, format, space, options, &data.rgb, a.max_de00, &a.output,
    ) {
        Ok(r) => {
            for (path, bytes) in &r.files {
                unit.write_bytes(path, bytes)?;
            }
            r
        }
        Err(e @ ExportError::TooInaccurate { limit, .. }) => {
            return Err(e).context(format!("--max-de00 {limit}"))
        }
        Err(e) => {
            return Err(e)
                .with_context(|| format!("exporting {} as {}", a.model.display(), format.name()))
        }
    };
    unit.commit()?;
    let what = if written.exact {
        "exact Matrix".to_string()
    } else {
        let n = written.lut_size.unwrap_or(0);
        format!("shaper + {n}³ LUT")
    };
    eprintln!(
        "{} order {} → {} ({}), {what}: {}",
        model.kind(),
        model.order(),
        space.name(),
        format.name(),
        written
            .files
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!("approximation error: {}", written.report.summary());
    let worst = written.report.max();
    if worst > POOR_EXPORT_DE00 {
        eprintln!(
            "warning: the export's max ΔE00 is {worst:.1} (over {POOR_EXPORT_DE00}): it departs visibly from the model somewhere in its range; check the report above, narrow --stops or enlarge --lut-size, or set --max-de00 to refuse such exports"
        );
    }
    Ok(ExitCode::SUCCESS)
}
