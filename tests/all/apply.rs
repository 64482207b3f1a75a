//! End-to-end tests of `nsrm render-chart` + `nsrm fit` + `nsrm apply`, running the built binary.

use crate::common::mat::apply as mat_apply;
use crate::common::read_frame;
use nsrm::delta_e00_xyz;
use nsrm::OutputSpace;
use nsrm_chart::ChartLayout;
use nsrm_io::ReadOptions;
use std::path::{Path, PathBuf};

use crate::common;
use common::{nsrm_in as nsrm, nsrm_ok as ok};

/// Renders the rawtoaces-190 chart under D65 and fits NSRM order 3 on the same data.
fn chart_and_model(dir: &Path) {
    chart_and_model_with(dir, &[]);
}

/// [`chart_and_model`] with extra `nsrm fit` flags (a fit variant).
fn chart_and_model_with(dir: &Path, fit_flags: &[&str]) {
    ok(
        dir,
        &[
            "render-chart",
            "--reflectances",
            "rawtoaces-190",
            "--illuminant",
            "D65",
            "--patch-size",
            "8",
            "-o",
            "chart.exr",
        ],
    );
    let mut fit = vec![
        "fit",
        "--reflectances",
        "rawtoaces-190",
        "--illuminant",
        "D65",
        "--model",
        "nsrm",
        "--order",
        "3",
        "-o",
        "m.json",
    ];
    fit.extend_from_slice(fit_flags);
    ok(dir, &fit);
}

/// Per-patch ΔE00 of a corrected chart (XYZ, white Y = 1) against the layout's ground truth.
fn chart_errors(corrected: &Path, layout: &ChartLayout) -> Vec<(String, f64)> {
    let f = read_frame(corrected, &ReadOptions::default()).unwrap();
    assert_eq!((f.width, f.height), (layout.width, layout.height));
    layout
        .patches
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let xyz = patch_mean(layout, &f, i).map(|v| v * 100.0);
            (p.label.clone(), delta_e00_xyz(xyz, p.xyz, layout.white_xyz))
        })
        .collect()
}

fn eval_in_sample(dir: &Path) -> serde_json::Value {
    eval_in_sample_with(dir, &[])
}

/// `nsrm eval --in-sample --json` of NSRM 3 (D65, rawtoaces-190) with extra fit flags.
fn eval_in_sample_with(dir: &Path, fit_flags: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "eval",
        "--in-sample",
        "--models",
        "nsrm",
        "--order",
        "3",
        "--illuminant",
        "D65",
        "--reflectances",
        "rawtoaces-190",
        "--json",
    ];
    args.extend_from_slice(fit_flags);
    let out = ok(dir, &args);
    serde_json::from_slice(&out.stdout).expect("eval --json output")
}

fn check_against_eval(errors: &[(String, f64)], eval: &serde_json::Value, tol: f64) {
    let r = &eval["results"][0];
    let per = r["per_patch"].as_array().unwrap();
    assert_eq!(per.len(), errors.len());
    let mut worst = 0.0f64;
    for (p, (label, de)) in per.iter().zip(errors) {
        assert_eq!(p["label"].as_str().unwrap(), label);
        let want = p["dE00"].as_f64().unwrap();
        worst = worst.max((want - de).abs());
        assert!(
            (want - de).abs() < tol,
            "patch {label}: ΔE00 {de} from the frame, {want} from eval"
        );
    }
    // Per-patch agreement carries the order statistics; the mean and the maximum are checked
    // as eval reports them.
    let n = errors.len() as f64;
    let mean = errors.iter().map(|e| e.1).sum::<f64>() / n;
    let max = errors.iter().map(|e| e.1).fold(0.0, f64::max);
    for (name, got) in [("mean", mean), ("max", max)] {
        let want = r[name].as_f64().unwrap();
        assert!(
            (want - got).abs() < tol,
            "{name}: {got} from the frame, {want} from eval"
        );
    }
    eprintln!(
        "in-sample NSRM3 D65 from the corrected frame: mean {mean:.4} max {max:.4}; \
         largest per-patch difference from eval {worst:.2e}"
    );
}

