//! Display-referred frames for chart reading: camera JPEGs, PNGs and 8/16-bit integer TIFFs,
//! decoded to linear values with the sRGB transfer function (IEC 61966-2-1) — or kept as they
//! are when the caller says the file holds linear values.
//!
//! What a display-referred frame can and cannot give: the sRGB decode undoes the standard
//! encoding, not the camera's own tone curve and saturation, so the values are only roughly
//! proportional to light. Chart detection copes with that (its colour check linearises the
//! neutral patches first); a model fitted from such values is marked so in its provenance.
//!
//! Orientation: pixels are taken as stored; an EXIF orientation tag is not applied (chart
//! detection finds the chart in any rotation, and positions refer to the stored pixels).

use super::{IoError, Limits, ReadOptions};
use nsrm::{Frame, Layout};
use std::path::Path;

/// How the pixel values of a frame are encoded (what `--encoding` names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoding {
    /// By the file: sRGB for JPEG, PNG and 8-bit integer TIFF; linear for EXR, 16-bit and
    /// float TIFF (what raw converters write) and camera raw.
    #[default]
    Auto,
    /// The values are linear: used as they are (integers scaled to 0..1).
    Linear,
    /// The values are sRGB-encoded: decoded with the sRGB transfer function.
    Srgb,
}

impl Encoding {
    /// `auto`, `linear` or `srgb` (case-insensitive).
    #[cfg(test)]
    pub(crate) fn parse(s: &str) -> Option<Encoding> {
        match s.trim().to_ascii_lowercase().as_str() {
            "auto" => Some(Encoding::Auto),
            "linear" => Some(Encoding::Linear),
            "srgb" => Some(Encoding::Srgb),
            _ => None,
        }
    }
}

/// What a read frame's values are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transfer {
    /// Linear as stored (scene-referred camera data).
    Linear,
    /// Display-referred values decoded with the sRGB transfer function.
    SrgbDecoded,
    /// Display-referred integer values taken as linear because the caller said so.
    DisplayAsLinear,
}

impl Transfer {
    /// True when the values went through a display encoding (a camera tone curve may remain).
    pub fn display_referred(self) -> bool {
        self == Transfer::SrgbDecoded
    }

    /// Words for messages and provenance.
    pub fn describe(self) -> &'static str {
        match self {
            Transfer::Linear => "linear",
            Transfer::SrgbDecoded => {
                "display-referred (sRGB decoded; camera tone curve not undone)"
            }
            Transfer::DisplayAsLinear => "integer values of a JPEG/PNG/8-bit TIFF taken as linear",
        }
    }
}

/// A frame for chart reading and how its values were decoded.
#[derive(Debug, Clone)]
pub struct ChartFrame {
    /// The decoded pixels (linear when `transfer` says they were decoded).
    pub frame: Frame,
    /// How its values were decoded.
    pub transfer: Transfer,
    /// The largest integer code of a display file decoded here (255, 65535); `None` for frames
    /// read by the linear readers.
    pub max_code: Option<f64>,
    /// Make, model and exposure of a camera raw frame; `None` for other files.
    pub camera: Option<super::raw::CameraInfo>,
}

