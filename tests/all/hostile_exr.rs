//! Hostile and corrupt EXR files, crafted here byte by byte: a header that claims a huge frame
//! costs an error (never an abort), a damaged offset table is refused with the reason (never
//! turned into black rows), a small file cannot drive memory up, and a bad frame in a
//! `--continue-on-error` batch fails alone. Ends with a bounded fuzz over mutated real files.

use crate::common;

use nsrm_io::{Decoded, IoError, Limits, ReadOptions};
use proptest::prelude::*;
use std::path::Path;
use std::process::Command;

/// A single-part scanline EXR with float `B`, `G`, `R`, written by hand.
struct Craft {
    width: i32,
    height: i32,
    /// 0 none, 1 RLE, 2 ZIPS, 3 ZIP, 4 PIZ.
    compression: u8,
}

fn attr(out: &mut Vec<u8>, name: &str, kind: &str, value: &[u8]) {
    out.extend_from_slice(name.as_bytes());
    out.push(0);
    out.extend_from_slice(kind.as_bytes());
    out.push(0);
    out.extend_from_slice(&(value.len() as i32).to_le_bytes());
    out.extend_from_slice(value);
}

fn ints(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|i| i.to_le_bytes()).collect()
}

impl Craft {
    fn lines_per_chunk(&self) -> i32 {
        match self.compression {
            0..=2 => 1,
            3 => 16,
            _ => 32,
        }
    }

    fn chunks(&self) -> usize {
        (self.height as i64 + self.lines_per_chunk() as i64 - 1) as usize
            / self.lines_per_chunk() as usize
    }

    fn header(&self) -> Vec<u8> {
        let mut h = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        let mut ch = Vec::new();
        for name in ["B", "G", "R"] {
            ch.extend_from_slice(name.as_bytes());
            ch.push(0);
            ch.extend_from_slice(&ints(&[2])); // float
            ch.extend_from_slice(&[0, 0, 0, 0]);
            ch.extend_from_slice(&ints(&[1, 1]));
        }
        ch.push(0);
        attr(&mut h, "channels", "chlist", &ch);
        attr(&mut h, "compression", "compression", &[self.compression]);
        let window = ints(&[0, 0, self.width - 1, self.height - 1]);
        attr(&mut h, "dataWindow", "box2i", &window);
        attr(&mut h, "displayWindow", "box2i", &window);
        attr(&mut h, "lineOrder", "lineOrder", &[0]);
        attr(&mut h, "pixelAspectRatio", "float", &1f32.to_le_bytes());
        attr(&mut h, "screenWindowCenter", "v2f", &[0; 8]);
        attr(&mut h, "screenWindowWidth", "float", &1f32.to_le_bytes());
        h.push(0);
        h
    }

    /// The whole file: header, offset table (`offsets(i, natural offset)` may lie), chunks
    /// holding `data(i)`.
    fn file(
        &self,
        data: impl Fn(usize) -> Vec<u8>,
        offsets: impl Fn(usize, u64) -> u64,
    ) -> Vec<u8> {
        let mut f = self.header();
        let n = self.chunks();
        let table_at = f.len();
        f.resize(table_at + 8 * n, 0);
        let mut natural = Vec::new();
        for i in 0..n {
            natural.push(f.len() as u64);
            let d = data(i);
            f.extend_from_slice(&ints(&[i as i32 * self.lines_per_chunk(), d.len() as i32]));
            f.extend_from_slice(&d);
        }
        for i in 0..n {
            let off = offsets(i, natural[i]);
            f[table_at + 8 * i..table_at + 8 * i + 8].copy_from_slice(&off.to_le_bytes());
        }
        f
    }

    /// An uncompressed line: B, G, R samples of value `v`.
    fn line(&self, v: f32) -> Vec<u8> {
        (0..3 * self.width).flat_map(|_| v.to_le_bytes()).collect()
    }
}

