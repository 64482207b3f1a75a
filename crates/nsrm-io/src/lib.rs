//! Frames in and out: linear camera-raw OpenEXR and TIFF files, read into a [`Frame`] with
//! everything the correction does not touch kept aside, and written back with that pass-through
//! data unchanged.
//!
//! * **OpenEXR** (via the `exr` crate): half, float or uint channels; scanline or tiled; single- or
//!   multi-part; any compression the crate decodes. The colour channels are found by name: `R`,
//!   `G`, `B` (and `A`, which passes through), or `NAME.R`, … / a part named `NAME` when a layer is
//!   asked for ([`ReadOptions::layer`]). Every other channel, every part, every mip/rip level and
//!   the header attributes are kept and written back; only `R`, `G`, `B` change (to float, or
//!   half when asked), plus the colour attributes (see [`WriteOptions`]).
//! * **TIFF** (via the `tiff` crate): RGB or RGBA, 16-bit unsigned (scaled to `[0, 1]`) or 16/32-bit
//!   float, taken as linear. Anything else (8-bit, palette, CMYK, grey, signed or 32-bit integer
//!   samples) is refused with the file name and the reason.
//!
//! The encoders write into any [`WriteSeek`] the caller gives: where a file lands, and whether
//! a partial one can be seen, is the caller's policy (the `nsrm` command's output session stages
//! each output in a temporary and commits it whole).
//!
//! Beside them: the batch plan ([`batch`]: inputs expanded, sliced into shards, outputs named)
//! and its executor (`batch::execute`), display-referred chart frames ([`display`]), camera raw
//! decoding ([`raw`], feature `raw`), sRGB PNG previews ([`preview`]) and the frame pool.
#![forbid(unsafe_code)]
#![deny(unreachable_pub)]
#![warn(missing_docs)]

/// The unit tests' kit, shared with the integration tests (the corrector's public API only).
#[cfg(test)]
#[path = "../../../tests/all/common/kit.rs"]
#[allow(unreachable_pub, dead_code)]
mod kit;

pub mod batch;
mod batch_exec;
pub mod display;
mod jpeg;
mod openexr;
pub mod preview;
pub mod raw;
mod tif;

pub use {
    display::Encoding,
    nsrm::{Concern, Param},
    raw::Demosaic,
};

/// What the library's encoders write into: any seekable writer that can move between threads
/// (a [`std::fs::File`], a `BufWriter` of one, a `Cursor<Vec<u8>>`). The library never decides
/// where a file lands: [`Decoded::write_to`] encodes into one of these, and the caller (the
/// `nsrm` command's output session, an embedder's own policy) owns the file.
pub trait WriteSeek: std::io::Write + std::io::Seek + Send {}

impl<T: std::io::Write + std::io::Seek + Send + ?Sized> WriteSeek for T {}

/// The ZIP level written when none is asked for (libdeflate's levels, 0-12): 1, the fastest,
/// which still compresses noisy float plates about as much as the higher levels. See
/// BENCHMARKS.md.
pub const DEFAULT_ZIP_LEVEL: u8 = 1;

/// The highest deflate level libdeflate has (`--zip-level` accepts 0 to this).
pub const MAX_ZIP_LEVEL: u8 = 12;

use nsrm::Frame;
use nsrm::OutputSpace;
use std::path::{Path, PathBuf};

