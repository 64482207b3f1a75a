//! Image sizes declared by raw containers, read before the decoder runs.
//!
//! Why one file (about 1,000 lines): every container's size walk (TIFF/DNG IFDs and their tiles,
//! the lossless-JPEG streams inside them, CR3's ISO-BMFF boxes) shares one bounded reader, one
//! cycle guard and one error type; the parts are kept together so no walk can skip a bound the
//! others apply.
//!
//! rawler allocates what a header claims (the mosaic, and in ISO-BMFF files every table an entry
//! count announces) before it finds out whether the file holds that much. So the headers are read
//! here first, every read bounded by the file (or the enclosing box / region), and the largest
//! declared image is checked against `--max-pixels`; a count or a box that reaches past what
//! encloses it marks the file damaged. What is read, per container (layouts as rawler reads them,
//! after the public descriptions: ISO/IEC 14496-12 and lclevy's "Canon CR3" for CR3, the RAF
//! notes of dcraw / LibRaw for RAF, dcraw's for MRW, CIFF 1.0r4 for CRW, Sigma's X3F 2.x):
//!
//! * **CR3** (ISO-BMFF): the box tree `moov/trak/mdia/minf/stbl/stsd`; each `CRAW` sample entry's
//!   width and height, its `CMP1` box's image and tile sizes; the sample tables' entry counts
//!   (`stts`, `stsc`, `stsz`, `stco`, `co64`, Canon's `CTMD`) against their boxes; the TIFF
//!   structures in the `CMT1`–`CMT4` boxes as TIFF-based raws are checked.
//! * **RAF**: the header's three pointers; the RAF directory's full and raw image sizes
//!   (tags 0x100, 0x121) and sensor layout (0x130: a SuperCCD sensor, whose mosaic the decoder
//!   turns by 45° into a second image of about (w + h/2)² pixels, declares that image too; as
//!   rawler turns by the camera the file names, whatever the tag says, `decode` checks that
//!   image again once rawler has named the camera, [`Declared::turned`]); the
//!   TIFF structure of the CFA record (with the Fuji IFD 0xF000 and its
//!   raw width / height 0xF001 / 0xF002) and the embedded JPEG's EXIF TIFF, as TIFF-based raws.
//! * **MRW**: the PRD block's sensor height and width (blocks bounded by the data offset).
//! * **CRW** (CIFF heaps, depth ≤ 8): every SensorInfo record's width and height.
//! * **X3F**: the directory at the offset the last four bytes give; every image section's size.
//! * **ORF, RW2** (TIFF with Olympus' or Panasonic's magic): the TIFF walk, with Panasonic's
//!   sensor width / height (tags 2, 3) in the first IFD.
//!
//! A container whose headers declare no image size is refused before decoding (the decoder
//! would find none either, or find it somewhere nsrm has not checked).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

/// What a container's headers declare.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub(crate) struct Declared {
    /// The largest image declared (width, height), by pixel count.
    pub(crate) largest: Option<(u64, u64)>,
    /// The first structural damage found (a box, entry or table reaching past its end).
    pub(crate) bad: Option<String>,
    /// Whether the file's TIFF structures mark it as raw (DNG version, CFA or linear-raw image).
    pub(crate) raw_marker: bool,
    /// The largest width and the largest height declared (of any images).
    pub(crate) sides: (u64, u64),
    /// A RAF: the side of the square image its mosaic becomes when the decoder turns it by 45°
    /// (a SuperCCD sensor). Declared in `largest` when the sensor-layout tag says SuperCCD; the
    /// decoder turns by the camera named, so `decode` checks it again once it knows that camera.
    pub(crate) turned: Option<u64>,
}

impl Declared {
    pub(crate) fn take(&mut self, w: u64, h: u64) {
        let px = |(a, b): (u64, u64)| a.saturating_mul(b);
        if w > 0 && h > 0 && self.largest.is_none_or(|d| px(d) < px((w, h))) {
            self.largest = Some((w, h));
        }
        if w > 0 && h > 0 {
            self.sides = (self.sides.0.max(w), self.sides.1.max(h));
        }
    }

    fn damage(&mut self, why: impl FnOnce() -> String) {
        if self.bad.is_none() {
            self.bad = Some(why());
        }
    }

    fn merge(&mut self, other: Declared) {
        if let Some((w, h)) = other.largest {
            self.take(w, h);
        }
        self.take(other.sides.0, other.sides.1);
        if let Some(b) = other.bad {
            self.damage(|| b);
        }
        self.raw_marker |= other.raw_marker;
    }
}

/// Reads `buf.len()` bytes at `off` if they lie before `end`; `false` (nothing read) if not.
fn read_at(f: &mut File, off: u64, end: u64, buf: &mut [u8]) -> std::io::Result<bool> {
    match off.checked_add(buf.len() as u64) {
        Some(e) if e <= end => {
            f.seek(SeekFrom::Start(off))?;
            f.read_exact(buf)?;
            Ok(true)
        }
        _ => Ok(false),
    }
}

fn be16(b: &[u8]) -> u16 {
    u16::from_be_bytes([b[0], b[1]])
}

fn be32(b: &[u8]) -> u32 {
    u32::from_be_bytes([b[0], b[1], b[2], b[3]])
}

fn le32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// The TIFF magic numbers rawler's reader takes: TIFF, Panasonic, Olympus (two).
const TIFF_MAGICS: [u16; 4] = [42, 85, 21330, 20306];
const MAGIC_PANASONIC: u16 = 85;

