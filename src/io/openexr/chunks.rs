//! EXR at the chunk level: the offset tables and chunk headers checked before any pixel buffer
//! exists, and the fast path for single-part scanline files.
//!
//! The `exr` crate still does the container: it parses and writes the headers (every attribute),
//! and writes the offset table. What this module adds:
//!
//! * [`Table::read`]: the offset table of every part is read and every entry checked: it points
//!   inside the file, at the chunk it should (its part number, scanline `y` or tile coordinates),
//!   whose data ends inside the file, and no two entries share or overlap a chunk. A chunk that is
//!   missing, repeated or past the end is refused with the reason, before decoding, instead of
//!   turning into black rows. Each chunk's size also bounds what it may decode to (an
//!   uncompressed chunk holds exactly its block; a ZIP chunk at most 1032× its size), so a small
//!   file cannot make the reader allocate a large frame.
//! * [`decode`] / [`Chunked::write`]: chunks read with positioned reads and (de)compressed in
//!   parallel across the cores (rayon), straight between the file's channel layout and the
//!   frame's interleaved RGB; channels other than `R`, `G`, `B` stay as raw bytes and are written
//!   back unchanged. ZIP and ZIPS go through libdeflate (`libdeflater`), with OpenEXR's byte interleave
//!   and predictor done here; RLE and PIZ blocks use the `exr` crate's codecs, block by block, in
//!   parallel.

use super::super::{IoError, Limits};
use crate::frame::{Frame, Layout};
use ::exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use ::exr::block::writer::ChunksWriter;
use ::exr::compression::Compression;
use ::exr::math::Vec2;
use ::exr::meta::attribute::{ChannelList, IntegerBounds, LineOrder, SampleType};
use ::exr::meta::header::Header;
use ::exr::meta::{BlockDescription, MetaData};
use ::exr::prelude::f16;
use rayon::prelude::*;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

/// The ZIP level written when none is asked for (libdeflate's levels, 0-12): 1, the fastest,
/// which still compresses noisy float plates about as much as the higher levels. See
/// BENCHMARKS.md.
pub const DEFAULT_ZIP_LEVEL: u8 = 1;

/// The most a deflate stream expands: 1032:1 (a 258-byte match coded in 2 bits); a margin in
/// [`max_decoded`] covers the stream's header and the last block.
const DEFLATE_MAX_RATIO: usize = 1032;
/// EXR's RLE: a count byte and one value byte expand to at most 128 bytes.
const RLE_MAX_RATIO: usize = 64;

pub(super) fn corrupt(path: &Path, why: String) -> IoError {
    IoError::Corrupt {
        path: path.to_path_buf(),
        why,
    }
}

fn read_err(path: &Path, err: std::io::Error) -> IoError {
    IoError::Read {
        path: path.to_path_buf(),
        err,
    }
}

/// Reads `buf.len()` bytes at `offset` without moving a shared cursor (so threads can share the
/// file).
fn read_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(windows)]
    {
        let mut done = 0;
        while done < buf.len() {
            match std::os::windows::fs::FileExt::seek_read(
                file,
                &mut buf[done..],
                offset + done as u64,
            )? {
                0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
                n => done += n,
            }
        }
        Ok(())
    }
}

/// Counts the bytes the header parser consumed: the offset tables start there.
struct Counting<R> {
    inner: R,
    n: u64,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let k = self.inner.read(buf)?;
        self.n += k as u64;
        Ok(k)
    }
}

/// Where one chunk's pixel data lies in the file.
#[derive(Debug, Clone, Copy)]
pub(super) struct ChunkAt {
    /// Offset of the first data byte (after the chunk's own header).
    pub data: u64,
    /// Number of data bytes.
    pub len: usize,
}

/// An EXR's headers and its checked offset tables.
#[derive(Debug)]
pub(super) struct Table {
    pub meta: MetaData,
    /// Per part, per offset-table entry (increasing-y order): its chunk.
    pub chunks: Vec<Vec<ChunkAt>>,
}

fn sample_bytes(t: SampleType) -> usize {
    match t {
        SampleType::F16 => 2,
        SampleType::F32 | SampleType::U32 => 4,
    }
}

