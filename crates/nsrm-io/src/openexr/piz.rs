//! A native decoder and encoder for OpenEXR's PIZ blocks of full-resolution channels (the `exr`
//! crate's codec, which decodes them to the same bytes, was several times slower both ways; it
//! stays as the encoder's fallback for Huffman codes longer than 56 bits).
//!
//! A PIZ block is, as OpenEXR's `ImfPizCompressor` and `ImfHuf` write it: a bitmap of the 16-bit
//! values present (its nonzero byte range), a Huffman stream of the values' indices in that
//! bitmap, and under the indices a 2-D Haar wavelet per channel (per 16-bit half of a 32-bit
//! channel). Decoding here: the canonical Huffman code is rebuilt from the stream's packed code
//! lengths, symbols are read from a 64-bit window (a 14-bit table for short codes, the canonical
//! first code per length for longer ones), then the wavelet is undone, the indices are mapped
//! back to values and the channels' lines are put back in file order. Any inconsistency is an
//! error, never a panic or a partial block. Encoding is the same steps backwards, the Huffman
//! code lengths from the usual least-frequent-pair merging (in linear time over the sorted
//! frequencies), so the bytes may differ from OpenEXR's where its tie-breaking differs; any PIZ
//! reader decodes them to the same pixels.

use ::exr::meta::attribute::SampleType;

const U16_RANGE: usize = 1 << 16;
const BITMAP_SIZE: usize = U16_RANGE >> 3;
/// Huffman symbols: the 16-bit values and the run-length symbol.
const ENC_SIZE: usize = U16_RANGE + 1;
/// Bits of the direct decoding table.
const TABLE_BITS: u32 = 14;
/// Longest code this decoder reads (OpenEXR allows 58; real streams stay far below).
const MAX_LEN: u32 = 56;
const SHORT_ZEROCODE_RUN: u64 = 59;
const LONG_ZEROCODE_RUN: u64 = 63;
const SHORTEST_LONG_RUN: u64 = 2 + LONG_ZEROCODE_RUN - SHORT_ZEROCODE_RUN;

/// Why a block does not decode.
pub(super) type Error = String;

/// Little-endian reader over the block.
struct Bytes<'a>(&'a [u8]);

impl<'a> Bytes<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], Error> {
        if self.0.len() < n {
            return Err("the PIZ data ends early".into());
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Ok(a)
    }

    fn u16(&mut self) -> Result<u16, Error> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> Result<u32, Error> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
}

/// Decodes the PIZ block `data` of `lines` lines of `width` pixels whose channels have `types`
/// (all full resolution) into `out`: the block's file lines, `out.len()` bytes. `words` is
/// scratch.
pub(super) fn decode(
    data: &[u8],
    types: &[SampleType],
    width: usize,
    lines: usize,
    out: &mut [u8],
    words: &mut Vec<u16>,
) -> Result<(), Error> {
    let per_pixel: usize = types.iter().map(|&t| words_of(t)).sum();
    let count = per_pixel * width * lines;
    if out.len() != 2 * count {
        return Err(format!(
            "a block of {} bytes, expected {}",
            out.len(),
            2 * count
        ));
    }
    let mut r = Bytes(data);
    let min_nz = usize::from(r.u16()?);
    let max_nz = usize::from(r.u16()?);
    if max_nz >= BITMAP_SIZE {
        return Err("PIZ bitmap out of range".into());
    }
    let mut bitmap = [0u8; BITMAP_SIZE];
    if min_nz <= max_nz {
        bitmap[min_nz..=max_nz].copy_from_slice(r.take(max_nz - min_nz + 1)?);
    }
    // The values present, in order (0 always): index -> value.
    let mut lut = vec![0u16; U16_RANGE];
    let mut k = 0usize;
    for v in 0..U16_RANGE {
        if v == 0 || bitmap[v >> 3] & (1 << (v & 7)) != 0 {
            lut[k] = v as u16;
            k += 1;
        }
    }
    let max_value = (k - 1) as u16;
    let length = r.u32()? as usize;
    let huffman = r.take(length)?;

    words.clear();
    words.resize(count, 0);
    huffman_decode(huffman, words)?;

    wavelets(words, types, width, lines, max_value, wavelet_decode);
    for w in words.iter_mut() {
        *w = lut[usize::from(*w)];
    }
    // Each channel's plane holds its lines one after the other; the file interleaves them by line.
    let starts = plane_starts(types, width, lines);
    let mut o = out.chunks_exact_mut(2);
    for y in 0..lines {
        for (&t, &s) in types.iter().zip(&starts) {
            let n = width * words_of(t);
            for (&w, d) in words[s + y * n..s + (y + 1) * n].iter().zip(o.by_ref()) {
                d.copy_from_slice(&w.to_le_bytes());
            }
        }
    }
    Ok(())
}

