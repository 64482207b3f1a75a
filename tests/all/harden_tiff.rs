//! Families 2 and 3 for TIFF: a hostile header costs an error, not the process, and a corrupt
//! file is never converted into made-up pixels. The files are crafted here from a valid TIFF
//! by rewriting its directory entries.

use crate::common;
use common::*;
use nsrm_io::{Decoded, Limits, ReadOptions};
use std::path::Path;

/// A valid uncompressed 16-bit RGB TIFF of `w`×`h`, 8 rows per strip.
pub fn tiff16(w: u32, h: u32) -> Vec<u8> {
    let mut c = std::io::Cursor::new(Vec::new());
    let data: Vec<u16> = (0..w * h * 3).map(|i| (i * 37 % 65536) as u16).collect();
    let mut enc = tiff::encoder::TiffEncoder::new(&mut c).unwrap();
    let mut img = enc
        .new_image::<tiff::encoder::colortype::RGB16>(w, h)
        .unwrap();
    img.rows_per_strip(8).unwrap();
    img.write_data(&data).unwrap();
    c.into_inner()
}

fn u16_at(b: &[u8], i: usize) -> u16 {
    u16::from_le_bytes([b[i], b[i + 1]])
}
fn u32_at(b: &[u8], i: usize) -> u32 {
    u32::from_le_bytes(b[i..i + 4].try_into().unwrap())
}

/// The byte position of directory entry `tag` (little-endian classic TIFF), and its type and
/// count.
fn entry(b: &[u8], tag: u16) -> Option<(usize, u16, u32)> {
    assert_eq!(&b[..4], b"II*\0");
    let ifd = u32_at(b, 4) as usize;
    let n = u16_at(b, ifd) as usize;
    (0..n)
        .map(|k| ifd + 2 + 12 * k)
        .find(|&e| u16_at(b, e) == tag)
        .map(|e| (e, u16_at(b, e + 2), u32_at(b, e + 4)))
}

/// Sets a one-value SHORT or LONG entry.
fn set(b: &mut [u8], tag: u16, v: u32) {
    let (e, ty, _) = entry(b, tag).unwrap_or_else(|| panic!("no tag {tag}"));
    match ty {
        3 => b[e + 8..e + 10].copy_from_slice(&(v as u16).to_le_bytes()),
        4 => b[e + 8..e + 12].copy_from_slice(&v.to_le_bytes()),
        t => panic!("type {t}"),
    }
}

/// The values of a SHORT/LONG array entry, and a setter.
fn values(b: &[u8], tag: u16) -> Vec<u32> {
    let (e, ty, n) = entry(b, tag).unwrap();
    let size = if ty == 3 { 2 } else { 4 };
    let at = if n as usize * size <= 4 {
        e + 8
    } else {
        u32_at(b, e + 8) as usize
    };
    (0..n as usize)
        .map(|k| {
            if ty == 3 {
                u16_at(b, at + 2 * k) as u32
            } else {
                u32_at(b, at + 4 * k)
            }
        })
        .collect()
}

fn set_values(b: &mut [u8], tag: u16, v: &[u32]) {
    let (e, ty, n) = entry(b, tag).unwrap();
    assert_eq!(v.len(), n as usize);
    let size = if ty == 3 { 2 } else { 4 };
    let at = if n as usize * size <= 4 {
        e + 8
    } else {
        u32_at(b, e + 8) as usize
    };
    for (k, x) in v.iter().enumerate() {
        if ty == 3 {
            b[at + 2 * k..at + 2 * k + 2].copy_from_slice(&(*x as u16).to_le_bytes());
        } else {
            b[at + 4 * k..at + 4 * k + 4].copy_from_slice(&x.to_le_bytes());
        }
    }
}

const WIDTH: u16 = 256;
const HEIGHT: u16 = 257;
const BITS: u16 = 258;
const ROWS_PER_STRIP: u16 = 278;
const STRIP_OFFSETS: u16 = 273;
const STRIP_BYTES: u16 = 279;

fn read(bytes: &[u8], limits: Limits) -> Result<Decoded, String> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.tif");
    std::fs::write(&p, bytes).unwrap();
    Decoded::read(
        &p,
        &ReadOptions {
            limits,
            ..Default::default()
        },
    )
    .map_err(|e| e.to_string())
}

