//! Decoding with rawler and developing the mosaic (feature `raw`).

use super::container::Declared;
use super::demosaic::Mosaic;
use super::xtrans::XTrans;
use super::{sniff, CameraInfo, Demosaic, Sniff, MAX_RAW_BYTES};
use crate::{IoError, Limits};
use nsrm::Frame;
use rayon::prelude::*;
use std::io::Read;
use std::path::Path;

/// A decoded raw file: its RGB frame and what it says about the camera.
#[derive(Debug)]
pub(crate) struct RawFrame {
    pub frame: Frame,
    pub info: CameraInfo,
}

pub(super) fn corrupt(path: &Path, why: impl Into<String>) -> IoError {
    IoError::Corrupt {
        path: path.to_path_buf(),
        why: why.into(),
    }
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".into())
}

/// Decodes the raw file `path` into linear camera RGB (see the module documentation).
pub(crate) fn read(path: &Path, limits: &Limits, demosaic: Demosaic) -> Result<RawFrame, IoError> {
    let sniffed = sniff(path)?;
    // A RAF's turned image, were the decoder to turn its mosaic (see `check_turned`).
    let turned = match &sniffed {
        Sniff::Container("RAF", d) => d.turned,
        _ => None,
    };
    let dims = match sniffed {
        Sniff::Plain => {
            return Err(IoError::Unsupported {
                path: path.to_path_buf(),
                why: "not a camera raw file".into(),
            })
        }
        Sniff::TiffBased(_, Some(why)) => return Err(corrupt(path, why)),
        Sniff::TiffBased(d, None) => d,
        Sniff::Container(_, Declared { bad: Some(why), .. }) => return Err(corrupt(path, why)),
        Sniff::Container(kind, d) => match d.largest {
            Some(dims) => Some(dims),
            None => {
                return Err(corrupt(
                    path,
                    format!(
                        "its {kind} headers declare no image size (nothing to check against \
                         the pixel limit before decoding)"
                    ),
                ))
            }
        },
    };
    if let Some((w, h)) = dims {
        limits.check_frame(path, w, h, 3, 4, None)?;
    }
    let rd = |err| IoError::Read {
        path: path.to_path_buf(),
        err,
    };
    let len = std::fs::metadata(path).map_err(rd)?.len();
    if len > MAX_RAW_BYTES {
        return Err(IoError::TooLarge {
            path: path.to_path_buf(),
            why: format!("{len} bytes, more than the {MAX_RAW_BYTES} bytes a raw file may have"),
        });
    }
    let mut bytes: Vec<u8> = crate::try_with_capacity(path, len as usize)?;
    std::fs::File::open(path)
        .and_then(|f| f.take(len).read_to_end(&mut bytes))
        .map_err(rd)?;
    // The JPEG streams' own sizes and data, before rawler allocates what they declare.
    super::ljpeg::check(&bytes, limits.max_pixels).map_err(|why| corrupt(path, why))?;
    let source = rawler::rawsource::RawSource::new_from_shared_vec(std::sync::Arc::new(bytes))
        .with_path(path);
    let decoded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let params = rawler::decoders::RawDecodeParams::default();
        let decoder = rawler::get_decoder(&source)?;
        let meta = decoder.raw_metadata(&source, &params).ok();
        if let Err(e) = check_turned(path, limits, turned, meta.as_ref()) {
            return Ok(Err(e));
        }
        let image = decoder.raw_image(&source, &params, false)?;
        Ok::<_, rawler::RawlerError>(Ok((image, meta)))
    }));
    let (image, meta) = match decoded {
        Ok(Ok(Ok(v))) => v,
        Ok(Ok(Err(e))) => return Err(e),
        Ok(Err(e)) => return Err(corrupt(path, format!("the raw decoder refused it: {e}"))),
        Err(p) => {
            return Err(corrupt(
                path,
                format!("the raw decoder failed on it ({})", panic_text(&*p)),
            ))
        }
    };
    drop(source);
    limits.check_frame(path, image.width as u64, image.height as u64, 3, 4, None)?;
    let mut info = camera_info(&image, meta.as_ref(), demosaic);
    if info.cfa.len() == 36 && demosaic == Demosaic::Mhc {
        // Malvar–He–Cutler is a Bayer method: X-Trans gets the bilinear interpolation.
        info.demosaic = Demosaic::Bilinear.name().to_string();
    }
    let developed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        develop(path, &image, demosaic)
    }));
    let frame = match developed {
        Ok(r) => r?,
        Err(p) => {
            return Err(corrupt(
                path,
                format!("its raw data could not be developed ({})", panic_text(&*p)),
            ))
        }
    };
    // As LibRaw: the frame turned to the orientation the file records.
    let frame = super::orient::orient(path, frame, info.orientation)?;
    Ok(RawFrame { frame, info })
}

