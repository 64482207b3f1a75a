//! What the integration tests share: one seeded RNG, one generator of frames full of awkward
//! pixels, one f32 error bound against the f64 reference, one training fixture, and the built
//! binary run the same way everywhere (with `XDG_RUNTIME_DIR` set, so Mesa prints no `error:`
//! lines on a machine without one, and without `NSRM_ADAPTER` from the caller's shell).
//!
//! Each test file takes it with `mod common;` and uses what it needs.

#![allow(dead_code)]

mod kit;

use nsrm::Model;
use nsrm::{Frame, Layout};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

pub use kit::*;

/// The ColorChecker SG spectra in `../shared/data`, or `None` (after [`skip`]) when absent:
/// they stay outside the repository.
pub fn sg_path() -> Option<PathBuf> {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("../shared/data/colorchecker_sg_140.csv");
    if p.exists() {
        Some(p)
    } else {
        skip(&format!(
            "{} is absent (the ColorChecker SG spectra stay outside the repository)",
            p.display()
        ));
        None
    }
}

/// The tests skipped in this run, `test name: reason`.
static SKIPS: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());

/// The real Canon DNG of a ColorChecker Passport, `../shared/data/colorchart.dng`, or under
/// `$NSRM_SHARED` (a worktree elsewhere) when that is absent.
pub fn chart_dng() -> PathBuf {
    let p = PathBuf::from(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
        "/../shared/data/colorchart.dng"
    ));
    match std::env::var_os("NSRM_SHARED") {
        Some(s) if !p.exists() => PathBuf::from(s).join("data/colorchart.dng"),
        _ => p,
    }
}

/// A test whose prerequisite (an external tool, a driver, `../shared` data) is absent: under
/// `CI=true` this fails the test; otherwise it prints `SKIP: reason` and records the test, and
/// the run ends with one summary line counting the skipped tests (after libtest's own result
/// line, which counts them as passed). The caller returns after it.
pub fn skip(reason: &str) {
    kit::skip_or_fail(reason);
    let name = std::thread::current()
        .name()
        .unwrap_or("(unnamed test)")
        .to_string();
    let mut skips = SKIPS.lock().unwrap_or_else(|e| e.into_inner());
    if skips.is_empty() {
        // SAFETY: `print_skips` takes no arguments, cannot unwind (it ignores write errors and
        // a poisoned lock) and is registered once per process.
        unsafe {
            libc::atexit(print_skips);
        }
    }
    skips.push(format!("{name}: {reason}"));
}

/// Prints the skipped tests at exit, after libtest's summary.
extern "C" fn print_skips() {
    use std::io::Write;
    let skips = SKIPS.lock().unwrap_or_else(|e| e.into_inner());
    let mut err = std::io::stderr().lock();
    let _ = writeln!(
        err,
        "\nSKIPPED {} test(s) for a missing prerequisite (counted as passed above; under CI=true they fail; docs/testing.md lists what to install):",
        skips.len()
    );
    for s in skips.iter() {
        let _ = writeln!(err, "  {s}");
    }
}

/// A runtime directory for Mesa (once per test process) when the environment has none.
pub fn xdg_runtime_dir() -> Option<PathBuf> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
            return None;
        }
        let d = std::env::temp_dir().join(format!("nsrm-test-xdg-{}", std::process::id()));
        std::fs::create_dir_all(&d).ok()?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o700));
        }
        Some(d)
    })
    .clone()
}

/// The built `nsrm`, with `XDG_RUNTIME_DIR` set and `NSRM_ADAPTER` unset.
pub fn nsrm() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_nsrm"));
    c.env_remove("NSRM_ADAPTER");
    if let Some(d) = xdg_runtime_dir() {
        c.env("XDG_RUNTIME_DIR", d);
    }
    c
}

/// Runs the built `nsrm` in `dir`.
pub fn nsrm_in(dir: &Path, args: &[&str]) -> Output {
    nsrm()
        .current_dir(dir)
        .args(args)
        .output()
        .expect("running nsrm")
}

