//! Finding a chart in a linear frame without `--corners`.
//!
//! Why one file (about 1,100 lines): the three searches (full scale, retry, coarse) and their
//! acceptance rules (match limits, ambiguity ratios, hue and surround checks) are one decision: a
//! rule changed in one search must be seen beside the others. The tests are in `detect_tests.rs`.
//!
//! 1. The frame is box-downsampled so its long side is at most [`DetectOptions::max_side`]
//!    pixels, smoothed (a Gaussian filter, σ = 1: imageproc's to the bit, [`super::raster`]) and
//!    turned into log-luminance and chromaticity — so the exposure does not matter and dark
//!    patches count as much as bright ones.
//! 2. *Flat* pixels (log-luminance and chromaticity gradients below a threshold) are labelled into
//!    connected regions (numbered as imageproc's `connected_components` does); regions of
//!    patch-like size and shape (second moments of a filled convex quadrilateral, not elongated)
//!    are candidate patches.
//! 3. Candidates are linked into a lattice: from a seed, each neighbour is looked for one step
//!    (or two, over a missed dark patch) along the two local lattice directions, which are updated
//!    as the walk goes, so perspective is followed. The largest lattice wins; a homography from
//!    lattice coordinates to the frame is fitted to its centroids (least squares) and refined.
//! 4. Every placement of the chart on the lattice — 4 rotations × mirror × the offsets the lattice
//!    allows — is scored by how well its patch colours match the reference (median ΔE00 after the
//!    best 3×3 linear map, or after linearising each channel through the chart's own grey ramp
//!    and then the best 3×3 map — a camera's tone curve — whichever is better,
//!    [`super::extract::chart_score`]). The best must be plausible (below
//!    [`DETECT_MATCH_LIMIT`], or [`MATCH_LIMIT`] when every cell of the chart's outer ring was
//!    seen as a patch and the next placement is [`ENCLOSED_AMBIGUITY_RATIO`] worse), clearly
//!    better than the next (ratio [`AMBIGUITY_RATIO`]), not a block of a larger grid of like
//!    patches (a CC24's colours inside a ColorChecker Digital SG, [`SURROUND_LIMIT`]) and seen
//!    under moderate perspective ([`PERSPECTIVE_LIMIT`]); where cells of the chart's outer ring
//!    were not seen, their placement must survive fitting the lattice without any one of its
//!    points ([`EXTRAPOLATION_LIMIT`]); otherwise detection fails with a message and the
//!    candidates, never a guess.
//! 5. When no chart was found and the frame is larger than [`DetectOptions::retry_side`], steps
//!    1–4 run once more on the frame downsampled to that long side: averaging more pixels
//!    quiets the noise and texture that break patches (dark ones, on phone JPEGs) into pieces
//!    at the finer scale. The second search is judged by the same rules; when it finds nothing
//!    either, a third runs at [`DetectOptions::coarse_side`] (a large chart under heavy sensor
//!    noise), and when that finds nothing, the first failure is reported. Within a search, when
//!    none of the largest lattices matches, up to [`MAX_EXTRA_LATTICES`] smaller ones are placed
//!    too (a small chart on textured ground).

use super::extract::{cell_means, chart_score, hue_errors, MATCH_LIMIT};
use super::reference::Reference;
use super::{ChartError, Homography};
use nsrm::Frame;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// The best placement must score at most this fraction of the second best.
pub(crate) const AMBIGUITY_RATIO: f64 = 0.7;

/// A found chart must match its reference at least this well (median ΔE00 after the best 3×3
/// map; stricter than [`MATCH_LIMIT`], which applies to `--corners`): correct detections of
/// synthetic scenes score at most 2.5, a placement shifted by some cells on a partial lattice
/// was seen at 7.6.
pub(crate) const DETECT_MATCH_LIMIT: f64 = 5.0;

/// With an enclosed placement (every cell of the chart's outer ring seen as a patch), a found
/// chart may match up to [`MATCH_LIMIT`] when the next placement scores at least 1 / this times
/// worse (stricter than [`AMBIGUITY_RATIO`]; the correct placements of the development
/// photographs score 4× to 12× better than the next). Until 2026-12-03 every cell had to be seen;
/// a photographed SG with one of its 140 cells unseen (median ΔE00 5.4, the next placement 4×
/// worse) was refused.
pub(crate) const ENCLOSED_AMBIGUITY_RATIO: f64 = 0.5;

/// A placement whose next is far worse ([`DECISIVE_RATIO`]) and whose colours keep the
/// reference's hues ([`hues_hold`]) may match up to this median ΔE00, whether or not its outer
/// ring was all seen: a strong camera look — a steep contrast curve and a saturation boost, a
/// product photograph's grading — bends colours beyond what the grey ramp and a 3×3 map undo,
/// but along their hues. Measured (`chart rate --family graded`, contrast 3–5, saturation
/// ×1.6–2.2): correct placements score up to 6.2 with the next 3.8–5.5× worse; a real graded
/// photograph 5.8 with the next 3.2× worse. Placements shifted across a partial lattice (what
/// [`DETECT_MATCH_LIMIT`] guards against, seen at 7.6) put colours in cells of other hues.
pub(crate) const DECISIVE_MATCH_LIMIT: f64 = 7.0;

/// [`DECISIVE_MATCH_LIMIT`]'s placement must score at most this fraction of the next (the next
/// at least 2.5× worse; stricter than [`AMBIGUITY_RATIO`]).
pub(crate) const DECISIVE_RATIO: f64 = 0.4;

/// [`hues_hold`]: a chromatic cell keeps its hue when its fitted hue lies within this many
/// degrees of the reference's.
pub(crate) const HUE_TOLERANCE: f64 = 30.0;

