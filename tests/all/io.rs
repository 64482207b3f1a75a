//! Round trips and refusals of `nsrm_io`: EXR (half/float/uint, RGB/RGBA, tiled, layers, parts,
//! mip levels, extra channels, attributes) and TIFF (u16/f32 in, f32 out).

use crate::common;

use crate::common::{read_frame, WriteStaged};
use exr::compression::Compression;
use exr::image::{
    AnyChannel, AnyChannels, AnyImage, Blocks, Encoding, FlatSamples, Image, Layer, Levels,
};
use exr::math::{RoundingMode, Vec2};
use exr::meta::attribute::{AttributeValue, Chromaticities, IntegerBounds, LineOrder, Text};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::{f16, SmallVec, WritableImage};
use nsrm::OutputSpace;
use nsrm::{Frame, Layout};
use nsrm_io::{Concern, Param};
use nsrm_io::{Decoded, FileFormat, IoError, ReadOptions, WriteOptions};
use std::path::Path;

fn halves(n: usize, seed: f32) -> Vec<f16> {
    (0..n)
        .map(|i| f16::from_f32(seed + 0.001 * i as f32))
        .collect()
}

fn floats(n: usize, seed: f32) -> Vec<f32> {
    (0..n).map(|i| seed + 0.37 * i as f32).collect()
}

fn chan(name: &str, s: FlatSamples) -> AnyChannel<Levels<FlatSamples>> {
    AnyChannel::new(name, Levels::Singular(s))
}

fn image_of(
    size: Vec2<usize>,
    channels: Vec<AnyChannel<Levels<FlatSamples>>>,
    attrs: LayerAttributes,
    encoding: Encoding,
) -> AnyImage {
    let layer = Layer::new(
        size,
        attrs,
        encoding,
        AnyChannels::sort(SmallVec::from_vec(channels)),
    );
    Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions(size)),
        SmallVec::from_vec(vec![layer]),
    )
}

fn read_all(path: &Path) -> AnyImage {
    exr::prelude::read_all_data_from_file(path).unwrap()
}

fn channel<'a>(img: &'a AnyImage, part: usize, name: &str) -> &'a Levels<FlatSamples> {
    &img.layer_data[part]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.eq(name))
        .unwrap_or_else(|| panic!("no channel {name}"))
        .sample_data
}

fn level0(l: &Levels<FlatSamples>) -> &FlatSamples {
    &l.levels_as_slice()[0]
}

fn opts(format: FileFormat, half: bool, space: OutputSpace) -> WriteOptions {
    WriteOptions {
        format,
        half,
        compression: nsrm_io::ExrCompression::Keep,
        space,
        ..Default::default()
    }
}

const TILED_PIZ: Encoding = Encoding {
    compression: Compression::PIZ,
    blocks: Blocks::Tiles(Vec2(16, 16)),
    line_order: LineOrder::Increasing,
};

/// A tiled half RGBA frame with depth, a normal channel, an offset data window, a larger display
/// window, camera chromaticities and custom attributes.
fn rich_exr(path: &Path) -> AnyImage {
    let size = Vec2(40, 30);
    let n = 40 * 30;
    let mut attrs = LayerAttributes {
        layer_position: Vec2(10, 20),
        owner: Some(Text::from("nsrm tests")),
        ..Default::default()
    };
    attrs.other.insert(
        Text::from("cameraSerial"),
        AttributeValue::Text(Text::from("SN123")),
    );
    attrs
        .other
        .insert(Text::from("exposureIndex"), AttributeValue::F32(800.0));
    let mut image = image_of(
        size,
        vec![
            chan("R", FlatSamples::F16(halves(n, 0.1))),
            chan("G", FlatSamples::F16(halves(n, 0.2))),
            chan("B", FlatSamples::F16(halves(n, 0.3))),
            chan("A", FlatSamples::F16(halves(n, 0.5))),
            chan("Z", FlatSamples::F32(floats(n, 3.0))),
            chan("N.x", FlatSamples::F32(floats(n, -1.0))),
        ],
        attrs,
        TILED_PIZ,
    );
    image.attributes.display_window = IntegerBounds::new(Vec2(0, 0), Vec2(64, 64));
    image.attributes.chromaticities = Some(Chromaticities {
        red: Vec2(0.7, 0.3),
        green: Vec2(0.2, 0.8),
        blue: Vec2(0.1, 0.05),
        white: Vec2(0.33, 0.33),
    });
    image.write().to_file(path).unwrap();
    image
}

