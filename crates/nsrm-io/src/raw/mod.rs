//! Camera raw files (NEF, CR2, CR3, ARW, RAF, ORF, RW2, PEF, DNG, …) as frames, decoded by the
//! `rawler` crate (feature `raw`).
//!
//! **Values** follow LibRaw's `dcraw_emu -4 -T -o 0 -r 1 1 1 1` (linear camera RGB, up to its
//! 16-bit scale): the black level is subtracted per CFA position, negatives are clamped to 0, the
//! result is divided by (white level − black level; with unequal per-position blacks, the
//! smallest, as LibRaw does); no white balance and no colour matrix. The
//! sensor's active area and the file's default crop are applied.
//!
//! **Orientation** is applied as LibRaw applies it by default (`dcraw_emu`, rawpy's
//! `postprocess`): the developed frame, in every demosaic (`half` included), is turned from the
//! sensor's orientation to the one the file records (TIFF Orientation 1–8, [`CameraInfo::orientation`];
//! in a DNG its `Orientation` tag), so 5–8 swap width and height (`orient`).
//!
//! **Demosaic** ([`Demosaic`]): `half` makes one pixel of each 2×2 CFA block (R, the mean of the
//! two greens, B: no interpolation); `bilinear` is LibRaw's linear interpolation (neighbours of
//! each colour in the 3×3 window, edge neighbours weighted 2, corners 1); `mhc` is the
//! gradient-corrected linear interpolation of Malvar, He and Cutler (ICASSP 2004), with the
//! bilinear rule on the outer two rows and columns. Fujifilm X-Trans (6×6 CFA): `half` makes
//! one pixel of each 3×3 block (each colour the mean of its sites there), `bilinear` is
//! LibRaw's linear interpolation on X-Trans, and `mhc` (a Bayer method) gives `bilinear`
//! (see `xtrans`). Other patterns go through rawler's own development, four-colour sensors are
//! refused, and a monochrome or already-RGB (linear DNG) file is only scaled.
//!
//! **Hostile files:** the file must be a regular file no larger than [`MAX_RAW_BYTES`]. Before
//! the decoder runs, the image sizes the headers declare are checked against
//! `Limits::max_pixels`: in a TIFF-based raw (DNG, NEF, ARW,
//! PEF, …, and ORF / RW2) those of every IFD; in CR3, RAF, MRW, CRW and X3F those their own
//! headers declare (`container`); a structure that reaches past its end is refused as damaged,
//! and a container declaring no image size is refused. A RAF naming a camera whose mosaic rawler
//! turns by 45° (SuperCCD) has the turned image checked too, whatever its layout tag says. An IFD chain
//! that comes back to its own path (a cycle, which the decoder follows for ever) is refused. The
//! JPEG streams of a DNG's strips and tiles are checked from the streams themselves (`ljpeg`):
//! sizes against the tile and the pixel limit, Huffman tables, and the data walked to its last
//! sample, so that data that runs out is an error, not zeros. The decoded mosaic is checked again
//! before anything of nsrm's is allocated. A panic inside the decoder is caught and reported as
//! a corrupt file.

use super::IoError;
use std::io::Read;
use std::path::Path;

mod container;
mod orient;
pub(crate) use orient::describe as describe_orientation;
#[cfg(feature = "raw")]
mod decode;
#[cfg(feature = "raw")]
mod demosaic;
#[cfg(feature = "raw")]
mod ljpeg;
#[cfg(feature = "raw")]
mod xtrans;
#[cfg(feature = "raw")]
pub(crate) use decode::read;

/// The largest raw file read: 2 GiB (real raw files are 10–200 MB).
#[cfg(feature = "raw")]
pub(crate) const MAX_RAW_BYTES: u64 = 2 << 30;

/// How a CFA mosaic becomes RGB pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Demosaic {
    /// One pixel per 2×2 block (half width and height), no interpolation: what chart readers use.
    #[cfg_attr(feature = "clap", value(name = "half"))]
    Half,
    /// LibRaw's linear interpolation.
    #[cfg_attr(feature = "clap", value(name = "bilinear"))]
    Bilinear,
    /// Malvar–He–Cutler gradient-corrected interpolation (full resolution).
    #[default]
    #[cfg_attr(feature = "clap", value(name = "mhc", alias = "malvar"))]
    Mhc,
}