/// Walks the TIFF structure whose header starts at `base` (offsets relative to `base`, the region
/// ending at `end`): its IFD chain, SubIFDs, EXIF / GPS / interoperability IFDs and Fuji's IFD
/// 0xF000 (bounded: 64 IFDs, 4096 entries each, depth 3), for the raw markers (DNGVersion, a CFA
/// or LinearRaw photometric), the largest declared image (ImageWidth / ImageLength, Fuji's
/// 0xF001 / 0xF002, Panasonic's sensor size in the first IFD) and entries reaching past the end.
/// Not a TIFF header at `base`: nothing declared.
pub(crate) fn tiff(f: &mut File, base: u64, end: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut hdr = [0u8; 8];
    if !read_at(f, base, end, &mut hdr)? {
        return Ok(d);
    }
    let le = match &hdr[..2] {
        b"II" => true,
        b"MM" => false,
        _ => return Ok(d),
    };
    let u16_of = |b: &[u8]| {
        if le {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            be16(b)
        }
    };
    let u32_of = |b: &[u8]| if le { le32(b) } else { be32(b) };
    let magic = u16_of(&hdr[2..4]);
    if !TIFF_MAGICS.contains(&magic) {
        // BigTIFF and others: not a layout rawler reads.
        return Ok(d);
    }
    let len = end.saturating_sub(base);
    // Each IFD with the IFDs that lead to it: one that comes back to its own path is a cycle,
    // which the decoder's parser follows for ever (an IFD reached twice otherwise is read once).
    let mut queue: Vec<(u64, u32, Vec<u64>)> = vec![(u64::from(u32_of(&hdr[4..8])), 0, Vec::new())];
    let mut seen = std::collections::HashSet::new();
    let mut first = true;
    while let Some((off, depth, path)) = queue.pop() {
        if path.contains(&off) {
            d.damage(|| {
                format!(
                    "the IFD at byte {} points back at itself (a cycle)",
                    base + off
                )
            });
            continue;
        }
        if off + 2 > len || seen.len() >= 64 || !seen.insert(off) {
            continue;
        }
        let mut path = path;
        path.push(off);
        let root = std::mem::take(&mut first);
        let mut cnt = [0u8; 2];
        read_at(f, base + off, end, &mut cnt)?;
        let count = u64::from(u16_of(&cnt)).min(4096);
        if off + 2 + count * 12 + 4 > len {
            d.damage(|| {
                format!(
                    "an IFD at byte {} runs past the end of the file",
                    base + off
                )
            });
            continue;
        }
        let mut entries = vec![0u8; (count * 12 + 4) as usize];
        read_at(f, base + off + 2, end, &mut entries)?;
        let (mut w, mut h, mut photometric) = (0u64, 0u64, 0u32);
        let (mut fw, mut fh, mut pw, mut ph) = (0u64, 0u64, 0u64, 0u64);
        // Samples per pixel and the tile size: the decoder allocates (width rounded up to whole
        // tiles) × samples × (height rounded up likewise).
        let (mut cpp, mut tw, mut tl) = (1u64, 0u64, 0u64);
        let panasonic = root && magic == MAGIC_PANASONIC;
        for (i, e) in entries[..(count * 12) as usize]
            .chunks_exact(12)
            .enumerate()
        {
            let tag = u16_of(&e[0..2]);
            let typ = u16_of(&e[2..4]);
            let n = u32_of(&e[4..8]);
            let value = match typ {
                3 | 8 => u32::from(u16_of(&e[8..10])),
                _ => u32_of(&e[8..12]),
            };
            let bytes = u64::from(n) * type_size(typ);
            if bytes > 4 && u64::from(u32_of(&e[8..12])) + bytes > len {
                d.damage(|| format!("tag {tag} claims {bytes} bytes, past the end of the file"));
            }
            let size_tag = matches!(tag, 256 | 257 | 277 | 322 | 323 | 0xF001 | 0xF002)
                || (panasonic && matches!(tag, 2 | 3));
            if size_tag {
                size_in_entry(&mut d, tag, typ, n);
            }
            match tag {
                256 => w = u64::from(value),
                257 => h = u64::from(value),
                262 => photometric = value,
                0xF001 => fw = u64::from(value),
                0xF002 => fh = u64::from(value),
                277 => cpp = u64::from(value),
                322 => tw = u64::from(value),
                323 => tl = u64::from(value),
                2 if panasonic => pw = u64::from(value),
                3 if panasonic => ph = u64::from(value),
                50706 => d.raw_marker = true,
                // SubIFDs, EXIF, GPS, interoperability and Fuji's raw IFD: the decoder parses
                // them too, from the offsets `sub_ifds` derives as it does.
                330 | 34665 | 34853 | 40965 | 0xF000 if depth < 3 => {
                    let at = off + 2 + i as u64 * 12 + 8;
                    for o in sub_ifds(f, base, end, typ, n, at, &e[8..12], u32_of)? {
                        queue.push((o, depth + 1, path.clone()));
                    }
                }
                _ => {}
            }
        }
        if photometric == 32803 || photometric == 34892 {
            d.raw_marker = true;
        }
        let whole = |v: u64, t: u64| {
            if t > 0 {
                v.div_ceil(t).saturating_mul(t)
            } else {
                v
            }
        };
        d.take(whole(w, tw).saturating_mul(cpp.max(1)), whole(h, tl));
        d.take(fw, fh);
        d.take(pw, ph);
        let next = u64::from(u32_of(&entries[(count * 12) as usize..]));
        if next != 0 {
            queue.push((next, depth, path));
        }
    }
    Ok(d)
}

/// A size is one BYTE, SHORT or LONG in the entry itself. Another count or type puts the value
/// elsewhere, where the decoder reads it and [`tiff`] would not: damage.
fn size_in_entry(d: &mut Declared, tag: u16, typ: u16, n: u32) {
    if n != 1 || !matches!(typ, 1 | 3 | 4 | 6 | 8 | 9) {
        d.damage(|| {
            format!(
                "tag {tag}, a size, holds {n} value(s) of TIFF type {typ} (one SHORT or LONG \
                 expected)"
            )
        });
    }
}

/// The offsets (relative to `base`) at which the decoder parses the sub-IFDs of one entry of
/// type `typ` and count `n`, whose value field (`field`) is at `at`. rawler takes them by the
/// entry's value: a LONG's values; for UNDEFINED, where the data is (the field itself when it
/// fits in 4 bytes); for a type it does not know (0 or above 12, IFD's 13 among them) the first
/// byte of the data. The conventional reading of a LONG-sized IFD (13) is walked as well.
#[allow(clippy::too_many_arguments)]
fn sub_ifds(
    f: &mut File,
    base: u64,
    end: u64,
    typ: u16,
    n: u32,
    at: u64,
    field: &[u8],
    u32_of: impl Fn(&[u8]) -> u32,
) -> std::io::Result<Vec<u64>> {
    let pointer = u64::from(u32_of(field));
    let len = end.saturating_sub(base);
    let mut offs = Vec::new();
    match typ {
        4 if n == 1 => offs.push(pointer),
        4 if n > 1 && pointer + u64::from(n) * 4 <= len => {
            let mut b = vec![0u8; n.min(64) as usize * 4];
            read_at(f, base + pointer, end, &mut b)?;
            offs.extend(b.chunks_exact(4).map(|o| u64::from(u32_of(o))));
        }
        7 => offs.push(if n <= 4 { at } else { pointer }),
        0 | 13.. if n >= 1 => {
            if typ == 13 && n == 1 {
                offs.push(pointer);
            }
            if n <= 4 {
                offs.push(u64::from(field[0]));
            } else {
                let mut b = [0u8; 1];
                if read_at(f, base + pointer, end, &mut b)? {
                    offs.push(u64::from(b[0]));
                }
            }
        }
        _ => {}
    }
    Ok(offs)
}

/// The bytes of one value of TIFF type `typ`, as rawler sizes it.
fn type_size(typ: u16) -> u64 {
    match typ {
        1 | 2 | 6 | 7 => 1,
        3 | 8 => 2,
        4 | 9 | 11 | 13 => 4,
        5 | 10 | 12 => 8,
        // rawler reads any other type as bytes (UNDEFINED), `count` of them: so must the walk,
        // or a garbage type hides a count the decoder allocates (found by
        // `mutated_containers_never_panic`: 3.9 GB from a RAF's EXIF).
        _ => 1,
    }
}

/// The UUID of Canon's CR3 description box (holding CMT1–CMT4), as rawler matches it.
const CANON_UUID: [u8; 16] = [
    0x85, 0xc0, 0xb6, 0x87, 0x82, 0x0f, 0x11, 0xe0, 0x81, 0x11, 0xf4, 0xce, 0x46, 0x2b, 0x6a, 0x48,
];

/// Boxes visited at most in one CR3 file (real files have about 60).
const MAX_BOXES: usize = 4096;

/// A CR3 (ISO-BMFF, brand `crx `) file of `len` bytes.
pub(crate) fn cr3(f: &mut File, len: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut budget = MAX_BOXES;
    bmff_boxes(f, 0, len, len, (0, b"file"), &mut d, &mut budget)?;
    Ok(d)
}

/// The boxes from `start` to `end` (a parent's body); `file_len` bounds what a table may make
/// the decoder allocate; `level`: the depth and the parent's type.
fn bmff_boxes(
    f: &mut File,
    start: u64,
    end: u64,
    file_len: u64,
    level: (u32, &[u8; 4]),
    d: &mut Declared,
    budget: &mut usize,
) -> std::io::Result<()> {
    let (depth, parent) = level;
    let mut at = start;
    while at + 8 <= end {
        if *budget == 0 {
            d.damage(|| format!("more than {MAX_BOXES} boxes"));
            return Ok(());
        }
        *budget -= 1;
        let Some(b) = bmff_header(f, at, end, d)? else {
            return Ok(());
        };
        bmff_box(f, &b, file_len, depth, d, budget)?;
        // In a `moov`, the decoder reads only the header of a `uuid` box other than Canon's and
        // goes on with what follows the header, as boxes of the `moov` (found by
        // `mutated_containers_never_panic`: a box of size 0 read there for ever).
        at = if parent == b"moov" && &b.typ == b"uuid" && b.uuid != CANON_UUID {
            b.body
        } else {
            b.end
        };
    }
    // The decoder reads boxes while any byte of the parent is left: a header that straddles
    // its parent's end is read from the bytes after it (found by
    // `mutated_containers_never_panic`: a `moov` whose walk then never ends).
    if at < end {
        d.damage(|| {
            format!(
                "{} bytes at byte {at} are too few for a box but left in its parent",
                end - at
            )
        });
    }
    Ok(())
}

