//! What went wrong in a chart shot, from its reading: the neutral ramp (camera response against
//! the reference Y of the neutral patches: its intercept is veiling glare, its curvature a
//! non-linear response), clipped and nearly clipped patches, uneven light, noise and a chart
//! too small in the frame. Each finding says what it measured and what to do.
//!
//! Veiling glare (flare) adds about the same light to every patch: on the ramp `camera = a·Y + b`
//! it is the intercept `b`, reported as a fraction of the white's response `a·100`. Glare
//! compensation ([`Ramp::glare_rgb`], [`remove_glare`]) subtracts that uniform term from every
//! patch before the fit, as dcamprof's glare matching does.

use super::extract::{Extraction, Flag};
use super::flat;
use super::reference::Reference;
use nsrm::xyz_to_lab;

/// Largest reference chroma C*ab of a neutral patch.
const NEUTRAL_CHROMA: f64 = 4.0;
/// Glare (intercept over white) above which it is reported as a problem.
pub(crate) const GLARE_WARN: f64 = 0.003;
/// A patch whose largest channel reaches this fraction of the clipping level is "near clipping".
pub const NEAR_CLIP: f64 = 0.9;
/// A white patch below this fraction of the clipping level is under-exposed (noise, quantisation).
const UNDER_EXPOSED: f64 = 0.2;
/// Light non-uniformity (max/min) above which uneven light is reported.
const UNEVEN: f64 = 1.05;
/// Relative standard error of a patch's mean above which its reading is called noisy.
const NOISY: f64 = 0.005;
/// Fewest pixels per patch for a reading that is not "too small".
const SMALL_PATCH_PIXELS: usize = 100;
/// Change of a neutral's R/G or B/G from the brightest to the darkest neutral above which the
/// neutrals are said to change colour with brightness.
const COLOUR_DRIFT: f64 = 0.05;

/// The neutral patches' camera response against their reference Y, a line per channel.
#[derive(Debug, Clone, PartialEq)]
pub struct Ramp {
    /// The neutral patches used: label, reference Y, camera RGB (brightest first).
    pub points: Vec<(String, f64, [f64; 3])>,
    /// Camera units per unit of reference Y, per channel.
    pub slope: [f64; 3],
    /// Camera response at Y = 0, per channel.
    pub intercept: [f64; 3],
    /// Largest distance of a neutral's G from its line, as a fraction of the white's G.
    pub nonlinearity: f64,
}

/// Whether the reference XYZ `xyz` (relative to `white`) is a neutral patch.
pub(crate) fn is_neutral(xyz: [f64; 3], white: [f64; 3]) -> bool {
    let lab = xyz_to_lab(xyz, white);
    xyz[1] > 1.0 && lab[1].hypot(lab[2]) < NEUTRAL_CHROMA
}

impl Ramp {
    /// The ramp of the usable neutral patches; `None` with fewer than 3 of them.
    pub fn of(ex: &Extraction, white: [f64; 3]) -> Option<Ramp> {
        let mut points: Vec<(String, f64, [f64; 3])> = ex
            .patches
            .iter()
            .filter(|p| p.usable() && is_neutral(p.xyz, white))
            .map(|p| (p.label.clone(), p.xyz[1], p.rgb))
            .collect();
        if points.len() < 3 {
            return None;
        }
        points.sort_by(|a, b| b.1.total_cmp(&a.1));
        let n = points.len() as f64;
        let my = points.iter().map(|p| p.1).sum::<f64>() / n;
        let syy = points.iter().map(|p| (p.1 - my).powi(2)).sum::<f64>();
        if !(syy > 0.0) {
            return None;
        }
        let mut slope = [0.0; 3];
        let mut intercept = [0.0; 3];
        for k in 0..3 {
            let mc = points.iter().map(|p| p.2[k]).sum::<f64>() / n;
            let syc = points
                .iter()
                .map(|p| (p.1 - my) * (p.2[k] - mc))
                .sum::<f64>();
            slope[k] = syc / syy;
            intercept[k] = mc - slope[k] * my;
        }
        let wg = slope[1] * 100.0;
        let nonlinearity = points
            .iter()
            .map(|p| (p.2[1] - slope[1] * p.1 - intercept[1]).abs() / wg)
            .fold(0.0, f64::max);
        let ok = slope.iter().chain(&intercept).all(|v| v.is_finite()) && wg > 0.0;
        ok.then_some(Ramp {
            points,
            slope,
            intercept,
            nonlinearity,
        })
    }