/// Runs `nsrm` in `dir` and asserts it succeeded.
pub fn nsrm_ok(dir: &Path, args: &[&str]) -> Output {
    let out = nsrm_in(dir, args);
    assert!(
        out.status.success(),
        "nsrm {args:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

/// Asserts that a command succeeded, showing its stderr when it did not.
pub fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A fresh directory under the system's temporary directory, named for the test, removed when
/// the test ends (kept, and its path printed, when the test fails, to look at what it left).
pub fn tempdir(name: &str) -> TestDir {
    // Unique per call (tempfile's random suffix): tests run in parallel in one process, and two
    // of them giving the same name once removed each other's files.
    let dir = tempfile::Builder::new()
        .prefix(&format!("nsrm-{name}-"))
        .tempdir()
        .unwrap();
    TestDir(dir)
}

/// [`tempdir`]'s directory: a [`Path`] that removes itself on drop unless the thread is
/// panicking.
pub struct TestDir(tempfile::TempDir);

impl std::ops::Deref for TestDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

impl AsRef<Path> for TestDir {
    fn as_ref(&self) -> &Path {
        self
    }
}

impl AsRef<std::ffi::OsStr> for TestDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.as_os_str()
    }
}

impl TestDir {
    /// The directory, never removed: for a fixture made once and shared by many tests through a
    /// static, which outlives every test.
    pub fn keep(mut self) -> PathBuf {
        self.0.disable_cleanup(true);
        self.0.path().to_path_buf()
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.disable_cleanup(true);
            eprintln!("kept for a failed test: {}", self.0.path().display());
        }
    }
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
        nsrm::Kind::Lrm,
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
    use nsrm_io::{ExrCompression, FileFormat, WriteOptions};
    let opts = WriteOptions {
        format: FileFormat::Exr,
        half: false,
        compression: ExrCompression::None,
        space: nsrm::OutputSpace::Xyz,
        ..Default::default()
    };
    committed(true, |u| write_exr(&frame(w, h), path, &opts, u)).unwrap();
}

/// Reads an EXR, TIFF or raw file into one frame with its alpha (`Decoded::into_frame`).
pub fn read_frame(path: &Path, opts: &nsrm_io::ReadOptions) -> Result<Frame, nsrm_io::IoError> {
    nsrm_io::Decoded::read(path, opts).map(nsrm_io::Decoded::into_frame)
}

/// A decoded frame written as the `nsrm` command writes it: the library's encoder
/// ([`nsrm_io::Decoded::write_to`]) into a temporary staged in an output session's unit.
pub trait WriteStaged {
    /// Stages the frame for `dest` in `unit`.
    fn write(
        self,
        dest: &Path,
        opts: &nsrm_io::WriteOptions,
        unit: &mut nsrm_output::Unit,
    ) -> Result<(), nsrm_io::IoError>;
}

impl WriteStaged for nsrm_io::Decoded {
    fn write(
        self,
        dest: &Path,
        opts: &nsrm_io::WriteOptions,
        unit: &mut nsrm_output::Unit,
    ) -> Result<(), nsrm_io::IoError> {
        unit.write_with(dest, |w| self.write_to(dest, opts, w))
    }
}

/// Stages a new EXR holding `frame` in `unit` (a frame made in memory, written by `Decoded`).
pub fn write_exr(
    frame: &Frame,
    dest: &Path,
    opts: &nsrm_io::WriteOptions,
    unit: &mut nsrm_output::Unit,
) -> Result<(), nsrm_io::IoError> {
    let opts = nsrm_io::WriteOptions {
        format: nsrm_io::FileFormat::Exr,
        ..*opts
    };
    WriteStaged::write(nsrm_io::Decoded::from(frame.clone()), dest, &opts, unit)
}

/// Stages a 32-bit float TIFF holding `frame` in `unit`.
pub fn write_tiff(
    frame: &Frame,
    dest: &Path,
    unit: &mut nsrm_output::Unit,
) -> Result<(), nsrm_io::IoError> {
    let opts = nsrm_io::WriteOptions {
        format: nsrm_io::FileFormat::Tiff,
        half: false,
        compression: nsrm_io::ExrCompression::Keep,
        space: nsrm::OutputSpace::Xyz,
        ..Default::default()
    };
    WriteStaged::write(nsrm_io::Decoded::from(frame.clone()), dest, &opts, unit)
}

/// Runs library writers on one unit of a fresh output session (replacing existing files when
/// `overwrite`) and commits it.
pub fn committed<E: From<nsrm_output::WriteError>>(
    overwrite: bool,
    write: impl FnOnce(&mut nsrm_output::Unit) -> Result<(), E>,
) -> Result<(), E> {
    let session = nsrm_output::Session::new(overwrite);
    let mut unit = session.unit();
    write(&mut unit)?;
    unit.commit()?;
    Ok(())
}

