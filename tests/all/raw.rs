//! Camera raw files as frames, judged by LibRaw (rawpy, dcraw_emu), never by rawler itself:
//! synthetic CFA DNGs written by `tests/tools/raw_judge.py` (tifffile; LibRaw checks it reads
//! back exactly the mosaic written) must decode to the values written (`half`: exact block
//! means), `bilinear` must match LibRaw's LINEAR demosaic in the interior, and the real Canon
//! DNG in `../shared/data` must give LibRaw's half-size chart reading. Bad raw files give clear
//! errors, write nothing and never end a `--continue-on-error` batch.

use crate::common::read_frame;
use crate::common::{self, chart_dng, no_crash, nsrm_in, stderr};
use nsrm_io::Demosaic;
use nsrm_io::{Limits, ReadOptions};
use std::ffi::{OsStr, OsString};
use std::path::{Path, PathBuf};
use std::process::Command;

const JUDGE: &str = concat!(
    concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
    "/tests/tools/raw_judge.py"
);
const CHART_DNG: &str = concat!(
    concat!(env!("CARGO_MANIFEST_DIR"), "/../.."),
    "/../shared/data/colorchart.dng"
);

fn on_ci() -> bool {
    std::env::var("CI").as_deref() == Ok("true")
}

/// Whether python3 with rawpy, tifffile and numpy is here (prints SKIP, fails on CI, if not).
pub(crate) fn judge_available() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import rawpy, tifffile, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            !on_ci(),
            "python3 with rawpy, tifffile and numpy is needed on CI (.ci/install.d/20-libraw.sh)"
        );
        eprintln!("SKIP: python3 with rawpy, tifffile and numpy is not installed");
    }
    ok
}