    /// The camera response of the perfect white (Y = 100) on the ramp, glare left out.
    pub(crate) fn white_rgb(&self) -> [f64; 3] {
        self.slope.map(|s| s * 100.0)
    }

    /// The glare in G: the intercept as a fraction of the white's G.
    pub fn glare(&self) -> f64 {
        self.intercept[1] / (self.slope[1] * 100.0)
    }

    /// The uniform glare term per channel (the positive intercepts; a negative one is no glare).
    pub(crate) fn glare_rgb(&self) -> [f64; 3] {
        self.intercept.map(|v| v.max(0.0))
    }

    /// How far the darkest neutral's R/G and B/G are from the brightest's (relative).
    fn colour_drift(&self) -> [f64; 2] {
        let (hi, lo) = (&self.points[0].2, &self.points[self.points.len() - 1].2);
        [0, 2].map(|k| (lo[k] / lo[1]) / (hi[k] / hi[1]) - 1.0)
    }
}

/// Subtracts a uniform glare term (camera RGB) from every patch of `ex`.
pub(crate) fn remove_glare(ex: &mut Extraction, glare: [f64; 3]) {
    for p in &mut ex.patches {
        for k in 0..3 {
            p.rgb[k] -= glare[k];
        }
    }
}

/// How serious a finding is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Measured and fine.
    Ok,
    /// Worth knowing.
    Note,
    /// It costs accuracy: act on it.
    Warning,
}

/// One line of the diagnosis: what was measured and what to do.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Finding {
    /// What it is about (`glare`, `clipping`, `exposure`, `light`, `noise`, `size`, `linearity`,
    /// `reference`).
    pub(crate) topic: &'static str,
    /// How serious.
    pub severity: Severity,
    /// What was measured.
    pub text: String,
    /// What to do (empty when nothing).
    pub advice: String,
}

fn finding(topic: &'static str, severity: Severity, text: String, advice: &str) -> Finding {
    Finding {
        topic,
        severity,
        text,
        advice: advice.to_string(),
    }
}

/// What the reading of a chart shot says about the shot: `ex` the patches as read (before any
/// glare compensation), `flat_nonuniformity` the light's non-uniformity when `--flat` measured
/// it, `score` the reading's match to the reference (median ΔE00).
pub fn diagnose(
    ex: &Extraction,
    reference: &Reference,
    flat_nonuniformity: Option<f64>,
    score: f64,
) -> Vec<Finding> {
    let mut out = Vec::new();
    let ramp = Ramp::of(ex, reference.white);
    match &ramp {
        Some(r) => ramp_findings(r, flat_nonuniformity.is_some(), &mut out),
        None => out.push(finding(
            "glare",
            Severity::Note,
            "fewer than 3 usable neutral patches: glare and linearity not measured".into(),
            "",
        )),
    }
    exposure_findings(ex, &mut out);
    light_findings(ex, reference, flat_nonuniformity, &mut out);
    size_and_noise_findings(ex, &mut out);
    if score > 3.0 {
        out.push(finding(
            "reference",
            Severity::Warning,
            format!("the reading matches its reference poorly (median ΔE00 {score:.2} after the best 3×3 map)"),
            "check the chart's edition (charts made before Nov 2014 have other reference values: the cc24-before2014 reference) and that the frame is linear (raw, linear EXR/TIFF)",
        ));
    }
    out.sort_by_key(|f| std::cmp::Reverse(f.severity));
    out
}