/// The cameras whose RAF mosaic rawler turns by 45° (SuperCCD sensors: its camera hints
/// `fuji_rotation` and `fuji_rotation_alt`), by the make and model its metadata reports.
fn turns_mosaic(make: &str, model: &str) -> bool {
    static TURNED: std::sync::OnceLock<std::collections::HashSet<(String, String)>> =
        std::sync::OnceLock::new();
    TURNED
        .get_or_init(|| {
            rawler::decoders::RawLoader::new()
                .get_cameras()
                .values()
                .filter(|c| c.find_hint("fuji_rotation") || c.find_hint("fuji_rotation_alt"))
                .map(|c| (c.clean_make.clone(), c.clean_model.clone()))
                .collect()
        })
        .contains(&(make.to_string(), model.to_string()))
}

/// rawler turns a RAF's mosaic by the camera the file names, whatever its sensor-layout tag
/// (0x130) says: a file that names a SuperCCD camera but whose tag says otherwise (so that
/// `container::raf` declared no turned image) has the turned image of `turned` pixels a side
/// checked against the limit here, before the decoder allocates it.
fn check_turned(
    path: &Path,
    limits: &Limits,
    turned: Option<u64>,
    meta: Option<&rawler::decoders::RawMetadata>,
) -> Result<(), IoError> {
    match (turned, meta) {
        (Some(side), Some(m)) if turns_mosaic(&m.make, &m.model) => {
            limits.check_frame(path, side, side, 3, 4, None).map(drop)
        }
        _ => Ok(()),
    }
}

fn camera_info(
    image: &rawler::RawImage,
    meta: Option<&rawler::decoders::RawMetadata>,
    demosaic: Demosaic,
) -> CameraInfo {
    let pos = |v: f32| (v.is_finite() && v > 0.0).then_some(v);
    let exif = meta.map(|m| &m.exif);
    let rational = |r: &rawler::formats::tiff::Rational| {
        pos(if r.d == 0 {
            f32::NAN
        } else {
            r.n as f32 / r.d as f32
        })
    };
    let wb = image.wb_coeffs;
    let neutral = (wb[..3].iter().all(|v| v.is_finite() && *v > 0.0))
        .then(|| [wb[1] / wb[0], 1.0, wb[1] / wb[2]]);
    let cfa = match &image.photometric {
        rawler::rawimage::RawPhotometricInterpretation::Cfa(c) => c.cfa.name.clone(),
        _ => String::new(),
    };
    CameraInfo {
        make: image.clean_make.clone(),
        model: image.clean_model.clone(),
        iso: exif.and_then(|e| {
            e.iso_speed
                .map(|v| v as f32)
                .or(e.iso_speed_ratings.map(f32::from))
                .and_then(pos)
        }),
        exposure_time: exif.and_then(|e| e.exposure_time.as_ref().and_then(rational)),
        aperture: exif.and_then(|e| e.fnumber.as_ref().and_then(rational)),
        as_shot_neutral: neutral,
        orientation: image.orientation.to_u16(),
        cfa,
        demosaic: demosaic.name().to_string(),
        color_matrices: color_matrices(image),
        clip_level: clip_level(image),
    }
}

