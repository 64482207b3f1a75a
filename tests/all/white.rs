//! One white, carried with the data (issue 23): the patch CSV of `chart extract` names its white,
//! `fit --training` on it gives the model `fit --capture` gives on the frame, a CSV without a
//! white needs `--white`, and every white flag takes the same forms.

use crate::common::{nsrm_in, nsrm_ok, stderr, tempdir};
use std::path::Path;

fn model_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    match v {
        serde_json::Value::Number(n) => vec![n.as_f64().unwrap()],
        serde_json::Value::Array(a) => a.iter().flat_map(numbers).collect(),
        _ => panic!("not numbers: {v}"),
    }
}

fn assert_close(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        assert!(
            (x - y).abs() <= 1e-9 * x.abs().max(1.0),
            "{what}: {x} vs {y}"
        );
    }
}

#[test]
fn both_routes_from_one_frame_give_the_same_model() {
    let d = tempdir("white-routes");
    crate::common::cc24_scene(&d, "shot.exr", &[]);
    nsrm_ok(
        &d,
        &[
            "chart", "extract", "shot.exr", "--chart", "cc24", "-o", "p.csv",
        ],
    );
    let csv = std::fs::read_to_string(d.join("p.csv")).unwrap();
    let white_line = csv
        .lines()
        .find(|l| l.starts_with("# white: "))
        .unwrap_or_else(|| panic!("no white line: {csv}"));
    let w: Vec<f64> = white_line["# white: ".len()..]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    // The built-in reference's white: D50.
    let d50 = nsrm_chart::Reference::load("cc24-after2014", nsrm_chart::ChartKind::Cc24, None)
        .unwrap()
        .white;
    assert_close(&w, &d50, "the CSV's white is D50");
    for kind in ["nsrm", "prm", "lrm"] {
        let a = format!("a_{kind}.json");
        let b = format!("b_{kind}.json");
        nsrm_ok(
            &d,
            &[
                "fit",
                "--capture",
                "shot.exr",
                "--chart",
                "cc24",
                "--kind",
                kind,
                "--order",
                "2",
                "-o",
                &a,
            ],
        );
        nsrm_ok(
            &d,
            &[
                "fit",
                "--training",
                "p.csv",
                "--kind",
                kind,
                "--order",
                "2",
                "-o",
                &b,
            ],
        );
        let (ma, mb) = (model_json(&d.join(&a)), model_json(&d.join(&b)));
        assert_close(
            &numbers(&ma["matrix"]),
            &numbers(&mb["matrix"]),
            &format!("{kind} matrix"),
        );
        assert_close(
            &numbers(&ma["output"]["reference_white"]),
            &numbers(&mb["output"]["reference_white"]),
            &format!("{kind} white"),
        );
        assert_close(
            &numbers(&mb["output"]["reference_white"]),
            &w,
            &format!("{kind} white is the CSV's"),
        );
    }
    // Given again, the same white is accepted; another one is refused (a usage error).
    nsrm_ok(
        &d,
        &[
            "fit",
            "--training",
            "p.csv",
            "--white",
            "D50",
            "-o",
            "c.json",
        ],
    );
    let o = nsrm_in(
        &d,
        &[
            "fit",
            "--training",
            "p.csv",
            "--white",
            "D65",
            "-o",
            "e.json",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--white"), "{}", stderr(&o));
    assert!(!d.join("e.json").exists());
}

#[test]
fn a_csv_without_a_white_needs_white_in_every_form() {
    let d = tempdir("white-forms");
    let mut text = String::from("label,R,G,B,X,Y,Z\n");
    // Patches from the built-in simulation, so the fit is well posed.
    let t = crate::common::training();
    for i in 0..t.len() {
        let (r, x) = (t.rgb[i], t.xyz[i]);
        text.push_str(&format!(
            "p{i},{},{},{},{},{},{}\n",
            r[0], r[1], r[2], x[0], x[1], x[2]
        ));
    }
    std::fs::write(d.join("m.csv"), text).unwrap();
    for cmd in [
        &["fit", "--training", "m.csv", "-o", "x.json"][..],
        &["eval", "--training", "m.csv", "--kinds", "lrm"][..],
    ] {
        let o = nsrm_in(&d, cmd);
        assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("--white") && stderr(&o).contains("# white:"),
            "{cmd:?}: {}",
            stderr(&o)
        );
    }
    // Every form, on fit and on eval (and export's --white, on a fitted model).
    // D50 as chart makers' tables and ICC profiles give it: x 0.345703, y 0.358539, Y = 100.
    let (x, y) = (0.345703, 0.358539);
    let d50 = [100.0 * x / y, 100.0, 100.0 * (1.0 - x - y) / y];
    let xyz = format!("{},{},{}", d50[0], d50[1], d50[2]);
    for (i, white) in ["D50", "d50", &xyz, "0.345703,0.358539", "D65", "TL865"]
        .into_iter()
        .enumerate()
    {
        let out = format!("m{i}.json");
        nsrm_ok(
            &d,
            &["fit", "--training", "m.csv", "--white", white, "-o", &out],
        );
        let w = numbers(&model_json(&d.join(&out))["output"]["reference_white"]);
        if i < 4 {
            assert_close(&w, &d50, white);
        } else {
            assert_close(&w, &nsrm::parse_white(white).unwrap(), white);
        }
        if i % 2 == 0 {
            nsrm_ok(
                &d,
                &[
                    "eval",
                    "--training",
                    "m.csv",
                    "--white",
                    white,
                    "--kinds",
                    "lrm",
                ],
            );
        }
    }
    nsrm_ok(
        &d,
        &[
            "export",
            "--model",
            "m0.json",
            "--format",
            "cube",
            "--lut-size",
            "9",
            "--training",
            "m.csv",
            "--white",
            "D50",
            "-o",
            "m.cube",
        ],
    );
    // A malformed white is a usage error naming the flag.
    let o = nsrm_in(
        &d,
        &[
            "fit",
            "--training",
            "m.csv",
            "--white",
            "not-a-light",
            "-o",
            "y.json",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--white"), "{}", stderr(&o));
}
