//! `nsrm export-shader`: a self-contained compute shader with a model's matrix baked in, in
//! WGSL or translated by naga to GLSL, HLSL, MSL or SPIR-V; or a DaVinci Resolve DCTL.

use super::values;
use anyhow::{Context, Result};
use nsrm::colorimetry::spaces::OutputSpace;
use nsrm::gpu::export::export;
use nsrm::{Layout, Model};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Output language: wgsl, glsl (450), hlsl (SM 5.1), msl (2.0), spirv (binary) or dctl
    /// (DaVinci Resolve DCTL `transform` function; --layout does not apply).
    #[arg(long, value_enum, ignore_case = true)]
    lang: values::Lang,
    /// Fold an output space into the matrix exactly as `nsrm apply --output-space` does
    /// (training white at Y = 1): xyz, linear-srgb, acescg or aces2065-1. Default: xyz for dctl;
    /// for the compute shaders, the model's own XYZ (white at Y = 100) unless given.
    #[arg(long, value_enum, ignore_case = true)]
    output_space: Option<values::Space>,
    /// Pixel layout of the buffer the shader corrects in place: packed f32 `rgb` or `rgba`
    /// (alpha untouched).
    #[arg(long, value_enum, ignore_case = true, default_value_t = values::Layout::Rgba)]
    layout: values::Layout,
    /// Where to write the shader.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    overwrite: bool,
}

/// The space named by `--output-space`, if any.
fn output_space(a: &Args) -> Option<OutputSpace> {
    a.output_space.map(OutputSpace::from)
}

/// `--lang dctl`: the exact model as a Resolve DCTL.
fn run_dctl(a: &Args) -> Result<ExitCode> {
    let space = output_space(a).unwrap_or(OutputSpace::Xyz);
    let session = super::outputs::open(a.overwrite, &[&a.model], &[&a.output])?;
    let model = Model::load(&a.model)?;
    let folded = nsrm::colorimetry::output_model(&model, space)?;
    let header = vec![
        format!(
            "nsrm DCTL: {} to {} ({}), scene-linear, training white at Y = 1 (as nsrm apply --output-space {})",
            nsrm::export::camera_space_name(&model),
            space.name(),
            space.interop_id(),
            space.name()
        ),
        nsrm::export::provenance_line(&model),
    ];
    let text = nsrm::export::dctl::generate(&folded, &header)
        .with_context(|| format!("exporting {} as DCTL", a.model.display()))?;
    session.write_bytes(&a.output, text.as_bytes())?;
    eprintln!(
        "{} order {} ({} terms) → {} as DCTL: {} bytes written to {}",
        model.kind(),
        model.order(),
        model.len_terms(),
        space.name(),
        text.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

pub fn run(a: Args) -> Result<ExitCode> {
    let Some(lang) = a.lang.shader() else {
        return run_dctl(&a);
    };
    let layout = Layout::from(a.layout);
    let space = output_space(&a);
    let session = super::outputs::open(a.overwrite, &[&a.model], &[&a.output])?;
    let model = Model::load(&a.model)?;
    let model = match space {
        Some(space) => nsrm::colorimetry::output_model(&model, space)?,
        None => model,
    };
    let bytes = export(&model, layout, lang).with_context(|| {
        format!(
            "exporting {} order {} as {}",
            model.kind(),
            model.order(),
            lang.name()
        )
    })?;
    session.write_bytes(&a.output, &bytes)?;
    eprintln!(
        "{} order {} ({} terms, {} pixels) as {}: {} bytes written to {} \
         (entry point `main`, workgroup 256, pixels at group 0 binding 1)",
        model.kind(),
        model.order(),
        model.len_terms(),
        layout.name(),
        lang.name(),
        bytes.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
