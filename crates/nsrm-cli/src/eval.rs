//! `nsrm eval`: the paper's experiment.

use super::capture::CaptureText;
use super::common::{parse_models, parse_orders, TrainingArgs};
use super::fit_args::FitVariantArgs;
use anyhow::{Context, Result};
use nsrm::display_name;
use nsrm::Kind;
use nsrm::{evaluate_with, plot, EvalResult, Protocol};
use nsrm::{FitOptions, FitWhite as White, Normalise, Ridge};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Illuminant: a built-in name (D65, FL3.15, FL7, TL865, LED-B5, LED-YAG) or a CSV file.
    /// Repeatable; default D65, TL865 and LED-B5 (the paper's).
    #[arg(
        long = "illuminant",
        value_name = "NAME|FILE",
        conflicts_with = "training"
    )]
    illuminants: Vec<String>,
    /// Model kinds to evaluate, comma-separated (`--models` is the old spelling).
    #[arg(
        long,
        alias = "models",
        default_value = "lrm,prm,rprm,nsrm",
        value_name = "LIST"
    )]
    kinds: String,
    /// Polynomial order, 1..4 (LRM is always linear).
    #[arg(long, default_value_t = 3, conflicts_with = "orders")]
    order: u8,
    /// Several orders: `1-4`, `2,3`.
    #[arg(long, value_name = "RANGE")]
    orders: Option<String>,
    /// Fit on all patches and predict them (instead of leave-one-out).
    #[arg(long)]
    in_sample: bool,
    /// Print one JSON object with a `results` array instead of the table.
    #[arg(long)]
    json: bool,
    /// Draw ΔE00 histograms per model, one panel per illuminant (the paper's Fig. 1): .png or .svg.
    #[arg(long, value_name = "FILE")]
    plot: Option<PathBuf>,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
    #[command(flatten)]
    training: TrainingArgs,
    /// Evaluate on the chart photographed in this frame (camera raw: DNG, CR2, CR3, NEF, ARW, …;
    /// linear EXR or TIFF; or a display-referred JPEG, PNG or 8-bit TIFF): see `nsrm chart
    /// extract` for the chart options.
    #[arg(long, value_name = "FRAME", conflicts_with_all = ["training", "camera", "reflectances", "grid", "illuminants"])]
    capture: Option<PathBuf>,
    #[command(flatten)]
    chart: super::capture::CaptureOptions,
    #[command(flatten)]
    fit: FitVariantArgs,
    /// Compare the fit variants: every model × {ls, de00, de00+preserve-white, ridge-auto, and
    /// for NSRM white-balanced}, with mean / median / p95 / max ΔE00 (one table; `--json` too).
    /// Measured data and captures have no perfect white: name a neutral patch with
    /// `--white-patch` for the variants that use a white.
    #[arg(long, conflicts_with_all = ["objective", "preserve_white", "ridge", "normalise"])]
    variants: bool,
    /// Evaluate the f32-guarded fits (as `fit` writes them: the ridge λ raised where evaluating
    /// the model in f32, as `apply` does, measurably moves its output by more than 0.01 ΔE00)
    /// instead of the paper's plain least squares. Without it, fits that would not survive f32
    /// evaluation are marked `*` in the table.
    #[arg(long)]
    f32_guard: bool,
}

/// One evaluation with the variant it used (`--json`'s `results` entries).
#[derive(Debug, Serialize)]
struct VariantResult {
    /// `ls`, `de00`, …, or `custom` when given by flags.
    variant: String,
    objective: String,
    preserve_white: String,
    ridge: String,
    normalise: String,
    #[serde(flatten)]
    result: EvalResult,
}

/// The variant name and the fields describing `opts`.
fn describe(name: &str, opts: &FitOptions, r: EvalResult) -> VariantResult {
    VariantResult {
        variant: name.to_string(),
        objective: opts.objective.name(),
        preserve_white: match (opts.preserve_white, &opts.white) {
            (false, _) => "none".into(),
            (true, White::Perfect) => "perfect-white".into(),
            (true, White::Patch(l)) => format!("patch:{l}"),
        },
        ridge: match opts.ridge {
            Ridge::None => "none".into(),
            Ridge::Lambda(l) => format!("{l}"),
            Ridge::Auto => "auto".into(),
            Ridge::AutoLoo => "auto-loo".into(),
        },
        normalise: opts.normalise.name().into(),
        result: r,
    }
}

