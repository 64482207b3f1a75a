//! TIFF in (16-bit unsigned, 16/32/64-bit float; RGB or RGBA; linear) and out (32-bit float).

use super::{Container, Decoded, FileFormat, IoError};
use crate::atomic::{check_clobber, WriteError};
use crate::frame::{Frame, Layout};
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

pub(super) fn read(path: &Path, limits: &super::Limits) -> Result<Decoded, IoError> {
    let tiff_err = |err| IoError::Tiff {
        path: path.to_path_buf(),
        err,
    };
    let file = std::fs::File::open(path).map_err(|err| IoError::Read {
        path: path.to_path_buf(),
        err,
    })?;
    // Frames are big: allow up to 16 GiB decoded (the default is 256 MiB).
    let mut tiff_limits = Limits::default();
    tiff_limits.decoding_buffer_size = 16 << 30;
    tiff_limits.intermediate_buffer_size = 1 << 30;
    let mut dec = Decoder::new(BufReader::new(file))
        .map_err(tiff_err)?
        .with_limits(tiff_limits);
    let (w, h) = dec.dimensions().map_err(tiff_err)?;
    limits.check_frame(path, w.into(), h.into(), 1, 1, None)?;
    let ct = dec.colortype().map_err(tiff_err)?;
    let (channels, bits) = match ct {
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
        ColorType::Multiband { num_samples, .. } => {
            return Err(unsupported(
                path,
                format!("{num_samples} samples per pixel with no RGB interpretation"),
            ))
        }
        other => return Err(unsupported(path, format!("colour type {other:?}"))),
    };
    if bits == 8 {
        return Err(unsupported(
            path,
            "8-bit samples; linear camera data must be 16-bit unsigned or 32-bit float \
             (8-bit files are display-encoded)",
        ));
    }
    let mut buf = DecodingResult::U16(Vec::new());
    let layout = dec.read_image_to_buffer(&mut buf).map_err(tiff_err)?;
    let raw: Vec<f32> = match buf {
        DecodingResult::U16(v) => v.into_iter().map(|x| x as f32 / 65535.0).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F16(v) => v.into_iter().map(|x| x.to_f32()).collect(),
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::U8(_) => return Err(unsupported(path, "8-bit samples")),
        DecodingResult::U32(_) | DecodingResult::U64(_) => {
            return Err(unsupported(
                path,
                format!(
                    "{bits}-bit unsigned integer samples; only 16-bit unsigned and float are read"
                ),
            ))
        }
        DecodingResult::I8(_)
        | DecodingResult::I16(_)
        | DecodingResult::I32(_)
        | DecodingResult::I64(_) => {
            return Err(unsupported(
                path,
                format!("signed {bits}-bit integer samples"),
            ))
        }
    };
    let n = w as usize * h as usize;
    let interleaved = if layout.planes > 1 {
        if raw.len() < n * channels || layout.planes != channels {
            return Err(unsupported(
                path,
                "planar samples that do not fit in memory in one piece",
            ));
        }
        let mut out = vec![0.0f32; n * channels];
        for c in 0..channels {
            for (i, v) in raw[c * n..(c + 1) * n].iter().enumerate() {
                out[i * channels + c] = *v;
            }
        }
        out
    } else {
        if raw.len() < n * channels {
            return Err(unsupported(
                path,
                format!("holds {} samples for {w}×{h}×{channels}", raw.len()),
            ));
        }
        raw
    };
    let (rgb, alpha) = if channels == 4 {
        let mut rgb = Vec::with_capacity(n * 3);
        let mut a = Vec::with_capacity(n);
        for px in interleaved.chunks_exact(4).take(n) {
            rgb.extend_from_slice(&px[..3]);
            a.push(px[3]);
        }
        (rgb, Some(a))
    } else {
        let mut rgb = interleaved;
        rgb.truncate(n * 3);
        (rgb, None)
    };
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

/// Writes a 32-bit float RGB or RGBA TIFF (deflate), atomically.
pub(super) fn write(
    rgb: &Frame,
    alpha: Option<&[f32]>,
    dest: &Path,
    overwrite: bool,
) -> Result<(), IoError> {
    check_clobber(dest, overwrite)?;
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
    let io_err = |err: std::io::Error| {
        IoError::Write(WriteError::Io {
            path: dest.to_path_buf(),
            err,
        })
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
    crate::atomic::write_with(dest, overwrite, |out| {
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
    })
}
