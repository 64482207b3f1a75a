//! The unit tests of `chunks.rs` (moved beside it to keep the file short).

use super::*;

#[test]
fn overlapping_chunks_are_named_by_entry() {
    let mut ok = vec![(100, 150, 0, 1), (10, 100, 0, 0)];
    assert_eq!(check_overlaps(&mut ok, false), Ok(()));
    let mut bad = vec![(100, 150, 0, 1), (120, 130, 1, 0), (10, 100, 0, 0)];
    let e = check_overlaps(&mut bad, true).unwrap_err();
    assert!(
        e.contains("entry 1 of part 0 (byte 100) and entry 0 of part 1 (byte 120)"),
        "{e}"
    );
}

#[test]
fn offsets_outside_the_chunk_data_are_refused() {
    assert_eq!(check_offset(200, 8, 200, 208), Ok(()));
    assert!(check_offset(0, 8, 200, 1000)
        .unwrap_err()
        .contains("missing"));
    assert!(check_offset(100, 8, 200, 1000)
        .unwrap_err()
        .contains("outside the chunk data"));
    assert!(check_offset(995, 8, 200, 1000)
        .unwrap_err()
        .contains("past the end"));
    assert!(check_offset(u64::MAX, 8, 200, 1000).is_err());
}

#[test]
fn chunk_heads_must_name_their_part_and_block() {
    assert_eq!(head_data_len(&[16, 77], 0, false, Block::Line(16)), Ok(77));
    let e = head_data_len(&[32, 77], 0, false, Block::Line(16)).unwrap_err();
    assert!(e.contains("line 32, expected line 16"), "{e}");
    assert_eq!(head_data_len(&[1, 16, 5], 1, true, Block::Line(16)), Ok(5));
    assert!(head_data_len(&[0, 16, 5], 1, true, Block::Line(16))
        .unwrap_err()
        .contains("belongs to part 0"));
    let tile = Block::Tile([1, 2, 0, 0]);
    assert_eq!(head_data_len(&[1, 2, 0, 0, 9], 0, false, tile), Ok(9));
    assert!(head_data_len(&[2, 1, 0, 0, 9], 0, false, tile)
        .unwrap_err()
        .contains("repeated or missing"));
}

#[test]
fn stored_lengths_must_be_able_to_hold_the_block() {
    assert!(length_fits(Compression::Uncompressed, 64, 64));
    assert!(!length_fits(Compression::Uncompressed, 63, 64));
    assert!(length_fits(Compression::ZIP16, 10, 64));
    assert!(!length_fits(Compression::ZIP16, 1, usize::MAX / 2));
    // Unknown ratio (PIZ): left to the decoder's own bounds.
    assert!(length_fits(Compression::PIZ, 1, usize::MAX / 2));
}

#[test]
fn zip_preprocessing_round_trips() {
    for n in [0usize, 1, 2, 3, 7, 64, 1001] {
        let raw: Vec<u8> = (0..n)
            .map(|i| (i * 37 % 251) as u8 ^ (i >> 3) as u8)
            .collect();
        let mut d = Vec::new();
        interleave_predict(&raw, &mut d);
        let mut back = vec![0u8; n];
        unpredict_deinterleave(&d, &mut back);
        assert_eq!(back, raw, "n = {n}");
    }
}

