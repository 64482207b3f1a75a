//! Family 5 (input size is bounded, parsing is linear) and family 7 (every input is reported,
//! by the right name, once).

use crate::common;
use common::*;
use nsrm::TrainingSet;
use std::path::Path;

#[cfg(unix)]
#[test]
fn dev_zero_as_any_text_input_fails_fast() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    exr(&d.join("a.exr"), 2, 2);
    let z = "/dev/zero";
    let cases: Vec<Vec<&str>> = vec![
        vec!["apply", "--model", z, "a.exr"],
        vec!["fit", "--camera", z, "-o", "m.json"],
        vec!["fit", "--illuminant", z, "-o", "m.json"],
        vec!["fit", "--reflectances", z, "-o", "m.json"],
        vec!["fit", "--training", z, "-o", "m.json"],
        vec!["fit", "--training", "t.csv", "--white", z, "-o", "m.json"],
    ];
    std::fs::write(d.join("t.csv"), "label,R,G,B,X,Y,Z\na,1,1,1,1,1,1\n").unwrap();
    for args in cases {
        let t = std::time::Instant::now();
        let o = nsrm_in(d, &args);
        no_crash(&o, &format!("{args:?}"));
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains("/dev/zero"), "{args:?}: {err}");
        assert!(
            err.contains("not a regular file or pipe (it is a character device)"),
            "{args:?}: {err}"
        );
        // Not a timing assertion: reading /dev/zero to the end would never return at all.
        assert!(t.elapsed().as_secs() < 60);
    }
    #[cfg(unix)]
    {
        // A FIFO is a pipe like `--model <(cat m.json)`: read, with the same cap (issue 19
        // family 8; tests/all/harden_commands.rs has the cap and the devices).
        std::process::Command::new("mkfifo")
            .arg(d.join("fifo.json"))
            .status()
            .unwrap();
        model(d);
        let feeder = {
            let (src, dst) = (d.join("m.json"), d.join("fifo.json"));
            std::thread::spawn(move || std::fs::write(dst, std::fs::read(src).unwrap()))
        };
        let o = nsrm_in(
            d,
            &["apply", "--model", "fifo.json", "--device", "cpu", "a.exr"],
        );
        feeder.join().unwrap().unwrap();
        assert_ok(&o);
        assert!(d.join("a_xyz.exr").is_file());
    }
}

#[test]
fn many_measured_rows_load_with_a_duplicate_check() {
    // 2·10⁵ rows here (a debug build); `nsrm fit --training` on 10⁶ rows is measured in the
    // README. A quadratic duplicate check would take minutes at this size.
    let n = 200_000;
    let mut text = String::with_capacity(n * 40);
    text.push_str("label,R,G,B,X,Y,Z\n");
    for i in 0..n {
        text.push_str(&format!("p{i},0.{i},0.2,0.3,10,20,30\n"));
    }
    let white = Some(nsrm::D65_WHITE_XYZ);
    let ts = TrainingSet::parse_measured(&text, "big.csv", white).unwrap();
    assert_eq!(ts.len(), n);
    text.push_str("p7,0.1,0.2,0.3,10,20,30\n");
    let e = TrainingSet::parse_measured(&text, "big.csv", white).unwrap_err();
    assert!(e.to_string().contains("p7"), "{e}");
    // Selecting many labels is linear too.
    let spec: Vec<String> = (0..n).step_by(2).map(|i| format!("p{i}")).collect();
    let sel = ts.select(&spec.join(",")).unwrap();
    assert_eq!(sel.len(), n / 2);
}

#[test]
fn model_json_with_a_bom_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    let text = std::fs::read_to_string(d.join("m.json")).unwrap();
    std::fs::write(d.join("bom.json"), format!("\u{feff}{text}")).unwrap();
    let a = nsrm::Model::load(&d.join("m.json")).unwrap();
    let b = nsrm::Model::load(&d.join("bom.json")).unwrap();
    assert_eq!(a.matrix(), b.matrix());
    // And so are measured CSVs and spectral tables.
    std::fs::write(
        d.join("t.csv"),
        "\u{feff}# white: D65\nlabel,R,G,B,X,Y,Z\na,1,1,1,1,1,1\n",
    )
    .unwrap();
    TrainingSet::read_measured(&d.join("t.csv"), None).unwrap();
}

