//! `nsrm export-shader --lang dctl`: Resolve is not available here, so the DCTL is compiled as C
//! with a small shim for its built-ins (`__DEVICE__`, `float3`, `make_float3`, `_sqrtf`, …) and
//! run on test pixels; its output must match the f64 model with the output space folded in, as
//! `nsrm apply` writes it, to the f32 accuracy of the GPU shaders.

use crate::common;

use nsrm::OutputSpace;
use nsrm::{fit, Kind, Model};
use nsrm::{fit_with, FitOptions, Normalise};
use nsrm::{simulate_named, Grid};
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

const SHIM: &str = r#"
#include <math.h>
#include <stdio.h>
#define __DEVICE__ static
#define DEVICE static
typedef struct { float x, y, z; } float3;
static float3 make_float3(float x, float y, float z) { float3 v; v.x = x; v.y = y; v.z = z; return v; }
#define _fabs fabsf
#define _sqrtf sqrtf
#define _cbrtf cbrtf
#define _copysignf copysignf
"#;

const MAIN: &str = r#"
int main(void) {
    float r, g, b;
    while (scanf("%f %f %f", &r, &g, &b) == 3) {
        float3 o = transform(1, 1, 0, 0, r, g, b);
        printf("%.9g %.9g %.9g\n", o.x, o.y, o.z);
    }
    return 0;
}
"#;

pub(crate) fn cc() -> Option<String> {
    for c in ["cc", "gcc", "clang"] {
        if Command::new(c)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
        {
            return Some(c.to_string());
        }
    }
    let msg = "no C compiler (cc, gcc or clang) to compile the DCTL with";
    crate::common::skip(msg);
    None
}

