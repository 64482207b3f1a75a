//! Issue 23, a newcomer's first hour: defaults that do not surprise (`--device auto`, no Mesa
//! lines, one Y scale for every export-shader language, `export -o newdir/…`), one vocabulary of
//! flags, and messages (the chart line of `fit --capture`, warnings on poor results, one error
//! style, a missing file named as such).

use crate::common::{model, nsrm, nsrm_in, nsrm_ok, stderr, tempdir};

/// What `--device auto` should pick here: `Some(true)` a hardware GPU, `Some(false)` only a
/// software adapter, `None` no adapter at all.
fn hardware_here() -> Option<bool> {
    match nsrm::gpu::GpuContext::new(&nsrm::gpu::GpuOptions::default()) {
        Ok(ctx) => Some(ctx.adapter.get_info().device_type != nsrm::gpu::wgpu::DeviceType::Cpu),
        Err(_) => None,
    }
}

#[test]
fn device_auto_says_which_and_why_and_mesa_stays_quiet() {
    let d = tempdir("first-hour-device");
    model(&d);
    nsrm_ok(&d, &["render-chart", "-o", "chart.exr"]);
    let mut c = nsrm();
    c.current_dir(&d).env_remove("XDG_RUNTIME_DIR").args([
        "apply",
        "--model",
        "m.json",
        "-o",
        "auto",
        "chart.exr",
    ]);
    let o = c.output().unwrap();
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("XDG_RUNTIME_DIR"), "Mesa complained: {err}");
    match hardware_here() {
        Some(true) => assert!(
            err.contains("--device auto: correcting on the GPU"),
            "{err}"
        ),
        Some(false) => assert!(
            err.contains("--device auto: correcting on the CPU")
                && err.contains("software rasteriser")
                && err.contains("--device gpu"),
            "{err}"
        ),
        None => assert!(
            err.contains("--device auto: correcting on the CPU") && err.contains("no GPU adapter"),
            "{err}"
        ),
    }
    // `--device gpu` still takes a software adapter.
    if hardware_here() == Some(false) {
        let mut c = nsrm();
        c.current_dir(&d).env_remove("XDG_RUNTIME_DIR").args([
            "apply",
            "--model",
            "m.json",
            "--device",
            "gpu",
            "-o",
            "gpu",
            "chart.exr",
        ]);
        let o = c.output().unwrap();
        let err = stderr(&o);
        assert!(o.status.success(), "{err}");
        assert!(!err.contains("XDG_RUNTIME_DIR"), "{err}");
        assert!(d.join("gpu/chart_xyz.exr").exists());
    }
}

#[test]
fn export_shader_writes_what_apply_writes_in_every_language() {
    let d = tempdir("first-hour-shader");
    model(&d);
    // The default is `--output-space xyz` (white at Y = 1), for the compute shaders as for DCTL.
    for lang in ["wgsl", "glsl", "dctl"] {
        let a = format!("default.{lang}");
        let b = format!("xyz.{lang}");
        let o = nsrm_ok(
            &d,
            &[
                "export-shader",
                "--model",
                "m.json",
                "--lang",
                lang,
                "-o",
                &a,
            ],
        );
        assert!(
            stderr(&o).contains("training white at Y = 1"),
            "{lang}: {}",
            stderr(&o)
        );
        nsrm_ok(
            &d,
            &[
                "export-shader",
                "--model",
                "m.json",
                "--lang",
                lang,
                "--output-space",
                "xyz",
                "-o",
                &b,
            ],
        );
        assert_eq!(
            std::fs::read(d.join(&a)).unwrap(),
            std::fs::read(d.join(&b)).unwrap(),
            "{lang}"
        );
    }
    // And that is not the model file's own scale (white at Y = 100): the WGSL matrix is 1/100 of it.
    let m = nsrm::Model::load(&d.join("m.json")).unwrap();
    let raw =
        nsrm_export::export_shader(&m, nsrm::Layout::Rgb, nsrm_export::ShaderLang::Wgsl).unwrap();
    assert_ne!(raw, std::fs::read(d.join("default.wgsl")).unwrap());
}

