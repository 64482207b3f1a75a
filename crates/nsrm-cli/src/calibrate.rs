//! `nsrm calibrate SHOT -o DIR`: one chart shot to a calibrated result. Finds and reads the
//! chart, diagnoses the shot, fits (a kind and order named, or the best by leave-one-out among
//! the candidates), and writes into DIR the model (carrying its training patches), the patches
//! CSV, the overlay, the report (text and one self-contained HTML page) and, on request, the
//! profiles (`--export dcp,icc,clf,cube,ocio`).

use super::calibrate_report::{self as report, Report};
use super::capture::{CaptureOptions, CaptureText};
use super::common::UsageError;
use super::fit_args::FitVariantArgs;
use anyhow::{Context, Result};
use nsrm::Kind;
use nsrm::TrainingSet;
use nsrm::{evaluate_with, Protocol};
use nsrm::{fit_with, FitOptions};
use nsrm_chart::capture::Capture;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The chart shot: a camera raw file (DNG, CR2, CR3, NEF, ARW, RAF, ORF, RW2, …), a linear
    /// EXR or TIFF, or a JPEG / PNG / 8-bit TIFF (display-referred: its tone curve stays in the
    /// model, and the report says so).
    #[arg(value_name = "SHOT")]
    shot: PathBuf,
    /// The folder to write into (created if missing): model.json, patches.csv, overlay.png,
    /// report.txt, report.html and the profiles of --export.
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    #[command(flatten)]
    chart: CaptureOptions,
    /// The model kind to fit (lrm, prm, rprm, nsrm); without it the kind and order with the
    /// smallest leave-one-out mean ΔE00 among --candidates is chosen, and the choice is printed.
    #[arg(long, value_enum, ignore_case = true)]
    kind: Option<nsrm::Kind>,
    /// The polynomial order of --kind, 1..4 (default 2; LRM is always 1).
    #[arg(long, value_name = "N", requires = "kind")]
    order: Option<u8>,
    /// The kinds and orders the choice is made among, comma-separated: `lrm`, `rprm2`,
    /// `nsrm3`, … (a kind without an order: orders 2 and 3).
    #[arg(
        long,
        default_value = "lrm,rprm2,rprm3,nsrm2,nsrm3",
        value_name = "LIST"
    )]
    candidates: String,
    /// Profiles to write too, comma-separated: dcp (profile.dcp, a DNG camera profile), icc
    /// (profile.icc), clf (model.clf), cube (model.cube), ocio (config.ocio with config.clf).
    #[arg(
        long,
        value_enum,
        ignore_case = true,
        value_delimiter = ',',
        value_name = "LIST"
    )]
    export: Vec<nsrm_export::Format>,
    /// Subtract the veiling glare measured on the neutral ramp (a uniform camera-RGB term: the
    /// ramp's positive intercepts) from every patch before the fit. Off by default; the report
    /// measures the glare either way.
    #[arg(long)]
    glare_compensation: bool,
    #[command(flatten)]
    fit: FitVariantArgs,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

/// The files written into DIR (the exports aside).
const MODEL: &str = "model.json";
const PATCHES: &str = "patches.csv";
const OVERLAY: &str = "overlay.png";
const REPORT_TXT: &str = "report.txt";
const REPORT_HTML: &str = "report.html";

/// One candidate's leave-one-out result.
pub(crate) struct Candidate {
    pub(crate) kind: Kind,
    pub(crate) order: u8,
    pub(crate) loo_mean: f64,
    pub(crate) loo_max: f64,
}

/// The candidates of `--candidates`: `lrm`, `rprm2`, `nsrm` (orders 2 and 3), …
fn parse_candidates(s: &str) -> Result<Vec<(Kind, u8)>> {
    let mut out: Vec<(Kind, u8)> = Vec::new();
    for item in s.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let split = item
            .find(|c: char| c.is_ascii_digit())
            .unwrap_or(item.len());
        let (name, order) = item.split_at(split);
        let kind =
            Kind::parse(name).map_err(|e| UsageError(format!("--candidates `{item}`: {e}")))?;
        let orders: Vec<u8> = if order.is_empty() {
            vec![2, 3]
        } else {
            match order.parse::<u8>() {
                Ok(o) if (1..=4).contains(&o) => vec![o],
                _ => {
                    return Err(UsageError(format!(
                        "--candidates `{item}`: the order must be 1..4"
                    ))
                    .into())
                }
            }
        };
        for o in orders {
            let c = (kind, kind.effective_order(o));
            if !out.contains(&c) {
                out.push(c);
            }
        }
    }
    if out.is_empty() {
        return Err(UsageError("--candidates names no model".into()).into());
    }
    Ok(out)
}