#[test]
fn gather_then_scatter_round_trips_every_layout() {
    let (w, lines) = (5usize, 3usize);
    let rows: Vec<f32> = (0..3 * w * lines).map(|i| i as f32 * 0.25 - 3.0).collect();
    // (sample types of the file's channels, which of them are R, G, B)
    let cases = [
        (vec![SampleType::F32; 3], [2, 1, 0]),
        (
            vec![
                SampleType::F16,
                SampleType::F32,
                SampleType::F32,
                SampleType::F32,
            ],
            [3, 2, 1],
        ),
        (
            vec![
                SampleType::F32,
                SampleType::F16,
                SampleType::F32,
                SampleType::U32,
            ],
            [2, 0, 1],
        ),
    ];
    for (types, rgb) in cases {
        let layout = LineLayout::new(types.iter().copied(), rgb, w);
        let rest: Vec<u8> = (0..layout.rest_line * lines).map(|i| i as u8).collect();
        let mut raw = vec![0u8; layout.line * lines];
        layout.gather(&rows, &rest, w, &mut raw);
        let mut back = vec![f32::NAN; rows.len()];
        let mut rest_back = vec![0u8; rest.len()];
        layout.scatter(&raw, &mut back, &mut rest_back, w);
        assert_eq!(rest_back, rest, "{types:?}");
        for (i, (&a, &b)) in rows.iter().zip(&back).enumerate() {
            let t = types[rgb[i % 3]];
            let want = if t == SampleType::F16 {
                f16::from_f32(a).to_f32()
            } else {
                a
            };
            assert_eq!(b, want, "{types:?} sample {i}");
        }
    }
}

#[test]
fn stored_noise_streams_inflate_to_the_block() {
    let mut deflate = libdeflater::Compressor::new(libdeflater::CompressionLvl::new(1).unwrap());
    let mut inflate = libdeflater::Decompressor::new();
    let mut state = 0x1234_5678_9abc_def0u64;
    let mut noise = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state as u8
    };
    for n in [2usize, 3, 1001, 40_000, 200_001] {
        // Noise in the first half (long enough for several stored blocks), a compressible
        // second half.
        let half = n.div_ceil(2);
        let d: Vec<u8> = (0..n)
            .map(|i| if i < half { noise() } else { (i % 7) as u8 })
            .collect();
        let mut out = vec![0u8; n + 64];
        let mut scratch = Vec::new();
        let Split::Fits(len) = zlib_storing_noise(&mut deflate, &d, &mut out, &mut scratch) else {
            panic!("n = {n}: not used");
        };
        let mut back = vec![0u8; n];
        let got = inflate.zlib_decompress(&out[..len], &mut back).unwrap();
        assert_eq!(got, n);
        assert_eq!(back, d, "n = {n}");
        // No room: refused, not truncated.
        assert_eq!(
            zlib_storing_noise(&mut deflate, &d, &mut out[..len - 1], &mut scratch),
            Split::TooLarge
        );
    }
    // A compressible first half is left to plain deflate.
    let d: Vec<u8> = (0..50_000).map(|i| (i % 5) as u8).collect();
    let mut out = vec![0u8; 60_000];
    assert_eq!(
        zlib_storing_noise(&mut deflate, &d, &mut out, &mut Vec::new()),
        Split::NotUsed
    );
}

#[test]
fn zip_preprocessing_matches_openexr() {
    // OpenEXR: interleave even/odd bytes, then t[i] - t[i-1] + 128 (first byte kept).
    let raw = [10u8, 200, 11, 201, 13];
    let mut d = Vec::new();
    interleave_predict(&raw, &mut d);
    // t = [10, 11, 13, 200, 201]
    assert_eq!(d, [10, 129, 130, 59, 129]);
}

#[test]
fn grouped_gather_and_scatter_match_sample_by_sample() {
    // Widths below, at and around the group of 8 pixels, and a row with a remainder.
    for w in (0..=20).chain([37, 64, 65]) {
        let row: Vec<f32> = (0..3 * w).map(|i| i as f32 * 0.37 - 5.0).collect();
        let (mut r, mut g, mut b) = (vec![0u8; 4 * w], vec![0u8; 4 * w], vec![0u8; 4 * w]);
        gather_f32(&row, &mut r, &mut g, &mut b);
        for (c, plane) in [&r, &g, &b].into_iter().enumerate() {
            let want: Vec<u8> = row
                .iter()
                .skip(c)
                .step_by(3)
                .flat_map(|v| v.to_le_bytes())
                .collect();
            assert_eq!(*plane, want, "width {w}, channel {c}");
        }
        let mut back = vec![f32::NAN; 3 * w];
        scatter_f32(&r, &g, &b, &mut back);
        assert_eq!(back, row, "width {w}");
    }
}
