//! `nsrm export --format icc`, judged by programs nobody here wrote: Little CMS's `transicc`
//! (Debian `liblcms2-utils`) and ArgyllCMS's `xicclu` (Debian `argyll`) apply the exported ICC
//! profile to camera RGB values, and their PCS XYZ must match `nsrm apply`'s output (converted
//! from its D65-referred XYZ to the PCS's D50 with the tests' own Bradford, `common::mat`, as
//! the profile's PCS is defined: `Bradford(W → D50) · XYZ / Y(W)`) within the error the export
//! reported. The device values are camera RGB over the scale the library reports for the same
//! model (`nsrm_export::icc::render`), whose profile the binary's is, byte for byte but the creation
//! date. Both are installed by `.ci/install.d/40-profiles.sh`; a missing one is a SKIP, and a
//! failure under `CI=true`.

use crate::common::mat::{bradford, output_matrix, ICC_D50 as D50};
use crate::common::{self, nsrm_in, nsrm_ok, stderr, tempdir};
use crate::common::{read_frame, write_tiff};
use nsrm::delta_e00_xyz;
use nsrm::OutputSpace;
use nsrm::{Frame, Layout, Model};
use nsrm_export::{icc, IccOptions};
use nsrm_io::ReadOptions;
use std::path::Path;
use std::process::{Command, Stdio};