/// The export file names in DIR (for OCIO: the config; its CLF is `config.clf` beside it).
fn export_name(f: nsrm_export::Format) -> &'static str {
    use nsrm_export::Format;
    match f {
        Format::Dcp => "profile.dcp",
        Format::Icc => "profile.icc",
        Format::Clf => "model.clf",
        Format::Cube => "model.cube",
        Format::Ocio => "config.ocio",
    }
}

pub(crate) fn run(mut a: Args) -> Result<ExitCode> {
    if let Some(o) = a.order {
        if !(1..=4).contains(&o) {
            return Err(UsageError(format!("--order {o} is out of range (1..4)")).into());
        }
    }
    let candidates = parse_candidates(&a.candidates)?;
    let opts = a.fit.options()?;
    if a.chart.chart.is_none() {
        a.chart.chart = Some(nsrm_chart::ChartKind::Cc24.into());
    }
    let formats: Vec<nsrm_export::Format> = a.export.clone();
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("creating the folder {}", a.output.display()))?;
    let dir = a.output.clone();
    let mut outputs: Vec<PathBuf> = [MODEL, PATCHES, OVERLAY, REPORT_TXT, REPORT_HTML]
        .iter()
        .map(|n| dir.join(n))
        .collect();
    for f in &formats {
        outputs.push(dir.join(export_name(*f)));
        if *f == nsrm_export::Format::Ocio {
            outputs.push(dir.join("config.clf"));
        }
    }
    let mut inputs: Vec<&Path> = vec![a.shot.as_path()];
    inputs.extend(a.chart.input_files());
    let out_refs: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &out_refs)?;
    let mut cap = a
        .chart
        .read(&a.shot, Some((&dir.join(OVERLAY), &session)))?;
    eprintln!("{}", cap.summary());
    if let Some(w) = cap.other_chart_warning() {
        eprintln!("{w}");
    }
    let findings = nsrm_chart::diagnose::diagnose(
        &cap.extraction,
        &cap.reference,
        cap.flat.as_ref().map(|f| f.nonuniformity),
        cap.score,
    );
    let ramp = nsrm_chart::diagnose::Ramp::of(&cap.extraction, cap.reference.white);
    let glare = if a.glare_compensation {
        cap.compensate_glare()
    } else {
        None
    };
    let mut data = cap.training_set();
    data.record_patches();
    let opts = a.fit.resolved(&opts, &data.labels)?;
    let (kind, order, tried) = choose(&a, &candidates, &data, &opts)?;
    let guarded = FitOptions {
        f32_also: super::fit_args::gpu_check(),
        ..opts.clone()
    };
    let fitted = fit_with(kind, order, &data, &guarded)
        .with_context(|| format!("fitting {kind} order {order} on {} patches", data.len()))?;
    let loo = evaluate_with(kind, order, &data, Protocol::LeaveOneOut, "capture", &opts)
        .with_context(|| format!("leave-one-out of {kind} order {order}"))?;
    let rep = Report::new(
        &cap,
        &fitted.model,
        &loo,
        report::Context {
            shot: &a.shot,
            findings,
            ramp,
            glare,
            tried,
            chosen_by_loo: a.kind.is_none(),
            display_referred: cap.transfer().display_referred(),
        },
    );
    let mut unit = session.unit();
    unit.write_bytes(&dir.join(MODEL), fitted.model.to_json().as_bytes())?;
    unit.write_bytes(&dir.join(PATCHES), cap.to_csv().as_bytes())?;
    let sw = super::capture::swatches(&cap, &fitted.model);
    let overlay_img = nsrm_chart::overlay::render(
        cap.frame.frame(),
        Some(&cap.extraction),
        &[],
        Some((&sw, cap.reference.white)),
    );
    let png = nsrm_chart::overlay::encode(&overlay_img)?;
    unit.write_bytes(&dir.join(OVERLAY), &png)?;
    let mut export_lines = Vec::new();
    for f in &formats {
        let line = export_one(*f, &fitted.model, &data, &cap, &dir, &mut unit)?;
        export_lines.push(line);
    }
    let text = rep.text(&export_lines);
    unit.write_bytes(&dir.join(REPORT_TXT), text.as_bytes())?;
    unit.write_bytes(&dir.join(REPORT_HTML), rep.html(&png).as_bytes())?;
    unit.commit()?;
    print!("{text}");
    eprintln!(
        "written to {}: {MODEL}, {PATCHES}, {OVERLAY}, {REPORT_TXT}, {REPORT_HTML}{}",
        dir.display(),
        formats
            .iter()
            .map(|f| format!(", {}", export_name(*f)))
            .collect::<String>()
    );
    Ok(ExitCode::SUCCESS)
}

