//! The two whole-frame steps of chart detection, written for speed and bit-identical to the
//! imageproc functions they replace (the tests compare them on random images):
//!
//! - [`gaussian_blur_rgb`]: imageproc's `gaussian_blur_f32` on packed RGB `f32` (the same kernel,
//!   edges clamped, each output the same sum in the same order), computed tap by tap over whole
//!   rows, so it vectorises, and rows in parallel. imageproc's generic per-pixel loop took 39 % of
//!   the detection on a 1024×768 photograph.
//! - [`region_moments`]: the moments of the 4-connected regions of a mask, numbered like
//!   imageproc's `connected_components` (in the raster order of each region's first pixel), from
//!   horizontal runs joined by a union–find and summed in closed form per run, without a label
//!   image. The sums are exact integers (pixel centres are half-integers), so their order does
//!   not matter; frames too large for exact `f64` sums take imageproc's path.

use imageproc::region_labelling::{connected_components, Connectivity};
use rayon::prelude::*;

/// imageproc's Gaussian kernel for `sigma`: radius ⌈2σ⌉, normalised to sum 1.
fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let radius = (2.0 * sigma).ceil() as usize;
    let mut k = vec![0.0f32; 2 * radius + 1];
    for i in 0..=radius {
        let x = i as f32;
        let v = ((2.0 * std::f32::consts::PI).sqrt() * sigma).recip()
            * (-x.powi(2) / (2.0 * sigma.powi(2))).exp();
        k[radius + i] = v;
        k[radius - i] = v;
    }
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= sum);
    k
}

/// `acc[e] = Σ_i k[i] · src_i[e]`, summed from 0 in tap order (imageproc's order).
fn taps<'a>(acc: &mut [f32], k: &[f32], src: impl Fn(usize) -> &'a [f32]) {
    acc.fill(0.0);
    for (i, &ki) in k.iter().enumerate() {
        let s = &src(i)[..acc.len()];
        for (a, &v) in acc.iter_mut().zip(s) {
            *a += v * ki;
        }
    }
}

/// imageproc's `gaussian_blur_f32(σ)` of a `w × h` packed RGB image (`rgb.len() == w·h·3`),
/// bit for bit.
pub(crate) fn gaussian_blur_rgb(rgb: &[f32], w: usize, h: usize, sigma: f32) -> Vec<f32> {
    assert!(sigma > 0.0 && rgb.len() == w * h * 3, "sized");
    let k = gaussian_kernel(sigma);
    let r = k.len() / 2;
    let row = w * 3;
    let mut horizontal = vec![0.0f32; rgb.len()];
    if w == 0 || h == 0 {
        return horizontal;
    }
    horizontal
        .par_chunks_mut(row)
        .zip(rgb.par_chunks(row))
        .for_each(|(out, src)| {
            // The row padded by its edge pixels (imageproc clamps the coordinates).
            let mut padded = Vec::with_capacity((w + 2 * r) * 3);
            for x in 0..w + 2 * r {
                let xc = x.saturating_sub(r).min(w - 1);
                padded.extend_from_slice(&src[xc * 3..xc * 3 + 3]);
            }
            taps(out, &k, |i| &padded[i * 3..]);
        });
    let mut out = vec![0.0f32; rgb.len()];
    out.par_chunks_mut(row).enumerate().for_each(|(y, o)| {
        taps(o, &k, |i| {
            let yc = (y + i).saturating_sub(r).min(h - 1);
            &horizontal[yc * row..]
        });
    });
    out
}

/// Pixel centres are summed as integers `2x + 1` (and products of them); these stay exact in
/// `f64` below 2⁵³, which bounds `Σ (2x + 1)²` by `4 · w · h · max(w, h)²`.
fn sums_exact(w: usize, h: usize) -> bool {
    let side = w.max(h) as u128;
    4 * (w as u128) * (h as u128) * side * side < (1u128 << 53)
}

/// A horizontal run of equal non-zero mask values: row, columns `x0..x1`, value.
struct Run {
    y: usize,
    x0: usize,
    x1: usize,
    v: u8,
}

fn root(parent: &mut [usize], mut a: usize) -> usize {
    while parent[a] != a {
        parent[a] = parent[parent[a]];
        a = parent[a];
    }
    a
}

/// The runs of one mask row.
fn row_runs(mask: &[u8], y: usize, w: usize, runs: &mut Vec<Run>) {
    let line = &mask[y * w..(y + 1) * w];
    let mut x = 0;
    while x < w {
        let v = line[x];
        let x0 = x;
        while x < w && line[x] == v {
            x += 1;
        }
        if v != 0 {
            runs.push(Run { y, x0, x1: x, v });
        }
    }
}

