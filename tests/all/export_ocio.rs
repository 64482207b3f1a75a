//! OpenColorIO judges `nsrm export`: each exported file is applied to a test EXR by OCIO's own
//! `ocioconvert` and compared with `nsrm apply` on the same frame (LRM to 1e-5 relative; LUT
//! exports within the ΔE00 the export reports); `ociocheck` validates the exported config. Each
//! LUT file the binary writes is the one the library writes for the same model
//! (`nsrm_export::render`), byte for byte: that file is judged against nsrm's evaluator of the
//! written nodes through `ocioconvert` beside the evaluator (`crates/nsrm-export/src/ocio_tests.rs`).
//!
//! Needs `ocioconvert` and `ociocheck` (Debian: `apt-get install opencolorio-tools`; `.ci/run`
//! installs it). Without them each test prints `SKIP: …` and passes, except under `CI=true`,
//! where they fail.

use crate::common;

use crate::common::{read_frame, write_exr};
use nsrm::delta_e00_xyz;
use nsrm::OutputSpace;
use nsrm::{fit, Kind};
use nsrm::{simulate_named, Grid};
use nsrm::{Frame, Layout, Model, TrainingSet};
use nsrm_export::{render, Format, LutOptions};
use nsrm_io::{ExrCompression, FileFormat, ReadOptions, WriteOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The OCIO tool `name` on PATH (Debian's in /usr/bin first), or `None` after printing why
/// the test is skipped; under `CI=true` a missing tool fails the test.
fn tool(name: &str) -> Option<PathBuf> {
    let mut dirs = vec![PathBuf::from("/usr/bin")];
    if let Some(path) = std::env::var_os("PATH") {
        dirs.extend(std::env::split_paths(&path));
    }
    let found = dirs.into_iter().map(|d| d.join(name)).find(|p| p.is_file());
    if found.is_none() {
        let msg =
            format!("`{name}` (OpenColorIO) is not installed: apt-get install opencolorio-tools");
        crate::common::skip(&msg);
    }
    found
}

fn run(cmd: &mut Command) -> std::process::Output {
    let out = cmd.output().expect("running a command");
    assert!(
        out.status.success(),
        "{cmd:?} failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

fn nsrm(dir: &Path, args: &[&str]) -> std::process::Output {
    run(common::nsrm().current_dir(dir).args(args))
}

fn data() -> TrainingSet {
    simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap()
}

/// A grid of camera chromaticities `(r, g)` (step `step`) inside the convex hull of the training
/// patches' chromaticities (the samples the library measures its exports on, built here again:
/// Andrew's monotone chain).
fn dense_chromaticities(rgb: &[[f64; 3]], step: f64) -> Vec<(f64, f64)> {
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    let mut pts: Vec<(f64, f64)> = rgb
        .iter()
        .filter_map(|c| {
            let s = c[0] + c[1] + c[2];
            (s > 0.0 && c.iter().all(|v| *v > 0.0)).then(|| (c[0] / s, c[1] / s))
        })
        .collect();
    pts.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    // Lower hull, then upper; counter-clockwise, no repeated end point.
    let mut hull: Vec<(f64, f64)> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let order: Vec<(f64, f64)> = if pass == 0 {
            pts.clone()
        } else {
            pts.iter().rev().copied().collect()
        };
        for p in order {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    assert!(hull.len() >= 3, "the training chromaticities span no area");
    let (mut rmin, mut rmax, mut gmin, mut gmax) = (1.0f64, 0.0f64, 1.0f64, 0.0f64);
    for &(r, g) in &hull {
        rmin = rmin.min(r);
        rmax = rmax.max(r);
        gmin = gmin.min(g);
        gmax = gmax.max(g);
    }
    let inside = |p: (f64, f64)| {
        (0..hull.len()).all(|i| cross(hull[i], hull[(i + 1) % hull.len()], p) >= 0.0)
    };
    let mut out = Vec::new();
    let mut r = rmin;
    while r <= rmax {
        let mut g = gmin;
        while g <= gmax {
            if inside((r, g)) {
                out.push((r, g));
            }
            g += step;
        }
        r += step;
    }
    out
}

/// A test frame: the training patches, the dense in-gamut chromaticities at several exposures
/// (all inside the LUT range) and black.
fn test_frame(d: &TrainingSet) -> Frame {
    let mut px: Vec<[f64; 3]> = d.rgb.clone();
    let s_ref = d.rgb.iter().map(|c| c[0] + c[1] + c[2]).fold(0.0, f64::max);
    for e in [-5.3, -2.9, -0.2, 2.3] {
        let s = f64::exp2(e) * s_ref;
        for (r, g) in dense_chromaticities(&d.rgb, 0.03) {
            px.push([r * s, g * s, (1.0 - r - g) * s]);
        }
    }
    px.push([0.0; 3]);
    let width = 64;
    let height = px.len().div_ceil(width);
    px.resize(width * height, [0.0; 3]);
    let data = px.iter().flat_map(|p| p.map(|v| v as f32)).collect();
    Frame::from_data(width, height, Layout::Rgb, data).unwrap()
}

fn write_frame(frame: &Frame, path: &Path) {
    let opts = WriteOptions {
        format: FileFormat::Exr,
        half: false,
        compression: ExrCompression::None,
        space: OutputSpace::Xyz,
        ..Default::default()
    };
    crate::common::committed(true, |u| write_exr(frame, path, &opts, u)).unwrap();
}

fn read(path: &Path) -> Vec<[f64; 3]> {
    let f = read_frame(path, &ReadOptions::default()).unwrap();
    let ch = f.layout.channels();
    f.data
        .chunks_exact(ch)
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect()
}

struct Case {
    dir: tempfile::TempDir,
    data: TrainingSet,
    input: Vec<[f64; 3]>,
}

fn case() -> Case {
    let dir = tempfile::tempdir().unwrap();
    let data = data();
    let frame = test_frame(&data);
    write_frame(&frame, &dir.path().join("in.exr"));
    let input = read(&dir.path().join("in.exr"));
    Case { dir, data, input }
}

impl Case {
    fn model(&self, kind: Kind, order: u8) -> (Model, PathBuf) {
        let m = fit(kind, order, &self.data).unwrap();
        let p = self.dir.path().join(format!("{}{order}.json", kind.name()));
        std::fs::write(&p, m.to_json()).unwrap();
        (m, p)
    }

    /// `nsrm apply` on the test frame.
    fn apply(&self, model: &Path, space: OutputSpace) -> Vec<[f64; 3]> {
        let out = self.dir.path().join(format!("apply_{}", space.name()));
        nsrm(
            self.dir.path(),
            &[
                "apply",
                "--model",
                model.to_str().unwrap(),
                "--device",
                "cpu",
                "--output-space",
                space.name(),
                "--overwrite",
                "-o",
                out.to_str().unwrap(),
                "in.exr",
            ],
        );
        read(&out.join(format!("in_{}.exr", space.name())))
    }

    /// `nsrm export`; returns the reported max ΔE00 (from its stdout).
    fn export(&self, model: &Path, format: Format, space: OutputSpace, out: &str) -> f64 {
        let o = nsrm(
            self.dir.path(),
            &[
                "export",
                "--model",
                model.to_str().unwrap(),
                "--format",
                format.name(),
                "--output-space",
                space.name(),
                "-o",
                out,
            ],
        );
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        // "... max A ΔE00 over N samples; ... max B ΔE00 over M samples"
        let maxima: Vec<f64> = text
            .split("max ")
            .skip(1)
            .map(|t| t.split_whitespace().next().unwrap().parse().unwrap())
            .collect();
        assert_eq!(maxima.len(), 2, "{text}");
        maxima.into_iter().fold(0.0, f64::max)
    }
}

/// ΔE00 between two output-space values, in the model's XYZ with its training white.
fn de(model: &Model, space: OutputSpace, a: [f64; 3], b: [f64; 3]) -> f64 {
    let back =
        crate::common::mat::invert(&crate::common::mat::output_matrix(model.white_xyz(), space));
    delta_e00_xyz(
        crate::common::mat::apply(&back, a),
        crate::common::mat::apply(&back, b),
        model.white_xyz(),
    )
}

fn ocioconvert_lut(c: &Case, file: &str, out: &str) -> Option<Vec<[f64; 3]>> {
    let exe = tool("ocioconvert")?;
    run(Command::new(exe)
        .current_dir(c.dir.path())
        .args(["--lut", file, "in.exr", out]));
    Some(read(&c.dir.path().join(out)))
}

#[test]
fn lrm_clf_is_reproduced_by_ocio_to_1e5() {
    let c = case();
    let (_, path) = c.model(Kind::Lrm, 1);
    for space in [OutputSpace::Acescg, OutputSpace::Xyz] {
        let reported = c.export(&path, Format::Clf, space, "lrm.clf");
        assert!(reported < 1e-6, "{reported}");
        let Some(ocio) = ocioconvert_lut(&c, "lrm.clf", "ocio_lrm.exr") else {
            return;
        };
        let reference = c.apply(&path, space);
        for (o, r) in ocio.iter().zip(&reference) {
            let scale = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for k in 0..3 {
                assert!(
                    (o[k] - r[k]).abs() <= 1e-5 * scale + 1e-9,
                    "{space:?}: OCIO {o:?} vs nsrm apply {r:?}"
                );
            }
        }
        std::fs::remove_file(c.dir.path().join("lrm.clf")).unwrap();
    }
}

/// OCIO applies each LUT export within the error `nsrm export` reported; the file is the
/// library's (`nsrm_export::render`) byte for byte, which `crates/nsrm-export/src/ocio_tests.rs` judges
/// against nsrm's own evaluator of the written nodes through OCIO (whether the declared
/// interpolation is the one OCIO uses).
#[test]
fn lut_exports_are_reproduced_by_ocio_within_the_reported_error() {
    let c = case();
    let opts = LutOptions::default();
    let (lo, hi) = (opts.stops[0].exp2(), opts.stops[1].exp2());
    for (kind, order, format, space) in [
        (Kind::Nsrm, 3, Format::Clf, OutputSpace::Acescg),
        (Kind::Rprm, 2, Format::Clf, OutputSpace::Xyz),
        (Kind::Nsrm, 3, Format::Cube, OutputSpace::LinearSrgb),
    ] {
        let (model, path) = c.model(kind, order);
        let file = format!("{}{order}.{}", kind.name(), format.name());
        let reported = c.export(&path, format, space, &file);
        // The library's export of the same model, from the same training patches (the binary
        // re-simulates them from the model's provenance).
        let library = c.dir.path().join(format!("library_{file}"));
        let r = render(&model, format, space, opts, &c.data.rgb, None, &library).unwrap();
        std::fs::write(&library, &r.files[0].1).unwrap();
        assert!(
            std::fs::read(c.dir.path().join(&file)).unwrap() == std::fs::read(&library).unwrap(),
            "{kind}{order} {}: `nsrm export` wrote another file than `nsrm_export::render`",
            format.name()
        );
        let Some(ocio) = ocioconvert_lut(&c, &file, "ocio.exr") else {
            return;
        };
        let reference = c.apply(&path, space);
        let (mut worst, mut worst_at) = (0.0f64, [0.0; 3]);
        for ((x, o), r) in c.input.iter().zip(&ocio).zip(&reference) {
            if x.iter().all(|v| *v == 0.0) {
                assert!(o.iter().all(|v| v.abs() < 1e-6), "black → {o:?}");
                continue;
            }
            if x.iter().any(|v| *v < lo || *v > hi) {
                continue;
            }
            let d = de(&model, space, *o, *r);
            if d > worst {
                worst = d;
                worst_at = *x;
            }
        }
        println!(
            "{kind}{order} {}: OCIO vs nsrm apply max ΔE00 {worst:.4} at camera RGB {worst_at:?} (reported {reported:.4})",
            format.name()
        );
        assert!(worst > 0.0, "{kind} is approximated, not exact");
        // The reported max is a sampled estimate (~440k samples); the frame's samples are others.
        assert!(
            worst <= 1.05 * reported + 2e-3,
            "{kind}{order} {}: OCIO's result is {worst} ΔE00 from nsrm apply, the export reported {reported}",
            format.name()
        );
    }
}

#[test]
fn ocio_config_validates_and_converts_like_apply() {
    let c = case();
    let (model, path) = c.model(Kind::Nsrm, 3);
    let space = OutputSpace::Acescg;
    std::fs::create_dir(c.dir.path().join("cfg")).unwrap();
    let reported = c.export(&path, Format::Ocio, space, "cfg/config.ocio");
    assert!(c.dir.path().join("cfg/config.clf").is_file());
    let Some(check) = tool("ociocheck") else {
        return;
    };
    let out = run(Command::new(check).args([
        "--iconfig",
        c.dir.path().join("cfg/config.ocio").to_str().unwrap(),
    ]));
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(!text.contains("ERROR"), "{text}");
    assert!(text.contains("passed"), "{text}");
    let Some(convert) = tool("ocioconvert") else {
        return;
    };
    // The camera's colour space: the config's first, an input space through the CLF.
    let config = std::fs::read_to_string(c.dir.path().join("cfg/config.ocio")).unwrap();
    let space_text = config
        .split("  - !<ColorSpace>\n")
        .nth(1)
        .unwrap_or_else(|| panic!("no colour space in {config}"));
    assert!(
        space_text.contains("family: Input") && space_text.contains("config.clf"),
        "{space_text}"
    );
    let camera = space_text
        .lines()
        .find_map(|l| l.trim().strip_prefix("name: "))
        .map(|n| n.trim_matches('"').to_string())
        .unwrap_or_else(|| panic!("no name in {space_text}"));
    assert!(camera.contains("camera RGB"), "{camera}");
    // Camera → ACES2065-1 through the config (the FileTransform, then the reference's matrix).
    run(Command::new(convert)
        .current_dir(c.dir.path())
        .env("OCIO", c.dir.path().join("cfg/config.ocio"))
        .args(["in.exr", &camera, "ocio_cfg.exr", "ACES2065-1"]));
    let ocio = read(&c.dir.path().join("ocio_cfg.exr"));
    let reference = c.apply(&path, OutputSpace::Aces2065_1);
    let opts = LutOptions::default();
    let (lo, hi) = (opts.stops[0].exp2(), opts.stops[1].exp2());
    let mut worst = 0.0f64;
    for ((x, o), r) in c.input.iter().zip(&ocio).zip(&reference) {
        if x.iter().any(|v| *v < lo || *v > hi) {
            continue;
        }
        worst = worst.max(de(&model, OutputSpace::Aces2065_1, *o, *r));
    }
    println!("config: OCIO camera → ACES2065-1 vs nsrm apply max ΔE00 {worst:.4} (reported {reported:.4})");
    assert!(worst <= 1.05 * reported + 2e-3, "{worst} > {reported}");
}

#[test]
fn malformed_requests_fail_and_leave_no_file() {
    let c = case();
    let (_, path) = c.model(Kind::Nsrm, 3);
    let m = path.to_str().unwrap();
    let fail = |args: &[&str], needle: &str| {
        let o = common::nsrm()
            .current_dir(c.dir.path())
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(needle), "{args:?}: {err}");
        o.status.code()
    };
    let base = |extra: &[&str]| {
        let mut v = vec!["export", "--model", m, "-o", "x.clf"];
        v.extend_from_slice(extra);
        v.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    let call = |extra: &[&str], needle: &str| {
        let v = base(extra);
        let r: Vec<&str> = v.iter().map(|s| s.as_str()).collect();
        fail(&r, needle)
    };
    assert_eq!(
        call(&["--format", "exr"], "invalid value 'exr' for '--format"),
        Some(2)
    );
    assert_eq!(
        call(&["--format", "clf", "--lut-size", "1"], "LUT size 1"),
        Some(2)
    );
    assert_eq!(
        call(
            &["--format", "cube", "--lut-size", "1000000"],
            "LUT size 1000000"
        ),
        Some(2)
    );
    assert_eq!(
        call(
            &["--format", "clf", "--output-space", "p3"],
            "--output-space"
        ),
        Some(2)
    );
    assert_eq!(
        call(
            &["--format", "clf", "--max-de00", "0.001"],
            "exceeds the limit 0.001"
        ),
        Some(1)
    );
    assert_eq!(
        call(
            &["--format", "clf", "--max-de00", "0.001"],
            "--max-de00 0.001: "
        ),
        Some(1)
    );
    assert!(!c.dir.path().join("x.clf").exists());
    // Nothing else left behind either (no temporary files).
    let names: Vec<String> = std::fs::read_dir(c.dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names
            .iter()
            .all(|n| !n.ends_with(".tmp") && !n.ends_with(".clf")),
        "{names:?}"
    );
    // An existing output is not replaced without --overwrite.
    std::fs::write(c.dir.path().join("x.clf"), b"mine").unwrap();
    call(&["--format", "clf"], "already exists");
    assert_eq!(std::fs::read(c.dir.path().join("x.clf")).unwrap(), b"mine");
    std::fs::write(c.dir.path().join("c.clf"), b"mine").unwrap();
    fail(
        &["export", "--model", m, "--format", "ocio", "-o", "c.ocio"],
        "already exists",
    );
    assert!(!c.dir.path().join("c.ocio").exists());
    nsrm(
        c.dir.path(),
        &[
            "export",
            "--model",
            m,
            "--format",
            "clf",
            "-o",
            "x.clf",
            "--overwrite",
            "--lut-size",
            "9",
        ],
    );
    assert!(std::fs::read_to_string(c.dir.path().join("x.clf"))
        .unwrap()
        .contains("<LUT3D"));
}