/// Runs `tests/tools/raw_judge.py` with `args` and returns its standard output; the test fails
/// if the judge does.
pub(crate) fn judge<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> String {
    let args: Vec<OsString> = args.into_iter().map(|a| a.as_ref().to_owned()).collect();
    let o = Command::new("python3")
        .arg(JUDGE)
        .args(&args)
        .output()
        .expect("running python3");
    assert!(
        o.status.success(),
        "raw_judge.py {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Writes a synthetic DNG with the judge; `args` after the output name.
pub(crate) fn write_dng(out: &Path, args: &[&str]) {
    let head = [OsStr::new("dng"), out.as_os_str()];
    judge(head.into_iter().chain(args.iter().map(OsStr::new)));
}

/// The little-endian f32s of a file the judge wrote.
pub(crate) fn f32s(path: &Path) -> Vec<f32> {
    std::fs::read(path)
        .unwrap()
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

/// `path` read as a frame with `demosaic` (the test fails on an error).
pub(crate) fn read(path: &Path, demosaic: Demosaic) -> nsrm::Frame {
    read_frame(
        path,
        &ReadOptions {
            demosaic,
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn half_gives_the_exact_block_means_of_the_mosaic_written() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-half");
    let cases: [(&str, &str, &str, &str, &str); 5] = [
        // pattern, width, height, black (per 2×2 position), white
        ("RGGB", "64", "48", "0", "65535"),
        ("BGGR", "50", "34", "512,512,512,512", "16383"),
        ("GRBG", "66", "40", "100,110,120,130", "4095"),
        ("GBRG", "31", "27", "2047,2049,2050,2046", "15000"),
        ("RGGB", "26", "22", "10", "1023"),
    ];
    for (i, (pattern, w, h, black, white)) in cases.iter().enumerate() {
        let p = dir.join(format!("s{i}.dng"));
        let seed = format!("{}", 7 + i);
        write_dng(
            &p,
            &[
                "--width",
                w,
                "--height",
                h,
                "--pattern",
                pattern,
                "--black",
                black,
                "--white",
                white,
                "--seed",
                &seed,
            ],
        );
        let want = f32s(&PathBuf::from(format!("{}.half.f32", p.display())));
        let f = read(&p, Demosaic::Half);
        let (w, h): (usize, usize) = (w.parse().unwrap(), h.parse().unwrap());
        assert_eq!((f.width, f.height), (w / 2, h / 2), "{pattern}");
        assert_eq!(f.data.len(), want.len());
        for (k, (g, t)) in f.data.iter().zip(&want).enumerate() {
            assert!(
                (g - t).abs() <= 1e-6 * t.abs().max(1e-3),
                "{pattern} {w}x{h}: sample {k}: nsrm {g} vs written {t}"
            );
        }
    }
}

#[test]
fn bilinear_matches_libraw_linear_in_the_interior() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-bilinear");
    for (i, pattern) in ["RGGB", "BGGR", "GRBG", "GBRG"].iter().enumerate() {
        let p = dir.join(format!("b{i}.dng"));
        let seed = format!("{}", 30 + i);
        write_dng(
            &p,
            &[
                "--width",
                "80",
                "--height",
                "60",
                "--pattern",
                pattern,
                "--black",
                "256,260,250,262",
                "--white",
                "16383",
                "--seed",
                &seed,
                "--smooth",
            ],
        );
        let lin = dir.join(format!("b{i}.lin.f32"));
        judge([OsStr::new("linear"), p.as_os_str(), lin.as_os_str()]);
        let libraw = f32s(&lin);
        let f = read(&p, Demosaic::Bilinear);
        assert_eq!((f.width, f.height), (80, 60));
        assert_eq!(libraw.len(), f.data.len());
        let mut worst = 0f32;
        for y in 2..58 {
            for x in 2..78 {
                for c in 0..3 {
                    let k = (y * 80 + x) * 3 + c;
                    worst = worst.max((f.data[k] - libraw[k]).abs());
                }
            }
        }
        // LibRaw works in 16-bit integers (rounded scaling, truncated averages): 2 codes.
        assert!(
            worst <= 2.5 / 65535.0,
            "{pattern}: largest interior difference {worst}"
        );
        // The full-resolution MHC demosaic keeps each pixel's own sample and stays close to
        // the bilinear one on this smooth field.
        let m = read(&p, Demosaic::Mhc);
        let mut worst_mhc = 0f32;
        for k in 0..m.data.len() {
            worst_mhc = worst_mhc.max((m.data[k] - f.data[k]).abs());
        }
        assert!(worst_mhc < 0.05, "{pattern}: mhc vs bilinear {worst_mhc}");
    }
}

/// LibRaw's decode of `dng` with its orientation applied (`raw_judge.py linear --flip`,
/// `--half` for the half-size decode): (width, height, RGB in [0, 1]).
fn libraw_oriented(dng: &Path, out: &Path, half: bool) -> (usize, usize, Vec<f32>) {
    let mut cmd = Command::new("python3");
    cmd.arg(JUDGE).arg("linear").arg(dng).arg(out).arg("--flip");
    if half {
        cmd.arg("--half");
    }
    let o = cmd.output().expect("running python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let dims: Vec<usize> = String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    (dims[0], dims[1], f32s(out))
}

/// The file's orientation is applied as LibRaw applies it by default (`dcraw_emu`, rawpy's
/// `postprocess`), in every demosaic: one mosaic written with each TIFF Orientation 1–8 reads
/// as LibRaw reads it — size, and pixels (bilinear in the interior, half everywhere) — and the
/// real Canon DNG keeps LibRaw's size.
#[test]
fn orientation_is_applied_as_libraw_applies_it() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-orientation");
    for o in 1..=8u16 {
        let p = dir.join(format!("o{o}.dng"));
        let os = o.to_string();
        write_dng(
            &p,
            &[
                "--width",
                "40",
                "--height",
                "30",
                "--pattern",
                "GRBG",
                "--black",
                "256,260,250,262",
                "--white",
                "16383",
                "--seed",
                "5",
                "--smooth",
                "--orientation",
                &os,
            ],
        );
        for (demosaic, half, margin) in [(Demosaic::Bilinear, false, 2), (Demosaic::Half, true, 0)]
        {
            let (w, h, libraw) = libraw_oriented(&p, &dir.join(format!("o{o}-{half}.f32")), half);
            let f = read(&p, demosaic);
            assert_eq!(
                (f.width, f.height),
                (w, h),
                "orientation {o}, {demosaic:?}: size"
            );
            if o >= 5 {
                assert_eq!(
                    (w, h),
                    if half { (15, 20) } else { (30, 40) },
                    "LibRaw turned it"
                );
            }
            let mut worst = 0f32;
            for y in margin..h - margin {
                for x in margin..w - margin {
                    for c in 0..3 {
                        let k = (y * w + x) * 3 + c;
                        worst = worst.max((f.data[k] - libraw[k]).abs());
                    }
                }
            }
            assert!(
                worst <= 2.5 / 65535.0,
                "orientation {o}, {demosaic:?}: largest difference {worst}"
            );
        }
    }
    let dng = chart_dng();
    if dng.exists() {
        let (w, h, _) = libraw_oriented(&dng, &dir.join("chart.f32"), true);
        let f = read(&dng, Demosaic::Half);
        assert_eq!((f.width, f.height), (w, h), "colorchart.dng, half");
    }
}

/// Patch readings of `nsrm chart extract` (label → RGB).
fn extract(dir: &Path, frame: &Path, extra: &[&str]) -> Vec<(String, [f64; 3])> {
    let csv = dir.join(format!(
        "{}.csv",
        frame.file_name().unwrap().to_string_lossy()
    ));
    let mut args = vec![
        "chart",
        "extract",
        frame.to_str().unwrap(),
        "--chart",
        "cc24",
        "-o",
        csv.to_str().unwrap(),
        "--overwrite",
    ];
    args.extend_from_slice(extra);
    let o = nsrm_in(dir, &args);
    no_crash(&o, "chart extract");
    assert!(
        o.status.success(),
        "chart extract {frame:?}: {}",
        stderr(&o)
    );
    std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("label,"))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v = |i: usize| f[i].trim().parse::<f64>().unwrap();
            (f[0].to_string(), [v(1), v(2), v(3)])
        })
        .collect()
}

#[test]
fn colorchart_dng_half_matches_libraw_half_size() {
    let dng = &chart_dng();
    if !dng.exists() {
        assert!(!on_ci(), "{CHART_DNG} is absent on CI");
        eprintln!("SKIP: {CHART_DNG} is absent");
        return;
    }
    let have = Command::new("dcraw_emu").arg("-v").output().is_ok();
    if !have {
        assert!(!on_ci(), "dcraw_emu (libraw-bin) is needed on CI");
        eprintln!("SKIP: dcraw_emu (Debian libraw-bin) is not installed");
        return;
    }
    let dir = common::tempdir("raw-chart");
    let copy = dir.join("chart.dng");
    std::fs::copy(dng, &copy).unwrap();
    let o = Command::new("dcraw_emu")
        .args(["-h", "-4", "-T", "-o", "0", "-r", "1", "1", "1", "1"])
        .arg(&copy)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tiff = dir.join("chart.dng.tiff");
    let libraw = extract(&dir, &tiff, &[]);
    let ours = extract(&dir, &copy, &["--demosaic", "half"]);
    assert!(
        libraw.len() >= 20,
        "LibRaw's reading: {} patches",
        libraw.len()
    );
    // One global scale (LibRaw's 16-bit scale), the median of the ratios.
    let mut pairs = Vec::new();
    for (l, a) in &ours {
        if let Some((_, b)) = libraw.iter().find(|(m, _)| m == l) {
            pairs.push((l.clone(), *a, *b));
        }
    }
    assert!(pairs.len() >= 20, "patches read by both: {}", pairs.len());
    let mut ratios: Vec<f64> = pairs
        .iter()
        .flat_map(|(_, a, b)| (0..3).map(move |c| b[c] / a[c]))
        .collect();
    ratios.sort_by(|x, y| x.total_cmp(y));
    let s = ratios[ratios.len() / 2];
    let mut worst = 0f64;
    for (l, a, b) in &pairs {
        for c in 0..3 {
            let e = (a[c] * s - b[c]).abs() / b[c];
            assert!(
                e <= 0.005,
                "{l} channel {c}: nsrm {} vs LibRaw {} (×{s})",
                a[c],
                b[c]
            );
            worst = worst.max(e);
        }
    }
    eprintln!(
        "colorchart.dng: {} patches, global scale {s:.6}, largest difference {:.4} %",
        pairs.len(),
        worst * 100.0
    );
}

#[test]
fn apply_on_a_raw_file_writes_exr_with_the_camera_in_its_header() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-apply");
    common::model(&dir);
    write_dng(
        &dir.join("shot.dng"),
        &[
            "--width", "40", "--height", "30", "--black", "64", "--white", "4095", "--make",
            "Acme", "--model", "Synth 9",
        ],
    );
    let before = common::bytes(&dir.join("shot.dng"));
    let o = nsrm_in(
        &dir,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--output-space",
            "aces2065-1",
            "-o",
            "out",
            "shot.dng",
        ],
    );
    no_crash(&o, "apply");
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        common::bytes(&dir.join("shot.dng")),
        before,
        "input untouched"
    );
    let names = common::names(&dir.join("out"));
    assert_eq!(names.len(), 1, "{names:?}");
    let exr = dir.join("out").join(&names[0]);
    let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let h = &meta.headers[0];
    assert_eq!(h.layer_size.0, 40, "mhc keeps full resolution");
    let text = |k: &str| match h
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from(k))
    {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        v => panic!("{k}: {v:?}"),
    };
    assert_eq!(text("cameraMake"), "Acme");
    assert!(
        text("cameraModel").contains("Synth 9"),
        "{}",
        text("cameraModel")
    );
    assert_eq!(h.own_attributes.iso_speed, Some(400.0));
    assert!((h.own_attributes.exposure.unwrap() - 1.0 / 125.0).abs() < 1e-7);
    match h
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from("nsrmAsShotNeutral"))
    {
        Some(exr::meta::attribute::AttributeValue::FloatVec3((r, g, b))) => {
            assert!(
                (r - 0.5).abs() < 1e-6 && (g - 1.0).abs() < 1e-6 && (b - 2.0 / 3.0).abs() < 1e-6
            )
        }
        v => panic!("nsrmAsShotNeutral: {v:?}"),
    }
    let ours = crate::common::read_frame(&exr, &ReadOptions::default()).unwrap();
    assert!(ours.data.iter().all(|v| v.is_finite()));
}

