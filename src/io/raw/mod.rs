//! Camera raw files (NEF, CR2, CR3, ARW, RAF, ORF, RW2, PEF, DNG, …) as frames, decoded by the
//! `rawler` crate (feature `raw`).
//!
//! **Values** follow LibRaw's `dcraw_emu -4 -T -o 0 -r 1 1 1 1` (linear camera RGB, up to its
//! 16-bit scale): the black level is subtracted per CFA position, negatives are clamped to 0, the
//! result is divided by (white level − black level; with unequal per-position blacks, the
//! smallest, as LibRaw does); no white balance and no colour matrix. The
//! sensor's active area and the file's default crop are applied.
//!
//! **Orientation** is not applied: the frame stays in the sensor's orientation (like
//! `dcraw_emu -t 0` or rawpy's `user_flip=0`); the file's orientation is reported in
//! [`CameraInfo::orientation`]. A colour correction is per pixel, so this changes nothing in its
//! values, and chart detection finds charts at any rotation.
//!
//! **Demosaic** ([`Demosaic`]): `half` makes one pixel of each 2×2 CFA block (R, the mean of the
//! two greens, B: no interpolation); `bilinear` is LibRaw's linear interpolation (neighbours of
//! each colour in the 3×3 window, edge neighbours weighted 2, corners 1); `mhc` is the
//! gradient-corrected linear interpolation of Malvar, He and Cutler (ICASSP 2004), with the
//! bilinear rule on the outer two rows and columns. Fujifilm X-Trans and four-colour sensors go
//! through rawler's own demosaic (bilinear) whatever is asked, and a monochrome or already-RGB
//! (linear DNG) file is only scaled.
//!
//! **Hostile files:** the file must be a regular file no larger than [`MAX_RAW_BYTES`]; in a
//! TIFF-based raw (DNG, NEF, ARW, PEF, …) the image dimensions in every IFD are checked against
//! [`Limits::max_pixels`] before the decoder runs; for other containers (CR3, RAF, …) the
//! decoded mosaic is checked before anything of nsrm's is allocated. A panic inside the decoder
//! is caught and reported as a corrupt file.

use super::IoError;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

#[cfg(feature = "raw")]
mod decode;
#[cfg(feature = "raw")]
mod demosaic;
#[cfg(feature = "raw")]
pub(crate) use decode::read;

/// The largest raw file read: 2 GiB (real raw files are 10–200 MB).
pub(crate) const MAX_RAW_BYTES: u64 = 2 << 30;

/// How a CFA mosaic becomes RGB pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Demosaic {
    /// One pixel per 2×2 block (half width and height), no interpolation: what chart readers use.
    Half,
    /// LibRaw's linear interpolation.
    Bilinear,
    /// Malvar–He–Cutler gradient-corrected interpolation (full resolution).
    #[default]
    Mhc,
}

impl Demosaic {
    /// Every choice with its name.
    pub(crate) const ALL: [(Demosaic, &'static str); 3] = [
        (Demosaic::Half, "half"),
        (Demosaic::Bilinear, "bilinear"),
        (Demosaic::Mhc, "mhc"),
    ];

    /// Parses `half`, `bilinear` or `mhc` (also `malvar`).
    #[cfg(test)]
    pub(crate) fn parse(s: &str) -> Option<Demosaic> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("malvar") {
            return Some(Demosaic::Mhc);
        }
        Self::ALL
            .iter()
            .find(|(_, n)| n.eq_ignore_ascii_case(s))
            .map(|(d, _)| *d)
    }

    /// The name `--demosaic` takes (`half`, `bilinear`, `mhc`).
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(d, _)| *d == self)
            .map_or("?", |(_, n)| n)
    }
}

/// What a raw file says about the camera and the shot (carried into EXR outputs and into a
/// model's capture provenance).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct CameraInfo {
    /// Camera maker (normalised by rawler, e.g. `Canon`).
    pub make: String,
    /// Camera model (normalised by rawler, e.g. `EOS 550D`).
    pub model: String,
    /// ISO speed, when recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iso: Option<f32>,
    /// Exposure time in seconds, when recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure_time: Option<f32>,
    /// F-number, when recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aperture: Option<f32>,
    /// The as-shot neutral in camera RGB (green = 1), when recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub as_shot_neutral: Option<[f32; 3]>,
    /// The file's orientation (TIFF Orientation 1–8; 0 unknown). Not applied to the pixels.
    #[serde(default)]
    pub orientation: u16,
    /// The CFA pattern as rawler names it (`RGGB`, a 36-letter X-Trans pattern, or empty).
    #[serde(default)]
    pub cfa: String,
    /// The demosaic the frame was made with.
    #[serde(default)]
    pub demosaic: String,
}

