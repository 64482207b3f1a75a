//! Issue 19, for every command (`chart extract`, `fit`, `eval`, `export`, `export-shader`,
//! `render-scene`, `render-chart`, `apply`): (1) no input is ever written, whatever path names
//! it (the same name, `..`, a symbolic link, a hard link); (2) a command's outputs are one unit;
//! (3) a signal leaves no temporary and exits 128 + signal; (5) and (6) numbers and files that
//! are not what they say are refused; (8) text inputs come through pipes, never from devices.

use crate::common;
use common::*;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A directory with a model (`m.json`), a rendered chart scene (`s.exr`) and its patches read
/// back (`p.csv`, `label,R,G,B,X,Y,Z`: a measured training file).
fn fixture() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    nsrm_ok(
        d,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "--width",
            "600",
            "--height",
            "400",
            "-o",
            "s.exr",
        ],
    );
    nsrm_ok(
        d,
        &[
            "chart", "extract", "s.exr", "--chart", "cc24", "-o", "p.csv",
        ],
    );
    dir
}

/// Every file under `dir` with its bytes, for "nothing changed" checks.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v = Vec::new();
    for e in walk(dir) {
        if e.is_file() {
            v.push((e.display().to_string(), std::fs::read(&e).unwrap()));
        }
    }
    v.sort();
    v
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() && !p.is_symlink() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// Temporaries of nsrm's form anywhere under `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    walk(dir)
        .into_iter()
        .filter_map(|p| {
            let n = p.file_name()?.to_string_lossy().into_owned();
            (n.contains(".nsrm-") && n.ends_with(".tmp")).then_some(n)
        })
        .collect()
}

/// Runs `args` in `d` and asserts a usage error (exit 2) whose message says `what`, with every
/// file under `d` unchanged (nothing written, nothing replaced) and no temporary left.
fn refused(d: &Path, args: &[&str], what: &str) {
    let before = snapshot(d);
    let o = nsrm_in(d, args);
    no_crash(&o, &format!("{args:?}"));
    assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    assert!(stderr(&o).contains(what), "{args:?}: {}", stderr(&o));
    assert_eq!(snapshot(d), before, "{args:?} changed a file");
    assert!(temporaries(d).is_empty(), "{args:?}");
}

const INPUT: &str = "is an input of this run";
const TWICE: &str = "two outputs of this run are the same file";

#[test]
#[cfg(unix)]
fn family1_no_command_writes_its_input() {
    let dir = fixture();
    let d = dir.path();
    let ln = |target: &str, name: &str| std::os::unix::fs::symlink(target, d.join(name)).unwrap();
    let hard = |target: &str, name: &str| std::fs::hard_link(d.join(target), d.join(name)).unwrap();
    // Names for the inputs that the commands' own extension checks accept.
    ln("s.exr", "frame_link.png");
    hard("p.csv", "p_hard.svg");
    hard("m.json", "m_hard.wgsl");
    ln("p.csv", "p_link.exr");
    std::fs::create_dir(d.join("sub")).unwrap();
    std::fs::copy(d.join("m.json"), d.join("cfg.clf")).unwrap();
    let o = "--overwrite";
    let cases: Vec<Vec<&str>> = vec![
        vec![
            "chart", "extract", "s.exr", "--chart", "cc24", "-o", "s.exr", o,
        ],
        vec![
            "chart",
            "extract",
            "s.exr",
            "--chart",
            "cc24",
            "-o",
            "q.csv",
            "--json",
            "sub/../s.exr",
            o,
        ],
        vec![
            "chart",
            "extract",
            "s.exr",
            "--chart",
            "cc24",
            "-o",
            "q.csv",
            "--overlay",
            "frame_link.png",
            o,
        ],
        vec![
            "fit",
            "--capture",
            "s.exr",
            "--chart",
            "cc24",
            "-o",
            "s.exr",
            o,
        ],
        vec!["fit", "--training", "p.csv", "-o", "p.csv", o],
        vec!["fit", "--training", "p.csv", "-o", "./sub/../p.csv", o],
        vec![
            "eval",
            "--training",
            "p.csv",
            "--in-sample",
            "--plot",
            "p_hard.svg",
            o,
        ],
        vec![
            "export",
            "--model",
            "m.json",
            "--format",
            "clf",
            "--training",
            "p.csv",
            "-o",
            "m.json",
            o,
        ],
        vec![
            "export",
            "--model",
            "m.json",
            "--format",
            "cube",
            "--training",
            "p.csv",
            "-o",
            "p.csv",
            o,
        ],
        // The OCIO config's companion CLF is the input model.
        vec![
            "export",
            "--model",
            "cfg.clf",
            "--format",
            "ocio",
            "--training",
            "p.csv",
            "-o",
            "cfg.ocio",
            o,
        ],
        vec![
            "export-shader",
            "--model",
            "m.json",
            "--lang",
            "wgsl",
            "-o",
            "m_hard.wgsl",
            o,
        ],
        vec![
            "export-shader",
            "--model",
            "m.json",
            "--lang",
            "dctl",
            "-o",
            "sub/../m.json",
            o,
        ],
        vec!["render-chart", "--training", "p.csv", "-o", "p_link.exr", o],
        vec![
            "render-scene",
            "--chart",
            "cc24",
            "--camera",
            "p.csv",
            "-o",
            "p_link.exr",
            o,
        ],
    ];
    for args in cases {
        refused(d, &args, INPUT);
    }
    // apply: the model is an input too (the plan compares the frames).
    std::fs::create_dir(d.join("out")).unwrap();
    std::fs::hard_link(d.join("m.json"), d.join("out/s_xyz.exr")).unwrap();
    refused(
        d,
        &[
            "apply", "--model", "m.json", "--device", "cpu", "-o", "out", "s.exr", o,
        ],
        INPUT,
    );
}