fn read(path: &Path) -> Result<Decoded, IoError> {
    Decoded::read(path, &ReadOptions::default())
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn a_crafted_file_reads_back() {
    let dir = tempfile::tempdir().unwrap();
    let c = Craft {
        width: 8,
        height: 4,
        compression: 0,
    };
    let p = write(
        dir.path(),
        "ok.exr",
        &c.file(|i| c.line(i as f32), |_, off| off),
    );
    let d = read(&p).unwrap();
    assert_eq!((d.frame.width, d.frame.height), (8, 4));
    for (y, row) in d.frame.data.chunks(3 * 8).enumerate() {
        assert!(row.iter().all(|&v| v == y as f32));
    }
}

#[test]
fn a_huge_header_costs_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let c = Craft {
        width: 100_000,
        height: 100_000,
        compression: 3,
    };
    let mut bytes = c.header();
    bytes.resize(bytes.len() + 64, 0);
    assert!(bytes.len() < 500);
    let p = write(dir.path(), "huge.exr", &bytes);
    let e = read(&p).unwrap_err();
    assert!(matches!(e, IoError::OverLimit { .. }), "{e}");
    assert!(e.to_string().contains("limit of 268435456 pixels"), "{e}");
    assert_eq!(
        e.concern(),
        Some(nsrm_io::Concern::Remedy(nsrm_io::Param::MaxPixels))
    );
    // Even with no pixel limit, the file is too small for its own offset table.
    let opts = ReadOptions {
        limits: Limits {
            max_pixels: u64::MAX,
        },
        ..Default::default()
    };
    let e = Decoded::read(&p, &opts).unwrap_err();
    assert!(matches!(e, IoError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("offset tables need"), "{e}");
    // Uncompressed samples must fit in the file.
    let c = Craft {
        width: 4000,
        height: 4000,
        compression: 0,
    };
    let p = write(dir.path(), "raw.exr", &c.header());
    let e = read(&p).unwrap_err();
    assert!(matches!(e, IoError::TooLarge { .. }), "{e}");
    assert!(e.to_string().contains("holds only"), "{e}");
}

#[test]
fn a_damaged_offset_table_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let c = Craft {
        width: 8,
        height: 4,
        compression: 0,
    };
    let good = c.file(|i| c.line(i as f32), |_, off| off);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "two lines at one chunk",
            c.file(
                |i| c.line(i as f32),
                |i, off| if i == 2 { off - 8 - 96 } else { off },
            ),
            "expected line 2",
        ),
        (
            "a missing chunk",
            c.file(|i| c.line(i as f32), |i, off| if i == 1 { 0 } else { off }),
            "missing",
        ),
        (
            "a chunk past the end",
            c.file(
                |i| c.line(i as f32),
                |i, off| if i == 3 { off + 10_000 } else { off },
            ),
            "past the end",
        ),
        (
            "a truncated last chunk",
            good[..good.len() - 5].to_vec(),
            "past the end",
        ),
        (
            "a short chunk",
            c.file(
                |i| {
                    if i == 0 {
                        c.line(0.0)[..40].to_vec()
                    } else {
                        c.line(1.0)
                    }
                },
                |_, off| off,
            ),
            "cannot hold",
        ),
        (
            "an offset into the table",
            c.file(
                |i| c.line(i as f32),
                |i, off| if i == 0 { off - 16 } else { off },
            ),
            "outside the chunk data",
        ),
    ];
    for (what, bytes, why) in cases {
        let p = write(dir.path(), "bad.exr", &bytes);
        let e = read(&p).unwrap_err();
        assert!(matches!(e, IoError::Corrupt { .. }), "{what}: {e}");
        assert!(e.to_string().contains(why), "{what}: {e}");
        assert!(e.to_string().contains("bad.exr"), "{what}: {e}");
    }
}