/// Where each channel's plane starts among a block's 16-bit words (a plane holds the channel's
/// lines one after the other; the file interleaves the channels line by line).
fn plane_starts(types: &[SampleType], width: usize, lines: usize) -> Vec<usize> {
    let mut starts = Vec::with_capacity(types.len());
    let mut at = 0;
    for &t in types {
        starts.push(at);
        at += width * lines * words_of(t);
    }
    starts
}

/// The 2-D wavelet `f` (encode or decode) over each channel's plane, per 16-bit half of a 32-bit
/// channel.
fn wavelets(
    words: &mut [u16],
    types: &[SampleType],
    width: usize,
    lines: usize,
    max_value: u16,
    f: fn(&mut [u16], usize, usize, usize, usize, u16),
) {
    for (&t, s) in types.iter().zip(plane_starts(types, width, lines)) {
        let size = words_of(t);
        let plane = &mut words[s..s + width * lines * size];
        for j in 0..size {
            f(&mut plane[j..], width, size, lines, width * size, max_value);
        }
    }
}

fn words_of(t: SampleType) -> usize {
    match t {
        SampleType::F16 => 1,
        SampleType::F32 | SampleType::U32 => 2,
    }
}

/// MSB-first bit reader over `data`, reading zeros past its end.
struct Bits<'a> {
    data: &'a [u8],
    /// Next bit to read.
    pos: usize,
}

impl Bits<'_> {
    /// The next 64 bits, left-aligned (bit 63 is the next bit).
    #[inline]
    fn peek(&self) -> u64 {
        let i = self.pos >> 3;
        let word = match self.data.get(i..i + 8) {
            Some(b) => u64::from_be_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
            None => {
                let mut b = [0u8; 8];
                let rest = self.data.get(i..).unwrap_or_default();
                b[..rest.len()].copy_from_slice(rest);
                u64::from_be_bytes(b)
            }
        };
        word << (self.pos & 7)
    }

    /// `n` (≤ 32) bits, as the low bits.
    fn read(&mut self, n: u32) -> u64 {
        let v = self.peek() >> (64 - n);
        self.pos += n as usize;
        v
    }
}

/// OpenEXR's Huffman stream (`hufUncompress`) into exactly `out.len()` symbols: the header
/// (symbol range and stream length), the packed code lengths ([`read_code_lengths`]), the
/// canonical code they define ([`Decoder::new`]), then the symbols ([`Decoder::decode`]).
fn huffman_decode(data: &[u8], out: &mut [u16]) -> Result<(), Error> {
    if data.is_empty() {
        return if out.is_empty() {
            Ok(())
        } else {
            Err("empty Huffman data".into())
        };
    }
    let mut r = Bytes(data);
    let im = r.u32()? as usize;
    let i_max = r.u32()? as usize;
    let _table_length = r.u32()?;
    let n_bits = r.u32()? as usize;
    r.take(4)?;
    if im >= ENC_SIZE || i_max >= ENC_SIZE || im > i_max {
        return Err("Huffman symbol range out of range".into());
    }
    let rest = r.0;
    let (lens, table_bits) = read_code_lengths(rest, im, i_max)?;
    let stream = &rest[table_bits.div_ceil(8)..];
    if n_bits.div_ceil(8) > stream.len() {
        return Err("the Huffman data ends early".into());
    }
    let stream = &stream[..n_bits.div_ceil(8)];
    let decoder = Decoder::new(&lens, im, i_max)?;
    decoder.decode(stream, n_bits, i_max as u32, out)
}

