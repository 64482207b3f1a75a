//! Fujifilm X-Trans (6×6 CFA) demosaics on a scaled plane: `half` and LibRaw's linear
//! interpolation.
//!
//! * `half` makes one pixel of each 3×3 block (a third of the width and height, no
//!   interpolation): each colour is the mean of that colour's sites in the block. Every 3×3
//!   block of an X-Trans pattern holds all three colours (5 green, 2 red, 2 blue when the block
//!   is aligned with the pattern), so this is the X-Trans counterpart of the Bayer 2×2 block:
//!   what chart readers want (a patch's mean, no interpolation), as profiling tools average a
//!   patch's sites of each colour.
//! * `bilinear` is LibRaw's `lin_interpolate` as it runs on X-Trans (`filters == 9`): every
//!   colour but the pixel's own is the weighted mean of that colour's samples in the 3×3 window
//!   (edge neighbours weigh 2, corners 1); on the one-pixel border, the plain mean, from the
//!   5×5 window where the 3×3 one inside the image lacks a colour (LibRaw leaves 0 there). Two
//!   deliberate differences: LibRaw divides by the weight sum S as `* (256 / S) >> 8` in
//!   integers, up to 0.4 % low for the sums X-Trans has (3, 5, 6); this divides exactly, so a
//!   flat field stays flat.
//! * Malvar–He–Cutler is a Bayer method: an X-Trans frame asked for `mhc` gets `bilinear`.

use crate::IoError;
use nsrm::Frame;
use rayon::prelude::*;
use std::path::Path;

/// A scaled X-Trans plane and its 6×6 colour pattern (row-major from the plane's first pixel;
/// colours 0 = R, 1 = G, 2 = B).
pub(super) struct XTrans<'a> {
    pub plane: &'a [f32],
    pub w: usize,
    pub h: usize,
    pub pattern: [u8; 36],
}

impl XTrans<'_> {
    #[inline]
    fn colour(&self, y: usize, x: usize) -> usize {
        self.pattern[(y % 6) * 6 + x % 6] as usize
    }

    fn frame(w: usize, h: usize, data: Vec<f32>) -> Frame {
        Frame {
            width: w,
            height: h,
            layout: nsrm::Layout::Rgb,
            data,
        }
    }

    /// Whether every 3×3 window of the pattern holds all three colours (true of Fujifilm's
    /// X-Trans layouts; a file claiming another 6×6 layout is refused).
    fn complete(&self, path: &Path) -> Result<(), IoError> {
        for y in 0..6 {
            for x in 0..6 {
                let mut seen = [false; 3];
                for dy in 0..3 {
                    for dx in 0..3 {
                        seen[self.pattern[((y + dy) % 6) * 6 + (x + dx) % 6] as usize % 3] = true;
                    }
                }
                if seen.contains(&false) || self.pattern.iter().any(|&c| c > 2) {
                    return Err(IoError::Unsupported {
                        path: path.to_path_buf(),
                        why: "a 6×6 CFA pattern with a 3×3 window lacking a colour".into(),
                    });
                }
            }
        }
        Ok(())
    }

    pub(crate) fn half(&self, path: &Path) -> Result<Frame, IoError> {
        self.complete(path)?;
        super::demosaic::block_means(path, self.plane, self.w, self.h, 3, |y, x| {
            self.colour(y, x)
        })
    }

    /// At (y, x): the pixel's own sample, and each other colour's mean over the 3×3 window
    /// (inside the image), weighted (edge 2, corner 1) in the interior, plain on the border.
    #[inline]
    fn pixel(&self, y: usize, x: usize, px: &mut [f32]) {
        let border = y == 0 || x == 0 || y + 1 >= self.h || x + 1 >= self.w;
        let mut sum = [0f32; 3];
        let mut wt = [0f32; 3];
        for yy in y.saturating_sub(1)..(y + 2).min(self.h) {
            for xx in x.saturating_sub(1)..(x + 2).min(self.w) {
                let c = self.colour(yy, xx);
                let k = if !border && (yy == y || xx == x) {
                    2.0
                } else {
                    1.0
                };
                sum[c] += k * self.plane[yy * self.w + xx];
                wt[c] += k;
            }
        }
        let own = self.colour(y, x);
        if border && wt.contains(&0.0) {
            // A corner's 2×2 may be all green: the 5×5 window (inside the image) then.
            for yy in y.saturating_sub(2)..(y + 3).min(self.h) {
                for xx in x.saturating_sub(2)..(x + 3).min(self.w) {
                    let c = self.colour(yy, xx);
                    if c != own && wt[c] == 0.0 {
                        sum[c] += self.plane[yy * self.w + xx];
                        wt[c] += 1.0;
                    }
                }
            }
        }
        for c in 0..3 {
            px[c] = if c == own {
                self.plane[y * self.w + x]
            } else if wt[c] > 0.0 {
                sum[c] / wt[c]
            } else {
                0.0
            };
        }
    }

    pub(crate) fn bilinear(&self, path: &Path) -> Result<Frame, IoError> {
        self.complete(path)?;
        let (w, h) = (self.w, self.h);
        let mut data = crate::try_zeroed::<f32>(path, w * h * 3)?;
        data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                self.pixel(y, x, px);
            }
        });
        Ok(Self::frame(w, h, data))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fujifilm's X-Trans layout (X-Pro1 … X-T5), as LibRaw and rawler list it.
    pub(crate) const XTRANS: &str = "GGRGGBGGBGGRBRGRBGGGBGGRGGRGGBRBGBRG";

    fn pattern() -> [u8; 36] {
        let mut p = [0u8; 36];
        for (i, c) in XTRANS.bytes().enumerate() {
            p[i] = match c {
                b'R' => 0,
                b'G' => 1,
                _ => 2,
            };
        }
        p
    }

    #[test]
    fn flat_colour_stays_flat() {
        let rgb = [0.25f32, 0.5, 0.125];
        let pattern = pattern();
        let (w, h) = (20, 14);
        let plane: Vec<f32> = (0..w * h)
            .map(|i| rgb[pattern[(i / w % 6) * 6 + i % w % 6] as usize])
            .collect();
        let m = XTrans {
            plane: &plane,
            w,
            h,
            pattern,
        };
        let p = Path::new("t");
        let half = m.half(p).unwrap();
        assert_eq!((half.width, half.height), (6, 4));
        for f in [half, m.bilinear(p).unwrap()] {
            for px in f.data.chunks_exact(3) {
                for c in 0..3 {
                    assert!((px[c] - rgb[c]).abs() < 1e-6, "{px:?}");
                }
            }
        }
    }

    #[test]
    fn a_pattern_missing_a_colour_is_refused() {
        let mut pattern = pattern();
        for c in pattern.iter_mut() {
            if *c == 2 {
                *c = 0;
            }
        }
        let plane = vec![0.5f32; 36];
        let m = XTrans {
            plane: &plane,
            w: 6,
            h: 6,
            pattern,
        };
        assert!(m.half(Path::new("t")).is_err());
        assert!(m.bilinear(Path::new("t")).is_err());
    }
}
