//! Camera profiles and two-illuminant models, judged by programs nobody here wrote: colour-hdri
//! (the DNG white-balance weighting), exiftool (the DCP's tags) and RawTherapee (develops a
//! synthetic DNG with the exported DCP). Each judge is installed by `.ci/install.d/40-profiles.sh`;
//! a missing one is a SKIP, and a failure under `CI=true`.

use crate::common::{nsrm_in, nsrm_ok, stderr, tempdir};
use nsrm::Kind;
use nsrm::Mat3;
use nsrm::{cct, temperature_xy, D50_XY};
use nsrm::{fit_with, FitOptions};
use nsrm::{simulate_named, Grid};
use nsrm::{FrameWhite, Profile};
use std::path::Path;
use std::process::{Command, Stdio};

fn skip(msg: &str) {
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{msg} (required under CI=true)");
    }
    println!("SKIP: {msg}");
}

/// Whether `python3` can import every module of `mods`.
fn python_with(mods: &[&str]) -> bool {
    let code = mods
        .iter()
        .map(|m| format!("import {m}"))
        .collect::<Vec<_>>()
        .join("; ");
    Command::new("python3")
        .args(["-W", "ignore", "-c", &code])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn python(code: &str, input: &str) -> String {
    let mut child = Command::new("python3")
        .args(["-W", "ignore", "-c", code])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3 runs");
    use std::io::Write;
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "python failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn model(kind: Kind, ill: &str) -> nsrm::Model {
    let d = simulate_named("nikon-d5100", ill, "rawtoaces-190", &Grid::default()).unwrap();
    let o = FitOptions {
        preserve_white: true,
        ..Default::default()
    };
    fit_with(kind, 3, &d, &o).unwrap().model
}

fn mat(m: &nsrm::Model) -> Mat3 {
    let v = m.matrix();
    [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]]
}

/// colour-hdri's `camera_neutral_to_xy` (the DNG fixed point over interpolated colour matrices)
/// and Robertson CCT agree with nsrm's for a two-illuminant LRM, whose colour matrices are its
/// inverted matrices normalised as the DNG SDK does.
#[test]
fn colour_hdri_judges_the_white_balance_weighting() {
    if !python_with(&["colour_hdri", "numpy"]) {
        return skip("python3 with colour-hdri and numpy is not installed");
    }
    let p = Profile::dual(model(Kind::Lrm, "A"), model(Kind::Lrm, "D65")).unwrap();
    let d50 = crate::common::mat::xy_to_xyz(D50_XY);
    let cms: Vec<Mat3> = p
        .models()
        .iter()
        .map(|m| {
            let inv = crate::common::mat::invert(&mat(m));
            let c = crate::common::mat::apply(&inv, d50.map(|v| v * m.white_xyz()[1]));
            let k = 1.0 / c.iter().cloned().fold(f64::MIN, f64::max);
            inv.map(|r| r.map(|v| v * k))
        })
        .collect();
    let [t1, t2] = p.temperatures();
    let temps = [2600.0, 3200.0, 4000.0, 4800.0, 5600.0, 7000.0];
    let neutrals: Vec<[f64; 3]> = temps
        .iter()
        .map(|&t| p.neutral_for_xy(temperature_xy(t).unwrap()).unwrap())
        .collect();
    let input =
        serde_json::json!({"t1": t1, "t2": t2, "cm1": cms[0], "cm2": cms[1], "n": neutrals});
    let code = r#"
import json, sys, numpy as np, colour
from colour_hdri import camera_neutral_to_xy
from colour.temperature import uv_to_CCT_Robertson1968
d = json.load(sys.stdin)
for n in d["n"]:
    xy = camera_neutral_to_xy(np.array(n), d["t1"], d["t2"], np.array(d["cm1"]), np.array(d["cm2"]),
                              np.identity(3), np.identity(3), np.ones(3), epsilon=1e-12)
    t = uv_to_CCT_Robertson1968(colour.UCS_to_uv(colour.XYZ_to_UCS(colour.xy_to_XYZ(xy))))[0]
    print(xy[0], xy[1], t)
"#;
    let out = python(code, &input.to_string());
    let rows: Vec<Vec<f64>> = out
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), temps.len());
    for ((t, n), row) in temps.iter().zip(&neutrals).zip(&rows) {
        let ours = p.xy_for_neutral(*n).unwrap();
        let want = temperature_xy(*t).unwrap();
        assert!(
            (ours[0] - row[0]).abs() < 2e-5 && (ours[1] - row[1]).abs() < 2e-5,
            "{t} K: nsrm {ours:?}, colour-hdri {row:?}"
        );
        assert!((ours[0] - want[0]).abs() < 1e-6 && (ours[1] - want[1]).abs() < 1e-6);
        let ct = cct(ours).unwrap();
        assert!(
            (ct - row[2]).abs() < 0.5 + 1e-4 * ct,
            "{t} K: CCT {ct} vs {}",
            row[2]
        );
        // The weight follows from the temperature by the DNG rule.
        let w = p.weight(ct);
        let want_w = if ct <= t1 {
            1.0
        } else if ct >= t2 {
            0.0
        } else {
            (1.0 / ct - 1.0 / t2) / (1.0 / t1 - 1.0 / t2)
        };
        assert!((w - want_w).abs() < 1e-12);
    }
}