fn ramp_findings(r: &Ramp, flat_given: bool, out: &mut Vec<Finding>) {
    let g = r.glare();
    let rgb = r.intercept.map(|v| v / (r.slope[1] * 100.0) * 100.0);
    let text = format!(
        "veiling glare: the neutral ramp's intercept is {:.2} % of white in G (R {:.2} %, B {:.2} %); {} neutral patches",
        100.0 * g,
        rgb[0],
        rgb[2],
        r.points.len()
    );
    if g > GLARE_WARN {
        let mut advice = "dark patches read too bright: shade the lens (a hood), keep bright light and windows out of and near the frame, do not backlight the chart; or fit with glare compensation".to_string();
        if !flat_given {
            advice.push_str(
                "; do not compensate light from the neutral patches here: on a CC24 it reads the glare as uneven light",
            );
        }
        out.push(finding("glare", Severity::Warning, text, &advice));
    } else {
        out.push(finding("glare", Severity::Ok, text, ""));
    }
    let d = r.colour_drift();
    let worst = d[0].abs().max(d[1].abs());
    if worst > COLOUR_DRIFT {
        out.push(finding(
            "glare",
            Severity::Warning,
            format!(
                "the neutrals change colour with brightness: the darkest's R/G is {:+.0} % and B/G {:+.0} % off the brightest's",
                100.0 * d[0],
                100.0 * d[1]
            ),
            "light of another colour reaches the dark patches (flare from a window or a lamp of another kind, mixed light): light the chart with one kind of light and shade the lens",
        ));
    }
    let sev = if r.nonlinearity > 0.01 {
        Severity::Warning
    } else {
        Severity::Ok
    };
    out.push(finding(
        "linearity",
        sev,
        format!(
            "the neutral ramp is linear to {:.2} % of white in G",
            100.0 * r.nonlinearity
        ),
        if sev == Severity::Ok {
            ""
        } else {
            "flare (see the glare lines), a channel near clipping, or a camera tone curve (a JPEG) bends the ramp: shade the lens, expose the white patch at 50–80 % of clipping, shoot raw"
        },
    ));
}

fn exposure_findings(ex: &Extraction, out: &mut Vec<Finding>) {
    let clipped: Vec<&str> = ex
        .patches
        .iter()
        .filter(|p| p.flags.contains(&Flag::Clipped))
        .map(|p| p.label.as_str())
        .collect();
    let Some(level) = ex.white_level else {
        if !clipped.is_empty() {
            out.push(clip_finding(&clipped));
        }
        return;
    };
    let near: Vec<&str> = ex
        .patches
        .iter()
        .filter(|p| p.usable() && p.rgb.iter().any(|&v| v >= NEAR_CLIP * level))
        .map(|p| p.label.as_str())
        .collect();
    if !clipped.is_empty() {
        out.push(clip_finding(&clipped));
    }
    if !near.is_empty() {
        out.push(finding(
            "clipping",
            Severity::Warning,
            format!(
                "nearly clipped (a channel at {:.0} % of the clipping level or more): {}",
                100.0 * NEAR_CLIP,
                near.join(", ")
            ),
            "the sensor's response bends near clipping: expose 1/3 to 1 stop less",
        ));
    }
    let top = ex
        .patches
        .iter()
        .filter(|p| p.usable())
        .map(|p| p.rgb.iter().cloned().fold(0.0, f64::max))
        .fold(0.0, f64::max);
    if clipped.is_empty() && near.is_empty() {
        let sev = if top < UNDER_EXPOSED * level {
            Severity::Warning
        } else {
            Severity::Ok
        };
        out.push(finding(
            "exposure",
            sev,
            format!(
                "the brightest patch reaches {:.0} % of the clipping level",
                100.0 * top / level
            ),
            if sev == Severity::Ok {
                ""
            } else {
                "under-exposed: noise and quantisation grow; expose so the white patch sits at 50–80 % of clipping"
            },
        ));
    }
}

