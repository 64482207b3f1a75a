//! `nsrm eval`: the paper's experiment.

use super::common::{parse_models, parse_orders, TrainingArgs, UsageError};
use anyhow::{Context, Result};
use nsrm::eval::{evaluate, plot, EvalResult, Protocol};
use nsrm::spectral::display_name;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    training: TrainingArgs,
    /// Illuminant: a built-in name (D65, FL3.15, FL7, TL865, LED-B5, LED-YAG) or a CSV file.
    /// Repeatable; default D65, TL865 and LED-B5 (the paper's).
    #[arg(
        long = "illuminant",
        value_name = "NAME|FILE",
        conflicts_with = "training"
    )]
    illuminants: Vec<String>,
    /// Models to evaluate, comma-separated.
    #[arg(long, default_value = "lrm,prm,rprm,nsrm", value_name = "LIST")]
    models: String,
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
    /// Replace an existing plot file.
    #[arg(long)]
    overwrite: bool,
    /// Evaluate on the chart photographed in this linear frame (EXR/TIFF): see `nsrm chart
    /// extract` for the chart options.
    #[arg(long, value_name = "FRAME", conflicts_with_all = ["training", "camera", "reflectances", "grid", "illuminants"])]
    capture: Option<PathBuf>,
    #[command(flatten)]
    chart: super::capture::CaptureOptions,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let kinds = parse_models(&a.models)?;
    let orders = match &a.orders {
        Some(s) => parse_orders(s, "--orders")?,
        None => parse_orders(&a.order.to_string(), "--order")?,
    };
    if let Some(p) = &a.plot {
        plot::Format::from_path(p).map_err(|e| UsageError(e.to_string()))?;
    }
    let captured = super::capture::for_model(a.capture.as_deref(), &a.chart)?;
    let illuminants: Vec<String> = if captured.is_some() {
        vec!["capture".to_string()]
    } else if a.training.training.is_some() {
        vec![a
            .training
            .white
            .clone()
            .unwrap_or_else(|| "measured".to_string())]
    } else if a.illuminants.is_empty() {
        vec!["D65".into(), "TL865".into(), "LED-B5".into()]
    } else {
        a.illuminants.clone()
    };
    let protocol = if a.in_sample {
        Protocol::InSample
    } else {
        Protocol::LeaveOneOut
    };
    let mut results: Vec<EvalResult> = Vec::new();
    let mut n_patches = 0;
    for ill in &illuminants {
        let data = match &captured {
            Some(c) => c.training_set().select(&a.training.patches)?,
            None => a.training.load(ill)?,
        };
        n_patches = data.len();
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
                let r = evaluate(kind, order, &data, protocol, &ill_name)
                    .with_context(|| format!("evaluating {kind} order {eff} under {ill_name}"))?;
                results.push(r);
            }
        }
    }
    if a.json {
        let out = serde_json::json!({
            "protocol": match protocol { Protocol::LeaveOneOut => "leave-one-out", Protocol::InSample => "in-sample" },
            "camera": if a.training.training.is_some() { None } else { Some(&a.training.camera) },
            "reflectances": a.training.training.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| a.training.reflectances.clone()),
            "capture": captured.as_ref().map(|c| c.provenance()),
            "patches": a.training.patches,
            "n_patches": n_patches,
            "grid": a.training.grid,
            "results": results,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_table(&a, protocol, n_patches, &illuminants, &results);
    }
    if let Some(p) = &a.plot {
        plot::histograms(&results, p, a.overwrite)
            .with_context(|| format!("writing the plot {}", p.display()))?;
        if !a.json {
            println!("\nplot written to {}", p.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn print_table(
    a: &Args,
    protocol: Protocol,
    n: usize,
    illuminants: &[String],
    results: &[EvalResult],
) {
    let source = match (&a.capture, &a.training.training) {
        (Some(p), _) => format!("patches read from {}", p.display()),
        (_, Some(p)) => format!("measured patches {}", p.display()),
        _ => format!(
            "camera {}, reflectances {}, grid {}",
            a.training.camera, a.training.reflectances, a.training.grid
        ),
    };
    let proto = match protocol {
        Protocol::LeaveOneOut => "leave-one-out",
        Protocol::InSample => "in-sample",
    };
    println!(
        "CIEDE2000, {proto}, {n} patches ({}); {source}",
        a.training.patches
    );
    let ills: Vec<&str> = {
        let mut v: Vec<&str> = Vec::new();
        for r in results {
            if !v.contains(&r.illuminant.as_str()) {
                v.push(&r.illuminant);
            }
        }
        v
    };
    let _ = illuminants;
    print!("{:<12}", "");
    for ill in &ills {
        print!(" | {:^22}", ill);
    }
    println!();
    print!("{:<12}", "model");
    for _ in &ills {
        print!(" | {:>6} {:>7} {:>7}", "mean", "median", "max");
    }
    println!();
    println!("{}", "-".repeat(12 + ills.len() * 25));
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
                    " | {:>6.2} {:>7.2} {:>7.2}",
                    r.stats.mean, r.stats.median, r.stats.max
                ),
                None => print!(" | {:>22}", "-"),
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
                .map(|r| format!("{}{}", r.model.to_uppercase(), r.order))
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
