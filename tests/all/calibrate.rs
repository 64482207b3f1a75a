//! `nsrm calibrate` on the real DNG (`../shared/data/colorchart.dng`, a Canon ColorChecker
//! Passport shot): one command → model (carrying its patches), patches CSV, overlay, report
//! (text and HTML), DCP and ICC; a re-export that needs no CSV; the DCP judged by exiftool (the
//! camera's name, the light) and RawTherapee (it develops the DNG with it); the report page in
//! headless Chromium (tests/browser/report.test.mjs); glare compensation on the real shot.

use crate::common::{chart_dng, nsrm_in, nsrm_ok, skip, stderr, tempdir};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// One `nsrm calibrate DNG -o DIR --export dcp,icc` for every test here: (DIR, its stdout).
fn calibrated() -> Option<&'static (PathBuf, String)> {
    static RUN: OnceLock<Option<(PathBuf, String)>> = OnceLock::new();
    RUN.get_or_init(|| {
        let dng = chart_dng();
        if !dng.exists() {
            return None;
        }
        // Shared by every test here, so never removed.
        let work = tempdir("calibrate").keep();
        let out = nsrm_ok(
            &work,
            &[
                "calibrate",
                dng.to_str().unwrap(),
                "-o",
                "out",
                "--export",
                "dcp,icc",
            ],
        );
        Some((
            work.join("out"),
            String::from_utf8_lossy(&out.stdout).into_owned(),
        ))
    })
    .as_ref()
}

fn model_json(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("model.json")).unwrap()).unwrap()
}