#[test]
fn export_creates_the_output_directory() {
    let d = tempdir("first-hour-export");
    nsrm_ok(&d, &["fit", "--kind", "lrm", "-o", "m.json"]);
    nsrm_ok(
        &d,
        &[
            "export",
            "--model",
            "m.json",
            "--format",
            "ocio",
            "-o",
            "new/dir/config.ocio",
        ],
    );
    assert!(d.join("new/dir/config.ocio").is_file());
}

#[test]
fn poor_results_are_warned_about() {
    let d = tempdir("first-hour-warn");
    // PRM 3 on the 24 patches of a CC24: 19 terms.
    let o = nsrm_ok(
        &d,
        &[
            "fit",
            "--reflectances",
            "cc24",
            "--kind",
            "prm",
            "--order",
            "3",
            "-o",
            "prm3.json",
        ],
    );
    assert!(
        stderr(&o).contains("warning: 19 terms fitted on 24 patches"),
        "{}",
        stderr(&o)
    );
    // NSRM 3 on 190 patches: no warning.
    let o = nsrm_ok(&d, &["fit", "--kind", "nsrm", "-o", "nsrm3.json"]);
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
}

#[test]
fn errors_read_alike_and_name_missing_files() {
    let d = tempdir("first-hour-errors");
    // clap's usage errors and nsrm's own begin the same way.
    let clap = nsrm_in(&d, &["fit", "--no-such-flag"]);
    let ours = nsrm_in(&d, &["fit", "--order", "9", "-o", "x.json"]);
    for o in [&clap, &ours] {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(o));
        assert!(stderr(o).starts_with("error: "), "{}", stderr(o));
    }
    // A CSV path that does not exist is a missing file, not an unknown reflectance set.
    let o = nsrm_in(&d, &["eval", "--reflectances", "no/such/patches.csv"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no/such/patches.csv: no such file") && !err.contains("unknown"),
        "{err}"
    );
}

#[test]
fn fit_capture_prints_the_chart_line_as_chart_extract_does() {
    let d = tempdir("first-hour-capture");
    nsrm_ok(
        &d,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "--seed",
            "5",
            "--min-area",
            "0.2",
            "--width",
            "800",
            "--height",
            "560",
            "--vignetting",
            "0.3",
            "-o",
            "shot.exr",
        ],
    );
    let ex = nsrm_ok(
        &d,
        &[
            "chart", "extract", "shot.exr", "--chart", "cc24", "--flat", "neutrals", "-o", "p.csv",
        ],
    );
    let fit = nsrm_ok(
        &d,
        &[
            "fit",
            "--capture",
            "shot.exr",
            "--chart",
            "cc24",
            "--flat",
            "neutrals",
            "-o",
            "m.json",
        ],
    );
    let line = |o: &std::process::Output| {
        stderr(o)
            .lines()
            .find(|l| l.starts_with("cc24 chart found") && l.contains(" in shot.exr "))
            .map(|l| l.split("; written to").next().unwrap().to_string())
            .unwrap_or_else(|| panic!("no chart line: {}", stderr(o)))
    };
    assert_eq!(line(&ex), line(&fit));
    assert!(
        line(&fit).contains("light non-uniformity"),
        "{}",
        line(&fit)
    );
    assert!(
        line(&fit).contains("relative to its white"),
        "{}",
        line(&fit)
    );
}

/// Old spellings keep working (hidden aliases) and give what the new ones give.
#[test]
fn old_flag_spellings_still_work() {
    let d = tempdir("first-hour-aliases");
    nsrm_ok(
        &d,
        &["fit", "--model", "rprm", "--order", "2", "-o", "old.json"],
    );
    nsrm_ok(
        &d,
        &["fit", "--kind", "rprm", "--order", "2", "-o", "new.json"],
    );
    let a: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("old.json")).unwrap()).unwrap();
    let b: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("new.json")).unwrap()).unwrap();
    assert_eq!(a["kind"], b["kind"]);
    assert_eq!(a["matrix"], b["matrix"]);
    let t = nsrm_ok(&d, &["terms", "--model", "prm", "--order", "2"]);
    assert!(String::from_utf8_lossy(&t.stdout).starts_with("PRM order 2"));
    // The help shows only the new spellings.
    let h = nsrm_ok(&d, &["fit", "--help"]);
    let help = String::from_utf8_lossy(&h.stdout);
    assert!(
        help.contains("--kind") && !help.contains("--model"),
        "{help}"
    );
}
