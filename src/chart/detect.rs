//! Finding a chart in a linear frame without `--corners`.
//!
//! 1. The frame is box-downsampled so its long side is at most [`DetectOptions::max_side`]
//!    pixels, smoothed (imageproc's Gaussian filter, σ = 1) and turned into log-luminance and
//!    chromaticity — so the exposure does not matter and dark patches count as much as bright ones.
//! 2. *Flat* pixels (log-luminance and chromaticity gradients below a threshold) are labelled into
//!    connected regions (imageproc's `connected_components`); regions of patch-like size and
//!    shape (second moments of a filled convex quadrilateral, not elongated) are candidate patches.
//! 3. Candidates are linked into a lattice: from a seed, each neighbour is looked for one step
//!    (or two, over a missed dark patch) along the two local lattice directions, which are updated
//!    as the walk goes, so perspective is followed. The largest lattice wins; a homography from
//!    lattice coordinates to the frame is fitted to its centroids (least squares) and refined.
//! 4. Every placement of the chart on the lattice — 4 rotations × mirror × the offsets the lattice
//!    allows — is scored by how well its patch colours match the reference (median ΔE00 after the
//!    best 3×3 linear map, or after linearising each channel through the chart's own grey ramp
//!    and then the best 3×3 map — a camera's tone curve — whichever is better,
//!    [`super::extract::chart_score`]). The best must be plausible (below
//!    [`DETECT_MATCH_LIMIT`], or [`MATCH_LIMIT`] when every cell of the chart was seen as a patch
//!    and the next placement is [`COMPLETE_AMBIGUITY_RATIO`] worse), clearly better than the next
//!    (ratio [`AMBIGUITY_RATIO`]) and seen under moderate perspective ([`PERSPECTIVE_LIMIT`]);
//!    otherwise detection fails with a message and the candidates, never a guess.

use super::extract::{cell_means, chart_score, MATCH_LIMIT};
use super::reference::Reference;
use super::{ChartError, Homography};
use crate::frame::Frame;
use imageproc::region_labelling::{connected_components, Connectivity};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The best placement must score at most this fraction of the second best.
pub const AMBIGUITY_RATIO: f64 = 0.7;

/// A found chart must match its reference at least this well (median ΔE00 after the best 3×3
/// map; stricter than [`MATCH_LIMIT`], which applies to `--corners`): correct detections of
/// synthetic scenes score at most 2.5, a placement shifted by some cells on a partial lattice
/// was seen at 7.6.
pub const DETECT_MATCH_LIMIT: f64 = 5.0;

/// With a complete lattice (every cell of the placement seen as a patch), a found chart may
/// match up to [`MATCH_LIMIT`] when the next placement scores at least 1 / this times worse
/// (stricter than [`AMBIGUITY_RATIO`]; the correct placements of the development photographs
/// score 4× to 12× better than the next).
pub const COMPLETE_AMBIGUITY_RATIO: f64 = 0.5;

/// Perspective strength above which a found chart is refused: the ratio of the largest to the
/// smallest patch scale (square root of the local area) over the chart's cells. Beyond it the
/// lattice's centroids are biased enough that cells extrapolated past the lattice can land a
/// quarter pitch off (seen at 1.69, a 54° tilt). Scenes inside the envelope (tilt ≤ 30°) reach
/// 1.51 (100 CC24 and 60 SG scenes).
pub const PERSPECTIVE_LIMIT: f64 = 1.6;

/// [`PERSPECTIVE_LIMIT`]'s measure: largest over smallest local patch scale, over the cells
/// that `h` (chart → image) places.
pub fn perspective(kind: super::ChartKind, h: &Homography) -> f64 {
    let scale = |c: [f64; 2]| {
        let p = h.apply(c);
        let a = h.apply([c[0] + 1.0, c[1]]);
        let b = h.apply([c[0], c[1] + 1.0]);
        let det = (a[0] - p[0]) * (b[1] - p[1]) - (a[1] - p[1]) * (b[0] - p[0]);
        det.abs().sqrt()
    };
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for i in 0..kind.cells() {
        let s = scale(kind.cell_centre(i));
        lo = lo.min(s);
        hi = hi.max(s);
    }
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

/// How detection works.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectOptions {
    /// Long side of the downsampled image searched.
    pub max_side: usize,
    /// Largest gradient (log units per pixel) of a flat pixel.
    pub flat_threshold: f32,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            max_side: 1600,
            flat_threshold: 0.08,
        }
    }
}