/// Bad raw files: each gives a clear error naming the file, writes nothing, and a
/// `--continue-on-error` batch still converts the good file.
#[test]
fn bad_raw_files_are_refused_and_the_batch_goes_on() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-bad");
    common::model(&dir);
    std::fs::create_dir_all(dir.join("in")).unwrap();
    let good = dir.join("in/a_good.dng");
    write_dng(
        &good,
        &["--width", "32", "--height", "24", "--white", "4095"],
    );
    let bytes = common::bytes(&good);
    // Truncated: the header and half the pixels.
    std::fs::write(dir.join("in/b_truncated.dng"), &bytes[..bytes.len() / 2]).unwrap();
    // Huge dimensions: ImageWidth / ImageLength set to 2^30 × 2^30 in every IFD entry.
    std::fs::write(
        dir.join("in/c_huge.dng"),
        with_dims(&bytes, 1 << 30, 1 << 30),
    )
    .unwrap();
    // Corrupt tags: every entry's type scrambled in the first IFD.
    std::fs::write(dir.join("in/d_corrupt_tags.dng"), scramble_types(&bytes)).unwrap();
    // A JPEG renamed .dng.
    let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xE0, 0, 16, b'J', b'F', b'I', b'F', 0];
    jpeg.extend(std::iter::repeat_n(0u8, 200));
    jpeg.extend([0xFF, 0xD9]);
    std::fs::write(dir.join("in/e_jpeg.dng"), &jpeg).unwrap();
    for bad in ["b_truncated", "c_huge", "d_corrupt_tags", "e_jpeg"] {
        let o = nsrm_in(
            &dir,
            &[
                "apply",
                "--model",
                "m.json",
                "--device",
                "cpu",
                "-o",
                "single",
                &format!("in/{bad}.dng"),
            ],
        );
        no_crash(&o, bad);
        assert!(!o.status.success(), "{bad} was accepted");
        let err = stderr(&o);
        assert!(err.contains(bad), "{bad}: the error names the file: {err}");
        assert!(
            !dir.join("single").exists() || common::names(&dir.join("single")).is_empty(),
            "{bad}: something was written"
        );
    }
    let o = nsrm_in(
        &dir,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--continue-on-error",
            "-o",
            "out",
            "in",
        ],
    );
    no_crash(&o, "batch");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let written = common::names(&dir.join("out"));
    assert!(
        written.len() == 1 && written[0].starts_with("a_good"),
        "only the good file is converted: {written:?}"
    );
    // --max-pixels is checked before decoding.
    let o = nsrm_in(
        &dir,
        &[
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--max-pixels",
            "100",
            "-o",
            "small",
            "in/a_good.dng",
        ],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--max-pixels"), "{}", stderr(&o));
    let r = read_frame(
        &good,
        &ReadOptions {
            limits: Limits { max_pixels: 100 },
            ..Default::default()
        },
    );
    assert!(
        matches!(r, Err(nsrm_io::IoError::OverLimit { .. })),
        "{r:?}"
    );
}