/// Bytes per pixel of a channel list, and whether every channel is full resolution.
fn full_resolution(channels: &ChannelList) -> bool {
    channels.list.iter().all(|c| c.sampling == Vec2(1, 1))
}

/// The largest number of bytes `len` stored bytes may decode to with `compression`, if known.
fn max_decoded(compression: Compression, len: usize) -> Option<usize> {
    let ratio = match compression {
        Compression::Uncompressed => 1,
        Compression::RLE => RLE_MAX_RATIO,
        Compression::ZIP1 | Compression::ZIP16 => DEFLATE_MAX_RATIO,
        // 24-bit floats deflated: 4/3 of deflate's ratio.
        Compression::PXR24 => DEFLATE_MAX_RATIO * 4 / 3 + 1,
        _ => return None,
    };
    Some(len.saturating_mul(ratio).saturating_add(4096))
}

impl Table {
    /// Reads the headers and the offset tables of `file` and checks every entry (see the
    /// module documentation), and the frame size against `limits`.
    pub fn read(path: &Path, file: &File, limits: &Limits) -> Result<Table, IoError> {
        let file_len = file.metadata().map_err(|e| read_err(path, e))?.len();
        let exr = |err| IoError::Exr {
            path: path.to_path_buf(),
            err,
        };
        let mut counting = Counting {
            inner: BufReader::new(file),
            n: 0,
        };
        // As `exr`'s own reader does: lenient parse, then the non-pedantic validation.
        let meta = MetaData::read_from_buffered(&mut counting, true).map_err(exr)?;
        MetaData::validate(&meta.headers, false).map_err(exr)?;
        let table_start = counting.n;
        drop(counting);

        let mut pixels: u64 = 0;
        let mut stored: u64 = 0;
        for h in meta.headers.iter() {
            if h.deep {
                return Err(IoError::Unsupported {
                    path: path.to_path_buf(),
                    why: "deep data".into(),
                });
            }
            let (w, ht) = (h.layer_size.0 as u64, h.layer_size.1 as u64);
            let factor = match h.blocks {
                BlockDescription::ScanLines => 1,
                BlockDescription::Tiles(t) => match t.level_mode {
                    ::exr::meta::attribute::LevelMode::Singular => 1,
                    ::exr::meta::attribute::LevelMode::MipMap => 2,
                    ::exr::meta::attribute::LevelMode::RipMap => 4,
                },
            };
            let n = w.saturating_mul(ht).saturating_mul(factor);
            pixels = pixels.saturating_add(n);
            if h.compression == Compression::Uncompressed {
                stored = stored.saturating_add(n.saturating_mul(h.channels.bytes_per_pixel as u64));
            }
            limits.check_frame(
                path,
                w,
                ht.saturating_mul(factor),
                h.channels.list.len() as u64,
                4,
                None,
            )?;
        }
        if pixels > limits.max_pixels {
            return Err(IoError::OverLimit {
                path: path.to_path_buf(),
                why: format!(
                    "the headers claim {pixels} pixels in all, more than the limit of {} pixels",
                    limits.max_pixels
                ),
            });
        }
        if stored > file_len {
            return Err(IoError::TooLarge {
                path: path.to_path_buf(),
                why: format!(
                    "the headers claim {stored} bytes of uncompressed samples, but the file \
                     holds only {file_len} bytes"
                ),
            });
        }

        let total: usize = meta.headers.iter().map(|h| h.chunk_count).sum();
        let table_bytes = (total as u64).saturating_mul(8);
        let table_end = table_start.saturating_add(table_bytes);
        if table_end > file_len {
            return Err(corrupt(
                path,
                format!(
                    "the offset tables need {table_bytes} bytes for {total} chunks, but the file \
                     ends {} bytes after the header",
                    file_len.saturating_sub(table_start)
                ),
            ));
        }
        let mut raw = Vec::new();
        raw.try_reserve_exact(table_bytes as usize)
            .map_err(|_| IoError::TooLarge {
                path: path.to_path_buf(),
                why: format!("not enough memory for an offset table of {total} chunks"),
            })?;
        raw.resize(table_bytes as usize, 0);
        read_at(file, &mut raw, table_start).map_err(|e| read_err(path, e))?;
        let mut entries = raw
            .chunks_exact(8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));

