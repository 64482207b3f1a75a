//! The file's orientation applied to a developed frame, as LibRaw applies its `flip` (by
//! default in `dcraw_emu` and in rawpy's `postprocess`): the frame is turned from the sensor's
//! orientation to the one the camera recorded (TIFF Orientation 1–8).

#[cfg(feature = "raw")]
use crate::IoError;
#[cfg(feature = "raw")]
use nsrm::Frame;
#[cfg(feature = "raw")]
use rayon::prelude::*;
#[cfg(feature = "raw")]
use std::path::Path;

/// What applying TIFF orientation `o` does to the sensor's frame, in words (the EXR header's
/// `nsrmOrientation`, ASCII as EXR text wants).
pub(crate) fn describe(o: u16) -> &'static str {
    match o {
        1 => "as stored",
        2 => "mirrored left to right",
        3 => "rotated 180 degrees",
        4 => "mirrored top to bottom",
        5 => "transposed (mirrored about the main diagonal)",
        6 => "rotated 90 degrees clockwise",
        7 => "transversed (mirrored about the anti-diagonal)",
        8 => "rotated 90 degrees counter-clockwise",
        _ => "as stored (no orientation recorded)",
    }
}

#[cfg(feature = "raw")]
/// The sensor pixel `(x, y)` that lands on pixel `(u, v)` of the oriented frame, for a sensor
/// frame of `w × h` and TIFF orientation `o` (2–8).
fn source(o: u16, w: usize, h: usize, u: usize, v: usize) -> (usize, usize) {
    match o {
        2 => (w - 1 - u, v),
        3 => (w - 1 - u, h - 1 - v),
        4 => (u, h - 1 - v),
        5 => (v, u),
        6 => (v, h - 1 - u),
        7 => (w - 1 - v, h - 1 - u),
        _ => (w - 1 - v, u),
    }
}

#[cfg(feature = "raw")]
/// `frame` (the sensor's orientation) turned to TIFF orientation `o`; orientations 5–8 swap
/// width and height. 1 and unknown values leave it as it is.
pub(crate) fn orient(path: &Path, frame: Frame, o: u16) -> Result<Frame, IoError> {
    if !(2..=8).contains(&o) {
        return Ok(frame);
    }
    let (w, h) = (frame.width, frame.height);
    let (ow, oh) = if o >= 5 { (h, w) } else { (w, h) };
    let ch = frame.layout.channels();
    let mut data = crate::try_zeroed::<f32>(path, frame.data.len())?;
    if ow > 0 {
        data.par_chunks_mut(ow * ch)
            .enumerate()
            .for_each(|(v, row)| {
                for (u, px) in row.chunks_exact_mut(ch).enumerate() {
                    let (x, y) = source(o, w, h, u, v);
                    px.copy_from_slice(&frame.data[(y * w + x) * ch..][..ch]);
                }
            });
    }
    Ok(Frame {
        width: ow,
        height: oh,
        layout: frame.layout,
        data,
    })
}

#[cfg(all(test, feature = "raw"))]
mod tests {
    use super::*;

    /// A 3×2 frame whose red channel numbers the pixels 0..6 in raster order.
    fn numbered() -> Frame {
        let data = (0..6).flat_map(|i| [i as f32, 0.0, 1.0]).collect();
        Frame::from_data(3, 2, nsrm::Layout::Rgb, data).unwrap()
    }

    fn reds(f: &Frame) -> Vec<f32> {
        f.data.chunks_exact(3).map(|p| p[0]).collect()
    }

    #[test]
    fn each_orientation_moves_the_pixels_as_tiff_says() {
        // Sensor:  0 1 2
        //          3 4 5
        let p = Path::new("x");
        let cases: [(u16, (usize, usize), [f32; 6]); 8] = [
            (1, (3, 2), [0., 1., 2., 3., 4., 5.]),
            (2, (3, 2), [2., 1., 0., 5., 4., 3.]),
            (3, (3, 2), [5., 4., 3., 2., 1., 0.]),
            (4, (3, 2), [3., 4., 5., 0., 1., 2.]),
            // 5: row 0 is the left side, column 0 the top.
            (5, (2, 3), [0., 3., 1., 4., 2., 5.]),
            // 6: row 0 is the right side, column 0 the top (turned 90° clockwise).
            (6, (2, 3), [3., 0., 4., 1., 5., 2.]),
            // 7: row 0 is the right side, column 0 the bottom.
            (7, (2, 3), [5., 2., 4., 1., 3., 0.]),
            // 8: row 0 is the left side, column 0 the bottom (turned 90° counter-clockwise).
            (8, (2, 3), [2., 5., 1., 4., 0., 3.]),
        ];
        for (o, dims, want) in cases {
            let f = orient(p, numbered(), o).unwrap();
            assert_eq!((f.width, f.height), dims, "orientation {o}");
            assert_eq!(reds(&f), want, "orientation {o}");
            assert!(f
                .data
                .chunks_exact(3)
                .all(|px| px[1] == 0.0 && px[2] == 1.0));
        }
        assert_eq!(reds(&orient(p, numbered(), 0).unwrap()), reds(&numbered()));
    }
}