impl CameraInfo {
    /// `make model`, for messages and comparisons.
    pub fn camera(&self) -> String {
        format!("{} {}", self.make.trim(), self.model.trim())
            .trim()
            .to_string()
    }
}

/// Names raw files commonly have (lower case, without the dot).
pub(crate) const RAW_EXTENSIONS: [&str; 24] = [
    "dng", "cr2", "cr3", "crw", "nef", "nrw", "arw", "srf", "sr2", "raf", "orf", "rw2", "rwl",
    "pef", "srw", "erf", "kdc", "dcr", "dcs", "mef", "mos", "mrw", "iiq", "x3f",
];

/// Whether a file name has a raw file's extension (for listing directories and globs; the
/// content decides how a file is read).
pub(crate) fn is_raw_name(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| RAW_EXTENSIONS.iter().any(|r| r.eq_ignore_ascii_case(e)))
}

/// What the first bytes and (for TIFF) the IFDs say.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Sniff {
    /// Not a raw file (maybe a plain TIFF, an EXR, or nothing nsrm reads).
    Plain,
    /// A TIFF-based raw file; the largest image its IFDs declare (width, height), if any, and
    /// why its structure is damaged, if it is (an entry or IFD reaching past the end of the
    /// file: the decoder would allocate what the entry claims before finding out).
    TiffBased(Option<(u64, u64)>, Option<String>),
    /// A raw container that is not TIFF (CR3, RAF, ORF, RW2, …).
    Container,
}

/// Looks at `path`'s content: a raw file or not. A plain TIFF (no CFA or linear-raw image, no
/// DNG version, not a CR2) is not raw.
pub(crate) fn sniff(path: &Path) -> Result<Sniff, IoError> {
    let rd = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    crate::limits::check_regular(path).map_err(rd)?;
    let mut f = std::fs::File::open(path).map_err(rd)?;
    let mut head = [0u8; 32];
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]).map_err(rd)? {
            0 => break,
            k => n += k,
        }
    }
    let h = &head[..n];
    let starts = |s: &[u8]| h.starts_with(s);
    let at = |o: usize, s: &[u8]| h.len() >= o + s.len() && &h[o..o + s.len()] == s;
    if at(4, b"ftypcrx ") || starts(b"FUJIFILMCCD-RAW") || starts(b"FOVb") || starts(b"\0MRM") {
        return Ok(Sniff::Container);
    }
    // ORF (IIRO, IIRS, MMOR), RW2 / RWL (IIU\0), CRW (II\x1a\0\0\0HEAPCCDR), IIQ (IIII).
    if starts(b"IIRO") || starts(b"IIRS") || starts(b"MMOR") || starts(b"IIU\0") {
        return Ok(Sniff::Container);
    }
    if at(6, b"HEAPCCDR") || (starts(b"IIII") && at(8, b"IIII")) {
        return Ok(Sniff::Container);
    }
    let tiff = starts(b"II*\0") || starts(b"MM\0*");
    if !tiff {
        return Ok(Sniff::Plain);
    }
    let cr2 = at(8, b"CR\x02\0");
    let scan = scan_tiff(&mut f, h[0] == b'I').map_err(rd)?;
    if cr2 || scan.raw {
        Ok(Sniff::TiffBased(scan.largest, scan.bad))
    } else {
        Ok(Sniff::Plain)
    }
}

#[derive(Debug, Default)]
struct TiffScan {
    raw: bool,
    largest: Option<(u64, u64)>,
    /// The first entry or IFD found to reach past the end of the file.
    bad: Option<String>,
}

