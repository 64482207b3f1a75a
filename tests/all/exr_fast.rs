//! The chunk-level EXR path (single-part scanline files): pixels bit for bit against the `exr`
//! crate's own whole-image reader, pass-through channels and attributes unchanged, every output
//! compression, and outputs read back by OpenEXR itself (Python bindings and `oiiotool`; skipped
//! with a printed reason only outside `CI=true`).

use crate::common;
use crate::common::WriteStaged;
use exr::compression::Compression;
use exr::image::Levels;
use exr::image::{AnyChannel, AnyChannels, AnyImage, Blocks, Encoding, FlatSamples, Image, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, IntegerBounds, LineOrder, Text};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::{f16, SmallVec, WritableImage};
use nsrm::OutputSpace;
use nsrm_io::{Decoded, ExrCompression, FileFormat, ReadOptions, WriteOptions};
use std::path::Path;
use std::process::Command;

const W: usize = 37;
const H: usize = 45;

/// Deterministic noisy floats, some negative, some large.
fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (s >> 40) as f32 / (1u64 << 24) as f32;
            (u - 0.1) * if s & 0xff == 0 { 1000.0 } else { 1.0 }
        })
        .collect()
}

fn chan(name: &str, s: FlatSamples) -> AnyChannel<Levels<FlatSamples>> {
    AnyChannel::new(name, Levels::Singular(s))
}

/// A scanline plate: R, G, B float (or half), A half, Z uint, N.x half; data window at (5, -3);
/// custom attributes.
fn plate(compression: Compression, rgb_half: bool) -> AnyImage {
    let n = W * H;
    let rgb = |seed| {
        let v = noise(n, seed);
        if rgb_half {
            FlatSamples::F16(v.into_iter().map(f16::from_f32).collect())
        } else {
            FlatSamples::F32(v)
        }
    };
    let channels = vec![
        chan("R", rgb(1)),
        chan("G", rgb(2)),
        chan("B", rgb(3)),
        chan(
            "A",
            FlatSamples::F16(noise(n, 4).into_iter().map(f16::from_f32).collect()),
        ),
        chan(
            "Z",
            FlatSamples::U32((0..n as u32).map(|i| i * 7919).collect()),
        ),
        chan(
            "N.x",
            FlatSamples::F16(noise(n, 5).into_iter().map(f16::from_f32).collect()),
        ),
    ];
    let mut attrs = LayerAttributes {
        layer_position: Vec2(5, -3),
        owner: Some(Text::from("nsrm tests")),
        ..Default::default()
    };
    attrs.other.insert(
        Text::from("cameraSerial"),
        AttributeValue::Text(Text::from("XK-1138")),
    );
    attrs
        .other
        .insert(Text::from("exposureIndex"), AttributeValue::F32(800.0));
    let layer = Layer::new(
        Vec2(W, H),
        attrs,
        Encoding {
            compression,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    let bounds = IntegerBounds::new(Vec2(5, -3), Vec2(W, H));
    Image::from_layers(
        ImageAttributes::new(bounds),
        SmallVec::from_vec(vec![layer]),
    )
}

fn samples<'a>(img: &'a AnyImage, name: &str) -> &'a FlatSamples {
    &img.layer_data[0]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.eq(name))
        .unwrap_or_else(|| panic!("no channel {name}"))
        .sample_data
        .levels_as_slice()[0]
}

fn as_f32(s: &FlatSamples) -> Vec<f32> {
    match s {
        FlatSamples::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        FlatSamples::F32(v) => v.clone(),
        FlatSamples::U32(v) => v.iter().map(|&u| u as f32).collect(),
    }
}

fn bits(s: &FlatSamples) -> Vec<u32> {
    match s {
        FlatSamples::F16(v) => v.iter().map(|h| u32::from(h.to_bits())).collect(),
        FlatSamples::F32(v) => v.iter().map(|f| f.to_bits()).collect(),
        FlatSamples::U32(v) => v.clone(),
    }
}

fn read_all(path: &Path) -> AnyImage {
    exr::prelude::read_all_data_from_file(path).unwrap()
}

fn opts(compression: ExrCompression, half: bool) -> WriteOptions {
    WriteOptions {
        format: FileFormat::Exr,
        half,
        compression,
        space: OutputSpace::Acescg,
        ..Default::default()
    }
}

const INPUTS: [Compression; 5] = [
    Compression::Uncompressed,
    Compression::RLE,
    Compression::ZIP1,
    Compression::ZIP16,
    Compression::PIZ,
];