/// Errors from reading, writing or listing frames. A cause is part of the message and not also
/// the `source()`, so an `anyhow` chain (`{:#}`) never prints it twice.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("{}: cannot read: {err}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        err: std::io::Error,
    },
    /// The file's signature is none of the formats read.
    #[error("{}: not an OpenEXR, TIFF or camera raw file (its first bytes are none of their signatures)", path.display())]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// The `exr` crate refused the file.
    #[error("{}: unreadable OpenEXR file: {err}", path.display())]
    Exr {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        err: ::exr::error::Error,
    },
    /// The `tiff` crate refused the file.
    #[error("{}: unreadable TIFF file: {err}", path.display())]
    Tiff {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        err: ::tiff::TiffError,
    },
    /// A well-formed file of a kind nsrm does not read (8-bit or palette TIFF, lossy raw, …).
    #[error("{}: unsupported: {why}", path.display())]
    Unsupported {
        /// The file.
        path: PathBuf,
        /// What is not supported.
        why: String,
    },
    /// The camera RGB cannot be found; `concern` says when the layer is the way out (several
    /// layers and none named) or the cause (a layer named that is not there).
    #[error("{}: {why}", path.display())]
    Channels {
        /// The file.
        path: PathBuf,
        /// Which channels were looked for and what the file has.
        why: String,
        /// The parameter that is the cause or the way out, if one is.
        concern: Option<nsrm::Concern>,
    },
    /// A frame could not be encoded into the output format.
    #[error("{}: cannot encode: {why}", path.display())]
    Encode {
        /// The output file.
        path: PathBuf,
        /// What the encoder refused.
        why: String,
    },
    /// Writing an output's bytes failed.
    #[error("{}: cannot write: {err}", path.display())]
    Write {
        /// The output file.
        path: PathBuf,
        /// The system's error.
        err: std::io::Error,
    },
    /// Where the output goes refused it or failed (a [`batch::FrameSink`]'s own error: for the
    /// `nsrm` command, an output that exists, a signal, a failed commit).
    #[error("{err}")]
    Output {
        /// Whether the request itself is wrong (an output that is an input, two outputs that
        /// are one file), not the file system.
        usage: bool,
        /// The sink's error.
        err: Box<dyn std::error::Error + Send + Sync>,
    },
    /// An input (a file, directory or glob) names no frame.
    #[error("input `{spec}`: {why}")]
    NoMatch {
        /// The input as given.
        spec: String,
        /// Why nothing matched.
        why: String,
    },
    /// A `--shard` value is malformed.
    #[error("shard `{spec}`: {why}")]
    Shard {
        /// The value as given.
        spec: String,
        /// What is wrong with it.
        why: String,
    },
    /// A request that cannot be carried out (a frame that does not fit a writer, …).
    #[error("{0}")]
    Invalid(String),
    /// A parameter of the request is out of range (`concern` says which).
    #[error("{why}")]
    Param {
        /// The parameter.
        concern: nsrm::Concern,
        /// What is wrong with its value.
        why: String,
    },
    /// A header asks for more pixels than [`Limits::max_pixels`] allows.
    #[error("{}: {why}", path.display())]
    OverLimit {
        /// The file.
        path: PathBuf,
        /// The size asked for and the limit.
        why: String,
    },
    /// A header asks for more than the file can hold or the machine can address.
    #[error("{}: {why}", path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// The size asked for and what bounds it.
        why: String,
    },
    /// The file is damaged: missing, repeated or out-of-file data blocks, and the like.
    #[error("{}: corrupt: {why}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What is damaged.
        why: String,
    },
}

impl IoError {
    /// True for inputs that name no frame, a malformed shard, and a parameter value out of range.
    pub fn is_usage(&self) -> bool {
        use IoError;
        matches!(
            self,
            IoError::NoMatch { .. }
                | IoError::Shard { .. }
                | IoError::Output { usage: true, .. }
                | IoError::Param {
                    concern: nsrm::Concern::Value(_),
                    ..
                }
        )
    }

    /// The parameter this error is about: a frame over the pixel limit, a layer that is not
    /// there or not named where several are, a rendered chart's option out of range.
    pub fn concern(&self) -> Option<nsrm::Concern> {
        use IoError;
        match self {
            IoError::OverLimit { .. } => Some(nsrm::Concern::Remedy(nsrm::Param::MaxPixels)),
            IoError::Channels { concern, .. } => *concern,
            IoError::Param { concern, .. } => Some(*concern),
            _ => None,
        }
    }
}

/// The default of [`Limits::max_pixels`] (and `--max-pixels`): 2²⁸ = 268 435 456 pixels
/// (16384 × 16384, 32× an 8K UHD frame): 3 GiB of f32 RGB.
pub const DEFAULT_MAX_PIXELS: u64 = 1 << 28;

/// Bounds on what a frame's header may make a reader allocate. Checked from the header, before
/// any pixel buffer exists; buffers whose size comes from a file are then allocated fallibly
/// (`try_filled`), so a hostile or damaged file costs an error, never the process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Most pixels in one frame (width × height; for a multi-part / multi-level EXR, of all the
    /// image data together).
    pub max_pixels: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_pixels: DEFAULT_MAX_PIXELS,
        }
    }
}

