//! Quick-look previews: 8-bit sRGB PNGs of corrected frames (linear sRGB, clipped to `[0, 1]`,
//! sRGB OETF, [`nsrm::srgb8`]). Not for grading: highlights above the perfect white clip.

use super::IoError;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};
use nsrm::Frame;
use nsrm::{apply_mat3 as apply, Mat3};
use rayon::prelude::*;

/// 8-bit sRGB bytes (`R G B`, row-major) of `frame`, whose pixels `to_linear_srgb` takes to linear
/// sRGB with white = 1. Values are clipped; NaN becomes 0.
pub(crate) fn srgb8(frame: &Frame, to_linear_srgb: &Mat3) -> Vec<u8> {
    let ch = frame.layout.channels();
    let mut out = vec![0u8; frame.pixels() * 3];
    out.par_chunks_mut(3 * 1024)
        .zip(frame.data.par_chunks(ch * 1024))
        .for_each(|(dst, src)| {
            for (d, s) in dst.chunks_exact_mut(3).zip(src.chunks_exact(ch)) {
                let rgb = apply(to_linear_srgb, [s[0] as f64, s[1] as f64, s[2] as f64]);
                for k in 0..3 {
                    d[k] = nsrm::srgb8(rgb[k]);
                }
            }
        });
    out
}

/// The preview of `frame` as PNG file bytes (8-bit sRGB, fast compression).
pub fn encode_png(frame: &Frame, to_linear_srgb: &Mat3) -> Result<Vec<u8>, IoError> {
    let (Ok(w), Ok(h)) = (u32::try_from(frame.width), u32::try_from(frame.height)) else {
        return Err(IoError::Invalid(format!(
            "a {}×{} frame is too big for a PNG preview",
            frame.width, frame.height
        )));
    };
    let bytes = srgb8(frame, to_linear_srgb);
    let mut png = Vec::new();
    PngEncoder::new_with_quality(&mut png, CompressionType::Fast, FilterType::Adaptive)
        .write_image(&bytes, w, h, ExtendedColorType::Rgb8)
        .map_err(|e| IoError::Invalid(format!("encoding a PNG preview: {e}")))?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm::Layout;
    use nsrm::MAT3_IDENTITY;

    #[test]
    fn encodes_white_black_and_clips() {
        #[rustfmt::skip]
        let data = vec![
            1.0, 1.0, 1.0,
            0.0, 0.0, 0.0,
            2.0, -1.0, 0.5,
            0.18, 0.18, 0.18,
            f32::NAN, 0.5, 0.5,
        ];
        let f = Frame::from_data(5, 1, Layout::Rgb, data).unwrap();
        let b = srgb8(&f, &MAT3_IDENTITY);
        assert_eq!(&b[..9], &[255, 255, 255, 0, 0, 0, 255, 0, 188]);
        // 18 % grey is sRGB 118.
        assert_eq!(&b[9..12], &[118, 118, 118]);
        // A NaN spreads through the matrix to the pixel's three channels: black, not garbage.
        assert_eq!(&b[12..], &[0, 0, 0]);
    }
}