/// Whether a placement's colours keep the reference's hues: at least 8 chromatic cells
/// ([`super::extract::HUE_CHROMA`]) were read, and at least five in six of them lie within [`HUE_TOLERANCE`]
/// of their reference hue after the fit (`hue_errors`: [`hue_errors`]'s degrees). Colours in
/// the wrong cells land at unrelated hues (a random hue difference lies within 30° one time in
/// six); a camera look moves them along their hues (the `graded` family: at most one of 18
/// beyond 30°, none beyond 45°).
pub(crate) fn hues_hold(hue_errors: &[f64]) -> bool {
    let n = hue_errors.len();
    let kept = hue_errors.iter().filter(|&&e| e <= HUE_TOLERANCE).count();
    n >= 8 && kept * 6 >= n * 5
}

/// Perspective strength above which a found chart is refused: the ratio of the largest to the
/// smallest patch scale (square root of the local area) over the chart's cells. Within it, a
/// cell not seen is either enclosed by seen ones or pinned by [`EXTRAPOLATION_LIMIT`]; what
/// remains is the centroid of a tilted patch lying off its projected centre, a small fraction
/// of a pitch (measured with `--family tilt` and `--family wide`, which reach 2.2). Scenes
/// inside the envelope (tilt ≤ 30°) reach 1.51 (100 CC24 and 60 SG scenes). Until 2026-12-03
/// the limit was 1.6 unless every cell of the outer ring was seen (a CC24 tilted 54° had been
/// read with a cell extrapolated 0.30 pitch off at 1.69), with a looser [`EXTRAPOLATION_LIMIT`].
pub(crate) const PERSPECTIVE_LIMIT: f64 = 2.2;

/// Where cells of the chart's outer ring were not seen, the most a cell not seen may move when
/// the lattice is fitted without one of its points, in pitches ([`extrapolation`]). The
/// jackknife sees part of the uncertainty only: the misplaced cell of a misread scene lay up to
/// 2.4× as far off as it moved (`--family wide --seed 1494`: a lattice of 20 fitted with
/// perspective 1.57 where the truth was 2.08, the jackknife 0.18, three cells up to 0.44 pitch
/// off, read under the limit of 0.25 used until 2026-12-03; `--family tilt --seed 205` under a
/// raised perspective limit: 0.17, one cell 0.34 off). Measured over 2 547 CC24 scenes read
/// with cells of the ring unseen (tilt, wide, 30–60° tilts, black frames, Passports; 200–1 000
/// seeds each): every correct one moved at most 0.145, the two misread ones 0.17 and 0.18.
/// Under this limit, 4 769 such scenes read (1 400 seeds of tilt, wide and black-frame, 1 000 of
/// passport): worst sampled centre 0.25 pitch, on a dark, noisy black-frame chart (seed 2374,
/// jackknife 0.026; the old limits read it the same). The real photographs move at most 0.03.
pub(crate) const EXTRAPOLATION_LIMIT: f64 = 0.1;

/// A placement is refused when at least this fraction of the cells just around it hold lattice
/// patches of its own patches' size ([`surround`]): the grid goes on past the chart, which is
/// then a block of a larger chart — a ColorChecker Digital SG holds the classic 24 colours in its
/// E2–J5 block, and a CC24 read there is a chart reported where there is another make (53 of 60
/// `--family nested` scenes were, before this check). Measured: `nested` scenes 19–22 of the 24
/// cells around that block, rendered SG scenes 17–21, a photographed SG 24; CC24 scenes (every
/// family, 60 seeds each) at most 2 and photographs at most 1, their frame or background lying
/// around the patches.
pub(crate) const SURROUND_LIMIT: f64 = 0.5;

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
    pub(crate) max_side: usize,
    /// Long side of the coarser image searched again when the first search finds no chart (and
    /// the frame is larger): see [`detect`].
    pub(crate) retry_side: usize,
    /// Long side of the coarsest image searched, last (a large chart under heavy sensor noise:
    /// averaging 3–7 pixels makes its patches uniform; `chart rate --family noisy`), when neither search above finds a chart:
    /// see [`detect`].
    pub(crate) coarse_side: usize,
    /// Largest gradient (log units per pixel) of a flat pixel.
    pub(crate) flat_threshold: f32,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            max_side: 1600,
            retry_side: 800,
            coarse_side: 400,
            flat_threshold: 0.08,
        }
    }
}

/// A candidate patch region (frame pixels).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Centre of the region.
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
    /// Median ΔE00 of the next best placement.
    pub runner_up: f64,
    /// Patches linked into the lattice.
    pub lattice: usize,
    /// Perspective strength: the largest over the smallest local patch scale over the cells.
    pub perspective: f64,
    /// Mirrored (the frame shows the chart's mirror image) — unusual; reported for the user.
    pub(crate) mirrored: bool,
    /// The factor the frame was box-downsampled by before the search.
    pub(crate) downsample: usize,
    /// Every candidate patch region looked at.
    pub(crate) candidates: Vec<Candidate>,
}

/// Why no chart was found, and what was looked at.
#[derive(Debug)]
pub struct DetectFailure {
    /// Why no chart was found.
    pub error: ChartError,
    /// Every candidate patch region looked at.
    pub(crate) candidates: Vec<Candidate>,
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
    // Each output pixel is summed in a local and written once: the output's pages come fresh
    // from the allocator, and reading one before writing it maps the shared zero page, whose
    // copy-on-write fault then flushes every CPU's TLB (40 % of a 1-Mpixel photo's detection
    // time, by `perf`). Same sums in the same order as a row-at-a-time accumulation.
    out.par_chunks_mut(ws * 3)
        .enumerate()
        .for_each(|(ys, row)| {
            for (xs, px) in row.chunks_exact_mut(3).enumerate() {
                let mut acc = [0.0f32; 3];
                for yy in ys * f..(ys + 1) * f {
                    let src = &frame.data[(yy * frame.width + xs * f) * ch..][..f * ch];
                    for p in src.chunks_exact(ch) {
                        for k in 0..3 {
                            let v = p[k];
                            acc[k] += if v.is_finite() { v } else { 0.0 };
                        }
                    }
                }
                for k in 0..3 {
                    px[k] = acc[k] * norm;
                }
            }
        });
    (ws, hs, out)
}

