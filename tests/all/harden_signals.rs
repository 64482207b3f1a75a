//! Family 6: temporary files are this run's alone, and interruptions clean up. SIGINT, SIGTERM
//! and SIGHUP sent to a child `nsrm apply` in the middle of a batch: it stops starting files,
//! removes its temporaries, prints the summary and exits 130 / 143 / 129; every output present
//! is complete. Stale temporaries of a killed run are reported and kept unless asked.

use crate::common;
use common::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A batch of `n` copies of one frame in `dir/in`.
fn batch(dir: &Path, n: usize) {
    model(dir);
    std::fs::create_dir(dir.join("in")).unwrap();
    exr(&dir.join("in/f.0000.exr"), 256, 256);
    for i in 1..n {
        std::fs::copy(
            dir.join("in/f.0000.exr"),
            dir.join(format!("in/f.{i:04}.exr")),
        )
        .unwrap();
    }
}

#[cfg(unix)]
fn interrupt_run(signal: &str, status: i32) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 400;
    batch(d, n);
    let child = nsrm()
        .current_dir(d)
        .args([
            "apply", "--model", "m.json", "--device", "cpu", "-j", "1", "-o", "out", "in",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Signal once the first output or temporary appears.
    let t = Instant::now();
    loop {
        // Not the plan's write probe (made and removed before the handlers are installed).
        let any = std::fs::read_dir(d.join("out"))
            .map(|r| {
                r.flatten()
                    .any(|e| !e.file_name().to_string_lossy().contains("nsrm-write-probe"))
            })
            .unwrap_or(false);
        if any {
            break;
        }
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "no output after 60 s"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    let ok = Command::new("kill")
        .args([&format!("-{signal}"), &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    no_crash(&out, signal);
    assert_eq!(out.status.code(), Some(status), "{signal}: {err}");
    assert!(
        err.contains(&format!("interrupted by SIG{signal}")),
        "{err}"
    );
    assert!(err.contains("not attempted"), "{err}");
    let names = names(&d.join("out"));
    assert!(
        names.iter().all(|n| !n.ends_with(".tmp")),
        "temporaries left: {names:?}"
    );
    assert!(names.len() < n, "the batch was not stopped: {err}");
    // Every output that exists is complete.
    for name in &names {
        let f = crate::common::read_frame(&d.join("out").join(name), &Default::default()).unwrap();
        assert_eq!((f.width, f.height), (256, 256));
    }
    let converted: usize = err
        .split("interrupted by")
        .nth(1)
        .and_then(|s| s.split(':').nth(1))
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no count in {err}"));
    assert_eq!(converted, names.len(), "{err}");
}

#[cfg(unix)]
#[test]
fn sigint_stops_cleanly_with_130() {
    interrupt_run("INT", 130);
}

#[cfg(unix)]
#[test]
fn sigterm_stops_cleanly_with_143() {
    interrupt_run("TERM", 143);
}

#[cfg(unix)]
#[test]
fn sighup_stops_cleanly_with_129() {
    interrupt_run("HUP", 129);
}

#[test]
fn stale_temporaries_are_reported_and_removed_only_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    batch(d, 2);
    std::fs::create_dir(d.join("out")).unwrap();
    let stale = d.join("out/.f_xyz.0000.exr.nsrm-1-0123456789abcdef.tmp");
    let other = d.join("out/.notes.tmp");
    std::fs::write(&stale, b"half a frame").unwrap();
    std::fs::write(&other, b"someone else's").unwrap();
    let args = [
        "apply", "--model", "m.json", "--device", "cpu", "-o", "out", "in",
    ];
    let o = nsrm_in(d, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 nsrm temporary file(s)"),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains(".f_xyz.0000.exr.nsrm-1-0123456789abcdef.tmp"));
    assert!(stale.exists() && other.exists());
    let mut with = args.to_vec();
    with.extend(["--skip-existing", "--remove-stale-temporaries"]);
    let o = nsrm_in(d, &with);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("removed 1 stale"), "{}", stderr(&o));
    assert!(!stale.exists());
    assert_eq!(std::fs::read(&other).unwrap(), b"someone else's");
}

#[test]
fn render_chart_writes_frame_and_layout_together() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The layout's name is taken by a directory: the frame must not appear alone.
    std::fs::create_dir(d.join("c.patches.json")).unwrap();
    let o = nsrm_in(
        d,
        &[
            "render-chart",
            "--reflectances",
            "cc24",
            "--patch-size",
            "2",
            "-o",
            "c.exr",
            "--overwrite",
        ],
    );
    no_crash(&o, "render-chart");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));
    assert_eq!(names(d), ["c.patches.json"]);
    std::fs::remove_dir(d.join("c.patches.json")).unwrap();
    let o = nsrm_in(
        d,
        &[
            "render-chart",
            "--reflectances",
            "cc24",
            "--patch-size",
            "2",
            "-o",
            "c.exr",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(names(d), ["c.exr", "c.patches.json"]);
}

/// Waits (at most 120 s) until `done` holds, polling every 2 ms.
fn wait_for(what: &str, mut done: impl FnMut() -> bool) {
    let t = Instant::now();
    while !done() {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "{what}: not after 120 s"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn an_output_and_its_preview_are_committed_together() {
    // The previews of the later frames cannot be committed: their names are taken by
    // directories made while the batch runs (after the plan, which would have refused them).
    // With the output committed before its preview, those outputs appeared alone; now neither
    // appears and the frame fails.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 300;
    batch(d, n);
    let child = Command::new(env!("CARGO_BIN_EXE_nsrm"))
        .current_dir(d)
        .args([
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "-j",
            "1",
            "-o",
            "out",
            "--preview",
            "prev",
            "--continue-on-error",
            "in",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for("the first output", || d.join("out/f_xyz.0000.exr").exists());
    let mut blocked = Vec::new();
    for i in (n / 2..n).rev() {
        // Fails (and the frame is not counted) when that preview was already written.
        if std::fs::create_dir(d.join(format!("prev/f_xyz.{i:04}.png"))).is_ok() {
            blocked.push(i);
        }
    }
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    no_crash(&out, "apply --preview");
    assert!(
        blocked.len() > 10,
        "the batch finished before the previews could be blocked: {err}"
    );
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("not a regular file"), "{err}");
    for i in 0..n {
        let o = d.join(format!("out/f_xyz.{i:04}.exr"));
        let p = d.join(format!("prev/f_xyz.{i:04}.png"));
        if blocked.contains(&i) {
            assert!(
                !o.exists(),
                "{} was committed without its preview",
                o.display()
            );
            assert!(p.is_dir());
        } else {
            assert!(o.exists() && p.is_file(), "frame {i}: {err}");
        }
    }
    assert!(err.contains(&format!("{} failed", blocked.len())), "{err}");
    for sub in ["out", "prev"] {
        let left: Vec<String> = names(&d.join(sub))
            .into_iter()
            .filter(|n| n.ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "temporaries left in {sub}: {left:?}");
    }
}

#[cfg(unix)]
#[test]
fn a_frame_being_written_at_sigterm_is_aborted_not_finished() {
    // A small frame, then a large noisy one written with the slowest deflate: the signal comes
    // while the large one's temporary is being written. It must be aborted (temporary removed,
    // nothing committed); the small one, committed before, stays.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    std::fs::create_dir(d.join("in")).unwrap();
    exr(&d.join("in/f.0000.exr"), 64, 64);
    let mut rng = Rng(7);
    let noise = (0..2048 * 2048 * 3).map(|_| rng.unit()).collect();
    let big = nsrm::Frame::from_data(2048, 2048, nsrm::Layout::Rgb, noise).unwrap();
    let opts = nsrm_io::WriteOptions {
        format: nsrm_io::FileFormat::Exr,
        half: false,
        compression: nsrm_io::ExrCompression::None,
        space: nsrm::OutputSpace::Xyz,
        ..Default::default()
    };
    crate::common::committed(true, |u| {
        crate::common::write_exr(&big, &d.join("in/f.0001.exr"), &opts, u)
    })
    .unwrap();
    drop(big);
    let child = Command::new(env!("CARGO_BIN_EXE_nsrm"))
        .current_dir(d)
        .args([
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "-j",
            "1",
            "--compression",
            "zip",
            "--zip-level",
            "9",
            "-o",
            "out",
            "in",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let writing = |d: &Path| {
        std::fs::read_dir(d.join("out")).is_ok_and(|r| {
            r.flatten().any(|e| {
                let n = e.file_name().to_string_lossy().into_owned();
                n.starts_with(".f_xyz.0001.exr.nsrm-") && n.ends_with(".tmp")
            })
        })
    };
    wait_for("the large frame's temporary", || {
        d.join("out/f_xyz.0000.exr").exists() && writing(d)
    });
    let ok = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    no_crash(&out, "SIGTERM while writing");
    assert_eq!(out.status.code(), Some(143), "{err}");
    assert!(err.contains("1 converted"), "{err}");
    assert!(err.contains("1 aborted while being written"), "{err}");
    assert_eq!(names(&d.join("out")), ["f_xyz.0000.exr"], "{err}");
    let f = crate::common::read_frame(&d.join("out/f_xyz.0000.exr"), &Default::default()).unwrap();
    assert_eq!((f.width, f.height), (64, 64));
}

/// Runs `nsrm args` in `dir` with its standard output and error pipes closed before it writes
/// (what `| head -1` does once it has its line): its exit status.
#[cfg(unix)]
fn with_closed_pipes(dir: &Path, args: &[&str]) -> std::process::ExitStatus {
    let mut child = nsrm()
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    drop(child.stderr.take());
    child.wait().unwrap()
}

/// A closed pipe ends a command quietly: `nsrm export … | head -1` exits 0 with its export
/// written (before: 101, "internal error … failed printing to stdout"), `nsrm apply … 2>&1 |
/// head -1` on a file that fails exits 1 (before: SIGABRT), and a batch's good outputs stay.
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_a_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    batch(d, 2);
    nsrm_ok(d, &["fit", "--kind", "lrm", "-o", "fitted.json"]);
    let st = with_closed_pipes(
        d,
        &[
            "export",
            "--model",
            "fitted.json",
            "--format",
            "cube",
            "-o",
            "x.cube",
        ],
    );
    assert_eq!((st.code(), st.signal()), (Some(0), None), "export: {st:?}");
    assert!(d.join("x.cube").is_file());
    std::fs::write(d.join("in/z_bad.exr"), b"not an exr").unwrap();
    let args = ["apply", "--model", "m.json", "--device", "cpu", "-o", "out"];
    let st = with_closed_pipes(d, &[&args[..], &["in/z_bad.exr"]].concat());
    assert_eq!((st.code(), st.signal()), (Some(1), None), "apply: {st:?}");
    let st = with_closed_pipes(d, &[&args[..], &["--continue-on-error", "in"]].concat());
    assert_eq!((st.code(), st.signal()), (Some(1), None), "batch: {st:?}");
    let written = names(&d.join("out"));
    assert_eq!(written.len(), 2, "the good outputs stay: {written:?}");
}