        let multi = meta.requirements.has_multiple_layers;
        let mut spans: Vec<(u64, u64, usize, usize)> = Vec::with_capacity(total);
        let mut chunks = Vec::with_capacity(meta.headers.len());
        for (part, h) in meta.headers.iter().enumerate() {
            let mut list = Vec::with_capacity(h.chunk_count);
            let tiled = matches!(h.blocks, BlockDescription::Tiles(_));
            let head_len: u64 = if multi { 4 } else { 0 } + if tiled { 16 } else { 4 } + 4;
            let lines = h.compression.scan_lines_per_block() as i64;
            let y0 = i64::from(h.own_attributes.layer_position.1);
            let full = full_resolution(&h.channels);
            let where_ = |i: usize| {
                if multi {
                    format!("offset table entry {i} of part {part}")
                } else {
                    format!("offset table entry {i}")
                }
            };
            for (i, tile) in h.blocks_increasing_y_order().enumerate() {
                let off = entries.next().expect("table sized from the chunk counts");
                if off < table_end || off.saturating_add(head_len) > file_len {
                    return Err(corrupt(
                        path,
                        if off == 0 {
                            format!(
                                "{}: the chunk is missing (offset 0: an incomplete file)",
                                where_(i)
                            )
                        } else if off >= table_end {
                            format!(
                                "{}: the chunk at byte {off} lies past the end of the file ({file_len} bytes)",
                                where_(i)
                            )
                        } else {
                            format!(
                                "{}: offset {off} is outside the chunk data (bytes {table_end}..{file_len})",
                                where_(i)
                            )
                        },
                    ));
                }
                let mut head = [0u8; 28];
                let head = &mut head[..head_len as usize];
                read_at(file, head, off).map_err(|e| read_err(path, e))?;
                let ints: Vec<i32> = head
                    .chunks_exact(4)
                    .map(|b| i32::from_le_bytes(b.try_into().expect("4 bytes")))
                    .collect();
                let mut ints = &ints[..];
                if multi {
                    if ints[0] as i64 != part as i64 {
                        return Err(corrupt(
                            path,
                            format!("{}: the chunk there belongs to part {}", where_(i), ints[0]),
                        ));
                    }
                    ints = &ints[1..];
                }
                if tiled {
                    let want = [
                        tile.location.tile_index.0,
                        tile.location.tile_index.1,
                        tile.location.level_index.0,
                        tile.location.level_index.1,
                    ];
                    if ints[..4]
                        .iter()
                        .zip(want)
                        .any(|(&g, w)| g as i64 != w as i64)
                    {
                        return Err(corrupt(
                            path,
                            format!(
                                "{}: points at tile {:?}, expected tile {want:?} (a tile repeated or missing)",
                                where_(i),
                                &ints[..4]
                            ),
                        ));
                    }
                    ints = &ints[4..];
                } else {
                    let want = y0 + i as i64 * lines;
                    if ints[0] as i64 != want {
                        return Err(corrupt(
                            path,
                            format!(
                                "{}: points at the block of line {}, expected line {want} (a block repeated or missing)",
                                where_(i),
                                ints[0]
                            ),
                        ));
                    }
                    ints = &ints[1..];
                }
                let len = ints[0];
                let data = off + head_len;
                if len < 0 || data + len as u64 > file_len {
                    return Err(corrupt(
                        path,
                        format!(
                            "{}: the chunk at byte {off} claims {len} data bytes, past the end of the file ({file_len} bytes)",
                            where_(i)
                        ),
                    ));
                }
                let len = len as usize;
                if full {
                    let bounds = h
                        .get_absolute_block_pixel_coordinates(tile.location)
                        .map_err(exr)?;
                    let raw_len = bounds
                        .size
                        .area()
                        .saturating_mul(h.channels.bytes_per_pixel);
                    let bad = match max_decoded(h.compression, len) {
                        _ if len == raw_len => false,
                        Some(_) if h.compression == Compression::Uncompressed => true,
                        Some(max) => raw_len > max,
                        None => false,
                    };
                    if bad {
                        return Err(corrupt(
                            path,
                            format!(
                                "{}: a {} chunk of {len} bytes cannot hold a block of {raw_len} bytes",
                                where_(i),
                                h.compression
                            ),
                        ));
                    }
                }
                spans.push((off, data + len as u64, part, i));
                list.push(ChunkAt { data, len });
            }
            chunks.push(list);
        }
        spans.sort_unstable();
        for w in spans.windows(2) {
            let ((a, a_end, pa, ia), (b, _, pb, ib)) = (w[0], w[1]);
            if b < a_end {
                let what = |p: usize, i: usize| {
                    if multi {
                        format!("entry {i} of part {p}")
                    } else {
                        format!("entry {i}")
                    }
                };
                return Err(corrupt(
                    path,
                    format!(
                        "offset table {} (byte {a}) and {} (byte {b}) point into the same chunk",
                        what(pa, ia),
                        what(pb, ib)
                    ),
                ));
            }
        }
        Ok(Table { meta, chunks })
    }

    /// Whether [`decode`] handles this file: one scanline part, full-resolution channels, lines
    /// stored in increasing (or unspecified) order, compressed with none, RLE, ZIPS, ZIP or PIZ.
    pub fn fast(&self) -> bool {
        let [h] = self.meta.headers.as_slice() else {
            return false;
        };
        cfg!(target_endian = "little")
            && h.blocks == BlockDescription::ScanLines
            && h.line_order != LineOrder::Decreasing
            && full_resolution(&h.channels)
            && matches!(
                h.compression,
                Compression::Uncompressed
                    | Compression::RLE
                    | Compression::ZIP1
                    | Compression::ZIP16
                    | Compression::PIZ
            )
    }
}

