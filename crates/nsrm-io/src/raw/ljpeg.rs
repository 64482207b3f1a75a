//! The JPEG streams of a TIFF-based raw (DNG Compression 7, lossless JPEG; 34892, lossy JPEG),
//! checked from the streams themselves before the decoder sees them.
//!
//! rawler allocates the size a stream's SOF declares (not the tile's), and its bit reader
//! returns zeros past the end of the data, as its Huffman decoder does for a code no table
//! holds: a 529-byte file declaring 65535×65535 ran 43 s at 8.4 GB, and streams with no data, an
//! empty Huffman table or 10 bytes for 4096² samples became frames of invented pixels. So every
//! strip or tile is checked here: the tiling covers the image (no tile larger than the image
//! rounded up to the 16 pixels DNG tiles come in), the SOF's samples are the tile's (a
//! lossless stream) or its pixels at most the tile's (a lossy one), each within `max_pixels`;
//! every table a scan uses is defined and holds codes; and the entropy-coded data of a lossless
//! stream is walked code by code (no prediction, nothing stored) to the last sample the SOF
//! declares: data that runs out or a code no table holds is an error, not zeros.

/// DNG Compression 7 (JPEG, lossless in raw IFDs) and 34892 (lossy JPEG).
const LOSSLESS: u32 = 7;
const LOSSY: u32 = 34892;
/// IFDs visited at most.
const MAX_IFDS: usize = 64;
/// Strips or tiles checked at most in one IFD (a 100-megapixel frame in 256² tiles has ~1500).
const MAX_SEGMENTS: usize = 1 << 16;

/// Checks every JPEG-compressed strip or tile of the TIFF in `b`; `Err(why)` when one is
/// damaged or declares more than the frame. Not a TIFF, or no JPEG in it: `Ok`.
pub(super) fn check(b: &[u8], max_pixels: u64) -> Result<(), String> {
    let Some(t) = Tiff::new(b) else {
        return Ok(());
    };
    let mut queue = vec![t.u32(4).unwrap_or(0) as usize];
    let mut seen = std::collections::HashSet::new();
    while let Some(off) = queue.pop() {
        if off < 8 || seen.len() >= MAX_IFDS || !seen.insert(off) {
            continue;
        }
        let Some(ifd) = t.ifd(off) else { continue };
        if let Some(next) = ifd.next {
            queue.push(next);
        }
        queue.extend(
            t.values(&ifd, 330)
                .into_iter()
                .take(MAX_IFDS)
                .map(|v| v as usize),
        );
        let compression = t.values(&ifd, 259).first().copied().unwrap_or(1);
        if compression == LOSSLESS || compression == LOSSY {
            check_ifd(&t, &ifd, compression == LOSSLESS, max_pixels).map_err(|why| {
                format!("the JPEG-compressed image of the IFD at byte {off}: {why}")
            })?;
        }
    }
    Ok(())
}

/// A TIFF's bytes and byte order.
struct Tiff<'a> {
    b: &'a [u8],
    le: bool,
}

/// One IFD's entries (tag, type, count, value-or-offset field) and the next IFD.
struct Ifd {
    entries: Vec<(u16, u16, u32, usize)>,
    next: Option<usize>,
}