/// A grey lit by real lights between the two calibration illuminants (CIE FL11, LED-B3, D50)
/// comes out neutral from the two-illuminant NSRM when the frame's white is the camera's real
/// response to that light.
#[test]
fn a_grey_under_a_real_light_between_comes_out_neutral() {
    let p = Profile::dual(model(Kind::Nsrm, "A"), model(Kind::Nsrm, "D65")).unwrap();
    for light in ["FL11", "LED-B3", "D50", "FL2"] {
        let d = simulate_named("nikon-d5100", light, "cc24", &Grid::default()).unwrap();
        let c = p
            .combine(FrameWhite::Neutral(d.white_rgb.unwrap()))
            .unwrap();
        for i in 18..24 {
            let out = nsrm::xyz_to_lab(c.apply_f64(d.rgb[i]), c.white_xyz);
            let want = nsrm::xyz_to_lab(d.xyz[i], d.white_xyz);
            assert!(
                (out[1] - want[1]).abs() < 0.5 && (out[2] - want[2]).abs() < 0.5,
                "{light} patch {i}: {out:?} vs {want:?}"
            );
        }
        // A flat grey (the camera's response to the light, scaled) is exactly the white, scaled.
        let g = c.apply_f64(d.white_rgb.unwrap().map(|v| 0.18 * v));
        for k in 0..3 {
            assert!(
                (g[k] - 0.18 * c.white_xyz[k]).abs() < 1e-6 * c.white_xyz[1],
                "{light}"
            );
        }
        // The white found is the light's own chromaticity (to what the camera can tell).
        let sum: f64 = d.white_xyz.iter().sum();
        let xy = [d.white_xyz[0] / sum, d.white_xyz[1] / sum];
        assert!(
            (c.xy[0] - xy[0]).abs() < 0.01 && (c.xy[1] - xy[1]).abs() < 0.01,
            "{light}: {:?} vs {xy:?}",
            c.xy
        );
    }
}

fn fit_cli(dir: &Path, kind: &str, ill: &str, out: &str) {
    nsrm_ok(
        dir,
        &[
            "fit",
            "--kind",
            kind,
            "--illuminant",
            ill,
            "--preserve-white",
            "-o",
            out,
        ],
    );
}

