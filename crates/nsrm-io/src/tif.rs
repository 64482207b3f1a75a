//! TIFF in (16-bit unsigned, 16/32/64-bit float; RGB or RGBA; linear) and out (32-bit float).

use super::WriteSeek;
use super::{Container, Decoded, FileFormat, IoError};
use nsrm::{Frame, Layout};
use std::io::BufReader;
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::encoder::{colortype, Compression, DeflateLevel, TiffEncoder};
use tiff::ColorType;

/// What a TIFF carries besides the camera RGB.
#[derive(Debug)]
pub(crate) struct TiffContainer {
    /// The alpha channel, as f32 (16-bit unsigned scaled to `[0, 1]`).
    pub alpha: Option<Vec<f32>>,
}

fn unsupported(path: &Path, why: impl Into<String>) -> IoError {
    IoError::Unsupported {
        path: path.to_path_buf(),
        why: why.into(),
    }
}

/// The sample types read, as the tiff crate decodes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sample {
    U16,
    F16,
    F32,
    F64,
}

impl Sample {
    fn bytes(self) -> u64 {
        match self {
            Sample::U16 | Sample::F16 => 2,
            Sample::F32 => 4,
            Sample::F64 => 8,
        }
    }

    /// An empty buffer of this type with room for `n` samples, reserved fallibly, so that the
    /// decoder fills it without allocating (it only grows a buffer that is too small).
    fn buffer(self, path: &Path, n: usize) -> Result<DecodingResult, IoError> {
        use super::try_with_capacity as cap;
        Ok(match self {
            Sample::U16 => DecodingResult::U16(cap(path, n)?),
            Sample::F16 => DecodingResult::F16(cap(path, n)?),
            Sample::F32 => DecodingResult::F32(cap(path, n)?),
            Sample::F64 => DecodingResult::F64(cap(path, n)?),
        })
    }
}

/// Decoded samples as f32 (16-bit unsigned scaled to `[0, 1]`), in a buffer with room for
/// `cap` of them.
fn to_f32(path: &Path, buf: DecodingResult, cap: usize) -> Result<Vec<f32>, IoError> {
    let mut raw: Vec<f32> = super::try_with_capacity(path, cap)?;
    match buf {
        DecodingResult::U16(v) => raw.extend(v.into_iter().map(|x| x as f32 / 65535.0)),
        DecodingResult::F32(v) => raw = v,
        DecodingResult::F16(v) => raw.extend(v.into_iter().map(|x| x.to_f32())),
        DecodingResult::F64(v) => raw.extend(v.into_iter().map(|x| x as f32)),
        _ => {
            return Err(unsupported(
                path,
                "a sample type other than the one declared",
            ))
        }
    }
    Ok(raw)
}