impl<'a> Tiff<'a> {
    fn new(b: &'a [u8]) -> Option<Tiff<'a>> {
        let le = match b.get(..4)? {
            b"II*\0" => true,
            b"MM\0*" => false,
            _ => return None,
        };
        Some(Tiff { b, le })
    }

    fn u16(&self, at: usize) -> Option<u16> {
        let s: [u8; 2] = self.b.get(at..at.checked_add(2)?)?.try_into().ok()?;
        Some(if self.le {
            u16::from_le_bytes(s)
        } else {
            u16::from_be_bytes(s)
        })
    }

    fn u32(&self, at: usize) -> Option<u32> {
        let s: [u8; 4] = self.b.get(at..at.checked_add(4)?)?.try_into().ok()?;
        Some(if self.le {
            u32::from_le_bytes(s)
        } else {
            u32::from_be_bytes(s)
        })
    }

    fn ifd(&self, off: usize) -> Option<Ifd> {
        let n = usize::from(self.u16(off)?);
        let mut entries = Vec::with_capacity(n.min(4096));
        for i in 0..n {
            let e = off + 2 + 12 * i;
            entries.push((self.u16(e)?, self.u16(e + 2)?, self.u32(e + 4)?, e + 8));
        }
        let next = self
            .u32(off + 2 + 12 * n)
            .filter(|&v| v != 0)
            .map(|v| v as usize);
        Some(Ifd { entries, next })
    }

    /// The values of `tag` (SHORT or LONG; at most [`MAX_SEGMENTS`]); empty when absent or
    /// past the end.
    fn values(&self, ifd: &Ifd, tag: u16) -> Vec<u32> {
        let Some(&(_, typ, n, field)) = ifd.entries.iter().find(|e| e.0 == tag) else {
            return Vec::new();
        };
        let size = match typ {
            3 => 2,
            4 | 13 => 4,
            _ => return Vec::new(),
        };
        let n = (n as usize).min(MAX_SEGMENTS);
        let at = if n * size <= 4 {
            field
        } else {
            match self.u32(field) {
                Some(o) => o as usize,
                None => return Vec::new(),
            }
        };
        (0..n)
            .map_while(|i| {
                if size == 2 {
                    self.u16(at + 2 * i).map(u32::from)
                } else {
                    self.u32(at + 4 * i)
                }
            })
            .collect()
    }

    fn one(&self, ifd: &Ifd, tag: u16) -> Option<u64> {
        self.values(ifd, tag).first().map(|&v| u64::from(v))
    }
}

/// The strips or tiles of one JPEG-compressed IFD.
fn check_ifd(t: &Tiff, ifd: &Ifd, lossless: bool, max_pixels: u64) -> Result<(), String> {
    let w = t.one(ifd, 256).ok_or("no ImageWidth")?;
    let h = t.one(ifd, 257).ok_or("no ImageLength")?;
    let spp = t.one(ifd, 277).unwrap_or(1).max(1);
    if w == 0 || h == 0 || w.saturating_mul(h) > max_pixels {
        return Err(format!("{w}×{h} pixels (the limit is {max_pixels})"));
    }
    // (width, height) of each segment, its offset and byte count.
    let (sizes, offsets, counts): (Vec<(u64, u64)>, _, _) =
        if let (Some(tw), Some(th)) = (t.one(ifd, 322), t.one(ifd, 323)) {
            let round = |v: u64| v.max(16).next_multiple_of(16);
            if tw == 0 || th == 0 || tw > round(w) || th > round(h) {
                return Err(format!("tiles of {tw}×{th} for an image of {w}×{h}"));
            }
            let n = w.div_ceil(tw) * h.div_ceil(th);
            let sizes = vec![(tw, th); n.min(MAX_SEGMENTS as u64) as usize];
            (sizes, t.values(ifd, 324), t.values(ifd, 325))
        } else {
            let rps = t.one(ifd, 278).unwrap_or(h).clamp(1, h);
            let sizes = (0..h.div_ceil(rps).min(MAX_SEGMENTS as u64))
                .map(|i| (w, rps.min(h - i * rps)))
                .collect();
            (sizes, t.values(ifd, 273), t.values(ifd, 279))
        };
    if sizes.len() >= MAX_SEGMENTS {
        return Err(format!("more than {MAX_SEGMENTS} strips or tiles"));
    }
    if offsets.len() < sizes.len() || counts.len() < sizes.len() {
        return Err(format!(
            "{} strips or tiles (offsets for {}, byte counts for {})",
            sizes.len(),
            offsets.len(),
            counts.len()
        ));
    }
    for (i, &(sw, sh)) in sizes.iter().enumerate() {
        let (o, c) = (offsets[i] as usize, counts[i] as usize);
        let seg = o
            .checked_add(c)
            .and_then(|end| t.b.get(o..end))
            .ok_or_else(|| format!("strip or tile {i} runs past the end of the file"))?;
        check_stream(seg, sw * sh * spp, sw * sh, lossless, max_pixels)
            .map_err(|why| format!("strip or tile {i}: {why}"))?;
    }
    Ok(())
}

/// A JPEG stream's frame header, its tables and where its scan's data starts.
#[derive(Default)]
struct Stream {
    sof: Option<(u8, u64, u64, usize)>,
    /// Per table id 0–3: the code counts by length (1–16) and the values.
    tables: [Option<([u8; 16], Vec<u8>)>; 4],
    /// The scan's components' table ids, in order.
    scan: Vec<usize>,
    restart: bool,
    data: usize,
}

/// Reads markers up to the scan's data.
fn parse(s: &[u8]) -> Result<Stream, String> {
    if !s.starts_with(&[0xFF, 0xD8]) {
        return Err("no JPEG start-of-image".into());
    }
    let mut st = Stream::default();
    let mut at = 2;
    loop {
        while s.get(at) == Some(&0xFF) && s.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let (Some(&0xFF), Some(&m)) = (s.get(at), s.get(at + 1)) else {
            return Err("the stream ends before its scan".into());
        };
        let len = s
            .get(at + 2..at + 4)
            .map(|l| usize::from(u16::from_be_bytes([l[0], l[1]])))
            .filter(|&l| l >= 2)
            .ok_or("a marker segment without its length")?;
        let body = s
            .get(at + 4..at + 2 + len)
            .ok_or("a marker segment runs past the end of the stream")?;
        match m {
            0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => {
                let [_, h0, h1, w0, w1, n, ..] = body else {
                    return Err("a short frame header".into());
                };
                let (h, w) = (
                    u16::from_be_bytes([*h0, *h1]),
                    u16::from_be_bytes([*w0, *w1]),
                );
                st.sof = Some((m, u64::from(w), u64::from(h), usize::from(*n)));
            }
            0xC4 => parse_dht(body, &mut st.tables)?,
            0xDD => st.restart = body.get(..2).is_some_and(|r| r != [0, 0]),
            0xDA => {
                let n = usize::from(*body.first().ok_or("an empty scan header")?);
                st.scan = (0..n)
                    .map(|i| body.get(2 + 2 * i).map(|t| usize::from(t >> 4)))
                    .collect::<Option<_>>()
                    .ok_or("a short scan header")?;
                st.data = at + 2 + len;
                return Ok(st);
            }
            0xD9 => return Err("the stream ends before its scan".into()),
            _ => {}
        }
        at += 2 + len;
    }
}

fn parse_dht(mut b: &[u8], tables: &mut [Option<([u8; 16], Vec<u8>)>; 4]) -> Result<(), String> {
    while let [tc_th, rest @ ..] = b {
        let id = usize::from(tc_th & 0x0F);
        let counts: [u8; 16] = rest
            .get(..16)
            .and_then(|c| c.try_into().ok())
            .ok_or("a short Huffman table")?;
        let n: usize = counts.iter().map(|&c| usize::from(c)).sum();
        let values = rest.get(16..16 + n).ok_or("a short Huffman table")?;
        if id > 3 {
            return Err(format!("Huffman table id {id}"));
        }
        if n == 0 {
            return Err(format!("Huffman table {id} holds no code"));
        }
        tables[id] = Some((counts, values.to_vec()));
        b = &rest[16 + n..];
    }
    Ok(())
}

/// One strip or tile of `samples` samples (`pixels` pixels).
fn check_stream(
    s: &[u8],
    samples: u64,
    pixels: u64,
    lossless: bool,
    max_pixels: u64,
) -> Result<(), String> {
    let st = parse(s)?;
    let (marker, w, h, n) = st.sof.ok_or("no frame header before the scan")?;
    let declared = w * h * n as u64;
    if w * h > max_pixels {
        return Err(format!(
            "its stream declares {w}×{h} (the limit is {max_pixels} pixels)"
        ));
    }
    if !lossless {
        return if w * h <= pixels {
            Ok(())
        } else {
            Err(format!(
                "its stream declares {w}×{h}, more than its {pixels} pixels"
            ))
        };
    }
    if marker != 0xC3 {
        return Err(format!(
            "a lossless image whose stream is not lossless (SOF {marker:#04X})"
        ));
    }
    if declared != samples || n == 0 {
        return Err(format!(
            "its stream declares {w}×{h}×{n} = {declared} samples for {samples}"
        ));
    }
    if st.scan.len() != n {
        return Err(format!("a scan of {} components for {n}", st.scan.len()));
    }
    let mut codes = Vec::with_capacity(n);
    for &id in &st.scan {
        let (counts, values) = st
            .tables
            .get(id)
            .and_then(Option::as_ref)
            .ok_or_else(|| format!("Huffman table {id} used, not defined"))?;
        codes.push(Codes::new(counts, values));
    }
    if st.restart {
        // Restart intervals: the data is not walked (rawler's reader stops at markers).
        return Ok(());
    }
    walk(&s[st.data..], &codes, w * h)
}

/// A canonical Huffman code: per length, its first and last code and the index of its first
/// value.
struct Codes {
    first: [i32; 17],
    last: [i32; 17],
    index: [usize; 17],
    values: Vec<u8>,
}

impl Codes {
    fn new(counts: &[u8; 16], values: &[u8]) -> Codes {
        let (mut first, mut last, mut index) = ([0; 17], [-1; 17], [0; 17]);
        let (mut code, mut k) = (0i32, 0usize);
        for len in 1..=16 {
            let c = i32::from(counts[len - 1]);
            first[len] = code;
            index[len] = k;
            if c > 0 {
                last[len] = code + c - 1;
            }
            code = (code + c) << 1;
            k += c as usize;
        }
        Codes {
            first,
            last,
            index,
            values: values.to_vec(),
        }
    }