/// One ISO-BMFF box: its type, where it starts, where its body starts and where it ends.
struct BmffBox {
    typ: [u8; 4],
    name: String,
    at: u64,
    body: u64,
    end: u64,
    uuid: [u8; 16],
}

impl BmffBox {
    fn body_len(&self) -> u64 {
        self.end - self.body
    }
}

/// The header of the box at `at` inside a parent ending at `end`, or `None` (the damage noted
/// in `d`) when it is cut off, has size 0, or reaches past its parent.
fn bmff_header(
    f: &mut File,
    at: u64,
    end: u64,
    d: &mut Declared,
) -> std::io::Result<Option<BmffBox>> {
    let mut h = [0u8; 8];
    read_at(f, at, end, &mut h)?;
    let typ: [u8; 4] = [h[4], h[5], h[6], h[7]];
    let name = String::from_utf8_lossy(&typ).into_owned();
    let mut header = 8u64;
    let size = match be32(&h[..4]) {
        1 => {
            let mut big = [0u8; 8];
            if !read_at(f, at + 8, end, &mut big)? {
                d.damage(|| format!("box `{name}` at byte {at} is cut off"));
                return Ok(None);
            }
            header = 16;
            u64::from_be_bytes(big)
        }
        // Size 0 ("to the end of the file" in ISO-BMFF): the decoder would seek back to
        // the box's start and read it again, for ever.
        0 => {
            d.damage(|| format!("box `{name}` at byte {at} has size 0"));
            return Ok(None);
        }
        s => u64::from(s),
    };
    let mut uuid = [0u8; 16];
    if &typ == b"uuid" {
        if !read_at(f, at + header, end, &mut uuid)? {
            d.damage(|| format!("box `uuid` at byte {at} is cut off"));
            return Ok(None);
        }
        header += 16;
    }
    let box_end = at.checked_add(size).filter(|&e| size >= header && e <= end);
    let Some(box_end) = box_end else {
        d.damage(|| {
            format!("box `{name}` at byte {at} claims {size} bytes, past the end of its parent (byte {end})")
        });
        return Ok(None);
    };
    Ok(Some(BmffBox {
        typ,
        name,
        at,
        body: at + header,
        end: box_end,
        uuid,
    }))
}

/// What one box declares: the containers walked into, Canon's sizes read, and every sample
/// table checked to fit in its box.
fn bmff_box(
    f: &mut File,
    b: &BmffBox,
    file_len: u64,
    depth: u32,
    d: &mut Declared,
    budget: &mut usize,
) -> std::io::Result<()> {
    let (at, body, box_end) = (b.at, b.body, b.end);
    match &b.typ {
        b"moov" | b"trak" | b"mdia" | b"minf" | b"stbl" if depth < 8 => {
            bmff_boxes(f, body, box_end, file_len, (depth + 1, &b.typ), d, budget)?;
        }
        b"uuid" if b.uuid == CANON_UUID && depth < 8 => {
            bmff_boxes(f, body, box_end, file_len, (depth + 1, &b.typ), d, budget)?;
        }
        // Version and flags, entry count, then the sample entries.
        b"stsd" if depth < 8 => {
            bmff_boxes(
                f,
                body + 8,
                box_end,
                file_len,
                (depth + 1, &b.typ),
                d,
                budget,
            )?;
        }
        // Canon's raw sample entry: 24 bytes, width, height (u16), 54 more, then boxes.
        b"CRAW" => {
            let mut wh = [0u8; 4];
            if read_at(f, body + 24, box_end, &mut wh)? {
                d.take(u64::from(be16(&wh[..2])), u64::from(be16(&wh[2..])));
            }
            if depth < 8 {
                bmff_boxes(
                    f,
                    body + 82,
                    box_end,
                    file_len,
                    (depth + 1, &b.typ),
                    d,
                    budget,
                )?;
            }
        }
        // Image width, height and tile width, height (u32) after 8 bytes.
        b"CMP1" => {
            let mut v = [0u8; 16];
            if read_at(f, body + 8, box_end, &mut v)? {
                d.take(u64::from(be32(&v[..4])), u64::from(be32(&v[4..8])));
                d.take(u64::from(be32(&v[8..12])), u64::from(be32(&v[12..])));
            } else {
                d.damage(|| format!("box `CMP1` at byte {at} is too short"));
            }
        }
        b"CMT1" | b"CMT2" | b"CMT3" | b"CMT4" => {
            let t = tiff(f, body, box_end)?;
            d.merge(Declared {
                raw_marker: false,
                ..t
            });
        }
        // Version/flags, count, entries of 8 (stts, co64), 12 (stsc) or 4 (stco) bytes.
        b"stts" | b"co64" => bmff_table(f, b, 8, 4, 8, d)?,
        b"stsc" => bmff_table(f, b, 8, 4, 12, d)?,
        b"stco" => bmff_table(f, b, 8, 4, 4, d)?,
        b"stsz" => bmff_stsz(f, b, file_len, d)?,
        // Canon's timed-metadata entry: 8 bytes, a record count, records of 8 bytes.
        b"CTMD" => bmff_table(f, b, 12, 8, 8, d)?,
        _ => {}
    }
    Ok(())
}

/// A table of `count` entries of `each` bytes after `skip` bytes (the count read at `count_at`
/// in the body) must fit in its box.
fn bmff_table(
    f: &mut File,
    b: &BmffBox,
    skip: u64,
    count_at: u64,
    each: u64,
    d: &mut Declared,
) -> std::io::Result<()> {
    let (name, at) = (&b.name, b.at);
    let mut c = [0u8; 4];
    if !read_at(f, b.body + count_at, b.end, &mut c)? {
        d.damage(|| format!("box `{name}` at byte {at} is too short for its table"));
        return Ok(());
    }
    let count = u64::from(be32(&c));
    if skip.saturating_add(count.saturating_mul(each)) > b.body_len() {
        d.damage(|| {
            format!("box `{name}` at byte {at} announces {count} entries, more than it holds")
        });
    }
    Ok(())
}

/// `stsz`: version/flags, sample size, sample count; the sizes follow only when the sample size
/// is 0, but the decoder reserves room for the count either way.
fn bmff_stsz(f: &mut File, b: &BmffBox, file_len: u64, d: &mut Declared) -> std::io::Result<()> {
    let at = b.at;
    let mut v = [0u8; 8];
    if read_at(f, b.body + 4, b.end, &mut v)? {
        let count = u64::from(be32(&v[4..]));
        let held = if be32(&v[..4]) == 0 {
            b.body_len().saturating_sub(12)
        } else {
            file_len
        };
        if count.saturating_mul(4) > held {
            d.damage(|| {
                format!("box `stsz` at byte {at} announces {count} samples, more than it holds")
            });
        }
    } else {
        d.damage(|| format!("box `stsz` at byte {at} is too short"));
    }
    Ok(())
}