/// A decoded single-part scanline EXR minus its camera RGB.
#[derive(Debug)]
pub(crate) struct Chunked {
    /// The input's header (attributes, channels, compression).
    pub header: Header,
    /// Indices of `R`, `G`, `B` and alpha in the header's channel list.
    pub rgb: [usize; 3],
    pub alpha: Option<usize>,
    /// The other channels' samples, as stored (little-endian): per line, each channel's samples.
    rest: Vec<u8>,
}

/// Where each channel of a line goes.
#[derive(Debug, Clone, Copy)]
enum Role {
    /// Frame channel 0..3.
    Rgb(usize),
    /// Byte offset in a line of [`Chunked::rest`].
    Rest(usize),
}

/// Per channel: sample type, byte offset in a file line, role; and bytes per file line and per
/// rest line.
struct LineLayout {
    channels: Vec<(SampleType, usize, Role)>,
    line: usize,
    rest_line: usize,
}

impl LineLayout {
    fn new(types: impl Iterator<Item = SampleType>, rgb: [usize; 3], width: usize) -> LineLayout {
        let mut channels = Vec::new();
        let (mut line, mut rest_line) = (0, 0);
        for (c, t) in types.enumerate() {
            let bytes = sample_bytes(t) * width;
            let role = match rgb.iter().position(|&k| k == c) {
                Some(ci) => Role::Rgb(ci),
                None => {
                    rest_line += bytes;
                    Role::Rest(rest_line - bytes)
                }
            };
            channels.push((t, line, role));
            line += bytes;
        }
        LineLayout {
            channels,
            line,
            rest_line,
        }
    }