/// A candidate patch region (frame pixels).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    pub centre: [f64; 2],
    /// Radius of a circle of the region's area.
    pub radius: f64,
    /// Part of the chart lattice that was kept.
    pub accepted: bool,
}

/// A found chart.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Chart coordinates → frame pixels.
    pub homography: Homography,
    /// Median ΔE00 of the best placement and of the next best.
    pub score: f64,
    pub runner_up: f64,
    /// Patches linked into the lattice.
    pub lattice: usize,
    /// Perspective strength ([`perspective`]).
    pub perspective: f64,
    /// Mirrored (the frame shows the chart's mirror image) — unusual; reported for the user.
    pub mirrored: bool,
    pub downsample: usize,
    pub candidates: Vec<Candidate>,
}

/// Why no chart was found, and what was looked at.
#[derive(Debug)]
pub struct DetectFailure {
    pub error: ChartError,
    pub candidates: Vec<Candidate>,
}

struct Blob {
    c: [f64; 2],
    area: f64,
}

/// Box-downsamples by an integer factor (RGB, any layout).
fn downsample(frame: &Frame, f: usize) -> (usize, usize, Vec<f32>) {
    let (ws, hs) = (frame.width / f, frame.height / f);
    let ch = frame.layout.channels();
    let mut out = vec![0.0f32; ws * hs * 3];
    let norm = 1.0 / (f * f) as f32;
    out.par_chunks_mut(ws * 3)
        .enumerate()
        .for_each(|(ys, row)| {
            for yy in ys * f..(ys + 1) * f {
                let src = &frame.data[yy * frame.width * ch..][..ws * f * ch];
                for (xs, px) in row.chunks_exact_mut(3).enumerate() {
                    for p in src[xs * f * ch..(xs + 1) * f * ch].chunks_exact(ch) {
                        for k in 0..3 {
                            let v = p[k];
                            px[k] += if v.is_finite() { v } else { 0.0 };
                        }
                    }
                }
            }
            for v in row.iter_mut() {
                *v *= norm;
            }
        });
    (ws, hs, out)
}

