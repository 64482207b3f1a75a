//! Bayer demosaics on a scaled plane: half size, LibRaw's bilinear, Malvar–He–Cutler.

use super::decode::corrupt;
use crate::IoError;
use nsrm::Frame;
use rayon::prelude::*;
use std::path::Path;

/// A scaled Bayer plane and its 2×2 colour pattern (`[row0col0, row0col1, row1col0,
/// row1col1]`, colours 0 = R, 1 = G, 2 = B).
pub(super) struct Mosaic<'a> {
    pub plane: &'a [f32],
    pub w: usize,
    pub h: usize,
    pub pattern: [u8; 4],
}

impl Mosaic<'_> {
    #[inline]
    fn colour(&self, y: usize, x: usize) -> usize {
        self.pattern[(y & 1) * 2 + (x & 1)] as usize
    }

    fn frame(w: usize, h: usize, data: Vec<f32>) -> Frame {
        Frame {
            width: w,
            height: h,
            layout: nsrm::Layout::Rgb,
            data,
        }
    }

    pub(crate) fn half(&self, path: &Path) -> Result<Frame, IoError> {
        block_means(path, self.plane, self.w, self.h, 2, |y, x| {
            self.colour(y, x)
        })
    }

    /// LibRaw's border rule at (y, x): every colour but the pixel's own is the plain mean of
    /// that colour's samples in the 3×3 window (inside the image).
    fn border_pixel(&self, y: usize, x: usize, px: &mut [f32]) {
        let mut sum = [0f32; 3];
        let mut n = [0u32; 3];
        for yy in y.saturating_sub(1)..(y + 2).min(self.h) {
            for xx in x.saturating_sub(1)..(x + 2).min(self.w) {
                let c = self.colour(yy, xx);
                sum[c] += self.plane[yy * self.w + xx];
                n[c] += 1;
            }
        }
        let own = self.colour(y, x);
        for c in 0..3 {
            px[c] = if c == own {
                self.plane[y * self.w + x]
            } else if n[c] > 0 {
                sum[c] / n[c] as f32
            } else {
                0.0
            };
        }
    }

    /// LibRaw's `lin_interpolate` at an interior pixel: edge neighbours weigh 2, corners 1.
    #[inline]
    fn bilinear_pixel(&self, y: usize, x: usize, px: &mut [f32]) {
        let w = self.w;
        let mut sum = [0f32; 3];
        let mut wt = [0f32; 3];
        for dy in 0..3 {
            for dx in 0..3 {
                let (yy, xx) = (y + dy - 1, x + dx - 1);
                let c = self.colour(yy, xx);
                let k = if dy == 1 || dx == 1 { 2.0 } else { 1.0 };
                sum[c] += k * self.plane[yy * w + xx];
                wt[c] += k;
            }
        }
        let own = self.colour(y, x);
        for c in 0..3 {
            px[c] = if c == own {
                self.plane[y * w + x]
            } else {
                sum[c] / wt[c].max(1.0)
            };
        }
    }

    pub(crate) fn bilinear(&self, path: &Path) -> Result<Frame, IoError> {
        let (w, h) = (self.w, self.h);
        let mut data = crate::try_zeroed::<f32>(path, w * h * 3)?;
        data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                if y == 0 || x == 0 || y + 1 >= h || x + 1 >= w {
                    self.border_pixel(y, x, px);
                } else {
                    self.bilinear_pixel(y, x, px);
                }
            }
        });
        Ok(Self::frame(w, h, data))
    }

    /// Malvar–He–Cutler: bilinear plus a Laplacian correction from the pixel's own colour
    /// (the 5×5 filters of the paper, gains α = 1/2, β = 5/8, γ = 3/4).
    pub(crate) fn mhc(&self, path: &Path) -> Result<Frame, IoError> {
        let (w, h) = (self.w, self.h);
        let mut data = crate::try_zeroed::<f32>(path, w * h * 3)?;
        data.par_chunks_mut(w * 3).enumerate().for_each(|(y, row)| {
            if y < 2 || y + 2 >= h {
                for (x, px) in row.chunks_exact_mut(3).enumerate() {
                    if y == 0 || x == 0 || y + 1 >= h || x + 1 >= w {
                        self.border_pixel(y, x, px);
                    } else {
                        self.bilinear_pixel(y, x, px);
                    }
                }
                return;
            }
            let p = self.plane;
            let r0 = &p[(y - 2) * w..(y - 1) * w];
            let r1 = &p[(y - 1) * w..y * w];
            let r2 = &p[y * w..(y + 1) * w];
            let r3 = &p[(y + 1) * w..(y + 2) * w];
            let r4 = &p[(y + 2) * w..(y + 3) * w];
            // Whether the pixel's row holds red (for green pixels: R-row vs B-row).
            let row_has_red = self.pattern[(y & 1) * 2] == 0 || self.pattern[(y & 1) * 2 + 1] == 0;
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                if x < 2 || x + 2 >= w {
                    if x == 0 || x + 1 >= w {
                        self.border_pixel(y, x, px);
                    } else {
                        self.bilinear_pixel(y, x, px);
                    }
                    continue;
                }
                let c = r2[x];
                let own = self.colour(y, x);
                // Neighbour sums.
                let cross1 = r1[x] + r3[x] + r2[x - 1] + r2[x + 1]; // N S W E
                let cross2 = r0[x] + r4[x] + r2[x - 2] + r2[x + 2]; // distance 2 along axes
                let diag = r1[x - 1] + r1[x + 1] + r3[x - 1] + r3[x + 1];
                let horiz1 = r2[x - 1] + r2[x + 1];
                let vert1 = r1[x] + r3[x];
                let horiz2 = r2[x - 2] + r2[x + 2];
                let vert2 = r0[x] + r4[x];
                let v = match own {
                    1 => {
                        // Green pixel: the colour along its row and the one along its column.
                        let along_row =
                            (5.0 * c + 4.0 * horiz1 - diag - horiz2 + 0.5 * vert2) / 8.0;
                        let along_col = (5.0 * c + 4.0 * vert1 - diag - vert2 + 0.5 * horiz2) / 8.0;
                        if row_has_red {
                            [along_row, c, along_col]
                        } else {
                            [along_col, c, along_row]
                        }
                    }
                    _ => {
                        let g = (4.0 * c + 2.0 * cross1 - cross2) / 8.0;
                        let other = (6.0 * c + 2.0 * diag - 1.5 * cross2) / 8.0;
                        if own == 0 {
                            [c, g, other]
                        } else {
                            [other, g, c]
                        }
                    }
                };
                px[0] = v[0].max(0.0);
                px[1] = v[1].max(0.0);
                px[2] = v[2].max(0.0);
            }
        });
        Ok(Self::frame(w, h, data))
    }
}