#[test]
fn cpu_chart_matches_eval_in_sample() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    ok(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "-o",
            "out",
            "--timing",
            "chart.exr",
        ],
    );
    let layout = read_layout(&d.join("chart.exr"));
    let errors = chart_errors(&d.join("out/chart_xyz.exr"), &layout);
    check_against_eval(&errors, &eval_in_sample(d), 1e-4);
}

#[test]
fn gpu_chart_matches_eval_in_sample() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    let out = nsrm(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "gpu",
            "-o",
            "out",
            "chart.exr",
        ],
    );
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        if err.contains("no GPU adapter") {
            crate::common::skip("no GPU adapter (install mesa-vulkan-drivers libvulkan1)");
            return;
        }
        panic!("nsrm apply --device gpu failed: {err}");
    }
    let layout = read_layout(&d.join("chart.exr"));
    let errors = chart_errors(&d.join("out/chart_xyz.exr"), &layout);
    check_against_eval(&errors, &eval_in_sample(d), 1e-4);
}

#[test]
fn white_balanced_nsrm_chart_matches_eval_in_sample() {
    // `fit --normalise white-balanced` writes the input gains into the model file; `apply` on
    // the rendered chart (CPU, and the GPU where there is an adapter) reproduces eval's per-patch
    // ΔE00 of the same fit.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let wb = ["--normalise", "white-balanced"];
    chart_and_model_with(d, &wb);
    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("m.json")).unwrap()).unwrap();
    let gains = model["input"]["gains"].as_array().expect("input gains");
    assert!(gains.iter().any(|g| g.as_f64() != Some(1.0)), "{gains:?}");
    assert_eq!(model["version"], 2);
    let eval = eval_in_sample_with(d, &wb);
    assert_eq!(eval["results"][0]["normalise"], "white-balanced");
    let layout = read_layout(&d.join("chart.exr"));
    ok(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "-o",
            "cpu",
            "chart.exr",
        ],
    );
    let errors = chart_errors(&d.join("cpu/chart_xyz.exr"), &layout);
    check_against_eval(&errors, &eval, 1e-4);
    // The raw NSRM gives other per-patch errors: the comparison can tell them apart.
    let raw = eval_in_sample(d);
    let differs = raw["results"][0]["per_patch"]
        .as_array()
        .unwrap()
        .iter()
        .zip(&errors)
        .any(|(p, (_, de))| (p["dE00"].as_f64().unwrap() - de).abs() > 1e-3);
    assert!(differs, "white-balanced and raw NSRM give the same chart");
    let out = nsrm(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "gpu",
            "-o",
            "gpu",
            "chart.exr",
        ],
    );
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        if err.contains("no GPU adapter") {
            crate::common::skip("no GPU adapter (install mesa-vulkan-drivers libvulkan1)");
            return;
        }
        panic!("nsrm apply --device gpu failed: {err}");
    }
    let errors = chart_errors(&d.join("gpu/chart_xyz.exr"), &layout);
    check_against_eval(&errors, &eval, 1e-4);
}