/// Step 1's result: the downsampled frame and its log-luminance and chromaticity planes.
struct Prepared {
    /// Downsampling factor.
    f: usize,
    ws: usize,
    hs: usize,
    /// The downsampled linear RGB (unsmoothed; patch colours are read from it).
    small: Vec<f32>,
    logl: Vec<f32>,
    cr: Vec<f32>,
    cb: Vec<f32>,
}

/// The box-downsampling factor that brings `frame`'s long side to at most `max_side` (at least
/// 64) pixels.
fn downsample_factor(frame: &Frame, max_side: usize) -> usize {
    frame
        .width
        .max(frame.height)
        .div_ceil(max_side.max(64))
        .max(1)
}

/// Step 1: downsample so the long side is at most `max_side`, smooth (σ = 1) and convert.
fn prepare(frame: &Frame, max_side: usize) -> Result<Prepared, String> {
    let f = downsample_factor(frame, max_side);
    let (ws, hs, small) = downsample(frame, f);
    if ws < 32 || hs < 32 {
        return Err(format!(
            "the frame ({}×{}) is too small",
            frame.width, frame.height
        ));
    }
    let smooth = super::raster::gaussian_blur_rgb(&small, ws, hs, 1.0);
    let (logl, cr, cb) = log_chroma(&smooth).ok_or_else(|| "the frame is black".to_string())?;
    Ok(Prepared {
        f,
        ws,
        hs,
        small,
        logl,
        cr,
        cb,
    })
}

/// Log-luminance (`R + 2G + B`) and chromaticity (`r`, `b`) of packed RGB; `None` when no
/// pixel is above zero. A floor 10⁻⁵ below the brightest pixel keeps the logarithm finite.
fn log_chroma(rgb: &[f32]) -> Option<(Vec<f32>, Vec<f32>, Vec<f32>)> {
    let ymax = rgb
        .chunks_exact(3)
        .map(|p| p[0] + 2.0 * p[1] + p[2])
        .fold(0.0f32, f32::max);
    if !(ymax > 0.0) {
        return None;
    }
    let floor = ymax * 1e-5;
    let n = rgb.len() / 3;
    let (mut logl, mut cr, mut cb) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    for (i, p) in rgb.chunks_exact(3).enumerate() {
        let (r, g, b) = (p[0].max(0.0), p[1].max(0.0), p[2].max(0.0));
        let s = r + g + b + floor;
        logl[i] = (r + 2.0 * g + b).max(floor).ln();
        cr[i] = r / s;
        cb[i] = b / s;
    }
    Some((logl, cr, cb))
}

/// Step 2a: the flat pixels — log-luminance and (4×) chromaticity central differences below
/// `t` — as 255 in a mask (the one-pixel border stays 0).
fn flat_mask(p: &Prepared, t: f32) -> image::GrayImage {
    let (ws, hs) = (p.ws, p.hs);
    let mut mask = image::GrayImage::new(ws as u32, hs as u32);
    for y in 1..hs.saturating_sub(1) {
        for x in 1..ws.saturating_sub(1) {
            let i = y * ws + x;
            let d = |a: &[f32]| {
                let gx = (a[i + 1] - a[i - 1]) * 0.5;
                let gy = (a[i + ws] - a[i - ws]) * 0.5;
                gx.abs().max(gy.abs())
            };
            let e = d(&p.logl).max(4.0 * d(&p.cr)).max(4.0 * d(&p.cb));
            if e < t {
                mask.put_pixel(x as u32, y as u32, image::Luma([255]));
            }
        }
    }
    mask
}

/// Step 2b: the connected flat regions' moments `[n, Σx, Σy, Σx², Σxy, Σy²]` (pixel centres),
/// indexed by label (0, the background, is unused).
fn region_moments(mask: &image::GrayImage) -> Vec<[f64; 6]> {
    let (w, h) = mask.dimensions();
    super::raster::region_moments(mask.as_raw(), w as usize, h as usize)
}

/// A region's centroid and whether its shape is that of a patch: a filled convex
/// quadrilateral (area / (12 √det Σ) is 1 for any parallelogram, 0.8..1.12 allows blur and
/// perspective), not elongated (eigenvalue ratio ≤ 4: a square tilted by 60° has 4), its area
/// within `min..=max`.
fn patch_shape(s: &[f64; 6], min: f64, max: f64) -> ([f64; 2], bool) {
    let n = s[0];
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
    let ok = n >= min && n <= max && (0.8..=1.12).contains(&fill) && l2 > 0.0 && l1 / l2 <= 4.0;
    ([mx, my], ok)
}

/// The smallest part of the frame a chart's patch grid may cover for its patches to be
/// candidates: a candidate region must hold 8 % of a cell of such a chart (and 10 pixels of the
/// searched image). Phone photographs show charts held at arm's length covering 1–2 % of the
/// frame; below that, a patch is a few pixels of the searched image.
const MIN_CHART_FRACTION: f64 = 0.01;

/// Step 2's result: the candidate patches and every region large enough to report.
struct Regions {
    blobs: Vec<Blob>,
    /// (index in `blobs` when patch-like, patch-like, centre, area) in downsampled pixels.
    all: Vec<(usize, bool, [f64; 2], f64)>,
}

impl Regions {
    /// Step 2b: the regions of `stats` in a `ws × hs` image, for a chart of `cells` cells.
    fn new(stats: &[[f64; 6]], cells: usize, ws: usize, hs: usize) -> Regions {
        let frame_area = (ws * hs) as f64;
        let min_area = 10.0f64.max(frame_area * MIN_CHART_FRACTION / cells as f64 * 0.08);
        // A patch is at most a cell of a chart whose patch grid fills the whole frame (a
        // chart cropped tight, no surround): frame area / cells.
        let max_area = frame_area / cells as f64;
        let mut blobs = Vec::new();
        let mut all = Vec::new();
        for s in stats.iter().skip(1).filter(|s| s[0] >= 4.0) {
            let (c, ok) = patch_shape(s, min_area, max_area);
            if s[0] >= min_area {
                all.push((blobs.len(), ok, c, s[0]));
            }
            if ok {
                blobs.push(Blob { c, area: s[0] });
            }
        }
        Regions { blobs, all }
    }

