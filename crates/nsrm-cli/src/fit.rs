//! `nsrm fit`: fit one model and write its JSON file.

use super::capture::{Capture, CaptureText};
use super::common::{TrainingArgs, UsageError};
use super::fit_args::FitVariantArgs;
use super::values;
use anyhow::{Context, Result};
use nsrm::delta_e00_xyz;
use nsrm::Kind;
use nsrm::Profile;
use nsrm::TrainingSet;
use nsrm::{fit_with, Normalise};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Illuminant the chart is lit by: a built-in name or a CSV file (default D65). Twice (e.g.
    /// `--illuminant A --illuminant D65`): a model per illuminant, written as one
    /// two-illuminant model file. With `--capture`: the light each capture was shot under, in
    /// the same order (the chart's reference values are adapted to it, so the model's white is
    /// that light's).
    #[arg(long, value_name = "NAME|FILE", conflicts_with = "training", action = clap::ArgAction::Append)]
    illuminant: Vec<String>,
    #[command(flatten)]
    kind: values::KindArg,
    /// Polynomial order, 1..4 (LRM is always linear).
    #[arg(long, default_value_t = 3)]
    order: u8,
    /// Where to write the model file (JSON).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
    #[command(flatten)]
    training: TrainingArgs,
    /// Fit on the chart photographed in this frame instead (camera raw: DNG, CR2, CR3, NEF,
    /// ARW, …; linear EXR or TIFF; or a display-referred JPEG, PNG or 8-bit TIFF): see `nsrm
    /// chart extract` for the chart options. Twice, each with its `--illuminant` (e.g. `--capture
    /// a.dng --illuminant A --capture d65.dng --illuminant D65`): a two-illuminant model file.
    #[arg(long, value_name = "FRAME", conflicts_with_all = ["training", "camera", "reflectances", "grid"], action = clap::ArgAction::Append)]
    capture: Vec<PathBuf>,
    #[command(flatten)]
    chart: super::capture::CaptureOptions,
    /// With one --capture: an overlay PNG of the reading with a swatch panel (reference vs
    /// corrected, ΔE00 per patch).
    #[arg(long, value_name = "FILE.png", requires = "capture")]
    overlay: Option<PathBuf>,
    #[command(flatten)]
    fit: FitVariantArgs,
}

/// How far evaluating the model in f32 as `apply` does moves its output (measured on the training
/// patches and an in-gamut probe set; the first-order bound as a diagnostic), and what the f32
/// guard changed: λ, and the in-sample ΔE00 mean / max before and after. A model kept beyond the
/// tolerance (`--ridge 0` turns the guard off) gets a warning.
fn f32_summary(report: &nsrm::FitReport) -> String {
    let tol = nsrm::F32_TOLERANCE_DE00;
    let measured = report.f32_error_measured.unwrap_or(f64::NAN);
    let bound = report.f32_error_bound.unwrap_or(f64::NAN);
    let on = match &report.f32_measured_on {
        Some(gpu) => format!("this CPU's kernel and the {gpu}"),
        None => "this CPU's kernel; no GPU open".into(),
    };
    let head = format!("f32 evaluation as apply does it ({on}) moves the output by at most {measured:.1e} ΔE00, measured on the training patches and an in-gamut probe set (first-order bound on the patches {bound:.1e})");
    match &report.f32_guard {
        Some(c) => format!(
            "{head}; the fit at λ {} moved it by {:.3} ΔE00 (> {tol}): f32 guard raised the ridge λ {} → {}, in-sample ΔE00 mean / max {:.3} / {:.3} → {:.3} / {:.3}",
            fmt_lambda(c.lambda_before),
            c.f32_error_before,
            fmt_lambda(c.lambda_before),
            fmt_lambda(report.ridge_lambda),
            c.de00_mean_before,
            c.de00_max_before,
            c.de00_mean_after,
            c.de00_max_after
        ),
        None if measured.is_nan() || measured > tol => format!(
            "{head}\nwarning: that is more than {tol} ΔE00 and the f32 guard is off (--ridge 0): apply's output will differ from this fit's by up to {measured:.3}"
        ),
        None => format!("{head}: within {tol}, no ridge added"),
    }
}