#[test]
fn a_small_zip_file_cannot_claim_a_big_frame() {
    // 8192 × 8192 (under the default pixel limit) in ZIP chunks of 12 bytes each: no deflate
    // stream that short decodes to a 1.5 MB block.
    let dir = tempfile::tempdir().unwrap();
    let c = Craft {
        width: 8192,
        height: 8192,
        compression: 3,
    };
    let bytes = c.file(
        |_| vec![0x78, 0x9c, 3, 0, 0, 0, 0, 1, 0, 0, 0, 0],
        |_, off| off,
    );
    assert!(bytes.len() < 234_000, "{}", bytes.len());
    let p = write(dir.path(), "bomb.exr", &bytes);
    let e = read(&p).unwrap_err();
    assert!(matches!(e, IoError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("cannot hold a block"), "{e}");
}

/// `nsrm apply` under a 2 GiB address-space limit: the small hostile files fail alone with their
/// reason, the good frame beside them is converted, exit status 1, no abort.
#[cfg(target_os = "linux")]
#[test]
fn a_batch_survives_hostile_frames_within_2_gib() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nsrm = env!("CARGO_BIN_EXE_nsrm");
    let model = d.join("lrm.json");
    let out = common::nsrm()
        .args(["fit", "--model", "lrm", "-o"])
        .arg(&model)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let ok = Craft {
        width: 16,
        height: 8,
        compression: 0,
    };
    write(d, "a_good.exr", &ok.file(|_| ok.line(0.5), |_, off| off));
    let huge = Craft {
        width: 100_000,
        height: 100_000,
        compression: 3,
    };
    write(d, "b_huge.exr", &huge.header());
    let bomb = Craft {
        width: 16_000,
        height: 16_000,
        compression: 3,
    };
    write(
        d,
        "c_bomb.exr",
        &bomb.file(|_| vec![0x78, 0x9c, 3, 0, 0, 0, 0, 1], |_, off| off),
    );
    write(
        d,
        "d_dup.exr",
        &ok.file(
            |_| ok.line(0.5),
            |i, off| if i == 5 { off - 8 - 192 } else { off },
        ),
    );
    let script = format!(
        "ulimit -v 2097152 && exec '{nsrm}' apply --device cpu --continue-on-error --model '{}' \
         -o '{}' '{}' '{}' '{}' '{}'",
        model.display(),
        d.join("out").display(),
        d.join("a_good.exr").display(),
        d.join("b_huge.exr").display(),
        d.join("c_bomb.exr").display(),
        d.join("d_dup.exr").display(),
    );
    let out = Command::new("sh").args(["-c", &script]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(d.join("out/a_good_xyz.exr").exists(), "{err}");
    for (name, why) in [
        ("b_huge.exr", "--max-pixels"),
        ("c_bomb.exr", "cannot hold a block"),
        ("d_dup.exr", "expected line 5"),
    ] {
        assert!(
            err.lines().any(|l| l.contains(name) && l.contains(why)),
            "{name}: {err}"
        );
    }
}

/// Small real files in every layout the reader has: the fuzz mutates these.
fn seeds() -> &'static [Vec<u8>] {
    static SEEDS: std::sync::OnceLock<Vec<Vec<u8>>> = std::sync::OnceLock::new();
    SEEDS.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        make_seeds(dir.path())
    })
}

fn make_seeds(dir: &Path) -> Vec<Vec<u8>> {
    use exr::prelude::*;
    let mut out = Vec::new();
    let (w, h) = (13, 35);
    let px = |x: usize, y: usize| (x as f32 * 0.1, y as f32 * 0.01, (x * y) as f32 * 0.001);
    for (k, (c, blocks)) in [
        (Compression::ZIP16, Blocks::ScanLines),
        (Compression::ZIP1, Blocks::ScanLines),
        (Compression::RLE, Blocks::ScanLines),
        (Compression::PIZ, Blocks::ScanLines),
        (Compression::Uncompressed, Blocks::ScanLines),
        (Compression::ZIP16, Blocks::Tiles(Vec2(8, 8))),
    ]
    .into_iter()
    .enumerate()
    {
        let p = dir.join(format!("seed{k}.exr"));
        let layer = Layer::new(
            Vec2(w, h),
            LayerAttributes::named("main"),
            Encoding {
                compression: c,
                blocks,
                line_order: LineOrder::Increasing,
            },
            SpecificChannels::rgb(|Vec2(x, y)| px(x, y)),
        );
        Image::from_layer(layer).write().to_file(&p).unwrap();
        out.push(std::fs::read(&p).unwrap());
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 192, failure_persistence: None, ..ProptestConfig::default() })]

    /// Mutated and truncated real files: the reader returns a value or an error, never panics
    /// or aborts, and what it returns has the size its header claims.
    #[test]
    fn mutated_files_fail_cleanly(
        which in 0usize..6,
        edits in proptest::collection::vec((any::<u32>(), any::<u8>()), 1..8),
        cut in proptest::option::weighted(0.2, any::<u32>()),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let mut bytes = seeds()[which].clone();
        for (at, v) in edits {
            let i = at as usize % bytes.len();
            bytes[i] = v;
        }
        if let Some(c) = cut {
            bytes.truncate(c as usize % bytes.len());
        }
        let p = write(dir.path(), "m.exr", &bytes);
        if let Ok(d) = read(&p) {
            prop_assert_eq!(d.frame.data.len(), 3 * d.frame.width * d.frame.height);
        }
    }
}