/// The output session: every file read (the capture, the chart's files, the spectra or patches)
/// and the plot written, resolved before any work.
fn open_session(a: &Args) -> Result<nsrm_output::Session> {
    let mut inputs: Vec<&Path> = Vec::new();
    inputs.extend(a.capture.as_deref());
    inputs.extend(a.chart.input_files());
    for ill in &a.illuminants {
        inputs.extend(a.training.input_files(ill));
    }
    inputs.extend(a.training.input_files("D65"));
    let outputs: Vec<&Path> = a.plot.iter().map(PathBuf::as_path).collect();
    super::outputs::open(a.overwrite.overwrite, &inputs, &outputs)
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let kinds = parse_models(&a.kinds)?;
    let orders = match &a.orders {
        Some(s) => parse_orders(s, "--orders")?,
        None => parse_orders(&a.order.to_string(), "--order")?,
    };
    if let Some(p) = &a.plot {
        plot::Format::from_path(p)?;
    }
    let session = open_session(&a)?;
    let captured = super::capture::for_model(a.capture.as_deref(), &a.chart)?;
    if let Some(c) = &captured {
        if let Some(w) = c.other_chart_warning() {
            eprintln!("{w}");
        }
        eprintln!("{}", c.summary());
    }
    let illuminants = illuminant_names(
        captured.is_some(),
        a.training.training.is_some(),
        a.training.white.white.as_deref(),
        &a.illuminants,
    );
    let protocol = if a.in_sample {
        Protocol::InSample
    } else {
        Protocol::LeaveOneOut
    };
    // With --variants, --white-patch names the white of the variants that use one.
    if a.f32_guard && a.fit.ridge_is_zero() {
        return Err(super::common::UsageError(
            "--f32-guard raises the ridge λ, --ridge 0 asks for none: choose one".into(),
        )
        .into());
    }
    let custom = if a.variants {
        FitOptions::default()
    } else {
        a.fit.options()?
    };
    let custom_name = if a.fit.is_default() { "ls" } else { "custom" };
    let mut results: Vec<VariantResult> = Vec::new();
    let mut n_patches = 0;
    for ill in &illuminants {
        let data = match &captured {
            Some(c) => c.training_set().select(&a.training.patches)?,
            None => a.training.load(ill)?,
        };
        n_patches = data.len();
        // `--white-patch` may name the patch by its number or name: the label it names.
        let custom = a.fit.resolved(&custom, &data.labels)?;
        let white_patch = a
            .fit
            .white_patch
            .as_deref()
            .map(|w| nsrm::resolve_patch(&data.labels, w))
            .transpose()
            .context("--white-patch")?;
        let ill_name = if a.training.training.is_some() || captured.is_some() {
            ill.clone()
        } else {
            display_name(data.provenance.illuminant.as_deref().unwrap_or(ill))
        };
        for &kind in &kinds {
            let mut done = Vec::new();
            for &order in &orders {
                let eff = kind.effective_order(order);
                if done.contains(&eff) {
                    continue;
                }
                done.push(eff);
                let white_patch = white_patch.as_deref();
                let list = if a.variants {
                    variant_fits(kind, white_patch)
                } else {
                    vec![(custom_name.to_string(), custom_fit(kind, &custom))]
                };
                for (name, mut opts) in list {
                    // The paper's method unless the guarded fits are asked for.
                    opts.f32_guard = a.f32_guard;
                    let r = evaluate_with(kind, order, &data, protocol, &ill_name, &opts)
                        .with_context(|| {
                            let source = match (&a.capture, &a.training.training) {
                                (Some(f), _) => format!(" on the chart read from {}", f.display()),
                                (None, Some(t)) => format!(" on the patches of {}", t.display()),
                                (None, None) => String::new(),
                            };
                            format!(
                                "evaluating {kind} order {eff} ({name}) under {ill_name}{source}"
                            )
                        })?;
                    results.push(describe(&name, &opts, r));
                }
            }
        }
    }
    if a.json {
        let out = json_report(&a, protocol, captured.as_ref(), n_patches, &results);
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else if a.variants {
        print_variants(&a, protocol, n_patches, &results);
    } else {
        let plain: Vec<EvalResult> = results.iter().map(|r| r.result.clone()).collect();
        print_table(&a, protocol, n_patches, &plain);
    }
    if !a.json {
        f32_notes(&results);
    }
    if let Some(p) = &a.plot {
        let title = format!("ΔE00 per patch: {}", plot_title(&a, protocol));
        let bytes = plot::histograms(&plotted(&results), Some(&title), p)
            .with_context(|| format!("drawing the plot {}", p.display()))?;
        session
            .write_bytes(p, &bytes)
            .with_context(|| format!("writing the plot {}", p.display()))?;
        if !a.json {
            println!("\nplot written to {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// `--json`'s object: the protocol, where the patches came from (a capture's camera and
/// reference, else the simulated camera and reflectances or the measured file) and the results.
fn json_report(
    a: &Args,
    protocol: Protocol,
    captured: Option<&super::capture::Capture>,
    n_patches: usize,
    results: &[VariantResult],
) -> serde_json::Value {
    serde_json::json!({
        "protocol": match protocol { Protocol::LeaveOneOut => "leave-one-out", Protocol::InSample => "in-sample" },
        "camera": match captured {
            Some(c) => c.camera(),
            None if a.training.training.is_some() => None,
            None => Some(a.training.camera.clone()),
        },
        "reflectances": match (captured, &a.training.training) {
            (Some(c), _) => c.reference.name.clone(),
            (None, Some(p)) => p.display().to_string(),
            (None, None) => a.training.reflectances.clone(),
        },
        "capture": captured.map(|c| c.provenance()),
        "patches": a.training.patches,
        "n_patches": n_patches,
        "grid": a.training.grid,
        "results": results,
    })
}

/// The illuminants evaluated: the capture's, the measured file's white (or `measured`), those
/// named, or by default the paper's three.
fn illuminant_names(
    captured: bool,
    measured: bool,
    white: Option<&str>,
    named: &[String],
) -> Vec<String> {
    if captured {
        vec!["capture".to_string()]
    } else if measured {
        vec![white.unwrap_or("measured").to_string()]
    } else if named.is_empty() {
        vec!["D65".into(), "TL865".into(), "LED-B5".into()]
    } else {
        named.to_vec()
    }
}

/// A named fit variant of `eval --variants`.
#[derive(Debug, Clone, PartialEq)]
struct Variant {
    /// `ls`, `de00`, `de00+preserve-white`, `ridge-auto`, `white-balanced`.
    name: &'static str,
    opts: FitOptions,
}

/// The variants compared by `eval --variants` for `kind`: least squares, ΔE00, ΔE00 with the
/// perfect white preserved, ridge with λ by GCV, and for NSRM white-balanced least squares.
fn variants(kind: Kind) -> Vec<Variant> {
    use nsrm::Objective;
    let de00 = FitOptions {
        objective: Objective::De00 { power: 2.0 },
        ..Default::default()
    };
    let mut v = vec![
        Variant {
            name: "ls",
            opts: FitOptions::default(),
        },
        Variant {
            name: "de00",
            opts: de00.clone(),
        },
        Variant {
            name: "de00+preserve-white",
            opts: FitOptions {
                preserve_white: true,
                ..de00
            },
        },
        Variant {
            name: "ridge-auto",
            opts: FitOptions {
                ridge: Ridge::Auto,
                ..Default::default()
            },
        },
    ];
    if kind == Kind::Nsrm {
        v.push(Variant {
            name: "white-balanced",
            opts: FitOptions {
                normalise: Normalise::WhiteBalanced,
                ..Default::default()
            },
        });
    }
    v
}

/// `--variants`: the paper's fitting variants of `kind`, each with the named white patch when
/// one is given.
fn variant_fits(kind: Kind, white_patch: Option<&str>) -> Vec<(String, FitOptions)> {
    variants(kind)
        .into_iter()
        .map(|v| {
            let mut opts = v.opts;
            if let Some(l) = white_patch {
                opts.white = White::Patch(l.to_string());
            }
            (v.name.to_string(), opts)
        })
        .collect()
}

/// The fit asked for, for `kind`: white balance is defined for NSRM, the other kinds are
/// fitted raw.
fn custom_fit(kind: Kind, custom: &FitOptions) -> FitOptions {
    let mut o = custom.clone();
    if kind != Kind::Nsrm {
        o.normalise = Normalise::Raw;
    }
    o
}

/// The results the plot shows: the plain fits, not the variants.
fn plotted(results: &[VariantResult]) -> Vec<EvalResult> {
    results
        .iter()
        .filter(|r| r.variant == "ls" || r.variant == "custom")
        .map(|r| r.result.clone())
        .collect()
}

/// Data set, camera and method in a few words (the plot's title).
fn plot_title(a: &Args, protocol: Protocol) -> String {
    let name = |p: &std::path::Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| p.display().to_string())
    };
    let source = match (&a.capture, &a.training.training) {
        (Some(p), _) => format!("chart in {}", name(p)),
        (_, Some(p)) => format!("measured {}", name(p)),
        _ => format!(
            "{}, camera {}",
            name(std::path::Path::new(&a.training.reflectances)),
            name(std::path::Path::new(&a.training.camera))
        ),
    };
    let patches = if a.training.patches == "all" {
        String::new()
    } else {
        format!(" (patches {})", a.training.patches)
    };
    format!(
        "{source}{patches}\n{}, {}",
        proto_name(protocol),
        a.fit.method_name()
    )
}

fn proto_name(protocol: Protocol) -> &'static str {
    match protocol {
        Protocol::LeaveOneOut => "leave-one-out",
        Protocol::InSample => "in-sample",
    }
}

fn header(a: &Args, protocol: Protocol, n: usize) {
    let source = match (&a.capture, &a.training.training) {
        (Some(p), _) => format!("patches read from {}", p.display()),
        (_, Some(p)) => format!("measured patches {}", p.display()),
        _ => format!(
            "camera {}, reflectances {}, grid {}",
            a.training.camera, a.training.reflectances, a.training.grid
        ),
    };
    let proto = proto_name(protocol);
    println!(
        "CIEDE2000, {proto}, {n} patches ({}); {source}",
        a.training.patches
    );
}

/// `*` after a result some of whose fits would not survive f32 evaluation, else a space.
fn marker(r: &EvalResult) -> char {
    if r.f32_unsafe_fits > 0 {
        '*'
    } else {
        ' '
    }
}

/// The lines under a table for the results marked `*`: how many fits would not survive f32
/// evaluation (`apply`'s CPU kernel) within the tolerance, and by how much; or, with the guarded
/// fits, a line saying so.
fn f32_notes(results: &[VariantResult]) {
    let tol = nsrm::F32_TOLERANCE_DE00;
    let mut marked = false;
    for v in results.iter().filter(|v| v.result.f32_unsafe_fits > 0) {
        let r = &v.result;
        let variant = if v.variant == "ls" || v.variant == "custom" {
            String::new()
        } else {
            format!(" {}", v.variant)
        };
        println!(
            "* {}{variant} under {}: {} of {} fits evaluate in f32 (as apply does) up to {:.3} ΔE00 away from f64 (> {tol})",
            model_label(r),
            r.illuminant,
            r.f32_unsafe_fits,
            r.fits,
            r.f32_error_max
        );
        marked = true;
    }
    if marked {
        if results.iter().any(|v| v.result.f32_guard) {
            println!("  no ridge λ up to the guard's limit brought those within; the figures are of the fits as solved");
        } else {
            println!("  the figures are the paper's method (least squares as solved); `--f32-guard` evaluates the fits `fit` would write (ridge λ raised until within)");
        }
    } else if results.iter().any(|v| v.result.f32_guard) {
        println!("fits f32-guarded as `fit` writes them (ridge λ raised where f32 evaluation moved the output by more than {tol} ΔE00)");
    }
}

fn model_label(r: &EvalResult) -> String {
    if r.model == "lrm" {
        "LRM".to_string()
    } else {
        format!("{}{}", r.model.to_uppercase(), r.order)
    }
}

/// The `--variants` table: one row per model × variant, mean / median / p95 / max per illuminant,
/// then the variants with the lowest mean and the lowest max under each illuminant.
fn print_variants(a: &Args, protocol: Protocol, n: usize, results: &[VariantResult]) {
    header(a, protocol, n);
    let mut ills: Vec<&str> = Vec::new();
    let mut rows: Vec<(String, u8, String)> = Vec::new();
    for r in results {
        if !ills.contains(&r.result.illuminant.as_str()) {
            ills.push(&r.result.illuminant);
        }
        let key = (r.result.model.clone(), r.result.order, r.variant.clone());
        if !rows.contains(&key) {
            rows.push(key);
        }
    }
    const W: usize = 29;
    print!("{:<26}", "");
    for ill in &ills {
        print!(" | {ill:^W$}");
    }
    println!();
    print!("{:<26}", "model, variant");
    for _ in &ills {
        print!(
            " | {:>6} {:>6} {:>6} {:>7} ",
            "mean", "median", "p95", "max"
        );
    }
    println!();
    println!("{}", "-".repeat(26 + ills.len() * (W + 3)));
    let find = |m: &str, o: u8, v: &str, ill: &str| {
        results.iter().find(|r| {
            r.result.model == m
                && r.result.order == o
                && r.variant == v
                && r.result.illuminant == ill
        })
    };
    for (model, order, variant) in &rows {
        let Some(first) = results.iter().find(|r| {
            &r.result.model == model && r.result.order == *order && &r.variant == variant
        }) else {
            continue;
        };
        print!(
            "{:<26}",
            format!("{} {variant}", model_label(&first.result))
        );
        for ill in &ills {
            match find(model, *order, variant, ill) {
                Some(r) => {
                    let s = r.result.stats;
                    print!(
                        " | {:>6.3} {:>6.3} {:>6.3} {:>7.3}{}",
                        s.mean,
                        s.median,
                        s.p95,
                        s.max,
                        marker(&r.result)
                    )
                }
                None => print!(" | {:>W$}", "-"),
            }
        }
        println!();
    }
    for ill in &ills {
        let of_ill: Vec<&VariantResult> = results
            .iter()
            .filter(|r| r.result.illuminant == *ill)
            .collect();
        let best = |f: fn(&VariantResult) -> f64| {
            of_ill
                .iter()
                .min_by(|x, y| f(x).total_cmp(&f(y)))
                .map(|r| format!("{} {} ({:.3})", model_label(&r.result), r.variant, f(r)))
                .unwrap_or_default()
        };
        println!(
            "{ill}: lowest mean {}, lowest max {}",
            best(|r| r.result.stats.mean),
            best(|r| r.result.stats.max)
        );
    }
}

fn print_table(a: &Args, protocol: Protocol, n: usize, results: &[EvalResult]) {
    header(a, protocol, n);
    let ills: Vec<&str> = {
        let mut v: Vec<&str> = Vec::new();
        for r in results {
            if !v.contains(&r.illuminant.as_str()) {
                v.push(&r.illuminant);
            }
        }
        v
    };
    print!("{:<12}", "");
    for ill in &ills {
        print!(" | {:^23}", ill);
    }
    println!();
    print!("{:<12}", "model");
    for _ in &ills {
        print!(" | {:>6} {:>7} {:>7} ", "mean", "median", "max");
    }
    println!();
    println!("{}", "-".repeat(12 + ills.len() * 26));
    let mut rows: Vec<(String, u8)> = Vec::new();
    for r in results {
        let key = (r.model.clone(), r.order);
        if !rows.contains(&key) {
            rows.push(key);
        }
    }
    for (model, order) in &rows {
        let label = if model == "lrm" {
            "LRM".to_string()
        } else {
            format!("{}{}", model.to_uppercase(), order)
        };
        print!("{label:<12}");
        for ill in &ills {
            match results
                .iter()
                .find(|r| &r.model == model && r.order == *order && r.illuminant == *ill)
            {
                Some(r) => print!(
                    " | {:>6.2} {:>7.2} {:>7.2}{}",
                    r.stats.mean,
                    r.stats.median,
                    r.stats.max,
                    marker(r)
                ),
                None => print!(" | {:>23}", "-"),
            }
        }
        println!();
    }
    for ill in &ills {
        let of_ill: Vec<&EvalResult> = results.iter().filter(|r| r.illuminant == *ill).collect();
        let best = |f: fn(&EvalResult) -> f64| {
            of_ill
                .iter()
                .min_by(|x, y| f(x).total_cmp(&f(y)))
                .map(|r| model_label(r))
                .unwrap_or_default()
        };
        if of_ill.len() > 1 {
            println!(
                "{ill}: smallest mean {}, median {}, max {}",
                best(|r| r.stats.mean),
                best(|r| r.stats.median),
                best(|r| r.stats.max)
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn illuminants_follow_the_source() {
        let named = vec!["FL7".to_string()];
        assert_eq!(
            illuminant_names(true, true, Some("D50"), &named),
            ["capture"]
        );
        assert_eq!(illuminant_names(false, true, Some("D50"), &named), ["D50"]);
        assert_eq!(illuminant_names(false, true, None, &named), ["measured"]);
        assert_eq!(illuminant_names(false, false, None, &named), ["FL7"]);
        assert_eq!(
            illuminant_names(false, false, None, &[]),
            ["D65", "TL865", "LED-B5"]
        );
    }

    #[test]
    fn fits_per_kind() {
        let custom = FitOptions::default();
        assert_eq!(custom_fit(Kind::Rprm, &custom).normalise, Normalise::Raw);
        assert_eq!(custom_fit(Kind::Nsrm, &custom).normalise, custom.normalise);
        let v = variant_fits(Kind::Nsrm, Some("D4"));
        assert!(v.len() > 1, "{v:?}");
        assert!(v.iter().all(|(_, o)| o.white == White::Patch("D4".into())));
        let names: Vec<&str> = v.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            variants(Kind::Nsrm)
                .iter()
                .map(|v| v.name)
                .collect::<Vec<_>>()
        );
    }
}