/// Finds the chart of `reference` in `frame`.
pub fn detect(
    frame: &Frame,
    reference: &Reference,
    opts: &DetectOptions,
) -> Result<Detection, DetectFailure> {
    let kind = reference.chart;
    let fail = |msg: String, candidates: Vec<Candidate>| DetectFailure {
        error: ChartError::NotFound(msg),
        candidates,
    };
    let long = frame.width.max(frame.height);
    let f = long.div_ceil(opts.max_side.max(64)).max(1);
    let (ws, hs, small) = downsample(frame, f);
    if ws < 32 || hs < 32 {
        return Err(fail(
            format!("the frame ({}×{}) is too small", frame.width, frame.height),
            vec![],
        ));
    }
    let img: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
        image::ImageBuffer::from_raw(ws as u32, hs as u32, small.clone()).expect("sized");
    let smooth = imageproc::filter::gaussian_blur_f32(&img, 1.0).into_raw();
    // Log-luminance and chromaticity.
    let ymax = smooth
        .chunks_exact(3)
        .map(|p| p[0] + 2.0 * p[1] + p[2])
        .fold(0.0f32, f32::max);
    if !(ymax > 0.0) {
        return Err(fail("the frame is black".into(), vec![]));
    }
    let floor = ymax * 1e-5;
    let mut logl = vec![0.0f32; ws * hs];
    let mut cr = vec![0.0f32; ws * hs];
    let mut cb = vec![0.0f32; ws * hs];
    for (i, p) in smooth.chunks_exact(3).enumerate() {
        let (r, g, b) = (p[0].max(0.0), p[1].max(0.0), p[2].max(0.0));
        let s = r + g + b + floor;
        logl[i] = (r + 2.0 * g + b).max(floor).ln();
        cr[i] = r / s;
        cb[i] = b / s;
    }
    let t = opts.flat_threshold;
    let mut mask = image::GrayImage::new(ws as u32, hs as u32);
    for y in 1..hs - 1 {
        for x in 1..ws - 1 {
            let i = y * ws + x;
            let d = |a: &[f32]| {
                let gx = (a[i + 1] - a[i - 1]) * 0.5;
                let gy = (a[i + ws] - a[i - ws]) * 0.5;
                gx.abs().max(gy.abs())
            };
            let e = d(&logl).max(4.0 * d(&cr)).max(4.0 * d(&cb));
            if e < t {
                mask.put_pixel(x as u32, y as u32, image::Luma([255]));
            }
        }
    }
    let labels = connected_components(&mask, Connectivity::Four, image::Luma([0u8]));
    // Moments per region.
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
    let frame_area = (ws * hs) as f64;
    let min_area = 10.0f64.max(frame_area * 0.05 / kind.cells() as f64 * 0.08);
    // A patch is at most a cell of a chart whose patch grid fills the whole frame (a chart
    // cropped tight, no surround): frame area / cells.
    let max_area = frame_area / kind.cells() as f64;
    let mut blobs = Vec::new();
    let mut all = Vec::new();
    for s in stats.iter().skip(1) {
        let n = s[0];
        if n < 4.0 {
            continue;
        }
        let (mx, my) = (s[1] / n, s[2] / n);
        let (sxx, sxy, syy) = (s[3] / n - mx * mx, s[4] / n - mx * my, s[5] / n - my * my);
        let det = sxx * syy - sxy * sxy;
        let tr = sxx + syy;
        let disc = (tr * tr / 4.0 - det).max(0.0).sqrt();
        let (l1, l2) = (tr / 2.0 + disc, tr / 2.0 - disc);
        let fill = if det > 0.0 {
            n / (12.0 * det.sqrt())
        } else {
            0.0
        };
        let ok = n >= min_area
            && n <= max_area
            && (0.8..=1.12).contains(&fill)
            && l2 > 0.0
            && l1 / l2 <= 4.0;
        if n >= min_area {
            all.push((blobs.len(), ok, [mx, my], n));
        }
        if ok {
            blobs.push(Blob {
                c: [mx, my],
                area: n,
            });
        }
    }
    let to_candidates = |accepted: &[bool]| -> Vec<Candidate> {
        all.iter()
            .map(|(bi, ok, c, n)| Candidate {
                centre: [c[0] * f as f64, c[1] * f as f64],
                radius: (n / std::f64::consts::PI).sqrt() * f as f64,
                accepted: *ok && accepted.get(*bi).copied().unwrap_or(false),
            })
            .collect()
    };
    if blobs.len() < 6 {
        return Err(fail(
            format!(
                "{} patch-like regions in the frame, too few for a {} chart",
                blobs.len(),
                kind.name()
            ),
            to_candidates(&[]),
        ));
    }
    // Lattice walk.
    let mut best: Vec<(usize, [i32; 2])> = Vec::new();
    let mut seen = vec![false; blobs.len()];
    let mut order: Vec<usize> = (0..blobs.len()).collect();
    order.sort_by(|a, b| blobs[*b].area.total_cmp(&blobs[*a].area));
    for &seed in &order {
        if seen[seed] {
            continue;
        }
        let lat = walk(&blobs, seed);
        for (b, _) in &lat {
            seen[*b] = true;
        }
        if lat.len() > best.len() {
            best = lat;
        }
        if best.len() >= kind.cells() {
            break;
        }
    }
    let mut accepted = vec![false; blobs.len()];
    if best.len() < 6 {
        return Err(fail(
            format!(
                "{} candidate patches, but at most {} of them form a grid",
                blobs.len(),
                best.len()
            ),
            to_candidates(&accepted),
        ));
    }
    // Homography lattice → small image, refined with outlier removal and pick-up of candidates
    // at predicted cells.
    let mut lattice = best;
    let mut h_obs = fit_lattice(&blobs, &lattice).map_err(|e| DetectFailure {
        error: e,
        candidates: to_candidates(&accepted),
    })?;
    for _ in 0..2 {
        let (imin, imax, jmin, jmax) = extent(&lattice);
        let span = kind.columns().max(kind.rows()) as i32;
        let mut taken: std::collections::HashMap<[i32; 2], usize> =
            lattice.iter().map(|(b, ij)| (*ij, *b)).collect();
        let used: std::collections::HashSet<usize> = lattice.iter().map(|(b, _)| *b).collect();
        for i in imax - span..=imin + span {
            for j in jmax - span..=jmin + span {
                if taken.contains_key(&[i, j]) {
                    continue;
                }
                let p = h_obs.apply([i as f64, j as f64]);
                let step = local_step(&h_obs, i, j);
                if let Some(b) = nearest(&blobs, p, 0.25 * step, |b| !used.contains(&b)) {
                    taken.insert([i, j], b);
                }
            }
        }
        let mut next: Vec<(usize, [i32; 2])> = taken.into_iter().map(|(ij, b)| (b, ij)).collect();
        next.sort_by_key(|(_, ij)| (ij[1], ij[0]));
        // Drop the points far from the fitted lattice.
        let h_new = fit_lattice(&blobs, &next).unwrap_or(h_obs);
        next.retain(|(b, ij)| {
            let p = h_new.apply([ij[0] as f64, ij[1] as f64]);
            let step = local_step(&h_new, ij[0], ij[1]);
            (p[0] - blobs[*b].c[0]).hypot(p[1] - blobs[*b].c[1]) < 0.25 * step
        });
        if next.len() >= 6 {
            if let Ok(h2) = fit_lattice(&blobs, &next) {
                h_obs = h2;
                lattice = next;
            }
        }
    }
    for (b, _) in &lattice {
        accepted[*b] = true;
    }
    // Placements of the chart on the lattice.
    let (imin, imax, jmin, jmax) = extent(&lattice);
    let side = kind.patch_fraction() * 0.5;
    let small_frame = Frame::from_data(ws, hs, crate::frame::Layout::Rgb, small).expect("sized");
    let mut scored: Vec<(f64, Homography, bool, usize, bool)> = Vec::new();
    for swap in [false, true] {
        let (ai, aj) = if swap {
            (kind.rows() as i32, kind.columns() as i32)
        } else {
            (kind.columns() as i32, kind.rows() as i32)
        };
        let wins_i = windows(&lattice, imin, imax, ai, 0);
        let wins_j = windows(&lattice, jmin, jmax, aj, 1);
        for sx in [1i32, -1] {
            for sy in [1i32, -1] {
                for &si in &wins_i {
                    for &sj in &wins_j {
                        let oi = if sx == 1 { si } else { si + ai - 1 };
                        let oj = if sy == 1 { sj } else { sj + aj - 1 };
                        // chart (u, v) → lattice (i, j).
                        let (sxf, syf) = (sx as f64, sy as f64);
                        let a = if swap {
                            Homography([
                                0.0,
                                sxf,
                                -0.5 * sxf + oi as f64,
                                syf,
                                0.0,
                                -0.5 * syf + oj as f64,
                                0.0,
                                0.0,
                                1.0,
                            ])
                        } else {
                            Homography([
                                sxf,
                                0.0,
                                -0.5 * sxf + oi as f64,
                                0.0,
                                syf,
                                -0.5 * syf + oj as f64,
                                0.0,
                                0.0,
                                1.0,
                            ])
                        };
                        let hc = h_obs.then_after(&a);
                        let means = cell_means(&small_frame, kind, &hc, side);
                        let inside = means.iter().filter(|m| m.is_some()).count();
                        if inside * 2 < kind.cells() {
                            continue;
                        }
                        if let Some(s) = chart_score(&means, reference) {
                            // Orientation-preserving maps have a positive determinant.
                            let det = if swap { -sxf * syf } else { sxf * syf };
                            let obs_det = {
                                let p0 = h_obs.apply([0.0, 0.0]);
                                let p1 = h_obs.apply([1.0, 0.0]);
                                let p2 = h_obs.apply([0.0, 1.0]);
                                (p1[0] - p0[0]) * (p2[1] - p0[1])
                                    - (p1[1] - p0[1]) * (p2[0] - p0[0])
                            };
                            let mirrored = det * obs_det < 0.0;
                            // Every cell of the placement holds a lattice patch: nothing is
                            // extrapolated past what was seen.
                            let covered = lattice
                                .iter()
                                .filter(|(_, ij)| {
                                    ij[0] >= si && ij[0] < si + ai && ij[1] >= sj && ij[1] < sj + aj
                                })
                                .count();
                            scored.push((
                                s,
                                hc,
                                mirrored,
                                kind.cells() - inside,
                                covered == kind.cells(),
                            ));
                        }
                    }
                }
            }
        }
    }
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let candidates = to_candidates(&accepted);
    let Some((score, hc, mirrored, outside, complete)) = scored.first().cloned() else {
        return Err(fail(
            format!(
                "a grid of {} patches was found, but no placement of the chart fits it",
                lattice.len()
            ),
            candidates,
        ));
    };
    let runner_up = scored.get(1).map_or(f64::INFINITY, |s| s.0);
    if score > MATCH_LIMIT {
        return Err(fail(
            format!(
                "a grid of {} patches was found, but its colours do not match reference {} (median ΔE00 {score:.1}, limit {MATCH_LIMIT})",
                lattice.len(),
                reference.name
            ),
            candidates,
        ));
    }
    // A complete lattice (every cell seen as a patch) with a decisive orientation may match
    // up to MATCH_LIMIT: the looser match then cannot come from a placement shifted across a
    // partial lattice (the failure DETECT_MATCH_LIMIT guards against), only from colours the
    // camera rendered (tone curve, saturation, a strong cast).
    let loose_ok =
        complete && score <= MATCH_LIMIT && score <= COMPLETE_AMBIGUITY_RATIO * runner_up;
    if score > DETECT_MATCH_LIMIT && !loose_ok {
        return Err(fail(
            format!(
                "a grid of {} patches was found, but its colours match reference {} only loosely (median ΔE00 {score:.1}, next placement {runner_up:.1}; limit {DETECT_MATCH_LIMIT} for a found chart{}): refused rather than risk a wrong placement; give the chart's corners",
                lattice.len(),
                reference.name,
                if complete {
                    format!(", or {MATCH_LIMIT} with a complete grid and the next placement {:.0}× worse", 1.0 / COMPLETE_AMBIGUITY_RATIO)
                } else {
                    String::new()
                }
            ),
            candidates,
        ));
    }
    let persp = perspective(kind, &hc);
    if persp > PERSPECTIVE_LIMIT {
        return Err(fail(
            format!(
                "the chart is seen under strong perspective (patch scale varies {persp:.2}× across it, limit {PERSPECTIVE_LIMIT}): refused rather than risk misplaced patches; shoot it more squarely or give the chart's corners"
            ),
            candidates,
        ));
    }
    if score > AMBIGUITY_RATIO * runner_up {
        return Err(fail(
            format!(
                "the chart's orientation is ambiguous (median ΔE00 {score:.2} vs {runner_up:.2} for the next placement)"
            ),
            candidates,
        ));
    }
    if outside > 0 {
        return Err(DetectFailure {
            error: ChartError::Geometry(format!(
                "the chart is partly outside the frame ({outside} of {} patches)",
                kind.cells()
            )),
            candidates,
        });
    }
    Ok(Detection {
        homography: hc.scaled(f as f64),
        score,
        runner_up,
        lattice: lattice.len(),
        perspective: persp,
        mirrored,
        downsample: f,
        candidates,
    })
}

