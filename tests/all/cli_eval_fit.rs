//! The `nsrm eval` and `nsrm fit` commands, run as a user would.

use crate::common;
use common::{nsrm, tempdir};

#[test]
fn eval_default_prints_the_table_for_three_illuminants() {
    let out = nsrm().arg("eval").output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s = String::from_utf8(out.stdout).unwrap();
    for want in ["D65", "TL865", "LED-B5", "190 patches"] {
        assert!(s.contains(want), "missing {want} in\n{s}");
    }
    // One row per model, named by its first word (a substring test would take "RPRM3" for "PRM3").
    let rows: Vec<&str> = s
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|w| w.ends_with('3') || *w == "LRM")
        .collect();
    assert_eq!(rows, ["LRM", "PRM3", "RPRM3", "NSRM3"], "in\n{s}");
}

#[test]
fn eval_json_has_the_documented_shape() {
    let out = nsrm()
        .args([
            "eval",
            "--json",
            "--illuminant",
            "FL7",
            "--orders",
            "1-4",
            "--models",
            "nsrm,lrm",
        ])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let results = v["results"].as_array().unwrap();
    // NSRM at 4 orders, LRM once.
    assert_eq!(results.len(), 5);
    for r in results {
        for key in [
            "illuminant",
            "model",
            "order",
            "terms",
            "mean",
            "median",
            "p95",
            "max",
        ] {
            assert!(!r[key].is_null(), "{key} missing in {r}");
        }
        assert_eq!(r["illuminant"], "FL7");
        let pp = r["per_patch"].as_array().unwrap();
        assert_eq!(pp.len(), 190);
        assert!(pp[0]["label"].is_string() && pp[0]["dE00"].is_number());
        let mean = r["mean"].as_f64().unwrap();
        let avg = pp.iter().map(|p| p["dE00"].as_f64().unwrap()).sum::<f64>() / 190.0;
        assert!((mean - avg).abs() < 1e-9);
    }
    let terms: Vec<u64> = results
        .iter()
        .map(|r| r["terms"].as_u64().unwrap())
        .collect();
    assert_eq!(terms, [3, 6, 10, 15, 3]);
}

#[test]
fn in_sample_is_better_than_leave_one_out() {
    let run = |extra: &[&str]| -> f64 {
        let out = nsrm()
            .args(["eval", "--json", "--illuminant", "D65", "--models", "rprm"])
            .args(extra)
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["results"][0]["mean"].as_f64().unwrap()
    };
    assert!(run(&["--in-sample"]) < run(&[]));
}

