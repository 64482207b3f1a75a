//! The unit tests of `piz.rs` (moved beside it to keep the file short).

use super::*;
use ::exr::compression::Compression;
use ::exr::math::Vec2;
use ::exr::meta::attribute::{ChannelDescription, ChannelList, IntegerBounds, LineOrder};
use ::exr::meta::header::Header;
use ::exr::meta::BlockDescription;

/// A xorshift generator: reproducible noise for the test blocks.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
}

/// A test block: its channel types, size, kind of data, PIZ header and raw bytes.
struct Block {
    types: &'static [SampleType],
    w: usize,
    h: usize,
    kind: usize,
    header: Header,
    raw: Vec<u8>,
}

/// Four channel layouts × six sizes × five kinds of data (noise, ramps, a constant, sparse
/// values, few distinct values in long runs).
fn blocks(rng: &mut Rng) -> Vec<Block> {
    let layouts: [&'static [SampleType]; 4] = [
        &[SampleType::F32; 3],
        &[
            SampleType::F16,
            SampleType::F32,
            SampleType::F32,
            SampleType::F32,
        ],
        &[SampleType::F16; 2],
        &[SampleType::U32, SampleType::F32, SampleType::F16],
    ];
    let mut out = Vec::new();
    for types in layouts {
        let sizes = [(1, 1), (2, 2), (7, 3), (33, 32), (64, 17), (300, 32)];
        for (w, h) in sizes {
            for kind in 0..5 {
                let list: Vec<ChannelDescription> = types
                    .iter()
                    .enumerate()
                    .map(|(i, &t)| ChannelDescription::named(["a", "b", "c", "d"][i], t))
                    .collect();
                let channels = ChannelList::new(list.into_iter().collect());
                let bpp = channels.bytes_per_pixel;
                let header = Header::new("x".into(), Vec2(w, h), channels.list.clone())
                    .with_encoding(
                        Compression::PIZ,
                        BlockDescription::ScanLines,
                        LineOrder::Increasing,
                    );
                let raw: Vec<u8> = (0..w * h * bpp)
                    .map(|i| match kind {
                        0 => rng.next() as u8,
                        1 => ((i / 7) % 251) as u8,
                        2 => 0x3c,
                        3 => {
                            if rng.next().is_multiple_of(9) {
                                rng.next() as u8
                            } else {
                                0
                            }
                        }
                        // Few distinct values (the 14-bit wavelet) in long runs.
                        _ => ((i / 200) % 3) as u8,
                    })
                    .collect();
                out.push(Block {
                    types,
                    w,
                    h,
                    kind,
                    header,
                    raw,
                });
            }
        }
    }
    out
}

/// Blocks PIZ-compressed by the `exr` crate (OpenEXR's format) decode here to the same bytes.
#[test]
fn decodes_what_the_exr_crate_encodes() {
    let mut words = Vec::new();
    let mut decoded = 0;
    for b in blocks(&mut Rng(0x9e37_79b9_7f4a_7c15)) {
        let (types, w, h, kind, raw) = (b.types, b.w, b.h, b.kind, &b.raw);
        let bounds = IntegerBounds::new(Vec2(0, 0), Vec2(w, h));
        let packed = Compression::PIZ
            .compress_image_section_to_le(&b.header, raw.clone(), bounds)
            .unwrap();
        if packed.len() >= raw.len() {
            continue; // stored raw
        }
        let mut out = vec![0u8; raw.len()];
        decode(&packed, types, w, h, &mut out, &mut words)
            .unwrap_or_else(|e| panic!("{types:?} {w}x{h} kind {kind}: {e}"));
        assert_eq!(&out, raw, "{types:?} {w}x{h} kind {kind}");
        decoded += 1;
        // Truncated data: an error, never a panic.
        for cut in [0, 1, 4, packed.len() / 2, packed.len() - 1] {
            let _ = decode(&packed[..cut], types, w, h, &mut out, &mut words);
        }
    }
    assert!(decoded >= 20, "{decoded} blocks decoded");
}