/// Walks a TIFF's IFD chain and SubIFDs (bounded: 64 IFDs, 4096 entries each, depth 3) for the
/// raw markers (DNGVersion, a CFA or LinearRaw photometric) and the largest declared image.
/// Damaged structure ends the walk; it is the decoder's to report.
fn scan_tiff(f: &mut std::fs::File, le: bool) -> std::io::Result<TiffScan> {
    let len = f.metadata()?.len();
    let u16_of = |b: &[u8]| {
        if le {
            u16::from_le_bytes([b[0], b[1]])
        } else {
            u16::from_be_bytes([b[0], b[1]])
        }
    };
    let u32_of = |b: &[u8]| {
        if le {
            u32::from_le_bytes([b[0], b[1], b[2], b[3]])
        } else {
            u32::from_be_bytes([b[0], b[1], b[2], b[3]])
        }
    };
    let mut hdr = [0u8; 8];
    f.seek(SeekFrom::Start(0))?;
    f.read_exact(&mut hdr)?;
    if u16_of(&hdr[2..4]) != 42 {
        // BigTIFF: not a raw layout rawler reads.
        return Ok(TiffScan::default());
    }
    let mut scan = TiffScan::default();
    let mut queue: Vec<(u64, u32)> = vec![(u64::from(u32_of(&hdr[4..8])), 0)];
    let mut seen = std::collections::HashSet::new();
    while let Some((off, depth)) = queue.pop() {
        if off < 8 || off + 2 > len || seen.len() >= 64 || !seen.insert(off) {
            continue;
        }
        f.seek(SeekFrom::Start(off))?;
        let mut cnt = [0u8; 2];
        f.read_exact(&mut cnt)?;
        let count = u64::from(u16_of(&cnt)).min(4096);
        if off + 2 + count * 12 + 4 > len {
            scan.bad.get_or_insert_with(|| {
                format!("an IFD at byte {off} runs past the end of the file")
            });
            continue;
        }
        let mut entries = vec![0u8; (count * 12 + 4) as usize];
        f.read_exact(&mut entries)?;
        let (mut w, mut h, mut photometric) = (0u64, 0u64, 0u32);
        for e in entries[..(count * 12) as usize].chunks_exact(12) {
            let tag = u16_of(&e[0..2]);
            let typ = u16_of(&e[2..4]);
            let n = u32_of(&e[4..8]);
            let value = match typ {
                3 => u32::from(u16_of(&e[8..10])),
                _ => u32_of(&e[8..12]),
            };
            let size: u64 = match typ {
                1 | 2 | 6 | 7 => 1,
                3 | 8 => 2,
                4 | 9 | 11 | 13 => 4,
                5 | 10 | 12 => 8,
                _ => 0,
            };
            let bytes = u64::from(n) * size;
            if bytes > 4 && u64::from(u32_of(&e[8..12])) + bytes > len {
                scan.bad.get_or_insert_with(|| {
                    format!("tag {tag} claims {bytes} bytes, past the end of the file")
                });
            }
            match tag {
                256 => w = u64::from(value),
                257 => h = u64::from(value),
                262 => photometric = value,
                50706 => scan.raw = true,
                // EXIF, GPS and interoperability IFDs: the decoder parses them too.
                34665 | 34853 | 40965 if depth < 3 && n == 1 && (typ == 4 || typ == 13) => {
                    queue.push((u64::from(value), depth + 1));
                }
                330 if depth < 3 => {
                    // SubIFDs: one offset inline, or an array of offsets.
                    if n == 1 {
                        queue.push((u64::from(value), depth + 1));
                    } else if n > 1 && u64::from(value) + u64::from(n) * 4 <= len {
                        let here = f.stream_position()?;
                        f.seek(SeekFrom::Start(u64::from(value)))?;
                        let mut offs = vec![0u8; n.min(64) as usize * 4];
                        f.read_exact(&mut offs)?;
                        for o in offs.chunks_exact(4) {
                            queue.push((u64::from(u32_of(o)), depth + 1));
                        }
                        f.seek(SeekFrom::Start(here))?;
                    }
                }
                _ => {}
            }
        }
        if photometric == 32803 || photometric == 34892 {
            scan.raw = true;
        }
        if w > 0 && h > 0 && scan.largest.is_none_or(|(a, b)| a * b < w * h) {
            scan.largest = Some((w, h));
        }
        let next = u64::from(u32_of(&entries[(count * 12) as usize..]));
        if next != 0 {
            queue.push((next, depth));
        }
    }
    Ok(scan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demosaic_names() {
        for (d, n) in Demosaic::ALL {
            assert_eq!(Demosaic::parse(n), Some(d));
            assert_eq!(d.name(), n);
        }
        assert_eq!(Demosaic::parse("Malvar"), Some(Demosaic::Mhc));
        assert_eq!(Demosaic::parse("ppg"), None);
    }

    #[test]
    fn raw_names() {
        assert!(is_raw_name(Path::new("a/IMG_0001.CR3")));
        assert!(is_raw_name(Path::new("x.dng")));
        assert!(!is_raw_name(Path::new("x.tif")));
    }
}