impl Limits {
    /// Checks a `width × height` frame of `channels` samples of `bytes_per_sample` bytes against
    /// [`max_pixels`](Self::max_pixels) and, when `stored_bytes` says how much of the file the
    /// samples may take (uncompressed data: the file's length), against that. Returns the pixel
    /// count.
    pub(crate) fn check_frame(
        &self,
        path: &Path,
        width: u64,
        height: u64,
        channels: u64,
        bytes_per_sample: u64,
        stored_bytes: Option<u64>,
    ) -> Result<usize, IoError> {
        let too = |why: String| IoError::TooLarge {
            path: path.to_path_buf(),
            why,
        };
        let pixels = width.checked_mul(height).filter(|&p| p <= self.max_pixels);
        let Some(pixels) = pixels else {
            return Err(IoError::OverLimit {
                path: path.to_path_buf(),
                why: format!(
                    "the header claims {width}×{height} pixels, more than the limit of {} pixels",
                    self.max_pixels
                ),
            });
        };
        let bytes = pixels
            .checked_mul(channels)
            .and_then(|s| s.checked_mul(bytes_per_sample));
        if let (Some(have), Some(need)) = (stored_bytes, bytes) {
            if need > have {
                return Err(too(format!(
                    "the header claims {width}×{height}×{channels} uncompressed samples \
                     ({need} bytes), but the file holds only {have} bytes"
                )));
            }
        }
        match bytes.and_then(|b| isize::try_from(b).ok()) {
            Some(_) => Ok(pixels as usize),
            None => Err(too(format!(
                "{width}×{height}×{channels} samples do not fit in this machine's memory"
            ))),
        }
    }
}

/// A vector of `n` copies of `value`, allocated fallibly: an error naming `path` instead of an
/// abort when memory runs out. For buffers whose size comes from a file.
pub(crate) fn try_filled<T: Clone>(path: &Path, n: usize, value: T) -> Result<Vec<T>, IoError> {
    let mut v = try_with_capacity(path, n)?;
    v.resize(n, value);
    Ok(v)
}

/// A vector of `n` zeros, allocated fallibly (see [`try_filled`]) and zeroed lazily: a large
/// allocation takes fresh pages from the kernel, which come zeroed, so nothing is written until
/// the caller writes the samples (no pass over the whole buffer first).
pub(crate) fn try_zeroed<T: bytemuck::Zeroable>(path: &Path, n: usize) -> Result<Vec<T>, IoError> {
    bytemuck::allocation::try_zeroed_vec(n).map_err(|()| IoError::TooLarge {
        path: path.to_path_buf(),
        why: format!(
            "not enough memory for {n} samples ({} bytes)",
            n.saturating_mul(std::mem::size_of::<T>())
        ),
    })
}

/// Frame sample buffers handed back by [`Decoded::write_to_recycling`] for the next
/// [`Decoded::read_pooled`]: a batch then allocates only as many frame buffers as it holds
/// frames at once, instead of one per frame (a fresh 24-Mpixel frame costs ~70 000 page faults,
/// each zeroing a page, and its release as much again). Holds at most `max` buffers; the
/// decoding and encoding threads share it by reference.
#[derive(Debug)]
pub struct FramePool {
    buffers: std::sync::Mutex<Vec<Vec<f32>>>,
    max: usize,
}

impl FramePool {
    /// A pool keeping at most `max` idle buffers.
    pub fn new(max: usize) -> FramePool {
        FramePool {
            buffers: Default::default(),
            max,
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Vec<f32>>> {
        self.buffers.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Keeps `buffer` for a later frame (dropped when the pool is full).
    pub(crate) fn give(&self, buffer: Vec<f32>) {
        if buffer.capacity() == 0 {
            return;
        }
        let mut b = self.lock();
        if b.len() < self.max {
            b.push(buffer);
        }
    }

    /// Idle buffers held now.
    #[cfg(test)]
    pub(crate) fn idle(&self) -> usize {
        self.lock().len()
    }

    /// A buffer of `n` samples whose contents are left over from an earlier frame (only for a
    /// reader that overwrites every sample), or `None` if no idle buffer is large enough; then
    /// one idle buffer is released, so the caller's new allocation does not add to the memory
    /// held.
    pub(crate) fn take(&self, n: usize) -> Option<Vec<f32>> {
        let mut b = self.lock();
        match b.iter().position(|v| v.capacity() >= n) {
            Some(i) => {
                let mut v = b.swap_remove(i);
                drop(b);
                // Zeroes only what lies past the old length (nothing for same-size frames).
                v.resize(n, 0.0);
                Some(v)
            }
            None => {
                let old = b.pop();
                drop(b);
                drop(old);
                None
            }
        }
    }
}

/// An empty vector with room for `n` elements, allocated fallibly (see [`try_filled`]).
pub(crate) fn try_with_capacity<T>(path: &Path, n: usize) -> Result<Vec<T>, IoError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| IoError::TooLarge {
        path: path.to_path_buf(),
        why: format!(
            "not enough memory for {n} samples ({} bytes)",
            n.saturating_mul(std::mem::size_of::<T>())
        ),
    })?;
    Ok(v)
}

/// File formats frames are read from and written to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum FileFormat {
    /// OpenEXR (`.exr`).
    #[default]
    #[cfg_attr(feature = "clap", value(name = "exr", alias = "openexr"))]
    Exr,
    /// TIFF (`.tif`, `.tiff`).
    #[cfg_attr(feature = "clap", value(name = "tiff", alias = "tif"))]
    Tiff,
}