fn clip_finding(clipped: &[&str]) -> Finding {
    finding(
        "clipping",
        Severity::Warning,
        format!("clipped, left out of the fit: {}", clipped.join(", ")),
        "expose less (the white patch at 50–80 % of clipping), or keep a reflection off those patches",
    )
}

fn light_findings(
    ex: &Extraction,
    reference: &Reference,
    measured: Option<f64>,
    out: &mut Vec<Finding>,
) {
    let (u, how) = match measured {
        Some(u) => (u, "measured, and compensated"),
        None => match flat::from_neutrals(ex, reference) {
            Ok(f) => (
                f.nonuniformity,
                "estimated from the neutral patches, not compensated",
            ),
            Err(_) => return,
        },
    };
    let sev = if u > UNEVEN && measured.is_none() {
        Severity::Note
    } else {
        Severity::Ok
    };
    out.push(finding(
        "light",
        sev,
        format!(
            "light non-uniformity over the chart {:.1} % (max/min {u:.3}; {how})",
            100.0 * (u - 1.0)
        ),
        if sev == Severity::Ok {
            ""
        } else {
            "light the chart evenly (two lights at 45°, or the chart small in an even light), or shoot a flat frame (a grey card in the chart's place) and compensate with it; on a CC24 the neutral estimate also reads glare as uneven light"
        },
    ));
}