/// A RAF file of `len` bytes.
pub(crate) fn raf(f: &mut File, len: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut ptrs = [0u8; 24];
    if !read_at(f, 84, len, &mut ptrs)? {
        d.damage(|| "its RAF header is cut off".into());
        return Ok(d);
    }
    let jpeg = u64::from(be32(&ptrs[0..4]));
    let dir = u64::from(be32(&ptrs[8..12]));
    // The sensor layout of tag 0x130: Some(true) for SuperCCD (45° turned), None if absent.
    let mut layout = None;
    let cfa = u64::from(be32(&ptrs[16..20]));
    // The embedded JPEG's EXIF TIFF (12 bytes in: SOI, APP1 marker and length, "Exif\0\0").
    let mut t = tiff(f, jpeg + 12, len)?;
    t.raw_marker = false;
    d.merge(t);
    // The CFA record: a TIFF structure with the Fuji IFD in newer files, raw data in older ones.
    let mut t = tiff(f, cfa, len)?;
    t.raw_marker = false;
    d.merge(t);
    // The RAF directory: a count (≤ 4000, as the decoder takes it), then tag, length, data.
    let mut c = [0u8; 4];
    if read_at(f, dir, len, &mut c)? {
        let n = be32(&c);
        let mut at = dir + 4;
        for _ in 0..n.min(4000) {
            let mut e = [0u8; 4];
            if !read_at(f, at, len, &mut e)? {
                break;
            }
            let (tag, size) = (be16(&e[..2]), u64::from(be16(&e[2..])));
            if matches!(tag, 0x100 | 0x121) && size >= 4 {
                let mut v = [0u8; 4];
                if read_at(f, at + 4, len, &mut v)? {
                    // Height, then width.
                    d.take(u64::from(be16(&v[2..])), u64::from(be16(&v[..2])));
                }
            }
            if tag == 0x130 && size >= 2 {
                let mut v = [0u8; 2];
                if read_at(f, at + 4, len, &mut v)? {
                    // LibRaw's `fuji_width`: bit 3 of the second byte clear.
                    layout = Some(v[1] & 8 == 0);
                }
            }
            at += 4 + size;
        }
    }
    // A SuperCCD sensor (layout flag set, or no layout recorded): the decoder turns the
    // mosaic by 45° into a second image of (w + h/2) × (w + h/2 − 1) pixels (or h + w/2 for
    // the other layout), so that is what is declared, from the largest sides declared.
    let (w, h) = d.sides;
    let side = (w + h / 2).max(h + w / 2);
    d.turned = Some(side);
    if layout != Some(false) {
        d.take(side, side);
    }
    Ok(d)
}

/// An MRW file of `len` bytes: blocks from byte 8 up to the data offset (byte 4, + 8).
pub(crate) fn mrw(f: &mut File, len: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut h = [0u8; 8];
    if !read_at(f, 0, len, &mut h)? {
        d.damage(|| "its MRW header is cut off".into());
        return Ok(d);
    }
    let data = u64::from(be32(&h[4..])) + 8;
    if data > len {
        d.damage(|| format!("its raw data would start at byte {data}, past the end of the file"));
        return Ok(d);
    }
    let mut at = 8u64;
    let mut ttw = None;
    for _ in 0..MAX_BOXES {
        // As the decoder loops: while `at + 20 < data` (strictly).
        if at + 20 >= data {
            break;
        }
        let mut b = [0u8; 20];
        read_at(f, at, data, &mut b)?;
        if &b[..4] == b"\0PRD" {
            // Version (8 bytes), sensor height, sensor width.
            d.take(u64::from(be16(&b[18..20])), u64::from(be16(&b[16..18])));
        }
        if &b[..4] == b"\0TTW" {
            ttw = Some(at + 8);
        }
        at += 8 + u64::from(be32(&b[4..8]));
    }
    // The decoder reads an IFD at byte 8 of the TTW block (of the file, when there is none)
    // whatever it holds, and allocates what its entries declare: the block must be there and
    // hold a TIFF whose first IFD is at byte 8, walked as every TIFF structure is.
    match ttw {
        None => d.damage(|| {
            "its MRW header has no TTW block (the TIFF structure the decoder reads)".into()
        }),
        Some(base) => {
            let mut hdr = [0u8; 8];
            let at8 =
                read_at(f, base, len, &mut hdr)? && &hdr[..4] == b"MM\0*" && be32(&hdr[4..]) == 8;
            if !at8 {
                d.damage(|| format!("its TTW block at byte {base} is not a big-endian TIFF with its IFD at byte 8"));
            }
            let mut t = tiff(f, base, len)?;
            t.raw_marker = false;
            d.merge(t);
        }
    }
    Ok(d)
}

/// A CRW (CIFF) file of `len` bytes.
pub(crate) fn crw(f: &mut File, len: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut h = [0u8; 6];
    if !read_at(f, 0, len, &mut h)? {
        d.damage(|| "its CIFF header is cut off".into());
        return Ok(d);
    }
    let start = u64::from(u32::from_le_bytes([h[2], h[3], h[4], h[5]]));
    let mut budget = MAX_BOXES;
    ciff_heap(f, start, len, 0, &mut d, &mut budget)?;
    Ok(d)
}

/// One CIFF heap from `start` to `end`: its records' offset is in the last four bytes.
fn ciff_heap(
    f: &mut File,
    start: u64,
    end: u64,
    depth: u32,
    d: &mut Declared,
    budget: &mut usize,
) -> std::io::Result<()> {
    let mut tail = [0u8; 4];
    if end < start + 4 || !read_at(f, end - 4, end, &mut tail)? {
        return Ok(());
    }
    let dir = start + u64::from(le32(&tail));
    let mut c = [0u8; 2];
    if !read_at(f, dir, end, &mut c)? {
        d.damage(|| format!("a CIFF heap's records at byte {dir} lie past its end"));
        return Ok(());
    }
    let n = u64::from(u16::from_le_bytes(c));
    for i in 0..n {
        if *budget == 0 {
            return Ok(());
        }
        *budget -= 1;
        let mut e = [0u8; 10];
        if !read_at(f, dir + 2 + i * 10, end, &mut e)? {
            d.damage(|| format!("a CIFF heap's records at byte {dir} run past its end"));
            return Ok(());
        }
        let p = u16::from_le_bytes([e[0], e[1]]);
        if p & 0xc000 != 0 {
            // Data in the record itself (0x4000) or an unknown location.
            continue;
        }
        let size = u64::from(le32(&e[2..6]));
        let off = start + u64::from(le32(&e[6..10]));
        let Some(data_end) = off.checked_add(size).filter(|&x| x <= end) else {
            d.damage(|| format!("a CIFF record at byte {off} claims {size} bytes, past its heap"));
            continue;
        };
        let typ = p & 0x3800;
        if (typ == 0x2800 || typ == 0x3000) && depth < 8 {
            ciff_heap(f, off, data_end, depth + 1, d, budget)?;
        } else if p & 0x3fff == 0x1031 {
            // SensorInfo: u16 values; width, height at indices 1, 2.
            let mut v = [0u8; 6];
            if read_at(f, off, data_end, &mut v)? {
                d.take(
                    u64::from(u16::from_le_bytes([v[2], v[3]])),
                    u64::from(u16::from_le_bytes([v[4], v[5]])),
                );
            }
        }
    }
    Ok(())
}