#[test]
fn exr_rgba_half_tiled_with_extras_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("rich.exr");
    let original = rich_exr(&src);
    for (half, space) in [(false, OutputSpace::Acescg), (true, OutputSpace::Xyz)] {
        let d = Decoded::read(&src, &ReadOptions::default()).unwrap();
        assert_eq!((d.frame.width, d.frame.height), (40, 30));
        let want_r: Vec<f32> = halves(1200, 0.1).iter().map(|h| h.to_f32()).collect();
        let got_r: Vec<f32> = d.frame.data.chunks(3).map(|p| p[0]).collect();
        assert_eq!(got_r, want_r);
        let dest = dir.path().join(format!("out_{half}.exr"));
        common::committed(false, |u| {
            d.write(&dest, &opts(FileFormat::Exr, half, space), u)
        })
        .unwrap();

        let back = read_all(&dest);
        let (l, o) = (&back.layer_data[0], &original.layer_data[0]);
        assert_eq!(l.attributes.layer_position, Vec2(10, 20));
        assert_eq!(l.size, Vec2(40, 30));
        assert_eq!(
            back.attributes.display_window,
            IntegerBounds::new(Vec2(0, 0), Vec2(64, 64))
        );
        assert_eq!(l.encoding.blocks, Blocks::Tiles(Vec2(16, 16)));
        assert_eq!(l.encoding.compression, Compression::PIZ);
        // Untouched channels are bit-identical, in their own sample type.
        for name in ["A", "Z", "N.x"] {
            assert_eq!(
                channel(&back, 0, name),
                channel(&original, 0, name),
                "{name}"
            );
        }
        // R, G, B hold the (here uncorrected) values, as float or half.
        match level0(channel(&back, 0, "R")) {
            FlatSamples::F32(v) => {
                assert!(!half);
                assert_eq!(v, &want_r);
            }
            FlatSamples::F16(v) => {
                assert!(half);
                assert_eq!(v, &halves(1200, 0.1));
            }
            FlatSamples::U32(_) => panic!("u32 R"),
        }
        // Attributes pass through; the colour attributes describe the output.
        assert_eq!(l.attributes.owner, o.attributes.owner);
        for key in ["cameraSerial", "exposureIndex"] {
            let k = Text::from(key);
            assert_eq!(
                l.attributes.other.get(&k),
                o.attributes.other.get(&k),
                "{key}"
            );
        }
        assert_eq!(
            l.attributes.other.get(&Text::from("colorInteropID")),
            Some(&AttributeValue::Text(Text::from(space.interop_id())))
        );
        match space.primaries() {
            None => assert!(back.attributes.chromaticities.is_none()),
            Some((p, w)) => {
                let c = back.attributes.chromaticities.unwrap();
                assert_eq!(c.green, Vec2(p[1][0] as f32, p[1][1] as f32));
                assert_eq!(c.white, Vec2(w[0] as f32, w[1] as f32));
            }
        }
    }
    // read_frame gives RGBA with the alpha channel.
    let f = read_frame(&src, &ReadOptions::default()).unwrap();
    assert_eq!(f.layout, Layout::Rgba);
    assert_eq!(f.data[3], f16::from_f32(0.5).to_f32());
}

#[test]
fn corrected_values_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("rich.exr");
    rich_exr(&src);
    let mut d = Decoded::read(&src, &ReadOptions::default()).unwrap();
    // The frame and its levels (none here) are public fields.
    for f in std::iter::once(&mut d.frame).chain(d.levels.iter_mut()) {
        for v in f.data.iter_mut() {
            *v = *v * 2.0 + 1.0;
        }
    }
    let dest = dir.path().join("out.exr");
    common::committed(false, |u| {
        d.write(&dest, &opts(FileFormat::Exr, false, OutputSpace::Xyz), u)
    })
    .unwrap();
    let back = read_frame(&dest, &ReadOptions::default()).unwrap();
    let before = read_frame(&src, &ReadOptions::default()).unwrap();
    for (b, a) in back.data.chunks(4).zip(before.data.chunks(4)) {
        for k in 0..3 {
            assert_eq!(b[k], a[k] * 2.0 + 1.0);
        }
        assert_eq!(b[3], a[3], "alpha changed");
    }
}