#[test]
fn output_spaces_are_matrices_of_xyz_and_tagged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    for space in ["xyz", "acescg", "linear-srgb", "aces2065-1"] {
        ok(
            d,
            &[
                "apply",
                "--model",
                "m.json",
                "--device",
                "cpu",
                "--output-space",
                space,
                "-o",
                "out",
                "chart.exr",
            ],
        );
    }
    let model = nsrm::Model::load(&d.join("m.json")).unwrap();
    let layout = read_layout(&d.join("chart.exr"));
    let xyz = read_frame(&d.join("out/chart_xyz.exr"), &ReadOptions::default()).unwrap();
    for (name, space) in [
        ("acescg", OutputSpace::Acescg),
        ("linear-srgb", OutputSpace::LinearSrgb),
        ("aces2065-1", OutputSpace::Aces2065_1),
    ] {
        let path = d.join(format!("out/chart_{name}.exr"));
        let rgb = read_frame(&path, &ReadOptions::default()).unwrap();
        let m = space.from_xyz(model.white_xyz());
        for i in 0..layout.patches.len() {
            let want = mat_apply(&m, patch_mean(&layout, &xyz, i));
            let got = patch_mean(&layout, &rgb, i);
            for k in 0..3 {
                assert!(
                    (want[k] - got[k]).abs() < 1e-5 * (1.0 + want[k].abs()),
                    "{name} patch {i}: {got:?} vs {want:?}"
                );
            }
        }
        let img = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
        let id = img.layer_data[0]
            .attributes
            .other
            .get(&exr::meta::attribute::Text::from("colorInteropID"))
            .cloned();
        assert_eq!(
            id,
            Some(exr::meta::attribute::AttributeValue::Text(
                exr::meta::attribute::Text::from(space.interop_id())
            ))
        );
        let c = img.attributes.chromaticities.expect("chromaticities");
        let (p, w) = space.primaries().unwrap();
        assert!((c.red.0 as f64 - p[0][0]).abs() < 1e-6 && (c.white.1 as f64 - w[1]).abs() < 1e-6);
    }
    let img = exr::prelude::read_all_flat_layers_from_file(d.join("out/chart_xyz.exr")).unwrap();
    assert!(img.attributes.chromaticities.is_none());
    // The training white comes out at Y = 1 in XYZ: the brightest neutral patch is below it.
    let max_y = (0..layout.patches.len())
        .map(|i| patch_mean(&layout, &xyz, i)[1])
        .fold(0.0, f64::max);
    assert!(max_y > 0.5 && max_y < 1.0, "{max_y}");
}

fn fnv1a(path: &Path) -> u64 {
    std::fs::read(path)
        .unwrap()
        .iter()
        .fold(0xcbf2_9ce4_8422_2325, |h, b| {
            (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3)
        })
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect(),
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

/// A directory of inputs: good frames, a truncated EXR, an 8-bit TIFF.
fn mixed_batch(d: &Path) -> Vec<PathBuf> {
    chart_and_model(d);
    let inputs = d.join("in");
    std::fs::create_dir(&inputs).unwrap();
    let chart = std::fs::read(d.join("chart.exr")).unwrap();
    for name in ["good1.exr", "good2.exr", "good3.exr"] {
        std::fs::write(inputs.join(name), &chart).unwrap();
    }
    std::fs::write(inputs.join("bad_truncated.exr"), &chart[..chart.len() / 2]).unwrap();
    let mut tif = std::io::Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut tif)
        .unwrap()
        .write_image::<tiff::encoder::colortype::RGB8>(4, 2, &[128u8; 24])
        .unwrap();
    std::fs::write(inputs.join("bad_8bit.tif"), tif.into_inner()).unwrap();
    let mut all: Vec<PathBuf> = std::fs::read_dir(&inputs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    all.sort();
    all
}

#[test]
fn bad_files_fail_alone_with_continue_on_error_and_inputs_stay_intact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let inputs = mixed_batch(d);
    let before: Vec<u64> = inputs.iter().map(|p| fnv1a(p)).collect();
    let out = nsrm(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "-o",
            "out",
            "--continue-on-error",
            "in",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("3 converted, 0 skipped, 2 failed"), "{err}");
    assert!(err.contains("bad_truncated.exr"), "{err}");
    assert!(
        err.contains("bad_8bit.tif") && err.contains("8 bits per sample"),
        "{err}"
    );
    assert_eq!(
        files_in(&d.join("out")),
        ["good1_xyz.exr", "good2_xyz.exr", "good3_xyz.exr"]
    );
    let after: Vec<u64> = inputs.iter().map(|p| fnv1a(p)).collect();
    assert_eq!(before, after, "an input changed");
    assert_eq!(files_in(&d.join("in")).len(), 5);
}

#[test]
fn first_failure_stops_the_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mixed_batch(d);
    // Sorted, bad_8bit.tif comes first; with one worker nothing after it starts.
    let out = nsrm(
        d,
        &[
            "apply", "--model", "m.json", "--device", "cpu", "-o", "out", "--jobs", "1", "in",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("0 converted, 0 skipped, 1 failed, 4 not attempted"),
        "{err}"
    );
    assert!(files_in(&d.join("out")).is_empty());
}