impl FileFormat {
    /// Parses `exr` / `tiff` (also `tif`).
    pub fn parse(s: &str) -> Option<FileFormat> {
        match s.trim().to_ascii_lowercase().as_str() {
            "exr" | "openexr" => Some(FileFormat::Exr),
            "tif" | "tiff" => Some(FileFormat::Tiff),
            _ => None,
        }
    }

    /// The format a file name's extension names (`.exr`, `.tif`, `.tiff`, any case).
    pub fn from_extension(path: &Path) -> Option<FileFormat> {
        FileFormat::parse(path.extension()?.to_str()?)
    }

    /// The format of a file by its signature (first four bytes).
    pub(crate) fn sniff(path: &Path) -> Result<FileFormat, IoError> {
        use std::io::Read;
        let mut magic = [0u8; 4];
        let mut read = || -> std::io::Result<usize> {
            // Never open a FIFO (it would block) or read a device.
            nsrm::limits::check_regular(path)?;
            let mut f = std::fs::File::open(path)?;
            let mut n = 0;
            while n < 4 {
                match f.read(&mut magic[n..])? {
                    0 => break,
                    k => n += k,
                }
            }
            Ok(n)
        };
        let n = read().map_err(|err| IoError::Read {
            path: path.to_path_buf(),
            err,
        })?;
        match &magic[..n] {
            [0x76, 0x2f, 0x31, 0x01] => Ok(FileFormat::Exr),
            [b'I', b'I', 42 | 43, 0] | [b'M', b'M', 0, 42 | 43] => Ok(FileFormat::Tiff),
            _ => Err(IoError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The extension written: `exr` or `tif`.
    pub(crate) fn extension(self) -> &'static str {
        match self {
            FileFormat::Exr => "exr",
            FileFormat::Tiff => "tif",
        }
    }

    /// `OpenEXR` / `TIFF`.
    pub fn name(self) -> &'static str {
        match self {
            FileFormat::Exr => "OpenEXR",
            FileFormat::Tiff => "TIFF",
        }
    }
}

/// How inputs are read.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// The EXR layer holding the camera RGB: channels `NAME.R`, `NAME.G`, `NAME.B` (and
    /// `NAME.A`), or `R`, `G`, `B` in a part named `NAME`. `None`: channels `R`, `G`, `B`.
    pub layer: Option<String>,
    /// Bounds on the header's sizes, checked before allocating.
    pub limits: Limits,
    /// How a camera raw file's CFA mosaic becomes RGB ([`Demosaic`]).
    pub demosaic: raw::Demosaic,
}

/// Lossless EXR compressions an output may be written with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum ExrCompression {
    /// The input's compression when it is lossless (else ZIP); ZIP for TIFF and camera raw
    /// inputs (at the `--zip-level`, default 1).
    #[default]
    #[cfg_attr(feature = "clap", value(name = "keep"))]
    Keep,
    /// Uncompressed.
    #[cfg_attr(feature = "clap", value(name = "none"))]
    None,
    /// Run-length encoded.
    #[cfg_attr(feature = "clap", value(name = "rle"))]
    Rle,
    /// ZIP, one scanline per block.
    #[cfg_attr(feature = "clap", value(name = "zips"))]
    Zips,
    /// ZIP, 16 scanlines per block.
    #[cfg_attr(feature = "clap", value(name = "zip"))]
    Zip,
    /// PIZ (wavelet and Huffman; 32 scanlines per block), the usual choice for noisy plates.
    #[cfg_attr(feature = "clap", value(name = "piz"))]
    Piz,
}