/// The level each channel of the developed frame clips at: the white level less the black
/// level, over the divisor the values are scaled by ([`levels`]), the smallest over the
/// positions of the black level's repeat (1 where every position has the same black). A CFA's
/// three colours share one set of levels; a three-channel image has its own per channel.
/// `None` when the levels leave no positive range (the file is refused as damaged anyway).
fn clip_level(image: &rawler::RawImage) -> Option<[f32; 3]> {
    let per_channel = |c: usize| {
        let raw = raw_levels(image, c);
        let min_black = raw.iter().map(|l| l.0).fold(f32::INFINITY, f32::min);
        raw.iter()
            .map(|&(b, w)| (w - b) / (w - min_black))
            .fold(f32::INFINITY, f32::min)
    };
    let clip: [f32; 3] = if image.cpp >= 3 {
        [0, 1, 2].map(per_channel)
    } else {
        [per_channel(0); 3]
    };
    clip.iter()
        .all(|v| v.is_finite() && *v > 0.0)
        .then_some(clip)
}

/// The raw file's 3×3 colour matrices with their light sources, by light source.
fn color_matrices(image: &rawler::RawImage) -> Vec<(u16, [f64; 9])> {
    let mut v: Vec<(u16, [f64; 9])> = image
        .color_matrix
        .iter()
        .filter(|(_, m)| m.len() == 9 && m.iter().all(|x| x.is_finite()))
        .map(|(ill, m)| (*ill as u16, std::array::from_fn(|i| f64::from(m[i]))))
        .collect();
    v.sort_by_key(|e| e.0);
    v
}

/// The rectangle of the raw image that is kept: the default crop (or active area), clamped to
/// the image. `(x, y, w, h)`.
fn kept_rect(image: &rawler::RawImage) -> (usize, usize, usize, usize) {
    let (iw, ih) = (image.width, image.height);
    let clamp = |r: &rawler::imgop::Rect| {
        let x = r.p.x.min(iw);
        let y = r.p.y.min(ih);
        (x, y, r.d.w.min(iw - x), r.d.h.min(ih - y))
    };
    let full = (0, 0, iw, ih);
    let active = image.active_area.as_ref().map(clamp).unwrap_or(full);
    match image.crop_area.as_ref().map(clamp) {
        Some(c) if c.2 > 0 && c.3 > 0 => c,
        _ => active,
    }
}

/// Black level and divisor per position of the black level's repeat (row-major), from
/// rawler's levels. The divisor is the white level less the smallest black level of the repeat,
/// as LibRaw scales (it subtracts the common black from its maximum and each position's excess
/// black from the samples only).
/// A black level that is not finite and non-negative, or a white level not above it, is a
/// damaged file.
fn levels(path: &Path, image: &rawler::RawImage, c: usize) -> Result<Vec<(f32, f32)>, IoError> {
    let raw = raw_levels(image, c);
    let min_black = raw.iter().map(|l| l.0).fold(f32::INFINITY, f32::min);
    raw.iter()
        .map(|&(b, w)| {
            let d = w - min_black;
            if b.is_finite() && b >= 0.0 && w.is_finite() && d > 0.0 && w > b {
                Ok((b, d))
            } else {
                Err(corrupt(
                    path,
                    format!("its black level {b} and white level {w} leave no range"),
                ))
            }
        })
        .collect()
}

/// Black and white per position of the black level's repeat (row-major).
fn raw_levels(image: &rawler::RawImage, c: usize) -> Vec<(f32, f32)> {
    let b = &image.blacklevel;
    let w = &image.whitelevel.0;
    let n = (b.width * b.height).max(1);
    (0..n)
        .map(|i| {
            let black = if b.levels.len() == n * b.cpp.max(1) {
                b.levels[i * b.cpp.max(1) + c.min(b.cpp.max(1) - 1)].as_f32()
            } else {
                b.levels.first().map_or(0.0, |r| r.as_f32())
            };
            let white = if w.len() == n {
                w[i] as f32
            } else if w.len() > c {
                w[c] as f32
            } else {
                w.first().map_or(65535.0, |&v| v as f32)
            };
            (black, white)
        })
        .collect()
}