#[test]
fn usage_and_setup_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    std::fs::create_dir(d.join("empty")).unwrap();
    std::fs::write(d.join("empty/notes.txt"), "x").unwrap();
    std::fs::write(d.join("broken.json"), "{ not json").unwrap();
    std::fs::write(d.join("file"), "x").unwrap();
    let cases: &[(&[&str], i32, &str)] = &[
        (&["empty"], 2, "no .exr, .tif or .tiff files"),
        (&["nothing-*.exr"], 2, "matches no"),
        (&["missing.exr"], 2, "no such file"),
        (&["--shard", "0/3", "chart.exr"], 2, "K must be within 1..N"),
        (&["--shard", "two", "chart.exr"], 2, "--shard"),
        (
            &["--output-space", "p3", "chart.exr"],
            2,
            "invalid value 'p3' for '--output-space",
        ),
        (&["--suffix", "", "chart.exr"], 2, "onto that input itself"),
        (&["--format", "tiff", "--half", "chart.exr"], 2, "--half"),
        (
            &["-o", "file/sub", "chart.exr"],
            1,
            "cannot create the output directory",
        ),
    ];
    for (args, code, msg) in cases {
        let mut all = vec!["apply", "--model", "m.json", "--device", "cpu"];
        all.extend_from_slice(args);
        let out = nsrm(d, &all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(*code), "{args:?}: {err}");
        assert!(err.contains(msg), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // A model file that does not parse: exit 1, nothing written.
    let out = nsrm(
        d,
        &["apply", "--model", "broken.json", "-o", "out2", "chart.exr"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("broken.json"), "{err}");
    assert!(!d.join("out2").exists());
    // Two inputs mapped to one output.
    std::fs::copy(d.join("chart.exr"), d.join("twin.exr")).unwrap();
    let mut tif = std::io::Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut tif)
        .unwrap()
        .write_image::<tiff::encoder::colortype::RGB16>(2, 1, &[1000u16; 6])
        .unwrap();
    std::fs::write(d.join("twin.tif"), tif.into_inner()).unwrap();
    let out = nsrm(
        d,
        &[
            "apply", "--model", "m.json", "-o", "o3", "twin.exr", "twin.tif",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("would both be written"), "{err}");
    // Two inputs with one preview name.
    for sub in ["a", "b"] {
        std::fs::create_dir(d.join(sub)).unwrap();
        std::fs::copy(d.join("chart.exr"), d.join(sub).join("x.exr")).unwrap();
    }
    let out = nsrm(
        d,
        &["apply", "--model", "m.json", "--preview", "prev", "a", "b"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("would both be written to prev/x_xyz.png"),
        "{err}"
    );
    assert!(files_in(&d.join("a")) == ["x.exr"] && !d.join("prev").exists());
    // Only files we expect: no temporary files anywhere.
    assert!(files_in(d).iter().all(|f| !f.ends_with(".tmp")));
}

#[test]
fn existing_outputs_need_overwrite_or_skip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    let args = [
        "apply",
        "--model",
        "m.json",
        "--device",
        "cpu",
        "-o",
        "out",
        "chart.exr",
    ];
    ok(d, &args);
    let out_file = d.join("out/chart_xyz.exr");
    std::fs::write(&out_file, b"sentinel").unwrap();
    let out = nsrm(d, &args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("already exists"), "{err}");
    assert_eq!(std::fs::read(&out_file).unwrap(), b"sentinel");
    let mut skip = args.to_vec();
    skip.push("--skip-existing");
    let out = ok(d, &skip);
    assert!(String::from_utf8_lossy(&out.stderr).contains("0 converted, 1 skipped"));
    assert_eq!(std::fs::read(&out_file).unwrap(), b"sentinel");
    let mut over = args.to_vec();
    over.push("--overwrite");
    ok(d, &over);
    assert!(read_frame(&out_file, &ReadOptions::default()).is_ok());
    assert_eq!(files_in(&d.join("out")), ["chart_xyz.exr"]);
}

#[test]
fn shards_partition_the_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    std::fs::create_dir(d.join("in")).unwrap();
    let chart = std::fs::read(d.join("chart.exr")).unwrap();
    for i in 0..7 {
        std::fs::write(d.join(format!("in/plate.{:04}.exr", 1001 + i)), &chart).unwrap();
    }
    let mut union: Vec<String> = Vec::new();
    for k in 1..=3 {
        let shard = format!("{k}/3");
        // Glob and directory naming the same files: listed once.
        let out = ok(
            d,
            &[
                "apply", "--model", "m.json", "--device", "cpu", "-o", "out", "--shard", &shard,
                "in", "in/*.exr",
            ],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(&format!("shard {k}/3")), "{err}");
        let now = files_in(&d.join("out"));
        let new: Vec<String> = now.iter().filter(|f| !union.contains(f)).cloned().collect();
        assert_eq!(new.len(), now.len() - union.len(), "shards overlap");
        assert_eq!(new.len(), if k == 1 { 3 } else { 2 });
        union = now;
    }
    let want: Vec<String> = (0..7)
        .map(|i| format!("plate_xyz.{:04}.exr", 1001 + i))
        .collect();
    assert_eq!(union, want);
    // --dry-run prints the plan and writes nothing.
    let out = ok(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--dry-run",
            "--shard",
            "2/3",
            "-o",
            "dry",
            "in",
        ],
    );
    let plan = String::from_utf8_lossy(&out.stdout);
    assert!(
        plan.contains("plate.1002.exr -> dry/plate_xyz.1002.exr"),
        "{plan}"
    );
    assert!(plan.contains("plate.1005.exr"), "{plan}");
    assert!(!plan.contains("plate.1001.exr"), "{plan}");
    assert!(!d.join("dry").exists());
}