    /// File lines (`raw`) → frame rows (interleaved RGB f32) and rest lines.
    fn scatter(&self, raw: &[u8], rows: &mut [f32], rest: &mut [u8], width: usize) {
        let lines = raw.len() / self.line.max(1);
        for l in 0..lines {
            let line = &raw[l * self.line..(l + 1) * self.line];
            let row = &mut rows[l * width * 3..(l + 1) * width * 3];
            for &(t, off, role) in &self.channels {
                let n = sample_bytes(t) * width;
                let src = &line[off..off + n];
                match role {
                    Role::Rest(o) => {
                        rest[l * self.rest_line + o..][..n].copy_from_slice(src);
                    }
                    Role::Rgb(ci) => {
                        let px = row.chunks_exact_mut(3);
                        match t {
                            SampleType::F32 => px.zip(src.chunks_exact(4)).for_each(|(p, s)| {
                                p[ci] = f32::from_le_bytes([s[0], s[1], s[2], s[3]])
                            }),
                            SampleType::F16 => px.zip(src.chunks_exact(2)).for_each(|(p, s)| {
                                p[ci] = f16::from_bits(u16::from_le_bytes([s[0], s[1]])).to_f32()
                            }),
                            SampleType::U32 => px.zip(src.chunks_exact(4)).for_each(|(p, s)| {
                                p[ci] = u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as f32
                            }),
                        }
                    }
                }
            }
        }
    }

    /// Frame rows and rest lines → file lines (`raw`, resized to fit).
    fn gather(&self, rows: &[f32], rest: &[u8], width: usize, raw: &mut Vec<u8>) {
        let lines = rows.len() / (3 * width).max(1);
        raw.clear();
        raw.resize(lines * self.line, 0);
        for l in 0..lines {
            let line = &mut raw[l * self.line..(l + 1) * self.line];
            let row = &rows[l * width * 3..(l + 1) * width * 3];
            for &(t, off, role) in &self.channels {
                let n = sample_bytes(t) * width;
                let dst = &mut line[off..off + n];
                match role {
                    Role::Rest(o) => dst.copy_from_slice(&rest[l * self.rest_line + o..][..n]),
                    Role::Rgb(ci) => {
                        let px = row.chunks_exact(3);
                        match t {
                            SampleType::F32 => dst
                                .chunks_exact_mut(4)
                                .zip(px)
                                .for_each(|(d, p)| d.copy_from_slice(&p[ci].to_le_bytes())),
                            SampleType::F16 => {
                                dst.chunks_exact_mut(2).zip(px).for_each(|(d, p)| {
                                    d.copy_from_slice(&f16::from_f32(p[ci]).to_bits().to_le_bytes())
                                })
                            }
                            SampleType::U32 => unreachable!("outputs hold float RGB"),
                        }
                    }
                }
            }
        }
    }
}

/// OpenEXR's ZIP preprocessing undone: `d` (byte-predicted, even bytes then odd bytes) → `out`.
fn unpredict_deinterleave(d: &[u8], out: &mut [u8]) {
    let half = d.len().div_ceil(2);
    let (lo, hi) = d.split_at(half);
    // t[0] = d[0], then t[i] = t[i - 1] + d[i] - 128.
    let mut prev = 128u8;
    for (o, &v) in out.iter_mut().step_by(2).zip(lo) {
        prev = prev.wrapping_add(v).wrapping_sub(128);
        *o = prev;
    }
    for (o, &v) in out.iter_mut().skip(1).step_by(2).zip(hi) {
        prev = prev.wrapping_add(v).wrapping_sub(128);
        *o = prev;
    }
}

/// OpenEXR's ZIP preprocessing in one pass, into `d`: the even bytes then the odd bytes of `raw`
/// (`t`), each replaced by its difference to the previous one in `t`, plus 128 (the first kept).
fn interleave_predict(raw: &[u8], d: &mut Vec<u8>) {
    let n = raw.len();
    d.clear();
    d.resize(n, 0);
    if n == 0 {
        return;
    }
    let half = n.div_ceil(2);
    let (lo, hi) = d.split_at_mut(half);
    let delta = |a: u8, b: u8| b.wrapping_sub(a).wrapping_add(128);
    // t[k] = raw[2k] for k < half: d[k] = raw[2k] - raw[2k - 2] + 128.
    lo[0] = raw[0];
    for ((o, p), q) in lo[1..]
        .iter_mut()
        .zip(raw.iter().step_by(2))
        .zip(raw.get(2..).unwrap_or_default().iter().step_by(2))
    {
        *o = delta(*p, *q);
    }
    // t[half + k] = raw[2k + 1]; its predecessor for k = 0 is the last even byte.
    if let Some(&first) = raw.get(1) {
        hi[0] = delta(raw[2 * (half - 1)], first);
        for ((o, p), q) in hi[1..]
            .iter_mut()
            .zip(raw[1..].iter().step_by(2))
            .zip(raw.get(3..).unwrap_or_default().iter().step_by(2))
        {
            *o = delta(*p, *q);
        }
    }
}