fn develop(path: &Path, image: &rawler::RawImage, demosaic: Demosaic) -> Result<Frame, IoError> {
    use rawler::rawimage::{RawImageData, RawPhotometricInterpretation as P};
    let (iw, ih) = (image.width, image.height);
    let samples = iw
        .checked_mul(ih)
        .and_then(|p| p.checked_mul(image.cpp))
        .ok_or_else(|| corrupt(path, "its image size overflows"))?;
    let n_data = match &image.data {
        RawImageData::Integer(d) => d.len(),
        RawImageData::Float(d) => d.len(),
    };
    if n_data < samples || iw == 0 || ih == 0 {
        return Err(corrupt(
            path,
            format!(
                "the decoder gave {n_data} samples for a {iw}×{ih}×{} image",
                image.cpp
            ),
        ));
    }
    // A float raw's non-finite samples read as 0 (no value to scale).
    let sample = |i: usize| -> f32 {
        match &image.data {
            RawImageData::Integer(d) => f32::from(d[i]),
            RawImageData::Float(d) if d[i].is_finite() => d[i],
            RawImageData::Float(_) => 0.0,
        }
    };
    let (x0, y0, w, h) = kept_rect(image);
    if w == 0 || h == 0 {
        return Err(corrupt(path, "its crop leaves no pixels"));
    }
    let bayer = match &image.photometric {
        P::Cfa(c) if image.cpp == 1 => {
            let cfa = &c.cfa;
            let rgb = cfa.is_rgb() && cfa.unique_colors() == 3;
            if cfa.width == 2 && cfa.height == 2 && rgb {
                Some(cfa.clone())
            } else if cfa.width == 6 && cfa.height == 6 && rgb {
                let plane = scaled_plane(path, image, &sample, (x0, y0, w, h))?;
                let mut pattern = [0u8; 36];
                for (i, p) in pattern.iter_mut().enumerate() {
                    *p = cfa.color_at(y0 + i / 6, x0 + i % 6) as u8;
                }
                let m = XTrans {
                    plane: &plane,
                    w,
                    h,
                    pattern,
                };
                return match demosaic {
                    Demosaic::Half => m.half(path),
                    Demosaic::Bilinear | Demosaic::Mhc => m.bilinear(path),
                };
            } else {
                return rawler_develop(path, image);
            }
        }
        P::Cfa(_) => {
            return Err(corrupt(
                path,
                "a CFA image with more than one sample per pixel",
            ))
        }
        _ => None,
    };
    let Some(cfa) = bayer else {
        // Linear raw (already RGB) or monochrome: scale only.
        return scale_linear(path, image, &sample, (x0, y0, w, h));
    };
    // Bayer: scale the kept rectangle into a plane of f32, with its 2×2 colour pattern.
    let plane = scaled_plane(path, image, &sample, (x0, y0, w, h))?;
    let pattern = [
        cfa.color_at(y0, x0) as u8,
        cfa.color_at(y0, x0 + 1) as u8,
        cfa.color_at(y0 + 1, x0) as u8,
        cfa.color_at(y0 + 1, x0 + 1) as u8,
    ];
    let mosaic = Mosaic {
        plane: &plane,
        w,
        h,
        pattern,
    };
    match demosaic {
        Demosaic::Half => mosaic.half(path),
        Demosaic::Bilinear => mosaic.bilinear(path),
        Demosaic::Mhc => mosaic.mhc(path),
    }
}