    /// The regions in frame pixels (`f`: the downsampling factor), those of `accepted` blobs
    /// marked.
    fn candidates(&self, f: usize, accepted: &[bool]) -> Vec<Candidate> {
        let f = f as f64;
        self.all
            .iter()
            .map(|(bi, ok, c, n)| Candidate {
                centre: [c[0] * f, c[1] * f],
                radius: (n / std::f64::consts::PI).sqrt() * f,
                accepted: *ok && accepted.get(*bi).copied().unwrap_or(false),
            })
            .collect()
    }
}

/// Lattice coordinates of linked candidates: (blob, `[i, j]`).
type Lattice = Vec<(usize, [i32; 2])>;

/// The fewest patches a lattice is fitted and placed with (a homography needs 4 points; 6
/// leave some redundancy).
const MIN_LATTICE: usize = 6;

/// At most this many lattices (largest first) are placed and scored; a lattice other than the
/// largest must hold half of the chart's cells (a second chart page, another chart in the
/// frame) — smaller ones are clutter that lines up by chance.
const MAX_LATTICES: usize = 3;

/// When none of the lattices above matches the chart, at most this many more (of 8 patches or
/// more, largest first) are placed and scored: a small chart on textured ground (leaf litter)
/// forms a smaller lattice than the ground's flat pieces do.
const MAX_EXTRA_LATTICES: usize = 8;

/// Step 3: the lattices the candidates form, largest first (at least 6 patches each). Seeds
/// are taken largest region first; each walk's lattice is split at empty lines
/// ([`split_gaps`]).
fn lattices(blobs: &[Blob]) -> Vec<Lattice> {
    let mut seen = vec![false; blobs.len()];
    let mut order: Vec<usize> = (0..blobs.len()).collect();
    order.sort_by(|a, b| blobs[*b].area.total_cmp(&blobs[*a].area));
    let mut out = Vec::new();
    for &seed in &order {
        if seen[seed] {
            continue;
        }
        let lat = walk(blobs, seed);
        for (b, _) in &lat {
            seen[*b] = true;
        }
        out.extend(
            split_gaps(lat)
                .into_iter()
                .filter(|l| l.len() >= MIN_LATTICE),
        );
    }
    out.sort_by_key(|l| std::cmp::Reverse(l.len()));
    out
}

/// Splits a lattice at every line (column `i` or row `j`) inside its extent that holds no
/// patch. The walk's double step exists to bridge one missed (dark) patch; a whole line
/// missing means the parts are not one grid — the hinge between a Passport's two pages or
/// the gutter between two charts, whose width is no whole number of pitches, so one
/// homography over both parts would misplace cells by a fraction of a pitch. Only a split
/// leaving at least [`MIN_LATTICE`] patches on both sides is made: a smaller part could not be
/// placed on its own, and a sparsely seen chart (heavy blur: many missed patches, hence empty
/// lines) is better judged whole, by its colours. Parts are returned largest first.
fn split_gaps(l: Lattice) -> Vec<Lattice> {
    for k in 0..2 {
        let lo = l.iter().map(|x| x.1[k]).min().unwrap_or(0);
        let hi = l.iter().map(|x| x.1[k]).max().unwrap_or(0);
        let gap = (lo + 1..hi).find(|&g| {
            l.iter().all(|x| x.1[k] != g)
                && l.iter().filter(|x| x.1[k] < g).count() >= MIN_LATTICE
                && l.iter().filter(|x| x.1[k] > g).count() >= MIN_LATTICE
        });
        if let Some(gap) = gap {
            let (a, b): (Lattice, Lattice) = l.into_iter().partition(|x| x.1[k] < gap);
            let mut parts = split_gaps(a);
            parts.extend(split_gaps(b));
            parts.sort_by_key(|p| std::cmp::Reverse(p.len()));
            return parts;
        }
    }
    vec![l]
}

/// Step 4: a homography from lattice coordinates to the downsampled image, fitted to the
/// lattice's centroids, then twice: candidates within a quarter pitch of a predicted cell
/// picked up, points more than a quarter pitch from the refit dropped, and the part split off
/// by an empty line ([`split_gaps`]) that holds fewer of the previous points dropped.
fn refine(
    blobs: &[Blob],
    lattice: Lattice,
    span: i32,
) -> Result<(Lattice, Homography), ChartError> {
    let mut lattice = lattice;
    let mut h_obs = fit_lattice(blobs, &lattice)?;
    for _ in 0..2 {
        let (imin, imax, jmin, jmax) = extent(&lattice);
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
                if let Some(b) = nearest(blobs, p, 0.25 * step, |b| !used.contains(&b)) {
                    taken.insert([i, j], b);
                }
            }
        }
        let mut next: Lattice = taken.into_iter().map(|(ij, b)| (b, ij)).collect();
        next.sort_by_key(|(_, ij)| (ij[1], ij[0]));
        let h_new = fit_lattice(blobs, &next).unwrap_or(h_obs);
        next.retain(|(b, ij)| {
            let p = h_new.apply([ij[0] as f64, ij[1] as f64]);
            let step = local_step(&h_new, ij[0], ij[1]);
            (p[0] - blobs[*b].c[0]).hypot(p[1] - blobs[*b].c[1]) < 0.25 * step
        });
        let next = split_gaps(next)
            .into_iter()
            .max_by_key(|p| p.iter().filter(|x| used.contains(&x.0)).count())
            .unwrap_or_default();
        if next.len() >= MIN_LATTICE {
            if let Ok(h2) = fit_lattice(blobs, &next) {
                h_obs = h2;
                lattice = next;
            }
        }
    }
    Ok((lattice, h_obs))
}