/// One worker's codecs (made on first use) and buffers, reused across its chunks.
struct Codec {
    level: u8,
    inflate: Option<libdeflater::Decompressor>,
    deflate: Option<libdeflater::Compressor>,
    a: Vec<u8>,
    b: Vec<u8>,
    c: Vec<u8>,
}

/// The highest deflate level libdeflate has (`--zip-level` accepts 0 to this).
pub const MAX_ZIP_LEVEL: u8 = 12;

impl Codec {
    fn new(level: u8) -> Codec {
        Codec {
            level: level.min(MAX_ZIP_LEVEL),
            inflate: None,
            deflate: None,
            a: Vec::new(),
            b: Vec::new(),
            c: Vec::new(),
        }
    }

    /// Reads the chunk `at` and decodes it into `self.a` (`raw_len` bytes of file lines).
    fn decode(
        &mut self,
        path: &Path,
        file: &File,
        header: &Header,
        at: ChunkAt,
        bounds: IntegerBounds,
        raw_len: usize,
    ) -> Result<(), IoError> {
        let bad = |why: String| {
            corrupt(
                path,
                format!("the block of line {}: {why}", bounds.position.1),
            )
        };
        self.b.clear();
        self.b.resize(at.len, 0);
        read_at(file, &mut self.b, at.data).map_err(|e| read_err(path, e))?;
        if at.len == raw_len {
            std::mem::swap(&mut self.a, &mut self.b);
            return Ok(());
        }
        match header.compression {
            Compression::ZIP1 | Compression::ZIP16 => {
                self.c.clear();
                self.c.resize(raw_len, 0);
                let inflate = self
                    .inflate
                    .get_or_insert_with(libdeflater::Decompressor::new);
                let n = inflate
                    .zlib_decompress(&self.b, &mut self.c)
                    .map_err(|e| match e {
                        libdeflater::DecompressionError::InsufficientSpace => bad(format!(
                            "the ZIP data decompresses to more than the block's {raw_len} bytes"
                        )),
                        libdeflater::DecompressionError::BadData => bad("bad ZIP data".to_string()),
                    })?;
                if n != raw_len {
                    return Err(bad(format!(
                        "the ZIP data decompresses to {n} bytes, not the block's {raw_len}"
                    )));
                }
                self.a.clear();
                self.a.resize(raw_len, 0);
                unpredict_deinterleave(&self.c, &mut self.a);
            }
            other => {
                let data = std::mem::take(&mut self.b);
                self.a = other
                    .decompress_image_section_from_le(header, data, bounds, false)
                    .map_err(|e| bad(e.to_string()))?;
                if self.a.len() != raw_len {
                    return Err(bad(format!(
                        "{} bytes decoded, expected {raw_len}",
                        self.a.len()
                    )));
                }
            }
        }
        Ok(())
    }

    /// Encodes the file lines in `self.a` into the chunk data for `header`'s compression
    /// (`self.a` is taken where the chunk stores them raw).
    fn encode(&mut self, header: &Header, bounds: IntegerBounds) -> Result<Vec<u8>, String> {
        let raw_len = self.a.len();
        match header.compression {
            Compression::Uncompressed => Ok(std::mem::take(&mut self.a)),
            Compression::ZIP1 | Compression::ZIP16 => {
                if self.level == 0 || raw_len < 2 {
                    return Ok(std::mem::take(&mut self.a));
                }
                interleave_predict(&self.a, &mut self.c);
                let level = self.level;
                let deflate = self.deflate.get_or_insert_with(|| {
                    libdeflater::Compressor::new(
                        libdeflater::CompressionLvl::new(i32::from(level)).unwrap_or_default(),
                    )
                });
                // Smaller than the raw block or not at all: a chunk as long as its block is
                // stored raw (OpenEXR's rule).
                let mut out = vec![0u8; raw_len - 1];
                match deflate.zlib_compress(&self.c, &mut out) {
                    Ok(n) => {
                        out.truncate(n);
                        Ok(out)
                    }
                    Err(libdeflater::CompressionError::InsufficientSpace) => {
                        Ok(std::mem::take(&mut self.a))
                    }
                }
            }
            other => other
                .compress_image_section_to_le(header, std::mem::take(&mut self.a), bounds)
                .map_err(|e| e.to_string()),
        }
    }
}