/// Compiles `dctl` with the shim and runs it on `px` (also used by `pixel_policy`).
pub(crate) fn run_dctl(
    cc: &str,
    dir: &Path,
    name: &str,
    dctl: &str,
    px: &[[f64; 3]],
) -> Vec<[f64; 3]> {
    let src = dir.join(format!("{name}.c"));
    let exe = dir.join(name);
    std::fs::write(&src, format!("{SHIM}\n{dctl}\n{MAIN}")).unwrap();
    let out = Command::new(cc)
        .args([
            "-std=c99",
            "-O1",
            "-Wall",
            "-Werror",
            "-Wno-unused-parameter",
            "-Wno-unused-function",
        ])
        .arg(&src)
        .arg("-o")
        .arg(&exe)
        .arg("-lm")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{name}: the DCTL does not compile as C:\n{}\n{dctl}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut child = Command::new(&exe)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let input: String = px
        .iter()
        .map(|p| format!("{:e} {:e} {:e}\n", p[0] as f32, p[1] as f32, p[2] as f32))
        .collect();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .map(|t| match t {
                    "nan" | "-nan" => f64::NAN,
                    t => t.parse().unwrap(),
                })
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

fn pixels(data: &nsrm::TrainingSet) -> Vec<[f64; 3]> {
    let mut px: Vec<[f64; 3]> = data.rgb.iter().take(60).cloned().collect();
    px.extend(data.rgb.iter().take(20).map(|c| c.map(|v| v * 37.0)));
    px.extend(data.rgb.iter().take(20).map(|c| c.map(|v| v * 1e-4)));
    px.extend([
        [0.0, 0.0, 0.0],
        [-0.01, 0.2, 0.3],
        [0.1, -0.2, 0.05],
        [0.1, -0.3, 0.05],
        [0.5, 0.5, 0.5],
    ]);
    // Round to f32 first: the C program reads f32.
    px.iter().map(|p| p.map(|v| v as f32 as f64)).collect()
}

/// `|dctl − f64| ≤ 1e-5 · max(|ref|, scale · Σ_j |M_ij p_j|)`: the f32 bound of the shaders.
fn check(model: &Model, px: &[[f64; 3]], got: &[[f64; 3]], what: &str) {
    assert_eq!(got.len(), px.len(), "{what}");
    let l = model.len_terms();
    let mut p = vec![0.0; l];
    for (x, g) in px.iter().zip(got) {
        let want = model.apply_f64(*x);
        let scale = model.features_of(*x, &mut p).unwrap_or(0.0);
        for i in 0..3 {
            let mag: f64 = (0..l)
                .map(|j| (model.matrix()[i * l + j] * p[j]).abs())
                .sum::<f64>()
                * scale.abs();
            let tol = 1e-5 * want[i].abs().max(mag) + 1e-30;
            assert!(
                (g[i] - want[i]).abs() <= tol,
                "{what}: pixel {x:?} channel {i}: DCTL {} vs f64 {} (tol {tol:e})",
                g[i],
                want[i]
            );
        }
    }
}

#[test]
fn dctl_compiles_as_c_and_matches_the_f64_model() {
    let Some(cc) = cc() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let px = pixels(&data);
    let wb = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let mut models = Vec::new();
    for kind in Kind::ALL {
        for order in 1..=4u8 {
            if kind == Kind::Lrm && order > 1 {
                continue;
            }
            models.push((String::new(), fit(kind, order, &data).unwrap()));
        }
    }
    // White-balanced NSRM: the input gains are written into the DCTL.
    for order in 1..=4u8 {
        let m = fit_with(Kind::Nsrm, order, &data, &wb).unwrap().model;
        assert!(!m.has_unit_gains());
        models.push(("_wb".into(), m));
    }
    {
        for (suffix, model) in models {
            let (kind, order) = (model.kind(), model.order());
            for space in [OutputSpace::Xyz, OutputSpace::Acescg] {
                let folded = nsrm::output_model(&model, space).unwrap();
                let dctl = nsrm::export::generate_dctl(&folded, &["test".into()]).unwrap();
                assert!(dctl.contains("__DEVICE__ float3 transform(int p_Width"));
                let name = format!(
                    "{}{order}{suffix}_{}",
                    kind.name(),
                    space.name().replace('-', "_")
                );
                // The gain step is printed where the gains are not 1.
                assert_eq!(dctl.contains("x0 = x0 * "), !suffix.is_empty());
                let got = run_dctl(&cc, dir.path(), &name, &dctl, &px);
                check(&folded, &px, &got, &name);
                if kind == Kind::Nsrm {
                    // The pixel policy: R+G+B <= 0 (after the input gains) is black.
                    let mut p = vec![0.0; folded.len_terms()];
                    let black: Vec<usize> = (0..px.len())
                        .filter(|&i| {
                            folded.features_of(px[i], &mut p).is_none() && px[i] != [0.0; 3]
                        })
                        .collect();
                    assert!(!black.is_empty(), "{name}: no pixel with s < 0");
                    for i in black {
                        assert_eq!(got[i], [0.0; 3], "{name}: pixel {:?}", px[i]);
                    }
                }
            }
        }
    }
}

#[test]
fn export_shader_writes_dctl_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default()).unwrap();
    let model = fit(Kind::Rprm, 3, &data).unwrap();
    std::fs::write(dir.path().join("m.json"), model.to_json()).unwrap();
    let run = |args: &[&str]| {
        common::nsrm()
            .current_dir(dir.path())
            .args(args)
            .output()
            .unwrap()
    };
    let out = run(&[
        "export-shader",
        "--model",
        "m.json",
        "--lang",
        "dctl",
        "--output-space",
        "acescg",
        "-o",
        "m.dctl",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("m.dctl")).unwrap();
    assert!(
        text.contains("acescg") && text.contains("cbrt(R*G^2)"),
        "{text}"
    );
    let folded = nsrm::output_model(&model, OutputSpace::Acescg).unwrap();
    if let Some(cc) = cc() {
        let px = pixels(&data);
        let got = run_dctl(&cc, dir.path(), "cli", &text, &px);
        check(&folded, &px, &got, "cli");
    }
    let again = run(&[
        "export-shader",
        "--model",
        "m.json",
        "--lang",
        "dctl",
        "-o",
        "m.dctl",
    ]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("already exists"));
    let bad = run(&[
        "export-shader",
        "--model",
        "m.json",
        "--lang",
        "dctl",
        "--output-space",
        "p3",
        "-o",
        "n.dctl",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(!dir.path().join("n.dctl").exists());
}