/// A placement of the chart on a lattice, scored.
#[derive(Debug, Clone)]
struct Placement {
    /// Median ΔE00 ([`chart_score`]).
    score: f64,
    /// Chart coordinates → downsampled image.
    hc: Homography,
    mirrored: bool,
    /// Cells outside the image.
    outside: usize,
    /// Every cell of the chart's outer ring holds a lattice patch: the cells not seen, if any,
    /// are enclosed by seen ones, so they are interpolated, never extrapolated.
    enclosed: bool,
    /// Chart → lattice ([`placement_map`]).
    map: Homography,
    /// The lattice window the chart covers: first `[i, j]` and sizes.
    window: ([i32; 2], [i32; 2]),
}

/// Whether lattice point `ij` lies in the window `(first [i, j], sizes)`.
fn in_window(ij: &[i32; 2], (s, a): ([i32; 2], [i32; 2])) -> bool {
    ij[0] >= s[0] && ij[0] < s[0] + a[0] && ij[1] >= s[1] && ij[1] < s[1] + a[1]
}

/// Chart `(u, v)` → lattice `(i, j)`: axes swapped or not, signs `sx`, `sy`, the cell
/// centre of chart cell (0, 0) on lattice point `(oi, oj)`.
fn placement_map(swap: bool, sx: f64, sy: f64, oi: i32, oj: i32) -> Homography {
    let (ti, tj) = (-0.5 * sx + oi as f64, -0.5 * sy + oj as f64);
    if swap {
        Homography([0.0, sx, ti, sy, 0.0, tj, 0.0, 0.0, 1.0])
    } else {
        Homography([sx, 0.0, ti, 0.0, sy, tj, 0.0, 0.0, 1.0])
    }
}

/// Step 5: every placement of the chart on the lattice — 4 rotations × mirror × the windows
/// of the lattice holding the most points — with half of its cells inside the image, scored
/// against the reference; best first.
fn placements(
    small: &Frame,
    reference: &Reference,
    lattice: &Lattice,
    h_obs: &Homography,
) -> Vec<Placement> {
    let kind = reference.chart;
    let (imin, imax, jmin, jmax) = extent(lattice);
    let side = kind.patch_fraction() * 0.5;
    // Orientation-preserving maps have a positive determinant.
    let obs_det = {
        let p0 = h_obs.apply([0.0, 0.0]);
        let p1 = h_obs.apply([1.0, 0.0]);
        let p2 = h_obs.apply([0.0, 1.0]);
        (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0])
    };
    let mut scored = Vec::new();
    for swap in [false, true] {
        let (ai, aj) = if swap {
            (kind.rows() as i32, kind.columns() as i32)
        } else {
            (kind.columns() as i32, kind.rows() as i32)
        };
        let wins_i = windows(lattice, imin, imax, ai, 0);
        let wins_j = windows(lattice, jmin, jmax, aj, 1);
        for (sx, sy) in [(1i32, 1i32), (1, -1), (-1, 1), (-1, -1)] {
            for &si in &wins_i {
                for &sj in &wins_j {
                    let oi = if sx == 1 { si } else { si + ai - 1 };
                    let oj = if sy == 1 { sj } else { sj + aj - 1 };
                    let (sxf, syf) = (sx as f64, sy as f64);
                    let map = placement_map(swap, sxf, syf, oi, oj);
                    let hc = h_obs.then_after(&map);
                    let means = cell_means(small, kind, &hc, side);
                    let inside = means.iter().filter(|m| m.is_some()).count();
                    if inside * 2 < kind.cells() {
                        continue;
                    }
                    let Some(score) = chart_score(&means, reference) else {
                        continue;
                    };
                    let det = if swap { -sxf * syf } else { sxf * syf };
                    let in_window = |ij: &[i32; 2]| in_window(ij, ([si, sj], [ai, aj]));
                    let ring = |ij: &[i32; 2]| {
                        ij[0] == si || ij[0] == si + ai - 1 || ij[1] == sj || ij[1] == sj + aj - 1
                    };
                    let ring_seen = lattice
                        .iter()
                        .filter(|(_, ij)| in_window(ij) && ring(ij))
                        .count();
                    scored.push(Placement {
                        score,
                        hc,
                        mirrored: det * obs_det < 0.0,
                        outside: kind.cells() - inside,
                        enclosed: ring_seen as i32 == 2 * (ai + aj) - 4,
                        map,
                        window: ([si, sj], [ai, aj]),
                    });
                }
            }
        }
    }
    scored.sort_by(|a, b| a.score.total_cmp(&b.score));
    scored
}

/// Step 5b: lattice points outside the best placement's window are no patches of the chart
/// (clutter or a neighbouring object that lined up within a quarter pitch); the homography is
/// refitted without them, since each pulls the fit towards itself (seen: three such points
/// moving a patch of a chart tilted 40° by 0.39 pitch). The lattice returned is what remains.
fn refit_inside(
    blobs: &[Blob],
    lattice: Lattice,
    mut scored: Vec<Placement>,
) -> (Lattice, Vec<Placement>) {
    let Some(best) = scored.first_mut() else {
        return (lattice, scored);
    };
    let inside: Lattice = lattice
        .iter()
        .copied()
        .filter(|(_, ij)| in_window(ij, best.window))
        .collect();
    if inside.len() == lattice.len() || inside.len() < MIN_LATTICE {
        return (lattice, scored);
    }
    match fit_lattice(blobs, &inside) {
        Ok(h) => {
            best.hc = h.then_after(&best.map);
            (inside, scored)
        }
        Err(_) => (lattice, scored),
    }
}

