//! Property-based fuzzing, bounded in time (a few hundred cases each): the TIFF reader over
//! mutated real files, and the flag parsers over arbitrary strings. Whatever the input, the
//! result is a value or an error, never a panic, an abort or an allocation the limits do not
//! allow; whatever is accepted is well formed.

use nsrm::{parse_white, TrainingSet};
use nsrm_io::{Decoded, Limits, ReadOptions};
use proptest::prelude::*;
use std::sync::OnceLock;

fn fuzz_cases(default: u32) -> u32 {
    std::env::var("NSRM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Small limits: a mutated header may legitimately ask for anything up to them.
const MAX_PIXELS: u64 = 1 << 16;

fn frame(w: usize, h: usize, ch: usize) -> nsrm::Frame {
    nsrm::Frame {
        width: w,
        height: h,
        layout: if ch == 4 {
            nsrm::Layout::Rgba
        } else {
            nsrm::Layout::Rgb
        },
        data: (0..w * h * ch).map(|i| (i % 13) as f32 / 13.0).collect(),
    }
}

/// Real files to mutate: uncompressed 16-bit RGB in strips, deflate f32 RGB, deflate f32 RGBA.
fn seeds() -> &'static [Vec<u8>] {
    static SEEDS: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    SEEDS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let mut v = Vec::new();
        let mut c = std::io::Cursor::new(Vec::new());
        {
            let mut enc = tiff::encoder::TiffEncoder::new(&mut c).unwrap();
            let mut img = enc
                .new_image::<tiff::encoder::colortype::RGB16>(16, 12)
                .unwrap();
            img.rows_per_strip(4).unwrap();
            let data: Vec<u16> = (0..16 * 12 * 3).map(|i| (i * 911 % 65536) as u16).collect();
            img.write_data(&data).unwrap();
        }
        v.push(c.into_inner());
        for ch in [3, 4] {
            let p = dir.path().join(format!("f{ch}.tif"));
            crate::common::committed(true, |u| crate::common::write_tiff(&frame(9, 7, ch), &p, u))
                .unwrap();
            v.push(std::fs::read(&p).unwrap());
        }
        v
    })
}

/// Where the first directory is, so that half the edits land in it.
fn ifd_range(b: &[u8]) -> (usize, usize) {
    let off = u32::from_le_bytes(b[4..8].try_into().unwrap()) as usize;
    let n = u16::from_le_bytes([b[off], b[off + 1]]) as usize;
    (off, off + 2 + 12 * n + 4)
}

#[derive(Debug, Clone)]
enum Edit {
    Byte(usize, u8),
    Word(usize, u32),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = (bool, Edit)> {
    let interesting = prop_oneof![
        Just(0u32),
        Just(1),
        Just(2),
        Just(0xffff),
        Just(0x1_0000),
        Just(0x7fff_ffff),
        Just(0xffff_ffff),
        any::<u32>(),
    ];
    (
        any::<bool>(),
        prop_oneof![
            (any::<usize>(), any::<u8>()).prop_map(|(p, b)| Edit::Byte(p, b)),
            (any::<usize>(), interesting).prop_map(|(p, w)| Edit::Word(p, w)),
            any::<usize>().prop_map(Edit::Truncate),
        ],
    )
}

fn mutate(base: &[u8], edits: &[(bool, Edit)]) -> Vec<u8> {
    let mut b = base.to_vec();
    let (lo, hi) = ifd_range(base);
    for (in_ifd, e) in edits {
        let pick = |p: usize, len: usize| {
            if *in_ifd && hi <= len {
                lo + p % (hi - lo)
            } else {
                p % len.max(1)
            }
        };
        match *e {
            Edit::Byte(p, v) if !b.is_empty() => {
                let i = pick(p, b.len());
                b[i] = v;
            }
            Edit::Word(p, v) if b.len() >= 4 => {
                let i = pick(p, b.len() - 3).min(b.len() - 4);
                b[i..i + 4].copy_from_slice(&v.to_le_bytes());
            }
            // Rarely: most truncations just remove the directory.
            Edit::Truncate(p) if !b.is_empty() && p % 8 == 0 => b.truncate(p % b.len()),
            _ => {}
        }
    }
    b
}

proptest! {
    // 300 cases by default (about 2 s); NSRM_FUZZ_CASES=100000 for a long run.
    #![proptest_config(ProptestConfig { cases: fuzz_cases(300), ..ProptestConfig::default() })]

    #[test]
    fn mutated_tiffs_are_read_or_refused(
        seed in 0usize..3,
        edits in prop::collection::vec(edit(), 1..5),
    ) {
        let bytes = mutate(&seeds()[seed], &edits);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.tif");
        std::fs::write(&p, &bytes).unwrap();
        let opts = ReadOptions { limits: Limits { max_pixels: MAX_PIXELS }, ..Default::default() };
        if let Ok(d) = Decoded::read(&p, &opts) {
            let f = &d.frame;
            prop_assert_eq!(f.data.len(), f.width * f.height * 3);
            prop_assert!((f.width * f.height) as u64 <= MAX_PIXELS);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: fuzz_cases(2000), ..ProptestConfig::default() })]

    #[test]
    fn patch_specs_select_or_refuse(spec in "[A-Za-z0-9:,]{0,24}|[A-Z]{1,12}[0-9]{1,12}:[A-Z]{1,12}[0-9]{1,12}") {
        let labels: Vec<String> = ["A1", "A2", "B1", "B2", "C1", "x"].map(String::from).to_vec();
        let set = TrainingSet {
            labels: labels.clone(),
            rgb: vec![[0.5; 3]; labels.len()],
            xyz: vec![[50.0; 3]; labels.len()],
            white_xyz: nsrm::D65_WHITE_XYZ,
            white_rgb: None,
            provenance: Default::default(),
        };
        // A selection out of range would panic in `subset`; a kept one names only known patches.
        if let Ok(sel) = set.select(&spec) {
            prop_assert!(sel.labels.iter().all(|l| labels.contains(l)));
        }
    }

    #[test]
    fn whites_parse_or_refuse(spec in "[0-9.e,+-]{0,30}|\\PC{0,20}") {
        if let Ok(w) = parse_white(&spec) {
            prop_assert!(w.iter().all(|v| v.is_finite()) && w[1] > 0.0);
        }
    }
}
