//! `nsrm export-shader`: a self-contained compute shader with a model's matrix baked in, in
//! WGSL or translated by naga to GLSL, HLSL, MSL or SPIR-V.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::gpu::export::{export, ShaderLang};
use nsrm::{Layout, Model};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `nsrm fit`.
    #[arg(long, value_name = "FILE")]
    model: PathBuf,
    /// Output language: wgsl, glsl (450), hlsl (SM 5.1), msl (2.0) or spirv (binary).
    #[arg(long, value_name = "LANG")]
    lang: String,
    /// Pixel layout of the buffer the shader corrects in place: packed f32 `rgb` or `rgba`
    /// (alpha untouched).
    #[arg(long, default_value = "rgba", value_name = "rgb|rgba")]
    layout: String,
    /// Where to write the shader.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Replace an existing output file.
    #[arg(long)]
    overwrite: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let lang = ShaderLang::parse(&a.lang).ok_or_else(|| {
        UsageError(format!(
            "--lang `{}`: expected wgsl, glsl, hlsl, msl or spirv",
            a.lang
        ))
    })?;
    let layout = Layout::parse(&a.layout)
        .ok_or_else(|| UsageError(format!("--layout `{}`: expected rgb or rgba", a.layout)))?;
    nsrm::atomic::check_clobber(&a.output, a.overwrite)?;
    let model = Model::load(&a.model)?;
    let bytes = export(&model, layout, lang).with_context(|| {
        format!(
            "exporting {} order {} as {}",
            model.kind(),
            model.order(),
            lang.name()
        )
    })?;
    nsrm::atomic::write_atomic(&a.output, &bytes, a.overwrite)?;
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