impl ExrCompression {
    /// Every choice with its command-line name.
    pub const ALL: [(ExrCompression, &'static str); 6] = [
        (ExrCompression::Keep, "keep"),
        (ExrCompression::None, "none"),
        (ExrCompression::Rle, "rle"),
        (ExrCompression::Zips, "zips"),
        (ExrCompression::Zip, "zip"),
        (ExrCompression::Piz, "piz"),
    ];

    /// Parses `keep`, `none`, `rle`, `zips`, `zip` or `piz` (the command line's names, checked
    /// against its parser).
    pub fn parse(s: &str) -> Option<ExrCompression> {
        Self::ALL
            .iter()
            .find(|(_, n)| n.eq_ignore_ascii_case(s.trim()))
            .map(|(c, _)| *c)
    }
}

/// How outputs are written.
#[derive(Debug, Clone, Copy)]
pub struct WriteOptions {
    /// The file format written.
    pub format: FileFormat,
    /// EXR only: write the corrected `R`, `G`, `B` as half floats instead of 32-bit floats.
    pub half: bool,
    /// EXR only: the compression of every part written. Lossy input compressions (DWA, B44,
    /// PXR24) are never reused: re-encoding would alter the pass-through channels again.
    pub compression: ExrCompression,
    /// The space the pixels are in (they must already be; see [`nsrm::output_model`]). Sets the EXR
    /// attribute `colorInteropID` to [`OutputSpace::interop_id`] and the `chromaticities`
    /// attribute to the space's primaries and white (removed for XYZ).
    pub space: OutputSpace,
    /// EXR only: the deflate level (libdeflate's, 0–12; higher is taken as 12) of ZIP and ZIPS
    /// outputs written by the chunk-level path; the default, 1 (`--zip-level`), is chosen for
    /// speed.
    pub zip_level: u8,
}

/// EXR, 32-bit floats, the input's compression when lossless, CIE XYZ, ZIP level 1.
impl Default for WriteOptions {
    fn default() -> WriteOptions {
        WriteOptions {
            format: FileFormat::Exr,
            half: false,
            compression: ExrCompression::Keep,
            space: OutputSpace::Xyz,
            zip_level: DEFAULT_ZIP_LEVEL,
        }
    }
}

/// A decoded input: the camera RGB to correct, and everything needed to write the file back.
#[derive(Debug)]
pub struct Decoded {
    /// The input file.
    pub path: PathBuf,
    /// The format it was read as.
    pub format: FileFormat,
    /// Full-resolution camera RGB ([`nsrm::Layout::Rgb`]; alpha is kept aside).
    pub frame: Frame,
    /// Lower mip/rip levels of a multi-resolution EXR, largest first (usually empty). They are
    /// corrected like the frame.
    pub levels: Vec<Frame>,
    container: Container,
}

#[derive(Debug)]
enum Container {
    Exr(Box<openexr::ExrContainer>),
    Tiff(tif::TiffContainer),
    /// A camera raw file: no pass-through data, only what it says about the camera.
    #[cfg_attr(not(feature = "raw"), allow(dead_code))]
    Raw(Box<raw::CameraInfo>),
}

impl Decoded {
    /// The frame and every lower resolution level: what a corrector must process.
    pub fn frames_mut(&mut self) -> impl Iterator<Item = &mut Frame> {
        std::iter::once(&mut self.frame).chain(self.levels.iter_mut())
    }

    /// Total pixels over the frame and its levels.
    pub fn pixels(&self) -> usize {
        self.frame.pixels() + self.levels.iter().map(Frame::pixels).sum::<usize>()
    }

    /// What a camera raw input says about the camera and the shot (`None` for EXR and TIFF).
    pub fn camera(&self) -> Option<&raw::CameraInfo> {
        match &self.container {
            Container::Raw(c) => Some(c),
            _ => None,
        }
    }

    /// The full-resolution frame with its alpha (RGB, or RGBA when the input has alpha); the
    /// levels and everything else passed through are dropped.
    pub fn into_frame(self) -> Frame {
        let alpha = match &self.container {
            Container::Exr(c) => c.alpha_f32(),
            Container::Tiff(c) => c.alpha.clone(),
            Container::Raw(_) => None,
        };
        let Some(a) = alpha else {
            return self.frame;
        };
        let mut data = Vec::with_capacity(self.frame.pixels() * 4);
        for (px, a) in self.frame.data.chunks_exact(3).zip(a) {
            data.extend_from_slice(px);
            data.push(a);
        }
        Frame {
            width: self.frame.width,
            height: self.frame.height,
            layout: nsrm::Layout::Rgba,
            data,
        }
    }