#[test]
fn tiff_output_and_preview() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    chart_and_model(d);
    ok(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--format",
            "tiff",
            "--preview",
            "prev",
            "chart.exr",
        ],
    );
    let tif = read_frame(&d.join("chart_xyz.tif"), &ReadOptions::default()).unwrap();
    let layout = read_layout(&d.join("chart.exr"));
    let errors = chart_errors(&d.join("chart_xyz.tif"), &layout);
    let mean = errors.iter().map(|e| e.1).sum::<f64>() / errors.len() as f64;
    assert!(mean < 1.0, "{mean}");
    assert_eq!((tif.width, tif.height), (layout.width, layout.height));
    let png = image::open(d.join("prev/chart_xyz.png")).unwrap().to_rgb8();
    assert_eq!(
        png.dimensions(),
        (layout.width as u32, layout.height as u32)
    );
}

/// The layout `nsrm render-chart` writes beside its chart (`NAME.patches.json` for `NAME.exr`).
fn read_layout(chart: &Path) -> ChartLayout {
    let text = std::fs::read_to_string(chart.with_extension("patches.json")).unwrap();
    let layout: ChartLayout = serde_json::from_str(&text).unwrap();
    assert_eq!(layout.format, "nsrm-chart");
    layout
}

/// The mean of each channel of `frame` over the inner part of patch `i` of `layout` (a quarter
/// of the patch left out on each side, so blur at the edges does not count).
fn patch_mean(layout: &ChartLayout, frame: &nsrm::Frame, i: usize) -> [f64; 3] {
    let p = &layout.patches[i];
    let (mx, my) = (p.width / 4, p.height / 4);
    let ch = frame.layout.channels();
    let mut sum = [0.0f64; 3];
    let mut n = 0usize;
    for y in p.y + my..p.y + p.height - my {
        for x in p.x + mx..p.x + p.width - mx {
            let px = &frame.data[(y * frame.width + x) * ch..][..3];
            for (s, v) in sum.iter_mut().zip(px) {
                *s += f64::from(*v);
            }
            n += 1;
        }
    }
    sum.map(|s| s / n.max(1) as f64)
}