/// Blocks encoded here decode to the same bytes in the `exr` crate's PIZ decoder and here.
#[test]
fn the_exr_crate_decodes_what_is_encoded_here() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let (mut words, mut packed) = (Vec::new(), Vec::new());
    for b in blocks(&mut rng) {
        let (types, w, h, kind, raw) = (b.types, b.w, b.h, b.kind, &b.raw);
        encode(raw, types, w, h, &mut packed, &mut words).unwrap();
        let mut out = vec![0u8; raw.len()];
        decode(&packed, types, w, h, &mut out, &mut words).unwrap();
        assert_eq!(&out, raw, "here: {types:?} {w}x{h} kind {kind}");
        // Damaged data: an error or other pixels, never a panic.
        for k in 0..16 {
            let mut bad = packed.clone();
            let at = (rng.next() as usize) % bad.len();
            bad[at] ^= 1 << (k % 8);
            let _ = decode(&bad, types, w, h, &mut out, &mut words);
        }
        let bounds = IntegerBounds::new(Vec2(0, 0), Vec2(w, h));
        let theirs = Compression::PIZ
            .decompress_image_section_from_le(&b.header, packed.clone(), bounds, true)
            .unwrap_or_else(|e| panic!("exr: {types:?} {w}x{h} kind {kind}: {e}"));
        assert_eq!(&theirs, raw, "exr: {types:?} {w}x{h} kind {kind}");
    }
}

/// Packs `(bits, value)` pairs MSB-first, zero-padded to a byte.
fn pack(fields: &[(u32, u64)]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut w = BitWriter {
        out: &mut out,
        acc: 0,
        n: 0,
    };
    for &(len, v) in fields {
        w.put(len, v);
    }
    w.finish(0);
    out
}

#[test]
fn code_lengths_unpack_with_their_zero_runs() {
    // Symbols 10..=20: 1, a short run of 3 zeros, 2, a long run of 6 zeros (fills to 20)...
    let t = pack(&[
        (6, 1),
        (6, SHORT_ZEROCODE_RUN + 1),
        (6, 2),
        (6, LONG_ZEROCODE_RUN),
        (8, 0),
    ]);
    let (lens, used) = read_code_lengths(&t, 10, 20).unwrap();
    assert_eq!(used, 32);
    assert_eq!(&lens[9..22], &[0, 1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0]);
    // ...which is one too many for symbols 10..=19, and too few for 10..=22.
    assert!(read_code_lengths(&t, 10, 19).is_err());
    assert!(read_code_lengths(&t, 10, 22).is_err());
}

#[test]
fn the_canonical_code_gives_longer_codes_the_smaller_values() {
    // Symbol 0: 1 bit, symbols 3 and 4: 2 bits → "1", "00", "01" (OpenEXR's order).
    let mut lens = vec![0u8; 5];
    lens[0] = 1;
    lens[3] = 2;
    lens[4] = 2;
    let d = Decoder::new(&lens, 0, 4).unwrap();
    assert_eq!(d.symbol(1 << 63), Some((1, 0)));
    assert_eq!(d.symbol(0), Some((2, 3)));
    assert_eq!(d.symbol(1 << 62), Some((2, 4)));
    // Three 1-bit codes do not fit.
    assert!(Decoder::new(&[1, 1, 1], 0, 2).is_err());
    // A 20-bit code is found past the direct table.
    let mut long = vec![0u8; 21];
    for (s, l) in long.iter_mut().enumerate().skip(1) {
        *l = s as u8;
    }
    long[0] = 20;
    let d = Decoder::new(&long, 0, 20).unwrap();
    assert_eq!(d.symbol(0).map(|(l, _)| l), Some(20));
}

#[test]
fn symbols_and_runs_decode_to_exactly_the_values_asked_for() {
    let mut lens = vec![0u8; 5];
    lens[0] = 1;
    lens[3] = 2;
    lens[4] = 2;
    let d = Decoder::new(&lens, 0, 4).unwrap();
    // 0, 3, then the run symbol (4) with a run of 3: 0 3 3 3 3.
    let stream = pack(&[(1, 1), (2, 0), (2, 1), (8, 3)]);
    let mut out = [9u16; 5];
    d.decode(&stream, 13, 4, &mut out).unwrap();
    assert_eq!(out, [0, 3, 3, 3, 3]);
    assert!(d.decode(&stream, 13, 4, &mut [0u16; 4]).is_err());
    assert!(d.decode(&stream, 13, 4, &mut [0u16; 6]).is_err());
    // A run first, or without its length.
    let first = pack(&[(2, 1), (8, 3)]);
    assert!(d.decode(&first, 10, 4, &mut out).is_err());
    assert!(d.decode(&stream, 7, 4, &mut out).is_err());
}