fn skip(msg: &str) {
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{msg} (required under CI=true)");
    }
    println!("SKIP: {msg}");
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Runs `cmd` with `input` on stdin; its stdout.
fn pipe(cmd: &mut Command, input: &str) -> String {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the judge runs");
    use std::io::Write;
    let mut stdin = child.stdin.take().unwrap();
    let text = input.to_string();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(text.as_bytes());
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The numbers of a line.
fn numbers(s: &str) -> Vec<f64> {
    s.split(|c: char| c.is_whitespace() || c == ',')
        .filter_map(|t| t.parse().ok())
        .collect()
}

/// `transicc`: device RGB on its 0–255 scale in, XYZ (`Y = 1` at the white) out.
fn transicc(icc: &Path, device: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let input: String = device
        .iter()
        .map(|d| {
            format!(
                "{:.6} {:.6} {:.6}\n",
                d[0] * 255.0,
                d[1] * 255.0,
                d[2] * 255.0
            )
        })
        .collect();
    let out = pipe(
        Command::new("transicc")
            .arg("-i")
            .arg(icc)
            .args(["-o", "*XYZ", "-t", "1", "-n"]),
        &input,
    );
    let rows: Vec<[f64; 3]> = out
        .lines()
        .map(numbers)
        .filter(|v| v.len() == 3)
        .map(|v| [v[0], v[1], v[2]])
        .collect();
    assert_eq!(rows.len(), device.len(), "transicc printed:\n{out}");
    // transicc prints XYZ on the 0–100 scale.
    rows.into_iter().map(|r| r.map(|v| v / 100.0)).collect()
}

/// `xicclu`: device RGB 0–1 in, XYZ × 100 out (`… [RGB] -> Lut -> X Y Z [XYZ]`).
fn xicclu(icc: &Path, device: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let input: String = device
        .iter()
        .map(|d| format!("{:.8} {:.8} {:.8}\n", d[0], d[1], d[2]))
        .collect();
    let out = pipe(
        Command::new("xicclu").args(["-ff", "-ir", "-pX"]).arg(icc),
        &input,
    );
    let rows: Vec<[f64; 3]> = out
        .lines()
        .filter(|l| l.contains("[XYZ]"))
        .map(|l| {
            let tail = l.rsplit("->").next().unwrap();
            let v = numbers(tail.split('[').next().unwrap());
            [v[0] / 100.0, v[1] / 100.0, v[2] / 100.0]
        })
        .collect();
    assert_eq!(rows.len(), device.len(), "xicclu printed:\n{out}");
    rows
}

/// The max ΔE00 `export` printed.
fn reported_max(stdout: &str) -> f64 {
    stdout
        .split("max ")
        .last()
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no max in {stdout}"))
}

/// Camera RGB samples: the 190 training patches at exposures 1, 1/4 and 1/16 of the training
/// white; the exposure of each (the white they are judged against is D50 × it).
fn samples() -> Vec<([f64; 3], f64)> {
    let d = common::training();
    let mut v = Vec::new();
    for e in [0.0f64, -2.0, -4.0] {
        let k = e.exp2();
        v.extend(d.rgb.iter().map(|c| (c.map(|x| x * k), k)));
    }
    v
}

/// `nsrm apply` on `rgb` (one TIFF row), converted to PCS XYZ D50 (white `Y = 1`).
fn apply_pcs(dir: &Path, model_file: &str, rgb: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let data: Vec<f32> = rgb.iter().flat_map(|c| c.map(|v| v as f32)).collect();
    let frame = Frame::from_data(rgb.len(), 1, Layout::Rgb, data).unwrap();
    let tif = dir.join("cam.tif");
    if !tif.exists() {
        common::committed(false, |u| write_tiff(&frame, &tif, u)).unwrap();
    }
    let out = format!("out-{model_file}");
    nsrm_ok(
        dir,
        &[
            "apply", "--model", model_file, "--device", "cpu", "-o", &out, "cam.tif",
        ],
    );
    let f = read_frame(&dir.join(&out).join("cam_xyz.exr"), &ReadOptions::default()).unwrap();
    let m = Model::load(&dir.join(model_file)).unwrap();
    // apply writes XYZ D65-referred with the white at Y = 1; back to the model's XYZ, then the
    // PCS adaptation.
    let back = crate::common::mat::invert(&output_matrix(m.white_xyz(), OutputSpace::Xyz));
    let w = m.white_xyz();
    let pcs = bradford(w, D50).map(|r| r.map(|v| v / w[1]));
    let to_pcs = crate::common::mat::mul(&pcs, &back);
    f.data
        .chunks_exact(f.layout.channels())
        .map(|p| crate::common::mat::apply(&to_pcs, [p[0] as f64, p[1] as f64, p[2] as f64]))
        .collect()
}

fn fit(dir: &Path, kind: &str, order: &str, out: &str) {
    nsrm_ok(
        dir,
        &[
            "fit",
            "--kind",
            kind,
            "--order",
            order,
            "--illuminant",
            "D65",
            "-o",
            out,
        ],
    );
}

/// Each kind's profile, applied by transicc and xicclu, matches `nsrm apply` within the error
/// `export` reported (plus 0.02 ΔE00 for apply's 32-bit floats and the judges' printed digits).
#[test]
fn transicc_and_xicclu_reproduce_apply() {
    let judges: Vec<&str> = ["transicc", "xicclu"]
        .into_iter()
        .filter(|t| have(t))
        .collect();
    if judges.len() < 2 {
        skip("transicc (liblcms2-utils) or xicclu (argyll) is not installed");
        if judges.is_empty() {
            return;
        }
    }
    let dir = tempdir("icc-judges");
    let samples = samples();
    let rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.0).collect();
    let mut lines = Vec::new();
    for (kind, order) in [
        ("lrm", "1"),
        ("nsrm", "2"),
        ("nsrm", "3"),
        ("rprm", "2"),
        ("rprm", "3"),
        ("prm", "2"),
    ] {
        let name = format!("{kind}{order}");
        let (mf, icc_file) = (format!("{name}.json"), format!("{name}.icc"));
        fit(&dir, kind, order, &mf);
        let out = nsrm_ok(
            &dir,
            &["export", "--model", &mf, "--format", "icc", "-o", &icc_file],
        );
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let max = reported_max(&text);
        if kind == "lrm" {
            assert!(max < 0.01, "LRM matrix/TRC is not exact: {text}");
        }
        let m = Model::load(&dir.join(&mf)).unwrap();
        // The library's profile of the same model, from the same training patches (the binary
        // re-simulates them from the model's provenance): the binary's file, and its scale.
        let library = dir.join(format!("library-{icc_file}"));
        let (bytes, written) =
            icc::render(&m, IccOptions::default(), &common::training().rgb, None).unwrap();
        std::fs::write(&library, bytes).unwrap();
        let (mut ours, mut theirs) = (
            std::fs::read(dir.join(&icc_file)).unwrap(),
            std::fs::read(&library).unwrap(),
        );
        // The header's creation date (ICC.1, 7.2.1: bytes 24..36) is the time of writing.
        ours[24..36].fill(0);
        theirs[24..36].fill(0);
        assert!(
            ours == theirs,
            "{name}: `nsrm export` wrote another profile than `nsrm_export::icc::render`"
        );
        let s = written.scale;
        // The samples inside the range the export measured (every channel within 2^lo..1 of the
        // device scale), as its report counts them.
        let lo = IccOptions::default().lo.exp2();
        let inside: Vec<usize> = (0..rgb.len())
            .filter(|&i| rgb[i].iter().all(|v| (lo..=1.0).contains(&(v / s))))
            .collect();
        assert!(inside.len() >= 200, "{name}: {}", inside.len());
        let device: Vec<[f64; 3]> = inside.iter().map(|&i| rgb[i].map(|v| v / s)).collect();
        let all = apply_pcs(&dir, &mf, &rgb);
        let want: Vec<[f64; 3]> = inside.iter().map(|&i| all[i]).collect();
        let samples: Vec<([f64; 3], f64)> = inside.iter().map(|&i| samples[i]).collect();
        let mut line = format!("{name}: export max {max:.4}; {} samples", inside.len());
        for judge in &judges {
            let got = match *judge {
                "transicc" => transicc(&dir.join(&icc_file), &device),
                _ => xicclu(&dir.join(&icc_file), &device),
            };
            let de: Vec<f64> = got
                .iter()
                .zip(&want)
                .zip(&samples)
                .map(|((g, w), (_, k))| delta_e00_xyz(*g, *w, D50.map(|v| v * k)))
                .collect();
            let worst = de.iter().cloned().fold(0.0, f64::max);
            let wi = de.iter().position(|v| *v == worst).unwrap_or(0);
            let mean = de.iter().sum::<f64>() / de.len() as f64;
            line.push_str(&format!("; {judge} vs apply {mean:.4}/{worst:.4}"));
            if kind == "lrm" {
                // Matrix/TRC: exact up to the file's fixed point and transicc's printed digits.
                assert!(worst < 0.01, "{name}: {judge} {worst}");
            }
            assert!(
                worst <= max + 0.02,
                "{name}: {judge} departs from apply by {worst:.4} ΔE00, more than the {max:.4} the export reported (at camera RGB {:?} ×{}: {judge} {:?}, apply {:?})",
                samples[wi].0, samples[wi].1, got[wi], want[wi]
            );
        }
        lines.push(line);
    }
    println!("{}", lines.join("\n"));
}