    /// The next value (an SSSS: how many bits of difference follow).
    fn next(&self, bits: &mut Bits) -> Result<u8, String> {
        let mut code = 0i32;
        for len in 1..=16 {
            code = (code << 1) | bits.take(1)? as i32;
            if code <= self.last[len] && code >= self.first[len] {
                let i = self.index[len] + (code - self.first[len]) as usize;
                return self
                    .values
                    .get(i)
                    .copied()
                    .ok_or_else(|| "a short Huffman table".into());
            }
        }
        Err(format!(
            "a code no Huffman table holds at byte {} of the data",
            bits.pos
        ))
    }
}

/// The entropy-coded data, MSB first, with 0xFF 0x00 unstuffed; it ends at a marker.
struct Bits<'a> {
    d: &'a [u8],
    pos: usize,
    acc: u64,
    n: u32,
    done: u64,
}

impl Bits<'_> {
    fn take(&mut self, k: u32) -> Result<u32, String> {
        while self.n < k {
            let b = match self.d.get(self.pos) {
                Some(0xFF) if self.d.get(self.pos + 1) == Some(&0) => {
                    self.pos += 2;
                    0xFF
                }
                Some(0xFF) | None => {
                    return Err(format!("its data runs out after {} samples", self.done))
                }
                Some(&b) => {
                    self.pos += 1;
                    b
                }
            };
            self.acc = (self.acc << 8) | u64::from(b);
            self.n += 8;
        }
        self.n -= k;
        Ok(((self.acc >> self.n) & ((1u64 << k) - 1)) as u32)
    }
}

