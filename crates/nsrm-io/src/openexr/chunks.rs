//! EXR at the chunk level: the offset tables and chunk headers checked before any pixel buffer
//! exists, and the fast path for single-part scanline files.
//!
//! Why one file (about 1,400 lines): the offset tables, the chunk headers and the fast single-part
//! path are checked by one walk before any pixel buffer exists; the PIZ codec is `piz.rs`, the
//! tests `chunks_tests.rs`.
//!
//! The `exr` crate still does the headers: it parses and serialises them (every attribute).
//! What this module adds:
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
//!   and predictor done here; a block whose first half (the even bytes: for noisy floats the low
//!   mantissa bytes) does not compress gets that half stored, only the second half deflated
//!   ([`zlib_storing_noise`]: half the deflate time, the same size within 0.001 %). PIZ blocks
//!   are decoded and encoded natively ([`super::piz`]), RLE blocks by the `exr` crate's codec,
//!   block by block, in parallel. Each worker of a call keeps its codecs and block buffers across
//!   the call's chunks ([`Codecs`], owned by the call: no state outlives it), and a decoded frame
//!   may reuse a written frame's buffer ([`super::super::FramePool`]): no buffer is allocated,
//!   zero-filled or faulted in per chunk once a worker's have grown.
//! * [`write_chunks`]: the output file's offset table and chunks are written here, not by the
//!   `exr` crate's chunk writer: blocks are encoded a round of a few MB at a time, each straight
//!   into its place in one buffer beside its chunk header, and written with as few writes as
//!   possible (one per round when the chunks are stored raw); the offset table is filled in at the
//!   end. The bytes are those the `exr` crate writes.
//! * [`Chunked::new`]: a new file (from a TIFF or camera raw input, or a frame made in memory)
//!   goes through the same writer, with the header the `exr` crate makes for it
//!   (`super::write_new`).

use super::super::{IoError, Limits};
use crate::MAX_ZIP_LEVEL;
use ::exr::compression::Compression;
use ::exr::math::Vec2;
use ::exr::meta::attribute::{ChannelList, IntegerBounds, LineOrder, SampleType};
use ::exr::meta::header::Header;
use ::exr::meta::{BlockDescription, MetaData};
use ::exr::prelude::f16;
use nsrm::{Frame, Layout};
use rayon::prelude::*;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

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

/// `spans` (start, end, part, entry) of every chunk: an error naming two entries whose chunks
/// overlap (one chunk read twice), if any. Sorts `spans`.
fn check_overlaps(spans: &mut [(u64, u64, usize, usize)], multi: bool) -> Result<(), String> {
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
            return Err(format!(
                "offset table {} (byte {a}) and {} (byte {b}) point into the same chunk",
                what(pa, ia),
                what(pb, ib)
            ));
        }
    }
    Ok(())
}

/// An offset-table entry's name in messages.
fn entry_name(multi: bool, part: usize, i: usize) -> String {
    if multi {
        format!("offset table entry {i} of part {part}")
    } else {
        format!("offset table entry {i}")
    }
}

/// Why the chunk offset `off` cannot be right: a chunk head of `head_len` bytes must lie after
/// the offset tables (which end at `table_end`) and inside the file.
fn check_offset(off: u64, head_len: u64, table_end: u64, file_len: u64) -> Result<(), String> {
    if off >= table_end && off.saturating_add(head_len) <= file_len {
        return Ok(());
    }
    Err(if off == 0 {
        "the chunk is missing (offset 0: an incomplete file)".to_string()
    } else if off >= table_end {
        format!("the chunk at byte {off} lies past the end of the file ({file_len} bytes)")
    } else {
        format!("offset {off} is outside the chunk data (bytes {table_end}..{file_len})")
    })
}

/// The block a chunk head must name.
#[derive(Debug, Clone, Copy)]
enum Block {
    /// A tile: its tile index (x, y) and level index (x, y).
    Tile([usize; 4]),
    /// A scanline block: its first line.
    Line(i64),
}

/// The data length a chunk head declares (its integers after the offset: the part number in
/// a multi-part file, the tile or line, the length), once the head is checked to name `part`
/// and `block`.
fn head_data_len(ints: &[i32], part: usize, multi: bool, block: Block) -> Result<i32, String> {
    let mut ints = ints;
    if multi {
        if ints[0] as i64 != part as i64 {
            return Err(format!("the chunk there belongs to part {}", ints[0]));
        }
        ints = &ints[1..];
    }
    match block {
        Block::Tile(want) => {
            if ints[..4]
                .iter()
                .zip(want)
                .any(|(&g, w)| g as i64 != w as i64)
            {
                return Err(format!(
                    "points at tile {:?}, expected tile {want:?} (a tile repeated or missing)",
                    &ints[..4]
                ));
            }
            ints = &ints[4..];
        }
        Block::Line(want) => {
            if ints[0] as i64 != want {
                return Err(format!(
                    "points at the block of line {}, expected line {want} (a block repeated or missing)",
                    ints[0]
                ));
            }
            ints = &ints[1..];
        }
    }
    Ok(ints[0])
}