/// The pixel rectangle (relative to the data window) and byte size of scanline block `b`.
fn block(header: &Header, b: usize) -> Result<(IntegerBounds, usize), ::exr::error::Error> {
    let bounds =
        header.get_absolute_block_pixel_coordinates(::exr::block::chunk::TileCoordinates {
            tile_index: Vec2(0, b),
            level_index: Vec2(0, 0),
        })?;
    Ok((bounds, bounds.size.area() * header.channels.bytes_per_pixel))
}

/// An empty-or-zeroed vector of `n` elements, allocated fallibly.
fn try_zeroed<T: Clone + Default>(path: &Path, n: usize) -> Result<Vec<T>, IoError> {
    super::super::try_filled(path, n, T::default())
}

/// Decodes a file [`Table::fast`] accepts: the camera RGB (`rgb`: channel indices) into a frame,
/// everything else into the returned [`Chunked`].
pub(super) fn decode(
    path: &Path,
    file: &File,
    table: Table,
    rgb: [usize; 3],
    alpha: Option<usize>,
) -> Result<(Frame, Chunked), IoError> {
    let Table { meta, chunks } = table;
    let header = meta.headers.into_iter().next().expect("one part");
    let chunks = chunks.into_iter().next().expect("one part");
    let (width, height) = (header.layer_size.0, header.layer_size.1);
    let layout = LineLayout::new(
        header.channels.list.iter().map(|c| c.sample_type),
        rgb,
        width,
    );
    let lines = header.compression.scan_lines_per_block();
    let mut data: Vec<f32> = try_zeroed(path, 3 * width * height)?;
    let mut rest: Vec<u8> = try_zeroed(path, layout.rest_line * height)?;
    let exr = |err| IoError::Exr {
        path: path.to_path_buf(),
        err,
    };
    let rest_parts: Vec<&mut [u8]> = if layout.rest_line == 0 {
        (0..chunks.len()).map(|_| &mut [][..]).collect()
    } else {
        rest.chunks_mut(lines * layout.rest_line).collect()
    };
    if width > 0 && height > 0 {
        data.par_chunks_mut(lines * width * 3)
            .zip(rest_parts)
            .enumerate()
            .try_for_each_init(
                || Codec::new(DEFAULT_ZIP_LEVEL),
                |codec, (b, (rows, rest))| -> Result<(), IoError> {
                    let (bounds, raw_len) = block(&header, b).map_err(exr)?;
                    codec.decode(path, file, &header, chunks[b], bounds, raw_len)?;
                    layout.scatter(&codec.a, rows, rest, width);
                    Ok(())
                },
            )?;
    }
    let frame = Frame {
        width,
        height,
        layout: Layout::Rgb,
        data,
    };
    Ok((
        frame,
        Chunked {
            header,
            rgb,
            alpha,
            rest,
        },
    ))
}

impl Chunked {
    /// Bytes of pass-through samples per line, and each pass-through channel's offset there.
    fn layout(&self) -> LineLayout {
        LineLayout::new(
            self.header.channels.list.iter().map(|c| c.sample_type),
            self.rgb,
            self.header.layer_size.0,
        )
    }