/// An X3F file of `len` bytes.
pub(crate) fn x3f(f: &mut File, len: u64) -> std::io::Result<Declared> {
    let mut d = Declared::default();
    let mut t = [0u8; 4];
    if len < 4 || !read_at(f, len - 4, len, &mut t)? {
        d.damage(|| "its X3F directory pointer is cut off".into());
        return Ok(d);
    }
    let dir = u64::from(le32(&t));
    let mut h = [0u8; 12];
    if !read_at(f, dir, len, &mut h)? {
        d.damage(|| format!("its X3F directory at byte {dir} lies past the end of the file"));
        return Ok(d);
    }
    let n = u64::from(le32(&h[8..]));
    if dir + 12 + n.saturating_mul(12) > len {
        d.damage(|| format!("its X3F directory announces {n} entries, past the end of the file"));
        return Ok(d);
    }
    for i in 0..n.min(MAX_BOXES as u64) {
        let mut e = [0u8; 12];
        read_at(f, dir + 12 + i * 12, len, &mut e)?;
        if &e[8..] == b"IMA2" {
            let mut img = [0u8; 24];
            if read_at(f, u64::from(le32(&e[..4])), len, &mut img)? {
                d.take(u64::from(le32(&img[16..20])), u64::from(le32(&img[20..24])));
            } else {
                d.damage(|| "an X3F image section lies past the end of the file".into());
            }
        }
    }
    Ok(d)
}

#[cfg(test)]
pub(crate) mod tests {
    //! Synthetic minimal containers (built from the published layouts, no real CR3 / RAF / MRW /
    //! CRW / X3F file being available here): the sizes they declare are found, huge ones are
    //! refused before decoding, damaged structure is refused, and mutated headers never panic.
    use super::super::{sniff, Sniff};
    use super::*;
    use std::path::{Path, PathBuf};

    fn bx(typ: &[u8; 4], body: &[u8]) -> Vec<u8> {
        let mut v = ((body.len() + 8) as u32).to_be_bytes().to_vec();
        v.extend_from_slice(typ);
        v.extend_from_slice(body);
        v
    }

    /// A little-endian TIFF with one IFD of `entries` (tag, type, count, value), magic `magic`.
    pub(crate) fn tiff_le(magic: u16, entries: &[(u16, u16, u32, u32)]) -> Vec<u8> {
        let mut v = b"II".to_vec();
        v.extend_from_slice(&magic.to_le_bytes());
        v.extend_from_slice(&8u32.to_le_bytes());
        v.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for &(tag, typ, n, val) in entries {
            v.extend_from_slice(&tag.to_le_bytes());
            v.extend_from_slice(&typ.to_le_bytes());
            v.extend_from_slice(&n.to_le_bytes());
            v.extend_from_slice(&val.to_le_bytes());
        }
        v.extend_from_slice(&0u32.to_le_bytes());
        v
    }

