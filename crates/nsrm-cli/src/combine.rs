//! `nsrm combine`: two model files of one kind and order, fitted under two illuminants, as one
//! two-illuminant model file (combined for each frame's white by `apply --white`, and exported
//! as a two-illuminant DCP).

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::Model;
use nsrm::Profile;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// The two model files (`nsrm fit` under two illuminants, e.g. StdA and D65), in any order.
    #[arg(required = true, num_args = 2, value_name = "MODEL")]
    models: Vec<PathBuf>,
    /// The two-illuminant model file to write.
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    #[command(flatten)]
    overwrite: super::values::OverwriteArg,
}

pub(crate) fn run(a: Args) -> Result<ExitCode> {
    if a.models.len() != 2 {
        return Err(UsageError("combine takes exactly two model files".into()).into());
    }
    for m in &a.models {
        if m == &a.output {
            return Err(UsageError(format!(
                "-o {}: that is an input; write the combined model elsewhere",
                a.output.display()
            ))
            .into());
        }
    }
    let inputs: Vec<&std::path::Path> = a.models.iter().map(|p| p.as_path()).collect();
    let session = super::outputs::open(a.overwrite.overwrite, &inputs, &[a.output.as_path()])?;
    let first = Model::load(&a.models[0]).with_context(|| a.models[0].display().to_string())?;
    let second = Model::load(&a.models[1]).with_context(|| a.models[1].display().to_string())?;
    same_camera(&a.models, [&first, &second])?;
    let profile = Profile::dual(first, second).context("combining the two models")?;
    let mut unit = session.unit();
    unit.write_bytes(&a.output, profile.to_json().as_bytes())?;
    unit.commit()?;
    eprintln!(
        "{} order {}: {} → {}",
        profile.models()[0].kind(),
        profile.models()[0].order(),
        calibrations_line(&profile),
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Refuses two models fitted on different cameras (as their files record them): one sensor's
/// two illuminants make a two-illuminant model, two sensors' do not. A model that records no
/// camera is taken as it is.
fn same_camera(paths: &[PathBuf], models: [&Model; 2]) -> Result<()> {
    // A raw frame's `make model`, else the sensitivities a simulated fit used.
    let camera = |m: &Model| {
        let p = m.provenance();
        p.capture
            .as_ref()
            .and_then(|c| c.camera.clone())
            .or_else(|| p.camera.clone())
            .filter(|c| !c.trim().is_empty())
    };
    if let (Some(a), Some(b)) = (camera(models[0]), camera(models[1])) {
        if !a.trim().eq_ignore_ascii_case(b.trim()) {
            anyhow::bail!(
                "{} was fitted on camera {a} and {} on camera {b}: a two-illuminant model is one \
                 camera's (fit both on the same camera)",
                paths[0].display(),
                paths[1].display()
            );
        }
    }
    Ok(())
}

/// `calibration illuminants T1 K (x, y …) and T2 K (x, y …)`: how `combine` and a two-illuminant
/// `fit` name a model set's two lights.
pub(crate) fn calibrations_line(profile: &nsrm::Profile) -> String {
    let c = profile.calibrations();
    format!(
        "calibration illuminants {:.0} K (x, y {:.4}, {:.4}) and {:.0} K (x, y {:.4}, {:.4})",
        c[0].cct, c[0].xy[0], c[0].xy[1], c[1].cct, c[1].xy[0], c[1].xy[1]
    )
}