/// The 4-connected regions of equal non-zero values of a `w × h` mask: their moments
/// `[n, Σx, Σy, Σx², Σxy, Σy²]` over pixel centres, indexed by imageproc's
/// `connected_components` label (0, the background, unused; empty when there is no region).
pub(crate) fn region_moments(mask: &[u8], w: usize, h: usize) -> Vec<[f64; 6]> {
    assert_eq!(mask.len(), w * h, "sized");
    if !sums_exact(w, h) {
        return region_moments_labelled(mask, w, h);
    }
    let mut runs: Vec<Run> = Vec::new();
    let mut parent: Vec<usize> = Vec::new();
    let mut prev = 0..0;
    for y in 0..h {
        let start = runs.len();
        row_runs(mask, y, w, &mut runs);
        parent.extend(start..runs.len());
        // Join each run to the runs of the row above that share a column and the value.
        let mut j = prev.start;
        for c in start..runs.len() {
            while j < prev.end && runs[j].x1 <= runs[c].x0 {
                j += 1;
            }
            let mut p = j;
            while p < prev.end && runs[p].x0 < runs[c].x1 {
                if runs[p].v == runs[c].v {
                    let (a, b) = (root(&mut parent, p), root(&mut parent, c));
                    parent[a.max(b)] = a.min(b);
                }
                p += 1;
            }
        }
        prev = start..runs.len();
    }
    // Labels in the order of each region's first run (its first pixel in raster order).
    let mut label = vec![0usize; runs.len()];
    let mut sums: Vec<[u64; 6]> = vec![[0; 6]];
    for i in 0..runs.len() {
        let r = root(&mut parent, i);
        if label[r] == 0 {
            label[r] = sums.len();
            sums.push([0; 6]);
        }
        let run = &runs[i];
        let (a, b, yy) = (run.x0 as u64, run.x1 as u64, 2 * run.y as u64 + 1);
        let n = b - a;
        // Σ over x in a..b of (2x + 1) = b² − a²; of (2x + 1)² = F(b) − F(a), F(m) = m(4m² − 1)/3.
        let odd = b * b - a * a;
        let f = |m: u64| m * (4 * m * m).saturating_sub(1) / 3;
        let s = &mut sums[label[r]];
        s[0] += n;
        s[1] += odd;
        s[2] += n * yy;
        s[3] += f(b) - f(a);
        s[4] += odd * yy;
        s[5] += n * yy * yy;
    }
    if sums.len() == 1 {
        return Vec::new();
    }
    sums.iter()
        .map(|s| {
            let q = |v: u64, d: f64| v as f64 / d;
            [
                s[0] as f64,
                q(s[1], 2.0),
                q(s[2], 2.0),
                q(s[3], 4.0),
                q(s[4], 4.0),
                q(s[5], 4.0),
            ]
        })
        .collect()
}

/// The same through imageproc's `connected_components` and a raster-order sum (the frames
/// whose sums might not be exact, and the tests' judge).
fn region_moments_labelled(mask: &[u8], w: usize, h: usize) -> Vec<[f64; 6]> {
    let img = image::GrayImage::from_raw(w as u32, h as u32, mask.to_vec()).expect("sized");
    let labels = connected_components(&img, Connectivity::Four, image::Luma([0u8]));
    let mut stats: Vec<[f64; 6]> = Vec::new();
    for (x, y, l) in labels.enumerate_pixels() {
        let l = l.0[0] as usize;
        if l == 0 {
            continue;
        }
        if stats.len() <= l {
            stats.resize(l + 1, [0.0; 6]);
        }
        let (x, y) = (x as f64 + 0.5, y as f64 + 0.5);
        let s = &mut stats[l];
        s[0] += 1.0;
        s[1] += x;
        s[2] += y;
        s[3] += x * x;
        s[4] += x * y;
        s[5] += y * y;
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence (xorshift).
    fn rng(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    #[test]
    fn the_blur_is_imageprocs_bit_for_bit() {
        let mut next = rng(3);
        for (w, h, sigma) in [
            (1, 1, 1.0f32),
            (2, 3, 1.0),
            (4, 5, 1.0),
            (7, 2, 2.5),
            (37, 23, 1.0),
            (64, 48, 0.6),
        ] {
            let data: Vec<f32> = (0..w * h * 3)
                .map(|_| match next() % 9 {
                    0 => 0.0,
                    1 => -0.0,
                    2 => -((next() % 1000) as f32) / 7.0,
                    _ => (next() % 100_000) as f32 / 997.0,
                })
                .collect();
            let img: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
                image::ImageBuffer::from_raw(w as u32, h as u32, data.clone()).unwrap();
            let want = imageproc::filter::gaussian_blur_f32(&img, sigma).into_raw();
            let got = gaussian_blur_rgb(&data, w, h, sigma);
            let same = want
                .iter()
                .zip(&got)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "{w}×{h}, σ {sigma}");
        }
    }

    #[test]
    fn region_moments_match_imageprocs_labels_and_sums() {
        let mut next = rng(11);
        for (w, h, density) in [
            (1, 1, 2),
            (5, 1, 2),
            (1, 6, 2),
            (13, 9, 2),
            (40, 30, 3),
            (97, 61, 4),
            (120, 80, 8),
        ] {
            // Blobs of 255 (and some 7s, another value that must not join them).
            let mask: Vec<u8> = (0..w * h)
                .map(|_| match next() % density {
                    0 => 0,
                    1 if density > 3 => 7,
                    _ => 255,
                })
                .collect();
            let want = region_moments_labelled(&mask, w, h);
            let got = region_moments(&mask, w, h);
            assert_eq!(got.len(), want.len(), "{w}×{h}: regions");
            for (l, (a, b)) in got.iter().zip(&want).enumerate() {
                let same = a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
                assert!(same, "{w}×{h}, region {l}: {a:?} vs {b:?}");
            }
        }
        // Snakes and U shapes: regions that join late keep their first pixel's number.
        let (w, h) = (9, 5);
        let rows = [
            "1.1.1.1.1",
            "1.1.1.1.1",
            "111.111.1",
            ".........",
            "1.11111.1",
        ];
        let mask: Vec<u8> = rows
            .iter()
            .flat_map(|r| r.bytes().map(|c| if c == b'1' { 255 } else { 0 }))
            .collect();
        let got = region_moments(&mask, w, h);
        assert_eq!(got, region_moments_labelled(&mask, w, h));
        assert_eq!(got.len(), 1 + 6, "3 regions above the empty row, 3 below");
    }

    #[test]
    fn frames_too_large_for_exact_sums_take_the_labelled_path() {
        assert!(sums_exact(1600, 1600));
        assert!(!sums_exact(20_000, 20_000));
    }
}