/// `combine` and `export --format dcp` on the command line; exiftool lists the DCP's tags;
/// malformed requests write nothing.
#[test]
fn dcp_export_and_refusals() {
    let dir = tempdir("profiles-dcp");
    fit_cli(&dir, "nsrm", "A", "a.json");
    fit_cli(&dir, "nsrm", "D65", "d65.json");
    fit_cli(&dir, "lrm", "D65", "lrm.json");
    fit_cli(&dir, "prm", "D65", "prm.json");
    fit_cli(&dir, "nsrm", "P4000", "p4000.json");
    nsrm_ok(&dir, &["combine", "a.json", "d65.json", "-o", "dual.json"]);
    let out = nsrm_ok(
        &dir,
        &[
            "export",
            "--model",
            "dual.json",
            "--format",
            "dcp",
            "-o",
            "dual.dcp",
        ],
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(text.contains("approximation error"), "{text}");
    let out = nsrm_ok(
        &dir,
        &[
            "export", "--model", "d65.json", "--format", "dcp", "-o", "one.dcp",
        ],
    );
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let max: f64 = text
        .split("max ")
        .last()
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or(f64::NAN);
    assert!(max < 0.5, "{text}");
    // Refusals write nothing.
    for (args, want) in [
        (
            vec!["combine", "a.json", "lrm.json", "-o", "bad.json"],
            "different kinds",
        ),
        (
            vec![
                "export", "--model", "prm.json", "--format", "dcp", "-o", "bad.dcp",
            ],
            "exposure-invariant",
        ),
        (
            vec![
                "export",
                "--model",
                "p4000.json",
                "--format",
                "dcp",
                "-o",
                "bad.dcp",
            ],
            "not one a DCP can name",
        ),
        (
            vec![
                "export",
                "--model",
                "d65.json",
                "--format",
                "dcp",
                "--max-de00",
                "0.0001",
                "-o",
                "bad.dcp",
            ],
            "exceeds the limit",
        ),
        (
            vec![
                "export",
                "--model",
                "dual.json",
                "--format",
                "clf",
                "-o",
                "bad.clf",
            ],
            "two calibration illuminants",
        ),
    ] {
        let o = nsrm_in(&dir, &args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        for f in ["bad.json", "bad.dcp", "bad.clf"] {
            assert!(!dir.join(f).exists(), "{args:?} wrote {f}");
        }
    }
    if !have("exiftool") {
        return skip("exiftool is not installed (Debian libimage-exiftool-perl)");
    }
    // `-m`: exiftool by default declines to decode any large array with a minor warning, which
    // it gives the 90×30 DCPs RawTherapee ships too; anything else is a complaint.
    let o = Command::new("exiftool")
        .args(["-m", "-a", "-G1", "-s", "dual.dcp"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let listing = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{listing}{}", stderr(&o));
    for tag in [
        "UniqueCameraModel",
        "ProfileName",
        "ProfileCopyright",
        "ColorMatrix1",
        "ColorMatrix2",
        "ForwardMatrix1",
        "ForwardMatrix2",
        "CalibrationIlluminant1",
        "CalibrationIlluminant2",
        "ProfileHueSatMapDims",
        "ProfileHueSatMapData1",
        "ProfileHueSatMapData2",
        "ProfileToneCurve",
        "ProfileEmbedPolicy",
    ] {
        assert!(listing.contains(tag), "exiftool lists no {tag}:\n{listing}");
    }
    assert!(listing.contains("Standard Light A"), "{listing}");
    assert!(!listing.contains("Warning"), "{listing}");
}

/// The two-illuminant comparison of the README (a measurement, not a check): spectral simulation
/// of the built-in D5100 on the 190-patch set, models fitted (white-preserving) under StdA and D65,
/// leave-one-out ΔE00 under lights between the two, each frame white-balanced by the camera's own
/// response to the light. Run with `cargo test --release --test all profiles::two_illuminant_table
/// -- --ignored --nocapture`.
#[test]
#[ignore]
fn two_illuminant_table() {
    use nsrm::TrainingSet;
    let grid = Grid::default();
    let sim = |ill: &str| simulate_named("nikon-d5100", ill, "rawtoaces-190", &grid).unwrap();
    let (a, d65) = (sim("A"), sim("D65"));
    let fit = |kind: Kind, d: &TrainingSet| {
        let o = FitOptions {
            preserve_white: true,
            ..Default::default()
        };
        fit_with(kind, 3, d, &o).unwrap().model
    };
    println!("| light (CCT) | NSRM 3, StdA + D65 | NSRM 3, D65 only | NSRM 3, StdA only | LRM, StdA + D65 |");
    println!("|---|---|---|---|---|");
    for light in ["D50", "FL2", "FL11", "LED-B3"] {
        let t = sim(light);
        let white = FrameWhite::Neutral(t.white_rgb.unwrap());
        let mut errs = vec![Vec::new(); 4];
        for i in 0..t.len() {
            let keep: Vec<usize> = (0..t.len()).filter(|&j| j != i).collect();
            let (sa, sd) = (a.subset(&keep), d65.subset(&keep));
            let (na, nd) = (fit(Kind::Nsrm, &sa), fit(Kind::Nsrm, &sd));
            let (la, ld) = (fit(Kind::Lrm, &sa), fit(Kind::Lrm, &sd));
            let profiles = [
                Profile::dual(na.clone(), nd.clone()).unwrap(),
                Profile::single(nd).unwrap(),
                Profile::single(na).unwrap(),
                Profile::dual(la, ld).unwrap(),
            ];
            for (e, p) in errs.iter_mut().zip(&profiles) {
                let c = p.combine(white).unwrap();
                let out = c.apply_f64(t.rgb[i]);
                // The output is relative to the white the camera's neutral names, the reference
                // to the light's own white: each in Lab against its white.
                let lab = nsrm::xyz_to_lab(out, c.white_xyz);
                let want = nsrm::xyz_to_lab(t.xyz[i], t.white_xyz);
                e.push(nsrm::ciede2000(lab, want));
            }
        }
        let cct = {
            let s: f64 = t.white_xyz.iter().sum();
            cct([t.white_xyz[0] / s, t.white_xyz[1] / s]).unwrap()
        };
        let cells: Vec<String> = errs
            .iter()
            .map(|e| {
                let mean = e.iter().sum::<f64>() / e.len() as f64;
                let max = e.iter().cloned().fold(0.0, f64::max);
                format!("{mean:.3} / {max:.2}")
            })
            .collect();
        println!("| {light} ({cct:.0} K) | {} |", cells.join(" | "));
    }
}