/// The TIFF header's byte order and the first IFD's entries (tag, type, count, value offset).
fn ifd0(bytes: &[u8]) -> (bool, usize, usize) {
    let le = bytes[0] == b'I';
    let u32_at = |o: usize| {
        let b = [bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]];
        if le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        }
    };
    let off = u32_at(4) as usize;
    let n = if le {
        u16::from_le_bytes([bytes[off], bytes[off + 1]])
    } else {
        u16::from_be_bytes([bytes[off], bytes[off + 1]])
    } as usize;
    (le, off + 2, n)
}

fn with_dims(bytes: &[u8], w: u32, h: u32) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let (le, start, n) = ifd0(bytes);
    for i in 0..n {
        let e = start + i * 12;
        let tag = if le {
            u16::from_le_bytes([b[e], b[e + 1]])
        } else {
            u16::from_be_bytes([b[e], b[e + 1]])
        };
        let v = match tag {
            256 => w,
            257 => h,
            _ => continue,
        };
        // Type LONG, count 1, the value.
        let (t, c, v) = if le {
            (4u16.to_le_bytes(), 1u32.to_le_bytes(), v.to_le_bytes())
        } else {
            (4u16.to_be_bytes(), 1u32.to_be_bytes(), v.to_be_bytes())
        };
        b[e + 2..e + 4].copy_from_slice(&t);
        b[e + 4..e + 8].copy_from_slice(&c);
        b[e + 8..e + 12].copy_from_slice(&v);
    }
    b
}

fn scramble_types(bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    let (_, start, n) = ifd0(bytes);
    for i in 0..n {
        let e = start + i * 12;
        b[e + 2] ^= 0x0B;
        b[e + 4] ^= 0xFF;
        b[e + 7] ^= 0x7F;
    }
    b
}

mod mutated {
    use super::*;
    use proptest::prelude::*;

