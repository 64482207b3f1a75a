//! Camera profiles and two-illuminant models, judged by programs nobody here wrote: exiftool (the
//! DCP's tags) and RawTherapee (develops a synthetic DNG with the exported DCP; in
//! `profiles_rawtherapee.rs`). colour-hdri's judgement of the DNG white-balance weighting and the
//! two-illuminant table moved beside the code (`src/model/dual_illuminant_tests.rs`). Each judge is installed by `.ci/install.d/40-profiles.sh`;
//! a missing one is a SKIP, and a failure under `CI=true`.

use crate::common::{nsrm_in, nsrm_ok, skip, stderr, tempdir};
use nsrm::Kind;
use nsrm::{fit_with, FitOptions};
use nsrm::{simulate_named, Grid};
use nsrm::{FrameWhite, Profile};
use std::path::Path;
use std::process::Command;

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

fn model(kind: Kind, ill: &str) -> nsrm::Model {
    let d = simulate_named("nikon-d5100", ill, "rawtoaces-190", &Grid::default()).unwrap();
    let o = FitOptions {
        preserve_white: true,
        ..Default::default()
    };
    fit_with(kind, 3, &d, &o).unwrap().model
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
    // A light no EXIF light source names (4000 K) was refused; since issue 36 it is written as
    // DNG 1.6's Other (255) with its chromaticity in IlluminantData1.
    nsrm_ok(
        &dir,
        &[
            "export",
            "--model",
            "p4000.json",
            "--format",
            "dcp",
            "-o",
            "p4000.dcp",
        ],
    );
    let bytes = std::fs::read(dir.join("p4000.dcp")).unwrap();
    let tag = |t: u16| {
        bytes
            .windows(4)
            .any(|w| w[..2] == t.to_le_bytes() && w[2..] == [7, 0])
    };
    assert!(
        tag(52533),
        "no IlluminantData1 (tag 52533, UNDEFINED) in p4000.dcp"
    );
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