/// Writes a small 32-bit float TIFF frame at `path`.
pub fn tiff(path: &Path, w: usize, h: usize) {
    committed(true, |u| write_tiff(&frame(w, h), path, u)).unwrap();
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

/// Fits a white-preserving NSRM (default order) under StdA and D65 from the built-in spectra in `dir`
/// (`a.json`, `d65.json`) and combines them into the two-illuminant `dual.json`.
pub fn dual_nsrm_model(dir: &Path) {
    for (ill, out) in [("A", "a.json"), ("D65", "d65.json")] {
        nsrm_ok(
            dir,
            &[
                "fit",
                "--kind",
                "nsrm",
                "--illuminant",
                ill,
                "--preserve-white",
                "-o",
                out,
            ],
        );
    }
    nsrm_ok(dir, &["combine", "a.json", "d65.json", "-o", "dual.json"]);
}

/// The tests' standard synthetic capture: `render-scene` of a CC24, 800×560, seed 5, chart at
/// least a fifth of the frame, written as `dir/name` (plus `extra` flags, e.g. `--flat-output`).
pub fn cc24_scene(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    chart_scene(dir, "cc24", name, extra)
}

/// [`cc24_scene`]'s capture of chart `chart` (`cc24`, `sg`, `spyder24`).
pub fn chart_scene(dir: &Path, chart: &str, name: &str, extra: &[&str]) -> PathBuf {
    let mut args = vec![
        "render-scene",
        "--chart",
        chart,
        "--width",
        "800",
        "--height",
        "560",
        "--seed",
        "5",
        "--min-area",
        "0.2",
        "-o",
        name,
    ];
    args.extend_from_slice(extra);
    nsrm_ok(dir, &args);
    dir.join(name)
}

/// 3×3 matrix helpers of the tests (the library keeps its own crate-private): `m · v`, `a · b`,
/// the inverse, XYZ (`Y = 1`) of a chromaticity, the D50 whites, Bradford adaptation and an RGB
/// space's matrix from its primaries (the profile judges' own colorimetry, written from the
/// standards, not read from the library).
pub mod mat {
    /// A 3×3 matrix, row-major.
    pub type Mat3 = [[f64; 3]; 3];

    /// The identity matrix.
    pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

    /// `m · v`.
    pub fn apply(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
        m.map(|r| r[0] * v[0] + r[1] * v[1] + r[2] * v[2])
    }

    /// `a · b`.
    pub fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
    }

    /// The inverse (panics on a singular matrix: the tests invert only invertible ones).
    pub fn invert(m: &Mat3) -> Mat3 {
        let inv = nalgebra::Matrix3::from_fn(|i, j| m[i][j])
            .try_inverse()
            .unwrap_or_else(|| panic!("singular matrix {m:?}"));
        [0, 1, 2].map(|i| [0, 1, 2].map(|j| inv[(i, j)]))
    }

    /// The model's XYZ (white at `Y = white[1]`) → the frames `nsrm apply` writes in `space`
    /// (white at `Y = 1`): [`nsrm::OutputSpace::from_xyz`] scaled by `1 / white[1]`.
    pub fn output_matrix(white: [f64; 3], space: nsrm::OutputSpace) -> Mat3 {
        space.from_xyz(white).map(|row| row.map(|v| v / white[1]))
    }

    /// xy chromaticity → XYZ with `Y = 1`.
    pub fn xy_to_xyz(xy: [f64; 2]) -> [f64; 3] {
        [xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1]]
    }

    /// The D50 white's chromaticity (the DNG `PCStoXYZ`; ICC's PCS white is its XYZ rounded to
    /// four places, [`ICC_D50`]).
    pub const D50_XY: [f64; 2] = [0.3457, 0.3585];

    /// The ICC PCS illuminant (ICC.1, 7.2.16).
    pub const ICC_D50: [f64; 3] = [0.9642, 1.0, 0.8249];

    /// Bradford chromatic adaptation from the white `src` to the white `dst` (XYZ, any scale: the
    /// matrix maps `src` to `dst` scaled to `src`'s Y).
    pub fn bradford(src: [f64; 3], dst: [f64; 3]) -> Mat3 {
        const B: Mat3 = [
            [0.8951, 0.2664, -0.1614],
            [-0.7502, 1.7135, 0.0367],
            [0.0389, -0.0685, 1.0296],
        ];
        let s = apply(&B, src.map(|v| v / src[1]));
        let d = apply(&B, dst.map(|v| v / dst[1]));
        let diag = [
            [d[0] / s[0], 0.0, 0.0],
            [0.0, d[1] / s[1], 0.0],
            [0.0, 0.0, d[2] / s[2]],
        ];
        mul(&invert(&B), &mul(&diag, &B))
    }

    /// RGB → XYZ (`Y = 1` at the white) of the RGB space with primaries `prim` (xy) and white
    /// `white` (xy).
    pub fn rgb_to_xyz(prim: [[f64; 2]; 3], white: [f64; 2]) -> Mat3 {
        let p = [0, 1, 2].map(|i| prim.map(|c| xy_to_xyz(c)[i]));
        let s = apply(&invert(&p), xy_to_xyz(white));
        p.map(|row| [0, 1, 2].map(|j| row[j] * s[j]))
    }

    /// Linear ProPhoto (ROMM, ISO 22028-2) RGB → XYZ D50 (`Y = 1` at the white).
    pub fn prophoto_to_xyz() -> Mat3 {
        rgb_to_xyz(
            [[0.7347, 0.2653], [0.1596, 0.8404], [0.0366, 0.0001]],
            D50_XY,
        )
    }
}

