//! Helpers shared by the hardening tests (`tests/harden_*.rs`): a tiny model, tiny frames and
//! the built binary.

#![allow(dead_code)]

use nsrm::colorimetry::spaces::OutputSpace;
use nsrm::io::{ExrCompression, FileFormat, WriteOptions};
use nsrm::model::{Kind, Model};
use nsrm::{Frame, Layout};
use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `nsrm` in `dir`.
pub fn nsrm(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nsrm"))
        .current_dir(dir)
        .args(args)
        .env_remove("NSRM_ADAPTER")
        .output()
        .expect("running nsrm")
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts no panic (101) and no abort (134 / SIGABRT) happened.
pub fn no_crash(o: &Output, what: &str) {
    let err = stderr(o);
    assert!(!err.contains("panicked"), "{what}: {err}");
    assert!(
        !matches!(o.status.code(), Some(101) | Some(134)),
        "{what}: {:?} {err}",
        o.status
    );
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert!(
            o.status.signal().is_none(),
            "{what}: killed by {:?}: {err}",
            o.status
        );
    }
}

/// Writes an identity-like LRM model (`m.json`) into `dir`.
pub fn model(dir: &Path) {
    let m = Model::from_matrix(
        Kind::Lrm,
        1,
        vec![50.0, 30.0, 15.0, 25.0, 60.0, 10.0, 2.0, 12.0, 90.0],
    )
    .unwrap();
    std::fs::write(dir.join("m.json"), m.to_json()).unwrap();
}

/// A small RGB frame with a gradient.
pub fn frame(w: usize, h: usize) -> Frame {
    let data = (0..w * h * 3).map(|i| (i % 97) as f32 / 97.0).collect();
    Frame {
        width: w,
        height: h,
        layout: Layout::Rgb,
        data,
    }
}

/// Writes a small EXR frame at `path`.
pub fn exr(path: &Path, w: usize, h: usize) {
    let opts = WriteOptions {
        format: FileFormat::Exr,
        half: false,
        compression: ExrCompression::None,
        space: OutputSpace::Xyz,
        overwrite: true,
        zip_level: nsrm::io::DEFAULT_ZIP_LEVEL,
    };
    nsrm::io::write_exr(&frame(w, h), path, &opts).unwrap();
}

/// Writes a small 32-bit float TIFF frame at `path`.
pub fn tiff(path: &Path, w: usize, h: usize) {
    nsrm::io::write_tiff(&frame(w, h), path, true).unwrap();
}

/// Bytes of a file, for checking inputs are never written.
pub fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

/// File names in `dir`, sorted.
pub fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}