/// The code lengths of symbols `im..=i_max` (the others stay 0), packed MSB-first in 6 bits
/// each with runs of zeros shortened, at the start of `table`; and how many bits they took.
fn read_code_lengths(table: &[u8], im: usize, i_max: usize) -> Result<(Vec<u8>, usize), Error> {
    let mut lens = vec![0u8; ENC_SIZE];
    let mut bits = Bits {
        data: table,
        pos: 0,
    };
    let mut i = im;
    while i <= i_max {
        if bits.pos >= 8 * table.len() {
            return Err("the Huffman code table ends early".into());
        }
        let l = bits.read(6);
        if l == LONG_ZEROCODE_RUN {
            let run = (bits.read(8) + SHORTEST_LONG_RUN) as usize;
            if i + run > i_max + 1 {
                return Err("the Huffman code table is too long".into());
            }
            i += run;
        } else if l >= SHORT_ZEROCODE_RUN {
            let run = (l - SHORT_ZEROCODE_RUN + 2) as usize;
            if i + run > i_max + 1 {
                return Err("the Huffman code table is too long".into());
            }
            i += run;
        } else {
            lens[i] = l as u8;
            i += 1;
        }
    }
    if bits.pos > 8 * table.len() {
        return Err("the Huffman code table ends early".into());
    }
    Ok((lens, bits.pos))
}

/// A canonical Huffman code (`hufCanonicalCodeTable`) ready to decode: per length, the first
/// code and how many codes; codes of one length go to the symbols in increasing order.
struct Decoder {
    count: [u64; 59],
    first: [u64; 59],
    /// Symbols sorted by (length, value): those of length `l` start at `offset[l]`.
    offset: [usize; 60],
    sorted: Vec<u32>,
    /// Direct table: (length << 24 | symbol) for codes up to TABLE_BITS, 0 where longer.
    table: Vec<u32>,
    max_len: u32,
}

impl Decoder {
    /// The code of symbols `im..=i_max` with lengths `lens` (indexed by symbol).
    fn new(lens: &[u8], im: usize, i_max: usize) -> Result<Decoder, Error> {
        let mut count = [0u64; 59];
        for &l in &lens[im..=i_max] {
            count[usize::from(l)] += 1;
        }
        let mut first = [0u64; 59];
        let mut c = 0u64;
        for l in (1..=58).rev() {
            first[l] = c;
            c = (c + count[l]) >> 1;
        }
        let max_len = (1..=58).rev().find(|&l| count[l] > 0).unwrap_or(0) as u32;
        if max_len > MAX_LEN {
            return Err(format!("Huffman codes of {max_len} bits"));
        }
        for l in 1..=max_len as usize {
            if first[l] + count[l] > 1u64 << l {
                return Err("invalid Huffman code table".into());
            }
        }
        let mut offset = [0usize; 60];
        for l in 1..=58 {
            offset[l + 1] = offset[l] + count[l] as usize;
        }
        let mut sorted = vec![0u32; offset[59]];
        let mut fill = offset;
        for s in im..=i_max {
            let l = usize::from(lens[s]);
            if l > 0 {
                sorted[fill[l]] = s as u32;
                fill[l] += 1;
            }
        }
        let mut table = vec![0u32; 1 << TABLE_BITS];
        for l in 1..=TABLE_BITS.min(max_len) as usize {
            for k in 0..count[l] as usize {
                let code = first[l] + k as u64;
                let sym = sorted[offset[l] + k];
                let span = 1usize << (TABLE_BITS as usize - l);
                let start = (code as usize) << (TABLE_BITS as usize - l);
                for e in &mut table[start..start + span] {
                    if *e != 0 {
                        return Err("invalid Huffman code table".into());
                    }
                    *e = (l as u32) << 24 | sym;
                }
            }
        }
        Ok(Decoder {
            count,
            first,
            offset,
            sorted,
            table,
            max_len,
        })
    }

    /// The (length, symbol) of the code at the start of `window` (bit 63 first).
    #[inline]
    fn symbol(&self, window: u64) -> Option<(u32, u32)> {
        let e = self.table[(window >> (64 - TABLE_BITS)) as usize];
        if e != 0 {
            return Some((e >> 24, e & 0xff_ffff));
        }
        for l in TABLE_BITS + 1..=self.max_len {
            let v = window >> (64 - l);
            let (f, c) = (self.first[l as usize], self.count[l as usize]);
            if v >= f && v - f < c {
                return Some((l, self.sorted[self.offset[l as usize] + (v - f) as usize]));
            }
        }
        None
    }

