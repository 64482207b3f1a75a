//! Two calibrations in one fit: `nsrm fit` with two `--illuminant` (spectra) writes the same
//! two-illuminant model file as two fits and `nsrm combine`; with two `--capture`, each with the
//! `--illuminant` it was shot under, each model is the single-capture fit with that illuminant
//! (the chart's reference adapted to the light), and the pair carries the lights' temperatures.
//! Malformed requests are refused and write nothing.

use crate::common::{nsrm_in, nsrm_ok, stderr, tempdir};
use nsrm::Profile;

#[test]
fn two_illuminants_from_spectra_is_two_fits_combined() {
    let d = tempdir("fit-two-spectra");
    let fit = |extra: &[&str], out: &str| {
        let mut args = vec!["fit", "--kind", "rprm", "--preserve-white", "-o", out];
        args.extend_from_slice(extra);
        nsrm_ok(&d, &args)
    };
    let o = fit(&["--illuminant", "A", "--illuminant", "D65"], "two.json");
    assert!(
        stderr(&o).contains("two-illuminant model: calibration illuminants 2863 K"),
        "{}",
        stderr(&o)
    );
    fit(&["--illuminant", "A"], "a.json");
    fit(&["--illuminant", "D65"], "d65.json");
    nsrm_ok(
        &d,
        &["combine", "d65.json", "a.json", "-o", "combined.json"],
    );
    assert_eq!(
        std::fs::read(d.join("two.json")).unwrap(),
        std::fs::read(d.join("combined.json")).unwrap()
    );
    // Refusals write nothing.
    for (args, want) in [
        (
            vec![
                "fit",
                "--illuminant",
                "A",
                "--illuminant",
                "D50",
                "--illuminant",
                "D65",
                "-o",
                "bad.json",
            ],
            "twice",
        ),
        (
            vec![
                "fit",
                "--illuminant",
                "D65",
                "--illuminant",
                "D65",
                "-o",
                "bad.json",
            ],
            "mired apart",
        ),
        (
            vec![
                "fit",
                "--kind",
                "prm",
                "--illuminant",
                "A",
                "--illuminant",
                "D65",
                "-o",
                "bad.json",
            ],
            "exposure-invariant",
        ),
    ] {
        let o = nsrm_in(&d, &args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!d.join("bad.json").exists(), "{args:?} wrote");
    }
}

#[test]
fn two_captures_each_with_its_light() {
    let d = tempdir("fit-two-captures");
    for (ill, out) in [("A", "a.exr"), ("D65", "d65.exr")] {
        crate::common::cc24_scene(&d, out, &["--illuminant", ill]);
    }
    let fit = |extra: &[&str], out: &str| {
        let mut args = vec![
            "fit", "--chart", "cc24", "--kind", "nsrm", "--order", "2", "-o", out,
        ];
        args.extend_from_slice(extra);
        nsrm_ok(&d, &args)
    };
    fit(
        &[
            "--capture",
            "a.exr",
            "--illuminant",
            "A",
            "--capture",
            "d65.exr",
            "--illuminant",
            "D65",
        ],
        "two.json",
    );
    fit(&["--capture", "a.exr", "--illuminant", "A"], "a.json");
    fit(&["--capture", "d65.exr", "--illuminant", "D65"], "d65.json");
    let two = Profile::load(&d.join("two.json")).unwrap();
    assert!(two.models().len() == 2);
    // The lights' temperatures, as the model file carries them (lower first).
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("two.json")).unwrap()).unwrap();
    let cct = |i: usize| {
        doc["calibration_illuminants"][i]["cct_kelvin"]
            .as_f64()
            .unwrap_or_else(|| panic!("no calibration_illuminants[{i}].cct_kelvin in {doc}"))
    };
    let [t1, t2] = [cct(0), cct(1)];
    assert!(
        (t1 - 2856.0).abs() < 30.0 && (t2 - 6504.0).abs() < 30.0,
        "{t1} {t2}"
    );
    let a = nsrm::Model::load(&d.join("a.json")).unwrap();
    let d65 = nsrm::Model::load(&d.join("d65.json")).unwrap();
    assert_eq!(two.models()[0].to_json(), a.to_json());
    assert_eq!(two.models()[1].to_json(), d65.to_json());
    // Without --illuminant a capture's model keeps the reference's white (D50).
    fit(&["--capture", "a.exr"], "plain.json");
    let plain = nsrm::Model::load(&d.join("plain.json")).unwrap();
    let w = plain.white_xyz();
    let x = w[0] / (w[0] + w[1] + w[2]);
    assert!((x - 0.3457).abs() < 1e-3, "{w:?}");
    // Refusals write nothing.
    for (args, want) in [
        (
            vec![
                "fit",
                "--chart",
                "cc24",
                "--capture",
                "a.exr",
                "--capture",
                "d65.exr",
                "-o",
                "bad.json",
            ],
            "an --illuminant each",
        ),
        (
            vec![
                "fit",
                "--chart",
                "cc24",
                "--capture",
                "a.exr",
                "--illuminant",
                "A",
                "--illuminant",
                "D65",
                "-o",
                "bad.json",
            ],
            "need two --capture",
        ),
        (
            vec![
                "fit",
                "--chart",
                "cc24",
                "--capture",
                "a.exr",
                "--illuminant",
                "A",
                "--capture",
                "d65.exr",
                "--illuminant",
                "D65",
                "--overlay",
                "o.png",
                "-o",
                "bad.json",
            ],
            "--overlay takes one --capture",
        ),
    ] {
        let o = nsrm_in(&d, &args);
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!d.join("bad.json").exists(), "{args:?} wrote");
        assert!(!d.join("o.png").exists(), "{args:?} wrote");
    }
}

/// `combine` refuses two models fitted on different cameras, naming both files and cameras,
/// and writes nothing.
#[test]
fn combining_two_cameras_is_refused() {
    let d = tempdir("combine-cameras");
    for (ill, out) in [("A", "a.json"), ("D65", "d65.json")] {
        nsrm_ok(
            &d,
            &["fit", "--kind", "lrm", "--illuminant", ill, "-o", out],
        );
    }
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("d65.json")).unwrap()).unwrap();
    let prov = v
        .get_mut("training")
        .and_then(|p| p.as_object_mut())
        .expect("a training object");
    let own = prov.get("camera").cloned().expect("the camera of the fit");
    prov.insert("camera".into(), "other-sensor.csv".into());
    std::fs::write(d.join("other.json"), serde_json::to_vec(&v).unwrap()).unwrap();
    let o = nsrm_in(&d, &["combine", "a.json", "other.json", "-o", "dual.json"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    for want in [
        "a.json",
        "other.json",
        "other-sensor.csv",
        own.as_str().unwrap(),
    ] {
        assert!(err.contains(want), "{want}: {err}");
    }
    assert!(!d.join("dual.json").exists());
    nsrm_ok(&d, &["combine", "a.json", "d65.json", "-o", "dual.json"]);
}