    /// The alpha channel's samples as f32.
    pub fn alpha_f32(&self) -> Option<Vec<f32>> {
        let a = self.alpha?;
        let layout = self.layout();
        let (t, _, role) = layout.channels[a];
        let Role::Rest(off) = role else { return None };
        let w = self.header.layer_size.0;
        let n = sample_bytes(t) * w;
        let mut out = Vec::with_capacity(w * self.header.layer_size.1);
        for line in self.rest.chunks_exact(layout.rest_line.max(1)) {
            let s = &line[off..off + n];
            match t {
                SampleType::F32 => out.extend(
                    s.chunks_exact(4)
                        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                ),
                SampleType::F16 => out.extend(
                    s.chunks_exact(2)
                        .map(|b| f16::from_bits(u16::from_le_bytes([b[0], b[1]])).to_f32()),
                ),
                SampleType::U32 => out.extend(
                    s.chunks_exact(4)
                        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32),
                ),
            }
        }
        Some(out)
    }

    /// Writes `frame` (the corrected RGB) with the pass-through channels and the input's header,
    /// RGB now `F32` (or `F16` with `half`), compressed with `compression` (ZIP at `zip_level`),
    /// to `w`; `edit` adjusts the header's attributes first.
    pub fn write<W: std::io::Write + std::io::Seek>(
        self,
        frame: &Frame,
        w: W,
        compression: Compression,
        half: bool,
        zip_level: u8,
        edit: impl FnOnce(&mut Header),
    ) -> Result<(), ::exr::error::Error> {
        let Chunked {
            mut header,
            rgb,
            rest,
            ..
        } = self;
        let mut list = header.channels.list.clone();
        for &c in &rgb {
            list[c].sample_type = if half {
                SampleType::F16
            } else {
                SampleType::F32
            };
        }
        header.channels = ChannelList::new(list);
        let line_order = header.line_order;
        header = header.with_encoding(compression, BlockDescription::ScanLines, line_order);
        edit(&mut header);
        let width = header.layer_size.0;
        if frame.width != width
            || frame.height != header.layer_size.1
            || frame.layout != Layout::Rgb
        {
            return Err(::exr::error::Error::Invalid(
                format!(
                    "the frame is {}×{} {}, the file {}×{} RGB",
                    frame.width,
                    frame.height,
                    frame.layout.name(),
                    width,
                    header.layer_size.1
                )
                .into(),
            ));
        }
        let layout = LineLayout::new(
            header.channels.list.iter().map(|c| c.sample_type),
            rgb,
            width,
        );
        let lines = compression.scan_lines_per_block();
        let y0 = header.own_attributes.layer_position.1;
        let headers = ::exr::prelude::SmallVec::from_vec(vec![header]);
        ::exr::block::write(w, headers, true, |meta, writer| {
            let header = &meta.headers[0];
            let n = header.chunk_count;
            let batch = 4 * rayon::current_num_threads().max(1);
            for start in (0..n).step_by(batch) {
                let end = (start + batch).min(n);
                let encoded: Vec<Result<Vec<u8>, String>> = (start..end)
                    .into_par_iter()
                    .map_init(
                        || Codec::new(zip_level),
                        |codec, b| {
                            let (bounds, _) = block(header, b).map_err(|e| e.to_string())?;
                            let h = bounds.size.1;
                            let y = b * lines;
                            let rows = &frame.data[y * width * 3..(y + h) * width * 3];
                            let rest = &rest[(y * layout.rest_line).min(rest.len())
                                ..((y + h) * layout.rest_line).min(rest.len())];
                            layout.gather(rows, rest, width, &mut codec.a);
                            codec.encode(header, bounds)
                        },
                    )
                    .collect();
                for (b, data) in (start..end).zip(encoded) {
                    let data = data.map_err(|e| ::exr::error::Error::Invalid(e.into()))?;
                    writer.write_chunk(
                        b,
                        Chunk {
                            layer_index: 0,
                            compressed_block: CompressedBlock::ScanLine(CompressedScanLineBlock {
                                y_coordinate: y0 + (b * lines) as i32,
                                compressed_pixels_le: data,
                            }),
                        },
                    )?;
                }
            }
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn zip_preprocessing_matches_openexr() {
        // OpenEXR: interleave even/odd bytes, then t[i] - t[i-1] + 128 (first byte kept).
        let raw = [10u8, 200, 11, 201, 13];
        let mut d = Vec::new();
        interleave_predict(&raw, &mut d);
        // t = [10, 11, 13, 200, 201]
        assert_eq!(d, [10, 129, 130, 59, 129]);
    }
}
