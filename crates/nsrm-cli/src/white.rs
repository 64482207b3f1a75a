//! `apply --white`: the frame's white for a two-illuminant model (or a white-balanced single
//! model), and the model(s) `apply` runs for it.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::temperature_xy;
use nsrm::Model;
use nsrm::{Combination, FrameWhite, Profile};
use std::path::Path;

/// What `--white` names: one white for every frame, or each raw frame's own as-shot neutral.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum WhiteSpec {
    Fixed(FrameWhite),
    /// `as-shot`: the camera neutral the raw file records (its AsShotNeutral, or the inverse of
    /// its white-balance coefficients), per frame; its temperature by the DNG fixed-point
    /// iteration.
    AsShot,
}

/// Parses `--white`: `CCT` (kelvin: Planckian below 4000 K, CIE daylight from 4000 K), `x,y`,
/// `as-shot` (each raw frame's own as-shot neutral) or `as-shot:R,G,B` / `neutral:R,G,B` (the
/// camera's response to the frame's white, given).
pub(crate) fn parse_white(s: &str) -> Result<WhiteSpec> {
    let t = s.trim();
    let nums = |v: &str| -> Option<Vec<f64>> {
        v.split(',')
            .map(|x| x.trim().parse::<f64>().ok().filter(|f| f.is_finite()))
            .collect()
    };
    let lower = t.to_ascii_lowercase();
    if lower == "as-shot" {
        return Ok(WhiteSpec::AsShot);
    }
    for prefix in ["as-shot:", "neutral:"] {
        if let Some(rest) = lower.strip_prefix(prefix) {
            return match nums(rest).as_deref() {
                Some([r, g, b]) if *r > 0.0 && *g > 0.0 && *b > 0.0 => {
                    Ok(WhiteSpec::Fixed(FrameWhite::Neutral([*r, *g, *b])))
                }
                _ => Err(UsageError(format!(
                    "--white {s}: expected {prefix}R,G,B with three numbers > 0"
                ))
                .into()),
            };
        }
    }
    match nums(t).as_deref() {
        Some([k]) => {
            let xy = temperature_xy(*k).map_err(|e| UsageError(format!("--white {s}: {e}")))?;
            Ok(WhiteSpec::Fixed(FrameWhite::Xy(xy)))
        }
        Some([x, y]) if *x > 0.0 && *y > 0.0 && x + y < 1.0 => {
            Ok(WhiteSpec::Fixed(FrameWhite::Xy([*x, *y])))
        }
        _ => Err(UsageError(format!(
            "--white {s}: expected a temperature in kelvin (e.g. 4300), a chromaticity x,y (e.g. 0.3805,0.3768), as-shot or as-shot:R,G,B"
        ))
        .into()),
    }
}

/// The model(s) `apply` runs.
pub(crate) enum ApplyModels {
    /// One white for every frame: the model file's one model (no `--white`), or the model set
    /// combined for the white (one part, or two whose outputs are summed).
    Fixed(Vec<Model>),
    /// `--white as-shot`: the model set, combined for each raw frame's as-shot neutral.
    PerFrame(Profile),
}

/// The model(s) `apply` runs for `--model` and `--white`.
pub(crate) fn models_for_apply(path: &Path, white: Option<&str>) -> Result<ApplyModels> {
    let Some(w) = white else {
        return match Model::load(path) {
            Ok(m) => Ok(ApplyModels::Fixed(vec![m])),
            Err(e) => {
                let dual = e.to_string().contains("two calibration illuminants");
                Err(anyhow::Error::from(e).context(if dual {
                    "--model (a two-illuminant model is combined for the frames' white: pass --white)"
                } else {
                    "--model"
                }))
            }
        };
    };
    let spec = parse_white(w)?;
    let profile = Profile::load(path).context("--model")?;
    let fw = match spec {
        WhiteSpec::AsShot => {
            eprintln!(
                "nsrm apply: --white as-shot: each frame is corrected for its raw file's as-shot neutral{}",
                if profile.is_dual() {
                    format!(
                        " (the {:.0} K and {:.0} K models mixed by its temperature)",
                        profile.temperatures()[0],
                        profile.temperatures()[1]
                    )
                } else {
                    " (one model, white-balanced)".to_string()
                }
            );
            return Ok(ApplyModels::PerFrame(profile));
        }
        WhiteSpec::Fixed(fw) => fw,
    };
    let c = profile
        .combine_for_apply(fw)
        .with_context(|| format!("--white {w}"))?;
    eprintln!("nsrm apply: {}", describe(&profile, &c));
    Ok(ApplyModels::Fixed(c.parts))
}

/// The white a combination was made for, and the models' weights.
pub(crate) fn describe(profile: &Profile, c: &Combination) -> String {
    format!(
        "white x, y {:.4}, {:.4} ({:.0} K), camera neutral {:.4}, {:.4}, {:.4}; {}",
        c.xy[0],
        c.xy[1],
        c.cct,
        c.neutral[0],
        c.neutral[1],
        c.neutral[2],
        if profile.is_dual() {
            format!(
                "weight {:.3} on the {:.0} K model, {:.3} on the {:.0} K model",
                c.weight,
                profile.temperatures()[0],
                1.0 - c.weight,
                profile.temperatures()[1]
            )
        } else {
            "one model, white-balanced".to_string()
        }
    )
}

/// The model set combined for a raw frame's as-shot neutral (`--white as-shot`): an error when
/// the frame records none.
pub(crate) fn for_as_shot(profile: &Profile, neutral: Option<[f32; 3]>) -> Result<Combination> {
    let n = neutral.ok_or_else(|| {
        UsageError(
            "--white as-shot: this frame records no as-shot neutral (only camera raw files do, and this one has none): give the white as --white CCT, x,y or as-shot:R,G,B".into(),
        )
    })?;
    profile
        .combine_for_apply(FrameWhite::Neutral(n.map(f64::from)))
        .with_context(|| {
            format!(
                "--white as-shot: the frame's as-shot neutral {}, {}, {}",
                n[0], n[1], n[2]
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_values() {
        assert!(matches!(
            parse_white("0.38,0.37").unwrap(),
            WhiteSpec::Fixed(FrameWhite::Xy(_))
        ));
        assert!(matches!(
            parse_white("3200").unwrap(),
            WhiteSpec::Fixed(FrameWhite::Xy(_))
        ));
        assert!(matches!(
            parse_white("as-shot:0.5,1,0.7").unwrap(),
            WhiteSpec::Fixed(FrameWhite::Neutral([0.5, 1.0, 0.7]))
        ));
        assert_eq!(parse_white(" As-Shot ").unwrap(), WhiteSpec::AsShot);
        for bad in [
            "as-shot:",
            "as-shot:1,0,1",
            "0.7,0.5",
            "nan",
            "99",
            "1,2,3",
            "x",
        ] {
            let e = parse_white(bad).unwrap_err();
            assert!(e.downcast_ref::<UsageError>().is_some(), "{bad}: {e}");
        }
    }
}