    /// Decodes the `n_bits` of `stream` into exactly `out.len()` values; symbol `rlc` followed
    /// by 8 bits repeats the previous value that many more times.
    fn decode(&self, stream: &[u8], n_bits: usize, rlc: u32, out: &mut [u16]) -> Result<(), Error> {
        let mut bits = Bits {
            data: stream,
            pos: 0,
        };
        let mut n = 0usize;
        while bits.pos < n_bits {
            let (len, sym) = self.symbol(bits.peek()).ok_or("invalid Huffman code")?;
            if bits.pos + len as usize > n_bits {
                return Err("invalid Huffman code at the end of the data".into());
            }
            bits.pos += len as usize;
            if sym == rlc {
                if bits.pos + 8 > n_bits {
                    return Err("a Huffman run without its length".into());
                }
                let run = bits.read(8) as usize;
                if n == 0 {
                    return Err("a Huffman run before any value".into());
                }
                if n + run > out.len() {
                    return Err("the Huffman data decodes to too many values".into());
                }
                let v = out[n - 1];
                out[n..n + run].fill(v);
                n += run;
            } else {
                let Some(o) = out.get_mut(n) else {
                    return Err("the Huffman data decodes to too many values".into());
                };
                *o = sym as u16;
                n += 1;
            }
        }
        if n != out.len() {
            return Err(format!(
                "the Huffman data decodes to {n} values, expected {}",
                out.len()
            ));
        }
        Ok(())
    }
}

/// OpenEXR's 14-bit inverse Haar step (`wdec14`).
#[inline]
fn wdec14(l: u16, h: u16) -> (u16, u16) {
    let (ls, hs) = (l as i16 as i32, h as i16 as i32);
    let ai = ls + (hs & 1) + (hs >> 1);
    let a = ai as i16;
    let b = (ai - hs) as i16;
    (a as u16, b as u16)
}

/// OpenEXR's 16-bit (modular) inverse Haar step (`wdec16`).
#[inline]
fn wdec16(l: u16, h: u16) -> (u16, u16) {
    let (m, d) = (i32::from(l), i32::from(h));
    let b = (m - (d >> 1)) & 0xffff;
    let a = (d + b - 0x8000) & 0xffff;
    (a as u16, b as u16)
}

/// OpenEXR's inverse 2-D wavelet (`wav2Decode`) of the `nx` × `ny` plane in `v` with strides
/// `ox` (x) and `oy` (y): the levels of [`wavelet_encode`] in reverse order.
fn wavelet_decode(v: &mut [u16], nx: usize, ox: usize, ny: usize, oy: usize, max: u16) {
    let dec = if max < (1 << 14) { wdec14 } else { wdec16 };
    let n = nx.min(ny);
    let mut p = 1usize;
    while 2 * p <= n {
        p <<= 1;
    }
    // p is the largest power of two ≤ n; the encoder's levels were 1, 2, … p/2.
    p >>= 1;
    while p >= 1 {
        wavelet_level::<false>(v, nx, ox, ny, oy, p, dec);
        p >>= 1;
    }
}

/// One level of the 2-D Haar wavelet at spacing `p`: the 1-D step `f` on the pairs of every
/// 2×2 group, rows then columns when encoding and columns then rows when decoding (the inverse
/// order), and on the lone pairs of an odd last column and row.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn wavelet_level<const ENCODE: bool>(
    v: &mut [u16],
    nx: usize,
    ox: usize,
    ny: usize,
    oy: usize,
    p: usize,
    f: fn(u16, u16) -> (u16, u16),
) {
    let p2 = 2 * p;
    let (oy1, oy2, ox1, ox2) = (oy * p, oy * p2, ox * p, ox * p2);
    let mut py = 0usize;
    let ey = oy * (ny - p2);
    while py <= ey {
        let mut px = py;
        let ex = py + ox * (nx - p2);
        while px <= ex {
            let (p01, p10) = (px + ox1, px + oy1);
            let p11 = p10 + ox1;
            // Encoding pairs (00, 01) and (10, 11) first; decoding, its transpose.
            let (pa, pb) = if ENCODE { (p01, p10) } else { (p10, p01) };
            let (i00, ia) = f(v[px], v[pa]);
            let (ib, i11) = f(v[pb], v[p11]);
            (v[px], v[pb]) = f(i00, ib);
            (v[pa], v[p11]) = f(ia, i11);
            px += ox2;
        }
        if nx & p != 0 {
            let p10 = px + oy1;
            (v[px], v[p10]) = f(v[px], v[p10]);
        }
        py += oy2;
    }
    if ny & p != 0 {
        let mut px = py;
        let ex = py + ox * (nx - p2);
        while px <= ex {
            let p01 = px + ox1;
            (v[px], v[p01]) = f(v[px], v[p01]);
            px += ox2;
        }
    }
}