/// A linear raw (already RGB, 3 samples per pixel) or monochrome (1) image's kept rectangle
/// `(x0, y0, w, h)` as an RGB frame: each sample's black subtracted (negatives clamped), divided
/// by its range; no demosaic.
fn scale_linear(
    path: &Path,
    image: &rawler::RawImage,
    sample: &(dyn Fn(usize) -> f32 + Sync),
    (x0, y0, w, h): (usize, usize, usize, usize),
) -> Result<Frame, IoError> {
    let (iw, cpp) = (image.width, image.cpp);
    if cpp != 3 && cpp != 1 {
        return Err(IoError::Unsupported {
            path: path.to_path_buf(),
            why: format!("a linear raw image with {cpp} samples per pixel"),
        });
    }
    let bl = &image.blacklevel;
    let (bw, bh) = (bl.width.max(1), bl.height.max(1));
    let lv = (0..cpp)
        .map(|c| levels(path, image, c))
        .collect::<Result<Vec<_>, _>>()?;
    let mut data = crate::try_zeroed::<f32>(path, w * h * 3)?;
    data.par_chunks_mut(w * 3).enumerate().for_each(|(r, row)| {
        let y = y0 + r;
        for (i, px) in row.chunks_exact_mut(3).enumerate() {
            let x = x0 + i;
            let li = (y % bh) * bw + (x % bw);
            for (ch, out) in px.iter_mut().enumerate() {
                let c = ch.min(cpp - 1);
                let (b, d) = lv[c].get(li).copied().unwrap_or(lv[c][0]);
                let v = sample((y * iw + x) * cpp + c);
                *out = (v - b).max(0.0) / d;
            }
        }
    });
    Ok(Frame {
        width: w,
        height: h,
        layout: nsrm::Layout::Rgb,
        data,
    })
}

/// The kept rectangle `(x0, y0, w, h)` of a one-sample CFA image as a plane of f32: each
/// position's black subtracted (negatives clamped), divided by its range.
fn scaled_plane(
    path: &Path,
    image: &rawler::RawImage,
    sample: &(dyn Fn(usize) -> f32 + Sync),
    (x0, y0, w, h): (usize, usize, usize, usize),
) -> Result<Vec<f32>, IoError> {
    let iw = image.width;
    let bl = &image.blacklevel;
    let (bw, bh) = (bl.width.max(1), bl.height.max(1));
    let lv = levels(path, image, 0)?;
    let mut plane = crate::try_zeroed::<f32>(path, w * h)?;
    plane.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        let y = y0 + r;
        let base = y * iw + x0;
        for (i, out) in row.iter_mut().enumerate() {
            let x = x0 + i;
            let (b, d) = lv[((y % bh) * bw + (x % bw)) % lv.len()];
            *out = (sample(base + i) - b).max(0.0) / d;
        }
    });
    Ok(plane)
}

/// Four-colour and other patterns: rawler's development without white balance,
/// matrix or gamma.
fn rawler_develop(path: &Path, image: &rawler::RawImage) -> Result<Frame, IoError> {
    use rawler::imgop::develop::{Intermediate, ProcessingStep as S, RawDevelop};
    let dev = RawDevelop::new_with(&[S::Rescale, S::Demosaic, S::CropActiveArea, S::CropDefault]);
    let out = dev
        .develop_intermediate(image)
        .map_err(|e| corrupt(path, format!("its raw data could not be developed: {e}")))?;
    let (w, h, data): (usize, usize, Vec<f32>) = match out {
        Intermediate::ThreeColor(p) => {
            let d = p.dim();
            (d.w, d.h, p.flatten())
        }
        Intermediate::Monochrome(p) => {
            let d = p.dim();
            (d.w, d.h, p.data.iter().flat_map(|&v| [v, v, v]).collect())
        }
        Intermediate::FourColor(_) => {
            return Err(IoError::Unsupported {
                path: path.to_path_buf(),
                why: "a four-colour sensor (CYGM / RGBE) is not read".into(),
            })
        }
    };
    Ok(Frame {
        width: w,
        height: h,
        layout: nsrm::Layout::Rgb,
        data: data.into_iter().map(|v| v.max(0.0)).collect(),
    })
}
