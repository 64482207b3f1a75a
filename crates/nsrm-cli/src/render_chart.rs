//! `nsrm render-chart`: a synthetic linear camera-RGB frame of a chart, for testing `apply`.

use super::common::{TrainingArgs, UsageError};
use anyhow::{Context, Result};
use nsrm_chart::synthetic::{self, ChartOptions};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    training: TrainingArgs,
    /// Illuminant the chart is lit by: a built-in name or a CSV file.
    #[arg(long, default_value = "D65", value_name = "NAME|FILE")]
    illuminant: String,
    /// Side of each patch in pixels.
    #[arg(long, default_value_t = 32, value_name = "PX")]
    patch_size: usize,
    /// Black pixels between patches and around the chart.
    #[arg(long, default_value_t = 4, value_name = "PX")]
    gap: usize,
    /// Patches per row (default: about 3:2 landscape).
    #[arg(long, value_name = "C")]
    columns: Option<usize>,
    /// Multiplies the camera RGB (1: the perfect white has G = 1).
    #[arg(long, default_value_t = 1.0, value_name = "K")]
    exposure: f64,
    /// Standard deviation of Gaussian noise added to every pixel value (camera RGB units).
    #[arg(long, default_value_t = 0.0, value_name = "SIGMA")]
    noise: f64,
    /// Seed of the noise (same seed, same frame).
    #[arg(long, default_value_t = 1, value_name = "N")]
    seed: u64,
    /// The frame to write: .exr (float) or .tif/.tiff (32-bit float). The patch layout goes to
    /// NAME.patches.json beside it.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    if nsrm_io::FileFormat::from_extension(&a.output).is_none() {
        return Err(UsageError(format!(
            "{}: the chart must be written as .exr, .tif or .tiff",
            a.output.display()
        ))
        .into());
    }
    let opts = ChartOptions {
        patch_size: a.patch_size,
        gap: a.gap,
        columns: a.columns,
        exposure: a.exposure,
        noise: a.noise,
        seed: a.seed,
    };
    // Refuse bad options before the (slower) simulation.
    opts.validate()?;
    let layout_file = synthetic::layout_path(&a.output);
    let session = super::outputs::open(
        a.overwrite.overwrite,
        &a.training.input_files(&a.illuminant),
        &[&a.output, &layout_file],
    )?;
    let data = a.training.load(&a.illuminant)?;
    let (frame, layout) = synthetic::render(&data, &opts).context("rendering the chart")?;
    let json = synthetic::layout_json(&layout)?;
    let mut unit = session.unit();
    unit.write_bytes(&layout_file, json.as_bytes())?;
    unit.write_with(&a.output, |w| {
        synthetic::write(&frame, &layout, &a.output, w)
    })?;
    unit.commit()?;
    eprintln!(
        "{} patches ({} columns, {} px) rendered to {} ({}×{}); layout in {}",
        layout.patches.len(),
        layout.columns,
        layout.patch_size,
        a.output.display(),
        layout.width,
        layout.height,
        synthetic::layout_path(&a.output).display()
    );
    Ok(ExitCode::SUCCESS)
}