/// Encodes the file lines `raw` (`lines` lines of `width` pixels whose channels have `types`,
/// all full resolution) as a PIZ block into `out` (cleared first), as OpenEXR's
/// `ImfPizCompressor` does: the bitmap of the values present, their indices in it under a 2-D
/// Haar wavelet per channel (per 16-bit half of a 32-bit channel), Huffman-coded with runs.
/// `words` is scratch.
pub(super) fn encode(
    raw: &[u8],
    types: &[SampleType],
    width: usize,
    lines: usize,
    out: &mut Vec<u8>,
    words: &mut Vec<u16>,
) -> Result<(), Error> {
    let per_pixel: usize = types.iter().map(|&t| words_of(t)).sum();
    let count = per_pixel * width * lines;
    if raw.len() != 2 * count {
        return Err(format!(
            "a block of {} bytes, expected {}",
            raw.len(),
            2 * count
        ));
    }
    // The file interleaves the channels by line; each gets a plane of its lines here.
    words.clear();
    words.resize(count, 0);
    let starts = plane_starts(types, width, lines);
    let mut src = raw.chunks_exact(2);
    for y in 0..lines {
        for (&t, &s) in types.iter().zip(&starts) {
            let n = width * words_of(t);
            for (w, b) in words[s + y * n..s + (y + 1) * n]
                .iter_mut()
                .zip(src.by_ref())
            {
                *w = u16::from_le_bytes([b[0], b[1]]);
            }
        }
    }
    let mut bitmap = [0u8; BITMAP_SIZE];
    for &w in words.iter() {
        bitmap[usize::from(w >> 3)] |= 1 << (w & 7);
    }
    // Zero is not stored: always assumed present.
    bitmap[0] &= !1;
    let nonzero = bitmap.iter().position(|&b| b != 0);
    let (min_nz, max_nz) = match nonzero {
        Some(lo) => (lo, bitmap.iter().rposition(|&b| b != 0).unwrap_or(lo)),
        None => (BITMAP_SIZE - 1, 0),
    };
    // value -> index among the values present.
    let mut lut = vec![0u16; U16_RANGE];
    let mut k = 0u32;
    for (v, e) in lut.iter_mut().enumerate() {
        if v == 0 || bitmap[v >> 3] & (1 << (v & 7)) != 0 {
            *e = k as u16;
            k += 1;
        }
    }
    let max_value = (k - 1) as u16;
    for w in words.iter_mut() {
        *w = lut[usize::from(*w)];
    }
    wavelets(words, types, width, lines, max_value, wavelet_encode);

    out.clear();
    out.extend_from_slice(&(min_nz as u16).to_le_bytes());
    out.extend_from_slice(&(max_nz as u16).to_le_bytes());
    if min_nz <= max_nz {
        out.extend_from_slice(&bitmap[min_nz..=max_nz]);
    }
    let length_at = out.len();
    out.extend_from_slice(&[0; 4]);
    huffman_encode(words, out)?;
    let length = i32::try_from(out.len() - length_at - 4).map_err(|_| "PIZ block too large")?;
    out[length_at..length_at + 4].copy_from_slice(&length.to_le_bytes());
    Ok(())
}

/// MSB-first bit writer.
struct BitWriter<'a> {
    out: &'a mut Vec<u8>,
    acc: u64,
    /// Bits in `acc` not yet written (< 32 between calls).
    n: u32,
}

