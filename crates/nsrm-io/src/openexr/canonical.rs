//! Byte-reproducible EXR headers.
//!
//! The `exr` crate keeps a header's custom attributes in a `HashMap` seeded at random per
//! process, and writes them in that map's order: two runs on the same frame wrote the same
//! attributes in different orders, so the files differed byte for byte (and a farm's hashes,
//! caches and verification could not trust them). The OpenEXR format leaves the order of a
//! header's attributes free, so every header nsrm writes has its attributes sorted by name:
//! the same set of attributes always gives the same bytes. Sorting moves bytes within the
//! header only; its length and everything after it (offset tables, chunks) are unchanged.

use std::io::{Seek, SeekFrom, Write};

/// The most header bytes held back for sorting; a header longer than this (none that nsrm
/// reads passes its limits) is written as it comes.
const MAX_HEADER_BYTES: usize = 16 << 20;

/// What [`scan`] found at the start of a file's bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Scan {
    /// More bytes are needed to reach the end of the headers.
    Incomplete,
    /// Not an EXR header this module understands: left as it is.
    Malformed,
    /// The headers end at this offset; each is the list of its attributes' byte ranges,
    /// with the range the attributes occupy.
    Done(usize, Vec<Attrs>),
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct Attrs {
    start: usize,
    end: usize,
    /// (name range, whole attribute range)
    list: Vec<(std::ops::Range<usize>, std::ops::Range<usize>)>,
}

/// Bit 12 of the version field: a multi-part file (headers end with an empty header).
const MULTIPART: u32 = 0x1000;

fn cstr(b: &[u8], at: usize) -> Result<usize, Scan> {
    // A name or type: at most 255 bytes and a NUL.
    let tail = b.get(at..).ok_or(Scan::Incomplete)?;
    match tail.iter().take(256).position(|&c| c == 0) {
        Some(0) => Err(Scan::Malformed),
        Some(n) => Ok(at + n + 1),
        None if tail.len() >= 256 => Err(Scan::Malformed),
        None => Err(Scan::Incomplete),
    }
}

fn header(b: &[u8], mut at: usize) -> Result<(Attrs, usize), Scan> {
    let start = at;
    let mut list = Vec::new();
    loop {
        match b.get(at) {
            None => return Err(Scan::Incomplete),
            Some(0) => {
                return Ok((
                    Attrs {
                        start,
                        end: at,
                        list,
                    },
                    at + 1,
                ))
            }
            Some(_) => {}
        }
        let name_end = cstr(b, at)?;
        let type_end = cstr(b, name_end)?;
        let size = b
            .get(type_end..type_end + 4)
            .ok_or(Scan::Incomplete)?
            .try_into()
            .map(i32::from_le_bytes)
            .map_err(|_| Scan::Malformed)?;
        let size = usize::try_from(size).map_err(|_| Scan::Malformed)?;
        let end = type_end
            .checked_add(4 + size)
            .filter(|&e| e <= MAX_HEADER_BYTES)
            .ok_or(Scan::Malformed)?;
        if end > b.len() {
            return Err(Scan::Incomplete);
        }
        list.push((at..name_end - 1, at..end));
        at = end;
    }
}

/// Finds the headers at the start of `b` (the file's first bytes).
fn scan(b: &[u8]) -> Scan {
    if b.len() < 8 {
        return Scan::Incomplete;
    }
    if b[..4] != [0x76, 0x2f, 0x31, 0x01] {
        return Scan::Malformed;
    }
    let flags = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
    let mut at = 8;
    let mut headers = Vec::new();
    loop {
        if flags & MULTIPART != 0 {
            match b.get(at) {
                None => return Scan::Incomplete,
                Some(0) if !headers.is_empty() => return Scan::Done(at + 1, headers),
                Some(_) => {}
            }
        }
        match header(b, at) {
            Ok((h, next)) => {
                headers.push(h);
                at = next;
            }
            Err(s) => return s,
        }
        if flags & MULTIPART == 0 {
            return Scan::Done(at, headers);
        }
    }
}

/// Sorts each header's attributes by name, in place. Returns the end of the headers, or
/// `None` when `b` does not hold them all (or is not an EXR), in which case `b` is unchanged.
pub(super) fn sort_attributes(b: &mut [u8]) -> Option<usize> {
    let Scan::Done(end, headers) = scan(b) else {
        return None;
    };
    for h in headers {
        let mut list = h.list;
        list.sort_by(|x, y| b[x.0.clone()].cmp(&b[y.0.clone()]));
        let mut sorted = Vec::with_capacity(h.end - h.start);
        for (_, whole) in &list {
            sorted.extend_from_slice(&b[whole.clone()]);
        }
        b[h.start..h.end].copy_from_slice(&sorted);
    }
    Some(end)
}

/// A writer that holds back a file's first bytes until its headers are complete, sorts their
/// attributes ([`sort_attributes`]), and passes everything else straight through. Call
/// [`finish`](Self::finish) at the end.
pub(super) struct SortedHeader<W: Write + Seek> {
    inner: W,
    /// Bytes from the start of the file, while the headers are not complete.
    head: Option<Vec<u8>>,
    /// Held-back length at which the headers are looked for again (doubling, so many small
    /// writes cost linear time).
    next_scan: usize,
}

impl<W: Write + Seek> SortedHeader<W> {
    /// Wraps a writer positioned at the start of the file.
    pub(super) fn new(inner: W) -> Self {
        SortedHeader {
            inner,
            head: Some(Vec::new()),
            next_scan: 0,
        }
    }

