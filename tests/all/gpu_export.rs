//! `nsrm export-shader` end to end (no GPU needed): fit a model file, export it in every
//! language, and read each output back with naga.

use std::path::Path;

use crate::common;

fn nsrm(args: &[&str]) -> std::process::Output {
    common::nsrm().args(args).output().expect("run nsrm")
}

/// Validates with the flags every shader of nsrm is held to: all validation flags, default
/// capabilities.
fn validate(module: &naga::Module) {
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(module)
    .unwrap();
}

fn fit(dir: &Path, kind: &str, order: &str) -> String {
    fit_with(dir, kind, order, &[])
}

fn fit_with(dir: &Path, kind: &str, order: &str, extra: &[&str]) -> String {
    let model = dir.join(format!("{kind}{order}{}.json", extra.join("")));
    let mut args = vec![
        "fit",
        "--model",
        kind,
        "--order",
        order,
        "-o",
        model.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = nsrm(&args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    model.to_str().unwrap().to_string()
}

#[test]
fn export_shader_writes_every_language() {
    let dir = tempfile::tempdir().unwrap();
    let rprm = fit(dir.path(), "rprm", "3");
    // A white-balanced NSRM: its input gains are baked into every language.
    let wb = fit_with(dir.path(), "nsrm", "3", &["--normalise", "white-balanced"]);
    for (model, gains) in [(rprm, false), (wb, true)] {
        export_every_language(dir.path(), &model, gains);
    }
    // No temporary files left behind.
    for entry in std::fs::read_dir(dir.path()).unwrap() {
        let name = entry.unwrap().file_name();
        assert!(!name.to_string_lossy().ends_with(".tmp"), "{name:?}");
    }
}

fn export_every_language(dir: &Path, model: &str, gains: bool) {
    let tag = if gains { "wb" } else { "plain" };
    for (lang, layout) in [
        ("wgsl", "rgb"),
        ("glsl", "rgba"),
        ("hlsl", "rgba"),
        ("msl", "rgb"),
        ("spirv", "rgba"),
    ] {
        let path = dir.join(format!("out_{tag}.{lang}"));
        let p = path.to_str().unwrap();
        let args = [
            "export-shader",
            "--model",
            model,
            "--lang",
            lang,
            "--layout",
            layout,
            "-o",
            p,
        ];
        let out = nsrm(&args);
        assert!(
            out.status.success(),
            "{lang}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let bytes = std::fs::read(&path).unwrap();
        match lang {
            "wgsl" => {
                let text = String::from_utf8(bytes).unwrap();
                assert!(text.contains("const CHANNELS: u32 = 3u;"));
                assert!(!text.contains("var<uniform>"));
                assert_eq!(text.contains("fn model_gain()"), gains, "{text}");
                assert_eq!(text.contains("input gains ["), gains, "{text}");
                let m = naga::front::wgsl::parse_str(&text).unwrap();
                validate(&m);
            }
            "glsl" => {
                let text = String::from_utf8(bytes).unwrap();
                let m = naga::front::glsl::Frontend::default()
                    .parse(&naga::ShaderStage::Compute.into(), &text)
                    .unwrap();
                validate(&m);
            }
            "spirv" => {
                let m = naga::front::spv::parse_u8_slice(&bytes, &Default::default()).unwrap();
                validate(&m);
                assert_eq!(m.entry_points[0].name, "main");
            }
            _ => {
                let text = String::from_utf8(bytes).unwrap();
                assert!(text.contains("main"), "{lang}");
            }
        }
        // An existing output is kept unless --overwrite is given.
        let again = nsrm(&args);
        assert_eq!(again.status.code(), Some(1));
        assert!(String::from_utf8_lossy(&again.stderr).contains("--overwrite"));
        let mut with = args.to_vec();
        with.push("--overwrite");
        assert!(nsrm(&with).status.success());
    }
}

#[test]
fn export_shader_usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let model = fit(dir.path(), "nsrm", "2");
    let out_path = dir.path().join("x");
    let o = out_path.to_str().unwrap();
    let bad_lang = nsrm(&[
        "export-shader",
        "--model",
        &model,
        "--lang",
        "cuda",
        "-o",
        o,
    ]);
    assert_eq!(bad_lang.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad_lang.stderr).contains("wgsl, glsl"));
    let bad_layout = nsrm(&[
        "export-shader",
        "--model",
        &model,
        "--lang",
        "wgsl",
        "--layout",
        "bgr",
        "-o",
        o,
    ]);
    assert_eq!(bad_layout.status.code(), Some(2));
    let missing = nsrm(&[
        "export-shader",
        "--model",
        dir.path().join("none.json").to_str().unwrap(),
        "--lang",
        "wgsl",
        "-o",
        o,
    ]);
    assert_eq!(missing.status.code(), Some(1));
    assert!(!out_path.exists());
}

/// `nsrm export-shader --lang dctl` writes the DCTL of the model with its output space folded in
/// (compiled as C by the kit's DCTL harness and checked against the f64 model), refuses to
/// overwrite, and refuses an unknown space with exit 2 leaving no file. (From
/// `tests/all/export_dctl.rs`, whose library test moved to `crates/nsrm-export/src/dctl_tests.rs`.)
#[test]
fn export_shader_writes_dctl_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let data = nsrm::simulate_named("nikon-d5100", "D65", "cc24", &nsrm::Grid::default()).unwrap();
    let model = nsrm::fit(nsrm::Kind::Rprm, 3, &data).unwrap();
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
    let folded = nsrm::output_model(&model, nsrm::OutputSpace::Acescg).unwrap();
    if let Some(cc) = common::cc() {
        let px = common::dctl_pixels(&data);
        let got = common::run_dctl(&cc, dir.path(), "cli", &text, &px);
        common::check_dctl(&folded, &px, &got, "cli");
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
