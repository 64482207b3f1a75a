//! The capture workflow as a library call (`nsrm_chart::capture`): `chart extract` writes the
//! bytes the library's reading gives (patches CSV and reading JSON), on a synthetic scene with a
//! flat frame, on an SG scene, and on the real raw frame `../shared/data/colorchart.dng`; and a
//! reading taken again from the decoded frame equals a fresh one.

use crate::common::{chart_dng, nsrm_ok, skip, tempdir};
use nsrm_chart::{read, CaptureFrame, ChartKind, FlatField, ReadingOptions, Reference};
use nsrm_io::Encoding;
use nsrm_io::ReadOptions;
use std::path::Path;
use std::sync::Arc;

/// The CLI's default frame reading (raw: half; JPEG/PNG: sRGB-decoded).
fn open(path: &Path) -> Arc<CaptureFrame> {
    Arc::new(
        CaptureFrame::open(
            path,
            &ReadOptions {
                demosaic: nsrm_io::Demosaic::Half,
                ..Default::default()
            },
            Encoding::Auto,
        )
        .expect("decoding the frame"),
    )
}

/// `chart extract FRAME --chart KIND [extra]` in `dir`; the CSV and JSON it wrote.
fn cli(dir: &Path, frame: &Path, kind: &str, extra: &[&str]) -> (Vec<u8>, Vec<u8>) {
    let f = frame.to_str().unwrap();
    let mut args = vec![
        "chart",
        "extract",
        f,
        "--chart",
        kind,
        "-o",
        "p.csv",
        "--json",
        "r.json",
        "--overwrite",
    ];
    args.extend_from_slice(extra);
    nsrm_ok(dir, &args);
    (
        std::fs::read(dir.join("p.csv")).unwrap(),
        std::fs::read(dir.join("r.json")).unwrap(),
    )
}

fn lib_bytes(c: &nsrm_chart::Capture) -> (Vec<u8>, Vec<u8>) {
    (
        c.to_csv().into_bytes(),
        serde_json::to_string_pretty(&c.report())
            .unwrap()
            .into_bytes(),
    )
}

#[test]
fn chart_extract_writes_what_the_library_reads() {
    let dir = tempdir("capture-lib");
    nsrm_ok(
        &dir,
        &[
            "render-scene",
            "--chart",
            "cc24",
            "-o",
            "cc.exr",
            "--flat-output",
            "flat.exr",
            "--gradient",
            "0.3",
            "--width",
            "900",
            "--height",
            "600",
        ],
    );
    let frame_path = dir.join("cc.exr");
    let frame = open(&frame_path);
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    // Detection, no flat field.
    let plain = read(&frame, &reference, &ReadingOptions::default()).unwrap();
    assert_eq!(lib_bytes(&plain), cli(&dir, &frame_path, "cc24", &[]));
    // The flat frame, decoded by the caller.
    let flat = crate::common::read_frame(&dir.join("flat.exr"), &ReadOptions::default()).unwrap();
    let flat_read = read(
        &frame,
        &reference,
        &ReadingOptions {
            flat: Some(FlatField::Frame(&flat)),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(
        lib_bytes(&flat_read),
        cli(&dir, &frame_path, "cc24", &["--flat", "flat.exr"])
    );
    assert_ne!(lib_bytes(&flat_read).0, lib_bytes(&plain).0);
    // At the detected corners, with the neutral-patch flat field: what `--corners` reads.
    let corners: [[f64; 2]; 4] = serde_json::from_value(plain.report()["corners"].clone()).unwrap();
    let text = corners
        .iter()
        .map(|p| format!("{},{}", p[0], p[1]))
        .collect::<Vec<_>>()
        .join(" ");
    let at = read(
        &frame,
        &reference,
        &ReadingOptions {
            corners: Some(corners),
            flat: Some(FlatField::Neutrals),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(at.report()["detection"].is_null());
    assert_eq!(
        lib_bytes(&at),
        cli(
            &dir,
            &frame_path,
            "cc24",
            &["--corners", &text, "--flat", "neutrals"]
        )
    );
    // The decoded frame is shared, never copied, by the readings.
    assert!(Arc::ptr_eq(&at.frame, &frame) && Arc::ptr_eq(&plain.frame, &frame));
    assert_eq!(Arc::strong_count(&frame), 4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_sg_scene_and_the_real_raw_frame_read_the_same_through_the_library() {
    let dir = tempdir("capture-lib-sg");
    let Some(sg) = crate::common::sg_path() else {
        return;
    };
    nsrm_ok(
        &dir,
        &[
            "render-scene",
            "--chart",
            "sg",
            "--reflectances",
            sg.to_str().unwrap(),
            "-o",
            "sg.exr",
            "--width",
            "1200",
            "--height",
            "800",
        ],
    );
    let reference = Reference::load("sg-after2014", ChartKind::Sg, None).unwrap();
    let p = dir.join("sg.exr");
    let c = read(&open(&p), &reference, &ReadingOptions::default()).unwrap();
    assert_eq!(c.report()["patches"].as_array().unwrap().len(), 140);
    assert_eq!(lib_bytes(&c), cli(&dir, &p, "sg", &[]));

    let dng = chart_dng();
    if !dng.exists() {
        skip(&format!("{} is absent", dng.display()));
        return;
    }
    let reference = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
    let c = read(&open(&dng), &reference, &ReadingOptions::default()).unwrap();
    assert!(
        c.report()["provenance"]["camera"].is_string(),
        "a raw frame names its camera"
    );
    assert_eq!(lib_bytes(&c), cli(&dir, &dng, "cc24", &[]));
    let _ = std::fs::remove_dir_all(&dir);
}