/// How uncertain the placement of the cells not seen as patches is, in local pitches: the most
/// a cell not seen moves when the lattice's homography is fitted again without one of its points
/// (a jackknife over the lattice). Cells seen are pinned by their centroids; a cell not seen is
/// placed by the fit alone, and when dropping a single point moves it, its projective terms are
/// extrapolated from too little (seen: a lattice of 12 patches whose fit showed perspective 1.46
/// where the chart's was 1.20, putting other rows most of a pitch off). Or, where larger, how
/// far the homography and an affine fit place such a cell apart when the lattice shows no
/// perspective ([`unsupported_perspective`]). 0 when every cell was seen.
fn extrapolation(blobs: &[Blob], lattice: &Lattice, p: &Placement, kind: super::ChartKind) -> f64 {
    let Some(to_chart) = p.map.inverse() else {
        return f64::INFINITY;
    };
    let seen: Vec<[f64; 2]> = lattice
        .iter()
        .map(|(_, ij)| to_chart.apply([ij[0] as f64, ij[1] as f64]))
        .collect();
    let unseen: Vec<[f64; 2]> = (0..kind.cells())
        .map(|i| kind.cell_centre(i))
        .filter(|c| !seen.iter().any(|q| (q[0] - c[0]).hypot(q[1] - c[1]) < 0.25))
        .collect();
    if unseen.is_empty() {
        return 0.0;
    }
    let mut worst = 0.0f64;
    for k in 0..lattice.len() {
        let rest: Lattice = lattice
            .iter()
            .enumerate()
            .filter(|(m, _)| *m != k)
            .map(|(_, x)| *x)
            .collect();
        let Ok(h) = fit_lattice(blobs, &rest) else {
            return f64::INFINITY;
        };
        let hc = h.then_after(&p.map);
        for c in &unseen {
            let (a, b) = (p.hc.apply(*c), hc.apply(*c));
            let step = local_step_at(&p.hc, *c);
            worst = worst.max((a[0] - b[0]).hypot(a[1] - b[1]) / step);
        }
    }
    let unsupported = unsupported_perspective(blobs, lattice, p, &unseen);
    let worst = worst.max(unsupported);
    if worst.is_finite() {
        worst
    } else {
        f64::INFINITY
    }
}

/// Below this F statistic the lattice does not show perspective: the two projective terms of
/// its homography lower the residual over an affine fit too little to trust. (For independent
/// Gaussian centroid errors, F with 2 and `2n − 8` degrees of freedom exceeds 10 by chance well
/// under one time in a thousand; the centroids' errors are neither, and a noisy SG scene fitted
/// a frontal chart's lattice of 52 at F 10.4 with perspective 1.09 where the chart's was 1.02,
/// a cell 0.26 pitch off. A tilted chart's lattice shows F in the hundreds or more.)
const PERSPECTIVE_EVIDENCE: f64 = 20.0;

/// How far, in local pitches, the homography places a cell not seen from where an affine fit of
/// the same lattice places it, when the lattice gives no evidence for perspective
/// ([`PERSPECTIVE_EVIDENCE`]); 0 when it does. A lattice of a frontal chart that leaves a corner
/// unseen (the SpyderCHECKR's black, grey 35 and blue share one) fits projective terms to
/// the noise of its centroids, and the fit swings the far corner out: seen in `--family noisy`,
/// a lattice of 12 fitted with perspective 1.19 where the chart's was 1.01, a cell 0.29 pitch
/// off, while dropping any one point moved it only 0.08 (the jackknife of [`extrapolation`]
/// sees a swing that every point shares only in part).
fn unsupported_perspective(
    blobs: &[Blob],
    lattice: &Lattice,
    p: &Placement,
    unseen: &[[f64; 2]],
) -> f64 {
    let n = lattice.len();
    if n < 5 {
        return f64::INFINITY;
    }
    let Ok(h) = fit_lattice(blobs, lattice) else {
        return f64::INFINITY;
    };
    let Some(affine) = affine_fit(blobs, lattice) else {
        return f64::INFINITY;
    };
    let rss = |f: &dyn Fn([f64; 2]) -> [f64; 2]| -> f64 {
        lattice
            .iter()
            .map(|(b, ij)| {
                let q = f([ij[0] as f64, ij[1] as f64]);
                let c = blobs[*b].c;
                (q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2)
            })
            .sum()
    };
    let rss_h = rss(&|q| h.apply(q));
    let rss_a = rss(&|q| apply_affine(&affine, q));
    let dof = (2 * n - 8) as f64;
    let f = if rss_h > 0.0 {
        ((rss_a - rss_h).max(0.0) / 2.0) / (rss_h / dof)
    } else {
        f64::INFINITY
    };
    if f >= PERSPECTIVE_EVIDENCE {
        return 0.0;
    }
    let mut worst = 0.0f64;
    for c in unseen {
        let a = p.hc.apply(*c);
        let b = apply_affine(&affine, p.map.apply(*c));
        let step = local_step_at(&p.hc, *c);
        worst = worst.max((a[0] - b[0]).hypot(a[1] - b[1]) / step);
    }
    worst
}