impl Args {
    /// The model kind asked for.
    #[cfg(test)]
    pub(crate) fn kind(&self) -> Kind {
        self.kind.kind
    }
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let kind = a.kind.kind;
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    let mut opts = a.fit.options()?;
    check_args(&a, kind, opts.normalise)?;
    opts.f32_also = super::fit_args::gpu_check();
    let illuminants: Vec<String> = if a.illuminant.is_empty() {
        vec!["D65".to_string()]
    } else {
        a.illuminant.clone()
    };
    let mut inputs: Vec<&Path> = a.capture.iter().map(PathBuf::as_path).collect();
    inputs.extend(a.chart.input_files());
    for ill in &illuminants {
        inputs.extend(a.training.input_files(ill));
    }
    let outputs: Vec<&Path> = std::iter::once(&a.output)
        .chain(&a.overlay)
        .map(PathBuf::as_path)
        .collect();
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &outputs)?;
    let sets = training_sets(&a, &illuminants)?;
    let mut fits = Vec::new();
    for (data, _, source) in &sets {
        let opts = a.fit.resolved(&opts, &data.labels)?;
        let fitted = fit_with(kind, a.order, data, &opts).with_context(|| {
            format!(
                "fitting {kind} order {} on {} patches{source}",
                a.order,
                data.len()
            )
        })?;
        fits.push(fitted);
    }
    let profile = if fits.len() == 2 {
        let p = Profile::dual(fits[0].model.clone(), fits[1].model.clone()).with_context(|| {
            format!(
                "combining the models fitted on the patches{} and{}",
                sets[0].2, sets[1].2
            )
        })?;
        Some(p)
    } else {
        None
    };
    let mut unit = session.unit();
    match &profile {
        Some(p) => unit.write_bytes(&a.output, p.to_json().as_bytes())?,
        None => unit.write_bytes(&a.output, fits[0].model.to_json().as_bytes())?,
    }
    if let (Some(c), Some(o)) = (&sets[0].1, &a.overlay) {
        let sw = super::capture::swatches(c, &fits[0].model);
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
    for ((data, _, source), fitted) in sets.iter().zip(&fits) {
        report(fitted, data, source, &a.output);
    }
    if let Some(p) = &profile {
        eprintln!(
            "two-illuminant model: {}, written to {} (apply it with --white; export it as a DCP)",
            super::combine::calibrations_line(p),
            a.output.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The usage checks of `nsrm fit` after the order's: the normalisation the kind allows
/// (`normalise`), and how `--capture`, `--illuminant` and `--overlay` go together.
fn check_args(a: &Args, kind: Kind, normalise: Normalise) -> Result<()> {
    if normalise == Normalise::WhiteBalanced && kind != Kind::Nsrm {
        return Err(UsageError(format!(
            "--normalise white-balanced is defined for NSRM only, not {kind}"
        ))
        .into());
    }
    if a.capture.len() > 2 || a.illuminant.len() > 2 {
        return Err(UsageError(
            "--capture and --illuminant are given once, or twice for a two-illuminant model".into(),
        )
        .into());
    }
    if a.capture.len() == 2 && a.illuminant.len() != 2 {
        return Err(UsageError(
            "two --capture need an --illuminant each, in the same order (the light each chart was shot under, e.g. --capture a.dng --illuminant A --capture d65.dng --illuminant D65)".into(),
        )
        .into());
    }
    if a.capture.len() == 1 && a.illuminant.len() == 2 {
        return Err(UsageError(
            "two --illuminant with --capture need two --capture (one chart shot under each light)"
                .into(),
        )
        .into());
    }
    if a.capture.len() == 2 && a.overlay.is_some() {
        return Err(UsageError("--overlay takes one --capture".into()).into());
    }
    Ok(())
}

/// One training set per illuminant: (the data, the capture it came from, where it came from —
/// the tail of the messages that name it).
fn training_sets(
    a: &Args,
    illuminants: &[String],
) -> Result<Vec<(TrainingSet, Option<Capture>, String)>> {
    let mut sets = Vec::new();
    if a.capture.is_empty() {
        super::capture::for_model(None, &a.chart)?;
        for ill in illuminants {
            let data = a.training.load(ill)?;
            let source = match &a.training.training {
                Some(t) => format!(" of {}", t.display()),
                None if illuminants.len() > 1 => format!(" simulated from spectra under {ill}"),
                None => " simulated from spectra".to_string(),
            };
            sets.push((data, None, source));
        }
    } else {
        for (i, f) in a.capture.iter().enumerate() {
            let c = super::capture::for_model(Some(f), &a.chart)?.expect("a capture was given");
            eprintln!("{}", c.summary());
            if let Some(w) = c.other_chart_warning() {
                eprintln!("{w}");
            }
            let mut data = c.training_set().select(&a.training.patches)?;
            let mut source = format!(" read from {}", f.display());
            if let Some(ill) = a.illuminant.get(i) {
                data = under_light(data, ill, &a.training)?;
                source.push_str(&format!(" (reference adapted to {ill})"));
            }
            // The model file carries the patches it was fitted on: `nsrm export` needs no CSV.
            data.record_patches();
            sets.push((data, Some(c), source));
        }
    }
    Ok(sets)
}

/// A chart capture's training set with its reference values adapted (Bradford) from their
/// white to the light the chart was shot under (`--illuminant`, its perfect white at the same
/// Y): the model fitted on it maps the camera's response to that light to that light's white,
/// which is what a calibration illuminant is.
fn under_light(
    mut data: nsrm::TrainingSet,
    ill: &str,
    t: &super::common::TrainingArgs,
) -> Result<nsrm::TrainingSet> {
    let grid = nsrm::Grid::parse(&t.grid)?;
    let light = nsrm::Illuminant::from_name_or_path(ill).context("--illuminant")?;
    let w = nsrm::white_xyz(&light, &grid).context("--illuminant")?;
    let y = data.white_xyz[1];
    let dst = w.map(|v| v * y / w[1]);
    let m = nsrm::bradford_between(data.white_xyz, dst);
    for x in &mut data.xyz {
        *x = nsrm::apply_mat3(&m, *x);
    }
    data.white_xyz = dst;
    Ok(data)
}

/// A ridge λ as people write it: `0`, `0.25`, or `1.778e-7` (four significant digits).
pub(crate) fn fmt_lambda(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        format!("{v}")
    } else if (1e-3..1e4).contains(&v.abs()) {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.3e}")
    }
}

/// What `fit` prints about one fitted model.
fn report(fitted: &nsrm::Fit, data: &nsrm::TrainingSet, source: &str, output: &Path) {
    let model = &fitted.model;
    let report = &fitted.report;
    let kind = model.kind();
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
        "{} order {} ({} terms) fitted on {} patches{source}, written to {}",
        kind,
        model.order(),
        model.len_terms(),
        data.len(),
        output.display()
    );
    let cond = report
        .condition_number
        .map(|c| format!("{c:.3e}"))
        .unwrap_or_else(|| "inf (singular)".into());
    eprintln!(
        "objective {}, preserve white {}, ridge λ {}{}, normalise {}; coefficient norm {:.4e}, design condition number {cond}; in-sample ΔE00 mean {mean:.3}, max {max:.3}{}",
        report.objective,
        report.preserve_white,
        fmt_lambda(report.ridge_lambda),
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
    eprintln!("{}", f32_summary(report));
    if let Some(w) = few_patches_warning(model.len_terms(), data.len()) {
        eprintln!("{w}");
    }
}

/// A warning when the fit has fewer than 1.5 patches per term: it can follow the patches'
/// noise, and its in-sample error says nothing about other colours (PRM 3, 19 terms, on 23 CC24
/// patches: leave-one-out max ΔE00 about 21).
pub(crate) fn few_patches_warning(terms: usize, patches: usize) -> Option<String> {
    (2 * patches < 3 * terms).then(|| {
        format!(
            "warning: {terms} terms fitted on {patches} patches (fewer than 1.5 per term): the fit can follow the patches' noise and go wild between them; check it with `nsrm eval` (leave-one-out), use a lower --order or more patches, or regularise with --ridge auto"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Fit {
        #[command(flatten)]
        a: Args,
    }

    fn args(extra: &[&str]) -> Args {
        let argv = ["fit", "-o", "m.json"]
            .into_iter()
            .chain(extra.iter().copied());
        Fit::try_parse_from(argv).unwrap().a
    }

    /// The ridge λ is printed as people write it (issue 36: `0.00000017782794100389227`).
    #[test]
    fn lambda_is_printed_sensibly() {
        assert_eq!(fmt_lambda(0.000_000_177_827_941_003_892_27), "1.778e-7");
        assert_eq!(fmt_lambda(0.0), "0");
        assert_eq!(fmt_lambda(0.25), "0.25");
        assert_eq!(fmt_lambda(10.0), "10");
        assert_eq!(fmt_lambda(3.0e5), "3.000e5");
    }

    #[test]
    fn captures_illuminants_and_overlays_must_pair_up() {
        let ok = |extra: &[&str]| {
            let a = args(extra);
            check_args(&a, a.kind(), Normalise::default())
        };
        assert!(ok(&[]).is_ok());
        assert!(ok(&["--capture", "a.dng", "--illuminant", "A"]).is_ok());
        for bad in [
            &[
                "--capture",
                "a.dng",
                "--capture",
                "b.dng",
                "--illuminant",
                "A",
            ][..],
            &[
                "--capture",
                "a.dng",
                "--illuminant",
                "A",
                "--illuminant",
                "D65",
            ],
            &[
                "--illuminant",
                "A",
                "--illuminant",
                "D50",
                "--illuminant",
                "D65",
            ],
            &[
                "--capture",
                "a.dng",
                "--capture",
                "b.dng",
                "--illuminant",
                "A",
                "--illuminant",
                "D65",
                "--overlay",
                "o.png",
            ],
        ] {
            let e = ok(bad).unwrap_err();
            assert!(e.downcast_ref::<UsageError>().is_some(), "{bad:?}: {e}");
        }
        let lrm = args(&["--kind", "lrm"]);
        assert!(check_args(&lrm, lrm.kind(), Normalise::WhiteBalanced).is_err());
    }
}