fn size_and_noise_findings(ex: &Extraction, out: &mut Vec<Finding>) {
    let usable: Vec<_> = ex.patches.iter().filter(|p| p.usable()).collect();
    let Some(min_px) = usable.iter().map(|p| p.count).min() else {
        return;
    };
    let sev = if min_px < SMALL_PATCH_PIXELS {
        Severity::Warning
    } else {
        Severity::Ok
    };
    out.push(finding(
        "size",
        sev,
        format!("the smallest patch is read from {min_px} pixels"),
        if sev == Severity::Ok {
            ""
        } else {
            "the chart is too small in the frame: come closer so that it fills a third of the frame or more"
        },
    ));
    // The relative standard error of each patch's mean, worst channel (texture and noise).
    let mut worst = (0.0f64, "");
    for p in &usable {
        for k in 0..3 {
            let se = p.std[k] / (p.count as f64).sqrt() / p.rgb[k].abs().max(f64::MIN_POSITIVE);
            if se > worst.0 {
                worst = (se, p.label.as_str());
            }
        }
    }
    let sev = if worst.0 > NOISY {
        Severity::Warning
    } else {
        Severity::Ok
    };
    out.push(finding(
        "noise",
        sev,
        format!(
            "noise: the patch means are known to {:.2} % or better (worst: {})",
            100.0 * worst.0,
            worst.1
        ),
        if sev == Severity::Ok {
            ""
        } else {
            "noisy readings: lower the ISO, expose more, or come closer"
        },
    ));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capture::{read, CaptureFrame, ReadingOptions};
    use crate::scene::{render, ChartColours, SceneOptions};
    use crate::ChartKind;
    use nsrm_io::display::{ChartFrame, Transfer};
    use std::sync::Arc;

    /// A rendered CC24 scene with `glare` (a fraction of the white's response) added to every
    /// pixel, read at its corners.
    fn reading(glare: f64) -> crate::capture::Capture {
        let colours = ChartColours::simulate(ChartKind::Cc24, "nikon-d5100", "D65", None).unwrap();
        let corners = [[60.0, 50.0], [460.0, 60.0], [450.0, 330.0], [70.0, 320.0]];
        let opts = SceneOptions {
            width: 520,
            height: 380,
            corners: Some(corners),
            exposure: 0.6,
            ..Default::default()
        };
        let (mut frame, _, _) = render(&colours, &opts).unwrap();
        let white = colours.white_rgb.map(|v| v * opts.exposure);
        for px in frame.data.chunks_exact_mut(3) {
            for k in 0..3 {
                px[k] += (glare * white[k]) as f32;
            }
        }
        // The reference is the rendered chart's own XYZ: without glare its ramp goes through 0.
        let grid = nsrm::Grid::default();
        let light = nsrm::Illuminant::from_name_or_path("D65").unwrap();
        let reference = Reference {
            name: "simulated".into(),
            chart: ChartKind::Cc24,
            xyz: colours.xyz.clone(),
            white: nsrm::white_xyz(&light, &grid).unwrap(),
        };
        let f = Arc::new(CaptureFrame::from_decoded(
            ChartFrame {
                frame,
                transfer: Transfer::Linear,
                max_code: None,
                camera: None,
            },
            "scene.exr".into(),
            "0".repeat(64),
        ));
        read(
            &f,
            &reference,
            &ReadingOptions {
                corners: Some(corners),
                ..Default::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn the_ramp_measures_added_glare_and_compensation_removes_it() {
        let clean = reading(0.0);
        let r0 = Ramp::of(&clean.extraction, clean.reference.white).unwrap();
        let glared = reading(0.02);
        let r1 = Ramp::of(&glared.extraction, glared.reference.white).unwrap();
        // The glare added is measured (the clean scene's own intercept aside).
        let measured = r1.glare() - r0.glare();
        assert!((measured - 0.02).abs() < 0.004, "{measured}");
        let f = diagnose(&glared.extraction, &glared.reference, None, glared.score);
        assert!(
            f.iter()
                .any(|x| x.topic == "glare" && x.severity == Severity::Warning),
            "{f:?}"
        );
        let f0 = diagnose(&clean.extraction, &clean.reference, None, clean.score);
        assert!(
            !f0.iter()
                .any(|x| x.topic == "glare" && x.severity == Severity::Warning),
            "{f0:?}"
        );
        // Removing the measured term gives a ramp through the origin.
        let mut ex = glared.extraction.clone();
        remove_glare(&mut ex, r1.glare_rgb());
        let r2 = Ramp::of(&ex, glared.reference.white).unwrap();
        assert!(r2.glare().abs() < 1e-9, "{}", r2.glare());
    }

    /// Mean in-sample ΔE00 of an LRM fitted on a reading.
    fn lrm_mean(c: &crate::capture::Capture) -> f64 {
        let data = c.training_set();
        let opts = nsrm::FitOptions::default();
        let f = nsrm::fit_with(nsrm::Kind::Lrm, 1, &data, &opts).unwrap();
        let de: Vec<f64> = data
            .rgb
            .iter()
            .zip(&data.xyz)
            .map(|(c, x)| nsrm::delta_e00_xyz(f.apply_f64(*c), *x, data.white_xyz))
            .collect();
        de.iter().sum::<f64>() / de.len() as f64
    }

    /// The fit error with and without glare compensation on rendered scenes with added glare
    /// (`cargo test --lib compensation_removes -- --nocapture` prints them). Compensation takes
    /// out the added glare whatever its level (the fits after it agree), and it pays once the
    /// glare is past the ramp's own precision (its intercept without glare).
    #[test]
    fn compensation_removes_added_glare_whatever_its_level() {
        let clean = reading(0.0);
        let clean_mean = lrm_mean(&clean);
        let own = Ramp::of(&clean.extraction, clean.reference.white)
            .unwrap()
            .glare();
        let mut after_all = Vec::new();
        for glare in [0.005, 0.01, 0.02, 0.05] {
            let mut c = reading(glare);
            let before = lrm_mean(&c);
            c.compensate_glare().unwrap();
            let after = lrm_mean(&c);
            println!(
                "glare {:.1} % of white: LRM mean ΔE00 {before:.3} → {after:.3} with compensation (no glare: {clean_mean:.3}; the clean ramp's own intercept {:.2} %)",
                100.0 * glare,
                100.0 * own
            );
            if glare > 10.0 * own.abs() {
                assert!(after < before, "{glare}: {after} vs {before}");
            }
            after_all.push(after);
        }
        let spread = after_all.iter().cloned().fold(f64::MIN, f64::max)
            - after_all.iter().cloned().fold(f64::MAX, f64::min);
        assert!(spread < 0.05, "{after_all:?}");
    }
}