#[test]
fn family2_outputs_are_one_unit() {
    let dir = fixture();
    let d = dir.path();
    let o = "--overwrite";
    for args in [
        vec![
            "chart", "extract", "s.exr", "--chart", "cc24", "-o", "q.csv", "--json", "q.csv", o,
        ],
        vec![
            "chart", "extract", "s.exr", "--chart", "cc24", "-o", "q.csv", "--json", "./q.csv",
        ],
        vec![
            "render-scene",
            "--chart",
            "cc24",
            "-o",
            "t.exr",
            "--flat-output",
            "t.exr",
            o,
        ],
        vec![
            "fit",
            "--capture",
            "s.exr",
            "--chart",
            "cc24",
            "-o",
            "f.png",
            "--overlay",
            "f.png",
            o,
        ],
    ] {
        refused(d, &args, TWICE);
    }
    // An output that cannot be written (a directory at its name) is refused before any work:
    // no earlier output appears.
    std::fs::create_dir(d.join("j.json")).unwrap();
    let before = snapshot(d);
    let r = nsrm_in(
        d,
        &[
            "chart", "extract", "s.exr", "--chart", "cc24", "-o", "r.csv", "--json", "j.json", o,
        ],
    );
    assert_eq!(r.status.code(), Some(1), "{}", stderr(&r));
    assert!(stderr(&r).contains("not a regular file"), "{}", stderr(&r));
    assert_eq!(snapshot(d), before);
    // An overlay into a missing directory: the directory is made and all three are written.
    nsrm_ok(
        d,
        &[
            "chart",
            "extract",
            "s.exr",
            "--chart",
            "cc24",
            "-o",
            "r.csv",
            "--json",
            "r.json",
            "--overlay",
            "new/dir/r.png",
        ],
    );
    for f in ["r.csv", "r.json", "new/dir/r.png"] {
        assert!(d.join(f).is_file(), "{f}");
    }
    // render-scene writes its three files together.
    nsrm_ok(
        d,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "--width",
            "300",
            "--height",
            "200",
            "-o",
            "v.exr",
            "--flat-output",
            "v_flat.tif",
        ],
    );
    for f in ["v.exr", "v.scene.json", "v_flat.tif"] {
        assert!(d.join(f).is_file(), "{f}");
    }
    // export ocio: both files, or (existing, no --overwrite) neither replaced.
    nsrm_ok(
        d,
        &[
            "export",
            "--model",
            "m.json",
            "--format",
            "ocio",
            "--training",
            "p.csv",
            "-o",
            "c.ocio",
        ],
    );
    assert!(d.join("c.ocio").is_file() && d.join("c.clf").is_file());
    std::fs::remove_file(d.join("c.ocio")).unwrap();
    let before = snapshot(d);
    let r = nsrm_in(
        d,
        &[
            "export",
            "--model",
            "m.json",
            "--format",
            "ocio",
            "--training",
            "p.csv",
            "-o",
            "c.ocio",
        ],
    );
    assert_eq!(r.status.code(), Some(1), "{}", stderr(&r));
    assert!(
        stderr(&r).contains("c.clf: already exists"),
        "{}",
        stderr(&r)
    );
    assert_eq!(snapshot(d), before);
    assert!(temporaries(d).is_empty());
}