    /// Writes what is held back, its headers sorted when they are complete.
    fn release(&mut self) -> std::io::Result<()> {
        if let Some(mut head) = self.head.take() {
            sort_attributes(&mut head);
            self.inner.write_all(&head)?;
        }
        Ok(())
    }

    /// Writes anything still held back; returns the inner writer.
    pub(super) fn finish(mut self) -> std::io::Result<W> {
        self.release()?;
        Ok(self.inner)
    }
}

impl<W: Write + Seek> Write for SortedHeader<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let Some(head) = self.head.as_mut() else {
            return self.inner.write(buf);
        };
        head.extend_from_slice(buf);
        if head.len() >= self.next_scan {
            match scan(head) {
                Scan::Incomplete if head.len() <= MAX_HEADER_BYTES => {
                    self.next_scan = head.len().saturating_mul(2).max(4096);
                }
                _ => self.release()?,
            }
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        // Held-back bytes stay held back until the headers are complete.
        self.inner.flush()
    }
}

impl<W: Write + Seek> Seek for SortedHeader<W> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        if let Some(head) = &self.head {
            if pos == SeekFrom::Current(0) {
                return Ok(self.inner.stream_position()? + head.len() as u64);
            }
            // Whatever comes next lands elsewhere: the headers are complete now or never.
            self.release()?;
        }
        self.inner.seek(pos)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attr(name: &str, ty: &str, value: &[u8]) -> Vec<u8> {
        let mut v = Vec::new();
        v.extend_from_slice(name.as_bytes());
        v.push(0);
        v.extend_from_slice(ty.as_bytes());
        v.push(0);
        v.extend_from_slice(&(value.len() as i32).to_le_bytes());
        v.extend_from_slice(value);
        v
    }

    fn file(multipart: bool, headers: &[Vec<Vec<u8>>], tail: &[u8]) -> Vec<u8> {
        let mut v = vec![0x76, 0x2f, 0x31, 0x01];
        let flags: u32 = 2 | if multipart { MULTIPART } else { 0 };
        v.extend_from_slice(&flags.to_le_bytes());
        for h in headers {
            for a in h {
                v.extend_from_slice(a);
            }
            v.push(0);
        }
        if multipart {
            v.push(0);
        }
        v.extend_from_slice(tail);
        v
    }

    #[test]
    fn attributes_are_sorted_by_name_in_every_header() {
        let a = attr("zeta", "string", b"1");
        let b = attr("alpha", "int", &7i32.to_le_bytes());
        let c = attr("mid", "string", b"");
        let tail = [0u8, 1, 2, 3, 4, 5, 6, 7];
        let mut f = file(false, &[vec![a.clone(), b.clone(), c.clone()]], &tail);
        let want = file(false, &[vec![b.clone(), c.clone(), a.clone()]], &tail);
        assert_eq!(sort_attributes(&mut f), Some(want.len() - tail.len()));
        assert_eq!(f, want);
        let mut m = file(
            true,
            &[vec![a.clone(), b.clone()], vec![a.clone(), c.clone()]],
            &tail,
        );
        let want = file(
            true,
            &[vec![b.clone(), a.clone()], vec![c.clone(), a.clone()]],
            &tail,
        );
        assert_eq!(sort_attributes(&mut m), Some(want.len() - tail.len()));
        assert_eq!(m, want);
    }

    #[test]
    fn incomplete_or_foreign_bytes_are_left_alone() {
        let full = file(
            false,
            &[vec![attr("b", "int", &[0; 4]), attr("a", "int", &[1; 4])]],
            &[],
        );
        for cut in 0..full.len() {
            let mut part = full[..cut].to_vec();
            assert_eq!(sort_attributes(&mut part), None, "cut at {cut}");
            assert_eq!(part, full[..cut]);
        }
        let mut junk = b"not an exr header at all".to_vec();
        assert_eq!(sort_attributes(&mut junk), None);
        let mut negative = full.clone();
        negative[8 + 2 + 4..8 + 2 + 4 + 4].copy_from_slice(&(-1i32).to_le_bytes());
        assert_eq!(sort_attributes(&mut negative), None);
    }

    #[test]
    fn the_writer_sorts_whatever_the_write_sizes() {
        let tail: Vec<u8> = (0..100u8).collect();
        let f = file(
            false,
            &[vec![
                attr("c", "int", &[3; 4]),
                attr("a", "int", &[1; 4]),
                attr("b", "int", &[2; 4]),
            ]],
            &tail,
        );
        let mut want = f.clone();
        sort_attributes(&mut want);
        for step in [1, 3, 7, 1000] {
            let mut w = SortedHeader::new(std::io::Cursor::new(Vec::new()));
            for piece in f.chunks(step) {
                w.write_all(piece).unwrap();
                let pos = w.stream_position().unwrap();
                assert!(pos as usize <= f.len());
            }
            // A seek back (as an offset table is filled in) after the headers went out.
            w.seek(SeekFrom::Start(f.len() as u64 - 4)).unwrap();
            w.write_all(&[9, 9, 9, 9]).unwrap();
            let out = w.finish().unwrap().into_inner();
            assert_eq!(out[..f.len() - 4], want[..f.len() - 4], "step {step}");
            assert_eq!(out[f.len() - 4..], [9, 9, 9, 9]);
        }
    }
}