#[test]
fn messages_name_the_right_thing_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    exr(&d.join("a.exr"), 2, 2);
    model(d);
    // A missing model: the OS error appears once.
    let o = nsrm_in(d, &["apply", "--model", "missing.json", "a.exr"]);
    let err = stderr(&o);
    assert_eq!(err.matches("(os error 2)").count(), 1, "{err}");
    assert_eq!(err.matches("missing.json").count(), 1, "{err}");
    // A bad frame: its name appears once per line.
    std::fs::write(d.join("bad.exr"), b"v/1\x01 not really").unwrap();
    let o = nsrm_in(
        d,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--continue-on-error",
            "-o",
            "o",
            "bad.exr",
            "a.exr",
        ],
    );
    no_crash(&o, "bad.exr");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    for line in err.lines().filter(|l| l.contains("bad.exr")) {
        assert_eq!(line.matches("bad.exr").count(), 1, "{line}");
    }
    assert!(
        d.join("o/a_xyz.exr").is_file(),
        "the good frame is converted: {err}"
    );
    // --order is not --orders.
    let o = nsrm_in(d, &["eval", "--order", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--order `0`"), "{}", stderr(&o));
    assert!(!stderr(&o).contains("--orders"), "{}", stderr(&o));
    // A path that exists but is a directory: not "no such file".
    std::fs::create_dir(d.join("dir.json")).unwrap();
    let o = nsrm_in(d, &["apply", "--model", "dir.json", "a.exr"]);
    assert!(
        stderr(&o).contains("not a regular file or pipe (it is a directory)"),
        "{}",
        stderr(&o)
    );
}

#[cfg(unix)]
#[test]
fn non_utf8_names_are_converted() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    std::fs::create_dir(d.join("in")).unwrap();
    let name = std::ffi::OsStr::from_bytes(b"pl\xe9te.0001.exr");
    exr(&d.join("in").join(name), 2, 2);
    exr(&d.join("in/plain.exr"), 2, 2);
    // A directory, a glob and the name itself all reach it.
    for (k, spec) in [
        std::ffi::OsStr::new("in"),
        std::ffi::OsStr::new("in/*.exr"),
        Path::new("in").join(name).into_os_string().leak() as &std::ffi::OsStr,
    ]
    .into_iter()
    .enumerate()
    {
        let out = format!("o{k}");
        let o = nsrm()
            .current_dir(d)
            .args(["apply", "--model", "m.json", "--device", "cpu", "-o", &out])
            .arg(spec)
            .output()
            .unwrap();
        assert!(o.status.success(), "{spec:?}: {}", stderr(&o));
        let want = std::ffi::OsStr::from_bytes(b"pl\xe9te_xyz.0001.exr");
        assert!(
            d.join(&out).join(want).is_file(),
            "{spec:?}: {:?}",
            names(&d.join(&out))
        );
    }
}

/// A camera JPEG cut short, or whose header declares 16000×16000 over a few kilobytes, is
/// refused before it is decoded: an error naming the file, no CSV, and no more memory than
/// reading the whole file takes (before: the cut file read without a word, the chart "found";
/// the inflated one 4.5 GB and 18 s before it was taken as a frame).
#[cfg(unix)]
#[test]
fn a_cut_or_inflated_jpeg_is_refused_before_decoding() {
    let dir = common::tempdir("jpeg-hostile");
    let mut img = image::RgbImage::new(320, 240);
    for (x, y, p) in img.enumerate_pixels_mut() {
        *p = image::Rgb([(x % 251) as u8, (y % 241) as u8, ((x * y) % 239) as u8]);
    }
    let mut whole = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut whole, 90)
        .encode_image(&img)
        .unwrap();
    let sof = whole.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
    let mut inflated = whole.clone();
    inflated[sof + 5..sof + 9].copy_from_slice(&16000u16.to_be_bytes().repeat(2));
    let cut = whole[..whole.len() * 8 / 10].to_vec();
    let limit = std::time::Duration::from_secs(120);
    let extract = |name: &str, bytes: &[u8]| {
        let file = format!("{name}.jpg");
        std::fs::write(dir.join(&file), bytes).unwrap();
        let csv = format!("{name}.csv");
        let args = ["chart", "extract", "--chart", "cc24", &file, "-o", &csv];
        (common::nsrm_measured(&dir, &args, limit), dir.join(csv))
    };
    // The whole file is decoded (then no chart is found in it: not what is measured).
    let ((o, whole_peak, _), _) = extract("whole", &whole);
    let err = common::stderr(&o);
    assert!(
        !err.contains("truncated") && !err.contains("blocks"),
        "{err}"
    );
    for (name, bytes, says) in [
        ("cut", &cut, "truncated"),
        ("inflated", &inflated, "blocks"),
    ] {
        let ((o, peak, _), csv) = extract(name, bytes);
        common::no_crash(&o, name);
        let err = common::stderr(&o);
        assert!(!o.status.success(), "{name} accepted");
        assert!(
            err.contains(&format!("{name}.jpg")) && err.contains(says),
            "{name}: {err}"
        );
        assert!(!csv.exists(), "{name}: a CSV written");
        assert!(
            peak <= whole_peak + whole_peak / 2,
            "{name}: {peak} KiB at its peak, the whole file {whole_peak} KiB"
        );
    }
}