fn extent(l: &[(usize, [i32; 2])]) -> (i32, i32, i32, i32) {
    let imin = l.iter().map(|x| x.1[0]).min().unwrap_or(0);
    let imax = l.iter().map(|x| x.1[0]).max().unwrap_or(0);
    let jmin = l.iter().map(|x| x.1[1]).min().unwrap_or(0);
    let jmax = l.iter().map(|x| x.1[1]).max().unwrap_or(0);
    (imin, imax, jmin, jmax)
}

/// Window starts `s` (window `[s, s + len)`) along axis `k` holding the most lattice points.
fn windows(l: &[(usize, [i32; 2])], lo: i32, hi: i32, len: i32, k: usize) -> Vec<i32> {
    let count = |s: i32| l.iter().filter(|x| x.1[k] >= s && x.1[k] < s + len).count();
    let starts: Vec<i32> = (lo - len + 1..=hi).collect();
    let best = starts.iter().map(|&s| count(s)).max().unwrap_or(0);
    starts
        .into_iter()
        .filter(|&s| count(s) * 10 >= best * 9)
        .collect()
}

fn local_step(h: &Homography, i: i32, j: i32) -> f64 {
    let p = h.apply([i as f64, j as f64]);
    let a = h.apply([i as f64 + 1.0, j as f64]);
    let b = h.apply([i as f64, j as f64 + 1.0]);
    (a[0] - p[0])
        .hypot(a[1] - p[1])
        .min((b[0] - p[0]).hypot(b[1] - p[1]))
}

