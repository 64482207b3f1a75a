//! `nsrm export-shader`: a self-contained compute shader with a model's matrix baked in, in
//! WGSL or translated by naga to GLSL, HLSL, MSL or SPIR-V; or a DaVinci Resolve DCTL.

use super::values;
use anyhow::{Context, Result};
use nsrm::Model;
use nsrm::OutputSpace;
use nsrm_export::shader::export;

use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Output language: wgsl, glsl (450), hlsl (SM 5.1), msl (2.0), spirv (binary) or dctl
    /// (DaVinci Resolve DCTL `transform` function; --layout does not apply).
    #[arg(long, value_enum, ignore_case = true)]
    lang: values::Lang,
    #[command(flatten)]
    output_space: super::values::OutputSpaceArg,
    #[command(flatten)]
    layout: values::LayoutArg,
    /// Where to write the shader.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

/// The space named by `--output-space`.
fn output_space(a: &Args) -> OutputSpace {
    a.output_space.output_space
}

/// What the output line says about the values written.
fn scale_note(space: OutputSpace) -> String {
    format!(
        "scene-linear {}, training white at Y = 1, as `nsrm apply --output-space {}` writes",
        space.name(),
        space.name()
    )
}

/// `--lang dctl`: the exact model as a Resolve DCTL.
fn run_dctl(a: &Args) -> Result<ExitCode> {
    let space = output_space(a);
    let session = super::outputs::open(a.overwrite.overwrite, &[&a.model], &[&a.output])?;
    let model = Model::load(&a.model)?;
    let folded = nsrm::output_model(&model, space)?;
    let header = vec![
        format!(
            "nsrm DCTL: {} to {} ({}), scene-linear, training white at Y = 1 (as nsrm apply --output-space {})",
            nsrm_export::camera_space_name(&model),
            space.name(),
            space.interop_id(),
            space.name()
        ),
        nsrm_export::provenance_line(&model),
    ];
    let text = nsrm_export::dctl::generate(&folded, &header)
        .with_context(|| format!("exporting {} as DCTL", a.model.display()))?;
    session.write_bytes(&a.output, text.as_bytes())?;
    eprintln!(
        "{} order {} ({} terms) as DCTL ({}): {} bytes written to {}",
        model.kind(),
        model.order(),
        model.len_terms(),
        scale_note(space),
        text.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    let Some(lang) = a.lang.shader() else {
        return run_dctl(&a);
    };
    let layout = a.layout.layout;
    let space = output_space(&a);
    let session = super::outputs::open(a.overwrite.overwrite, &[&a.model], &[&a.output])?;
    let model = Model::load(&a.model)?;
    let model = nsrm::output_model(&model, space)?;
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
        "{} order {} ({} terms, {} pixels) as {} ({}): {} bytes written to {} \
         (entry point `main`, workgroup 256, pixels at group 0 binding 1)",
        model.kind(),
        model.order(),
        model.len_terms(),
        layout.name(),
        lang.name(),
        scale_note(space),
        bytes.len(),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
