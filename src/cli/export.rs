//! `nsrm export`: a model as a CLF, a `.cube` or an OpenColorIO v2 config (with its CLF), with
//! the file's measured approximation error against the exact model.

use super::common::UsageError;
use super::values;
use anyhow::{Context, Result};
use nsrm::colorimetry::spaces::OutputSpace;
use nsrm::export::nodes::Interpolation;
use nsrm::export::{export_to, ExportError, Format, LutOptions};
use nsrm::training::TrainingSet;
use nsrm::Model;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// clf (Academy/SMPTE Common LUT Format v3), cube (Resolve/OCIO .cube: 1D shaper + 3D LUT) or
    /// ocio (an OpenColorIO v2 config, with its CLF written beside it as <stem>.clf).
    #[arg(long, value_enum, ignore_case = true)]
    format: values::ExportFormat,
    /// Output space, folded in exactly as `nsrm apply --output-space` does (training white at
    /// Y = 1): xyz (D65-referred), linear-srgb, acescg or aces2065-1. For OCIO: the scene reference.
    #[arg(long, value_enum, ignore_case = true, default_value_t = values::Space::Xyz)]
    output_space: values::Space,
    /// Lattice points per axis of the 3D LUT (PRM, RPRM, NSRM; and every .cube), 2..129.
    #[arg(long, default_value_t = 65, value_name = "N")]
    lut_size: usize,
    /// Entries of the .cube 1D shaper, 2..65536.
    #[arg(long, default_value_t = 65536, value_name = "N")]
    shaper_size: usize,
    /// The 3D LUT interpolation, declared in the CLF and measured: tetrahedral (OpenColorIO's
    /// best; what `ocioconvert --lut` uses for .cube) or trilinear (Resolve's default for .cube).
    #[arg(long, value_enum, ignore_case = true, default_value_t = values::Interpolation::Tetrahedral)]
    interpolation: values::Interpolation,
    /// The LUT's accurate range, log2 of camera units (training white G = 1): LO:HI.
    #[arg(
        long,
        default_value = "-6:4",
        value_name = "LO:HI",
        allow_hyphen_values = true
    )]
    stops: String,
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
    /// Replace existing output files.
    #[arg(long)]
    overwrite: bool,
}

/// Max ΔE00 of an export above which it is flagged as poor (a visible departure from the model).
const POOR_EXPORT_DE00: f64 = 5.0;

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
    let (Some(camera), Some(ill), Some(refl)) = (&p.camera, &p.illuminant, &p.reflectances) else {
        return Err(UsageError(format!(
            "{}: the model's provenance names no spectra to re-simulate its training patches from; pass --training FILE",
            a.model.display()
        ))
        .into());
    };
    let strip = |s: &str| s.strip_prefix("builtin:").unwrap_or(s).to_string();
    let grid = nsrm::spectral::Grid::parse(p.grid.as_deref().unwrap_or("400:700:10"))?;
    let data = nsrm::spectral::simulate_named(&strip(camera), &strip(ill), &strip(refl), &grid)
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

pub fn run(a: Args) -> Result<ExitCode> {
    let format = Format::from(a.format);
    let space = OutputSpace::from(a.output_space);
    let options = LutOptions {
        size: a.lut_size,
        stops: parse_stops(&a.stops)?,
        shaper_size: a.shaper_size,
        interpolation: Interpolation::from(a.interpolation),
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
    let companion = nsrm::export::companion_path(format, &a.output)?;
    let mut inputs = vec![a.model.as_path()];
    inputs.extend(a.training.as_deref());
    let mut outputs = vec![a.output.as_path()];
    outputs.extend(companion.as_deref());
    let session = super::outputs::open(a.overwrite, &inputs, &outputs)?;
    let model = Model::load(&a.model)?;
    let data = training_set(&a, &model)?;
    let mut unit = session.unit();
    let written = match export_to(
        &model, format, space, options, &data.rgb, a.max_de00, &a.output, &mut unit,
    ) {
        Ok(w) => w,
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
            .map(|p| p.display().to_string())
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