/// Whether a chunk of `len` stored bytes compressed with `compression` can hold a block of
/// `raw_len` bytes (unknown ratios: yes).
fn length_fits(compression: Compression, len: usize, raw_len: usize) -> bool {
    match max_decoded(compression, len) {
        _ if len == raw_len => true,
        Some(_) if compression == Compression::Uncompressed => false,
        Some(max) => raw_len <= max,
        None => true,
    }
}

/// Checks the pixel and byte counts the headers claim, before anything is allocated for them:
/// no deep data, each part and all of them within `limits`, uncompressed samples no more than
/// the file holds.
fn check_claims(
    path: &Path,
    meta: &MetaData,
    file_len: u64,
    limits: &Limits,
) -> Result<(), IoError> {
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
    Ok(())
}

/// The `total` offset-table entries starting at byte `table_start` of `file`, read once their
/// size is checked against the file's.
fn read_offsets(
    path: &Path,
    file: &File,
    table_start: u64,
    total: usize,
    file_len: u64,
) -> Result<Vec<u64>, IoError> {
    let table_bytes = (total as u64).saturating_mul(8);
    if table_start.saturating_add(table_bytes) > file_len {
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
    Ok(raw
        .chunks_exact(8)
        .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
        .collect())
}

/// One part of a file being checked: what its offset-table entries are held against.
struct PartCheck<'a> {
    path: &'a Path,
    file: &'a File,
    h: &'a Header,
    part: usize,
    multi: bool,
    table_end: u64,
    file_len: u64,
}

impl PartCheck<'_> {
    /// The chunks of this part, from its offset-table entries `offsets` (each checked: inside
    /// the file, its head naming this part and the expected block, its length possible); each
    /// chunk's span is added to `spans`.
    fn chunks(
        &self,
        offsets: &[u64],
        spans: &mut Vec<(u64, u64, usize, usize)>,
    ) -> Result<Vec<ChunkAt>, IoError> {
        let h = self.h;
        let tiled = matches!(h.blocks, BlockDescription::Tiles(_));
        let head_len: u64 = if self.multi { 4 } else { 0 } + if tiled { 16 } else { 4 } + 4;
        let lines = h.compression.scan_lines_per_block() as i64;
        let y0 = i64::from(h.own_attributes.layer_position.1);
        let full = full_resolution(&h.channels);
        let mut list = Vec::with_capacity(h.chunk_count);
        for ((i, tile), &off) in h.blocks_increasing_y_order().enumerate().zip(offsets) {
            let at = |why: String| {
                corrupt(
                    self.path,
                    format!("{}: {why}", entry_name(self.multi, self.part, i)),
                )
            };
            check_offset(off, head_len, self.table_end, self.file_len).map_err(at)?;
            let mut head = [0u8; 28];
            let head = &mut head[..head_len as usize];
            read_at(self.file, head, off).map_err(|e| read_err(self.path, e))?;
            let ints: Vec<i32> = head
                .chunks_exact(4)
                .map(|b| i32::from_le_bytes(b.try_into().expect("4 bytes")))
                .collect();
            let block = if tiled {
                let (t, l) = (tile.location.tile_index, tile.location.level_index);
                Block::Tile([t.0, t.1, l.0, l.1])
            } else {
                Block::Line(y0 + i as i64 * lines)
            };
            let len = head_data_len(&ints, self.part, self.multi, block).map_err(at)?;
            let data = off + head_len;
            if len < 0 || data + len as u64 > self.file_len {
                return Err(at(format!(
                    "the chunk at byte {off} claims {len} data bytes, past the end of the file ({} bytes)",
                    self.file_len
                )));
            }
            let len = len as usize;
            if full {
                let bounds = h
                    .get_absolute_block_pixel_coordinates(tile.location)
                    .map_err(|err| IoError::Exr {
                        path: self.path.to_path_buf(),
                        err,
                    })?;
                let raw_len = bounds
                    .size
                    .area()
                    .saturating_mul(h.channels.bytes_per_pixel);
                if !length_fits(h.compression, len, raw_len) {
                    return Err(at(format!(
                        "a {} chunk of {len} bytes cannot hold a block of {raw_len} bytes",
                        h.compression
                    )));
                }
            }
            spans.push((off, data + len as u64, self.part, i));
            list.push(ChunkAt { data, len });
        }
        Ok(list)
    }
}