#[test]
fn fast_path_reads_what_the_exr_crate_reads_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for c in INPUTS {
        for half in [false, true] {
            let src = dir.path().join(format!("in-{c}-{half}.exr"));
            plate(c, half).write().to_file(&src).unwrap();
            let want = read_all(&src);
            let d = Decoded::read(&src, &ReadOptions::default()).unwrap();
            assert_eq!((d.frame.width, d.frame.height), (W, H));
            for (ci, name) in ["R", "G", "B"].into_iter().enumerate() {
                let w = as_f32(samples(&want, name));
                let got: Vec<f32> = d.frame.data.iter().skip(ci).step_by(3).copied().collect();
                assert!(
                    w.iter().zip(&got).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{c} half={half} channel {name}"
                );
            }
            // A, N.x and Z pass through: the next test writes them back and compares.
        }
    }
}

#[test]
fn fast_path_writes_every_compression_with_pass_through_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let outs = [
        (ExrCompression::Keep, None),
        (ExrCompression::None, Some(Compression::Uncompressed)),
        (ExrCompression::Rle, Some(Compression::RLE)),
        (ExrCompression::Zips, Some(Compression::ZIP1)),
        (ExrCompression::Zip, Some(Compression::ZIP16)),
        (ExrCompression::Piz, Some(Compression::PIZ)),
    ];
    for c in [
        Compression::ZIP16,
        Compression::PIZ,
        Compression::Uncompressed,
    ] {
        let src = dir.path().join(format!("in-{c}.exr"));
        let input = plate(c, false);
        input.write().to_file(&src).unwrap();
        for (k, &(out_c, expect)) in outs.iter().enumerate() {
            for half in [false, true] {
                let mut d = Decoded::read(&src, &ReadOptions::default()).unwrap();
                // A "correction": scale, so that output differs from input.
                d.frame.data.iter_mut().for_each(|v| *v *= 0.5);
                let frame = d.frame.clone();
                let dest = dir.path().join(format!("out-{c}-{k}-{half}.exr"));
                common::committed(false, |u| d.write(&dest, &opts(out_c, half), u)).unwrap();
                let got = read_all(&dest);
                let layer = &got.layer_data[0];
                assert_eq!(
                    layer.encoding.compression,
                    expect.unwrap_or(c),
                    "{c} → {out_c:?}"
                );
                assert_eq!(layer.attributes.layer_position, Vec2(5, -3));
                assert_eq!(layer.size, Vec2(W, H));
                for (ci, name) in ["R", "G", "B"].into_iter().enumerate() {
                    let s = samples(&got, name);
                    let want: Vec<f32> = frame.data.iter().skip(ci).step_by(3).copied().collect();
                    match s {
                        FlatSamples::F32(v) if !half => assert!(
                            v.iter().zip(&want).all(|(a, b)| a.to_bits() == b.to_bits()),
                            "{name}"
                        ),
                        FlatSamples::F16(v) if half => assert!(v
                            .iter()
                            .zip(&want)
                            .all(|(a, b)| a.to_bits() == f16::from_f32(*b).to_bits())),
                        other => panic!("{name}: unexpected samples {:?}", other.len()),
                    }
                }
                for name in ["A", "Z", "N.x"] {
                    assert_eq!(
                        bits(samples(&got, name)),
                        bits(samples(&input, name)),
                        "{name}"
                    );
                }
                let a = &layer.attributes;
                assert_eq!(a.owner, Some(Text::from("nsrm tests")));
                assert_eq!(
                    a.other.get(&Text::from("cameraSerial")),
                    Some(&AttributeValue::Text(Text::from("XK-1138")))
                );
                assert_eq!(
                    a.other.get(&Text::from("exposureIndex")),
                    Some(&AttributeValue::F32(800.0))
                );
                assert_eq!(
                    a.other.get(&Text::from("colorInteropID")),
                    Some(&AttributeValue::Text(Text::from("lin_ap1_scene")))
                );
                assert!(got.attributes.chromaticities.is_some());
            }
        }
    }
}

#[test]
fn every_zip_level_round_trips() {
    // ZIP (16 lines) and ZIPS (1 line), every libdeflate level: the same pixels back, and the
    // default level compresses this (partly constant-exponent) data where level 0 stores it.
    for (comp, exr_comp) in [
        (Compression::ZIP16, ExrCompression::Zip),
        (Compression::ZIP1, ExrCompression::Zips),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("in.exr");
        plate(comp, false).write().to_file(&src).unwrap();
        let first = Decoded::read(&src, &ReadOptions::default()).unwrap().frame;
        let mut sizes = Vec::new();
        // libdeflate's levels, 0 to 12.
        for level in 0..=12u8 {
            let d = Decoded::read(&src, &ReadOptions::default()).unwrap();
            let dest = dir.path().join(format!("l{level}.exr"));
            let o = WriteOptions {
                zip_level: level,
                ..opts(exr_comp, false)
            };
            common::committed(false, |u| d.write(&dest, &o, u)).unwrap();
            let back = Decoded::read(&dest, &ReadOptions::default()).unwrap().frame;
            assert_eq!(back, first, "{comp:?} level {level}");
            // The exr crate (its own inflate) reads the same pixels.
            let theirs = exr::prelude::read_all_data_from_file(&dest);
            assert!(
                theirs.is_ok(),
                "{comp:?} level {level}: the exr crate cannot read it"
            );
            sizes.push(std::fs::metadata(&dest).unwrap().len());
        }
        // ZIPS blocks of this small plate (one short line each) do not shrink and are stored raw.
        let d = sizes[WriteOptions::default().zip_level as usize];
        if comp == Compression::ZIP16 {
            assert!(d < sizes[0], "{comp:?}: {sizes:?}");
        } else {
            assert!(d <= sizes[0], "{comp:?}: {sizes:?}");
        }
    }
}