#[test]
fn the_crafted_base_file_is_valid_and_has_several_strips() {
    let b = tiff16(64, 64);
    assert!(values(&b, STRIP_OFFSETS).len() > 2);
    let d = read(&b, Limits::default()).unwrap();
    assert_eq!((d.frame.width, d.frame.height), (64, 64));
}

#[test]
fn huge_headers_are_refused_before_allocating() {
    let mut b = tiff16(8, 8);
    set(&mut b, WIDTH, 100_000);
    set(&mut b, HEIGHT, 100_000);
    set(&mut b, ROWS_PER_STRIP, 100_000);
    let e = read(&b, Limits::default()).unwrap_err();
    assert!(
        e.contains("100000×100000") && e.contains("limit of 268435456 pixels"),
        "{e}"
    );
    // Within --max-pixels but more than the (uncompressed) file holds.
    let mut b = tiff16(8, 8);
    set(&mut b, WIDTH, 4000);
    set(&mut b, HEIGHT, 4000);
    set(&mut b, ROWS_PER_STRIP, 4000);
    let e = read(&b, Limits::default()).unwrap_err();
    assert!(e.contains("but the file holds only"), "{e}");
    // A lower --max-pixels refuses a valid frame, naming the limit.
    let e = read(&tiff16(8, 8), Limits { max_pixels: 63 }).unwrap_err();
    assert!(e.contains("more than the limit of 63"), "{e}");
    read(&tiff16(8, 8), Limits { max_pixels: 64 }).unwrap();
}

#[test]
fn strips_must_each_be_present_once_inside_the_file() {
    let b = tiff16(64, 64);
    let offsets = values(&b, STRIP_OFFSETS);
    // Several strips pointing at one chunk.
    let mut dup = b.clone();
    let same = vec![offsets[0]; offsets.len()];
    set_values(&mut dup, STRIP_OFFSETS, &same);
    let e = read(&dup, Limits::default()).unwrap_err();
    assert!(
        e.contains("corrupt") && e.contains("point at the same bytes"),
        "{e}"
    );
    // A strip past the end of the file.
    let mut past = b.clone();
    let mut o = offsets.clone();
    *o.last_mut().unwrap() = b.len() as u32 + 10;
    set_values(&mut past, STRIP_OFFSETS, &o);
    let e = read(&past, Limits::default()).unwrap_err();
    assert!(e.contains("past the end"), "{e}");
    // A truncated file: the last strips are missing.
    let cut = &b[..offsets[offsets.len() - 1] as usize + 3];
    // (Its directory may be after the data: keep the file when it is still parseable.)
    if let Err(e) = read(cut, Limits::default()) {
        assert!(!e.is_empty());
    } else {
        panic!("a truncated file was accepted");
    }
    // Fewer strips listed than the image needs (rows per strip claims more strips).
    let mut few = b.clone();
    let rows = values(&b, ROWS_PER_STRIP)[0];
    set(&mut few, ROWS_PER_STRIP, rows / 2);
    let e = read(&few, Limits::default()).unwrap_err();
    // (The tiff crate itself refuses this table; either reason is fine.)
    assert!(
        (e.contains("needs") && e.contains("strips")) || e.contains("inconsistent sizes"),
        "{e}"
    );
    // More strips listed than the image needs.
    let mut many = b.clone();
    set(&mut many, ROWS_PER_STRIP, rows * 2);
    let e = read(&many, Limits::default()).unwrap_err();
    assert!(
        (e.contains("needs") && e.contains("strips")) || e.contains("inconsistent sizes"),
        "{e}"
    );
    // An empty strip.
    let mut empty = b.clone();
    let mut n = values(&b, STRIP_BYTES);
    n[1] = 0;
    set_values(&mut empty, STRIP_BYTES, &n);
    let e = read(&empty, Limits::default()).unwrap_err();
    assert!(e.contains("empty"), "{e}");
}

#[test]
fn sample_sizes_are_named_as_bits() {
    let mut b = tiff16(8, 8);
    set_values(&mut b, BITS, &[7, 7, 7]);
    let e = read(&b, Limits::default()).unwrap_err();
    assert!(e.contains("7 bits per sample"), "{e}");
    assert!(!e.contains("samples per pixel"), "{e}");
}