/// Walks `pixels` pixels of interleaved samples, one code (and its difference bits) each.
fn walk(data: &[u8], codes: &[Codes], pixels: u64) -> Result<(), String> {
    let mut bits = Bits {
        d: data,
        pos: 0,
        acc: 0,
        n: 0,
        done: 0,
    };
    for _ in 0..pixels {
        for c in codes {
            let ssss = c.next(&mut bits)?;
            match ssss {
                0 | 16 => {}
                1..=15 => {
                    bits.take(u32::from(ssss))?;
                }
                _ => return Err(format!("a difference of {ssss} bits")),
            }
            bits.done += 1;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lossless stream of `w`×`h`, one component, every difference coded in `code_bits`
    /// bits of SSSS 0 (the table: 17 values of 5 bits).
    fn stream(w: u16, h: u16, data: &[u8]) -> Vec<u8> {
        let mut s = vec![0xFF, 0xD8, 0xFF, 0xC3, 0, 11, 16];
        s.extend_from_slice(&h.to_be_bytes());
        s.extend_from_slice(&w.to_be_bytes());
        s.extend_from_slice(&[1, 1, 0x11, 0]);
        let mut counts = [0u8; 16];
        counts[4] = 17;
        s.extend_from_slice(&[0xFF, 0xC4, 0, (2 + 1 + 16 + 17) as u8, 0]);
        s.extend_from_slice(&counts);
        s.extend(0u8..17);
        s.extend_from_slice(&[0xFF, 0xDA, 0, 8, 1, 1, 0, 1, 0, 0]);
        s.extend_from_slice(data);
        s.extend_from_slice(&[0xFF, 0xD9]);
        s
    }

    #[test]
    fn a_stream_is_walked_to_its_last_sample() {
        // 8 samples of SSSS 0 (code 00000): 40 bits = 5 bytes.
        let ok = stream(4, 2, &[0; 5]);
        assert_eq!(check_stream(&ok, 8, 8, true, 100), Ok(()));
        // One byte short: the data runs out.
        let short = stream(4, 2, &[0; 4]);
        let e = check_stream(&short, 8, 8, true, 100).unwrap_err();
        assert!(e.contains("runs out after 6 samples"), "{e}");
        // Code 11111 is no table's.
        let bad = stream(4, 2, &[0xFF, 0, 0xFF, 0, 0xFF, 0, 0xFF, 0, 0xFF, 0]);
        let e = check_stream(&bad, 8, 8, true, 100).unwrap_err();
        assert!(e.contains("no Huffman table holds"), "{e}");
        // A frame header of another size than the tile, or over the limit.
        let e = check_stream(&ok, 16, 16, true, 100).unwrap_err();
        assert!(e.contains("8 samples for 16"), "{e}");
        let e = check_stream(&stream(65535, 65535, &[0; 5]), 8, 8, true, 1 << 28).unwrap_err();
        assert!(e.contains("65535×65535"), "{e}");
    }

    #[test]
    fn an_empty_or_missing_table_is_refused() {
        let mut s = stream(4, 2, &[0; 5]);
        // The table's 17 codes of length 5 → none.
        let at = s.windows(2).position(|w| w == [0xFF, 0xC4]).unwrap() + 5 + 4;
        s[at] = 0;
        assert!(check_stream(&s, 8, 8, true, 100)
            .unwrap_err()
            .contains("no code"));
        let mut s = stream(4, 2, &[0; 5]);
        let sos = s.windows(2).position(|w| w == [0xFF, 0xDA]).unwrap();
        s[sos + 6] = 0x20;
        let e = check_stream(&s, 8, 8, true, 100).unwrap_err();
        assert!(e.contains("table 2 used, not defined"), "{e}");
    }
}
