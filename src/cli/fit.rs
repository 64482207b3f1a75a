//! `nsrm fit`: fit one model and write its JSON file.

use super::common::{TrainingArgs, UsageError};
use anyhow::{Context, Result};
use nsrm::model::{fit, Kind};
use std::path::PathBuf;
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
    /// Model kind: lrm, prm, rprm or nsrm.
    #[arg(long, default_value = "nsrm")]
    model: String,
    /// Polynomial order, 1..4 (LRM is always linear).
    #[arg(long, default_value_t = 3)]
    order: u8,
    /// Where to write the model file (JSON).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    overwrite: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let kind = Kind::parse(&a.model).map_err(|e| UsageError(e.to_string()))?;
    if !(1..=4).contains(&a.order) {
        return Err(UsageError(format!("--order {} is out of range (1..4)", a.order)).into());
    }
    nsrm::atomic::check_clobber(&a.output, a.overwrite)?;
    let data = a.training.load(&a.illuminant)?;
    let model = fit(kind, a.order, &data)
        .with_context(|| format!("fitting {kind} order {} on {} patches", a.order, data.len()))?;
    nsrm::atomic::write_atomic(&a.output, model.to_json().as_bytes(), a.overwrite)?;
    eprintln!(
        "{} order {} ({} terms) fitted on {} patches, written to {}",
        kind,
        model.order(),
        model.len_terms(),
        data.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