/// The kind and order to fit: `--kind`/`--order`, or the candidate with the smallest
/// leave-one-out mean ΔE00 (the candidates' results, for the report).
fn choose(
    a: &Args,
    candidates: &[(Kind, u8)],
    data: &TrainingSet,
    opts: &FitOptions,
) -> Result<(Kind, u8, Vec<Candidate>)> {
    if let Some(k) = a.kind {
        let kind = k;
        let order = kind.effective_order(a.order.unwrap_or(2));
        return Ok((kind, order, Vec::new()));
    }
    let mut tried = Vec::new();
    for &(kind, order) in candidates {
        match evaluate_with(kind, order, data, Protocol::LeaveOneOut, "capture", opts) {
            Ok(r) => tried.push(Candidate {
                kind,
                order,
                loo_mean: r.stats.mean,
                loo_max: r.stats.max,
            }),
            Err(e) => eprintln!("{kind} order {order} left out of the choice: {e}"),
        }
    }
    let best = tried
        .iter()
        .filter(|c| c.loo_mean.is_finite())
        .min_by(|x, y| x.loo_mean.total_cmp(&y.loo_mean))
        .ok_or_else(|| anyhow::anyhow!("no candidate model could be fitted on the chart"))?;
    Ok((best.kind, best.order, tried))
}

/// Writes one export of `model` into `dir` (staged in `unit`); its line for the report.
fn export_one(
    f: nsrm_export::Format,
    model: &nsrm::Model,
    data: &TrainingSet,
    cap: &Capture,
    dir: &Path,
    unit: &mut nsrm_output::Unit,
) -> Result<String> {
    use nsrm_export::Format;
    let out = dir.join(export_name(f));
    let ctx = || format!("exporting the model as {}", f.name());
    // The LUT range in camera units around the capture's white (camera RGB as recorded).
    let wg = cap.white_g();
    let centre = if wg.is_finite() && wg > 0.0 {
        wg.log2()
    } else {
        0.0
    };
    let stops = [centre - 6.0, centre + 4.0];
    let summary = match f {
        Format::Dcp => {
            let profile = nsrm::Profile::single(model.clone())?;
            let t = nsrm_export::dcp::DcpTraining {
                rgb: data.rgb.clone(),
                white_rgb: None,
            };
            let (bytes, w) =
                nsrm_export::dcp::render(&profile, &[t], Default::default(), stops, None)
                    .with_context(ctx)?;
            unit.write_bytes(&out, &bytes)?;
            format!(
                "{} ({}): {}",
                out.display(),
                w.illuminants.join(" + "),
                w.report.summary()
            )
        }
        Format::Icc => {
            let (bytes, w) = nsrm_export::icc::render(model, Default::default(), &data.rgb, None)
                .with_context(ctx)?;
            unit.write_bytes(&out, &bytes)?;
            format!("{}: {}", out.display(), w.report.summary())
        }
        _ => {
            let options = nsrm_export::LutOptions {
                stops,
                ..Default::default()
            };
            let w = nsrm_export::render(
                model,
                f,
                nsrm::OutputSpace::Xyz,
                options,
                &data.rgb,
                None,
                &out,
            )
            .with_context(ctx)?;
            for (path, bytes) in &w.files {
                unit.write_bytes(path, bytes)?;
            }
            format!("{}: {}", out.display(), w.report.summary())
        }
    };
    Ok(format!(
        "{} (approximation error against the model): {summary}",
        f.name()
    ))
}
