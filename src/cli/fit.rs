//! `nsrm fit`: fit one model and write its JSON file.

use super::capture::CaptureText;
use super::common::{TrainingArgs, UsageError};
use super::fit_args::FitVariantArgs;
use super::values;
use anyhow::{Context, Result};
use nsrm::colorimetry::delta_e00_xyz;
use nsrm::model::fit::{fit_with, Normalise};
use nsrm::model::Kind;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    training: TrainingArgs,
    /// Illuminant the chart is lit by: a built-in name or a CSV file.
    #[arg(
        long,
        default_value = "D65",
        value_name = "NAME|FILE",
        conflicts_with = "training"
    )]
    illuminant: String,
    #[command(flatten)]
    kind: values::KindArg,
    /// Polynomial order, 1..4 (LRM is always linear).
    #[arg(long, default_value_t = 3)]
    order: u8,
    /// Where to write the model file (JSON).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    overwrite: bool,
    /// Fit on the chart photographed in this linear frame (EXR/TIFF) instead: see `nsrm chart
    /// extract` for the chart options.
    #[arg(long, value_name = "FRAME", conflicts_with_all = ["training", "camera", "reflectances", "grid"])]
    capture: Option<PathBuf>,
    #[command(flatten)]
    chart: super::capture::CaptureOptions,
    /// With --capture: an overlay PNG of the reading with a swatch panel (reference vs
    /// corrected, ΔE00 per patch).
    #[arg(long, value_name = "FILE.png", requires = "capture")]
    overlay: Option<PathBuf>,
    #[command(flatten)]
    fit: FitVariantArgs,
}

/// How far evaluating the model in f32 (`apply`'s CPU and GPU paths) can move the in-sample ΔE00:
/// the bound every back end keeps, what this CPU's fast path does, and whether the ridge λ was
/// raised to keep it small.
fn f32_summary(
    model: &nsrm::model::Model,
    report: &nsrm::model::fit::FitReport,
    data: &nsrm::TrainingSet,
) -> String {
    let measured = nsrm::model::fit::f32_error_measured(model, &data.rgb, &data.xyz);
    let bound = report.f32_error_bound.unwrap_or(f64::NAN);
    let raised = match report.ridge_requested {
        Some(r) => format!(
            "; ridge λ raised from {r} to {} to keep it within {}",
            report.ridge_lambda,
            nsrm::model::fit::F32_TOLERANCE_DE00
        ),
        None => String::new(),
    };
    format!("f32 evaluation (apply on CPU or GPU) moves a patch's ΔE00 by at most {bound:.1e} (bound), {measured:.1e} measured on this CPU{raised}")
}

impl Args {
    /// The model kind asked for.
    #[cfg(test)]
    pub fn kind(&self) -> Kind {
        Kind::from(self.kind.kind)
    }
}

pub fn run(a: Args) -> Result<ExitCode> {
    let kind = Kind::from(a.kind.kind);
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    let opts = a.fit.options()?;
    if opts.normalise == Normalise::WhiteBalanced && kind != Kind::Nsrm {
        return Err(UsageError(format!(
            "--normalise white-balanced is defined for NSRM only, not {kind}"
        ))
        .into());
    }
    let mut inputs: Vec<&Path> = Vec::new();
    inputs.extend(a.capture.as_deref());
    inputs.extend(a.chart.input_files());
    inputs.extend(a.training.input_files(&a.illuminant));
    let outputs: Vec<&Path> = std::iter::once(&a.output)
        .chain(&a.overlay)
        .map(PathBuf::as_path)
        .collect();
    let session = super::outputs::open(a.overwrite, &inputs, &outputs)?;
    let captured = super::capture::for_model(a.capture.as_deref(), &a.chart)?;
    if let Some(c) = &captured {
        if let Some(w) = c.other_chart_warning() {
            eprintln!("{w}");
        }
        eprintln!("{}", c.summary());
    }
    let data = match &captured {
        Some(c) => c.training_set().select(&a.training.patches)?,
        None => a.training.load(&a.illuminant)?,
    };
    let source = match (&a.capture, &a.training.training) {
        (Some(f), _) => format!(" read from {}", f.display()),
        (None, Some(t)) => format!(" of {}", t.display()),
        (None, None) => " simulated from spectra".to_string(),
    };
    let fitted = fit_with(kind, a.order, &data, &opts).with_context(|| {
        format!(
            "fitting {kind} order {} on {} patches{source}",
            a.order,
            data.len()
        )
    })?;
    let model = &fitted.model;
    let report = &fitted.report;
    let mut unit = session.unit();
    unit.write_bytes(&a.output, model.to_json().as_bytes())?;
    if let (Some(c), Some(o)) = (&captured, &a.overlay) {
        let sw = super::capture::swatches(c, model);
        super::capture::write_overlay(
            c.frame.frame(),
            Some(&c.extraction),
            &[],
            Some((&sw, c.reference.white)),
            o,
            &mut unit,
        )?;
    }
    unit.commit()?;
    // In parallel: a measured set can hold 10^6 patches.
    let de: Vec<f64> = data
        .rgb
        .par_iter()
        .zip(&data.xyz)
        .map(|(c, x)| delta_e00_xyz(fitted.apply_f64(*c), *x, data.white_xyz))
        .collect();
    let mean = de.iter().sum::<f64>() / de.len() as f64;
    let max = de.iter().fold(0.0f64, |m, v| m.max(*v));
    eprintln!(
        "{} order {} ({} terms) fitted on {} patches, written to {}",
        kind,
        model.order(),
        model.len_terms(),
        data.len(),
        a.output.display()
    );
    let cond = report
        .condition_number
        .map(|c| format!("{c:.3e}"))
        .unwrap_or_else(|| "inf (singular)".into());
    eprintln!(
        "objective {}, preserve white {}, ridge λ {}{}, normalise {}; coefficient norm {:.4e}, design condition number {cond}; in-sample ΔE00 mean {mean:.3}, max {max:.3}{}",
        report.objective,
        report.preserve_white,
        report.ridge_lambda,
        match report.ridge_criterion.as_deref() {
            Some("loo") => " (leave-one-out)",
            Some(_) => " (GCV)",
            None => "",
        },
        report.normalise,
        report.coefficient_norm,
        match (report.de00_start, report.de00_end) {
            (Some(s), Some(e)) => format!(
                "; Σ ΔE00^P {s:.4} → {e:.4} in {} iterations",
                report.iterations
            ),
            _ => String::new(),
        }
    );
    eprintln!("{}", f32_summary(model, report, &data));
    if let Some(w) = few_patches_warning(model.len_terms(), data.len()) {
        eprintln!("{w}");
    }
    Ok(ExitCode::SUCCESS)
}

/// A warning when the fit has fewer than 1.5 patches per term: it can follow the patches'
/// noise, and its in-sample error says nothing about other colours (PRM 3, 19 terms, on 23 CC24
/// patches: leave-one-out max ΔE00 about 21).
pub fn few_patches_warning(terms: usize, patches: usize) -> Option<String> {
    (2 * patches < 3 * terms).then(|| {
        format!(
            "warning: {terms} terms fitted on {patches} patches (fewer than 1.5 per term): the fit can follow the patches' noise and go wild between them; check it with `nsrm eval` (leave-one-out), use a lower --order or more patches, or regularise with --ridge auto"
        )
    })
}