/// Malformed requests get clear errors and write nothing.
#[test]
fn icc_refusals_write_nothing() {
    let dir = tempdir("icc-refusals");
    fit(&dir, "nsrm", "3", "nsrm.json");
    fit(&dir, "prm", "3", "prm.json");
    // A PRM whose cubic terms blow up over the profile's range: the model file with the last
    // term of each output row set to 1e6.
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("prm.json")).unwrap()).unwrap();
    for row in doc["matrix"].as_array_mut().unwrap() {
        let row = row.as_array_mut().unwrap();
        *row.last_mut().unwrap() = 1e6.into();
    }
    std::fs::write(dir.join("boom.json"), doc.to_string()).unwrap();
    let bad = Model::load(&dir.join("boom.json")).unwrap();
    let l = bad.matrix().len() / 3;
    assert!((0..3).all(|i| bad.matrix()[i * l + l - 1] == 1e6));
    nsrm_ok(
        &dir,
        &["fit", "--kind", "nsrm", "--illuminant", "A", "-o", "a.json"],
    );
    nsrm_ok(&dir, &["combine", "a.json", "nsrm.json", "-o", "dual.json"]);
    for (args, want) in [
        (
            vec![
                "export",
                "--model",
                "boom.json",
                "--format",
                "icc",
                "-o",
                "bad.icc",
            ],
            "explodes",
        ),
        (
            vec![
                "export",
                "--model",
                "nsrm.json",
                "--format",
                "icc",
                "--stops",
                "-8:2",
                "-o",
                "bad.icc",
            ],
            "no headroom",
        ),
        (
            vec![
                "export",
                "--model",
                "nsrm.json",
                "--format",
                "icc",
                "--max-de00",
                "0.00001",
                "-o",
                "bad.icc",
            ],
            "exceeds the limit",
        ),
        (
            vec![
                "export",
                "--model",
                "dual.json",
                "--format",
                "icc",
                "-o",
                "bad.icc",
            ],
            "two calibration illuminants",
        ),
    ] {
        let o = nsrm_in(&dir, &args);
        common::no_crash(&o, &format!("{args:?}"));
        assert!(!o.status.success(), "{args:?}");
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        assert!(!dir.join("bad.icc").exists(), "{args:?} wrote bad.icc");
    }
}