#[test]
fn layers_by_name_in_one_part() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("aovs.exr");
    let size = Vec2(8, 4);
    let mut channels = Vec::new();
    for (layer, base) in [("beauty", 1.0), ("diffuse", 5.0)] {
        for (k, c) in ["R", "G", "B"].into_iter().enumerate() {
            channels.push(chan(
                &format!("{layer}.{c}"),
                FlatSamples::F32(floats(32, base + k as f32)),
            ));
        }
    }
    channels.push(chan("Z", FlatSamples::F32(floats(32, 9.0))));
    let original = image_of(
        size,
        channels,
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
    );
    original.write().to_file(&src).unwrap();

    let e = Decoded::read(&src, &ReadOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, IoError::Channels { .. }), "{msg}");
    assert!(msg.contains("aovs.exr"), "{msg}");
    assert!(msg.contains("beauty, diffuse (pick one)"), "{msg}");
    // The library names no flag; it says the layer is the way out (the binary adds `--layer`).
    assert!(!msg.contains("--"), "{msg}");
    assert_eq!(e.concern(), Some(Concern::Remedy(Param::Layer)));
    let e = Decoded::read(
        &src,
        &ReadOptions {
            layer: Some("specular".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("no layer `specular`"), "{e}");
    assert_eq!(e.concern(), Some(Concern::Value(Param::Layer)));

    let d = Decoded::read(
        &src,
        &ReadOptions {
            layer: Some("beauty".into()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(d.frame.data[0..3], [1.0, 2.0, 3.0]);
    let dest = dir.path().join("out.exr");
    common::committed(false, |u| {
        d.write(&dest, &opts(FileFormat::Exr, true, OutputSpace::Xyz), u)
    })
    .unwrap();
    let back = read_all(&dest);
    for name in ["diffuse.R", "diffuse.G", "diffuse.B", "Z"] {
        assert_eq!(
            channel(&back, 0, name),
            channel(&original, 0, name),
            "{name}"
        );
    }
    assert!(matches!(
        level0(channel(&back, 0, "beauty.G")),
        FlatSamples::F16(_)
    ));

    // The binary adds the flag: a hint for the way out, a prefix for the value at fault (one
    // line per failed file of the batch).
    common::model(dir.path());
    let o = common::nsrm_in(dir.path(), &["apply", "--model", "m.json", "aovs.exr"]);
    let err = common::stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.lines().any(|l| l.contains("aovs.exr")
            && l.contains("beauty, diffuse (pick one)")
            && l.contains("hint: pick the layer with --layer NAME")),
        "{err}"
    );
    let o = common::nsrm_in(
        dir.path(),
        &[
            "apply", "--model", "m.json", "--layer", "specular", "aovs.exr",
        ],
    );
    let err = common::stderr(&o);
    assert!(
        err.lines()
            .any(|l| l.contains("--layer: ") && l.contains("no layer `specular`")),
        "{err}"
    );
}

#[test]
fn multi_part_files_keep_every_part() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("parts.exr");
    let size = Vec2(6, 5);
    let part = |name: &str, channels: Vec<AnyChannel<Levels<FlatSamples>>>| {
        Layer::new(
            size,
            LayerAttributes::named(name),
            Encoding::SMALL_LOSSLESS,
            AnyChannels::sort(SmallVec::from_vec(channels)),
        )
    };
    let image: AnyImage = Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions(size)),
        SmallVec::from_vec(vec![
            part("depth", vec![chan("Z", FlatSamples::F32(floats(30, 2.0)))]),
            part(
                "beauty",
                vec![
                    chan("R", FlatSamples::F32(floats(30, 0.1))),
                    chan("G", FlatSamples::F32(floats(30, 0.2))),
                    chan("B", FlatSamples::U32((0..30).collect())),
                ],
            ),
        ]),
    );
    image.write().to_file(&src).unwrap();
    for layer in [None, Some("beauty".to_string())] {
        let d = Decoded::read(
            &src,
            &ReadOptions {
                layer,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(d.frame.data[0..3], [0.1, 0.2, 0.0]);
        assert_eq!(d.frame.data[5], 1.0, "u32 samples are read as their value");
        let dest = dir.path().join("out.exr");
        let _ = std::fs::remove_file(&dest);
        common::committed(false, |u| {
            d.write(
                &dest,
                &opts(FileFormat::Exr, false, OutputSpace::LinearSrgb),
                u,
            )
        })
        .unwrap();
        let back = read_all(&dest);
        assert_eq!(back.layer_data.len(), 2);
        let depth = back
            .layer_data
            .iter()
            .position(|l| l.attributes.layer_name == Some(Text::from("depth")))
            .unwrap();
        let orig_depth = image
            .layer_data
            .iter()
            .position(|l| l.attributes.layer_name == Some(Text::from("depth")))
            .unwrap();
        assert_eq!(channel(&back, depth, "Z"), channel(&image, orig_depth, "Z"));
    }
}

#[test]
fn mip_levels_are_corrected_too() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("mip.exr");
    let size = Vec2(32, 16);
    let sizes: Vec<Vec2<usize>> = exr::meta::mip_map_levels(RoundingMode::Down, size)
        .map(|(_, s)| s)
        .collect();
    assert!(sizes.len() > 3);
    let mip = |seed: f32| Levels::Mip {
        rounding_mode: RoundingMode::Down,
        level_data: sizes
            .iter()
            .map(|s| FlatSamples::F32(floats(s.0 * s.1, seed)))
            .collect(),
    };
    let channels = vec![
        AnyChannel::new("R", mip(0.1)),
        AnyChannel::new("G", mip(0.2)),
        AnyChannel::new("B", mip(0.3)),
    ];
    let image = image_of(size, channels, LayerAttributes::default(), TILED_PIZ);
    image.write().to_file(&src).unwrap();
    let mut d = Decoded::read(&src, &ReadOptions::default()).unwrap();
    assert_eq!(d.levels.len(), sizes.len() - 1);
    assert_eq!(
        d.frame.pixels() + d.levels.iter().map(Frame::pixels).sum::<usize>(),
        sizes.iter().map(|s| s.0 * s.1).sum::<usize>()
    );
    for f in std::iter::once(&mut d.frame).chain(d.levels.iter_mut()) {
        f.data.iter_mut().for_each(|v| *v = -*v);
    }
    let dest = dir.path().join("out.exr");
    common::committed(false, |u| {
        d.write(&dest, &opts(FileFormat::Exr, false, OutputSpace::Xyz), u)
    })
    .unwrap();
    let back = read_all(&dest);
    let got = channel(&back, 0, "G").levels_as_slice();
    assert_eq!(got.len(), sizes.len());
    for (k, s) in sizes.iter().enumerate() {
        let want: Vec<f32> = floats(s.0 * s.1, 0.2).iter().map(|v| -v).collect();
        assert_eq!(got[k], FlatSamples::F32(want), "level {k}");
    }
}

#[test]
fn missing_channels_and_bad_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let no_g = d.join("no_g.exr");
    image_of(
        Vec2(2, 2),
        vec![
            chan("R", FlatSamples::F32(floats(4, 0.0))),
            chan("B", FlatSamples::F32(floats(4, 0.0))),
        ],
        LayerAttributes::default(),
        Encoding::UNCOMPRESSED,
    )
    .write()
    .to_file(&no_g)
    .unwrap();
    let e = Decoded::read(&no_g, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("no_g.exr: no G channel"), "{e}");

    let full = std::fs::read(&no_g).unwrap();
    let truncated = d.join("truncated.exr");
    std::fs::write(&truncated, &full[..full.len() - 20]).unwrap();
    let e = Decoded::read(&truncated, &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::Corrupt { .. }), "{e}");
    assert!(e.to_string().contains("past the end of the file"), "{e}");
    assert!(e.to_string().contains("truncated.exr"), "{e}");

    let png = d.join("fake.exr");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n....").unwrap();
    let e = Decoded::read(&png, &ReadOptions::default()).unwrap_err();
    assert!(matches!(e, IoError::UnknownFormat { .. }), "{e}");

    let e = Decoded::read(&d.join("absent.exr"), &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("absent.exr: cannot read"), "{e}");

    for (name, bytes, why) in [
        ("grey.tif", tiff_gray16(), "greyscale"),
        ("rgb8.tif", tiff_rgb8(), "8 bits per sample"),
    ] {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = Decoded::read(&p, &ReadOptions::default()).unwrap_err();
        assert!(matches!(e, IoError::Unsupported { .. }), "{e}");
        assert!(
            e.to_string().contains(name) && e.to_string().contains(why),
            "{e}"
        );
    }
}