    /// Decodes `path` (EXR, TIFF or, with the `raw` feature, a camera raw file; told by its
    /// content, not its name). [`into_frame`](Self::into_frame) gives one frame of it;
    /// [`write_to`](Self::write_to) writes it back with everything passed through.
    pub fn read(path: &Path, opts: &ReadOptions) -> Result<Decoded, IoError> {
        Decoded::read_from(path, opts, None)
    }

    /// [`read`](Self::read), taking the frame's buffer from `pool` where one fits (the
    /// chunk-level EXR path, which overwrites every sample).
    pub fn read_pooled(
        path: &Path,
        opts: &ReadOptions,
        pool: &FramePool,
    ) -> Result<Decoded, IoError> {
        Decoded::read_from(path, opts, Some(pool))
    }

    /// Decodes `path`; a panic inside a decoder crate (an assertion it trips on a layout it
    /// mishandles) is contained here and reported as this file's error, so it never ends the
    /// process or a batch.
    fn read_from(
        path: &Path,
        opts: &ReadOptions,
        pool: Option<&FramePool>,
    ) -> Result<Decoded, IoError> {
        let run = std::panic::AssertUnwindSafe(|| Decoded::decode(path, opts, pool));
        std::panic::catch_unwind(run).unwrap_or_else(|payload| {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "no message".into());
            Err(IoError::Unsupported {
                path: path.to_path_buf(),
                why: format!("the decoder failed on this file's layout ({what})"),
            })
        })
    }

    fn decode(
        path: &Path,
        opts: &ReadOptions,
        pool: Option<&FramePool>,
    ) -> Result<Decoded, IoError> {
        if raw::sniff(path)? != raw::Sniff::Plain {
            return Decoded::read_raw(path, opts);
        }
        match FileFormat::sniff(path)? {
            FileFormat::Exr => openexr::read(path, opts, pool),
            FileFormat::Tiff => {
                if let Some(layer) = &opts.layer {
                    return Err(IoError::Channels {
                        path: path.to_path_buf(),
                        why: format!("a TIFF has no layers, but layer `{layer}` was asked for"),
                        concern: Some(nsrm::Concern::Value(nsrm::Param::Layer)),
                    });
                }
                tif::read(path, &opts.limits)
            }
        }
    }

    #[cfg(feature = "raw")]
    fn read_raw(path: &Path, opts: &ReadOptions) -> Result<Decoded, IoError> {
        if let Some(layer) = &opts.layer {
            return Err(IoError::Channels {
                path: path.to_path_buf(),
                why: format!("a camera raw file has no layers, but layer `{layer}` was asked for"),
                concern: Some(nsrm::Concern::Value(nsrm::Param::Layer)),
            });
        }
        let r = raw::read(path, &opts.limits, opts.demosaic)?;
        Ok(Decoded {
            path: path.to_path_buf(),
            format: FileFormat::Tiff,
            frame: r.frame,
            levels: Vec::new(),
            container: Container::Raw(Box::new(r.info)),
        })
    }

    #[cfg(not(feature = "raw"))]
    fn read_raw(path: &Path, _opts: &ReadOptions) -> Result<Decoded, IoError> {
        Err(IoError::Unsupported {
            path: path.to_path_buf(),
            why: "a camera raw file, and this build of nsrm reads none (cargo feature `raw`)"
                .into(),
        })
    }

    /// Encodes the (corrected) pixels into `w`, with the pass-through data of the input, in
    /// `opts.format`; `dest` names the output in errors. Writing a TIFF refuses an EXR input
    /// that has channels other than RGB(A), since a TIFF cannot carry them. Where `w` leads is the
    /// caller's: a file it created, a temporary it commits later, a buffer.
    ///
    /// ```
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// use nsrm_io::{Decoded, FileFormat, WriteOptions};
    /// let data = vec![0.2, 0.3, 0.4, 0.5, 0.6, 0.7];
    /// let frame = nsrm::Frame::from_data(2, 1, nsrm::Layout::Rgb, data).ok_or("size")?;
    /// let mut bytes = std::io::Cursor::new(Vec::new());
    /// let opts = WriteOptions { format: FileFormat::Tiff, ..WriteOptions::default() };
    /// Decoded::from(frame).write_to(std::path::Path::new("out.tif"), &opts, &mut bytes)?;
    /// assert!(bytes.into_inner().starts_with(b"II*\0"));
    /// # Ok(()) }
    /// ```
    pub fn write_to(
        self,
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
    ) -> Result<(), IoError> {
        self.write_returning(dest, opts, w).0
    }

