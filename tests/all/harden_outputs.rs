//! Family 1: an input is never written. Odd `--suffix` values, `-o` through directories that do
//! not exist yet, symlinks and hard links, `--preview` names, and destinations that are not
//! regular files, with and without `--overwrite`.

use crate::common;
use common::*;
use std::path::Path;

fn apply(dir: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["apply", "--model", "m.json", "--device", "cpu"];
    args.extend_from_slice(extra);
    let o = nsrm_in(dir, &args);
    no_crash(&o, &format!("{extra:?}"));
    o
}

#[test]
fn suffixes_must_be_name_fragments() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    exr(&d.join("a.exr"), 4, 3);
    let before = bytes(&d.join("a.exr"));
    for suffix in ["/x", "_/../a", "..", "sub/", "a\\b"] {
        let o = apply(d, &["--overwrite", "--suffix", suffix, "a.exr"]);
        assert_eq!(o.status.code(), Some(2), "{suffix}: {}", stderr(&o));
        assert!(stderr(&o).contains("--suffix"), "{suffix}: {}", stderr(&o));
    }
    // An empty suffix beside the input is the input itself.
    let o = apply(d, &["--overwrite", "--suffix", "", "a.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("onto that input itself"),
        "{}",
        stderr(&o)
    );
    assert_eq!(bytes(&d.join("a.exr")), before);
    assert_eq!(names(d), ["a.exr", "m.json"]);
}

#[test]
fn output_dirs_that_lead_back_to_the_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    std::fs::create_dir(d.join("in")).unwrap();
    exr(&d.join("in/a.exr"), 4, 3);
    let before = bytes(&d.join("in/a.exr"));
    // Through a directory that does not exist yet, and back up.
    for out in ["in/newdir/..", "./in/x/y/../..", "in/."] {
        let o = apply(d, &["--overwrite", "--suffix", "", "-o", out, "in/a.exr"]);
        assert_eq!(o.status.code(), Some(2), "{out}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("onto that input itself"),
            "{out}: {}",
            stderr(&o)
        );
    }
    assert_eq!(bytes(&d.join("in/a.exr")), before);
    assert_eq!(names(&d.join("in")), ["a.exr"], "nothing created");
    #[cfg(unix)]
    {
        // A symlinked output directory, and an existing output that is a link to the input.
        std::os::unix::fs::symlink(d.join("in"), d.join("link")).unwrap();
        let o = apply(
            d,
            &["--overwrite", "--suffix", "", "-o", "link", "in/a.exr"],
        );
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        std::fs::create_dir(d.join("out")).unwrap();
        std::fs::hard_link(d.join("in/a.exr"), d.join("out/a_xyz.exr")).unwrap();
        let o = apply(d, &["--overwrite", "-o", "out", "in/a.exr"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("onto that input itself"),
            "{}",
            stderr(&o)
        );
        std::fs::remove_file(d.join("out/a_xyz.exr")).unwrap();
        std::os::unix::fs::symlink(d.join("in/a.exr"), d.join("out/a_xyz.exr")).unwrap();
        let o = apply(d, &["--overwrite", "-o", "out", "in/a.exr"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        // A preview name that is a link to an input.
        std::fs::remove_file(d.join("out/a_xyz.exr")).unwrap();
        std::os::unix::fs::symlink(d.join("in/a.exr"), d.join("out/a_xyz.png")).unwrap();
        let o = apply(
            d,
            &["--overwrite", "-o", "out", "--preview", "out", "in/a.exr"],
        );
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("the preview for"), "{}", stderr(&o));
        assert_eq!(bytes(&d.join("in/a.exr")), before);
    }
    // A plain, legitimate run still works.
    let o = apply(d, &["-o", "fresh/sub/..", "in/a.exr"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("fresh/a_xyz.exr").is_file());
    assert_eq!(bytes(&d.join("in/a.exr")), before);
}

#[cfg(unix)]
#[test]
fn only_regular_files_are_ever_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    exr(&d.join("a.exr"), 4, 3);
    exr(&d.join("b.exr"), 4, 3);
    let status = std::process::Command::new("mkfifo")
        .arg(d.join("a_xyz.exr"))
        .status()
        .expect("mkfifo");
    assert!(status.success());
    std::fs::create_dir(d.join("b_xyz.exr")).unwrap();
    let o = apply(d, &["--overwrite", "--continue-on-error", "a.exr", "b.exr"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("not a regular file (it is a FIFO)"), "{err}");
    assert!(
        err.contains("not a regular file (it is a directory)"),
        "{err}"
    );
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(d.join("a_xyz.exr"))
        .unwrap()
        .file_type()
        .is_fifo());
    assert!(d.join("b_xyz.exr").is_dir());
    // The library refuses as well, whoever calls it.
    let e = nsrm_output::Session::new(true)
        .unit()
        .write_bytes(&d.join("a_xyz.exr"), b"x")
        .unwrap_err();
    assert!(e.to_string().contains("FIFO"), "{e}");
    // An input that is a FIFO is reported by what it is, never opened (which would block).
    let status = std::process::Command::new("mkfifo")
        .arg(d.join("pipe.exr"))
        .status()
        .unwrap();
    assert!(status.success());
    let o = apply(d, &["pipe.exr"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("not a regular file (it is a FIFO)"),
        "{}",
        stderr(&o)
    );
    // In a directory it is taken, and fails alone with the reason.
    std::fs::create_dir(d.join("dir")).unwrap();
    exr(&d.join("dir/good.exr"), 4, 3);
    std::process::Command::new("mkfifo")
        .arg(d.join("dir/z.exr"))
        .status()
        .unwrap();
    let o = apply(d, &["--continue-on-error", "-o", "o", "dir"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("z.exr: cannot read: not a regular file (it is a FIFO)"),
        "{}",
        stderr(&o)
    );
    assert!(d.join("o/good_xyz.exr").is_file());
}