#[test]
fn the_real_dng_calibrates_in_one_command() {
    let Some((dir, stdout)) = calibrated() else {
        return skip("../shared/data/colorchart.dng is absent");
    };
    for f in [
        "model.json",
        "patches.csv",
        "overlay.png",
        "report.txt",
        "report.html",
        "profile.dcp",
        "profile.icc",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    // The printed table: a row per patch, worst first (by leave-one-out), then the summary,
    // the choice said plainly, and the diagnosis.
    let rows: Vec<&str> = stdout
        .lines()
        .skip_while(|l| !l.starts_with("patch (worst first)"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .collect();
    let m = model_json(dir);
    let labels = m["training"]["patch_labels"].as_array().unwrap();
    assert_eq!(rows.len(), labels.len(), "{stdout}");
    let loo: Vec<f64> = rows
        .iter()
        .map(|r| {
            let cols: Vec<&str> = r.split_whitespace().collect();
            // label words, 3 + 3 Lab values, ΔE00, LOO (no flags on this shot).
            cols[cols.len() - 1].parse().unwrap()
        })
        .collect();
    assert!(loo.windows(2).all(|w| w[0] >= w[1]), "{loo:?}");
    for want in [
        "in-sample ΔE00:",
        "leave-one-out ΔE00:",
        "the smallest leave-one-out mean",
        "diagnosis:",
        "veiling glare",
    ] {
        assert!(stdout.contains(want), "{want}: {stdout}");
    }
    assert_eq!(
        std::fs::read_to_string(dir.join("report.txt")).unwrap(),
        *stdout
    );
    // The model carries its training patches, and its camera scale says where its white is.
    let t = &m["training"]["capture"]["training"];
    assert_eq!(t["rgb"].as_array().unwrap().len(), labels.len());
    assert_eq!(t["xyz"].as_array().unwrap().len(), labels.len());
    let scale = m["input"]["camera_scale"].as_str().unwrap();
    assert!(!scale.contains("G = 1 "), "{scale}");
    let wg = m["training"]["capture"]["white_g"].as_f64().unwrap();
    assert!(scale.contains(&format!("{wg:.6}")), "{scale} vs {wg}");
}

#[test]
fn a_capture_model_exports_with_nothing_else() {
    let Some((dir, _)) = calibrated() else {
        return skip("../shared/data/colorchart.dng is absent");
    };
    let work = tempdir("calibrate-reexport");
    let model = dir.join("model.json");
    nsrm_ok(
        &work,
        &[
            "export",
            "--model",
            model.to_str().unwrap(),
            "--format",
            "dcp",
            "-o",
            "again.dcp",
        ],
    );
    assert_eq!(
        std::fs::read(work.join("again.dcp")).unwrap(),
        std::fs::read(dir.join("profile.dcp")).unwrap(),
        "nsrm export of the model differs from calibrate's DCP"
    );
    nsrm_ok(
        &work,
        &[
            "export",
            "--model",
            model.to_str().unwrap(),
            "--format",
            "icc",
            "-o",
            "again.icc",
        ],
    );
    // A capture model written without its patches: the error names the file and the command.
    let mut m = model_json(dir);
    m["training"]["capture"]
        .as_object_mut()
        .unwrap()
        .remove("training");
    std::fs::write(work.join("old.json"), m.to_string()).unwrap();
    let o = nsrm_in(
        &work,
        &[
            "export", "--model", "old.json", "--format", "dcp", "-o", "old.dcp",
        ],
    );
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--training PATCHES.csv") && e.contains("nsrm chart extract colorchart.dng"),
        "{e}"
    );
}

/// The EXIF light source exiftool prints for a temperature, as the DCP writer names it
/// (within 6 mired of a standard light, else Other).
fn expected_light(cct: f64) -> &'static str {
    let named = [
        (2850.0, "Standard Light A"),
        (3200.0, "ISO Studio Tungsten"),
        (5000.0, "D50"),
        (5500.0, "D55"),
        (6500.0, "D65"),
        (7500.0, "D75"),
    ];
    named
        .iter()
        .find(|(t, _)| (1e6 / t - 1e6 / cct).abs() <= 6.0)
        .map_or("Other", |(_, n)| n)
}

#[test]
fn exiftool_reads_the_camera_and_the_light_from_the_dcp() {
    let Some((dir, _)) = calibrated() else {
        return skip("../shared/data/colorchart.dng is absent");
    };
    if !have("exiftool") {
        return skip("exiftool is not installed (Debian libimage-exiftool-perl)");
    }
    let o = Command::new("exiftool")
        .args(["-m", "-s", "-a"])
        .arg(dir.join("profile.dcp"))
        .output()
        .unwrap();
    let listing = String::from_utf8_lossy(&o.stdout).into_owned();
    let tag = |name: &str| {
        listing
            .lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
            .unwrap_or_else(|| panic!("no {name} in {listing}"))
    };
    let m = model_json(dir);
    let cap = &m["training"]["capture"];
    let camera = cap["camera"].as_str().unwrap();
    assert!(camera.starts_with("Canon"), "{camera}");
    assert_eq!(tag("UniqueCameraModel"), camera);
    let name = tag("ProfileName");
    let kind = m["kind"].as_str().unwrap().to_uppercase();
    assert!(name.contains(camera) && name.contains(&kind), "{name}");
    let cct = cap["light_cct"].as_f64().unwrap();
    assert!(name.contains(&format!("{cct:.0}K")), "{name} vs {cct}");
    assert_eq!(tag("CalibrationIlluminant1"), expected_light(cct));
    assert_eq!(tag("ProfileEmbedPolicy"), "Allow Copying");
    assert!(tag("ProfileCopyright").starts_with("Generated by nsrm"));
    if expected_light(cct) == "Other" {
        let v = Command::new("exiftool")
            .args(["-v3"])
            .arg(dir.join("profile.dcp"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&v.stdout);
        assert!(text.contains("IlluminantData1"), "{text}");
    }
}

#[test]
fn rawtherapee_develops_the_dng_with_the_dcp() {
    let Some((dir, _)) = calibrated() else {
        return skip("../shared/data/colorchart.dng is absent");
    };
    if let Err(why) = crate::common::rawtherapee() {
        return skip(&why);
    }
    let work = tempdir("calibrate-rt");
    let profile = |input: &str| {
        format!(
            "[Exposure]\nAuto=false\nCompensation=0\n\n[White Balance]\nEnabled=true\nSetting=Camera\n\n\
             [Color Management]\nInputProfile={input}\nToneCurve=false\nApplyLookTable=false\nApplyBaselineExposureOffset=false\nApplyHueSatMap=true\nDCPIlluminant=0\nWorkingProfile=ProPhoto\nOutputProfile=file:/usr/share/color/argyll/ref/ProPhotoLin.icm\n"
        )
    };
    let dcp = format!("file:{}", dir.join("profile.dcp").display());
    let mut outs = Vec::new();
    for (tag, input) in [("dcp", dcp.as_str()), ("camera", "(camera)")] {
        let pp3 = work.join(format!("{tag}.pp3"));
        std::fs::write(&pp3, profile(input)).unwrap();
        let out = work.join(format!("{tag}.tif"));
        let o = Command::new("rawtherapee-cli")
            .args(["-q", "-Y", "-o"])
            .arg(&out)
            .arg("-p")
            .arg(&pp3)
            .args(["-t", "-b32", "-c"])
            .arg(chart_dng())
            .output()
            .unwrap();
        assert!(
            o.status.success() && out.exists(),
            "rawtherapee-cli: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        outs.push(out);
    }
    // The DCP is what RawTherapee used: its rendering differs from the camera's own matrix.
    let py = "import sys, tifffile, numpy as np\n\
              a = tifffile.imread(sys.argv[1]).astype(float)\n\
              b = tifffile.imread(sys.argv[2]).astype(float)\n\
              print(np.abs(a - b).mean() / b.mean())";
    let o = Command::new("python3")
        .args(["-c", py])
        .args(&outs)
        .output()
        .unwrap();
    let rel: f64 = String::from_utf8_lossy(&o.stdout).trim().parse().unwrap();
    assert!(
        rel > 0.005,
        "the DCP rendering equals the camera-matrix one ({rel})"
    );
}

#[test]
fn the_report_renders_in_chromium_and_fetches_nothing() {
    let Some((dir, _)) = calibrated() else {
        return skip("../shared/data/colorchart.dng is absent");
    };
    let Some(chromium) = crate::common::browser_prerequisites() else {
        return;
    };
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    // Nothing external in the file: the SVG namespace is the only URL.
    let html = std::fs::read_to_string(dir.join("report.html"))
        .unwrap()
        .replace("http://www.w3.org/2000/svg", "");
    for external in ["http://", "https://", "href=", "src=\"/", "url("] {
        assert!(!html.contains(external), "{external} in the report");
    }
    let out_dir = root.join("target/calibrate-report");
    crate::common::run_browser_script(
        "report.test.mjs",
        "calibrate-browser",
        &chromium,
        &[
            ("REPORT_HTML", &dir.join("report.html")),
            ("REPORT_OUT", &out_dir),
        ],
    );
    assert!(out_dir.join("report.png").exists());
}

/// Glare compensation on the real shot (a backlit chart: the neutral ramp's intercept is
/// positive): the fit's in-sample mean and max ΔE00 drop.
#[test]
fn glare_compensation_lowers_the_error_on_the_real_dng() {
    let dng = chart_dng();
    if !dng.exists() {
        return skip("../shared/data/colorchart.dng is absent");
    }
    let work = tempdir("calibrate-glare");
    let stat = |extra: &[&str], dir: &str| {
        let mut args = vec![
            "calibrate",
            dng.to_str().unwrap(),
            "-o",
            dir,
            "--kind",
            "lrm",
        ];
        args.extend_from_slice(extra);
        let o = nsrm_ok(&work, &args);
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        let line = text
            .lines()
            .find(|l| l.starts_with("in-sample ΔE00:"))
            .unwrap()
            .to_string();
        let num = |key: &str| -> f64 {
            line.split(key)
                .nth(1)
                .and_then(|s| s.trim().split([',', ' ']).next())
                .and_then(|s| s.parse().ok())
                .unwrap()
        };
        (num("mean "), num("max "), text)
    };
    let (m0, x0, _) = stat(&[], "plain");
    let (m1, x1, text) = stat(&["--glare-compensation"], "glare");
    println!("LRM in-sample ΔE00 mean {m0} → {m1}, max {x0} → {x1} with --glare-compensation");
    assert!(m1 < m0 && x1 < x0, "{m0} {x0} → {m1} {x1}");
    assert!(text.contains("glare compensation: subtracted"), "{text}");
}

/// The wording fixes of issue 36 on the real DNG: `eval --capture` prints the reading's line
/// once and its `--json` names the capture's camera and reference; the summary names LRM as the
/// table does; `--white-patch 19` is the white patch's number.
#[test]
fn eval_and_fit_on_a_capture_say_things_once_and_right() {
    let dng = chart_dng();
    if !dng.exists() {
        return skip("../shared/data/colorchart.dng is absent");
    }
    let work = tempdir("calibrate-words");
    let d = dng.to_str().unwrap();
    let o = nsrm_ok(
        &work,
        &[
            "eval",
            "--capture",
            d,
            "--chart",
            "cc24",
            "--kinds",
            "lrm,rprm",
        ],
    );
    let err = stderr(&o);
    assert_eq!(err.matches("cc24 chart found").count(), 1, "{err}");
    let out = String::from_utf8_lossy(&o.stdout);
    // The summary line (the f32 notes, when any, come after it).
    let last = out
        .lines()
        .find(|l| l.contains("smallest mean"))
        .unwrap_or("");
    assert!(!last.contains("LRM1") && last.contains("LRM"), "{out}");
    let o = nsrm_ok(
        &work,
        &[
            "eval",
            "--capture",
            d,
            "--chart",
            "cc24",
            "--kinds",
            "lrm",
            "--json",
        ],
    );
    let j: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(j["camera"].as_str().unwrap().starts_with("Canon"), "{j}");
    assert_eq!(j["reflectances"], "cc24-after2014");
    let o = nsrm_ok(
        &work,
        &[
            "fit",
            "--capture",
            d,
            "--chart",
            "cc24",
            "--kind",
            "nsrm",
            "--preserve-white",
            "--white-patch",
            "19",
            "-o",
            "m.json",
        ],
    );
    let err = stderr(&o);
    assert_eq!(err.matches("cc24 chart found").count(), 1, "{err}");
    let m: Value = serde_json::from_slice(&std::fs::read(work.join("m.json")).unwrap()).unwrap();
    assert!(
        m["fit"]["preserve_white"]
            .to_string()
            .contains("19 white 9.5"),
        "{}",
        m["fit"]
    );
}