    fn seeds() -> &'static Vec<Vec<u8>> {
        static S: std::sync::OnceLock<Vec<Vec<u8>>> = std::sync::OnceLock::new();
        S.get_or_init(|| {
            let mut v = Vec::new();
            if let Ok(b) = std::fs::read(chart_dng()) {
                v.push(b);
            }
            if judge_available() {
                let dir = common::tempdir("raw-mutated");
                let p = dir.join("s.dng");
                write_dng(&p, &["--width", "48", "--height", "32", "--white", "4095"]);
                v.push(std::fs::read(&p).unwrap());
            }
            v
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]
        /// Mutated real and synthetic raw files: an error or a frame, never a panic, an abort
        /// or more than the pixel limit.
        #[test]
        fn mutated_raw_files_never_crash(
            which in 0usize..2,
            edits in proptest::collection::vec((0usize..1 << 16, any::<u8>()), 1..24),
            cut in proptest::option::of(0usize..1 << 22),
        ) {
            let seeds = seeds();
            if seeds.is_empty() {
                return Ok(());
            }
            let mut b = seeds[which % seeds.len()].clone();
            // Edits land in the first 64 KiB, where the headers and IFDs are.
            for (at, v) in edits {
                let n = b.len().min(1 << 16);
                b[at % n] = v;
            }
            if let Some(c) = cut {
                b.truncate(c.min(b.len()));
            }
            let dir = std::env::temp_dir().join(format!("nsrm-raw-mut-{}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            let p = dir.join("m.dng");
            std::fs::write(&p, &b).unwrap();
            for d in [Demosaic::Half, Demosaic::Mhc] {
                let r = read_frame(&p, &ReadOptions {
                    demosaic: d,
                    limits: Limits { max_pixels: 4 << 20 },
                    ..Default::default()
                });
                if let Ok(f) = r {
                    prop_assert!(f.pixels() as u64 <= 4 << 20);
                    prop_assert!(f.data.iter().all(|v| v.is_finite()));
                }
            }
        }
    }
}

/// A model fitted on a raw chart capture records the camera; `apply` warns once per other
/// camera it meets (never for the same camera), and still converts every file.
#[test]
fn apply_warns_once_per_camera_other_than_the_fitted_one() {
    if !judge_available() {
        return;
    }
    let chart = chart_dng();
    if !chart.exists() {
        assert!(!on_ci(), "{} is absent on CI", chart.display());
        eprintln!("SKIP: {} is absent", chart.display());
        return;
    }
    let dir = common::tempdir("raw-other-camera");
    let fit = nsrm_in(
        &dir,
        &[
            "fit",
            "--capture",
            chart.to_str().unwrap(),
            "--chart",
            "cc24",
            "--model",
            "lrm",
            "-o",
            "m.json",
        ],
    );
    assert!(fit.status.success(), "{}", stderr(&fit));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("m.json")).unwrap()).unwrap();
    let fitted = m["training"]["capture"]["camera"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(fitted.contains("Canon"), "{fitted}");
    for (name, model) in [
        ("a.dng", "Synth 9"),
        ("b.dng", "Synth 9"),
        ("c.dng", "Other 2"),
    ] {
        write_dng(
            &dir.join(name),
            &[
                "--width", "40", "--height", "30", "--black", "64", "--white", "4095", "--make",
                "Acme", "--model", model,
            ],
        );
    }
    let apply = |files: &[&str], out: &str| {
        let mut args = vec![
            "apply",
            "--model",
            "m.json",
            "--device",
            "cpu",
            "--demosaic",
            "half",
            "-o",
            out,
        ];
        args.extend_from_slice(files);
        let o = nsrm_in(&dir, &args);
        no_crash(&o, "apply");
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(common::names(&dir.join(out)).len(), files.len());
        stderr(&o)
    };
    let err = apply(&["a.dng", "b.dng", "c.dng"], "out1");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning:")).collect();
    assert_eq!(warnings.len(), 2, "one per other camera: {err}");
    for (cam, w) in ["Synth 9", "Other 2"].iter().zip([
        warnings.iter().find(|w| w.contains("Synth 9")),
        warnings.iter().find(|w| w.contains("Other 2")),
    ]) {
        let w = w.unwrap_or_else(|| panic!("no warning for {cam}: {err}"));
        assert!(w.contains(&fitted), "{w}");
    }
    // The camera it was fitted on: no warning.
    let err = apply(&[chart.to_str().unwrap()], "out2");
    assert!(!err.contains("warning:"), "{err}");
}

/// A lossless-JPEG DNG (Compression 7, as cameras and Adobe's converter write them), made here
/// with rawler's DNG writer from an uncompressed one. LibRaw must read the same mosaic from
/// both (so the file is a valid lossless DNG, judged by a reader that is not rawler), and nsrm
/// must read the same frame from both: for the synthetic DNG, the exact block means written.
/// (Two other LJPEG decoders, imagecodecs' liblj92 and jpegsof3, also decode rawler's tiles to
/// exactly the mosaic; checked by hand, not here.)
fn to_lossless_dng(src: &Path, dst: &Path) {
    use rawler::dng::convert::{convert_raw_file, ConvertParams};
    use rawler::dng::DngCompression;
    let params = ConvertParams::default()
        .with_compression(DngCompression::Lossless)
        .with_embedded(false)
        .with_preview(false)
        .with_thumbnail(false);
    let mut f = std::fs::File::create(dst).unwrap();
    convert_raw_file(src, &mut f, &params).unwrap();
}

fn libraw_same(a: &Path, b: &Path) -> serde_json::Value {
    let out = judge([OsStr::new("same"), a.as_os_str(), b.as_os_str()]);
    serde_json::from_str(&out).unwrap()
}

#[test]
fn lossless_jpeg_dngs_read_as_libraw_reads_them() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-ljpeg");
    let mut pairs = Vec::new();
    for (name, args) in [
        (
            "rggb",
            ["--pattern", "RGGB", "--black", "64", "--white", "4095"],
        ),
        (
            "gbrg",
            ["--pattern", "GBRG", "--black", "512", "--white", "16383"],
        ),
    ] {
        let plain = dir.join(format!("{name}.dng"));
        // Frames of several 256×256 tiles, the last ones partial, as a camera's are: LibRaw
        // (and dcraw) misplace the samples of a tile wider than the whole frame (a frame
        // below 256 pixels wide; seen: rows from the tile's padding), which no camera writes.
        let mut a = vec!["--width", "600", "--height", "420"];
        a.extend_from_slice(&args);
        write_dng(&plain, &a);
        pairs.push((plain, Some(dir.join(format!("{name}.dng.half.f32")))));
    }
    let chart = chart_dng();
    if chart.exists() {
        pairs.push((chart, None));
    } else {
        assert!(!on_ci(), "{} is absent on CI", chart.display());
        eprintln!("SKIP (that part): {} is absent", chart.display());
    }
    for (plain, truth) in pairs {
        let lossless = dir.join(format!(
            "{}-ljpeg.dng",
            plain.file_stem().unwrap().to_string_lossy()
        ));
        to_lossless_dng(&plain, &lossless);
        let j = libraw_same(&plain, &lossless);
        assert_eq!(j["compression"][1], 7, "{}: {j}", lossless.display());
        assert_eq!(j["mosaic_equal"], true, "{}: {j}", lossless.display());
        assert_eq!(j["levels_equal"], true, "{}: {j}", lossless.display());
        for demosaic in [Demosaic::Half, Demosaic::Mhc] {
            let a = read(&plain, demosaic);
            let b = read(&lossless, demosaic);
            assert_eq!((a.width, a.height), (b.width, b.height));
            assert!(a.data == b.data, "{}: {demosaic:?}", lossless.display());
        }
        if let Some(t) = truth {
            let want = f32s(&t);
            let got = read(&lossless, Demosaic::Half).data;
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).abs() <= 1e-6 * w.abs().max(1e-3), "{g} vs {w}");
            }
        }
    }
}