/// Starts `args` in `d`, sends `signal` once a temporary of nsrm's form appears (or after
/// `fallback`), and returns its output.
#[cfg(unix)]
fn interrupted(d: &Path, args: &[&str], signal: &str, fallback: Duration) -> (Output, bool) {
    let child = nsrm()
        .current_dir(d)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    let mut seen = false;
    while !seen && t.elapsed() < fallback {
        std::thread::sleep(Duration::from_millis(1));
        seen = !temporaries(d).is_empty();
    }
    let ok = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    (child.wait_with_output().unwrap(), seen)
}

#[test]
#[cfg(unix)]
fn family3_signals_leave_no_temporaries() {
    let dir = fixture();
    let d = dir.path();
    let cases: [(&[&str], &[&str]); 3] = [
        (
            &[
                "render-scene",
                "--chart",
                "cc24",
                "--width",
                "1500",
                "--height",
                "1000",
                "-o",
                "big.exr",
                "--flat-output",
                "big_flat.exr",
            ],
            &["big.exr", "big_flat.exr", "big.scene.json"],
        ),
        (
            &[
                "export",
                "--model",
                "m.json",
                "--format",
                "cube",
                "--lut-size",
                "129",
                "--training",
                "p.csv",
                "-o",
                "big.cube",
            ],
            &["big.cube"],
        ),
        (
            &[
                "chart",
                "extract",
                "s.exr",
                "--chart",
                "cc24",
                "-o",
                "x.csv",
                "--json",
                "x.json",
                "--overlay",
                "x.png",
            ],
            &["x.csv", "x.json", "x.png"],
        ),
    ];
    for (signal, status) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        for (args, outputs) in &cases {
            let (o, _) = interrupted(d, args, signal, Duration::from_millis(1000));
            no_crash(&o, &format!("{args:?}"));
            let present: Vec<&&str> = outputs.iter().filter(|f| d.join(f).exists()).collect();
            if o.status.success() {
                // Finished before the signal came: every output is there.
                assert_eq!(present.len(), outputs.len(), "{args:?}");
            } else {
                assert_eq!(
                    o.status.code(),
                    Some(status),
                    "{signal} {args:?}: {}",
                    stderr(&o)
                );
                // All outputs or none.
                assert!(
                    present.is_empty() || present.len() == outputs.len(),
                    "{signal} {args:?}: {present:?}"
                );
            }
            assert!(
                temporaries(d).is_empty(),
                "{signal} {args:?}: {:?}",
                temporaries(d)
            );
            for f in *outputs {
                let _ = std::fs::remove_file(d.join(f));
            }
        }
    }
    // While a temporary is being written (the signal sent once one appears): removed, nothing
    // committed, 143.
    let args = [
        "render-scene",
        "--chart",
        "cc24",
        "--width",
        "1200",
        "--height",
        "800",
        "-o",
        "w.exr",
        "--flat-output",
        "w_flat.exr",
    ];
    let (o, seen) = interrupted(d, &args, "TERM", Duration::from_secs(300));
    no_crash(&o, "render-scene while writing");
    if seen && !o.status.success() {
        assert_eq!(o.status.code(), Some(143), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("interrupted by SIGTERM"),
            "{}",
            stderr(&o)
        );
        for f in ["w.exr", "w_flat.exr", "w.scene.json"] {
            assert!(!d.join(f).exists(), "{f}");
        }
    } else {
        println!(
            "note: render-scene finished before its temporary was seen ({:?})",
            o.status
        );
    }
}