/// The sRGB electro-optical transfer function: an encoded value in `[0, 1]` to linear.
pub fn srgb_eotf(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

enum Kind {
    Jpeg,
    Png,
    Tiff8,
    Other,
}

fn sniff(path: &Path) -> Result<Kind, IoError> {
    use std::io::Read;
    let read_err = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    nsrm::limits::check_regular(path).map_err(read_err)?;
    let mut f = std::fs::File::open(path).map_err(read_err)?;
    let mut magic = [0u8; 8];
    let mut n = 0;
    while n < magic.len() {
        match f.read(&mut magic[n..]).map_err(read_err)? {
            0 => break,
            k => n += k,
        }
    }
    Ok(match &magic[..n] {
        [0xff, 0xd8, 0xff, ..] => Kind::Jpeg,
        [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a] => Kind::Png,
        [b'I', b'I', 42, 0, ..] | [b'M', b'M', 0, 42, ..] => {
            if tiff_is_8bit(path) {
                Kind::Tiff8
            } else {
                Kind::Other
            }
        }
        _ => Kind::Other,
    })
}

/// True for a TIFF of 8-bit integer RGB(A) samples (the linear reader refuses those).
fn tiff_is_8bit(path: &Path) -> bool {
    let Ok(file) = std::fs::File::open(path) else {
        return false;
    };
    let Ok(mut dec) = tiff::decoder::Decoder::new(std::io::BufReader::new(file)) else {
        return false;
    };
    matches!(
        dec.colortype(),
        Ok(tiff::ColorType::RGB(8)) | Ok(tiff::ColorType::RGBA(8))
    )
}

/// Reads a frame for chart reading: JPEG, PNG and 8-bit TIFF through `image` (display
/// encodings), anything else through [`super::read_frame`] (EXR, 16-bit / float TIFF, and
/// whatever else that dispatch reads), then decodes per `encoding`.
pub fn read_chart_frame(
    path: &Path,
    opts: &ReadOptions,
    encoding: Encoding,
) -> Result<ChartFrame, IoError> {
    let mut camera = None;
    // A display-encoded file is decoded as it is read (through a table of its codes).
    let srgb = matches!(encoding, Encoding::Srgb | Encoding::Auto);
    let (frame, integer_display, format) = match sniff(path)? {
        Kind::Jpeg => {
            check_jpeg(path, &opts.limits)?;
            (read_image(path, &opts.limits, srgb)?, true, "JPEG")
        }
        Kind::Png => (read_image(path, &opts.limits, srgb)?, true, "PNG"),
        Kind::Tiff8 => (read_image(path, &opts.limits, srgb)?, true, "TIFF (8-bit)"),
        Kind::Other => {
            let (f, c) = super::read_frame_and_camera(path, opts)?;
            camera = c;
            ((f, None), false, "frame")
        }
    };
    let (mut frame, max_code) = frame;
    if integer_display && opts.layer.is_some() {
        return Err(IoError::Channels {
            path: path.to_path_buf(),
            why: format!("a {format} file has no layers"),
            concern: Some(nsrm::Concern::Value(nsrm::Param::Layer)),
        });
    }
    let transfer = match (encoding, integer_display) {
        // Decoded by `read_image`.
        (Encoding::Srgb | Encoding::Auto, true) => Transfer::SrgbDecoded,
        (Encoding::Srgb, false) => {
            decode_srgb(&mut frame);
            Transfer::SrgbDecoded
        }
        (Encoding::Linear, true) => Transfer::DisplayAsLinear,
        (Encoding::Linear | Encoding::Auto, false) => Transfer::Linear,
    };
    Ok(ChartFrame {
        frame,
        transfer,
        max_code,
        camera,
    })
}

/// The JPEG's structure before it is decoded ([`super::jpeg::check`]): its end marker, and
/// data enough for the size its header declares. A file larger than 8 bytes a pixel at the
/// pixel limit (JPEGs hold 1–3) is refused unread.
fn check_jpeg(path: &Path, limits: &Limits) -> Result<(), IoError> {
    use std::io::Read;
    let rd = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    let f = std::fs::File::open(path).map_err(rd)?;
    let len = f.metadata().map_err(rd)?.len();
    let cap = limits.max_pixels.saturating_mul(8).saturating_add(64 << 20);
    if len > cap {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            why: format!("a JPEG of {len} bytes, more than {cap} at the pixel limit"),
        });
    }
    let mut bytes = super::try_with_capacity(path, len as usize)?;
    f.take(len).read_to_end(&mut bytes).map_err(rd)?;
    super::jpeg::check(&bytes).map_err(|why| IoError::Corrupt {
        path: path.to_path_buf(),
        why,
    })
}

/// The sRGB decode of one value (clamped to `[0, 1]` first; not finite: 0).
fn decode_one(v: f32) -> f32 {
    let x = if v.is_finite() {
        f64::from(v).clamp(0.0, 1.0)
    } else {
        0.0
    };
    srgb_eotf(x) as f32
}

/// Applies the sRGB decode to the colour channels (values clamped to `[0, 1]` first; alpha is
/// left alone): a linear-reader frame that `--encoding srgb` says is encoded.
fn decode_srgb(frame: &mut Frame) {
    let ch = frame.layout.channels();
    for px in frame.data.chunks_exact_mut(ch) {
        for v in &mut px[..3] {
            *v = decode_one(*v);
        }
    }
}