impl Demosaic {
    /// Every choice with its name.
    pub const ALL: [(Demosaic, &'static str); 3] = [
        (Demosaic::Half, "half"),
        (Demosaic::Bilinear, "bilinear"),
        (Demosaic::Mhc, "mhc"),
    ];

    /// Parses `half`, `bilinear` or `mhc` (also `malvar`).
    pub fn parse(s: &str) -> Option<Demosaic> {
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
    /// The file's orientation (TIFF Orientation 1–8; 0 unknown), applied to the pixels (the
    /// frame is in this orientation, as LibRaw's).
    #[serde(default)]
    pub orientation: u16,
    /// The CFA pattern as rawler names it (`RGGB`, a 36-letter X-Trans pattern, or empty).
    #[serde(default)]
    pub cfa: String,
    /// The demosaic the frame was made with.
    #[serde(default)]
    pub demosaic: String,
    /// The file's colour matrices (XYZ → camera RGB, row-major), each with the EXIF light
    /// source it is for (17 A, 21 D65, …): what the DNG pipeline finds a neutral's light with.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub color_matrices: Vec<(u16, [f64; 9])>,
    /// The level each channel of the frame clips at (the file's white level, in the frame's
    /// scale: 1 where every CFA position has the same black level), when the levels are known:
    /// what the highlight policy (`nsrm::model::highlights`) takes as the clip.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clip_level: Option<[f32; 3]>,
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

/// What the first bytes and the headers say.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Sniff {
    /// Not a raw file (maybe a plain TIFF, an EXR, or nothing nsrm reads).
    Plain,
    /// A TIFF-based raw file; the largest image its IFDs declare (width, height), if any, and
    /// why its structure is damaged, if it is (an entry or IFD reaching past the end of the
    /// file: the decoder would allocate what the entry claims before finding out).
    TiffBased(Option<(u64, u64)>, Option<String>),
    /// A raw container that is not TIFF (CR3, RAF, ORF, RW2, …): its name and what its headers
    /// declare ([`container`]).
    Container(&'static str, container::Declared),
}

/// Looks at `path`'s content: a raw file or not, and what its headers declare. A plain TIFF (no
/// CFA or linear-raw image, no DNG version, not a CR2) is not raw.
pub(crate) fn sniff(path: &Path) -> Result<Sniff, IoError> {
    let rd = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    nsrm::limits::check_regular(path).map_err(rd)?;
    let mut f = std::fs::File::open(path).map_err(rd)?;
    let len = f.metadata().map_err(rd)?.len();
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
    let f = &mut f;
    let found = |kind, d: std::io::Result<container::Declared>| {
        d.map(|d| Sniff::Container(kind, d)).map_err(rd)
    };
    if at(4, b"ftypcrx ") {
        return found("CR3", container::cr3(f, len));
    }
    if starts(b"FUJIFILMCCD-RAW") {
        return found("RAF", container::raf(f, len));
    }
    if starts(b"FOVb") {
        return found("X3F", container::x3f(f, len));
    }
    if starts(b"\0MRM") {
        return found("MRW", container::mrw(f, len));
    }
    // CRW (II\x1a\0\0\0HEAPCCDR): CIFF heaps.
    if at(6, b"HEAPCCDR") {
        return found("CRW", container::crw(f, len));
    }
    // ORF (IIRO, IIRS, MMOR), RW2 / RWL (IIU\0): TIFF structures with their own magic.
    if starts(b"IIRO") || starts(b"IIRS") || starts(b"MMOR") || starts(b"IIU\0") {
        let kind = if starts(b"IIU\0") { "RW2" } else { "ORF" };
        return found(kind, container::tiff(f, 0, len));
    }
    // IIQ (IIII … IIII): a layout nsrm reads no size from.
    if starts(b"IIII") && at(8, b"IIII") {
        return Ok(Sniff::Container("IIQ", container::Declared::default()));
    }
    let tiff = starts(b"II*\0") || starts(b"MM\0*");
    if !tiff {
        return Ok(Sniff::Plain);
    }
    let cr2 = at(8, b"CR\x02\0");
    let scan = container::tiff(f, 0, len).map_err(rd)?;
    if cr2 || scan.raw_marker {
        Ok(Sniff::TiffBased(scan.largest, scan.bad))
    } else {
        Ok(Sniff::Plain)
    }
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
