//! `nsrm eval` against an independent oracle (`tests/tools/table1_oracle.py`: colour-science's
//! Lab, CIEDE2000 and Finlayson 2015 expansions, numpy's spectral sums and `lstsq`, NSRM written
//! from the paper): every patch's leave-one-out ΔE00, and so every cell of the paper's Table 1
//! (mean, median, max), agree to 0.011 ΔE00 on the built-in set and on the ColorChecker SG's inner
//! 96 patches, under D65, TL865 and LED-B5, order 3.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

use crate::common;

/// The agreement asked for, in ΔE00.
const TOLERANCE: f64 = 0.011;

const ILLUMINANTS: [&str; 3] = ["D65", "TL865", "LED-B5"];

/// Per (illuminant/model): per patch label, ΔE00.
type Errors = BTreeMap<String, BTreeMap<String, f64>>;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
}

/// The oracle's errors for `reflectances` (restricted to `patches`), or `None` (skipped) without
/// python3, numpy and colour-science.
fn oracle(data: &Path, reflectances: &Path, patches: &str) -> Option<Errors> {
    let have = Command::new("python3")
        .args(["-c", "import numpy, colour"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !have {
        common::skip(
            "python3 with numpy and colour-science (PyPI colour-science): the Table-1 oracle",
        );
        return None;
    }
    let mut cmd = Command::new("python3");
    cmd.arg(root().join("tests/tools/table1_oracle.py"))
        .arg(data.join("nikon_d5100_npl_darrodi2015.csv"))
        .arg(reflectances)
        .arg(data.join("cie1931_2deg_cmf.csv"))
        .arg(patches);
    for i in ILLUMINANTS {
        cmd.arg(data.join(format!("illuminant_{i}.csv")));
    }
    let o = cmd.output().unwrap();
    common::assert_ok(&o);
    Some(serde_json::from_slice(&o.stdout).unwrap())
}

/// `nsrm eval --json` with `args`, as the oracle's map.
fn nsrm_eval(args: &[&str]) -> Errors {
    let dir = common::tempdir("table1-oracle");
    let mut all = vec!["eval", "--json", "--order", "3"];
    for i in ILLUMINANTS {
        all.extend(["--illuminant", i]);
    }
    all.extend(args);
    let o = common::nsrm_ok(&dir, &all);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let mut out = Errors::new();
    for r in v["results"].as_array().unwrap() {
        let key = format!(
            "{}/{}",
            r["illuminant"].as_str().unwrap(),
            r["model"].as_str().unwrap()
        );
        let per: BTreeMap<String, f64> = r["per_patch"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                (
                    p["label"].as_str().unwrap().to_string(),
                    p["dE00"].as_f64().unwrap(),
                )
            })
            .collect();
        out.insert(key, per);
    }
    let _ = std::fs::remove_dir_all(&dir);
    out
}

/// Mean, median and max of `v`: the cells of Table 1, as `nsrm eval` summarises its patches.
fn cell(v: &[f64]) -> [f64; 3] {
    let s = nsrm::Stats::of(v);
    [s.mean, s.median, s.max]
}

/// Every patch and every Table-1 cell of `ours` within [`TOLERANCE`] of `oracle`; the worst
/// difference.
fn compare(what: &str, ours: &Errors, oracle: &Errors) -> f64 {
    assert_eq!(
        ours.keys().collect::<Vec<_>>(),
        oracle.keys().collect::<Vec<_>>(),
        "{what}: the same illuminants and models"
    );
    let mut worst: f64 = 0.0;
    for (key, want) in oracle {
        let got = &ours[key];
        assert_eq!(got.len(), want.len(), "{what} {key}: patches");
        for (label, w) in want {
            let g = got
                .get(label)
                .unwrap_or_else(|| panic!("{what} {key}: no {label}"));
            let d = (g - w).abs();
            worst = worst.max(d);
            assert!(
                d <= TOLERANCE,
                "{what} {key} {label}: nsrm {g:.4}, oracle {w:.4}"
            );
        }
        let g: Vec<f64> = want.keys().map(|l| got[l]).collect();
        let w: Vec<f64> = want.values().copied().collect();
        for (k, (a, b)) in cell(&g).iter().zip(cell(&w)).enumerate() {
            let name = ["mean", "median", "max"][k];
            assert!(
                (a - b).abs() <= TOLERANCE,
                "{what} {key} {name}: nsrm {a:.4}, oracle {b:.4}"
            );
        }
    }
    worst
}

#[test]
fn the_built_in_table_agrees_with_the_oracle() {
    let data = root().join("assets");
    let Some(want) = oracle(&data, &data.join("rawtoaces_190_patches.csv"), "all") else {
        return;
    };
    let ours = nsrm_eval(&[]);
    let worst = compare("built-in set", &ours, &want);
    eprintln!("built-in set: 12 cells × 190 patches, worst per-patch difference {worst:.2e} ΔE00");
}

#[test]
fn the_sg_table_agrees_with_the_oracle() {
    let Some(sg) = common::sg_path() else { return };
    let data = root().join("assets");
    let Some(want) = oracle(&data, &sg, "B2:M9") else {
        return;
    };
    let sg = sg.to_str().unwrap();
    let ours = nsrm_eval(&["--reflectances", sg, "--patches", "B2:M9"]);
    let worst = compare("SG inner 96", &ours, &want);
    eprintln!("SG inner 96: 12 cells × 96 patches, worst per-patch difference {worst:.2e} ΔE00");
}