/// Messages that name their file: a camera CSV whose channels overflow once its white's green
/// is 1 (before: "fitting PRM order …" and a patch, no file), the DCP export of a model with
/// an all-zero matrix (before: "no positive camera response …", no file); and `--illuminant
/// D3000` (daylight is defined from 4000 K) lists every name it could have been, with ranges.
#[test]
fn messages_name_the_camera_file_the_model_file_and_the_illuminant_forms() {
    let dir = common::tempdir("named-files");
    let src = std::fs::read_to_string(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
        "/assets/nikon_d5100_npl_darrodi2015.csv"
    ))
    .unwrap();
    let mut lines = src.lines();
    let mut cam = format!("{}\n", lines.next().unwrap());
    for l in lines {
        let wl = l.split(',').next().unwrap();
        cam.push_str(&format!("{wl},1e300,1e-10,1e300\n"));
    }
    std::fs::write(dir.join("huge_cam.csv"), cam).unwrap();
    let o = nsrm_in(
        &dir,
        &[
            "fit",
            "--kind",
            "prm",
            "--order",
            "2",
            "--camera",
            "huge_cam.csv",
            "-o",
            "p.json",
        ],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("huge_cam.csv") && err.contains("green"),
        "{err}"
    );
    assert!(!dir.join("p.json").exists());

    nsrm_ok(&dir, &["fit", "--kind", "lrm", "-o", "m.json"]);
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("m.json")).unwrap()).unwrap();
    for row in v["matrix"].as_array_mut().unwrap() {
        for x in row.as_array_mut().unwrap() {
            *x = 0.0.into();
        }
    }
    std::fs::write(dir.join("zero_model.json"), v.to_string()).unwrap();
    let o = nsrm_in(
        &dir,
        &[
            "export",
            "--model",
            "zero_model.json",
            "--format",
            "dcp",
            "-o",
            "z.dcp",
        ],
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("zero_model.json"), "{err}");
    assert!(!dir.join("z.dcp").exists());

    let o = nsrm_in(
        &dir,
        &[
            "fit",
            "--kind",
            "lrm",
            "--illuminant",
            "D3000",
            "-o",
            "d.json",
        ],
    );
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    for want in [
        "D3000",
        "A (StdA)",
        "D50",
        "D<kelvin>",
        "4000",
        "P<kelvin>",
        "1000",
        "25000",
    ] {
        assert!(err.contains(want), "{want}: {err}");
    }
}

/// Inputs the user running nsrm may not read (issue 42): a mode-000 file in a
/// `--continue-on-error` batch fails alone, its message naming the file and the reason; a file
/// inside a folder that cannot be searched is refused as such ("permission denied"), not as
/// missing. Run as `nobody` (via `setpriv`) when the tests run as root, who reads everything.
#[test]
fn unreadable_inputs_are_named_with_the_reason() {
    use std::os::unix::fs::PermissionsExt;
    let root = real_uid() == 0;
    if root && !Path::new("/usr/bin/setpriv").exists() {
        skip("setpriv (util-linux), to run nsrm as another user than root");
        return;
    }
    let dir = tempdir("harden-unreadable");
    let perm = |p: &Path, mode: u32| {
        std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap()
    };
    perm(&dir, 0o777);
    model(&dir);
    exr(&dir.join("a.exr"), 8, 4);
    exr(&dir.join("b.exr"), 8, 4);
    for f in ["m.json", "a.exr"] {
        perm(&dir.join(f), 0o644);
    }
    perm(&dir.join("b.exr"), 0o000);
    std::fs::create_dir(dir.join("closed")).unwrap();
    exr(&dir.join("closed/c.exr"), 8, 4);
    perm(&dir.join("closed"), 0o000);
    let run = |args: &[&str]| {
        let mut c = if root {
            let mut c = std::process::Command::new("/usr/bin/setpriv");
            c.args(["--reuid=65534", "--regid=65534", "--clear-groups"])
                .arg(env!("CARGO_BIN_EXE_nsrm"));
            c
        } else {
            std::process::Command::new(env!("CARGO_BIN_EXE_nsrm"))
        };
        c.current_dir(&dir)
            .env("XDG_RUNTIME_DIR", &dir)
            .env_remove("NSRM_ADAPTER")
            .args(args)
            .output()
            .unwrap()
    };
    let o = run(&[
        "apply",
        "--model",
        "m.json",
        "--device",
        "cpu",
        "--continue-on-error",
        "-o",
        "out",
        "a.exr",
        "b.exr",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("failed: b.exr: cannot read: Permission denied"),
        "{err}"
    );
    assert!(!err.contains("planning the outputs"), "{err}");
    assert!(dir.join("out/a_xyz.exr").exists(), "{err}");
    let o = run(&[
        "apply",
        "--model",
        "m.json",
        "--device",
        "cpu",
        "-o",
        "out2",
        "closed/c.exr",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("closed/c.exr"), "{err}");
    assert!(err.contains("permission denied"), "{err}");
    assert!(!err.contains("no such file"), "{err}");
    perm(&dir.join("closed"), 0o755);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The real user id (`id -u`), without `unsafe`.
fn real_uid() -> u32 {
    std::process::Command::new("id")
        .arg("-u")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(u32::MAX)
}