#[test]
fn a_bad_tiff_fails_alone_in_a_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    model(d);
    std::fs::create_dir(d.join("in")).unwrap();
    std::fs::write(d.join("in/a_good.tif"), tiff16(16, 16)).unwrap();
    let mut b = tiff16(8, 8);
    set(&mut b, WIDTH, 100_000);
    set(&mut b, HEIGHT, 100_000);
    std::fs::write(d.join("in/b_huge.tif"), &b).unwrap();
    let mut b = tiff16(64, 64);
    let o = values(&b, STRIP_OFFSETS);
    set_values(&mut b, STRIP_OFFSETS, &vec![o[0]; o.len()]);
    std::fs::write(d.join("in/c_dup.tif"), &b).unwrap();
    std::fs::write(d.join("in/d_good.tif"), tiff16(16, 16)).unwrap();
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
            "out",
            "in",
        ],
    );
    no_crash(&o, "batch");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("2 converted") && err.contains("2 failed"),
        "{err}"
    );
    assert!(
        err.contains("b_huge.tif") && err.contains("c_dup.tif"),
        "{err}"
    );
    assert_eq!(names(&d.join("out")), ["a_good_xyz.exr", "d_good_xyz.exr"]);
    assert!(!Path::new(&d.join("out/b_huge_xyz.exr")).exists());
}

/// Writes the TIFF layouts of issue 19 families 4 and 5 with tifffile (a writer nobody here
/// wrote), each beside the samples nsrm must read from it (`NAME.bin`: little-endian f32, RGB or
/// RGBA interleaved, 16-bit values divided by 65535).
const PY_LAYOUTS: &str = r#"
import sys, numpy as np, tifffile
d = sys.argv[1]
rng = np.random.default_rng(19)
def save(name, arr, want, **kw):
    if kw.get("planarconfig") == "separate":
        arr = np.moveaxis(arr, 2, 0)  # samples first
    tifffile.imwrite(f"{d}/{name}.tif", arr, photometric="rgb", **kw)
    np.ascontiguousarray(want, dtype="<f4").tofile(f"{d}/{name}.bin")
a = rng.random((18, 20, 3)).astype("float32")
# Planar-separate, tiled, 20x18 with 16x16 tiles: partial edge tiles (the tiff crate asserted).
save("planar_tiled", a, a, planarconfig="separate", tile=(16, 16))
save("planar_tiled_even", np.tile(a, (2, 2, 1))[:32, :32], np.tile(a, (2, 2, 1))[:32, :32], planarconfig="separate", tile=(16, 16))
save("planar_strips", a, a, planarconfig="separate", rowsperstrip=5)
save("chunky_tiled", a, a, tile=(16, 16))
# RGB + an unspecified extra sample: RGB read, the extra sample ignored.
b = rng.random((18, 20, 4)).astype("float32")
save("rgb_extra", b, b[..., :3], extrasamples=[0])
# RGB + alpha + an unspecified sample, chunky and planar: RGBA read.
c = rng.random((18, 20, 5)).astype("float32")
save("rgba_extra", c, c[..., :4], extrasamples=[2, 0])
save("rgba_extra_planar", c, c[..., :4], extrasamples=[2, 0], planarconfig="separate", tile=(16, 16))
u = (rng.random((18, 20, 4)) * 65535).astype("uint16")
save("rgb16_extra", u, u[..., :3].astype("float32") / np.float32(65535), extrasamples=[0])
save("rgb16_planar_tiled", u[..., :3], u[..., :3].astype("float32") / np.float32(65535), planarconfig="separate", tile=(16, 16))
"#;