fn tiff_bytes<C: tiff::encoder::colortype::ColorType>(w: u32, h: u32, data: &[C::Inner]) -> Vec<u8>
where
    [C::Inner]: tiff::encoder::TiffValue,
{
    let mut out = std::io::Cursor::new(Vec::new());
    tiff::encoder::TiffEncoder::new(&mut out)
        .unwrap()
        .write_image::<C>(w, h, data)
        .unwrap();
    out.into_inner()
}

fn tiff_gray16() -> Vec<u8> {
    tiff_bytes::<tiff::encoder::colortype::Gray16>(2, 2, &[1, 2, 3, 4])
}

fn tiff_rgb8() -> Vec<u8> {
    tiff_bytes::<tiff::encoder::colortype::RGB8>(2, 1, &[1, 2, 3, 4, 5, 6])
}

#[test]
fn tiff_in_u16_and_f32_and_out_f32() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u16_path = d.join("raw16.tif");
    let data16: Vec<u16> = (0..3 * 6).map(|i| i as u16 * 3000).collect();
    std::fs::write(
        &u16_path,
        tiff_bytes::<tiff::encoder::colortype::RGB16>(3, 2, &data16),
    )
    .unwrap();
    let f = read_frame(&u16_path, &ReadOptions::default()).unwrap();
    assert_eq!((f.width, f.height, f.layout), (3, 2, Layout::Rgb));
    for (got, want) in f.data.iter().zip(&data16) {
        assert_eq!(*got, *want as f32 / 65535.0);
    }

    let f32_path = d.join("rawf.tif");
    let data32: Vec<f32> = (0..4 * 6).map(|i| 0.25 * i as f32 - 1.0).collect();
    std::fs::write(
        &f32_path,
        tiff_bytes::<tiff::encoder::colortype::RGBA32Float>(2, 3, &data32),
    )
    .unwrap();
    let f = read_frame(&f32_path, &ReadOptions::default()).unwrap();
    assert_eq!(f.layout, Layout::Rgba);
    assert_eq!(f.data, data32);
    let e = Decoded::read(
        &f32_path,
        &ReadOptions {
            layer: Some("beauty".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("no layers"), "{e}");
    assert_eq!(e.concern(), Some(Concern::Value(Param::Layer)));

    // TIFF in → EXR out keeps alpha; TIFF in → TIFF out is 32-bit float.
    let dec = Decoded::read(&f32_path, &ReadOptions::default()).unwrap();
    let exr_out = d.join("from_tiff.exr");
    common::committed(false, |u| {
        dec.write(&exr_out, &opts(FileFormat::Exr, false, OutputSpace::Xyz), u)
    })
    .unwrap();
    assert_eq!(
        read_frame(&exr_out, &ReadOptions::default()).unwrap().data,
        data32
    );
    let dec = Decoded::read(&f32_path, &ReadOptions::default()).unwrap();
    let tif_out = d.join("out.tif");
    common::committed(false, |u| {
        dec.write(
            &tif_out,
            &opts(FileFormat::Tiff, false, OutputSpace::Xyz),
            u,
        )
    })
    .unwrap();
    let mut t = tiff::decoder::Decoder::new(std::fs::File::open(&tif_out).unwrap()).unwrap();
    assert_eq!(t.colortype().unwrap(), tiff::ColorType::RGBA(32));
    match t.read_image().unwrap() {
        tiff::decoder::DecodingResult::F32(v) => assert_eq!(v, data32),
        other => panic!("not f32: {:?}", std::mem::discriminant(&other)),
    }
}

#[test]
fn exr_to_tiff_refuses_channels_tiff_cannot_hold() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("rich.exr");
    rich_exr(&src);
    let d = Decoded::read(&src, &ReadOptions::default()).unwrap();
    let dest = dir.path().join("out.tif");
    let e = common::committed(false, |u| {
        d.write(&dest, &opts(FileFormat::Tiff, false, OutputSpace::Xyz), u)
    })
    .unwrap_err();
    assert!(e.to_string().contains("N.x, Z"), "{e}");
    assert!(!dest.exists());

    // Plain RGB EXR → float TIFF.
    let plain = dir.path().join("plain.exr");
    let frame = Frame::from_data(2, 2, Layout::Rgb, floats(12, 0.5)).unwrap();
    common::committed(false, |u| {
        crate::common::write_exr(
            &frame,
            &plain,
            &opts(FileFormat::Exr, false, OutputSpace::Xyz),
            u,
        )
    })
    .unwrap();
    let d = Decoded::read(&plain, &ReadOptions::default()).unwrap();
    common::committed(false, |u| {
        d.write(&dest, &opts(FileFormat::Tiff, false, OutputSpace::Xyz), u)
    })
    .unwrap();
    assert_eq!(read_frame(&dest, &ReadOptions::default()).unwrap(), frame);
}