#[test]
fn family5_numbers_out_of_range_are_refused() {
    let dir = fixture();
    let d = dir.path();
    for (args, what) in [
        (
            vec![
                "render-scene",
                "--chart",
                "cc24",
                "--exposure",
                "1e300",
                "-o",
                "x.exr",
            ],
            "exposure",
        ),
        (
            vec![
                "render-scene",
                "--chart",
                "cc24",
                "--white-level",
                "1e300",
                "-o",
                "x.exr",
            ],
            "white level",
        ),
        (
            vec![
                "render-scene",
                "--chart",
                "cc24",
                "--noise",
                "1e300",
                "-o",
                "x.exr",
            ],
            "noise",
        ),
        (
            vec![
                "render-scene",
                "--chart",
                "cc24",
                "--shot-noise",
                "1e300",
                "-o",
                "x.exr",
            ],
            "noise",
        ),
        (
            vec![
                "render-scene",
                "--chart",
                "cc24",
                "--exposure",
                "NaN",
                "-o",
                "x.exr",
            ],
            "exposure",
        ),
        (
            vec![
                "chart",
                "rate",
                "--chart",
                "cc24",
                "--scenes",
                "1",
                "--min-area",
                "NaN",
            ],
            "--min-area",
        ),
        (
            vec![
                "chart",
                "rate",
                "--chart",
                "cc24",
                "--scenes",
                "1",
                "--max-tilt=-5",
            ],
            "--max-tilt",
        ),
        (
            vec![
                "chart", "rate", "--chart", "cc24", "--scenes", "1", "--stops", "inf",
            ],
            "--max-stops inf",
        ),
        (
            vec![
                "chart",
                "rate",
                "--chart",
                "cc24",
                "--scenes",
                "1",
                "--min-blur",
                "1",
                "--max-blur",
                "0.5",
            ],
            "--min-blur 1 is above --max-blur 0.5",
        ),
        (
            vec![
                "chart",
                "rate",
                "--chart",
                "cc24",
                "--scenes",
                "1",
                "--min-tilt",
                "40",
            ],
            "--min-tilt 40 is above --max-tilt 30 (its default)",
        ),
        (
            vec![
                "chart",
                "rate",
                "--chart",
                "cc24",
                "--scenes",
                "2",
                "--seed",
                "18446744073709551615",
            ],
            "the last seed",
        ),
    ] {
        refused(d, &args, what);
    }
    // A rendered scene at the largest exposure and white level has only finite pixels.
    nsrm_ok(
        d,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "--width",
            "64",
            "--height",
            "48",
            "--exposure",
            "1e30",
            "--white-level",
            "1e30",
            "--noise",
            "1e30",
            "-o",
            "hot.exr",
        ],
    );
    let f = crate::common::read_frame(&d.join("hot.exr"), &Default::default()).unwrap();
    assert!(f.data.iter().all(|v| v.is_finite()));
    // A degenerate chart reference (all zero, constant) is refused, not "matched".
    let labels: Vec<String> = std::fs::read_to_string(d.join("p.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("label,"))
        .map(|l| l.split(',').next().unwrap().to_string())
        .collect();
    for (name, v) in [("zero.csv", "0,0,0"), ("grey.csv", "20,20,20")] {
        let text: String = std::iter::once("label,X,Y,Z".to_string())
            .chain(labels.iter().map(|l| format!("{l},{v}")))
            .collect::<Vec<_>>()
            .join("\n");
        std::fs::write(d.join(name), text).unwrap();
        let o = nsrm_in(
            d,
            &[
                "chart",
                "extract",
                "s.exr",
                "--chart",
                "cc24",
                "--reference",
                name,
                "-o",
                "z.csv",
            ],
        );
        no_crash(&o, name);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("nearly alike"),
            "{name}: {}",
            stderr(&o)
        );
        assert!(!d.join("z.csv").exists());
    }
}