/// The image assembled chunk (strip or tile) by chunk: `channels` interleaved samples per pixel
/// (R, G, B and alpha when there is one), from planes (`planar`: one sample per chunk, planes
/// in sample order) or from chunky chunks that may carry extra samples after them. Edge tiles
/// hold only their data part.
fn by_chunks<R: std::io::Read + std::io::Seek>(
    dec: &mut Decoder<R>,
    path: &Path,
    (w, h): (u32, u32),
    sample: Sample,
    channels: usize,
    planar: bool,
) -> Result<Vec<f32>, IoError> {
    let tiff_err = |err| IoError::Tiff {
        path: path.to_path_buf(),
        err,
    };
    let corrupt = |why: String| IoError::Corrupt {
        path: path.to_path_buf(),
        why,
    };
    let (width, height) = (w as usize, h as usize);
    let n = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels))
        .ok_or_else(|| unsupported(path, "too many samples"))?;
    let mut out = super::try_filled(path, n, 0.0f32)?;
    let (cw, ch) = dec.chunk_dimensions();
    let (cw, ch) = (cw.max(1) as usize, ch.max(1) as usize);
    let across = width.div_ceil(cw);
    let per_plane = across * height.div_ceil(ch);
    let planes = if planar { channels } else { 1 };
    for plane in 0..planes {
        for k in 0..per_plane {
            let index = u32::try_from(plane * per_plane + k)
                .map_err(|_| unsupported(path, "too many chunks"))?;
            let (x0, y0) = ((k % across) * cw, (k / across) * ch);
            let (dw, dh) = (cw.min(width - x0), ch.min(height - y0));
            // The crate's own idea of the chunk's data size: for planes after the first it
            // counts edge tiles as whole (tiff 0.11 `get_padding` takes the plane's tiles for
            // further rows), which is harmless here since a tile is stored whole; only the
            // image's part of it is used.
            let (cdw, cdh) = dec.chunk_data_dimensions(index);
            let (cdw, cdh) = (cdw as usize, cdh as usize);
            let need = if planar { 1 } else { channels };
            let buf = dec.read_chunk(index).map_err(tiff_err)?;
            let data = to_f32(path, buf, cdw * cdh * need)?;
            let texels = cdw * cdh;
            let spc = data.len().checked_div(texels).unwrap_or(0);
            let fits = cdw >= dw && cdh >= dh && data.len() == texels * spc;
            if !fits || spc < need || (planar && spc != 1) {
                return Err(corrupt(format!(
                    "chunk {index} holds {} {} samples for its {dw}×{dh} pixels of {need}",
                    data.len(),
                    match sample {
                        Sample::U16 => "16-bit",
                        Sample::F16 => "half",
                        Sample::F32 => "float",
                        Sample::F64 => "double",
                    }
                )));
            }
            for (row, src) in data.chunks_exact(cdw * spc).take(dh).enumerate() {
                let base = ((y0 + row) * width + x0) * channels;
                for (i, px) in src.chunks_exact(spc).take(dw).enumerate() {
                    let dst = base + i * channels;
                    if planar {
                        out[dst + plane] = px[0];
                    } else {
                        out[dst..dst + channels].copy_from_slice(&px[..channels]);
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The sample type of the image, from BitsPerSample and SampleFormat, or why it is refused.
fn sample_type(bits: u8, format: u16) -> Result<Sample, String> {
    const READ: &str = "only 16-bit unsigned and 16/32/64-bit float samples are read";
    match (format, bits) {
        (1, 16) => Ok(Sample::U16),
        (3, 16) => Ok(Sample::F16),
        (3, 32) => Ok(Sample::F32),
        (3, 64) => Ok(Sample::F64),
        (1, 8) => Err(
            "8 bits per sample; linear camera data must be 16-bit unsigned or float \
                       (8-bit files are display-encoded)"
                .into(),
        ),
        (1, b) => Err(format!("{b} bits per sample (unsigned integer); {READ}")),
        (2, b) => Err(format!("{b} bits per sample (signed integer); {READ}")),
        (3, b) => Err(format!("{b} bits per sample (float); {READ}")),
        (f, b) => Err(format!(
            "{b} bits per sample in sample format {f} (neither integer nor float); {READ}"
        )),
    }
}

/// Checks the strip or tile table: exactly the number of chunks the image needs, each non-empty,
/// inside the file, and no two sharing bytes (several rows read from one chunk would be
/// made-up pixels).
fn check_chunks<R: std::io::Read + std::io::Seek>(
    dec: &mut Decoder<R>,
    path: &Path,
    (w, h): (u32, u32),
    samples: u64,
    file_len: u64,
) -> Result<(), IoError> {
    use tiff::decoder::ChunkType;
    use tiff::tags::Tag;
    let corrupt = |why: String| IoError::Corrupt {
        path: path.to_path_buf(),
        why,
    };
    let tiff_err = |err| IoError::Tiff {
        path: path.to_path_buf(),
        err,
    };
    let planar = dec
        .find_tag_unsigned::<u16>(Tag::PlanarConfiguration)
        .map_err(tiff_err)?
        .unwrap_or(1)
        == 2;
    let planes = if planar { samples } else { 1 };
    let (kind, offsets_tag, counts_tag, expected) = match dec.get_chunk_type() {
        ChunkType::Strip => {
            let rows = dec
                .find_tag_unsigned::<u64>(Tag::RowsPerStrip)
                .map_err(tiff_err)?
                .unwrap_or(u64::from(h))
                .clamp(1, u64::from(h).max(1));
            (
                "strip",
                Tag::StripOffsets,
                Tag::StripByteCounts,
                u64::from(h).div_ceil(rows) * planes,
            )
        }
        ChunkType::Tile => {
            let tw = dec
                .find_tag_unsigned::<u64>(Tag::TileWidth)
                .map_err(tiff_err)?;
            let th = dec
                .find_tag_unsigned::<u64>(Tag::TileLength)
                .map_err(tiff_err)?;
            let (Some(tw @ 1..), Some(th @ 1..)) = (tw, th) else {
                return Err(corrupt("a tiled image without a tile size".into()));
            };
            (
                "tile",
                Tag::TileOffsets,
                Tag::TileByteCounts,
                u64::from(w).div_ceil(tw) * u64::from(h).div_ceil(th) * planes,
            )
        }
    };
    let offsets = dec
        .find_tag_unsigned_vec::<u64>(offsets_tag)
        .map_err(tiff_err)?
        .unwrap_or_default();
    let counts = dec
        .find_tag_unsigned_vec::<u64>(counts_tag)
        .map_err(tiff_err)?
        .unwrap_or_default();
    if offsets.len() as u64 != expected || counts.len() as u64 != expected {
        return Err(corrupt(format!(
            "the image needs {expected} {kind}s but the file lists {} offsets and {} byte counts",
            offsets.len(),
            counts.len()
        )));
    }
    let mut ranges: Vec<(u64, u64, usize)> = Vec::with_capacity(offsets.len());
    for (i, (&o, &n)) in offsets.iter().zip(&counts).enumerate() {
        let end = o.checked_add(n).filter(|&e| e <= file_len);
        let Some(end) = end.filter(|_| n > 0) else {
            return Err(corrupt(format!(
                "{kind} {i} ({n} bytes at offset {o}) is {} the {file_len}-byte file",
                if n == 0 {
                    "empty, missing from"
                } else {
                    "past the end of"
                }
            )));
        };
        ranges.push((o, end, i));
    }
    ranges.sort_unstable();
    for pair in ranges.windows(2) {
        let ((_, end_a, a), (start_b, _, b)) = (pair[0], pair[1]);
        if start_b < end_a {
            return Err(corrupt(format!(
                "{kind}s {a} and {b} point at the same bytes of the file (offset {start_b})"
            )));
        }
    }
    Ok(())
}

/// Reads an RGB or RGBA TIFF of 16-bit unsigned or float samples: the decoder opened within
/// bounds ([`open_decoder`]), the colour type and sample type checked ([`rgb_channels`],
/// [`uniform_sample_type`]), the frame size and the chunk table checked, the samples read
/// (whole, or chunk by chunk for planar files and extra samples), and alpha split off
/// ([`split_alpha`]).
pub(super) fn read(path: &Path, limits: &super::Limits) -> Result<Decoded, IoError> {
    let tiff_err = |err| IoError::Tiff {
        path: path.to_path_buf(),
        err,
    };
    let (mut dec, file_len) = open_decoder(path, limits)?;
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    let ct = dec.colortype().map_err(tiff_err)?;
    let (channels, bits) = rgb_channels(path, ct)?;
    let sample = uniform_sample_type(&mut dec, path, bits)?;
    let compression = dec
        .find_tag_unsigned::<u16>(tiff::tags::Tag::Compression)
        .map_err(tiff_err)?
        .unwrap_or(1);
    // Every sample the file says it stores (extra samples included).
    let samples = dec
        .find_tag_unsigned::<u64>(tiff::tags::Tag::SamplesPerPixel)
        .map_err(tiff_err)?
        .unwrap_or(channels as u64)
        .max(channels as u64);
    let n = limits.check_frame(
        path,
        w.into(),
        h.into(),
        samples,
        sample.bytes(),
        (compression == 1).then_some(file_len),
    )?;
    check_chunks(&mut dec, path, (w, h), samples, file_len)?;
    let planar = dec
        .find_tag_unsigned::<u16>(tiff::tags::Tag::PlanarConfiguration)
        .map_err(tiff_err)?
        .unwrap_or(1)
        == 2;
    // The whole-image read of the tiff crate serves the common layout (chunky, no extra samples);
    // planar files and extra samples are assembled here chunk by chunk (the crate's whole-image
    // path asserts on planar tiles with partial edge tiles, and drops extra samples).
    let interleaved = if planar || samples != channels as u64 {
        by_chunks(&mut dec, path, (w, h), sample, channels, planar)?
    } else {
        let total = n
            .checked_mul(channels)
            .ok_or_else(|| unsupported(path, "too many samples"))?;
        let mut buf = sample.buffer(path, total)?;
        dec.read_image_to_buffer(&mut buf).map_err(tiff_err)?;
        let raw = to_f32(path, buf, total)?;
        if raw.len() < total {
            return Err(IoError::Corrupt {
                path: path.to_path_buf(),
                why: format!("holds {} samples for {w}×{h}×{channels}", raw.len()),
            });
        }
        raw
    };
    let (rgb, alpha) = split_alpha(path, interleaved, channels, n)?;
    Ok(Decoded {
        path: path.to_path_buf(),
        format: FileFormat::Tiff,
        frame: Frame {
            width: w as usize,
            height: h as usize,
            layout: Layout::Rgb,
            data: rgb,
        },
        levels: Vec::new(),
        container: Container::Tiff(TiffContainer { alpha }),
    })
}

/// The file opened in a decoder with its own bounds (a whole frame within `--max-pixels` of
/// RGBA f64, tag values such as the strip tables bounded by the file itself), and its length.
fn open_decoder(
    path: &Path,
    limits: &super::Limits,
) -> Result<(Decoder<BufReader<std::fs::File>>, u64), IoError> {
    let read_err = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    let file = std::fs::File::open(path).map_err(read_err)?;
    let file_len = file.metadata().map_err(read_err)?.len();
    let mut tiff_limits = Limits::default();
    tiff_limits.decoding_buffer_size =
        usize::try_from(limits.max_pixels.saturating_mul(32)).unwrap_or(usize::MAX);
    tiff_limits.intermediate_buffer_size = 1 << 30;
    tiff_limits.ifd_value_size = usize::try_from(file_len.min(1 << 30)).unwrap_or(1 << 30);
    let dec = Decoder::new(BufReader::new(file))
        .map_err(|err| IoError::Tiff {
            path: path.to_path_buf(),
            err,
        })?
        .with_limits(tiff_limits);
    Ok((dec, file_len))
}

/// The channels (3: RGB, 4: RGBA) and bits per sample of a colour type, or why it is refused.
fn rgb_channels(path: &Path, ct: ColorType) -> Result<(usize, u8), IoError> {
    Ok(match ct {
        ColorType::RGB(b) => (3usize, b),
        ColorType::RGBA(b) => (4, b),
        ColorType::Gray(_) | ColorType::GrayA(_) => {
            return Err(unsupported(
                path,
                "one colour channel (greyscale); camera RGB needs R, G and B",
            ))
        }
        ColorType::Palette(_) => return Err(unsupported(path, "palette (indexed) colour")),
        ColorType::CMYK(_) | ColorType::CMYKA(_) => return Err(unsupported(path, "CMYK colour")),
        ColorType::YCbCr(_) => return Err(unsupported(path, "YCbCr colour")),
        ColorType::Lab(_) => return Err(unsupported(path, "CIE L*a*b* colour")),
        ColorType::Multiband {
            bit_depth,
            num_samples,
        } => {
            return Err(unsupported(
                path,
                format!(
                    "{num_samples} samples per pixel of {bit_depth} bits with no RGB \
                     interpretation (photometric interpretation grey)"
                ),
            ))
        }
        other => return Err(unsupported(path, format!("colour type {other:?}"))),
    })
}

/// The sample type of samples of `bits` bits: one SampleFormat per sample, all alike (the
/// decoder reads them as one type).
fn uniform_sample_type<R: std::io::Read + std::io::Seek>(
    dec: &mut Decoder<R>,
    path: &Path,
    bits: u8,
) -> Result<Sample, IoError> {
    let formats = dec
        .find_tag_unsigned_vec::<u16>(tiff::tags::Tag::SampleFormat)
        .map_err(|err| IoError::Tiff {
            path: path.to_path_buf(),
            err,
        })?
        .unwrap_or_default();
    let format = formats.first().copied().unwrap_or(1);
    if formats.iter().any(|&f| f != format) {
        return Err(unsupported(
            path,
            format!("mixed sample formats {formats:?}"),
        ));
    }
    sample_type(bits, format).map_err(|why| unsupported(path, why))
}

/// The first `n` pixels of `interleaved` (`channels` samples each) as RGB, and their alpha
/// when there are four channels.
fn split_alpha(
    path: &Path,
    interleaved: Vec<f32>,
    channels: usize,
    n: usize,
) -> Result<(Vec<f32>, Option<Vec<f32>>), IoError> {
    let mut rgb = super::try_with_capacity(path, n * 3)?;
    let alpha = if channels == 4 {
        let mut a = super::try_with_capacity(path, n)?;
        for px in interleaved.chunks_exact(channels).take(n) {
            rgb.extend_from_slice(&px[..3]);
            a.push(px[3]);
        }
        Some(a)
    } else {
        for px in interleaved.chunks_exact(channels).take(n) {
            rgb.extend_from_slice(&px[..3]);
        }
        None
    };
    Ok((rgb, alpha))
}

/// Encodes a 32-bit float RGB or RGBA TIFF (deflate) into `out` (`dest` names it in errors).
pub(super) fn write(
    rgb: &Frame,
    alpha: Option<&[f32]>,
    dest: &Path,
    out: &mut dyn WriteSeek,
) -> Result<(), IoError> {
    let encode_err = |why: String| IoError::Encode {
        path: dest.to_path_buf(),
        why,
    };
    let (Ok(w), Ok(h)) = (u32::try_from(rgb.width), u32::try_from(rgb.height)) else {
        return Err(encode_err(format!(
            "{}×{} is too big for a TIFF",
            rgb.width, rgb.height
        )));
    };
    let io_err = |err: std::io::Error| IoError::Write {
        path: dest.to_path_buf(),
        err,
    };
    let tiff_err = |e: tiff::TiffError| match e {
        tiff::TiffError::IoError(err) => io_err(err),
        other => encode_err(other.to_string()),
    };
    let rgb_data: Vec<f32> = match rgb.layout {
        Layout::Rgb => rgb.data.clone(),
        Layout::Rgba => rgb
            .data
            .chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect(),
    };
    let mut enc = TiffEncoder::new(out)
        .map_err(tiff_err)?
        .with_compression(Compression::Deflate(DeflateLevel::Balanced));
    match alpha {
        None => enc
            .write_image::<colortype::RGB32Float>(w, h, &rgb_data)
            .map_err(tiff_err)?,
        Some(a) => {
            let mut data = Vec::with_capacity(a.len() * 4);
            for (px, a) in rgb_data.chunks_exact(3).zip(a) {
                data.extend_from_slice(px);
                data.push(*a);
            }
            enc.write_image::<colortype::RGBA32Float>(w, h, &data)
                .map_err(tiff_err)?
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_rgb_and_rgba_colour_types_are_read() {
        let p = Path::new("x.tif");
        assert_eq!(rgb_channels(p, ColorType::RGB(16)).unwrap(), (3, 16));
        assert_eq!(rgb_channels(p, ColorType::RGBA(32)).unwrap(), (4, 32));
        for refused in [
            ColorType::Gray(16),
            ColorType::CMYK(8),
            ColorType::Palette(8),
        ] {
            let e = rgb_channels(p, refused).unwrap_err();
            assert!(matches!(e, IoError::Unsupported { .. }), "{refused:?}: {e}");
        }
    }

    #[test]
    fn alpha_is_split_off_and_extra_pixels_dropped() {
        let p = Path::new("x.tif");
        let rgba = vec![1.0, 2.0, 3.0, 0.5, 4.0, 5.0, 6.0, 0.25, 9.0, 9.0, 9.0, 9.0];
        let (rgb, alpha) = split_alpha(p, rgba, 4, 2).unwrap();
        assert_eq!(rgb, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(alpha.unwrap(), [0.5, 0.25]);
        let (rgb, alpha) = split_alpha(p, vec![1.0, 2.0, 3.0], 3, 1).unwrap();
        assert_eq!((rgb, alpha), (vec![1.0, 2.0, 3.0], None));
    }
}
