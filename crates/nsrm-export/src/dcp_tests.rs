//! RawTherapee against nsrm's DNG evaluator (`Dcp::eval`, `Dcp::eval_weighted`: crate-private).
//! A two-illuminant DCP the library builds ([`super::dcp::render`]: white-preserving NSRM 3
//! under StdA and D65, as `common::dual_nsrm_model` fits it through the binary) is developed by
//! `rawtherapee-cli` (the kit's harness, `kit::rt_develop`) on a chart lit by a 4000 K Planckian
//! light. RawTherapee weights the two sides by its own white-balance temperature: the test finds
//! that weight (the one at which nsrm's evaluator best reproduces RawTherapee's patches) and
//! checks the evaluator reproduces RawTherapee there, and that the weight is told apart from
//! either side alone. (Moved from `tests/all/profiles_rawtherapee.rs`, where RawTherapee still
//! judges the DCPs `nsrm export` writes against `nsrm apply`.)
//!
//! Needs `rawtherapee-cli`, Argyll's linear ProPhoto profile and python3 with tifffile and numpy
//! (`.ci/install.d/40-profiles.sh`); without them the test prints `SKIP: …` and passes, except
//! under `CI=true`, where it fails (`kit::skip_or_fail`).

use super::dcp::{d50, prophoto_to_xyz, render, Dcp, DcpOptions, DcpTraining};
use crate::kit::{rawtherapee, rt_chart, rt_develop, skip_or_fail};
use crate::spaces;
use nsrm::{delta_e00_xyz, fit_with, simulate_named, FitOptions, Grid, Kind, Profile};

fn stats(e: &[f64]) -> (f64, f64) {
    (
        e.iter().sum::<f64>() / e.len() as f64,
        e.iter().cloned().fold(0.0, f64::max),
    )
}

#[test]
fn rawtherapee_weights_the_two_sides_and_the_evaluator_reproduces_it_there() {
    if let Err(why) = rawtherapee() {
        return skip_or_fail(&why);
    }
    let dir = tempfile::tempdir().unwrap();
    let opts = FitOptions {
        preserve_white: true,
        ..Default::default()
    };
    // StdA first: the profile orders its models by temperature, and the training sets follow.
    let mut models = Vec::new();
    let mut training = Vec::new();
    for light in ["A", "D65"] {
        let d = simulate_named("nikon-d5100", light, "rawtoaces-190", &Grid::default()).unwrap();
        models.push(fit_with(Kind::Nsrm, 3, &d, &opts).unwrap().model);
        training.push(DcpTraining {
            rgb: d.rgb,
            white_rgb: d.white_rgb,
        });
    }
    let d65 = models.pop().unwrap();
    let a = models.pop().unwrap();
    let profile = Profile::dual(a, d65).unwrap();
    let path = dir.path().join("dual.dcp");
    let (bytes, _) = render(
        &profile,
        &training,
        DcpOptions::default(),
        [-6.0, 4.0],
        None,
    )
    .unwrap();
    std::fs::write(&path, bytes).unwrap();

    let (patches, neutral, white_y) = rt_chart("P4000");
    let d = rt_develop(dir.path(), "dual", &path, &patches, neutral);
    let pp = prophoto_to_xyz();
    let rt: Vec<[f64; 3]> = d.prophoto.iter().map(|c| spaces::apply(&pp, *c)).collect();
    let white = d50().map(|v| v * white_y);
    // ΔE00 per patch against RawTherapee, the white at the perfect white's level in the frame.
    let errors = |b: &[[f64; 3]]| -> Vec<f64> {
        rt.iter()
            .zip(b)
            .map(|(x, y)| delta_e00_xyz(*x, *y, white))
            .collect()
    };

    // Which weight of side 1 (StdA) did RawTherapee use? nsrm's DNG evaluator at weight w
    // against RawTherapee's patches; Adobe's rule gives the weight `Dcp::eval` finds.
    let dcp = Dcp::parse(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(dcp.sides.len(), 2);
    // `Dcp::eval_weighted` per patch, its pipeline (the mixed matrices and map) built once per
    // weight.
    let at = |w: f64| -> Vec<[f64; 3]> {
        let p = dcp.at_weight(w);
        d.camera.iter().map(|c| p.eval(*c, neutral)).collect()
    };
    assert_eq!(at(0.3)[5], dcp.eval_weighted(d.camera[5], neutral, 0.3));
    let (_, adobe_w) = dcp.eval(d.camera[0], neutral).unwrap();
    let mut best = (f64::INFINITY, 0.0);
    for i in 0..=1000 {
        let w = i as f64 / 1000.0;
        let (m, _) = stats(&errors(&at(w)));
        if m < best.0 {
            best = (m, w);
        }
    }
    let (_, max_best) = stats(&errors(&at(best.1)));
    let (mean_adobe, max_adobe) = stats(&errors(&at(adobe_w)));
    let (mean_0, _) = stats(&errors(&at(0.0)));
    let (mean_1, _) = stats(&errors(&at(1.0)));
    let t = dcp.temperatures();
    let temp = |w: f64| 1.0 / (w / t[0] + (1.0 - w) / t[1]);
    println!(
        "RawTherapee weighted StdA by {:.3} (as at {:.0} K); the DNG rule on the same neutral gives {adobe_w:.3} ({:.0} K). nsrm's DNG evaluator vs RawTherapee: at RawTherapee's weight mean {:.4} / max {max_best:.4}, at the DNG rule's weight mean {mean_adobe:.4} / max {max_adobe:.4} ΔE00 (at D65 alone mean {mean_0:.3}, StdA alone {mean_1:.3})",
        best.1,
        temp(best.1),
        temp(adobe_w),
        best.0
    );
    // nsrm's evaluator of the DNG pipeline reproduces RawTherapee at RawTherapee's weight, and
    // that weight is told apart from either side alone.
    assert!(max_best < 0.1, "evaluator vs RawTherapee: max {max_best}");
    assert!(
        best.0 < 0.5 * mean_0.min(mean_1),
        "{best:?} {mean_0} {mean_1}"
    );
}