/// Families 4 and 5: a planar-separate tiled float TIFF with partial edge tiles (which made the
/// tiff crate panic, exit 101, ending a whole `apply --continue-on-error` batch) and RGB +
/// extra-sample TIFFs (called "corrupt" with a wrong sample count) are read, sample for sample,
/// and converted in a batch.
#[test]
fn tifffile_layouts_are_read_sample_for_sample() {
    let present = std::process::Command::new("python3")
        .args(["-c", "import tifffile, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !present {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "python3 with tifffile and numpy is required under CI (.ci/install.d/40-tifffile.sh)"
        );
        println!("SKIP: python3 with tifffile and numpy not found (.ci/install.d/40-tifffile.sh)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("in")).unwrap();
    let py = std::process::Command::new("python3")
        .args(["-c", PY_LAYOUTS])
        .arg(d.join("in"))
        .output()
        .unwrap();
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );
    let names = [
        ("planar_tiled", 3),
        ("planar_tiled_even", 3),
        ("planar_strips", 3),
        ("chunky_tiled", 3),
        ("rgb_extra", 3),
        ("rgba_extra", 4),
        ("rgba_extra_planar", 4),
        ("rgb16_extra", 3),
        ("rgb16_planar_tiled", 3),
    ];
    for (name, channels) in names {
        let path = d.join(format!("in/{name}.tif"));
        let want: Vec<f32> = std::fs::read(d.join(format!("in/{name}.bin")))
            .unwrap()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        std::fs::remove_file(d.join(format!("in/{name}.bin"))).unwrap();
        let f = crate::common::read_frame(&path, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(f.layout.channels(), channels, "{name}");
        assert_eq!(f.data.len(), want.len(), "{name}");
        let bad: Vec<(usize, usize, usize)> = f
            .data
            .iter()
            .zip(&want)
            .enumerate()
            .filter(|(_, (a, b))| a != b)
            .map(|(i, _)| {
                (
                    (i / channels) % f.width,
                    i / channels / f.width,
                    i % channels,
                )
            })
            .collect();
        assert!(
            bad.is_empty(),
            "{name}: {} samples differ, (x, y, channel) {:?}",
            bad.len(),
            &bad[..bad.len().min(12)]
        );
    }
    // In a batch, with --continue-on-error: every file converted, nothing fails.
    model(d);
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
            "out",
            "in",
        ],
    );
    no_crash(&o, "batch");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(&format!("{} converted", names.len())),
        "{}",
        stderr(&o)
    );
}

/// A little-endian TIFF of `w`×`h` RGB 32-bit float samples, planar-separate (one plane per
/// channel) and tiled `tile`×`tile`, uncompressed: sample `(x, y, c)` is `c + (y·w + x) / 1024`.
/// Each tile is stored whole (edge tiles padded with zeros), planes one after the other, as
/// TIFF 6.0 (section 15) and libtiff write them. The layout of `docs/upstream/tiff-planar-tiled-edge.md`.
pub fn planar_tiled_f32(w: u32, h: u32, tile: u32) -> Vec<u8> {
    let (across, down) = (w.div_ceil(tile), h.div_ceil(tile));
    let tiles = 3 * across * down;
    let tile_bytes = tile * tile * 4;
    // Header, then the IFD (12 entries), then its arrays, then the tiles.
    let entries: u32 = 12;
    let ifd = 8u32;
    let arrays = ifd + 2 + 12 * entries + 4;
    let (bits_at, format_at) = (arrays, arrays + 6);
    let (offsets_at, counts_at) = (arrays + 12, arrays + 12 + 4 * tiles);
    let data_at = counts_at + 4 * tiles;
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&ifd.to_le_bytes());
    b.extend_from_slice(&(entries as u16).to_le_bytes());
    let mut entry = |tag: u16, typ: u16, count: u32, value: u32| {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&typ.to_le_bytes());
        b.extend_from_slice(&count.to_le_bytes());
        b.extend_from_slice(&value.to_le_bytes());
    };
    entry(256, 4, 1, w); // ImageWidth
    entry(257, 4, 1, h); // ImageLength
    entry(258, 3, 3, bits_at); // BitsPerSample 32, 32, 32
    entry(259, 3, 1, 1); // Compression: none
    entry(262, 3, 1, 2); // PhotometricInterpretation: RGB
    entry(277, 3, 1, 3); // SamplesPerPixel
    entry(284, 3, 1, 2); // PlanarConfiguration: separate
    entry(322, 4, 1, tile); // TileWidth
    entry(323, 4, 1, tile); // TileLength
    entry(324, 4, tiles, offsets_at); // TileOffsets
    entry(325, 4, tiles, counts_at); // TileByteCounts
    entry(339, 3, 3, format_at); // SampleFormat: float, float, float
    b.extend_from_slice(&0u32.to_le_bytes()); // no next IFD
    for _ in 0..3 {
        b.extend_from_slice(&32u16.to_le_bytes());
    }
    for _ in 0..3 {
        b.extend_from_slice(&3u16.to_le_bytes());
    }
    for t in 0..tiles {
        b.extend_from_slice(&(data_at + t * tile_bytes).to_le_bytes());
    }
    for _ in 0..tiles {
        b.extend_from_slice(&tile_bytes.to_le_bytes());
    }
    assert_eq!(b.len() as u32, data_at);
    for c in 0..3 {
        for ty in 0..down {
            for tx in 0..across {
                for y in ty * tile..(ty + 1) * tile {
                    for x in tx * tile..(tx + 1) * tile {
                        let v = if x < w && y < h {
                            c as f32 + (y * w + x) as f32 / 1024.0
                        } else {
                            0.0
                        };
                        b.extend_from_slice(&v.to_le_bytes());
                    }
                }
            }
        }
    }
    b
}

