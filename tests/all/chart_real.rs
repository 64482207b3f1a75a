//! Chart detection on the four real photographs of `../shared/realcharts/` (never committed;
//! read by path, or from `$NSRM_SHARED/realcharts/`), run as a user would: `nsrm chart extract`
//! must find each chart and put every label where it is. The expected centres of four corner
//! patches were read off the overlay PNGs by eye (patch colours against the CC24's layout) and
//! are asserted to a quarter of the patch pitch, so a placement one cell off, rotated or
//! mirrored fails.

use crate::common::{nsrm_in, stderr, tempdir};
use std::path::PathBuf;

fn realcharts() -> Option<PathBuf> {
    let mut dirs = vec![PathBuf::from(concat!(
        concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
        "/../shared/realcharts"
    ))];
    if let Some(s) = std::env::var_os("NSRM_SHARED") {
        dirs.push(PathBuf::from(s).join("realcharts"));
    }
    let found = dirs.into_iter().find(|d| d.join("NOTICE.md").exists());
    if found.is_none() {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "../shared/realcharts is missing under CI=true"
        );
        eprintln!("SKIP: ../shared/realcharts (the real photographs) is absent");
    }
    found
}

/// (file, --encoding, expected centres of 01 dark skin, 06 bluish green, 19 white 9.5,
/// 24 black 2 in pixels).
const PHOTOS: [(&str, &str, [[f64; 2]; 4]); 4] = [
    // Rotated 90°: 01 at the bottom left, 06 top left, 19 bottom right, 24 top right.
    (
        "jtvd_classic_1.jpg",
        "auto",
        [
            [498.0, 1345.0],
            [476.0, 395.0],
            [1085.0, 1311.0],
            [1028.0, 369.0],
        ],
    ),
    // Passport held upright in a cluttered scene, sun spots.
    (
        "pedrodiamel_scene.jpg",
        "auto",
        [
            [261.0, 303.0],
            [511.0, 303.0],
            [261.0, 453.0],
            [515.0, 442.0],
        ],
    ),
    // Rotated the other way: the grey row is the left column, white at the top.
    (
        "jarrelscy_203500.jpg",
        "auto",
        [
            [1123.0, 980.0],
            [1123.0, 1815.0],
            [607.0, 974.0],
            [640.0, 1812.0],
        ],
    ),
    // Filling the frame, linear 8-bit values (NOTICE.md).
    (
        "andriy_sun_linear8.tif",
        "linear",
        [[49.0, 50.0], [549.0, 51.0], [51.0, 349.0], [551.0, 348.0]],
    ),
];

fn read(
    dir: &std::path::Path,
    photo: &std::path::Path,
    encoding: &str,
) -> (bool, String, Option<serde_json::Value>) {
    let json = dir.join("r.json");
    let _ = std::fs::remove_file(&json);
    let out = nsrm_in(
        dir,
        &[
            "chart",
            "extract",
            photo.to_str().unwrap(),
            "--chart",
            "cc24",
            "--encoding",
            encoding,
            "-o",
            "p.csv",
            "--json",
            "r.json",
            "--overwrite",
        ],
    );
    let v = std::fs::read_to_string(&json)
        .ok()
        .map(|t| serde_json::from_str(&t).unwrap());
    (out.status.success(), stderr(&out), v)
}

fn centre(v: &serde_json::Value, label: &str) -> [f64; 2] {
    let p = v["patches"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["label"].as_str().unwrap().starts_with(label))
        .unwrap();
    [
        p["centre"][0].as_f64().unwrap(),
        p["centre"][1].as_f64().unwrap(),
    ]
}

fn check_positions(name: &str, v: &serde_json::Value, want: &[[f64; 2]; 4]) {
    // Pitch: 01 → 06 spans five pitches.
    let pitch = (want[0][0] - want[1][0]).hypot(want[0][1] - want[1][1]) / 5.0;
    for (label, w) in ["01 ", "06 ", "19 ", "24 "].iter().zip(want) {
        let c = centre(v, label);
        let off = (c[0] - w[0]).hypot(c[1] - w[1]);
        assert!(
            off < 0.25 * pitch,
            "{name}: patch {label}at ({:.0}, {:.0}), expected ({:.0}, {:.0})",
            c[0],
            c[1],
            w[0],
            w[1]
        );
    }
}

#[test]
fn the_four_real_photographs_are_read_correctly() {
    let Some(dir) = realcharts() else { return };
    let d = tempdir("chart-real");
    for (name, enc, want) in PHOTOS {
        let (ok, err, v) = read(&d, &dir.join(name), enc);
        assert!(ok, "{name}: {err}");
        let v = v.expect("report");
        assert_eq!(v["patches"].as_array().unwrap().len(), 24, "{name}");
        check_positions(name, &v, &want);
        let usable = v["patches"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["flags"].as_array().unwrap().is_empty())
            .count();
        assert!(usable >= 8, "{name}: {usable} usable patches");
        let enc_recorded = v["provenance"]["encoding"].as_str().unwrap();
        if enc == "auto" {
            assert!(
                enc_recorded.starts_with("display-referred"),
                "{name}: {enc_recorded}"
            );
        }
    }
}

#[test]
fn a_linear_photograph_read_as_srgb_is_found_in_the_same_place_or_refused() {
    // The wrong encoding must never turn into a wrong reading.
    let Some(dir) = realcharts() else { return };
    let d = tempdir("chart-real-enc");
    let (name, _, want) = PHOTOS[3];
    let (ok, err, v) = read(&d, &dir.join(name), "srgb");
    if ok {
        check_positions(name, &v.expect("report"), &want);
    } else {
        assert!(err.contains("chart"), "{err}");
    }
}

#[test]
fn fit_from_a_camera_jpeg_warns_and_is_marked_display_referred() {
    let Some(dir) = realcharts() else { return };
    let d = tempdir("chart-real-fit");
    let photo = dir.join("jtvd_classic_1.jpg");
    let out = nsrm_in(
        &d,
        &[
            "fit",
            "--capture",
            photo.to_str().unwrap(),
            "--chart",
            "cc24",
            "--model",
            "nsrm",
            "--order",
            "2",
            "-o",
            "m.json",
        ],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("cc24 chart found"), "{err}");
    assert!(err.contains("display-referred"), "{err}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("m.json")).unwrap()).unwrap();
    let enc = m["training"]["capture"]["encoding"].as_str().unwrap_or("");
    assert!(enc.starts_with("display-referred"), "provenance: {enc}");
}