/// The least-squares affine map from a lattice's coordinates to its patches' centroids, as
/// `[[a, b, c], [d, e, f]]` (`x = a·i + b·j + c`); `None` when the lattice spans no area.
fn affine_fit(blobs: &[Blob], lattice: &Lattice) -> Option<[[f64; 3]; 2]> {
    use nalgebra::{Matrix3, Vector3};
    let mut m = Matrix3::<f64>::zeros();
    let mut rx = Vector3::<f64>::zeros();
    let mut ry = Vector3::<f64>::zeros();
    for (b, ij) in lattice {
        let v = Vector3::new(ij[0] as f64, ij[1] as f64, 1.0);
        m += v * v.transpose();
        rx += v * blobs[*b].c[0];
        ry += v * blobs[*b].c[1];
    }
    let inv = m.try_inverse()?;
    let (x, y) = (inv * rx, inv * ry);
    let out = [[x[0], x[1], x[2]], [y[0], y[1], y[2]]];
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

fn apply_affine(a: &[[f64; 3]; 2], q: [f64; 2]) -> [f64; 2] {
    [
        a[0][0] * q[0] + a[0][1] * q[1] + a[0][2],
        a[1][0] * q[0] + a[1][1] * q[1] + a[1][2],
    ]
}

/// The cells just around placement `p`'s window (the ring one cell outside it) that hold lattice
/// points of the chart's patch size (area within a factor 2 of the median of the points inside
/// the window: clutter and specks on a chart's frame are not), and how many cells that ring has.
fn surround(blobs: &[Blob], lattice: &Lattice, p: &Placement) -> (usize, usize) {
    let ([si, sj], [ai, aj]) = p.window;
    let mut inside: Vec<f64> = lattice
        .iter()
        .filter(|(_, ij)| in_window(ij, p.window))
        .map(|(b, _)| blobs[*b].area)
        .collect();
    let ring = (2 * (ai + aj) + 4) as usize;
    if inside.is_empty() {
        return (0, ring);
    }
    inside.sort_by(f64::total_cmp);
    let median = inside[inside.len() / 2];
    let around = ([si - 1, sj - 1], [ai + 2, aj + 2]);
    let like = lattice
        .iter()
        .filter(|(b, ij)| {
            let a = blobs[*b].area;
            in_window(ij, around)
                && !in_window(ij, p.window)
                && a >= 0.5 * median
                && a <= 2.0 * median
        })
        .count();
    (like, ring)
}

/// Step 6: the best placement if it is certain — plausible colours, decisive against the next
/// placement, not a block of a larger grid (`surround`: the best placement's [`surround`]),
/// moderate perspective, its unseen cells placed with certainty (`extrapolation`: the best
/// placement's [`extrapolation`], looked at only when it is not enclosed), inside the image —
/// with the runner-up's score and the perspective; otherwise why not.
fn judge(
    reference: &Reference,
    lattice: usize,
    scored: &[Placement],
    surround: (usize, usize),
    extrapolation: f64,
    hue_errors: &[f64],
) -> Result<(Placement, f64, f64), ChartError> {
    let kind = reference.chart;
    let nf = |m: String| ChartError::NotFound(m);
    let Some(best) = scored.first().cloned() else {
        return Err(nf(format!(
            "a grid of {lattice} patches was found, but no placement of the chart fits it"
        )));
    };
    let score = best.score;
    let runner_up = scored.get(1).map_or(f64::INFINITY, |s| s.score);
    if score > MATCH_LIMIT {
        return Err(nf(format!(
            "a grid of {lattice} patches was found, but its colours do not match reference {} (median ΔE00 {score:.1}, limit {MATCH_LIMIT})",
            reference.name
        )));
    }
    // An enclosed placement (every cell of its outer ring seen as a patch) with a decisive
    // orientation may match up to MATCH_LIMIT: the looser match then cannot come from a
    // placement shifted across a partial lattice (the failure DETECT_MATCH_LIMIT guards
    // against; a shifted window leaves cells of its ring unseen, and a lattice going on past
    // the window is refused below, SURROUND_LIMIT), only from colours the camera rendered (tone
    // curve, saturation, a strong cast).
    let loose_ok = best.enclosed && score <= ENCLOSED_AMBIGUITY_RATIO * runner_up;
    // A decisive placement (the next far worse, the hues kept) may match a little beyond
    // DETECT_MATCH_LIMIT, enclosed or not: a strongly graded photograph.
    let decisive_ok = score <= DECISIVE_MATCH_LIMIT
        && score <= DECISIVE_RATIO * runner_up
        && hues_hold(hue_errors);
    if score > DETECT_MATCH_LIMIT && !loose_ok && !decisive_ok {
        let kept = hue_errors.iter().filter(|&&e| e <= HUE_TOLERANCE).count();
        return Err(nf(format!(
            "a grid of {lattice} patches was found, but its colours match reference {} only loosely (median ΔE00 {score:.1}, next placement {runner_up:.1}{}; limit {DETECT_MATCH_LIMIT} for a found chart, or {DECISIVE_MATCH_LIMIT} with the next placement {:.1}× worse and five in six colours within {HUE_TOLERANCE}° of their hue{}): refused rather than risk a wrong placement; give the chart's corners",
            reference.name,
            if hue_errors.is_empty() {
                String::new()
            } else {
                format!("; {kept} of {} colours within {HUE_TOLERANCE}° of their hue", hue_errors.len())
            },
            1.0 / DECISIVE_RATIO,
            if best.enclosed {
                format!(", or {MATCH_LIMIT} with the chart's outer ring all seen and the next placement {:.0}× worse", 1.0 / ENCLOSED_AMBIGUITY_RATIO)
            } else {
                String::new()
            }
        )));
    }
    let (like, ring) = surround;
    if like as f64 >= SURROUND_LIMIT * ring as f64 {
        return Err(nf(format!(
            "a grid of patches matching the {} chart was found, but the grid goes on past it: {like} of the {ring} cells around it hold patches like its own (limit {:.0} %), so it is part of a larger chart (a ColorChecker Digital SG holds the classic 24 colours in its middle), not a {}",
            kind.name(),
            100.0 * SURROUND_LIMIT,
            kind.name()
        )));
    }
    let persp = perspective(kind, &best.hc);
    if !best.enclosed && extrapolation > EXTRAPOLATION_LIMIT {
        return Err(nf(format!(
            "cells of the chart's outer ring were not seen as patches, and where they lie is uncertain (one moves {extrapolation:.3} pitch when the grid is fitted without one of its patches or without the perspective it does not show, limit {EXTRAPOLATION_LIMIT}): refused rather than risk misplaced patches; give the chart's corners"
        )));
    }
    if persp > PERSPECTIVE_LIMIT {
        return Err(nf(format!(
            "the chart is seen under strong perspective (patch scale varies {persp:.3}× across it, limit {PERSPECTIVE_LIMIT}): refused rather than risk misplaced patches; shoot it more squarely or give the chart's corners"
        )));
    }
    if score > AMBIGUITY_RATIO * runner_up {
        return Err(nf(format!(
            "the chart's orientation is ambiguous (median ΔE00 {score:.2} vs {runner_up:.2} for the next placement)"
        )));
    }
    if best.outside > 0 {
        return Err(ChartError::Geometry(format!(
            "the chart is partly outside the frame ({} of {} patches)",
            best.outside,
            kind.cells()
        )));
    }
    Ok((best, runner_up, persp))
}

/// Finds the chart of `reference` in `frame`.
pub fn detect(
    frame: &Frame,
    reference: &Reference,
    opts: &DetectOptions,
) -> Result<Detection, DetectFailure> {
    let first = detect_at(frame, reference, opts, opts.max_side);
    let Err(e) = first else {
        return first;
    };
    // The first failure is the one reported: its candidates are the finer ones.
    let mut searched = vec![downsample_factor(frame, opts.max_side)];
    for side in [opts.retry_side, opts.coarse_side] {
        let f = downsample_factor(frame, side);
        if searched.contains(&f) {
            continue;
        }
        searched.push(f);
        if let Ok(d) = detect_at(frame, reference, opts, side) {
            return Ok(d);
        }
    }
    Err(e)
}

/// [`detect`] on the frame downsampled to a long side of at most `max_side`.
fn detect_at(
    frame: &Frame,
    reference: &Reference,
    opts: &DetectOptions,
    max_side: usize,
) -> Result<Detection, DetectFailure> {
    let kind = reference.chart;
    let fail = |error: ChartError, candidates: Vec<Candidate>| DetectFailure { error, candidates };
    let prep = prepare(frame, max_side).map_err(|m| fail(ChartError::NotFound(m), vec![]))?;
    let f = prep.f;
    let regions = Regions::new(
        &region_moments(&flat_mask(&prep, opts.flat_threshold)),
        kind.cells(),
        prep.ws,
        prep.hs,
    );
    let blobs = &regions.blobs;
    if blobs.len() < 6 {
        return Err(fail(
            ChartError::NotFound(format!(
                "{} patch-like regions in the frame, too few for a {} chart",
                blobs.len(),
                kind.name()
            )),
            regions.candidates(f, &[]),
        ));
    }
    let lats = lattices(blobs);
    let Some(largest) = lats.first().map(Vec::len) else {
        return Err(fail(
            ChartError::NotFound(format!(
                "{} candidate patches, but fewer than 6 of them form a grid",
                blobs.len()
            )),
            regions.candidates(f, &[]),
        ));
    };
    let small = Frame::from_data(prep.ws, prep.hs, nsrm::Layout::Rgb, prep.small).expect("sized");
    let span = kind.columns().max(kind.rows()) as i32;
    // Each lattice tried: refined, placed; the one whose best placement matches best is judged.
    let mut tried: Vec<(Lattice, Vec<Placement>)> = Vec::new();
    let mut first_err = None;
    let best_of = |t: &(Lattice, Vec<Placement>)| t.1.first().map_or(f64::INFINITY, |p| p.score);
    for (k, lat) in lats.into_iter().enumerate() {
        let extra = k >= MAX_LATTICES || (k > 0 && lat.len() * 2 < kind.cells());
        if extra {
            // Beyond the largest lattices: only when none of those matches, and only lattices
            // the colour check can judge (8 patches).
            let matched = tried.iter().map(best_of).fold(f64::INFINITY, f64::min);
            if matched <= DETECT_MATCH_LIMIT || k >= MAX_LATTICES + MAX_EXTRA_LATTICES {
                break;
            }
            if lat.len() < 8 {
                continue;
            }
        }
        match refine(blobs, lat, span) {
            Ok((lat, h_obs)) => {
                let scored = placements(&small, reference, &lat, &h_obs);
                tried.push((lat, scored));
            }
            Err(e) => {
                first_err.get_or_insert(e);
            }
        }
    }
    let Some((lattice, scored)) = tried
        .into_iter()
        .min_by(|a, b| best_of(a).total_cmp(&best_of(b)))
    else {
        let e = first_err.unwrap_or_else(|| {
            ChartError::NotFound(format!("a grid of {largest} patches could not be fitted"))
        });
        return Err(fail(e, regions.candidates(f, &[])));
    };
    // Measured before `refit_inside` drops the points outside the best placement's window.
    let around = scored
        .first()
        .map_or((0, 1), |best| surround(blobs, &lattice, best));
    let (lattice, scored) = refit_inside(blobs, lattice, scored);
    // Only a placement whose outer ring was not all seen is judged by it (the jackknife refits
    // the lattice once per point).
    let spread = match scored.first() {
        Some(best) if !best.enclosed => extrapolation(blobs, &lattice, best, kind),
        _ => 0.0,
    };
    let mut accepted = vec![false; blobs.len()];
    for (b, _) in &lattice {
        accepted[*b] = true;
    }
    let candidates = regions.candidates(f, &accepted);
    // The hues of the best placement, looked at only where the decisive rule may apply.
    let hues = match scored.first() {
        Some(best) if best.score > DETECT_MATCH_LIMIT && best.score <= DECISIVE_MATCH_LIMIT => {
            let means = cell_means(&small, kind, &best.hc, kind.patch_fraction() * 0.5);
            hue_errors(&means, reference).unwrap_or_default()
        }
        _ => Vec::new(),
    };
    match judge(reference, lattice.len(), &scored, around, spread, &hues) {
        Ok((best, runner_up, persp)) => Ok(Detection {
            homography: best.hc.scaled(f as f64),
            score: best.score,
            runner_up,
            lattice: lattice.len(),
            perspective: persp,
            mirrored: best.mirrored,
            downsample: f,
            candidates,
        }),
        Err(e) => Err(fail(e, candidates)),
    }
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
    local_step_at(h, [i as f64, j as f64])
}

/// The shorter of the two unit steps of `h` from `q`.
fn local_step_at(h: &Homography, q: [f64; 2]) -> f64 {
    let p = h.apply(q);
    let a = h.apply([q[0] + 1.0, q[1]]);
    let b = h.apply([q[0], q[1] + 1.0]);
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

#[cfg(test)]
#[path = "detect_tests.rs"]
mod tests;