/// The upstream report `docs/upstream/tiff-planar-tiled-edge.md`: the tiff crate's whole-image
/// read panics (an `assert!`, not an error) on a planar-separate tiled float TIFF whose edge
/// tiles are partial. Reproduced on the crate alone, contained by `catch_unwind` as
/// `Decoded::read` contains every decoder panic; nsrm reads the same bytes chunk by chunk,
/// sample for sample. When this fails because the crate no longer panics, the report is
/// resolved and the chunk-by-chunk path of `crates/nsrm-io/src/tif.rs` may serve only extra samples.
#[test]
fn the_tiff_crates_planar_edge_tile_panic_is_reproduced_and_contained() {
    let (w, h) = (20u32, 18u32);
    let bytes = planar_tiled_f32(w, h, 16);
    let whole_image = std::panic::catch_unwind(|| {
        let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes.clone())).unwrap();
        let mut all_planes = tiff::decoder::DecodingResult::F32(Vec::new());
        dec.read_image_to_buffer(&mut all_planes).map(|_| ())
    });
    let message = match whole_image {
        Err(payload) => payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_default(),
        Ok(result) => panic!(
            "the tiff crate's whole-image read no longer panics here ({result:?}): the upstream \
             report is resolved (update docs/upstream/tiff-planar-tiled-edge.md)"
        ),
    };
    assert!(
        message.contains("assertion failed: buf.len() >= layout.row_stride"),
        "{message}"
    );
    // The cause: for planes after the first, the crate sizes bottom-edge tiles as whole (its
    // padding ignores the plane), where plane 0's are cut to the image.
    let dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes.clone())).unwrap();
    assert_eq!(
        dec.chunk_data_dimensions(2),
        (16, 2),
        "plane 0, bottom-left tile"
    );
    assert_eq!(
        dec.chunk_data_dimensions(3),
        (4, 2),
        "plane 0, bottom-right tile"
    );
    assert_eq!(
        dec.chunk_data_dimensions(6),
        (16, 16),
        "plane 1, bottom-left tile"
    );
    assert_eq!(
        dec.chunk_data_dimensions(7),
        (4, 16),
        "plane 1, bottom-right tile"
    );
    let f = read(&bytes, Limits::default()).unwrap().frame;
    assert_eq!((f.width, f.height, f.layout.channels()), (20, 18, 3));
    for (i, px) in f.data.chunks_exact(3).enumerate() {
        for (c, &v) in px.iter().enumerate() {
            assert_eq!(v, c as f32 + i as f32 / 1024.0, "pixel {i} channel {c}");
        }
    }
    // The even layout (no partial tile), which the crate reads whole (plane after plane),
    // agrees with nsrm.
    let even = planar_tiled_f32(32, 32, 16);
    let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(even.clone())).unwrap();
    let mut planes = tiff::decoder::DecodingResult::F32(Vec::new());
    dec.read_image_to_buffer(&mut planes).unwrap();
    let tiff::decoder::DecodingResult::F32(planes) = planes else {
        panic!("not f32");
    };
    let ours = read(&even, Limits::default()).unwrap().frame.data;
    assert_eq!(planes.len(), ours.len());
    for (i, px) in ours.chunks_exact(3).enumerate() {
        for (c, &v) in px.iter().enumerate() {
            assert_eq!(v, planes[c * 32 * 32 + i], "pixel {i} channel {c}");
        }
    }
}