    /// A CR3 skeleton: `ftyp crx`, Canon's description box with a CMT1 TIFF, one track whose
    /// `CRAW` sample entry holds a `CMP1` box declaring `w`×`h`, sample tables, an `mdat`.
    /// `stsz_count` is the sample count the `stsz` box announces (its sample size is 0, so the
    /// sizes should follow).
    pub(crate) fn cr3(w: u32, h: u32, stsz_count: u32) -> Vec<u8> {
        let mut cmp1 = vec![0u8; 8];
        for v in [w, h, w.min(4096), h.min(4096)] {
            cmp1.extend_from_slice(&v.to_be_bytes());
        }
        cmp1.extend_from_slice(&[14, 0x11, 0x10, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        let mut craw = vec![0u8; 24];
        craw.extend_from_slice(&(w.min(0xffff) as u16).to_be_bytes());
        craw.extend_from_slice(&(h.min(0xffff) as u16).to_be_bytes());
        craw.extend_from_slice(&[0u8; 54]);
        craw.extend(bx(b"CMP1", &cmp1));
        let mut stsd = vec![0, 0, 0, 0, 0, 0, 0, 1];
        stsd.extend(bx(b"CRAW", &craw));
        let mut stsz = vec![0u8; 8];
        stsz.extend_from_slice(&stsz_count.to_be_bytes());
        stsz.extend_from_slice(&1000u32.to_be_bytes());
        let mut co64 = vec![0, 0, 0, 0, 0, 0, 0, 1];
        co64.extend_from_slice(&0u64.to_be_bytes());
        let stbl = [bx(b"stsd", &stsd), bx(b"stsz", &stsz), bx(b"co64", &co64)].concat();
        let trak = bx(b"trak", &bx(b"mdia", &bx(b"minf", &bx(b"stbl", &stbl))));
        let cmt1 = bx(b"CMT1", &tiff_le(42, &[(0x10f, 2, 4, 0x6e6f6e61)]));
        let mut canon = CANON_UUID.to_vec();
        canon.extend(cmt1);
        let mut uuid = ((canon.len() + 8) as u32).to_be_bytes().to_vec();
        uuid.extend_from_slice(b"uuid");
        uuid.extend(canon);
        let moov = bx(b"moov", &[uuid, trak].concat());
        let ftyp = bx(b"ftyp", b"crx \0\0\0\x01crx isom");
        [ftyp, moov, bx(b"mdat", &[0u8; 64])].concat()
    }

    /// A RAF skeleton: the 108-byte header, an embedded "JPEG" with an EXIF TIFF, a CFA record
    /// that is a TIFF with the Fuji IFD declaring `fw`×`fh`, and a RAF directory declaring
    /// `w`×`h` (tag 0x100, height first) and a sensor layout that is not SuperCCD (0x130).
    pub(crate) fn raf(w: u16, h: u16, fw: u32, fh: u32) -> Vec<u8> {
        raf_layout(w, h, fw, fh, 8)
    }

    /// The same with tag 0x130's second byte `layout` (bit 3 clear: SuperCCD).
    pub(crate) fn raf_layout(w: u16, h: u16, fw: u32, fh: u32, layout: u8) -> Vec<u8> {
        let mut v = b"FUJIFILMCCD-RAW 0201FF383501".to_vec();
        v.resize(108, 0);
        let jpeg_at = v.len() as u32;
        v.extend_from_slice(&[0xFF, 0xD8, 0xFF, 0xE1, 0, 30]);
        v.extend_from_slice(b"Exif\0\0");
        v.extend(tiff_le(42, &[(0x10f, 2, 4, 0x494a5546)]));
        let dir_at = v.len() as u32;
        v.extend_from_slice(&2u32.to_be_bytes());
        v.extend_from_slice(&0x100u16.to_be_bytes());
        v.extend_from_slice(&4u16.to_be_bytes());
        v.extend_from_slice(&h.to_be_bytes());
        v.extend_from_slice(&w.to_be_bytes());
        v.extend_from_slice(&0x130u16.to_be_bytes());
        v.extend_from_slice(&2u16.to_be_bytes());
        v.extend_from_slice(&[0, layout]);
        let cfa_at = v.len() as u32;
        // Root IFD: one entry, the Fuji IFD (0xF000) at byte 26 of the record.
        let mut t = tiff_le(42, &[(0xF000, 13, 1, 26)]);
        t.extend_from_slice(&2u16.to_le_bytes());
        for (tag, val) in [(0xF001u16, fw), (0xF002, fh)] {
            t.extend_from_slice(&tag.to_le_bytes());
            t.extend_from_slice(&4u16.to_le_bytes());
            t.extend_from_slice(&1u32.to_le_bytes());
            t.extend_from_slice(&val.to_le_bytes());
        }
        t.extend_from_slice(&0u32.to_le_bytes());
        v.extend(t);
        let end = v.len() as u32;
        for (i, x) in [
            jpeg_at,
            dir_at - jpeg_at,
            dir_at,
            cfa_at - dir_at,
            cfa_at,
            end - cfa_at,
        ]
        .iter()
        .enumerate()
        {
            v[84 + i * 4..88 + i * 4].copy_from_slice(&x.to_be_bytes());
        }
        v
    }

    /// An MRW skeleton: the MRM block holding a PRD block declaring `w`×`h`.
    pub(crate) fn mrw(w: u16, h: u16) -> Vec<u8> {
        let mut prd = b"21810002".to_vec();
        prd.extend_from_slice(&h.to_be_bytes());
        prd.extend_from_slice(&w.to_be_bytes());
        prd.extend_from_slice(&h.to_be_bytes());
        prd.extend_from_slice(&w.to_be_bytes());
        prd.extend_from_slice(&[12, 12, 0x59, 0, 0, 1, 0, 0]);
        let mut blk = b"\0PRD".to_vec();
        blk.extend_from_slice(&(prd.len() as u32).to_be_bytes());
        blk.extend(prd);
        // The TTW block: a big-endian TIFF whose IFD (at byte 8) has no entries.
        let ttw: &[u8] = b"MM\0*\0\0\0\x08\0\0\0\0\0\0";
        blk.extend_from_slice(b"\0TTW");
        blk.extend_from_slice(&(ttw.len() as u32).to_be_bytes());
        blk.extend_from_slice(ttw);
        let mut v = b"\0MRM".to_vec();
        v.extend_from_slice(&(blk.len() as u32).to_be_bytes());
        v.extend(blk);
        v.extend_from_slice(&[0u8; 64]);
        v
    }

    /// A CRW skeleton: the CIFF header and a root heap holding a sub-heap with a SensorInfo
    /// record declaring `w`×`h`.
    pub(crate) fn crw(w: u16, h: u16) -> Vec<u8> {
        // Sub-heap: SensorInfo data (u16: 0, w, h, …), its record table, its table offset.
        let mut sub = Vec::new();
        for x in [0u16, w, h, 0, 0, 0, 0, 0] {
            sub.extend_from_slice(&x.to_le_bytes());
        }
        let table = sub.len() as u32;
        sub.extend_from_slice(&1u16.to_le_bytes());
        sub.extend_from_slice(&0x1031u16.to_le_bytes());
        sub.extend_from_slice(&16u32.to_le_bytes());
        sub.extend_from_slice(&0u32.to_le_bytes());
        sub.extend_from_slice(&table.to_le_bytes());
        // Root heap: the sub-heap, a record pointing at it (type 0x2800), its table offset.
        let mut root = sub.clone();
        let table = root.len() as u32;
        root.extend_from_slice(&1u16.to_le_bytes());
        root.extend_from_slice(&0x300au16.to_le_bytes());
        root.extend_from_slice(&(sub.len() as u32).to_le_bytes());
        root.extend_from_slice(&0u32.to_le_bytes());
        root.extend_from_slice(&table.to_le_bytes());
        let mut v = b"II".to_vec();
        v.extend_from_slice(&26u32.to_le_bytes());
        v.extend_from_slice(b"HEAPCCDR");
        v.resize(26, 0);
        v.extend(root);
        v
    }

    /// An X3F skeleton: an IMA2 image section declaring `w`×`h` and the directory.
    pub(crate) fn x3f(w: u32, h: u32) -> Vec<u8> {
        let mut v = b"FOVb".to_vec();
        v.resize(40, 0);
        let img = v.len() as u32;
        v.extend_from_slice(b"SECi");
        for x in [0x0002_0000u32, 1, 3, w, h, w.wrapping_mul(2)] {
            v.extend_from_slice(&x.to_le_bytes());
        }
        let dir = v.len() as u32;
        v.extend_from_slice(b"SECd");
        v.extend_from_slice(&0x0002_0000u32.to_le_bytes());
        v.extend_from_slice(&1u32.to_le_bytes());
        v.extend_from_slice(&img.to_le_bytes());
        v.extend_from_slice(&28u32.to_le_bytes());
        v.extend_from_slice(b"IMA2");
        v.extend_from_slice(&dir.to_le_bytes());
        v
    }

    /// An RW2 skeleton: Panasonic's TIFF magic and its sensor size in tags 2 and 3.
    pub(crate) fn rw2(w: u32, h: u32) -> Vec<u8> {
        tiff_le(85, &[(2, 4, 1, w), (3, 4, 1, h), (0x10f, 2, 4, 0x534e4150)])
    }

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    fn declared(p: &Path) -> (&'static str, Declared) {
        match sniff(p).unwrap() {
            Sniff::Container(k, d) => (k, d),
            s => panic!("{}: {s:?}", p.display()),
        }
    }

    #[test]
    fn each_container_declares_its_size() {
        let dir = tempfile::tempdir().unwrap();
        type Case = (&'static str, Vec<u8>, &'static str, (u64, u64));
        let cases: [Case; 7] = [
            ("a.cr3", cr3(6000, 4000, 1), "CR3", (6000, 4000)),
            ("b.raf", raf(6160, 4032, 6240, 4160), "RAF", (6240, 4160)),
            ("c.raf", raf(6160, 4032, 0, 0), "RAF", (6160, 4032)),
            ("d.mrw", mrw(3016, 2008), "MRW", (3016, 2008)),
            ("e.crw", crw(3152, 2068), "CRW", (3152, 2068)),
            ("f.x3f", x3f(2652, 1768), "X3F", (2652, 1768)),
            ("g.rw2", rw2(5488, 3664), "RW2", (5488, 3664)),
        ];
        for (name, bytes, kind, dims) in cases {
            let (k, d) = declared(&write(dir.path(), name, &bytes));
            assert_eq!(k, kind, "{name}");
            assert_eq!(d.bad, None, "{name}");
            assert_eq!(d.largest, Some(dims), "{name}");
        }
    }

    /// A SuperCCD RAF (tag 0x130 says so, or says nothing) declares the 45°-turned image the
    /// decoder allocates beside the mosaic: (w + h/2)², from the largest sides declared.
    #[test]
    fn a_superccd_raf_declares_its_turned_image() {
        let dir = tempfile::tempdir().unwrap();
        let (_, d) = declared(&write(
            dir.path(),
            "s.raf",
            &raf_layout(3000, 2000, 0, 0, 0),
        ));
        assert_eq!(d.largest, Some((4000, 4000)), "3000 + 2000/2");
        // The Fuji IFD's sides count too (the decoder takes its size from there).
        let (_, d) = declared(&write(
            dir.path(),
            "t.raf",
            &raf_layout(100, 100, 1000, 3000, 0x80),
        ));
        assert_eq!(d.largest, Some((3500, 3500)), "3000 + 1000/2");
        // No layout tag at all: taken as SuperCCD (the bound that is safe).
        let mut b = raf(3000, 2000, 0, 0);
        // The directory (pointer at byte 92): its count, the 0x100 entry, then 0x130's tag.
        let at = u32::from_be_bytes([b[92], b[93], b[94], b[95]]) as usize + 12;
        assert_eq!(b[at..at + 2], [0x01, 0x30]);
        b[at] = 0x7f;
        let (_, d) = declared(&write(dir.path(), "u.raf", &b));
        assert_eq!(d.largest, Some((4000, 4000)));
        // A layout tag that says otherwise: only the mosaic is declared, and the turned image
        // is kept for the decoder's check by camera.
        let (_, d) = declared(&write(dir.path(), "v.raf", &raf(3000, 2000, 0, 0)));
        assert_eq!((d.largest, d.turned), (Some((3000, 2000)), Some(4000)));
    }

    /// An MRW whose TTW block is missing or not a TIFF with its IFD at byte 8 is refused before
    /// the decoder, which reads an IFD there whatever it holds (a mutated header once made it
    /// allocate 3.9 GB: this file, found by `mutated_containers_never_panic`).
    #[test]
    fn an_mrw_without_its_tiff_block_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let found: &[u8] = b"\0MRM\0\0\0 \0PRD\0\0\xea\x1821810002\x01\xef\x02X\x01\x90\x02X\x0c\x0cY\0\0\x01\0\0\0\0\0\0\0\0\0\r\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0w\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0Z\0\0";
        assert_eq!(found.len(), 104);
        let (_, d) = declared(&write(dir.path(), "found.mrw", found));
        assert!(
            d.bad.as_deref().is_some_and(|b| b.contains("no TTW block")),
            "{:?}",
            d.bad
        );
        let mut b = mrw(600, 400);
        let at = b.windows(4).position(|w| w == b"\0TTW").unwrap() + 8;
        b[at] = b'I';
        let (_, d) = declared(&write(dir.path(), "bad.mrw", &b));
        assert!(
            d.bad.as_deref().is_some_and(|b| b.contains("TTW block")),
            "{:?}",
            d.bad
        );
    }

    /// A TIFF entry of an unknown type is sized as bytes, as the decoder reads it: a RAF whose
    /// EXIF holds one with a count of 3.9 G is refused (found by
    /// `mutated_containers_never_panic`, where the decoder allocated it).
    #[test]
    fn an_entry_of_unknown_type_counts_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let found: &[u8] = b"FUJIFILMCCD-RAW 0\x8f0IFF383501\0\0\0\0\0\0\0\0\0\0\0d\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0l\0\0\0&\0\0\0\x92\0\0\0\x12\0\0\0\xa4\0\0\x008\xff\xd8\xff\xe1\0\x1eExif\0\0II*\0\x08\0\0\0\x01\0\x0f\x01\x02\x8f\x8a\0\0\xebFUJI\0\0\0\0\0\0\0\x02\x01\0\0\x04\x01\x90\x02X\x010\0\x02\0\x08II*\0\x08X\0\0\x01\0\0\xf0\r\0\x01\0\0\0\x1a\0\0\0\0\0\0\0\x02\0\x01\xf0\xb2\0\x01\0\0\0X\x02\0\0\x02\xf0\x04\0\x01\0\0\0\x90\x01\0\0\0\0\0\0";
        assert_eq!(found.len(), 220);
        let (_, d) = declared(&write(dir.path(), "found.raf", found));
        assert!(
            d.bad.as_deref().is_some_and(|b| b.contains("claims")),
            "{:?}",
            d.bad
        );
    }