#[test]
fn fit_writes_a_model_that_loads_and_refuses_to_clobber() {
    let d = tempdir("fit");
    let m = d.join("m.json");
    let out = nsrm()
        .args([
            "fit",
            "--model",
            "rprm",
            "--order",
            "4",
            "--illuminant",
            "LED-YAG",
            "-o",
        ])
        .arg(&m)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let model = nsrm::Model::load(&m).unwrap();
    assert_eq!(model.kind(), nsrm::Kind::Rprm);
    assert_eq!(model.matrix().len() / 3, 22);
    assert_eq!(model.patches().len(), 190);
    assert!(model
        .provenance()
        .illuminant
        .as_deref()
        .unwrap()
        .contains("LED-YAG"));
    let before = std::fs::read(&m).unwrap();
    let out = nsrm().args(["fit", "-o"]).arg(&m).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("already exists"));
    assert_eq!(
        std::fs::read(&m).unwrap(),
        before,
        "the existing file is untouched"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn measured_training_data_round_trip() {
    // Simulated patches written as a measured CSV give the same figures as the spectra.
    let d = tempdir("measured");
    let data = nsrm::simulate_named("nikon-d5100", "D65", "cc24", &nsrm::Grid::default()).unwrap();
    let mut csv = String::from("label,R,G,B,X,Y,Z\n");
    for i in 0..data.len() {
        let (c, x) = (data.rgb[i], data.xyz[i]);
        csv.push_str(&format!(
            "p{i},{:e},{:e},{:e},{:e},{:e},{:e}\n",
            c[0], c[1], c[2], x[0], x[1], x[2]
        ));
    }
    let f = d.join("patches.csv");
    std::fs::write(&f, csv).unwrap();
    let w = data.white_xyz;
    let white = format!("{:e},{:e},{:e}", w[0], w[1], w[2]);
    let json = |args: &[&str]| -> serde_json::Value {
        let out = nsrm()
            .args(["eval", "--json", "--models", "nsrm"])
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let measured = json(&["--training", f.to_str().unwrap(), "--white", &white]);
    let spectral = json(&["--reflectances", "cc24", "--illuminant", "D65"]);
    let a = measured["results"][0]["mean"].as_f64().unwrap();
    let b = spectral["results"][0]["mean"].as_f64().unwrap();
    assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn bad_inputs_give_clear_errors_and_exit_codes() {
    let d = tempdir("bad");
    let ragged = d.join("ragged.csv");
    std::fs::write(&ragged, "nm,a,b\n400,0.1,0.2\n410,0.3\n").unwrap();
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        (
            vec!["eval".into(), "--models".into(), "xyz".into()],
            2,
            "unknown model kind",
        ),
        (
            vec!["eval".into(), "--orders".into(), "0-9".into()],
            2,
            "--orders",
        ),
        (
            vec!["eval".into(), "--grid".into(), "400:700".into()],
            2,
            "invalid grid",
        ),
        (
            vec!["eval".into(), "--illuminant".into(), "D66".into()],
            1,
            "unknown illuminant",
        ),
        (
            vec![
                "eval".into(),
                "--reflectances".into(),
                ragged.display().to_string(),
            ],
            1,
            "line 3",
        ),
        (
            vec!["eval".into(), "--patches".into(), "B2:M9".into()],
            1,
            "rectangle",
        ),
        (
            vec!["eval".into(), "--plot".into(), "x.jpg".into()],
            2,
            ".png or .svg",
        ),
        (
            vec![
                "fit".into(),
                "--model".into(),
                "prm".into(),
                "--reflectances".into(),
                "cc24".into(),
                "--order".into(),
                "4".into(),
                "-o".into(),
                d.join("x.json").display().to_string(),
            ],
            1,
            "34 terms but only 24 patches",
        ),
    ];
    for (args, code, want) in cases {
        let out = nsrm().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: want `{want}` in: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!d.join("x.json").exists());
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn plot_writes_png_and_svg() {
    let d = tempdir("plot");
    for name in ["fig.png", "fig.svg"] {
        let p = d.join(name);
        let out = nsrm()
            .args([
                "eval",
                "--reflectances",
                "cc24",
                "--orders",
                "1-2",
                "--plot",
            ])
            .arg(&p)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let bytes = std::fs::read(&p).unwrap();
        if name.ends_with("png") {
            assert_eq!(&bytes[1..4], b"PNG");
        } else {
            assert!(String::from_utf8(bytes).unwrap().contains("NSRM2"));
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn eval_marks_fits_that_f32_cannot_evaluate_and_evaluates_the_guarded_ones_on_request() {
    // RPRM 4 on rawtoaces-190: least squares as solved takes coefficients f32 cannot evaluate
    // within 0.01 ΔE00. `eval` evaluates it as the paper does, marks it `*` and says why under the
    // table; `--f32-guard` evaluates the fit `fit` writes; `--ridge 0` with it is refused.
    let base = [
        "eval",
        "--kinds",
        "rprm",
        "--order",
        "4",
        "--illuminant",
        "D65",
        "--in-sample",
    ];
    let plain = nsrm().args(base).output().unwrap();
    common::assert_ok(&plain);
    let s = String::from_utf8(plain.stdout).unwrap();
    let row = s.lines().find(|l| l.starts_with("RPRM4")).unwrap();
    assert!(row.trim_end().ends_with('*'), "{s}");
    assert!(s.contains("* RPRM4 under D65: 1 of 1 fits"), "{s}");
    assert!(s.contains("--f32-guard"), "{s}");
    let json = nsrm().args(base).arg("--json").output().unwrap();
    common::assert_ok(&json);
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let r = &v["results"][0];
    assert_eq!(r["f32_guard"], false);
    assert_eq!(r["f32_unsafe_fits"], 1);
    assert!(r["f32_error_max"].as_f64().unwrap() > nsrm::F32_TOLERANCE_DE00);
    let guarded = nsrm().args(base).arg("--f32-guard").output().unwrap();
    common::assert_ok(&guarded);
    let g = String::from_utf8(guarded.stdout).unwrap();
    let row = g.lines().find(|l| l.starts_with("RPRM4")).unwrap();
    assert!(!row.contains('*'), "{g}");
    assert!(g.contains("f32-guarded"), "{g}");
    let both = nsrm()
        .args(base)
        .args(["--f32-guard", "--ridge", "0"])
        .output()
        .unwrap();
    assert_eq!(both.status.code(), Some(2), "{}", common::stderr(&both));
}