impl Table {
    /// Reads the headers and the offset tables of `file` and checks every entry (see the
    /// module documentation), and the frame size against `limits`.
    pub(crate) fn read(path: &Path, file: &File, limits: &Limits) -> Result<Table, IoError> {
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
        check_claims(path, &meta, file_len, limits)?;

        let total: usize = meta.headers.iter().map(|h| h.chunk_count).sum();
        let offsets = read_offsets(path, file, table_start, total, file_len)?;
        let multi = meta.requirements.has_multiple_layers;
        let mut spans = Vec::with_capacity(total);
        let mut chunks = Vec::with_capacity(meta.headers.len());
        let mut rest = &offsets[..];
        for (part, h) in meta.headers.iter().enumerate() {
            let (mine, after) = rest.split_at(h.chunk_count.min(rest.len()));
            rest = after;
            let check = PartCheck {
                path,
                file,
                h,
                part,
                multi,
                table_end: table_start + offsets.len() as u64 * 8,
                file_len,
            };
            chunks.push(check.chunks(mine, &mut spans)?);
        }
        check_overlaps(&mut spans, multi).map_err(|why| corrupt(path, why))?;
        Ok(Table { meta, chunks })
    }

    /// Whether [`decode`] handles this file: one scanline part, full-resolution channels, lines
    /// stored in increasing (or unspecified) order, compressed with none, RLE, ZIPS, ZIP or PIZ.
    pub(crate) fn fast(&self) -> bool {
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
            let mut rgb: [Option<(SampleType, &[u8])>; 3] = [None; 3];
            for &(t, off, role) in &self.channels {
                let n = sample_bytes(t) * width;
                let src = &line[off..off + n];
                match role {
                    Role::Rest(o) => {
                        rest[l * self.rest_line + o..][..n].copy_from_slice(src);
                    }
                    Role::Rgb(ci) => rgb[ci] = Some((t, src)),
                }
            }
            if let [Some((SampleType::F32, r)), Some((SampleType::F32, g)), Some((SampleType::F32, b))] =
                rgb
            {
                // The common case in one pass over the row.
                scatter_f32(r, g, b, row);
                continue;
            }
            for (ci, c) in rgb.into_iter().enumerate() {
                let Some((t, src)) = c else { continue };
                let px = row.chunks_exact_mut(3);
                match t {
                    SampleType::F32 => px.zip(f32s(src)).for_each(|(p, v)| p[ci] = v),
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

    /// Frame rows and rest lines → file lines (`raw`: exactly their size; every byte written).
    fn gather(&self, rows: &[f32], rest: &[u8], width: usize, raw: &mut [u8]) {
        let lines = rows.len() / (3 * width).max(1);
        debug_assert_eq!(raw.len(), lines * self.line);
        for l in 0..lines {
            let mut line = &mut raw[l * self.line..(l + 1) * self.line];
            let row = &rows[l * width * 3..(l + 1) * width * 3];
            let mut rgb: [Option<(SampleType, &mut [u8])>; 3] = [None, None, None];
            // Channels lie in the line in list order: split it channel by channel.
            for &(t, _, role) in &self.channels {
                let n = sample_bytes(t) * width;
                let (dst, more) = std::mem::take(&mut line).split_at_mut(n);
                line = more;
                match role {
                    Role::Rest(o) => dst.copy_from_slice(&rest[l * self.rest_line + o..][..n]),
                    Role::Rgb(ci) => rgb[ci] = Some((t, dst)),
                }
            }
            if let [Some((SampleType::F32, r)), Some((SampleType::F32, g)), Some((SampleType::F32, b))] =
                &mut rgb
            {
                // The common case in one pass over the row.
                gather_f32(row, r, g, b);
                continue;
            }
            for (ci, c) in rgb.into_iter().enumerate() {
                let Some((t, dst)) = c else { continue };
                let px = row.chunks_exact(3);
                match t {
                    SampleType::F32 => dst
                        .chunks_exact_mut(4)
                        .zip(px)
                        .for_each(|(d, p)| d.copy_from_slice(&p[ci].to_le_bytes())),
                    SampleType::F16 => dst.chunks_exact_mut(2).zip(px).for_each(|(d, p)| {
                        d.copy_from_slice(&f16::from_f32(p[ci]).to_bits().to_le_bytes())
                    }),
                    SampleType::U32 => unreachable!("outputs hold float RGB"),
                }
            }
        }
    }
}

/// Pixels handled at once by [`scatter_f32`] and [`gather_f32`]: fixed-size groups the compiler
/// turns into whole-register loads, shuffles and stores.
const GROUP: usize = 8;

/// Three lines of little-endian f32 samples (R, G, B) → interleaved RGB `row`.
fn scatter_f32(r: &[u8], g: &[u8], b: &[u8], row: &mut [f32]) {
    let one = |p: &mut [f32], r: &[u8], g: &[u8], b: &[u8]| {
        let px = p.chunks_exact_mut(3);
        let planes = r
            .chunks_exact(4)
            .zip(g.chunks_exact(4))
            .zip(b.chunks_exact(4));
        for (p, ((r, g), b)) in px.zip(planes) {
            let f = |s: &[u8]| f32::from_le_bytes([s[0], s[1], s[2], s[3]]);
            p.copy_from_slice(&[f(r), f(g), f(b)]);
        }
    };
    let bytes = 4 * GROUP;
    let groups = r
        .chunks_exact(bytes)
        .zip(g.chunks_exact(bytes))
        .zip(b.chunks_exact(bytes));
    for (p, ((r, g), b)) in row.chunks_exact_mut(3 * GROUP).zip(groups) {
        one(p, r, g, b);
    }
    let done = row.len() / (3 * GROUP) * GROUP;
    if let (Some(p), Some(r), Some(g), Some(b)) = (
        row.get_mut(3 * done..),
        r.get(4 * done..),
        g.get(4 * done..),
        b.get(4 * done..),
    ) {
        one(p, r, g, b);
    }
}

/// Interleaved RGB `row` → three lines of little-endian f32 samples (R, G, B).
fn gather_f32(row: &[f32], r: &mut [u8], g: &mut [u8], b: &mut [u8]) {
    let one = |p: &[f32], r: &mut [u8], g: &mut [u8], b: &mut [u8]| {
        let planes = r
            .chunks_exact_mut(4)
            .zip(g.chunks_exact_mut(4))
            .zip(b.chunks_exact_mut(4));
        for (p, ((r, g), b)) in p.chunks_exact(3).zip(planes) {
            r.copy_from_slice(&p[0].to_le_bytes());
            g.copy_from_slice(&p[1].to_le_bytes());
            b.copy_from_slice(&p[2].to_le_bytes());
        }
    };
    let bytes = 4 * GROUP;
    let done = row.len() / (3 * GROUP) * GROUP;
    let groups = r
        .chunks_exact_mut(bytes)
        .zip(g.chunks_exact_mut(bytes))
        .zip(b.chunks_exact_mut(bytes));
    for (p, ((r, g), b)) in row.chunks_exact(3 * GROUP).zip(groups) {
        one(p, r, g, b);
    }
    if let (Some(p), Some(r), Some(g), Some(b)) = (
        row.get(3 * done..),
        r.get_mut(4 * done..),
        g.get_mut(4 * done..),
        b.get_mut(4 * done..),
    ) {
        one(p, r, g, b);
    }
}

/// Little-endian f32 samples.
fn f32s(s: &[u8]) -> impl Iterator<Item = f32> + '_ {
    s.chunks_exact(4)
        .map(|s| f32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// OpenEXR's ZIP preprocessing undone: `d` (byte-predicted, even bytes then odd bytes) → `out`.
/// The running sums of the two halves are kept side by side, so each output pair is written at
/// once; the second half's sum starts where the first half's ends (its total, summed first).
fn unpredict_deinterleave(d: &[u8], out: &mut [u8]) {
    let half = d.len().div_ceil(2);
    let (lo, hi) = d.split_at(half);
    // t[0] = d[0], then t[i] = t[i - 1] + d[i] - 128.
    let total = lo.iter().fold(0u8, |s, &v| s.wrapping_add(v));
    let (mut a, mut b) = (
        128u8,
        (128u8.wrapping_add(total)).wrapping_sub((half % 2 * 128) as u8),
    );
    let mut pairs = out.chunks_exact_mut(2);
    for ((o, &l), &h) in pairs.by_ref().zip(lo).zip(hi) {
        a = a.wrapping_add(l).wrapping_sub(128);
        b = b.wrapping_add(h).wrapping_sub(128);
        o[0] = a;
        o[1] = b;
    }
    if let ([last], Some(&l)) = (pairs.into_remainder(), lo.get(half.wrapping_sub(1))) {
        *last = a.wrapping_add(l).wrapping_sub(128);
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
    // t[k] = raw[2k] for k < half: d[k] = raw[2k] - raw[2k - 2] + 128; t[half + k] = raw[2k + 1],
    // whose predecessor for k = 0 is the last even byte.
    lo[0] = raw[0];
    if n >= 2 {
        hi[0] = delta(raw[2 * (half - 1)], raw[1]);
    }
    let pairs = raw.chunks_exact(2).zip(raw[2.min(n)..].chunks_exact(2));
    for ((l, h), (p, c)) in lo[1..].iter_mut().zip(hi.iter_mut().skip(1)).zip(pairs) {
        *l = delta(p[0], c[0]);
        *h = delta(p[1], c[1]);
    }
    // An odd length: the last even byte has no odd partner.
    if n % 2 == 1 && n >= 3 {
        lo[half - 1] = delta(raw[n - 3], raw[n - 1]);
    }
}

/// One worker's codecs (made on first use) and buffers, kept for the call's later chunks
/// ([`Codecs`]): no allocation, zero-filling or page fault per chunk once it has grown.
struct Codec {
    inflate: Option<libdeflater::Decompressor>,
    /// The compressor and its level.
    deflate: Option<(u8, libdeflater::Compressor)>,
    a: Vec<u8>,
    b: Vec<u8>,
    c: Vec<u8>,
    /// PIZ's 16-bit words.
    words: Vec<u16>,
}

impl Codec {
    /// No codecs made and no buffers held yet.
    const fn empty() -> Codec {
        Codec {
            inflate: None,
            deflate: None,
            a: Vec::new(),
            b: Vec::new(),
            c: Vec::new(),
            words: Vec::new(),
        }
    }
}

/// The codecs of one read or write call, shared by its workers: a chunk takes an idle one (or
/// makes one) and hands it back, so the call holds at most one per worker and a chunk allocates
/// nothing once the codecs have grown. Owned by the call and dropped with it: no state outlives a
/// frame, none is shared between calls (scratch only; every use overwrites what it reads).
#[derive(Default)]
struct Codecs(std::sync::Mutex<Vec<Codec>>);

impl Codecs {
    /// Runs `f` with an idle codec of this call.
    fn with<R>(&self, f: impl FnOnce(&mut Codec) -> R) -> R {
        let idle = self.0.lock().ok().and_then(|mut v| v.pop());
        let mut codec = idle.unwrap_or_else(Codec::empty);
        let r = f(&mut codec);
        if let Ok(mut v) = self.0.lock() {
            v.push(codec);
        }
        r
    }
}

/// `v` resized to `n` bytes; only growth is zero-filled (callers overwrite what they use).
fn sized(v: &mut Vec<u8>, n: usize) -> &mut [u8] {
    v.resize(n, 0);
    v
}

impl Codec {
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
        if at.len == raw_len {
            read_at(file, sized(&mut self.a, raw_len), at.data).map_err(|e| read_err(path, e))?;
            return Ok(());
        }
        read_at(file, sized(&mut self.b, at.len), at.data).map_err(|e| read_err(path, e))?;
        match header.compression {
            Compression::ZIP1 | Compression::ZIP16 => {
                sized(&mut self.c, raw_len);
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
                unpredict_deinterleave(&self.c, sized(&mut self.a, raw_len));
            }
            Compression::PIZ => {
                let types: Vec<SampleType> =
                    header.channels.list.iter().map(|c| c.sample_type).collect();
                super::piz::decode(
                    &self.b,
                    &types,
                    bounds.size.0,
                    bounds.size.1,
                    sized(&mut self.a, raw_len),
                    &mut self.words,
                )
                .map_err(bad)?;
            }
            other => {
                let data = self.b.clone();
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

    /// Encodes the file lines in `raw` into `out` (room for `raw.len()` bytes) as the chunk data
    /// for `header`'s compression (ZIP at `level`); returns the length written. A chunk that does
    /// not shrink is stored raw (OpenEXR's rule).
    fn encode(
        &mut self,
        header: &Header,
        bounds: IntegerBounds,
        level: u8,
        raw: &[u8],
        out: &mut [u8],
    ) -> Result<usize, String> {
        let raw_len = raw.len();
        let stored = |out: &mut [u8]| {
            out[..raw_len].copy_from_slice(raw);
            Ok(raw_len)
        };
        match header.compression {
            Compression::Uncompressed => stored(out),
            Compression::ZIP1 | Compression::ZIP16 => {
                let level = level.min(MAX_ZIP_LEVEL);
                if level == 0 || raw_len < 2 {
                    return stored(out);
                }
                interleave_predict(raw, &mut self.c);
                let deflate = match &mut self.deflate {
                    Some((l, d)) if *l == level => d,
                    slot => {
                        let d = libdeflater::Compressor::new(
                            libdeflater::CompressionLvl::new(i32::from(level)).unwrap_or_default(),
                        );
                        &mut slot.insert((level, d)).1
                    }
                };
                // Smaller than the raw block or not at all.
                let out_len = raw_len - 1;
                match zlib_storing_noise(deflate, &self.c, &mut out[..out_len], &mut self.b) {
                    Split::Fits(n) => return Ok(n),
                    Split::TooLarge => return stored(out),
                    Split::NotUsed => {}
                }
                match deflate.zlib_compress(&self.c, &mut out[..out_len]) {
                    Ok(n) => Ok(n),
                    Err(libdeflater::CompressionError::InsufficientSpace) => stored(out),
                }
            }
            Compression::PIZ => {
                let types: Vec<SampleType> =
                    header.channels.list.iter().map(|c| c.sample_type).collect();
                let (w, h) = (bounds.size.0, bounds.size.1);
                match super::piz::encode(raw, &types, w, h, &mut self.b, &mut self.words) {
                    Ok(()) if self.b.len() < raw_len => {
                        out[..self.b.len()].copy_from_slice(&self.b);
                        Ok(self.b.len())
                    }
                    Ok(()) => stored(out),
                    // Codes too long for this encoder (not seen in practice): the exr crate's.
                    Err(_) => exr_encode(Compression::PIZ, header, bounds, raw, out),
                }
            }
            other => exr_encode(other, header, bounds, raw, out),
        }
    }
}

/// Encodes `raw` with the `exr` crate's codec for `compression` into `out` (room for
/// `raw.len()` bytes); returns the length written.
fn exr_encode(
    compression: Compression,
    header: &Header,
    bounds: IntegerBounds,
    raw: &[u8],
    out: &mut [u8],
) -> Result<usize, String> {
    let data = compression
        .compress_image_section_to_le(header, raw.to_vec(), bounds)
        .map_err(|e| e.to_string())?;
    // The exr crate stores a block raw unless it shrinks.
    let n = data.len().min(raw.len());
    out[..n].copy_from_slice(&data[..n]);
    Ok(n)
}

/// How [`zlib_storing_noise`] ended.
#[derive(Debug, PartialEq)]
enum Split {
    /// The first half compresses: deflate the whole block instead.
    NotUsed,
    /// The zlib stream's length.
    Fits(usize),
    /// The stream would not be shorter than `out`.
    TooLarge,
}

/// Bytes per probe of the first half in [`zlib_storing_noise`], and how many probes.
const PROBE: usize = 4096;
const PROBES: usize = 4;

/// `d` (a block after OpenEXR's ZIP preprocessing) as one zlib stream in `out` whose first half
/// is stored, not deflated, when probes of it do not compress (by 1 % or more); the second half
/// is deflated. The first half holds the even bytes of the block: for noisy float samples the low
/// mantissa bytes, pure noise, on which deflate spends half its time to gain nothing (measured on
/// noisy plates: 1.0003× stored size); the second half holds the exponent bytes, where its gains
/// are. Any zlib reader (OpenEXR's) reads the stream: stored deflate blocks (not final), then
/// libdeflate's blocks, then the Adler-32 of all of `d`. `scratch` holds the probes' output.
fn zlib_storing_noise(
    deflate: &mut libdeflater::Compressor,
    d: &[u8],
    out: &mut [u8],
    scratch: &mut Vec<u8>,
) -> Split {
    let half = d.len().div_ceil(2);
    let (lo, hi) = d.split_at(half);
    if hi.is_empty() {
        return Split::NotUsed;
    }
    let (mut probed, mut packed) = (0usize, 0usize);
    let mut probe = |p: &[u8]| {
        let bound = deflate.deflate_compress_bound(p.len());
        let n = deflate
            .deflate_compress(p, sized(scratch, bound))
            .unwrap_or(p.len());
        probed += p.len();
        packed += n;
    };
    if lo.len() <= PROBE * PROBES {
        probe(lo);
    } else {
        for k in 0..PROBES {
            let at = k * (lo.len() - PROBE) / (PROBES - 1);
            probe(&lo[at..at + PROBE]);
        }
    }
    if packed * 100 < probed * 99 {
        return Split::NotUsed;
    }
    // zlib header: deflate, 32 KiB window, no dictionary, "fastest" (as libdeflate's level 1).
    let mut pos = 2;
    if out.len() < pos {
        return Split::TooLarge;
    }
    out[..2].copy_from_slice(&[0x78, 0x01]);
    for piece in lo.chunks(usize::from(u16::MAX)) {
        let n = piece.len() as u16;
        let Some(room) = out.get_mut(pos..pos + 5 + piece.len()) else {
            return Split::TooLarge;
        };
        // BFINAL 0, BTYPE 00 (stored), padded to the byte; LEN, NLEN.
        room[0] = 0;
        room[1..3].copy_from_slice(&n.to_le_bytes());
        room[3..5].copy_from_slice(&(!n).to_le_bytes());
        room[5..].copy_from_slice(piece);
        pos += 5 + piece.len();
    }
    let Some(end) = out.len().checked_sub(4).filter(|&e| e > pos) else {
        return Split::TooLarge;
    };
    match deflate.deflate_compress(hi, &mut out[pos..end]) {
        Ok(n) => pos += n,
        Err(libdeflater::CompressionError::InsufficientSpace) => return Split::TooLarge,
    }
    out[pos..pos + 4].copy_from_slice(&libdeflater::adler32(d).to_be_bytes());
    Split::Fits(pos + 4)
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

/// Decodes a file [`Table::fast`] accepts: the camera RGB (`rgb`: channel indices) into a frame,
/// everything else into the returned [`Chunked`].
pub(super) fn decode(
    path: &Path,
    file: &File,
    table: Table,
    rgb: [usize; 3],
    alpha: Option<usize>,
    pool: Option<&super::super::FramePool>,
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
    // Every sample is overwritten below (each block decodes to exactly its lines, or the
    // frame is dropped with the error), so a pooled buffer's old contents never show.
    let n = 3 * width * height;
    let mut data: Vec<f32> = match pool.and_then(|p| p.take(n)) {
        Some(v) => v,
        None => super::super::try_zeroed(path, n)?,
    };
    let mut rest: Vec<u8> = super::super::try_zeroed(path, layout.rest_line * height)?;
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
        let codecs = Codecs::default();
        data.par_chunks_mut(lines * width * 3)
            .zip(rest_parts)
            .enumerate()
            .try_for_each(|(b, (rows, rest))| -> Result<(), IoError> {
                let (bounds, raw_len) = block(&header, b).map_err(exr)?;
                codecs.with(|codec| {
                    codec.decode(path, file, &header, chunks[b], bounds, raw_len)?;
                    layout.scatter(&codec.a, rows, rest, width);
                    Ok(())
                })
            })?;
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
    /// A new file's parts for [`Chunked::write`]: its `header` (single-part scanline), the
    /// indices of `R`, `G`, `B` and alpha in its channel list, and the other channels' samples
    /// (`rest`: per line, each channel's samples as stored, little-endian).
    pub(crate) fn new(
        header: Header,
        rgb: [usize; 3],
        alpha: Option<usize>,
        rest: Vec<u8>,
    ) -> Chunked {
        Chunked {
            header,
            rgb,
            alpha,
            rest,
        }
    }

    /// Bytes of pass-through samples per line, and each pass-through channel's offset there.
    fn layout(&self) -> LineLayout {
        LineLayout::new(
            self.header.channels.list.iter().map(|c| c.sample_type),
            self.rgb,
            self.header.layer_size.0,
        )
    }

    /// The alpha channel's samples as f32.
    pub(crate) fn alpha_f32(&self) -> Option<Vec<f32>> {
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
    pub(crate) fn write<W: std::io::Write + std::io::Seek + Send>(
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
        let codecs = Codecs::default();
        write_chunks(w, headers, |header, b, bounds, out| {
            let h = bounds.size.1;
            let y = b * lines;
            let rows = &frame.data[y * width * 3..(y + h) * width * 3];
            let rest = &rest[(y * layout.rest_line).min(rest.len())
                ..((y + h) * layout.rest_line).min(rest.len())];
            let y = i32::try_from(y)
                .ok()
                .and_then(|y| y.checked_add(y0))
                .ok_or("line number out of range")?;
            let raw_len = out.len();
            codecs.with(|codec| {
                let n = if header.compression == Compression::Uncompressed {
                    layout.gather(rows, rest, width, out);
                    raw_len
                } else {
                    let mut raw = std::mem::take(&mut codec.a);
                    layout.gather(rows, rest, width, sized(&mut raw, raw_len));
                    let n = codec.encode(header, bounds, zip_level, &raw, out);
                    codec.a = raw;
                    n?
                };
                Ok((y, n))
            })
        })
    }
}

/// Bytes of raw block data each round of [`write_chunks`] aims at: enough blocks for every core,
/// and few large writes.
const BATCH_BYTES: usize = 4 << 20;

/// The byte ranges of a round buffer to write, in file order: consecutive chunks that filled
/// their slots lie back to back and make one range.
type Spans = Vec<(usize, usize)>;

/// Writes a single-part scanline EXR with `headers` (one): the header and offset table as the
/// `exr` crate writes them, then every block, encoded in parallel by `encode(header, index,
/// pixel bounds, out)` into `out` (room for the raw block) returning the block's first line and
/// the bytes of chunk data it left at the start of `out`. Blocks are encoded a round at a time
/// into one buffer, each beside its 8-byte chunk header, and written in as few writes as
/// possible; while one round is written, the next is encoded into a second buffer (the write, a
/// copy into the file's pages, then overlaps the encoding instead of leaving the other cores
/// idle). The offset table is filled in at the end.
fn write_chunks<W: std::io::Write + std::io::Seek + Send>(
    mut w: W,
    headers: ::exr::meta::Headers,
    encode: impl Fn(&Header, usize, IntegerBounds, &mut [u8]) -> Result<(i32, usize), String> + Sync,
) -> Result<(), ::exr::error::Error> {
    let requirements = MetaData::validate(&headers, true)?;
    if requirements.has_multiple_layers || headers.len() != 1 {
        return Err(::exr::error::Error::Invalid("one part expected".into()));
    }
    let mut head = Vec::new();
    ::exr::meta::magic_number::write(&mut head)?;
    requirements.write(&mut head)?;
    Header::write_all(&headers, &mut head, false)?;
    // Attributes sorted by name: the same frame gives the same bytes (canonical.rs).
    super::canonical::sort_attributes(&mut head);
    let header = &headers[0];
    let n = header.chunk_count;
    let table_at = head.len() as u64;
    w.write_all(&head)?;
    w.write_all(&vec![0u8; n * 8])?;
    let mut pos = table_at + n as u64 * 8;
    let mut table = vec![0u64; n];

    let mut blocks = Vec::with_capacity(n);
    for b in 0..n {
        blocks.push(block(header, b)?);
    }
    let most = blocks.iter().map(|&(_, len)| len).max().unwrap_or(0).max(1);
    let per_round = (BATCH_BYTES / most).max(4 * rayon::current_num_threads().max(1));
    // Two round buffers for the call (about BATCH_BYTES each), reused round after round: one
    // being written while the other is encoded.
    let mut rounds = [Vec::new(), Vec::new()];
    let mut pending: Spans = Vec::new();
    for (r, start) in (0..n).step_by(per_round).enumerate() {
        let end = (start + per_round).min(n);
        let [even, odd] = &mut rounds;
        let (cur, prev) = if r % 2 == 0 { (even, odd) } else { (odd, even) };
        let prev: &[u8] = prev;
        let spans = std::mem::take(&mut pending);
        let wr = &mut w;
        let (written, lens) = rayon::join(
            move || -> std::io::Result<()> {
                for (from, to) in spans {
                    wr.write_all(&prev[from..to])?;
                }
                Ok(())
            },
            || encode_round(header, &blocks[start..end], start, cur, &encode),
        );
        written?;
        // Consecutive chunks that filled their slots lie back to back: one write for them.
        let (mut from, mut to) = (0, 0);
        let mut slot_at = 0;
        for (k, len) in lens.into_iter().enumerate() {
            let len = len.map_err(|e| ::exr::error::Error::Invalid(e.into()))?;
            let b = start + k;
            table[b] = pos;
            pos += 8 + len as u64;
            if slot_at != to {
                pending.push((from, to));
                from = slot_at;
            }
            to = slot_at + 8 + len;
            slot_at += 8 + blocks[b].1;
        }
        pending.push((from, to));
    }
    let [even, odd] = &rounds;
    let last = if n.div_ceil(per_round) % 2 == 1 {
        even
    } else {
        odd
    };
    for (from, to) in pending {
        w.write_all(&last[from..to])?;
    }
    w.seek(std::io::SeekFrom::Start(table_at))?;
    let mut bytes = Vec::with_capacity(n * 8);
    for off in table {
        bytes.extend_from_slice(&off.to_le_bytes());
    }
    w.write_all(&bytes)?;
    w.flush()?;
    Ok(())
}

/// Encodes blocks `first..first + blocks.len()` in parallel into `buf`, each in its slot (its
/// 8-byte chunk header, then room for the raw block); returns each block's chunk data length.
fn encode_round(
    header: &Header,
    blocks: &[(IntegerBounds, usize)],
    first: usize,
    buf: &mut Vec<u8>,
    encode: &(impl Fn(&Header, usize, IntegerBounds, &mut [u8]) -> Result<(i32, usize), String> + Sync),
) -> Vec<Result<usize, String>> {
    let size: usize = blocks.iter().map(|&(_, len)| 8 + len).sum();
    let buf = sized(buf, size);
    let mut slots = Vec::with_capacity(blocks.len());
    let mut left = &mut buf[..];
    for &(_, len) in blocks {
        let (slot, more) = left.split_at_mut(8 + len);
        slots.push(slot);
        left = more;
    }
    slots
        .into_par_iter()
        .enumerate()
        .map(|(k, slot)| {
            let (head, out) = slot.split_at_mut(8);
            let (y, len) = encode(header, first + k, blocks[k].0, out)?;
            let len32 = i32::try_from(len).map_err(|_| "chunk too large".to_string())?;
            head[..4].copy_from_slice(&y.to_le_bytes());
            head[4..].copy_from_slice(&len32.to_le_bytes());
            Ok(len)
        })
        .collect()
}

#[cfg(test)]
#[path = "chunks_tests.rs"]
mod tests;
