//! Fujifilm X-Trans (6×6 CFA) raw files, judged by LibRaw (rawpy) and by the values written:
//! synthetic X-Trans DNGs written by `tests/tools/raw_judge.py` (LibRaw first checks it reads
//! back the mosaic and pattern written). `half` is one pixel per 3×3 block, each colour the mean
//! of its sites there (exact, 1e-6 relative); flat fields decode to the values written in every
//! demosaic; `bilinear` matches LibRaw's LINEAR demosaic (`lin_interpolate`) in the interior.

use crate::raw::{f32s, judge, judge_available, read, write_dng};
use nsrm_io::Demosaic;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

/// Fujifilm's X-Trans layout (X-Pro1 … X-T5), row-major.
const XTRANS: &str = "GGRGGBGGBGGRBRGRBGGGBGGRGGRGGBRBGBRG";

fn xtrans_dng(out: &Path, w: usize, h: usize, extra: &[&str]) {
    let (w, h) = (w.to_string(), h.to_string());
    let mut args = vec![
        "--width",
        &w,
        "--height",
        &h,
        "--pattern",
        XTRANS,
        "--black",
        "256",
        "--white",
        "16383",
    ];
    args.extend_from_slice(extra);
    write_dng(out, &args);
}

fn half_truth(dng: &Path) -> Vec<f32> {
    f32s(&PathBuf::from(format!("{}.half.f32", dng.display())))
}

fn colour(y: usize, x: usize) -> usize {
    match XTRANS.as_bytes()[(y % 6) * 6 + x % 6] {
        b'R' => 0,
        b'G' => 1,
        _ => 2,
    }
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-6 * b.abs().max(1e-3)
}

#[test]
fn xtrans_flat_fields_decode_to_the_values_written() {
    if !judge_available() {
        return;
    }
    let dir = crate::common::tempdir("raw-xtrans-flat");
    let p = dir.join("flat.dng");
    let (w, h) = (66, 48);
    xtrans_dng(&p, w, h, &["--flat", "0.3,0.6,0.15"]);
    // The written value of each colour (as LibRaw scales it): any block's mean, all equal.
    let truth = half_truth(&p);
    let want = [truth[0], truth[1], truth[2]];
    for px in truth.chunks_exact(3) {
        assert_eq!(px, want, "the field written is flat");
    }
    for d in [Demosaic::Half, Demosaic::Bilinear, Demosaic::Mhc] {
        let f = read(&p, d);
        let size = if d == Demosaic::Half {
            (w / 3, h / 3)
        } else {
            (w, h)
        };
        assert_eq!((f.width, f.height), size, "{d:?}");
        for (i, px) in f.data.chunks_exact(3).enumerate() {
            for c in 0..3 {
                assert!(
                    close(px[c], want[c]),
                    "{d:?}: pixel {i} channel {c}: {} vs {}",
                    px[c],
                    want[c]
                );
            }
        }
    }
}

#[test]
fn xtrans_half_gives_the_block_means_and_bilinear_matches_libraw_linear() {
    if !judge_available() {
        return;
    }
    let dir = crate::common::tempdir("raw-xtrans-smooth");
    let p = dir.join("smooth.dng");
    let (w, h) = (90, 60);
    xtrans_dng(&p, w, h, &["--smooth", "--seed", "5"]);
    // half: the exact 3×3 block means of each colour's sites.
    let want = half_truth(&p);
    let f = read(&p, Demosaic::Half);
    assert_eq!((f.width, f.height), (w / 3, h / 3));
    assert_eq!(f.data.len(), want.len());
    for (k, (g, t)) in f.data.iter().zip(&want).enumerate() {
        assert!(close(*g, *t), "half sample {k}: nsrm {g} vs written {t}");
    }
    // bilinear against LibRaw's LINEAR demosaic.
    let lin = dir.join("smooth.lin.f32");
    judge([OsStr::new("linear"), p.as_os_str(), lin.as_os_str()]);
    let libraw = f32s(&lin);
    let ours = read(&p, Demosaic::Bilinear);
    assert_eq!((ours.width, ours.height), (w, h));
    assert_eq!(libraw.len(), ours.data.len());
    // LibRaw's lin_interpolate divides by the weight sum S (edge neighbours 2, corners 1) as
    // `* (256 / S) >> 8` in integers: for the sums X-Trans has (3, 5, 6, …) that is up to 0.4 %
    // low. So: within 0.5 % of LibRaw as it is, and within 2.5 codes of 65535 of LibRaw with
    // its reciprocal put back (its 16-bit truncation left).
    let (mut worst_rel, mut worst_codes) = (0f32, 0f32);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let mut wt = [0u32; 3];
            for yy in y - 1..=y + 1 {
                for xx in x - 1..=x + 1 {
                    wt[colour(yy, xx)] += if yy == y || xx == x { 2 } else { 1 };
                }
            }
            for c in 0..3 {
                let k = (y * w + x) * 3 + c;
                let (a, b) = (ours.data[k], libraw[k]);
                worst_rel = worst_rel.max((a - b).abs() / b.max(1e-3));
                let scale = if c == colour(y, x) {
                    1.0
                } else {
                    (256 / wt[c]) as f32 * wt[c] as f32 / 256.0
                };
                worst_codes = worst_codes.max((a * scale - b).abs() * 65535.0);
            }
        }
    }
    eprintln!(
        "X-Trans bilinear vs LibRaw LINEAR, interior: {:.3} % largest, {worst_codes:.2} codes \
         after LibRaw's reciprocal",
        worst_rel * 100.0
    );
    assert!(
        worst_rel <= 0.005,
        "largest interior difference {worst_rel}"
    );
    assert!(
        worst_codes <= 2.5,
        "after LibRaw's reciprocal: {worst_codes} codes"
    );
    // mhc is a Bayer method: X-Trans gets the same bilinear frame.
    assert!(read(&p, Demosaic::Mhc).data == ours.data);
}