/// A RAF as rawler reads it, from the published layout (LibRaw's and rawler's notes): the
/// 108-byte header's pointers; an embedded "JPEG" whose EXIF TIFF names `make` / `model` and
/// holds a Fujifilm maker note (an empty IFD after "FUJIFILM" and its offset); a CFA record
/// that is no TIFF (the raw data would start there); and the RAF directory declaring `w`×`h`
/// (tag 0x100, height first) and the sensor layout (tag 0x130, bytes `layout`). No pixel data.
fn raf_naming(make: &str, model: &str, w: u16, h: u16, layout: [u8; 2]) -> Vec<u8> {
    // The EXIF TIFF (little-endian): IFD0 with Make, Model and the EXIF IFD pointer; the EXIF
    // IFD with the maker note; then the strings and the note.
    let (make, model) = (format!("{make}\0"), format!("{model}\0"));
    let note: Vec<u8> = [&b"FUJIFILM"[..], &12u32.to_le_bytes(), &[0; 6]].concat();
    let ifd0_len = 2 + 3 * 12 + 4;
    let exif_at = 8 + ifd0_len;
    let strings_at = exif_at + 2 + 12 + 4;
    let model_at = strings_at + make.len();
    let note_at = model_at + model.len();
    let mut t = b"II*\0".to_vec();
    t.extend(8u32.to_le_bytes());
    let entry = |t: &mut Vec<u8>, tag: u16, typ: u16, count: usize, value: usize| {
        t.extend(tag.to_le_bytes());
        t.extend(typ.to_le_bytes());
        t.extend((count as u32).to_le_bytes());
        t.extend((value as u32).to_le_bytes());
    };
    t.extend(3u16.to_le_bytes());
    entry(&mut t, 0x10f, 2, make.len(), strings_at);
    entry(&mut t, 0x110, 2, model.len(), model_at);
    entry(&mut t, 0x8769, 4, 1, exif_at);
    t.extend(0u32.to_le_bytes());
    t.extend(1u16.to_le_bytes());
    entry(&mut t, 0x927c, 7, note.len(), note_at);
    t.extend(0u32.to_le_bytes());
    t.extend(make.as_bytes());
    t.extend(model.as_bytes());
    t.extend(&note);
    let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xE1];
    jpeg.extend(((t.len() + 8) as u16).to_be_bytes());
    jpeg.extend(b"Exif\0\0");
    jpeg.extend(&t);
    jpeg.extend([0xFF, 0xD9]);
    // The RAF directory: a count, then tag, length, data (big-endian).
    let mut dir = 2u32.to_be_bytes().to_vec();
    dir.extend([0x01, 0x00, 0, 4]);
    dir.extend(h.to_be_bytes());
    dir.extend(w.to_be_bytes());
    dir.extend([0x01, 0x30, 0, 2]);
    dir.extend(layout);
    let cfa = vec![0u8; 64];
    let jpeg_at = 108u32;
    let dir_at = jpeg_at + jpeg.len() as u32;
    let cfa_at = dir_at + dir.len() as u32;
    let mut b = b"FUJIFILMCCD-RAW 0201FF383501".to_vec();
    b.resize(84, 0);
    for (at, len) in [
        (jpeg_at, jpeg.len()),
        (dir_at, dir.len()),
        (cfa_at, cfa.len()),
    ] {
        b.extend(at.to_be_bytes());
        b.extend((len as u32).to_be_bytes());
    }
    b.extend(&jpeg);
    b.extend(&dir);
    b.extend(&cfa);
    b
}

/// rawler turns a SuperCCD mosaic by 45° into a square image of about (w + h/2)² pixels
/// because of the camera the file names, whatever its sensor-layout tag (0x130) says. A crafted
/// RAF naming a SuperCCD camera (the FinePix E900) whose tag claims another layout, with a
/// 3000×3000 mosaic (within `--max-pixels` 2^24), must be refused over the limit for its
/// 4500×4500 turned image before rawler allocates it; the same file naming a camera whose
/// mosaic is not turned (the X-T2) gets past the limit to the decoder, which finds no data.
#[test]
fn a_raf_naming_a_superccd_camera_is_bounded_whatever_its_layout_tag_says() {
    let dir = common::tempdir("raw-raf-layout");
    let limits = ReadOptions {
        limits: Limits {
            max_pixels: 1 << 24,
        },
        ..Default::default()
    };
    let read = |name: &str, bytes: &[u8]| {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        (p.clone(), read_frame(&p, &limits))
    };
    // Byte 1, bit 3 set: not SuperCCD as LibRaw reads the tag; byte 0, bit 7: rawler's layout.
    let not_superccd = [0x80, 0x08];
    let (p, r) = read(
        "e900.raf",
        &raf_naming("FUJIFILM", "FinePix E900", 3000, 3000, not_superccd),
    );
    match r {
        Err(nsrm_io::IoError::OverLimit { why, .. }) => {
            assert!(why.contains("4500×4500"), "{why}")
        }
        r => panic!("{r:?}"),
    }
    // The command line says so too, naming the limit.
    let o = nsrm_in(
        &dir,
        &[
            "chart",
            "extract",
            p.to_str().unwrap(),
            "--chart",
            "cc24",
            "--max-pixels",
            "16777216",
        ],
    );
    no_crash(&o, "e900.raf");
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--max-pixels"), "{}", stderr(&o));
    // Not a SuperCCD camera: the mosaic's own size is within the limit, and the decoder runs.
    let (_, r) = read(
        "xt2.raf",
        &raf_naming("FUJIFILM", "X-T2", 3000, 3000, not_superccd),
    );
    assert!(matches!(r, Err(nsrm_io::IoError::Corrupt { .. })), "{r:?}");
}

/// An IFD's entries: (tag, type, count, value field position).
type IfdEntries = Vec<(u16, u16, u32, usize)>;