#[test]
fn writes_are_atomic_and_never_clobber() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frame = Frame::from_data(2, 1, Layout::Rgb, floats(6, 0.0)).unwrap();
    let o = opts(FileFormat::Exr, false, OutputSpace::Xyz);
    let dest = d.join("a.exr");
    std::fs::write(&dest, b"keep me").unwrap();
    let e =
        common::committed(false, |u| crate::common::write_exr(&frame, &dest, &o, u)).unwrap_err();
    assert!(e.to_string().contains("already exists"), "{e}");
    assert_eq!(std::fs::read(&dest).unwrap(), b"keep me");
    common::committed(true, |u| crate::common::write_exr(&frame, &dest, &o, u)).unwrap();
    assert_eq!(read_frame(&dest, &ReadOptions::default()).unwrap(), frame);
    // A destination under a regular file cannot be written; nothing is left behind.
    let e = common::committed(false, |u| {
        crate::common::write_exr(&frame, &dest.join("x.exr"), &o, u)
    })
    .unwrap_err();
    assert!(e.to_string().contains("cannot write"), "{e}");
    let e = common::committed(false, |u| {
        crate::common::write_tiff(&frame, &d.join("no/such/dir/x.tif"), u)
    })
    .unwrap_err();
    assert!(e.to_string().contains("cannot write"), "{e}");
    let names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["a.exr"]);
}

