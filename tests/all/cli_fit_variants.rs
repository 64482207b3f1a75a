//! `nsrm fit` and `nsrm eval` with the fit-variant flags (issue 11), run as a user would.

use crate::common;
use common::nsrm;

#[test]
fn fit_writes_the_variant_and_its_diagnostics_into_the_model_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.json");
    let out = nsrm()
        .args([
            "fit",
            "--model",
            "rprm",
            "--order",
            "3",
            "--reflectances",
            "cc24",
        ])
        .args([
            "--objective",
            "de00",
            "--ridge",
            "auto",
            "--preserve-white",
            "-o",
        ])
        .arg(&path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    for want in [
        "objective de00",
        "coefficient norm",
        "condition number",
        "(GCV)",
        "perfect-white",
        "in-sample ΔE00 mean",
    ] {
        assert!(err.contains(want), "missing {want} in {err}");
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let fit = &v["fit"];
    assert_eq!(fit["objective"], "de00");
    assert_eq!(fit["preserve_white"], "perfect-white");
    assert!(fit["ridge_auto"].as_bool().unwrap());
    assert!(fit["ridge_lambda"].as_f64().unwrap() > 0.0);
    assert!(fit["coefficient_norm"].as_f64().unwrap() > 0.0);
    assert!(fit["condition_number"].as_f64().unwrap() > 1.0);
    // The file loads back with its report.
    let m = nsrm::Model::load(&path).unwrap();
    let r = m.fit_report().unwrap();
    assert_eq!(r.objective, "de00");
    assert!(r.de00_end.unwrap() <= r.de00_start.unwrap());
}

#[test]
fn eval_variants_prints_one_table_and_json_carries_the_variant_fields() {
    let out = nsrm()
        .args([
            "eval",
            "--variants",
            "--reflectances",
            "cc24",
            "--illuminant",
            "D65",
        ])
        .args(["--models", "lrm,nsrm", "--in-sample"])
        .output()
        .unwrap();
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for want in [
        "LRM ls",
        "LRM de00+preserve-white",
        "NSRM3 ridge-auto",
        "NSRM3 white-balanced",
        "p95",
        "lowest mean",
        "lowest max",
    ] {
        assert!(s.contains(want), "missing {want} in\n{s}");
    }
    assert!(!s.contains("LRM white-balanced"), "{s}");
    let out = nsrm()
        .args([
            "eval",
            "--variants",
            "--reflectances",
            "cc24",
            "--illuminant",
            "D65",
        ])
        .args(["--models", "nsrm", "--in-sample", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let rs = v["results"].as_array().unwrap();
    let names: Vec<&str> = rs.iter().map(|r| r["variant"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "ls",
            "de00",
            "de00+preserve-white",
            "ridge-auto",
            "white-balanced"
        ]
    );
    for r in rs {
        for f in [
            "objective",
            "preserve_white",
            "ridge",
            "normalise",
            "mean",
            "median",
            "p95",
            "max",
        ] {
            assert!(r.get(f).is_some(), "{f} missing in {r}");
        }
    }
    let mean = |i: usize| rs[i]["mean"].as_f64().unwrap();
    assert!(mean(1) < mean(0), "de00 does not lower the in-sample mean");
}

#[test]
fn bad_variant_flags_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("m.json");
    for (args, want) in [
        (vec!["eval", "--objective", "de00:1"], "--objective"),
        (vec!["eval", "--ridge=-1"], "--ridge"),
        (vec!["eval", "--normalise", "balanced"], "--normalise"),
        (vec!["eval", "--white-patch", "A1"], "--white-patch"),
        (
            vec!["eval", "--variants", "--objective", "de00"],
            "cannot be used",
        ),
        (
            vec!["fit", "--model", "lrm", "--normalise", "white-balanced"],
            "NSRM only",
        ),
    ] {
        let out = nsrm().args(&args).arg("-o").arg(&o).output().unwrap();
        let out = if args[0] == "eval" {
            nsrm().args(&args).output().unwrap()
        } else {
            out
        };
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!o.exists());
    }
}

#[test]
fn fit_writes_a_white_balanced_nsrm_with_its_gains() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("m.json");
    let out = nsrm()
        .args(["fit", "--normalise", "white-balanced", "-o"])
        .arg(&o)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("normalise white-balanced"), "{err}");
    let m = nsrm::Model::load(&o).unwrap();
    // The gains balance the training white (D5100 under D65, rawtoaces-190 by default).
    let data = nsrm::simulate_named(
        "nikon-d5100",
        "D65",
        "rawtoaces-190",
        &nsrm::Grid::default(),
    )
    .unwrap();
    let w = data.white_rgb.unwrap();
    assert_eq!(m.input_gains(), [1.0 / w[0], 1.0 / w[1], 1.0 / w[2]]);
    assert_eq!(m.fit_report().unwrap().normalise, "white-balanced");
}
