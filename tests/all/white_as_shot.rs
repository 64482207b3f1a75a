//! `apply --white as-shot`: each raw frame is corrected for the as-shot neutral its file records
//! (the same output as that neutral given by hand as `as-shot:R,G,B`); a frame without one fails
//! with a clear message and writes nothing. On `../shared/data/colorchart.dng` (AsShotNeutral
//! 1, 2.477, 1.462, as exiftool prints it).

use crate::common::read_frame;
use crate::common::{chart_dng, nsrm_in, nsrm_ok, skip, stderr, tempdir};
use nsrm_io::ReadOptions;

/// The numbers after `camera neutral ` in apply's line about the white.
fn neutral_printed(err: &str) -> [f64; 3] {
    let s = err
        .split("camera neutral ")
        .nth(1)
        .unwrap_or_else(|| panic!("no camera neutral in {err}"));
    let v: Vec<f64> = s
        .split(';')
        .next()
        .unwrap()
        .split(',')
        .map(|x| x.trim().parse().unwrap())
        .collect();
    [v[0], v[1], v[2]]
}

#[test]
fn as_shot_reads_the_raw_files_neutral() {
    let dng = chart_dng();
    if !dng.exists() {
        return skip("../shared/data/colorchart.dng is absent");
    }
    let dir = tempdir("white-as-shot");
    crate::common::dual_nsrm_model(&dir);
    let dng = dng.to_str().unwrap();
    let run = |white: &str, out: &str| {
        nsrm_ok(
            &dir,
            &[
                "apply",
                "--model",
                "dual.json",
                "--white",
                white,
                "--demosaic",
                "half",
                "--format",
                "tiff",
                "--device",
                "cpu",
                "-o",
                out,
                dng,
            ],
        )
    };
    let o = run("as-shot", "shot");
    let err = stderr(&o);
    let n = neutral_printed(&err);
    // exiftool: AsShotNeutral 1 2.477 1.462 → G = 1.
    let want = [1.0 / 2.477, 1.0, 1.462 / 2.477];
    for k in 0..3 {
        assert!((n[k] - want[k]).abs() < 1e-3, "{n:?} vs {want:?}\n{err}");
    }
    assert!(err.contains("as-shot white x, y"), "{err}");
    let given = format!("as-shot:{},{},{}", want[0], want[1], want[2]);
    run(&given, "given");
    let read = |p: &str| {
        read_frame(
            &dir.join(p).join("colorchart_xyz.tif"),
            &ReadOptions::default(),
        )
        .unwrap()
    };
    let (a, b) = (read("shot"), read("given"));
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut worst = 0.0f32;
    for (x, y) in a.data.iter().zip(&b.data) {
        worst = worst.max((x - y).abs() / y.abs().max(1e-3));
    }
    // The file's neutral is the f32 ratio of rawler's coefficients; the given one is 4 digits.
    assert!(worst < 2e-3, "as-shot vs as-shot:R,G,B differ by {worst}");

    // A frame that records no neutral (a TIFF) fails with a clear message and writes nothing.
    let tif = dir.join("given/colorchart_xyz.tif");
    let o = nsrm_in(
        &dir,
        &[
            "apply",
            "--model",
            "dual.json",
            "--white",
            "as-shot",
            "--device",
            "cpu",
            "-o",
            "none",
            tif.to_str().unwrap(),
        ],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no as-shot neutral"), "{}", stderr(&o));
    assert!(
        !dir.join("none/colorchart_xyz_xyz.exr").exists(),
        "a failed frame was written"
    );
}

/// Issue 35: exposure is defined once. A chart-fitted model (`fit --capture` on the real DNG)
/// applied with `--white` at its own training white — as x,y, and as the camera neutral apply
/// prints for it (`as-shot:R,G,B`, 4 digits) — writes what it writes without `--white`: the
/// training white at the training exposure is Y = 1 either way (before, the capture's raw white
/// level, G about 0.105, ended up as a scale: 3.3 stops).
#[test]
fn white_at_the_training_white_leaves_a_chart_fitted_model_unchanged() {
    let dng = chart_dng();
    if !dng.exists() {
        return skip("../shared/data/colorchart.dng is absent");
    }
    let dir = tempdir("white-own");
    let dng = dng.to_str().unwrap();
    nsrm_ok(
        &dir,
        &["fit", "--capture", dng, "--chart", "cc24", "-o", "cap.json"],
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("cap.json")).unwrap()).unwrap();
    let w: Vec<f64> = doc["output"]["reference_white"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let sum: f64 = w.iter().sum();
    let run = |white: Option<&str>, out: &str| {
        let mut args = vec![
            "apply",
            "--model",
            "cap.json",
            "--demosaic",
            "half",
            "--format",
            "tiff",
            "--device",
            "cpu",
            "-o",
            out,
            dng,
        ];
        if let Some(w) = white {
            args.extend(["--white", w]);
        }
        nsrm_ok(&dir, &args)
    };
    run(None, "plain");
    let xy = format!("{:.10},{:.10}", w[0] / sum, w[1] / sum);
    let n = neutral_printed(&stderr(&run(Some(&xy), "xy")));
    let given = format!("as-shot:{},{},{}", n[0], n[1], n[2]);
    run(Some(&given), "neutral");
    let read = |p: &str| {
        read_frame(
            &dir.join(p).join("colorchart_xyz.tif"),
            &ReadOptions::default(),
        )
        .unwrap()
    };
    let plain = read("plain");
    let mean_y = |f: &nsrm::Frame| {
        let ys: Vec<f64> = f.data.chunks_exact(3).map(|p| p[1] as f64).collect();
        ys.iter().sum::<f64>() / ys.len() as f64
    };
    for (name, tol) in [("xy", 1e-4), ("neutral", 2e-3)] {
        let f = read(name);
        assert_eq!((f.width, f.height), (plain.width, plain.height));
        let ratio = mean_y(&f) / mean_y(&plain);
        assert!(
            (ratio - 1.0).abs() < tol,
            "--white {name}: mean Y scaled by {ratio}"
        );
        // Pixel by pixel, relative to the frame's white level (Y = 1).
        let worst = f
            .data
            .iter()
            .zip(&plain.data)
            .map(|(a, b)| (a - b).abs() / b.abs().max(0.05))
            .fold(0.0f32, f32::max);
        assert!(
            worst < tol as f32 * 5.0,
            "--white {name}: differs by {worst}"
        );
    }
}