#[test]
fn family6_files_are_what_they_say() {
    let dir = fixture();
    let d = dir.path();
    // A PRM whose coefficients are finite in f32 but whose LUT entries overflow.
    let big: Vec<f64> = (0..27)
        .map(|i| if i % 2 == 0 { 3e38 } else { -3e38 })
        .collect();
    let m = nsrm::Model::from_matrix(nsrm::Kind::Prm, 2, big).unwrap();
    std::fs::write(d.join("huge.json"), m.to_json()).unwrap();
    for format in ["cube", "clf"] {
        let out = format!("huge.{format}");
        let o = nsrm_in(
            d,
            &[
                "export",
                "--model",
                "huge.json",
                "--format",
                format,
                "--training",
                "p.csv",
                "-o",
                &out,
            ],
        );
        no_crash(&o, format);
        assert_eq!(o.status.code(), Some(1), "{format}: {}", stderr(&o));
        // The .cube's LUT overflows; the CLF's linear part is already singular. Refused either way.
        if format == "cube" {
            assert!(
                stderr(&o).contains("not finite"),
                "{format}: {}",
                stderr(&o)
            );
        }
        assert!(!d.join(&out).exists());
    }
    // eval --variants on measured data: the white that some variants need is a patch, and
    // --white-patch is accepted with --variants.
    let o = nsrm_in(
        d,
        &[
            "eval",
            "--training",
            "p.csv",
            "--models",
            "lrm",
            "--in-sample",
            "--variants",
        ],
    );
    no_crash(&o, "variants");
    if !o.status.success() {
        assert!(stderr(&o).contains("--white-patch"), "{}", stderr(&o));
    }
    let o = nsrm_ok(
        d,
        &[
            "eval",
            "--training",
            "p.csv",
            "--models",
            "lrm,nsrm",
            "--in-sample",
            "--variants",
            "--white-patch",
            "19 white 9.5",
        ],
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("de00+preserve-white"), "{out}");
}

#[test]
#[cfg(unix)]
fn family8_text_inputs_come_through_pipes_never_from_devices() {
    let dir = fixture();
    let d = dir.path();
    // A model through a pipe (`--model <(cat m.json)` is /dev/fd/N, a pipe).
    let mut child = nsrm()
        .current_dir(d)
        .args([
            "export-shader",
            "--model",
            "/dev/stdin",
            "--lang",
            "wgsl",
            "-o",
            "m.wgsl",
        ])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let json = std::fs::read(d.join("m.json")).unwrap();
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(&json).unwrap();
    }
    let o = child.wait_with_output().unwrap();
    assert_ok(&o);
    assert!(d.join("m.wgsl").is_file());
    // A named FIFO fed by another process, as training data.
    assert!(Command::new("mkfifo")
        .arg(d.join("t.fifo"))
        .status()
        .unwrap()
        .success());
    let feeder = {
        let (src, dst) = (d.join("p.csv"), d.join("t.fifo"));
        std::thread::spawn(move || std::fs::write(dst, std::fs::read(src).unwrap()))
    };
    nsrm_ok(
        d,
        &[
            "fit",
            "--training",
            "t.fifo",
            "--model",
            "lrm",
            "-o",
            "f.json",
        ],
    );
    feeder.join().unwrap().unwrap();
    // Over the cap through a pipe: refused by the cap, not read to the end.
    let mut child = nsrm()
        .current_dir(d)
        .args(["fit", "--training", "/dev/stdin", "-o", "g.json"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let writer = {
        let mut stdin = child.stdin.take().unwrap();
        std::thread::spawn(move || {
            use std::io::Write;
            let line = b"a,1,1,1,1,1,1\n".repeat(1 << 16);
            for _ in 0..80 {
                if stdin.write_all(&line).is_err() {
                    break;
                }
            }
        })
    };
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap();
    no_crash(&o, "big pipe");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("larger than the 64 MiB limit"),
        "{}",
        stderr(&o)
    );
    // Devices are refused by what they are.
    for args in [
        vec![
            "export-shader",
            "--model",
            "/dev/zero",
            "--lang",
            "wgsl",
            "-o",
            "z.wgsl",
        ],
        vec!["fit", "--training", "/dev/null", "-o", "z.json"],
    ] {
        let o = nsrm_in(d, &args);
        no_crash(&o, &format!("{args:?}"));
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("(it is a character device)"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
    // A fit that fails on an overflowing value names the file as well as the patch.
    let text = std::fs::read_to_string(d.join("p.csv")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let cells: Vec<String> = lines[3].split(',').map(String::from).collect();
    lines[3] = format!("{},1e200,{}", cells[0], cells[2..].join(","));
    std::fs::write(d.join("over.csv"), lines.join("\n")).unwrap();
    let o = nsrm_in(
        d,
        &[
            "fit",
            "--training",
            "over.csv",
            "--model",
            "prm",
            "--order",
            "3",
            "-o",
            "o.json",
        ],
    );
    no_crash(&o, "overflow");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("over.csv"), "{}", stderr(&o));
    assert!(stderr(&o).contains(&cells[0]), "{}", stderr(&o));
}