fn nearest(blobs: &[Blob], p: [f64; 2], tol: f64, ok: impl Fn(usize) -> bool) -> Option<usize> {
    let mut best = None;
    let mut bd = tol;
    for (k, b) in blobs.iter().enumerate() {
        let d = (b.c[0] - p[0]).hypot(b.c[1] - p[1]);
        if d < bd && ok(k) {
            bd = d;
            best = Some(k);
        }
    }
    best
}

fn fit_lattice(blobs: &[Blob], l: &[(usize, [i32; 2])]) -> Result<Homography, ChartError> {
    let src: Vec<[f64; 2]> = l
        .iter()
        .map(|(_, ij)| [ij[0] as f64, ij[1] as f64])
        .collect();
    let dst: Vec<[f64; 2]> = l.iter().map(|(b, _)| blobs[*b].c).collect();
    let (imin, imax, jmin, jmax) = extent(l);
    if imax - imin < 1 || jmax - jmin < 1 {
        return Err(ChartError::NotFound(
            "the patch-like regions lie on one line".into(),
        ));
    }
    Homography::from_points(&src, &dst)
}

/// Links candidates into a lattice from `seed`: (blob, lattice coordinates).
fn walk(blobs: &[Blob], seed: usize) -> Vec<(usize, [i32; 2])> {
    let s = &blobs[seed];
    let similar = |a: f64, b: f64| (0.4..=2.5).contains(&(a / b));
    // Neighbours of the seed, nearest first.
    let mut near: Vec<(f64, usize)> = blobs
        .iter()
        .enumerate()
        .filter(|(k, b)| *k != seed && similar(b.area, s.area))
        .map(|(k, b)| ((b.c[0] - s.c[0]).hypot(b.c[1] - s.c[1]), k))
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    let side = s.area.sqrt();
    let Some(&(d1, n1)) = near.first() else {
        return vec![(seed, [0, 0])];
    };
    if !(d1 > 0.9 * side && d1 < 3.5 * side) {
        return vec![(seed, [0, 0])];
    }
    let u = [blobs[n1].c[0] - s.c[0], blobs[n1].c[1] - s.c[1]];
    let v = near.iter().skip(1).take(8).find_map(|&(d, k)| {
        let w = [blobs[k].c[0] - s.c[0], blobs[k].c[1] - s.c[1]];
        let cos = (u[0] * w[0] + u[1] * w[1]) / (d1 * d);
        (cos.abs() < 0.5 && d / d1 > 0.6 && d / d1 < 1.7).then_some(w)
    });
    let Some(v) = v else {
        return vec![(seed, [0, 0])];
    };
    let mut at: std::collections::HashMap<[i32; 2], usize> = std::collections::HashMap::new();
    let mut of = vec![None; blobs.len()];
    at.insert([0, 0], seed);
    of[seed] = Some([0, 0]);
    let mut queue = std::collections::VecDeque::new();
    queue.push_back((seed, [0i32, 0i32], u, v));
    while let Some((b, ij, u, v)) = queue.pop_front() {
        let c = blobs[b].c;
        for (di, dj) in [(1i32, 0i32), (-1, 0), (0, 1), (0, -1)] {
            let step = if di != 0 { u } else { v };
            let sgn = (di + dj) as f64;
            for mult in [1i32, 2] {
                let nij = [ij[0] + di * mult, ij[1] + dj * mult];
                if at.contains_key(&nij) {
                    break;
                }
                let m = mult as f64 * sgn;
                let p = [c[0] + m * step[0], c[1] + m * step[1]];
                let len = step[0].hypot(step[1]);
                let found = nearest(blobs, p, 0.3 * len * mult as f64, |k| {
                    of[k].is_none() && similar(blobs[k].area, blobs[b].area)
                });
                if let Some(k) = found {
                    at.insert(nij, k);
                    of[k] = Some(nij);
                    let d = [(blobs[k].c[0] - c[0]) / m, (blobs[k].c[1] - c[1]) / m];
                    let (nu, nv) = if di != 0 { (d, v) } else { (u, d) };
                    queue.push_back((k, nij, nu, nv));
                    break;
                }
            }
        }
    }
    let mut out: Vec<(usize, [i32; 2])> = at.into_iter().map(|(ij, b)| (b, ij)).collect();
    out.sort_by_key(|(_, ij)| (ij[1], ij[0]));
    out
}