#[test]
fn compression_is_kept_when_lossless_and_chosen_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("pxr24.exr");
    let n = 16 * 8;
    image_of(
        Vec2(16, 8),
        vec![
            chan("R", FlatSamples::F32(floats(n, 0.1))),
            chan("G", FlatSamples::F32(floats(n, 0.2))),
            chan("B", FlatSamples::F32(floats(n, 0.3))),
        ],
        LayerAttributes::default(),
        Encoding {
            compression: Compression::PXR24,
            blocks: Blocks::ScanLines,
            line_order: LineOrder::Increasing,
        },
    )
    .write()
    .to_file(&src)
    .unwrap();
    for (want, got) in [
        (nsrm_io::ExrCompression::Keep, Compression::ZIP16),
        (nsrm_io::ExrCompression::None, Compression::Uncompressed),
        (nsrm_io::ExrCompression::Piz, Compression::PIZ),
    ] {
        let d = Decoded::read(&src, &ReadOptions::default()).unwrap();
        let dest = dir.path().join(format!("out_{got:?}.exr"));
        let o = WriteOptions {
            compression: want,
            ..opts(FileFormat::Exr, false, OutputSpace::Xyz)
        };
        common::committed(false, |u| d.write(&dest, &o, u)).unwrap();
        assert_eq!(read_all(&dest).layer_data[0].encoding.compression, got);
    }
}