/// A TIFF's IFDs as (offset, entries), IFD0's chain and SubIFDs, in the order met.
fn ifds(b: &[u8]) -> (bool, Vec<(usize, IfdEntries)>) {
    let le = b[0] == b'I';
    let u16_at = |o: usize| {
        let v = [b[o], b[o + 1]];
        (if le {
            u16::from_le_bytes(v)
        } else {
            u16::from_be_bytes(v)
        }) as usize
    };
    let u32_at = |o: usize| {
        let v = [b[o], b[o + 1], b[o + 2], b[o + 3]];
        (if le {
            u32::from_le_bytes(v)
        } else {
            u32::from_be_bytes(v)
        }) as usize
    };
    let mut out = Vec::new();
    let mut queue = vec![u32_at(4)];
    while let Some(off) = queue.pop() {
        if off == 0 || out.iter().any(|(o, _)| *o == off) {
            continue;
        }
        let n = u16_at(off);
        let entries: Vec<_> = (0..n)
            .map(|i| {
                let e = off + 2 + 12 * i;
                (
                    u16_at(e) as u16,
                    u16_at(e + 2) as u16,
                    u32_at(e + 4) as u32,
                    e + 8,
                )
            })
            .collect();
        for &(tag, typ, count, field) in &entries {
            if tag == 330 {
                if count == 1 {
                    queue.push(u32_at(field));
                } else {
                    let at = u32_at(field);
                    queue.extend((0..count as usize).map(|i| u32_at(at + 4 * i)));
                }
                let _ = typ;
            }
        }
        queue.push(u32_at(off + 2 + 12 * n));
        out.push((off, entries));
    }
    (le, out)
}

/// Lossless-JPEG DNGs whose streams lie (a frame header of 65535×65535, data that stops after
/// ten bytes, a Huffman table with no code, a tile four times the image) and DNGs whose IFD
/// chain loops are refused before the decoder sees them: a clear error naming the file, no
/// output, and no more memory or time than reading the true file takes (before: 8.4 GB and
/// 43 s for the first; invented zero pixels and exit 0 for the next three; a decoder that
/// grew until it aborted for the loops).
#[cfg(unix)]
#[test]
fn lossless_jpeg_dngs_that_lie_are_refused_before_decoding() {
    if !judge_available() {
        return;
    }
    let dir = common::tempdir("raw-ljpeg-hostile");
    common::model(&dir);
    let plain = dir.join("plain.dng");
    write_dng(&plain, &["--width", "600", "--height", "420"]);
    let good = dir.join("good.dng");
    to_lossless_dng(&plain, &good);
    let b = std::fs::read(&good).unwrap();
    let (le, all) = ifds(&b);
    let put32 = |b: &mut Vec<u8>, at: usize, v: u32| {
        let bytes = if le { v.to_le_bytes() } else { v.to_be_bytes() };
        b[at..at + 4].copy_from_slice(&bytes);
    };
    let field = |tag: u16| {
        all.iter()
            .flat_map(|(_, e)| e.iter())
            .find(|e| e.0 == tag)
            .copied()
            .unwrap_or_else(|| panic!("no tag {tag}"))
    };
    let u32_of = |at: usize| {
        let v = [b[at], b[at + 1], b[at + 2], b[at + 3]];
        if le {
            u32::from_le_bytes(v)
        } else {
            u32::from_be_bytes(v)
        }
    };
    let (_, typ, count, f) = field(324);
    let tile0 = if count == 1 {
        u32_of(f)
    } else {
        u32_of(u32_of(f) as usize)
    } as usize;
    let _ = typ;
    let in_tile = |m: u8| tile0 + b[tile0..].windows(2).position(|w| w == [0xFF, m]).unwrap();
    let mut cases: Vec<(&str, Vec<u8>)> = Vec::new();
    let mut huge = b.clone();
    huge[in_tile(0xC3) + 5..in_tile(0xC3) + 9].copy_from_slice(&[0xFF; 4]);
    cases.push(("sof_65535", huge));
    let mut short = b.clone();
    let sos = in_tile(0xDA);
    let data = sos + 2 + usize::from(u16::from_be_bytes([b[sos + 2], b[sos + 3]]));
    short[data + 10..data + 12].copy_from_slice(&[0xFF, 0xD9]);
    cases.push(("ten_bytes", short));
    let mut empty = b.clone();
    let dht = in_tile(0xC4);
    empty[dht + 5..dht + 21].fill(0);
    cases.push(("empty_table", empty));
    let mut wide = b.clone();
    let (_, typ, _, f) = field(322);
    let four = 4 * u32_of(field(256).3).max(1);
    if typ == 3 {
        let v = if le {
            (four as u16).to_le_bytes()
        } else {
            (four as u16).to_be_bytes()
        };
        wide[f..f + 2].copy_from_slice(&v);
    } else {
        put32(&mut wide, f, four);
    }
    cases.push(("tile_too_large", wide));
    // IFD0's next IFD is IFD0; the last IFD's next is IFD0.
    let (ifd0, e0) = &all[0];
    let mut self_loop = b.clone();
    put32(&mut self_loop, ifd0 + 2 + 12 * e0.len(), *ifd0 as u32);
    cases.push(("ifd_loop", self_loop));
    let (last, el) = all.last().unwrap();
    let mut back = b.clone();
    put32(&mut back, last + 2 + 12 * el.len(), *ifd0 as u32);
    cases.push(("ifd_back_to_the_first", back));
    let limit = std::time::Duration::from_secs(120);
    let apply = |name: &str| {
        let out = format!("out_{name}");
        let file = format!("{name}.dng");
        let args = [
            "apply", "--model", "m.json", "--device", "cpu", "-o", &out, &file,
        ];
        (common::nsrm_measured(&dir, &args, limit), dir.join(out))
    };
    std::fs::write(dir.join("true.dng"), &b).unwrap();
    let ((o, true_peak, true_time), _) = apply("true");
    common::assert_ok(&o);
    for (name, bytes) in &cases {
        std::fs::write(dir.join(format!("{name}.dng")), bytes).unwrap();
        let ((o, peak, took), out) = apply(name);
        no_crash(&o, name);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {:?} {err}", o.status);
        assert!(err.contains(&format!("{name}.dng")), "{name}: {err}");
        assert!(
            !out.exists() || common::names(&out).is_empty(),
            "{name}: written"
        );
        assert!(
            peak <= true_peak + true_peak / 2,
            "{name}: {peak} KiB at its peak, the true file {true_peak} KiB"
        );
        assert!(
            took <= 2 * true_time + std::time::Duration::from_secs(5),
            "{name}: {took:?}"
        );
        eprintln!("{name}: {} ({peak} KiB, {took:?})", err.trim());
    }
}