    /// [`write_to`](Self::write_to), then gives the frame's buffer to `pool` (whether or not
    /// the write succeeded) for a later [`read_pooled`](Self::read_pooled).
    pub fn write_to_recycling(
        self,
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
        pool: &FramePool,
    ) -> Result<(), IoError> {
        let (r, buffer) = self.write_returning(dest, opts, w);
        pool.give(buffer);
        r
    }

    /// [`write_to`](Self::write_to), and the frame's sample buffer.
    fn write_returning(
        self,
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
    ) -> (Result<(), IoError>, Vec<f32>) {
        let Decoded {
            path,
            frame,
            levels,
            container,
            ..
        } = self;
        let r = Decoded::write_parts(&path, &frame, &levels, container, dest, opts, w);
        (r, frame.data)
    }

    fn write_parts(
        path: &Path,
        frame: &Frame,
        levels: &[Frame],
        container: Container,
        dest: &Path,
        opts: &WriteOptions,
        w: &mut dyn WriteSeek,
    ) -> Result<(), IoError> {
        match (opts.format, container) {
            (FileFormat::Exr, Container::Exr(c)) => c.write(frame, levels, dest, opts, w),
            (FileFormat::Exr, Container::Tiff(c)) => openexr::write_new(
                frame,
                c.alpha.as_deref(),
                dest,
                &openexr::NewExr::output(opts),
                w,
            ),
            (FileFormat::Tiff, Container::Exr(c)) => {
                let extra = c.extra_channels();
                if !extra.is_empty() {
                    return Err(IoError::Encode {
                        path: dest.to_path_buf(),
                        why: format!(
                            "the input {} has channels a TIFF cannot carry ({}); write OpenEXR instead",
                            path.display(),
                            extra.join(", ")
                        ),
                    });
                }
                let alpha = c.alpha_f32();
                tif::write(frame, alpha.as_deref(), dest, w)
            }
            (FileFormat::Tiff, Container::Tiff(c)) => {
                tif::write(frame, c.alpha.as_deref(), dest, w)
            }
            (FileFormat::Exr, Container::Raw(c)) => openexr::write_new(
                frame,
                None,
                dest,
                &openexr::NewExr {
                    camera: Some(&c),
                    ..openexr::NewExr::output(opts)
                },
                w,
            ),
            (FileFormat::Tiff, Container::Raw(_)) => tif::write(frame, None, dest, w),
        }
    }
}

/// A frame made in memory (RGB, or RGBA: the alpha is kept aside and written back), with nothing
/// else to pass through: [`Decoded::write_to`] writes it as a new EXR (f32 channels, or half with
/// `half`; `colorInteropID` and `chromaticities` for its `space`) or a 32-bit float TIFF.
/// [`Decoded::path`] is empty and [`Decoded::format`] [`FileFormat::Exr`].
impl From<Frame> for Decoded {
    fn from(frame: Frame) -> Decoded {
        let (frame, alpha) = match frame.layout {
            nsrm::Layout::Rgb => (frame, None),
            nsrm::Layout::Rgba => split_alpha(&frame),
        };
        Decoded {
            path: PathBuf::new(),
            format: FileFormat::Exr,
            frame,
            levels: Vec::new(),
            container: Container::Tiff(tif::TiffContainer { alpha }),
        }
    }
}

/// Writes a frame of camera RGB (no colour space attribute): a 32-bit float TIFF when `dest`
/// ends in `.tif`/`.tiff`, else a float EXR carrying the `text` attributes (name, value) in its
/// header; encoded into `w`.
pub fn write_camera_float(
    frame: &Frame,
    dest: &Path,
    text: &[(&str, &str)],
    w: &mut dyn WriteSeek,
) -> Result<(), IoError> {
    if FileFormat::from_extension(dest) == Some(FileFormat::Tiff) {
        tif::write(frame, None, dest, w)
    } else {
        openexr::write_new(
            frame,
            None,
            dest,
            &openexr::NewExr {
                half: false,
                compression: ExrCompression::Keep,
                zip_level: DEFAULT_ZIP_LEVEL,
                space: None,
                text,
                camera: None,
            },
            w,
        )
    }
}