impl BitWriter<'_> {
    #[inline]
    fn put(&mut self, len: u32, value: u64) {
        if len > 32 {
            self.put(len - 32, value >> 32);
            self.put(32, value & 0xffff_ffff);
            return;
        }
        self.acc = self.acc << len | value;
        self.n += len;
        if self.n >= 32 {
            self.n -= 32;
            self.out
                .extend_from_slice(&((self.acc >> self.n) as u32).to_be_bytes());
        }
    }

    /// Writes the last bits (zero-padded to a byte); returns how many bits were put in all
    /// since `start` bytes.
    fn finish(self, start: usize) -> usize {
        let mut n = self.n;
        while n >= 8 {
            n -= 8;
            self.out.push((self.acc >> n) as u8);
        }
        let total = (self.out.len() - start) * 8 + n as usize;
        if n > 0 {
            self.out.push((self.acc << (8 - n)) as u8);
        }
        total
    }
}

/// Huffman code lengths for `freq` (zero for absent symbols): the usual merging of the two
/// least frequent, in linear time over the leaves sorted by frequency (two queues: leaves, and
/// merged nodes, which are made in increasing frequency).
fn code_lengths(freq: &[u32], lens: &mut [u8]) {
    let mut leaves: Vec<(u32, u32)> = freq
        .iter()
        .enumerate()
        .filter(|(_, &f)| f > 0)
        .map(|(s, &f)| (f, s as u32))
        .collect();
    let n = leaves.len();
    if n == 1 {
        lens[leaves[0].1 as usize] = 1;
        return;
    }
    if n == 0 {
        return;
    }
    leaves.sort_unstable();
    // Nodes 0..n are the sorted leaves, n.. the merged ones; parent[node].
    let mut parent = vec![u32::MAX; 2 * n - 1];
    let mut merged: Vec<u64> = Vec::with_capacity(n - 1);
    let (mut i, mut j) = (0usize, 0usize);
    let smallest = |i: &mut usize, j: &mut usize, merged: &Vec<u64>| -> (u64, usize) {
        let leaf = leaves.get(*i).map(|&(f, _)| u64::from(f));
        let node = merged.get(*j).copied();
        match (leaf, node) {
            (Some(a), Some(b)) if a <= b => {
                *i += 1;
                (a, *i - 1)
            }
            (Some(a), None) => {
                *i += 1;
                (a, *i - 1)
            }
            (_, Some(b)) => {
                *j += 1;
                (b, n + *j - 1)
            }
            (None, None) => unreachable!("n - 1 merges of n nodes"),
        }
    };
    for k in 0..n - 1 {
        let (fa, a) = smallest(&mut i, &mut j, &merged);
        let (fb, b) = smallest(&mut i, &mut j, &merged);
        parent[a] = (n + k) as u32;
        parent[b] = (n + k) as u32;
        merged.push(fa + fb);
    }
    // Parents come after their children: depths from the root down.
    let mut depth = vec![0u8; 2 * n - 1];
    for node in (0..2 * n - 2).rev() {
        depth[node] = depth[parent[node] as usize].saturating_add(1);
    }
    for (k, &(_, s)) in leaves.iter().enumerate() {
        lens[s as usize] = depth[k];
    }
}