/// Whether an external reader must be present: under `CI=true` its absence fails the test.
fn require(tool: &str, present: bool) -> bool {
    if !present {
        crate::common::skip(&format!(
            "{tool} not found; install it (see .ci/run) to check outputs in OpenEXR"
        ));
    }
    present
}

const PY_DUMP: &str = r#"
import sys, OpenEXR, numpy as np
f = OpenEXR.File(sys.argv[1], separate_channels=True)
h = f.header()
for name, ch in sorted(f.channels().items()):
    a = np.ascontiguousarray(ch.pixels)
    open(sys.argv[2] + "." + name, "wb").write(a.astype(a.dtype.newbyteorder("<")).tobytes())
print(h["compression"], h["dataWindow"], h.get("cameraSerial"), h.get("colorInteropID"))
"#;

#[test]
fn outputs_open_in_openexr_with_the_pixels_nsrm_computed() {
    let dir = tempfile::tempdir().unwrap();
    let py = Command::new("python3")
        .args(["-c", "import OpenEXR, numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    let oiio = Command::new("oiiotool")
        .arg("--help")
        .output()
        .is_ok_and(|o| o.status.success());
    let (py, oiio) = (
        require("python3 with OpenEXR and numpy", py),
        require("oiiotool", oiio),
    );
    if !py && !oiio {
        return;
    }
    let src = dir.path().join("in.exr");
    let input = plate(Compression::ZIP16, false);
    input.write().to_file(&src).unwrap();
    for (k, (c, half)) in [
        (ExrCompression::Zip, false),
        (ExrCompression::Zips, false),
        (ExrCompression::Piz, false),
        (ExrCompression::None, false),
        (ExrCompression::Zip, true),
    ]
    .into_iter()
    .enumerate()
    {
        let mut d = Decoded::read(&src, &ReadOptions::default()).unwrap();
        d.frame.data.iter_mut().for_each(|v| *v = *v * 1.5 - 0.25);
        let frame = d.frame.clone();
        let dest = dir.path().join(format!("out{k}.exr"));
        common::committed(false, |u| d.write(&dest, &opts(c, half), u)).unwrap();
        if py {
            let dump = dir.path().join(format!("dump{k}"));
            let out = Command::new("python3")
                .args(["-c", PY_DUMP])
                .arg(&dest)
                .arg(&dump)
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                stdout.contains("XK-1138") && stdout.contains("lin_ap1_scene"),
                "{stdout}"
            );
            let file = |name: &str| std::fs::read(format!("{}.{name}", dump.display())).unwrap();
            for (ci, name) in ["R", "G", "B"].into_iter().enumerate() {
                let want: Vec<u8> = frame
                    .data
                    .iter()
                    .skip(ci)
                    .step_by(3)
                    .flat_map(|&v| {
                        if half {
                            f16::from_f32(v).to_bits().to_le_bytes().to_vec()
                        } else {
                            v.to_bits().to_le_bytes().to_vec()
                        }
                    })
                    .collect();
                assert_eq!(
                    file(name),
                    want,
                    "{c:?} half={half}: {name} as OpenEXR reads it"
                );
            }
            let le = |s: &FlatSamples| -> Vec<u8> {
                match s {
                    FlatSamples::F16(v) => {
                        v.iter().flat_map(|h| h.to_bits().to_le_bytes()).collect()
                    }
                    FlatSamples::F32(v) => v.iter().flat_map(|f| f.to_le_bytes()).collect(),
                    FlatSamples::U32(v) => v.iter().flat_map(|u| u.to_le_bytes()).collect(),
                }
            };
            for name in ["A", "Z", "N.x"] {
                assert_eq!(
                    file(name),
                    le(samples(&input, name)),
                    "{name} as OpenEXR reads it"
                );
            }
        }
        if oiio {
            let out = Command::new("oiiotool")
                .args(["--info", "-v", "--stats"])
                .arg(&dest)
                .output()
                .unwrap();
            let text = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{text}{}",
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(text.contains("6 channel"), "{text}");
            assert!(text.contains("N.x") && text.contains("XK-1138"), "{text}");
            let nan = text
                .lines()
                .find(|l| l.contains("NanCount"))
                .unwrap_or_default();
            assert!(nan.split_whitespace().skip(3).all(|n| n == "0"), "{text}");
        }
    }
}

/// A frame made in memory (as a TIFF or camera raw input is) goes through the chunk-level writer:
/// RGBA in every compression, float and half, read back by the `exr` crate bit for bit (alpha
/// included) and by OpenImageIO where it is installed.
#[test]
fn new_files_from_frames_keep_every_sample_in_every_compression() {
    let n = W * H;
    let (rgb, a) = (noise(3 * n, 11), noise(n, 12));
    let data: Vec<f32> = rgb
        .chunks_exact(3)
        .zip(&a)
        .flat_map(|(p, &a)| [p[0], p[1], p[2], a])
        .collect();
    let frame = nsrm::Frame {
        width: W,
        height: H,
        layout: nsrm::Layout::Rgba,
        data,
    };
    let oiio = Command::new("oiiotool")
        .arg("--help")
        .output()
        .is_ok_and(|o| o.status.success());
    let dir = tempfile::tempdir().unwrap();
    let outs = [
        (ExrCompression::Keep, Compression::ZIP16),
        (ExrCompression::None, Compression::Uncompressed),
        (ExrCompression::Rle, Compression::RLE),
        (ExrCompression::Zips, Compression::ZIP1),
        (ExrCompression::Zip, Compression::ZIP16),
        (ExrCompression::Piz, Compression::PIZ),
    ];
    for (k, &(c, expect)) in outs.iter().enumerate() {
        for half in [false, true] {
            let dest = dir.path().join(format!("new-{k}-{half}.exr"));
            common::committed(false, |u| {
                common::write_exr(&frame, &dest, &opts(c, half), u)
            })
            .unwrap();
            let got = read_all(&dest);
            let layer = &got.layer_data[0];
            assert_eq!(layer.encoding.compression, expect, "{c:?}");
            assert_eq!(layer.size, Vec2(W, H));
            for (ci, name) in ["R", "G", "B", "A"].into_iter().enumerate() {
                let want = frame.data.iter().skip(ci).step_by(4);
                let ok = match samples(&got, name) {
                    FlatSamples::F32(v) if !half => {
                        v.iter().zip(want).all(|(a, b)| a.to_bits() == b.to_bits())
                    }
                    FlatSamples::F16(v) if half => v
                        .iter()
                        .zip(want)
                        .all(|(a, b)| a.to_bits() == f16::from_f32(*b).to_bits()),
                    other => panic!("{name}: unexpected samples {:?}", other.len()),
                };
                assert!(ok, "{c:?} half={half}: {name}");
            }
            assert_eq!(
                layer.attributes.other.get(&Text::from("colorInteropID")),
                Some(&AttributeValue::Text(Text::from("lin_ap1_scene")))
            );
            if !half {
                let back = crate::common::read_frame(&dest, &ReadOptions::default()).unwrap();
                assert_eq!(back, frame, "{c:?}: nsrm reads back the frame");
            }
            if oiio {
                let out = Command::new("oiiotool")
                    .args(["--info", "-v", "--stats"])
                    .arg(&dest)
                    .output()
                    .unwrap();
                let text = String::from_utf8_lossy(&out.stdout);
                assert!(out.status.success() && text.contains("4 channel"), "{text}");
            }
        }
    }
}

/// Frames tall enough that the writer encodes and writes them in several rounds (an even and an
/// odd number; each round is written while the next is encoded) come back bit for bit.
#[test]
fn tall_frames_written_in_several_rounds_come_back_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for h in [10_000usize, 19_000] {
        let frame = nsrm::Frame {
            width: W,
            height: h,
            layout: nsrm::Layout::Rgb,
            data: noise(3 * W * h, h as u64),
        };
        for c in [
            ExrCompression::None,
            ExrCompression::Zip,
            ExrCompression::Piz,
        ] {
            let dest = dir.path().join(format!("tall-{h}-{c:?}.exr"));
            common::committed(false, |u| {
                common::write_exr(&frame, &dest, &opts(c, false), u)
            })
            .unwrap();
            let got = read_all(&dest);
            assert_eq!(got.layer_data[0].size, Vec2(W, h));
            for (ci, name) in ["R", "G", "B"].into_iter().enumerate() {
                let want = frame.data.iter().skip(ci).step_by(3);
                let FlatSamples::F32(v) = samples(&got, name) else {
                    panic!("{name}: not f32")
                };
                assert!(
                    v.iter().zip(want).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{h} lines, {c:?}: {name}"
                );
            }
        }
    }
}
