//! `apply --white`: the frame's white for a two-illuminant model (or a white-balanced single
//! model), and the model(s) `apply` runs for it.

use super::common::UsageError;
use anyhow::{Context, Result};
use nsrm::colorimetry::temperature::temperature_xy;
use nsrm::model::dual_illuminant::{FrameWhite, Profile};
use nsrm::Model;
use std::path::Path;

/// Parses `--white`: `CCT` (kelvin: Planckian below 4000 K, CIE daylight from 4000 K), `x,y`, or
/// `as-shot:R,G,B` / `neutral:R,G,B` (the camera's response to the frame's white, e.g. a raw
/// file's AsShotNeutral).
pub fn parse_white(s: &str) -> Result<FrameWhite> {
    let t = s.trim();
    let nums = |v: &str| -> Option<Vec<f64>> {
        v.split(',')
            .map(|x| x.trim().parse::<f64>().ok().filter(|f| f.is_finite()))
            .collect()
    };
    let lower = t.to_ascii_lowercase();
    if lower == "as-shot" {
        return Err(UsageError(
            "--white as-shot: this build reads no raw metadata into frames yet; give the as-shot neutral as --white as-shot:R,G,B (e.g. from `exiftool -AsShotNeutral`)".into(),
        )
        .into());
    }
    for prefix in ["as-shot:", "neutral:"] {
        if let Some(rest) = lower.strip_prefix(prefix) {
            return match nums(rest).as_deref() {
                Some([r, g, b]) if *r > 0.0 && *g > 0.0 && *b > 0.0 => {
                    Ok(FrameWhite::Neutral([*r, *g, *b]))
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
            Ok(FrameWhite::Xy(xy))
        }
        Some([x, y]) if *x > 0.0 && *y > 0.0 && x + y < 1.0 => Ok(FrameWhite::Xy([*x, *y])),
        _ => Err(UsageError(format!(
            "--white {s}: expected a temperature in kelvin (e.g. 4300), a chromaticity x,y (e.g. 0.3805,0.3768) or as-shot:R,G,B"
        ))
        .into()),
    }
}

/// The model(s) `apply` runs: without `--white` the model file's one model; with it, the model
/// set combined for that white (one part, or two whose outputs are summed).
pub fn models_for_apply(path: &Path, white: Option<&str>) -> Result<Vec<Model>> {
    let Some(w) = white else {
        return match Model::load(path) {
            Ok(m) => Ok(vec![m]),
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
    let fw = parse_white(w)?;
    let profile = Profile::load(path).context("--model")?;
    let c = profile
        .combine(fw)
        .with_context(|| format!("--white {w}"))?;
    eprintln!(
        "nsrm apply: white x, y {:.4}, {:.4} ({:.0} K), camera neutral {:.4}, {:.4}, {:.4}; {}",
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
    );
    Ok(c.parts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn white_values() {
        assert!(matches!(
            parse_white("0.38,0.37").unwrap(),
            FrameWhite::Xy(_)
        ));
        assert!(matches!(parse_white("3200").unwrap(), FrameWhite::Xy(_)));
        assert!(matches!(
            parse_white("as-shot:0.5,1,0.7").unwrap(),
            FrameWhite::Neutral([0.5, 1.0, 0.7])
        ));
        for bad in [
            "as-shot",
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