/// Runs `nsrm args` in `dir`, killed after `limit`: its output, its peak resident memory in
/// KiB (the kernel's `ru_maxrss` of that child) and how long it ran.
#[cfg(unix)]
pub fn nsrm_measured(
    dir: &Path,
    args: &[&str],
    limit: std::time::Duration,
) -> (Output, u64, std::time::Duration) {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    let t0 = std::time::Instant::now();
    // Reaped by `wait4` below (for its resource usage), not by `Child::wait`.
    #[allow(clippy::zombie_processes)]
    let mut child = nsrm()
        .current_dir(dir)
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("running nsrm");
    let pid = child.id() as libc::pid_t;
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let (mut o, mut e) = (Vec::new(), Vec::new());
        let _ = err.read_to_end(&mut e);
        let _ = out.read_to_end(&mut o);
        (o, e)
    });
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = std::sync::Arc::clone(&done);
    std::thread::spawn(move || {
        let t = std::time::Instant::now();
        while t.elapsed() < limit {
            if flag.load(std::sync::atomic::Ordering::SeqCst) {
                return;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        if !flag.load(std::sync::atomic::Ordering::SeqCst) {
            // The child has not been reaped yet (wait4 below), so the pid is still its own.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
    });
    let mut status = 0;
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    assert_eq!(r, pid, "wait4");
    let elapsed = t0.elapsed();
    let (stdout, stderr) = reader.join().unwrap();
    let o = Output {
        status: std::process::ExitStatus::from_raw(status),
        stdout,
        stderr,
    };
    (o, usage.ru_maxrss as u64, elapsed)
}

/// Chromium for the browser tests (`$NSRM_CHROMIUM`, else `/usr/bin/chromium`), or `None`
/// after [`skip`] when it, node or `tests/browser/node_modules` (puppeteer-core) is absent.
pub fn browser_prerequisites() -> Option<String> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("tests/browser");
    let chromium = std::env::var("NSRM_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    let missing = if Command::new("node").arg("--version").output().is_err() {
        Some("node is not installed (.ci/install.d/60-browser.sh installs it)")
    } else if !Path::new(&chromium).exists() {
        Some("chromium is not installed (apt-get install chromium)")
    } else if !dir.join("node_modules/puppeteer-core").exists() {
        Some("tests/browser/node_modules is absent (npm ci in tests/browser)")
    } else {
        None
    };
    match missing {
        Some(why) => {
            skip(why);
            None
        }
        None => Some(chromium),
    }
}

/// Runs `tests/browser/SCRIPT` with node and `env`, Chromium's (and GLib's) per-user files in a
/// fresh work directory named after `name` (never the caller's home or the repository); asserts
/// it succeeded and returns its output.
pub fn run_browser_script(
    script: &str,
    name: &str,
    chromium: &str,
    env: &[(&str, &Path)],
) -> String {
    let work = tempdir(name);
    let mut cmd = Command::new("node");
    cmd.arg(script)
        .current_dir(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("tests/browser"))
        .env("NSRM_CHROMIUM", chromium)
        .env("HOME", &work)
        .env("XDG_CONFIG_HOME", work.join("config"))
        .env("XDG_CACHE_HOME", work.join("cache"))
        .env("XDG_RUNTIME_DIR", &work);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().expect("running node");
    let text = format!(
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    assert!(out.status.success(), "{script} failed:\n{text}");
    text
}