/// OpenEXR's Huffman stream (`hufCompress`) of `data` appended to `out`.
fn huffman_encode(data: &[u16], out: &mut Vec<u8>) -> Result<(), Error> {
    if data.is_empty() {
        return Ok(());
    }
    let mut freq = vec![0u32; ENC_SIZE];
    for &v in data {
        freq[usize::from(v)] += 1;
    }
    let im = freq.iter().position(|&f| f > 0).unwrap_or(0);
    // The run-length pseudo-symbol: one past the largest value.
    let rlc = freq.iter().rposition(|&f| f > 0).unwrap_or(0) + 1;
    freq[rlc] = 1;
    let i_max = rlc;
    let mut lens = vec![0u8; ENC_SIZE];
    code_lengths(&freq, &mut lens);
    if lens.iter().any(|&l| u32::from(l) > MAX_LEN) {
        return Err("Huffman codes too long".into());
    }
    // Canonical codes, as the decoder rebuilds them.
    let mut count = [0u64; 59];
    for &l in &lens[im..=i_max] {
        count[usize::from(l)] += 1;
    }
    let mut next = [0u64; 59];
    let mut c = 0u64;
    for l in (1..=58).rev() {
        next[l] = c;
        c = (c + count[l]) >> 1;
    }
    let mut codes = vec![0u64; ENC_SIZE];
    for s in im..=i_max {
        let l = usize::from(lens[s]);
        if l > 0 {
            codes[s] = next[l];
            next[l] += 1;
        }
    }

    let start = out.len();
    out.extend_from_slice(&[0; 20]);
    // The code lengths, 6 bits each, runs of zeros shortened.
    let table_start = out.len();
    let mut w = BitWriter { out, acc: 0, n: 0 };
    let mut s = im;
    while s <= i_max {
        let l = lens[s];
        if l == 0 {
            let mut run = 1u64;
            while s < i_max && run < 255 + SHORTEST_LONG_RUN && lens[s + 1] == 0 {
                s += 1;
                run += 1;
            }
            if run >= SHORTEST_LONG_RUN {
                w.put(6, LONG_ZEROCODE_RUN);
                w.put(8, run - SHORTEST_LONG_RUN);
                s += 1;
                continue;
            } else if run >= 2 {
                w.put(6, SHORT_ZEROCODE_RUN + run - 2);
                s += 1;
                continue;
            }
        }
        w.put(6, u64::from(l));
        s += 1;
    }
    w.finish(table_start);
    let table_length = out.len() - table_start;
    let data_start = out.len();
    let mut w = BitWriter { out, acc: 0, n: 0 };
    let code = |s: usize| (u32::from(lens[s]), codes[s]);
    let (rl, rc) = code(rlc);
    let send = |w: &mut BitWriter<'_>, s: usize, run: u32| {
        let (l, c) = code(s);
        if l + rl + 8 < l * run {
            w.put(l, c);
            w.put(rl, rc);
            w.put(8, u64::from(run));
        } else {
            for _ in 0..=run {
                w.put(l, c);
            }
        }
    };
    let mut cur = usize::from(data[0]);
    let mut run = 0u32;
    for &v in &data[1..] {
        let v = usize::from(v);
        if v == cur && run < 255 {
            run += 1;
        } else {
            send(&mut w, cur, run);
            run = 0;
        }
        cur = v;
    }
    send(&mut w, cur, run);
    let n_bits = w.finish(data_start);
    let head = [
        im as u32,
        i_max as u32,
        table_length as u32,
        n_bits as u32,
        0,
    ];
    if u32::try_from(n_bits).is_err() {
        return Err("PIZ block too large".into());
    }
    for (k, v) in head.iter().enumerate() {
        out[start + 4 * k..start + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
    Ok(())
}

/// OpenEXR's 14-bit Haar step (`wenc14`).
#[inline]
fn wenc14(a: u16, b: u16) -> (u16, u16) {
    let (a, b) = (i32::from(a as i16), i32::from(b as i16));
    let m = ((a + b) >> 1) as i16;
    let d = (a - b) as i16;
    (m as u16, d as u16)
}

/// OpenEXR's 16-bit (modular) Haar step (`wenc16`).
#[inline]
fn wenc16(a: u16, b: u16) -> (u16, u16) {
    let ao = (i32::from(a) + 0x8000) & 0xffff;
    let b = i32::from(b);
    let mut m = (ao + b) >> 1;
    let d = ao - b;
    if d < 0 {
        m = (m + 0x8000) & 0xffff;
    }
    (m as u16, (d & 0xffff) as u16)
}

/// OpenEXR's 2-D wavelet (`wav2Encode`) of the `nx` × `ny` plane in `v` with strides `ox`
/// (x) and `oy` (y).
fn wavelet_encode(v: &mut [u16], nx: usize, ox: usize, ny: usize, oy: usize, max: u16) {
    let enc = if max < (1 << 14) { wenc14 } else { wenc16 };
    let n = nx.min(ny);
    let mut p = 1usize;
    while 2 * p <= n {
        wavelet_level::<true>(v, nx, ox, ny, oy, p, enc);
        p <<= 1;
    }
}

#[cfg(test)]
#[path = "piz_tests.rs"]
mod tests;