    /// Found by `mutated_containers_never_panic` with a random seed: a RAF whose CFA record's
    /// Fuji IFD entry has type 13 (IFD), which rawler reads as one byte (26) where the
    /// conventional reading (a LONG) points past the end; the IFD at 26 declares an entry of
    /// 15 GB, which the decoder allocated before the walk mirrored its sub-IFD offsets.
    #[test]
    fn a_raf_fuji_ifd_bomb_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let found: &[u8] = b"FUJIFILMCCD-RAW 0201FF383501\0\0\0\0\0\xf5\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\xc2\0\0\0\0\0\x12\0\0\x86\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0l\0\0\0&\0\0\0\x92\0\x02\0\x12\0\0\0\xa4\0\0\x008W\xd8\xff\xe1\0\xc5Exif\0\0II*\0\x08\0\0\0\x01\0\x0f\x01\x02\0\x04\0\0\0FUJI\0\0\0\0\0\0\0\x02\x01\0\0\x04\x01\x90\x02X\x010\0\x02\0\x08II*\0\x08\0\0\0\x01\0\0\xf0\r\0\x01\0\0\0\x1a\0Z\0\0\0\0\0'\0\x01\xf0\x04\0\x01\0\0\0X\x02\0\0\x02\xf0\x04\0\x01\0\0\xe1\x90\x01\0\0\0\0\0\0";
        let p = write(dir.path(), "found.raf", found);
        let (_, d) = declared(&p);
        assert!(
            d.bad.is_some(),
            "not refused: the decoder would allocate 15 GB"
        );
    }

    /// More files found by `mutated_containers_never_panic` with random seeds, on which rawler
    /// allocated gigabytes: a RAF whose Fuji IFD entry (type 13, read as its first byte)
    /// points at byte 2 of the CFA record, an IFD the walk skipped as inside the header (42
    /// entries reaching past the end); a CR3 whose `moov` holds a `uuid` box that is not Canon's,
    /// which the decoder enters as more `moov` boxes, and a box of size 0 there (read for ever).
    #[test]
    fn sub_ifds_and_boxes_are_walked_as_the_decoder_walks_them() {
        let dir = tempfile::tempdir().unwrap();
        let raf: &[u8] = b"FUJIFILMCCD-RAW 0\xf301FF383501h\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\x1f\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0l\0\0\0&\0\0\0\x92\0\0\0\x12\0\0\0\xa4\0\0\x008\xff\xd8\xae\xe1\0\x1eExif\0\0II*\0\x08\0\0\0\x01\0\x0f\x01\x02\0\x04\0\0\0FUJI\0\0\0\0\0\0\0\x02\x01\0\0\x04\x01\x90\x02X\x010\0\x02\0\x08II*\0\x08\0\0\0\x01\0\0\xf0\r\0\x01\0\0\0\x02\0\0\0\0\0\0\0\x02\0\x01\xf0\x04I\x01\0\0\0X\x02\0\0\x02\xf0\x04\0\x01\0\xde\0\x90\x01\0\0\0\0\0\0";
        let cr3: &[u8] = b"\0\0\0\x18ftypcrx \0\0\0\x01crx isom\0\0\x01(moov\0\0\0:uuid\x85\xc0\xb6\x87\x82\x0f`\xe0\x81\x11\xf4\xceF+jH\0\0\0\x1fCMT1II*\0\x08\0\0\0\x01\0\x0f\x01\x02\0\x04\0\0\0anon\0\0\0\0\0\0\0\xe6trak\0\0\0\xdemdia\0\0\0\xd6minf\0\0\0\xcestbl\0\0\0\x96stsd\0\0\0\0\0\0\x04\x01\0\0\0\x86CRAW\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0k\0\0\0\0\x02X\x01\x90\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\x87\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\xd4\0\0\0\0\0\0\0\0,CMP1\0\0\0\0\0\0\0\0\0\0\x02X\0\0\x01\x90\0\0\x02X\0\0\x01\x90\x0e\x11\x10\0\0\0\0\0\0\0\0\0\0\0\0\x18stsz\0\0\0\0\0\0\0\0\0\0\0\x01\0\0\x03\xe8\0\0\0\x18c\xd664\0\0\0\0\0\0\0\x01\0\0\0\0\0\0\0\0\0\0\0Hmdat\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\xab\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\xc7\0\0\0\0\0\0\0\0";
        // An MRW whose TTW block starts 20 bytes before the data: the decoder's loop stops
        // before it (`at + 20 < data`), so it reads an IFD at byte 8 of the file.
        let mrw: &[u8] = b"\0MRM\0\0\x004\0PRD\0\0\0\x1821810002\x01\x90\x02X\x01\x90\x02X\x0c\x0cY\0\0\x01\0\0\0TTW\0\0\0\x0eMM\0*\0\0\0\x08\0\0\0\0\0\0\xef\xb6\0\0\0\0\0\0\0\0\0\0k\0\0\0\0\0\0\xee\0\0\0\0\0\0\0\0\0\0\0\x1b\xfe\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0";
        for (name, bytes) in [("r.raf", raf), ("c.cr3", cr3), ("m.mrw", mrw)] {
            let (_, d) = declared(&write(dir.path(), name, bytes));
            assert!(d.bad.is_some(), "{name} not refused: {d:?}");
        }
    }

    /// A DNG-like TIFF's sizes as the decoder allocates them: samples per pixel and whole tiles
    /// count, and a size held anywhere but in its entry (where the decoder would read a value
    /// this scan did not) is refused. A mutated DNG whose ImageWidth count became 2 made the
    /// decoder read 135,332,483 from the offset 1888 and ask for 320 GB.
    #[test]
    fn tiff_sizes_count_samples_tiles_and_refuse_values_held_elsewhere() {
        let dir = tempfile::tempdir().unwrap();
        let scan = |name: &str, entries: &[(u16, u16, u32, u32)]| {
            let mut e = vec![(50706, 1, 4, 0x0001_0401)];
            e.extend_from_slice(entries);
            let p = write(dir.path(), name, &tiff_le(42, &e));
            let len = std::fs::metadata(&p).unwrap().len();
            tiff(&mut File::open(&p).unwrap(), 0, len).unwrap()
        };
        let d = scan(
            "plain.dng",
            &[(256, 4, 1, 1888), (257, 4, 1, 1182), (277, 3, 1, 1)],
        );
        assert_eq!((d.largest, d.bad), (Some((1888, 1182)), None));
        let d = scan(
            "cpp.dng",
            &[(256, 4, 1, 1888), (257, 4, 1, 1182), (277, 3, 1, 60000)],
        );
        assert_eq!(d.largest, Some((1888 * 60000, 1182)));
        let tiles = [
            (256, 4, 1, 100),
            (257, 4, 1, 100),
            (322, 4, 1, 1 << 20),
            (323, 4, 1, 256),
        ];
        assert_eq!(scan("tiles.dng", &tiles).largest, Some((1 << 20, 256)));
        for (name, entry) in [
            ("count.dng", (256, 4, 2, 40)),
            ("rational.dng", (257, 5, 1, 40)),
            ("cppcount.dng", (277, 3, 3, 40)),
        ] {
            let d = scan(name, &[(256, 4, 1, 64), (257, 4, 1, 64), entry]);
            assert!(
                d.bad.as_deref().is_some_and(|b| b.contains("a size")),
                "{name}: {d:?}"
            );
        }
    }

    #[test]
    fn damaged_structure_is_found() {
        let dir = tempfile::tempdir().unwrap();
        // An stsz announcing 2^31 sample sizes in a 20-byte box.
        let (_, d) = declared(&write(dir.path(), "a.cr3", &cr3(600, 400, 1 << 31)));
        assert!(
            d.bad.as_deref().is_some_and(|b| b.contains("stsz")),
            "{d:?}"
        );
        // A box claiming more than its parent holds: the mdat cut short.
        let mut b = cr3(600, 400, 1);
        b.truncate(b.len() - 10);
        let (_, d) = declared(&write(dir.path(), "b.cr3", &b));
        assert!(
            d.bad.as_deref().is_some_and(|b| b.contains("mdat")),
            "{d:?}"
        );
        // An X3F directory announcing more entries than the file holds.
        let mut b = x3f(100, 100);
        let n = b.len() - 20;
        b[n..n + 4].copy_from_slice(&0x0100_0000u32.to_le_bytes());
        let (_, d) = declared(&write(dir.path(), "c.x3f", &b));
        assert!(d.bad.is_some(), "{d:?}");
    }

    #[cfg(feature = "raw")]
    fn read(p: &Path, max_pixels: u64) -> Result<nsrm::Frame, crate::IoError> {
        crate::read_frame(
            p,
            &crate::ReadOptions {
                limits: crate::Limits { max_pixels },
                ..Default::default()
            },
        )
    }

    /// Huge declared sizes are refused over `--max-pixels` before decoding: none of these
    /// skeletons is a file rawler could decode (no camera it knows, no CMT boxes in the CR3
    /// sense it needs), so an over-limit error can only come from the headers read here.
    #[cfg(feature = "raw")]
    #[test]
    fn huge_declared_sizes_are_refused_before_decoding() {
        use crate::IoError;
        let dir = tempfile::tempdir().unwrap();
        let cases: [(&str, Vec<u8>, &str); 8] = [
            ("a.cr3", cr3(1 << 20, 1 << 20, 1), "1048576×1048576"),
            ("b.raf", raf(60000, 60000, 100, 100), "60000×60000"),
            ("c.raf", raf(100, 100, 1 << 20, 1 << 19), "1048576×524288"),
            ("d.mrw", mrw(60000, 50000), "60000×50000"),
            ("e.crw", crw(65535, 65535), "65535×65535"),
            ("f.x3f", x3f(1 << 30, 1 << 30), "1073741824×1073741824"),
            ("g.rw2", rw2(1 << 20, 1 << 20), "1048576×1048576"),
            // SuperCCD: 15000² is within 2²⁸, the turned image 22500² is not.
            ("h.raf", raf_layout(15000, 15000, 0, 0, 0), "22500×22500"),
        ];
        for (name, bytes, dims) in cases {
            let p = write(dir.path(), name, &bytes);
            match read(&p, 1 << 28) {
                Err(IoError::OverLimit { why, .. }) => assert!(why.contains(dims), "{name}: {why}"),
                r => panic!("{name}: {r:?}"),
            }
        }
        // Within the limit, the decoder runs and refuses what it cannot read (no camera).
        let p = write(dir.path(), "ok.cr3", &cr3(600, 400, 1));
        let r = read(&p, 1 << 28);
        assert!(matches!(r, Err(IoError::Corrupt { .. })), "{r:?}");
        // Damaged structure and no declared size: refused, naming why.
        let p = write(dir.path(), "bad.cr3", &cr3(600, 400, u32::MAX));
        match read(&p, 1 << 28) {
            Err(IoError::Corrupt { why, .. }) => assert!(why.contains("stsz"), "{why}"),
            r => panic!("{r:?}"),
        }
        let p = write(dir.path(), "none.mrw", &mrw(0, 0));
        match read(&p, 1 << 28) {
            Err(IoError::Corrupt { why, .. }) => assert!(why.contains("no image size"), "{why}"),
            r => panic!("{r:?}"),
        }
    }

    mod mutated {
        use super::*;
        use proptest::prelude::*;

        proptest! {
            // A fixed seed, so that CI runs the same cases each time. Random ones found three
            // files on which rawler allocated gigabytes, each now refused before it and kept as
            // a test (`an_mrw_without_its_tiff_block_is_refused`,
            // `an_entry_of_unknown_type_counts_its_bytes`, `a_raf_fuji_ifd_bomb_is_refused`).
            // `PROPTEST_RNG_SEED` / `PROPTEST_CASES` explore further (under `ulimit -v`: an
            // allocation bomb aborts the process instead of failing the case).
            #![proptest_config(ProptestConfig {
                cases: std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256),
                failure_persistence: None,
                rng_seed: proptest::test_runner::RngSeed::Fixed(
                    std::env::var("PROPTEST_RNG_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(42),
                ),
                ..ProptestConfig::default()
            })]
            /// Mutated container headers: the header reading never panics, and a read gives an
            /// error or a frame within the pixel limit, never an abort.
            #[test]
            fn mutated_containers_never_panic(
                which in 0usize..6,
                edits in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..16),
                cut in proptest::option::of(any::<usize>()),
            ) {
                // Each skeleton and the length of its signature, which stays (else it is
                // another kind of file); edits land after it.
                let (mut b, keep) = match which {
                    0 => (cr3(600, 400, 1), 12),
                    1 => (raf(600, 400, 600, 400), 15),
                    2 => (mrw(600, 400), 4),
                    3 => (crw(600, 400), 14),
                    4 => (x3f(600, 400), 4),
                    _ => (rw2(600, 400), 4),
                };
                for (at, v) in edits {
                    let n = b.len() - keep;
                    b[keep + at % n] = v;
                }
                if let Some(c) = cut {
                    b.truncate(keep + c % (b.len() - keep + 1));
                }
                let dir = tempfile::tempdir().unwrap();
                let p = write(dir.path(), "m.raw", &b);
                let s = sniff(&p);
                prop_assert!(s.is_ok(), "{s:?}");
                #[cfg(feature = "raw")]
                if let Ok(f) = read(&p, 1 << 22) {
                    prop_assert!(f.pixels() as u64 <= 1 << 22);
                }
            }
        }
    }
}