/// Decodes an 8/16-bit image with the `image` crate into RGB values scaled to `[0, 1]`, and
/// sRGB-decoded when `srgb` ([`code_table`]). Dimensions are checked against `limits` from the header,
/// before the pixels are decoded; the decoder's own allocation is bounded too.
fn read_image(path: &Path, limits: &Limits, srgb: bool) -> Result<(Frame, Option<f64>), IoError> {
    let open = || -> Result<image::ImageReader<std::io::BufReader<std::fs::File>>, IoError> {
        image::ImageReader::open(path)
            .map_err(|err| IoError::Read {
                path: path.to_path_buf(),
                err,
            })?
            .with_guessed_format()
            .map_err(|err| IoError::Read {
                path: path.to_path_buf(),
                err,
            })
    };
    let (w, h) = open()?.into_dimensions().map_err(|e| image_err(path, e))?;
    let n = limits.check_frame(path, w.into(), h.into(), 3, 4, None)?;
    let mut reader = open()?;
    let mut il = image::Limits::default();
    // Room for the decoded image at 16 bits per sample with alpha, plus the decoder's own rows.
    il.max_alloc = Some((n as u64).saturating_mul(16).saturating_add(64 << 20));
    reader.limits(il);
    let img = reader.decode().map_err(|e| image_err(path, e))?;
    let mut data: Vec<f32> = super::try_with_capacity(path, n.saturating_mul(3))?;
    let eight = matches!(
        img,
        image::DynamicImage::ImageRgb8(_)
            | image::DynamicImage::ImageRgba8(_)
            | image::DynamicImage::ImageLuma8(_)
            | image::DynamicImage::ImageLumaA8(_)
    );
    match img {
        image::DynamicImage::ImageRgb8(_)
        | image::DynamicImage::ImageRgba8(_)
        | image::DynamicImage::ImageLuma8(_)
        | image::DynamicImage::ImageLumaA8(_) => {
            let lut = code_table(255, srgb);
            data.extend(
                img.to_rgb8()
                    .into_raw()
                    .into_iter()
                    .map(|v| lut[v as usize]),
            );
        }
        _ => {
            let lut = code_table(65535, srgb);
            data.extend(
                img.to_rgb16()
                    .into_raw()
                    .into_iter()
                    .map(|v| lut[v as usize]),
            );
        }
    }
    let frame = Frame::from_data(w as usize, h as usize, Layout::Rgb, data).ok_or_else(|| {
        IoError::Corrupt {
            path: path.to_path_buf(),
            why: "the decoded image does not hold its pixels".into(),
        }
    })?;
    Ok((frame, Some(if eight { 255.0 } else { 65535.0 })))
}

/// The value of each integer code `0..=max`: `code / max`, sRGB-decoded when `srgb` (the same
/// bits as [`decode_srgb`] of the scaled value; one `pow` per code instead of per sample, which
/// was most of a JPEG chart reading's time).
fn code_table(max: u32, srgb: bool) -> Vec<f32> {
    let m = max as f32;
    (0..=max)
        .map(|c| {
            let v = c as f32 / m;
            if srgb {
                decode_one(v)
            } else {
                v
            }
        })
        .collect()
}

fn image_err(path: &Path, e: image::ImageError) -> IoError {
    match e {
        image::ImageError::Limits(l) => IoError::OverLimit {
            path: path.to_path_buf(),
            why: format!("decoding needs more memory than allowed ({l})"),
        },
        image::ImageError::IoError(err) => IoError::Read {
            path: path.to_path_buf(),
            err,
        },
        image::ImageError::Unsupported(u) => IoError::Unsupported {
            path: path.to_path_buf(),
            why: u.to_string(),
        },
        other => IoError::Corrupt {
            path: path.to_path_buf(),
            why: other.to_string(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_code_tables_give_the_formulas_bits() {
        for m in [255u32, 65535] {
            let (plain, srgb) = (code_table(m, false), code_table(m, true));
            for c in 0..=m {
                let v = c as f32 / m as f32;
                assert_eq!(plain[c as usize].to_bits(), v.to_bits());
                assert_eq!(srgb[c as usize].to_bits(), decode_one(v).to_bits());
            }
        }
    }

    #[test]
    fn srgb_round_trip() {
        for i in 0..=100 {
            let v = i as f64 / 100.0;
            let back = srgb_eotf(nsrm::srgb_oetf(v));
            assert!((back - v).abs() < 1e-12, "{v} → {back}");
        }
        assert_eq!(Encoding::parse("SRGB"), Some(Encoding::Srgb));
        assert_eq!(Encoding::parse("gamma"), None);
    }

    #[test]
    fn png_and_jpeg_are_decoded_and_bounded() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = image::RgbImage::new(40, 30);
        for (x, _, p) in img.enumerate_pixels_mut() {
            *p = image::Rgb([(x * 6) as u8, 128, 255]);
        }
        let png = dir.path().join("a.png");
        img.save(&png).unwrap();
        let f = read_chart_frame(&png, &ReadOptions::default(), Encoding::Auto).unwrap();
        assert_eq!(f.transfer, Transfer::SrgbDecoded);
        assert_eq!((f.frame.width, f.frame.height), (40, 30));
        let mid = f.frame.data[1] as f64;
        assert!((mid - srgb_eotf(128.0 / 255.0)).abs() < 1e-6, "{mid}");
        assert!((f.frame.data[2] - 1.0).abs() < 1e-6);
        let lin = read_chart_frame(&png, &ReadOptions::default(), Encoding::Linear).unwrap();
        assert_eq!(lin.transfer, Transfer::DisplayAsLinear);
        assert!((lin.frame.data[1] - 128.0 / 255.0).abs() < 1e-6);
        let small = ReadOptions {
            limits: Limits { max_pixels: 100 },
            ..Default::default()
        };
        assert!(matches!(
            read_chart_frame(&png, &small, Encoding::Auto),
            Err(IoError::OverLimit { .. })
        ));
        // A truncated PNG is an error, not a panic.
        let bytes = std::fs::read(&png).unwrap();
        let cut = dir.path().join("cut.png");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        assert!(read_chart_frame(&cut, &ReadOptions::default(), Encoding::Auto).is_err());
    }
}