/// Reads an EXR or TIFF into one frame (RGB, or RGBA when the file has alpha); pass-through
/// data is dropped ([`Decoded::into_frame`] of [`Decoded::read`]).
pub fn read_frame(path: &Path, opts: &ReadOptions) -> Result<Frame, IoError> {
    read_frame_and_camera(path, opts).map(|(f, _)| f)
}

/// [`read_frame`], and what a camera raw file says about its camera (`None` for EXR / TIFF).
pub(crate) fn read_frame_and_camera(
    path: &Path,
    opts: &ReadOptions,
) -> Result<(Frame, Option<raw::CameraInfo>), IoError> {
    let d = Decoded::read(path, opts)?;
    let camera = d.camera().cloned();
    Ok((d.into_frame(), camera))
}

fn split_alpha(frame: &Frame) -> (Frame, Option<Vec<f32>>) {
    match frame.layout {
        nsrm::Layout::Rgb => (frame.clone(), None),
        nsrm::Layout::Rgba => {
            let mut rgb = Vec::with_capacity(frame.pixels() * 3);
            let mut a = Vec::with_capacity(frame.pixels());
            for px in frame.data.chunks_exact(4) {
                rgb.extend_from_slice(&px[..3]);
                a.push(px[3]);
            }
            (
                Frame {
                    width: frame.width,
                    height: frame.height,
                    layout: nsrm::Layout::Rgb,
                    data: rgb,
                },
                Some(a),
            )
        }
    }
}

/// What an EXR's or TIFF's header says of its largest frame, read without decoding a pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HeaderSize {
    /// Width in pixels.
    pub width: u64,
    /// Height in pixels.
    pub height: u64,
    /// Stored bytes per pixel of its channels other than R, G and B (those become the camera
    /// RGB; an alpha is kept aside): what a batch holds beside the frame's 12 bytes a pixel.
    pub extra_bytes_per_pixel: u64,
}

/// The largest frame of an EXR or TIFF file, from its header only (a farm submitter sizes a
/// task's memory with it); `None` for other files and for headers that do not read.
pub fn header_size(path: &Path) -> Option<HeaderSize> {
    let mut magic = [0u8; 4];
    {
        use std::io::Read;
        let mut f = std::fs::File::open(path).ok()?;
        f.read_exact(&mut magic).ok()?;
    }
    if magic == [0x76, 0x2f, 0x31, 0x01] {
        let meta = ::exr::meta::MetaData::read_from_file(path, false).ok()?;
        let mut best = (0u64, 0u64, 0u64);
        for h in meta.headers.iter() {
            let (w, ht) = (h.layer_size.0 as u64, h.layer_size.1 as u64);
            let stored: u64 = h
                .channels
                .list
                .iter()
                .filter(|c| {
                    let name = c.name.to_string();
                    let last = name.rsplit('.').next().unwrap_or("");
                    !matches!(last, "R" | "G" | "B")
                })
                .map(|c| c.sample_type.bytes_per_sample() as u64)
                .sum();
            if w * ht * (12 + stored) > best.0 * best.1 * (12 + best.2) {
                best = (w, ht, stored);
            }
        }
        return (best.0 > 0).then_some(HeaderSize {
            width: best.0,
            height: best.1,
            extra_bytes_per_pixel: best.2,
        });
    }
    if &magic[..2] == b"II" || &magic[..2] == b"MM" {
        let f = std::io::BufReader::new(std::fs::File::open(path).ok()?);
        let mut dec = tiff::decoder::Decoder::new(f).ok()?;
        let (w, h) = dec.dimensions().ok()?;
        // The alpha is kept aside as f32; other layouts are counted as four more channels.
        let bytes_pp = match dec.colortype().ok()? {
            tiff::ColorType::RGB(_) | tiff::ColorType::Gray(_) => 0,
            tiff::ColorType::RGBA(_) | tiff::ColorType::GrayA(_) => 4,
            _ => 16,
        };
        return Some(HeaderSize {
            width: u64::from(w),
            height: u64::from(h),
            extra_bytes_per_pixel: bytes_pp,
        });
    }
    None
}

#[cfg(test)]
#[path = "lib_tests.rs"]
mod tests;
