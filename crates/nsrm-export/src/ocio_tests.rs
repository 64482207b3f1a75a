//! OpenColorIO against nsrm's evaluator of the written nodes (`LutExport::eval`, crate-private):
//! each LUT export the library builds ([`super::render`]) is applied to a test EXR by OCIO's
//! own `ocioconvert --lut` and must agree with the evaluator to 2e-5 relative, which tells
//! whether the interpolation the file declares (CLF) or is measured for (`.cube`) is the one OCIO
//! uses. (Moved from `tests/all/export_ocio.rs`, where OCIO still judges the files `nsrm export`
//! writes against `nsrm apply`, and those files are checked to be these, byte for byte.)
//!
//! The EXRs are written and read with the `exr` crate itself (the `io` room is not one `export`
//! may use, tests included: docs/ARCHITECTURE.md), so the test is built with the `io` feature
//! that brings the crate.
//!
//! Needs `ocioconvert` (Debian: `apt-get install opencolorio-tools`); without it the test prints
//! `SKIP: …` and passes, except under `CI=true`, where it fails (`kit::skip_or_fail`).

use super::{dense_chromaticities, render, Format, LutExport, LutOptions};
use crate::kit::skip_or_fail;
use nsrm::{fit, simulate_named, Grid, Kind, OutputSpace, TrainingSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The OCIO tool `name` (Debian's in /usr/bin first, then PATH), or `None` after
/// [`skip_or_fail`].
fn tool(name: &str) -> Option<PathBuf> {
    let mut dirs = vec![PathBuf::from("/usr/bin")];
    if let Some(path) = std::env::var_os("PATH") {
        dirs.extend(std::env::split_paths(&path));
    }
    let found = dirs.into_iter().map(|d| d.join(name)).find(|p| p.is_file());
    if found.is_none() {
        skip_or_fail(&format!(
            "`{name}` (OpenColorIO) is not installed: apt-get install opencolorio-tools"
        ));
    }
    found
}

/// A test frame, 64 pixels wide: the training patches, the dense in-gamut chromaticities at
/// several exposures (all inside the LUT range) and black (as `tests/all/export_ocio.rs` builds
/// it).
fn test_frame(d: &TrainingSet) -> Vec<[f64; 3]> {
    let mut px: Vec<[f64; 3]> = d.rgb.clone();
    let s_ref = d.rgb.iter().map(|c| c[0] + c[1] + c[2]).fold(0.0, f64::max);
    for e in [-5.3, -2.9, -0.2, 2.3] {
        let s = f64::exp2(e) * s_ref;
        for (r, g) in dense_chromaticities(&d.rgb, 0.03) {
            px.push([r * s, g * s, (1.0 - r - g) * s]);
        }
    }
    px.push([0.0; 3]);
    px.resize(px.len().div_ceil(WIDTH) * WIDTH, [0.0; 3]);
    px
}

const WIDTH: usize = 64;

/// Writes `px` (rows of [`WIDTH`]) as a 32-bit float RGB EXR.
fn write(path: &Path, px: &[[f64; 3]]) {
    exr::prelude::write_rgb_file(path, WIDTH, px.len() / WIDTH, |x, y| {
        let p = px[y * WIDTH + x].map(|v| v as f32);
        (p[0], p[1], p[2])
    })
    .unwrap();
}

/// The RGB of an EXR's first layer, row by row.
fn read(path: &Path) -> Vec<[f64; 3]> {
    type Pixels = (usize, Vec<[f64; 3]>);
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| -> Pixels { (size.width(), vec![[0.0; 3]; size.area()]) },
        |p: &mut Pixels, at, (r, g, b, _): (f32, f32, f32, f32)| {
            p.1[at.y() * p.0 + at.x()] = [r, g, b].map(f64::from);
        },
    )
    .unwrap();
    image.layer_data.channel_data.pixels.1
}

#[test]
fn ocio_applies_the_written_nodes_as_nsrms_evaluator_does() {
    let Some(ocioconvert) = tool("ocioconvert") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    write(&dir.path().join("in.exr"), &test_frame(&data));
    let input = read(&dir.path().join("in.exr"));
    let opts = LutOptions::default();
    let (lo, hi) = (opts.stops[0].exp2(), opts.stops[1].exp2());
    for (kind, order, format, space) in [
        (Kind::Nsrm, 3, Format::Clf, OutputSpace::Acescg),
        (Kind::Rprm, 2, Format::Clf, OutputSpace::Xyz),
        (Kind::Nsrm, 3, Format::Cube, OutputSpace::LinearSrgb),
    ] {
        let model = fit(kind, order, &data).unwrap();
        let file = format!("{}{order}.{}", kind.name(), format.name());
        let written = render(
            &model,
            format,
            space,
            opts,
            &data.rgb,
            None,
            &dir.path().join(&file),
        )
        .unwrap();
        for (path, bytes) in &written.files {
            std::fs::write(path, bytes).unwrap();
        }
        assert!(!written.exact, "{kind} is approximated, not exact");
        let out = format!("ocio_{file}.exr");
        let o = Command::new(&ocioconvert)
            .current_dir(dir.path())
            .args(["--lut", &file, "in.exr", &out])
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "ocioconvert failed: {}{}",
            String::from_utf8_lossy(&o.stderr),
            String::from_utf8_lossy(&o.stdout)
        );
        let ocio = read(&dir.path().join(&out));
        let chain = match format {
            Format::Cube => LutExport::cube(&model, space, opts).unwrap(),
            _ => LutExport::clf(&model, space, opts, &data.rgb).unwrap(),
        };
        let mut worst_chain = 0.0f64;
        let mut judged = 0;
        for (x, o) in input.iter().zip(&ocio) {
            if x.iter().all(|v| *v == 0.0) {
                assert!(o.iter().all(|v| v.abs() < 1e-6), "black → {o:?}");
                continue;
            }
            if x.iter().any(|v| *v < lo || *v > hi) {
                continue;
            }
            judged += 1;
            let e = chain.eval(*x);
            let scale = e.iter().fold(1e-4f64, |m, v| m.max(v.abs()));
            for k in 0..3 {
                worst_chain = worst_chain.max((o[k] - e[k]).abs() / scale);
            }
        }
        println!(
            "{kind}{order} {}: OCIO vs nsrm's evaluator of the written nodes max rel {worst_chain:.2e} over {judged} pixels",
            format.name()
        );
        assert!(judged > 100, "only {judged} pixels inside the LUT range");
        assert!(
            worst_chain < 2e-5,
            "{kind}{order} {}: OCIO differs from nsrm's evaluator of the written nodes by {worst_chain:e}",
            format.name()
        );
    }
}