/// `path` (an EXR) with its `R`, `G`, `B` as the `exr` crate reads them, interleaved, as bits.
fn exr_rgb_bits(path: &Path) -> (usize, usize, Vec<u32>) {
    use exr::image::FlatSamples;
    let img = exr::prelude::read_all_data_from_file(path)
        .unwrap_or_else(|e| panic!("the exr crate reads {}: {e}", path.display()));
    let layer = &img.layer_data[0];
    let chan = |n: &str| -> Vec<u32> {
        let c = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.eq(n))
            .unwrap_or_else(|| panic!("no channel {n}"));
        match &c.sample_data.levels_as_slice()[0] {
            FlatSamples::F32(v) => v.iter().map(|f| f.to_bits()).collect(),
            other => panic!("{n}: not f32 ({} samples)", other.len()),
        }
    };
    let (r, g, b) = (chan("R"), chan("G"), chan("B"));
    let rgb = r
        .iter()
        .zip(&g)
        .zip(&b)
        .flat_map(|((r, g), b)| [*r, *g, *b])
        .collect();
    (layer.size.0, layer.size.1, rgb)
}

/// A raw input reaches the chunk-level EXR writer (ZIP by default) and its output holds the
/// pixels the previous path wrote: the corrected frame `apply` writes as a TIFF (a writer of its
/// own), written by the `exr` crate's whole-image writer as `apply` did before. Judged by the
/// `exr` crate (bit for bit) and by OpenImageIO (`oiiotool --diff`, OpenEXR's reader).
#[test]
fn apply_on_a_raw_file_writes_through_the_fast_writer_the_pixels_of_the_previous_path() {
    use exr::image::{AnyChannel, AnyChannels, Blocks, Encoding, FlatSamples, Image, Layer};
    use exr::prelude::WritableImage;
    let dng = common::chart_dng();
    if !dng.exists() {
        common::skip(&format!("{} is absent", dng.display()));
        return;
    }
    let oiio = Command::new("oiiotool")
        .arg("--help")
        .output()
        .is_ok_and(|o| o.status.success());
    if !oiio {
        common::skip("oiiotool not found (apt-get install -y openimageio-tools)");
        return;
    }
    let dir = common::tempdir("raw-fast-writer");
    common::model(&dir);
    let dng = dng.to_str().unwrap();
    let apply = |extra: &[&str]| {
        let mut args = vec!["apply", "--model", "m.json", "--device", "cpu"];
        args.extend_from_slice(extra);
        args.push(dng);
        let o = nsrm_in(&dir, &args);
        no_crash(&o, "apply");
        assert!(o.status.success(), "{}", stderr(&o));
    };
    apply(&["-o", "exr"]);
    apply(&["--format", "tiff", "-o", "tif"]);
    let new = dir.join("exr/colorchart_xyz.exr");
    let tif = dir.join("tif/colorchart_xyz.tif");

    let meta = exr::meta::MetaData::read_from_file(&new, false).unwrap();
    let h = &meta.headers[0];
    assert_eq!(
        h.compression,
        exr::compression::Compression::ZIP16,
        "a raw input's default"
    );
    assert!(
        h.own_attributes
            .other
            .contains_key(&exr::meta::attribute::Text::from("cameraMake")),
        "the camera in the header"
    );

    // The corrected frame, and the file the previous path (the exr crate's writer) made of it.
    let want = read_frame(&tif, &ReadOptions::default()).unwrap();
    let (w, h) = (want.width, want.height);
    let plane = |c: usize| FlatSamples::F32(want.data.iter().skip(c).step_by(3).copied().collect());
    let channels = ["R", "G", "B"]
        .into_iter()
        .enumerate()
        .map(|(c, n)| AnyChannel::new(n, exr::image::Levels::Singular(plane(c))))
        .collect();
    let layer = Layer::new(
        (w, h),
        exr::meta::header::LayerAttributes::default(),
        Encoding {
            compression: exr::compression::Compression::ZIP16,
            blocks: Blocks::ScanLines,
            line_order: exr::meta::attribute::LineOrder::Increasing,
        },
        AnyChannels::sort(channels),
    );
    let old = dir.join("old.exr");
    Image::from_layer(layer).write().to_file(&old).unwrap();

    let (nw, nh, got) = exr_rgb_bits(&new);
    assert_eq!((nw, nh), (w, h));
    let want_bits: Vec<u32> = want.data.iter().map(|v| v.to_bits()).collect();
    assert!(got == want_bits, "the exr crate reads the corrected frame");
    assert_eq!(exr_rgb_bits(&old).2, got, "as the previous writer wrote it");
    for other in [&old, &tif] {
        let o = Command::new("oiiotool")
            .args(["--diff", "--fail", "0", "--warn", "0"])
            .arg(&new)
            .arg(other)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success() && text.contains("PASS"),
            "oiiotool --diff {} {}: {text}{}",
            new.display(),
            other.display(),
            String::from_utf8_lossy(&o.stderr)
        );
    }
}