/// One pixel of each `block`×`block` block of a CFA `plane` (`w`×`h`, the colour of each site
/// from `colour`): each colour the mean of its sites in the block (`half`, for Bayer and X-Trans).
pub(super) fn block_means(
    path: &Path,
    plane: &[f32],
    w: usize,
    h: usize,
    block: usize,
    colour: impl Fn(usize, usize) -> usize + Sync,
) -> Result<Frame, IoError> {
    let (ow, oh) = (w / block, h / block);
    if ow == 0 || oh == 0 {
        return Err(corrupt(
            path,
            format!("the image is smaller than one {block}×{block} block"),
        ));
    }
    let mut data = crate::try_zeroed::<f32>(path, ow * oh * 3)?;
    data.par_chunks_mut(ow * 3)
        .enumerate()
        .for_each(|(by, row)| {
            for (bx, px) in row.chunks_exact_mut(3).enumerate() {
                let mut sum = [0f32; 3];
                let mut n = [0u8; 3];
                for dy in 0..block {
                    for dx in 0..block {
                        let (y, x) = (by * block + dy, bx * block + dx);
                        let c = colour(y, x);
                        sum[c] += plane[y * w + x];
                        n[c] += 1;
                    }
                }
                for c in 0..3 {
                    px[c] = sum[c] / f32::from(n[c].max(1));
                }
            }
        });
    Ok(Frame {
        width: ow,
        height: oh,
        layout: nsrm::Layout::Rgb,
        data,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mosaic_of(
        w: usize,
        h: usize,
        f: impl Fn(usize, usize, usize) -> f32,
    ) -> (Vec<f32>, [u8; 4]) {
        let pattern = [0u8, 1, 1, 2]; // RGGB
        let mut p = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                p[y * w + x] = f(y, x, pattern[(y & 1) * 2 + (x & 1)] as usize);
            }
        }
        (p, pattern)
    }

    #[test]
    fn flat_colour_stays_flat_in_every_demosaic() {
        let rgb = [0.25f32, 0.5, 0.125];
        let (plane, pattern) = mosaic_of(12, 10, |_, _, c| rgb[c]);
        let m = Mosaic {
            plane: &plane,
            w: 12,
            h: 10,
            pattern,
        };
        let p = Path::new("t");
        for f in [m.half(p), m.bilinear(p), m.mhc(p)] {
            let f = f.unwrap();
            for px in f.data.chunks_exact(3) {
                for c in 0..3 {
                    assert!((px[c] - rgb[c]).abs() < 1e-6, "{px:?}");
                }
            }
        }
    }

    #[test]
    fn mhc_is_exact_on_linear_ramps() {
        // A linear ramp in each channel is reproduced exactly by both interpolations.
        let (plane, pattern) = mosaic_of(16, 16, |y, x, c| {
            0.01 * (c as f32 + 1.0) * (x as f32 + 2.0 * y as f32)
        });
        let m = Mosaic {
            plane: &plane,
            w: 16,
            h: 16,
            pattern,
        };
        let p = Path::new("t");
        let f = m.mhc(p).unwrap();
        for y in 2..14 {
            for x in 2..14 {
                for c in 0..3 {
                    let want = 0.01 * (c as f32 + 1.0) * (x as f32 + 2.0 * y as f32);
                    let got = f.data[(y * 16 + x) * 3 + c];
                    assert!((got - want).abs() < 1e-4, "({y},{x},{c}) {got} vs {want}");
                }
            }
        }
    }
}
