//! Reading the patches of a located chart: each patch is sampled over the central part of its
//! cell, averaged robustly and flagged when it cannot be trusted.
//!
//! * **Sampled area**: the centred square of side [`ExtractOptions::sample_fraction`] (default
//!   0.5) of the patch side — a quarter of the patch area — so blur, registration error up to a
//!   quarter of a patch and the patch edges do not count. A pixel is in when its centre maps
//!   inside that square.
//! * **Robust mean**: per channel, the mean after dropping [`ExtractOptions::trim`] (10 %) of the
//!   values at each end; the standard deviation and count are of all sampled pixels.
//! * **Flags**: `clipped` (at least 0.5 % of the sampled pixels have a channel at or above the white
//!   level: `--white-level`, else the level inferred from the frame by [`infer_white_level`]),
//!   `dark` (the brightest channel's mean below [`ExtractOptions::dark_fraction`] of the white
//!   level, or any channel's mean not positive), `nonuniform` (the means of the four quadrants of
//!   the sampled area differ from the patch mean by more than [`ExtractOptions::nonuniform`] (4 %),
//!   by more than five standard errors and, in a frame decoded from integer codes
//!   ([`Quantisation`]), by more than one code step and more than the chart's code-noise floor
//!   (three times its patches' median quadrant spread, at most six code steps: a camera JPEG's
//!   mottle and block errors; see `flag_nonuniform`): glare, dust, a finger, an edge).

use super::reference::Reference;
use super::{ChartError, ChartKind, Homography};
use nsrm::delta_e00_xyz;
use nsrm::Frame;
use nsrm::Param;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// How patches are read.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtractOptions {
    /// Side of the sampled square as a fraction of the patch side (default 0.5).
    pub sample_fraction: f64,
    /// Fraction of the sampled pixels dropped at each end per channel for the robust
    /// mean (default 0.1).
    pub trim: f64,
    /// The sensor's clipping level; `None`: inferred from the frame.
    pub white_level: Option<f64>,
    /// A patch is `dark` below this fraction of the white level (default 1e-3).
    pub dark_fraction: f64,
    /// A patch is `nonuniform` when a quadrant's mean differs from the patch mean by more
    /// than this fraction (default 0.04).
    pub nonuniform: f64,
    /// The integer encoding the frame was decoded from, if any: a quadrant must then differ by
    /// more than one code step of it to count as non-uniform (dark channels of an 8-bit JPEG
    /// are a few codes, whose steps are tens of percent of their value), and by more than the
    /// chart's code-noise floor (`flag_nonuniform`).
    pub quantisation: Option<Quantisation>,
}

/// An integer encoding that values were decoded from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantisation {
    /// The largest code (255 for 8 bits).
    pub(crate) max_code: f64,
    /// Codes are sRGB-encoded (else linear).
    pub(crate) srgb: bool,
}

impl Quantisation {
    /// The encoding a chart frame was decoded from: `None` for the linear readers' frames.
    pub fn of(read: &nsrm_io::display::ChartFrame) -> Option<Quantisation> {
        read.max_code.map(|max_code| Quantisation {
            max_code,
            srgb: read.transfer.display_referred(),
        })
    }

    /// The difference between the decoded values of the codes around the (decoded) value `v`.
    pub(crate) fn step(&self, v: f64) -> f64 {
        if self.srgb {
            use nsrm::srgb_oetf;
            use nsrm_io::display::srgb_eotf;
            let e = srgb_oetf(v.clamp(0.0, 1.0));
            srgb_eotf((e + 1.0 / self.max_code).min(1.0)) - srgb_eotf(e)
        } else {
            1.0 / self.max_code
        }
    }
}

impl ExtractOptions {
    /// Checks the options (before any frame is read, if the caller likes): a sample fraction in
    /// (0, 1] and a finite, positive white level.
    pub fn validate(&self) -> Result<(), ChartError> {
        if !(self.sample_fraction > 0.0 && self.sample_fraction <= 1.0) {
            return Err(ChartError::Invalid(
                "the sample fraction must be in (0, 1]".into(),
            ));
        }
        if let Some(w) = self.white_level {
            if !(w.is_finite() && w > 0.0) {
                return Err(ChartError::value(
                    Param::WhiteLevel,
                    format!("white level {w}: it must be a positive number"),
                ));
            }
        }
        Ok(())
    }
}

impl Default for ExtractOptions {
    fn default() -> Self {
        ExtractOptions {
            sample_fraction: 0.5,
            trim: 0.1,
            white_level: None,
            dark_fraction: 1e-3,
            nonuniform: 0.04,
            quantisation: None,
        }
    }
}

/// Why a patch is not used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Flag {
    /// A channel reaches the white level.
    Clipped,
    /// Too dark to read (see [`ExtractOptions::dark_fraction`]).
    Dark,
    /// Not evenly lit or not a uniform patch (see [`ExtractOptions::nonuniform`]).
    Nonuniform,
    /// Bright enough, but a channel is at 0 or below (clipped at black: a display-referred
    /// frame's saturated colour, e.g. a JPEG's cyan with red 0).
    #[serde(rename = "clipped-black")]
    ClippedBlack,
}

impl Flag {
    /// The flag's name in reports and CSV files (`clipped`, `dark`, `nonuniform`, …).
    pub fn name(self) -> &'static str {
        match self {
            Flag::Clipped => "clipped",
            Flag::Dark => "dark",
            Flag::Nonuniform => "nonuniform",
            Flag::ClippedBlack => "a channel clipped at 0",
        }
    }
}

/// One patch as read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatchReading {
    /// The patch label (`01 dark skin`, `A1`, …).
    pub label: String,
    /// Robust mean camera RGB (after flat-field compensation when one was applied).
    pub rgb: [f64; 3],
    /// Standard deviation of the sampled pixels, per channel.
    pub std: [f64; 3],
    /// Pixels sampled.
    pub count: usize,
    /// Why the patch is not used; empty when it is.
    pub flags: Vec<Flag>,
    /// Reference XYZ (perfect white Y = 100).
    pub xyz: [f64; 3],
    /// Centre of the sampled area in the frame (pixels).
    pub centre: [f64; 2],
    /// Corners of the sampled area in the frame (pixels).
    pub outline: [[f64; 2]; 4],
    /// Flat-field factor divided out (1 without compensation).
    pub flat: f64,
}

impl PatchReading {
    /// True when no flag is set: the patch goes into the training data.
    pub fn usable(&self) -> bool {
        self.flags.is_empty()
    }
}

/// The patches of one chart in a frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Extraction {
    /// The chart read.
    pub(crate) chart: ChartKind,
    /// Chart coordinates → frame pixels.
    pub(crate) homography: Homography,
    /// The clipping level used, if one was known or inferred.
    pub white_level: Option<f64>,
    /// Whether the white level was inferred from the frame (not given).
    pub(crate) white_level_inferred: bool,
    /// Every patch, in the chart's reading order.
    pub patches: Vec<PatchReading>,
}

impl Extraction {
    /// Labels of the flagged patches, with their flags.
    pub fn flagged(&self) -> Vec<String> {
        self.patches
            .iter()
            .filter(|p| !p.usable())
            .map(|p| {
                let f: Vec<&str> = p.flags.iter().map(|f| f.name()).collect();
                format!("{} ({})", p.label, f.join(", "))
            })
            .collect()
    }

    /// The unflagged patches as training data (`label,R,G,B,X,Y,Z`).
    pub fn training_set(&self, reference: &Reference) -> nsrm::TrainingSet {
        let ok: Vec<&PatchReading> = self.patches.iter().filter(|p| p.usable()).collect();
        nsrm::TrainingSet {
            labels: ok.iter().map(|p| p.label.clone()).collect(),
            rgb: ok.iter().map(|p| p.rgb).collect(),
            xyz: ok.iter().map(|p| p.xyz).collect(),
            white_xyz: reference.white,
            // A photographed chart has no perfect white: name a neutral patch (--white-patch).
            white_rgb: None,
            provenance: nsrm::Provenance {
                source: "capture".into(),
                reflectances: Some(reference.name.clone()),
                ..Default::default()
            },
        }
    }

    /// The CSV that `--training` reads: unflagged patches only, after two comment lines: what
    /// the file is, and `# white: X,Y,Z` — the reference's white, which its X,Y,Z are relative
    /// to (read back by [`nsrm::TrainingSet::read_measured`], exactly).
    pub(crate) fn to_csv(&self, reference: &Reference) -> String {
        let mut s = format!(
            "# nsrm chart patches: linear camera R,G,B and reference X,Y,Z ({}; perfect white Y = 100)\n{}label,R,G,B,X,Y,Z\n",
            reference.name.replace(|c: char| c.is_control(), "?"),
            nsrm::white_line(reference.white)
        );
        for p in self.patches.iter().filter(|p| p.usable()) {
            s.push_str(&format!(
                "{},{},{},{},{},{},{}\n",
                p.label, p.rgb[0], p.rgb[1], p.rgb[2], p.xyz[0], p.xyz[1], p.xyz[2]
            ));
        }
        s
    }
}

/// The clipping level of a frame: its largest value when at least 0.01 % of the pixels (and at
/// least 4) sit within 0.1 % of it — a pile-up that unclipped scenes do not have; `None`
/// otherwise.
pub(crate) fn infer_white_level(frame: &Frame) -> Option<f64> {
    let ch = frame.layout.channels();
    // Two parallel passes over the frame (the largest finite value, then the pixels near it),
    // in blocks of 64 Ki pixels.
    let block = ch << 16;
    let max = frame
        .data
        .par_chunks(block)
        .map(|b| {
            b.chunks_exact(ch).fold(f32::MIN, |m, p| {
                p[..3]
                    .iter()
                    .fold(m, |m, &v| if v.is_finite() { m.max(v) } else { m })
            })
        })
        .reduce(|| f32::MIN, f32::max);
    if !(max > 0.0) {
        return None;
    }
    let near = max * 0.999;
    let n: usize = frame
        .data
        .par_chunks(block)
        .map(|b| {
            b.chunks_exact(ch)
                .filter(|p| p[..3].iter().any(|&v| v >= near))
                .count()
        })
        .sum();
    (n >= 4 && n as f64 >= 1e-4 * frame.pixels() as f64).then_some(max as f64)
}

/// Pixel values of one sampled area, with each pixel's quadrant.
struct Samples {
    values: [Vec<f32>; 3],
    quadrant: Vec<u8>,
}

/// The pixels whose centres map (through `h`, chart → frame) into the square of side `side`
/// (chart units) centred on `centre`. Errors when the square reaches outside the frame.
fn gather(
    frame: &Frame,
    h: &Homography,
    hinv: &Homography,
    centre: [f64; 2],
    side: f64,
) -> Option<(Samples, [[f64; 2]; 4])> {
    let r = side / 2.0;
    let corners = [
        [centre[0] - r, centre[1] - r],
        [centre[0] + r, centre[1] - r],
        [centre[0] + r, centre[1] + r],
        [centre[0] - r, centre[1] + r],
    ];
    let img: Vec<[f64; 2]> = corners.iter().map(|c| h.apply(*c)).collect();
    if corners.iter().any(|c| h.w(*c) <= 0.0) {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    for p in &img {
        x0 = x0.min(p[0]);
        y0 = y0.min(p[1]);
        x1 = x1.max(p[0]);
        y1 = y1.max(p[1]);
    }
    if !(x0 >= 0.0 && y0 >= 0.0 && x1 <= frame.width as f64 && y1 <= frame.height as f64) {
        return None;
    }
    let ch = frame.layout.channels();
    let mut s = Samples {
        values: [Vec::new(), Vec::new(), Vec::new()],
        quadrant: Vec::new(),
    };
    let (xa, xb) = (x0.floor() as usize, (x1.ceil() as usize).min(frame.width));
    let (ya, yb) = (y0.floor() as usize, (y1.ceil() as usize).min(frame.height));
    for y in ya..yb {
        for x in xa..xb {
            let q = hinv.apply([x as f64 + 0.5, y as f64 + 0.5]);
            let (du, dv) = (q[0] - centre[0], q[1] - centre[1]);
            if du.abs() < r && dv.abs() < r {
                let px = &frame.data[(y * frame.width + x) * ch..][..3];
                for k in 0..3 {
                    s.values[k].push(px[k]);
                }
                s.quadrant
                    .push(u8::from(du >= 0.0) | (u8::from(dv >= 0.0) << 1));
            }
        }
    }
    let outline = [img[0], img[1], img[2], img[3]];
    Some((s, outline))
}

/// Mean of each channel over the sampled area of every cell (no trimming, no flags): for flat
/// frames and detection scoring. `None` for cells outside the frame or without pixels.
pub(crate) fn cell_means(
    frame: &Frame,
    kind: ChartKind,
    h: &Homography,
    side: f64,
) -> Vec<Option<[f64; 3]>> {
    let Some(hinv) = h.inverse() else {
        return vec![None; kind.cells()];
    };
    (0..kind.cells())
        .map(|i| {
            let (s, _) = gather(frame, h, &hinv, kind.cell_centre(i), side)?;
            let n = s.quadrant.len();
            (n > 0).then(|| {
                [0, 1, 2].map(|k| s.values[k].iter().map(|&v| v as f64).sum::<f64>() / n as f64)
            })
        })
        .collect()
}

/// Side of the sampled square in chart units.
pub(crate) fn sample_side(kind: ChartKind, opts: &ExtractOptions) -> f64 {
    kind.patch_fraction() * opts.sample_fraction
}

/// Reads every patch of the chart that `h` (chart → frame pixels) places in `frame`.
pub fn extract(
    frame: &Frame,
    reference: &Reference,
    h: &Homography,
    opts: &ExtractOptions,
) -> Result<Extraction, ChartError> {
    let kind = reference.chart;
    opts.validate()?;
    let hinv = h
        .inverse()
        .ok_or_else(|| ChartError::Geometry("the chart transform is singular".into()))?;
    let (white_level, inferred) = match opts.white_level {
        Some(w) => (Some(w), false),
        None => (infer_white_level(frame), true),
    };
    let side = sample_side(kind, opts);
    let labels = kind.labels();
    // Patches are read in parallel (each gathers its own pixels); results are taken in cell
    // order, so the first error is the same as a sequential reading's.
    let read: Vec<Option<Result<(PatchReading, Quadrants), ChartError>>> = (0..kind.cells())
        .into_par_iter()
        .map(|i| {
            read_patch(
                frame,
                h,
                &hinv,
                kind.cell_centre(i),
                side,
                &labels[i],
                reference.xyz[i],
                white_level,
                opts,
            )
        })
        .collect();
    let mut patches = Vec::with_capacity(kind.cells());
    let mut outside = Vec::new();
    let mut frame_max = 0.0f64;
    for (i, r) in read.into_iter().enumerate() {
        match r {
            None => outside.push(labels[i].clone()),
            Some(Err(e)) => return Err(e),
            Some(Ok(p)) => {
                frame_max = frame_max.max(p.0.rgb[0].max(p.0.rgb[1]).max(p.0.rgb[2]));
                patches.push(p);
            }
        }
    }
    if !outside.is_empty() {
        return Err(ChartError::Geometry(format!(
            "the chart is partly outside the frame: {} of {} patches ({}{}) are not in it",
            outside.len(),
            kind.cells(),
            outside
                .iter()
                .take(6)
                .cloned()
                .collect::<Vec<_>>()
                .join(", "),
            if outside.len() > 6 { ", …" } else { "" }
        )));
    }
    flag_nonuniform(&mut patches);
    let level = white_level.unwrap_or(frame_max);
    for (p, _) in patches.iter_mut() {
        let m = p.rgb[0].max(p.rgb[1]).max(p.rgb[2]);
        if m < opts.dark_fraction * level {
            p.flags.push(Flag::Dark);
        } else if p.rgb.iter().any(|&v| v <= 0.0) {
            p.flags.push(Flag::ClippedBlack);
        }
    }
    let patches: Vec<PatchReading> = patches.into_iter().map(|(p, _)| p).collect();
    if patches.iter().all(|p| p.flags.contains(&Flag::Clipped)) {
        return Err(ChartError::Implausible(
            "every patch is clipped: the frame is overexposed".into(),
        ));
    }
    Ok(Extraction {
        chart: kind,
        homography: *h,
        white_level,
        white_level_inferred: inferred && white_level.is_some(),
        patches,
    })
}

/// Reads the patch of the cell centred on `centre`: `None` when its sampled area is not inside
/// the frame.
#[allow(clippy::too_many_arguments)]
fn read_patch(
    frame: &Frame,
    h: &Homography,
    hinv: &Homography,
    centre: [f64; 2],
    side: f64,
    label: &str,
    xyz: [f64; 3],
    white_level: Option<f64>,
    opts: &ExtractOptions,
) -> Option<Result<(PatchReading, Quadrants), ChartError>> {
    let (s, outline) = gather(frame, h, hinv, centre, side)?;
    let n = s.quadrant.len();
    if n < 4 {
        return Some(Err(ChartError::Geometry(format!(
            "patch {label} covers {n} pixels in the frame; the chart is too small to read"
        ))));
    }
    let mut rgb = [0.0; 3];
    let mut std = [0.0; 3];
    let mut finite = true;
    let cut = ((n as f64) * opts.trim).floor() as usize;
    for k in 0..3 {
        let v = &s.values[k];
        finite &= v.iter().all(|x| x.is_finite());
        let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        std[k] = (v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        rgb[k] = trimmed_mean(v, cut);
    }
    if !finite {
        return Some(Err(ChartError::Invalid(format!(
            "patch {label}: the frame has NaN or infinite values there"
        ))));
    }
    let mut flags = Vec::new();
    if let Some(w) = white_level {
        let at = (0..n)
            .filter(|&j| (0..3).any(|k| s.values[k][j] as f64 >= w * 0.999))
            .count();
        if at as f64 >= 0.005 * n as f64 {
            flags.push(Flag::Clipped);
        }
    }
    // Non-uniformity: quadrant means against the patch mean, per channel.
    let mut qsum = [[0.0f64; 3]; 4];
    let mut qn = [0usize; 4];
    for j in 0..n {
        let q = s.quadrant[j] as usize;
        qn[q] += 1;
        for k in 0..3 {
            qsum[q][k] += s.values[k][j] as f64;
        }
    }
    // The largest quadrant deviation, in code steps of the encoding (0 without one), over all
    // quadrants and channels (`spread`), and over those past the other limits (`excess`;
    // `None`: none is, the patch is uniform).
    let (mut spread, mut excess) = (0.0f64, None::<f64>);
    for q in (0..4).filter(|&q| qn[q] >= 2) {
        for k in 0..3 {
            let m = qsum[q][k] / qn[q] as f64;
            let dev = (m - rgb[k]).abs();
            let se = std[k] / (qn[q] as f64).sqrt();
            let step = opts.quantisation.map_or(0.0, |q| q.step(rgb[k]));
            let codes = if step > 0.0 { dev / step } else { 0.0 };
            spread = spread.max(codes);
            if dev > opts.nonuniform * rgb[k].abs() && dev > 5.0 * se && dev > step {
                excess = Some(excess.map_or(codes, |e| e.max(codes)));
            }
        }
    }
    Some(Ok((
        PatchReading {
            label: label.to_string(),
            rgb,
            std,
            count: n,
            flags,
            xyz,
            centre: h.apply(centre),
            outline,
            flat: 1.0,
        },
        Quadrants { spread, excess },
    )))
}

/// How far a patch's quadrant means stray from its mean (see [`read_patch`]).
#[derive(Debug, Clone, Copy)]
struct Quadrants {
    /// The largest deviation, in code steps of the encoding decoded (0 without one).
    spread: f64,
    /// The largest deviation past the percentage, standard-error and one-step limits, in code
    /// steps; `None` when no quadrant is past them.
    excess: Option<f64>,
}

/// Sets `nonuniform` on the patches whose quadrants stray past the limits of [`read_patch`] and,
/// for a frame decoded from integer codes, by more than the chart's noise floor: [`CODE_NOISE_FACTOR`]
/// times the median spread of its patches, in code steps, at most [`CODE_NOISE_LIMIT`] steps.
/// A camera's noise reduction and a lossy encoder's block errors (a JPEG's 8×8 blocks and
/// subsampled chroma) are spatially correlated and shared by every patch of the chart, so
/// the standard error of a quadrant of a small patch understates them; glare, a speck, a finger
/// or an edge on one patch stands out from that floor, and the limit keeps a structure printed
/// on every patch (labels, texture) from raising the floor past what encoders leave.
fn flag_nonuniform(patches: &mut [(PatchReading, Quadrants)]) {
    let mut spreads: Vec<f64> = patches.iter().map(|(_, q)| q.spread).collect();
    spreads.sort_by(f64::total_cmp);
    let median = spreads.get(spreads.len() / 2).copied().unwrap_or(0.0);
    let floor = (CODE_NOISE_FACTOR * median).min(CODE_NOISE_LIMIT);
    for (p, q) in patches.iter_mut() {
        // Without an integer encoding the spreads are 0 and the other limits decide alone.
        if q.excess.is_some_and(|e| floor <= 0.0 || e > floor) {
            p.flags.push(Flag::Nonuniform);
        }
    }
}

/// How many times the chart's median quadrant spread (in code steps) a patch's must exceed to
/// be flagged `nonuniform` in a frame decoded from integer codes (see [`flag_nonuniform`]).
const CODE_NOISE_FACTOR: f64 = 3.0;

/// The most code steps of quadrant deviation counted as the encoding's noise (see
/// [`flag_nonuniform`]).
const CODE_NOISE_LIMIT: f64 = 6.0;

/// The mean of `v` without its `cut` smallest and `cut` largest values (`2 * cut < v.len()`):
/// the values are partitioned around the two cut points (linear time), not sorted.
fn trimmed_mean(v: &[f32], cut: usize) -> f64 {
    let n = v.len();
    let mut w = v.to_vec();
    if cut > 0 {
        w.select_nth_unstable_by(cut - 1, f32::total_cmp);
        let (_, rest) = w.split_at_mut(cut);
        rest.select_nth_unstable_by(n - 2 * cut, f32::total_cmp);
    }
    let kept = &w[cut..n - cut];
    kept.iter().map(|&x| x as f64).sum::<f64>() / kept.len() as f64
}

/// Least-squares 3×3 matrix taking `rgb` to `xyz` (weights `w`), or `None` when singular.
pub(crate) fn linear_fit(rgb: &[[f64; 3]], xyz: &[[f64; 3]], w: &[f64]) -> Option<[[f64; 3]; 3]> {
    use nalgebra::Matrix3;
    let mut rr = Matrix3::<f64>::zeros();
    let mut xr = Matrix3::<f64>::zeros();
    for ((r, x), &wi) in rgb.iter().zip(xyz).zip(w) {
        for a in 0..3 {
            for b in 0..3 {
                rr[(a, b)] += wi * r[a] * r[b];
                xr[(a, b)] += wi * x[a] * r[b];
            }
        }
    }
    let m = xr * rr.try_inverse()?;
    let out = [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ];
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

/// How well patch colours match a reference: the median ΔE00 after the best 3×3 linear map
/// from camera RGB to the reference XYZ (`rgb[i]` is cell `i`; `None` cells are skipped).
/// A right chart in the right orientation scores a few ΔE00; a wrong one scores far more.
pub(crate) fn match_score(rgb: &[Option<[f64; 3]>], reference: &Reference) -> Option<f64> {
    fitted(rgb, reference).map(|(score, _)| score)
}

/// [`match_score`] and the fitted colours (XYZ after the map; `None` where `rgb` is unreadable).
fn fitted(rgb: &[Option<[f64; 3]>], reference: &Reference) -> Option<(f64, Vec<Option<[f64; 3]>>)> {
    let idx: Vec<usize> = (0..rgb.len())
        .filter(|&i| rgb[i].is_some_and(|v| v.iter().all(|x| x.is_finite())))
        .collect();
    if idx.len() < 8 {
        return None;
    }
    let r: Vec<[f64; 3]> = idx.iter().map(|&i| rgb[i].expect("filtered")).collect();
    let x: Vec<[f64; 3]> = idx.iter().map(|&i| reference.xyz[i]).collect();
    let w: Vec<f64> = x.iter().map(|v| 1.0 / (v[1] + 10.0)).collect();
    let m = linear_fit(&r, &x, &w)?;
    let mut out = vec![None; rgb.len()];
    let mut de: Vec<f64> = idx
        .iter()
        .zip(&r)
        .zip(&x)
        .map(|((&i, ri), xi)| {
            let p = nsrm::apply_mat3(&m, *ri);
            let p = p.map(|v| v.max(0.0));
            out[i] = Some(p);
            delta_e00_xyz(p, *xi, reference.white)
        })
        .collect();
    de.sort_by(f64::total_cmp);
    Some((de[de.len() / 2], out))
}

/// Reference cells at least this chromatic (CIELAB chroma) have their hue checked by
/// [`hue_order`]; the CC24's colours have chroma 14–80 (16 of its 18 colours above 20), its greys
/// below 1.
pub(crate) const HUE_CHROMA: f64 = 20.0;

/// How a placement's colours keep the reference's hues, after the fit that [`chart_score`]
/// judges by (the better of the linear map and the map through the grey ramp): for every cell
/// of reference chroma at least [`HUE_CHROMA`] that was read, the difference between the
/// fitted and the reference CIELAB hue angle, in degrees (largest first). A tone curve and a
/// saturation gain move colours along their hue; colours placed in the wrong cells land at
/// unrelated hues. `None` when no fit was possible.
pub(crate) fn hue_errors(rgb: &[Option<[f64; 3]>], reference: &Reference) -> Option<Vec<f64>> {
    let lin = fitted(rgb, reference);
    let tone = linearise(rgb, reference).and_then(|l| fitted(&l, reference));
    let (_, xyz) = match (lin, tone) {
        (Some(a), Some(b)) => {
            if b.0 < a.0 {
                b
            } else {
                a
            }
        }
        (a, b) => a.or(b)?,
    };
    let hue = |lab: [f64; 3]| lab[2].atan2(lab[1]).to_degrees();
    let mut errs: Vec<f64> = xyz
        .iter()
        .zip(&reference.xyz)
        .filter_map(|(p, r)| {
            let p = (*p)?;
            let lr = nsrm::xyz_to_lab(*r, reference.white);
            if lr[1].hypot(lr[2]) < HUE_CHROMA {
                return None;
            }
            let lp = nsrm::xyz_to_lab(p, reference.white);
            let d = (hue(lp) - hue(lr)).rem_euclid(360.0);
            Some(d.min(360.0 - d))
        })
        .collect();
    errs.sort_by(|a, b| b.total_cmp(a));
    Some(errs)
}

/// The median ΔE00 above which patch colours are taken not to match the reference.
pub(crate) const MATCH_LIMIT: f64 = 8.0;

/// Reference patches this close to neutral (CIELAB chroma) form the grey ramp that
/// [`tone_score`] linearises through: the CC24's bottom row (chroma ≤ 1), the SG's greys.
pub(crate) const NEUTRAL_CHROMA: f64 = 4.0;

/// Two neutral patches whose reference luminances differ by more than this factor must keep
/// their order in every channel (a tone curve is monotone); CC24's neighbouring greys differ
/// by 1.5× to 2.9×.
pub(crate) const RAMP_ORDER_RATIO: f64 = 1.25;

/// How well patch colours seen through an unknown camera tone curve match a reference: the
/// per-channel curve is estimated from the chart's own grey ramp (the neutral patches,
/// [`NEUTRAL_CHROMA`], in the order of their reference luminance: isotonic regression of
/// luminance on the channel value, interpolated piecewise linearly), the linearised values are
/// mapped by the best 3×3 matrix and scored by the median ΔE00 as in [`match_score`].
///
/// `None` when the ramp has fewer than four readable greys, or when it is out of order: two
/// greys whose reference luminances differ by more than [`RAMP_ORDER_RATIO`] swap order in a
/// channel by more than 1 % of the ramp's range — no tone curve does that, so such a placement
/// is not this chart (or the greys are glared) and only the linear [`match_score`] may judge it.
pub(crate) fn tone_score(rgb: &[Option<[f64; 3]>], reference: &Reference) -> Option<f64> {
    let lin = linearise(rgb, reference)?;
    match_score(&lin, reference)
}

/// The colour check used for found charts and `verify`: the better of the linear
/// [`match_score`] and the tone-tolerant [`tone_score`].
pub(crate) fn chart_score(rgb: &[Option<[f64; 3]>], reference: &Reference) -> Option<f64> {
    match (match_score(rgb, reference), tone_score(rgb, reference)) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The values of `rgb` through per-channel curves fitted to the chart's grey ramp (see
/// [`tone_score`]); `None` when the ramp cannot be used.
pub(crate) fn linearise(
    rgb: &[Option<[f64; 3]>],
    reference: &Reference,
) -> Option<Vec<Option<[f64; 3]>>> {
    let greys: Vec<(f64, [f64; 3])> = (0..rgb.len().min(reference.xyz.len()))
        .filter_map(|i| {
            let x = reference.xyz[i];
            let lab = nsrm::xyz_to_lab(x, reference.white);
            let v = rgb[i]?;
            (lab[1].hypot(lab[2]) < NEUTRAL_CHROMA && v.iter().all(|c| c.is_finite()))
                .then_some((x[1], v))
        })
        .collect();
    if greys.len() < 4 {
        return None;
    }
    let mut curves: Vec<Vec<(f64, f64)>> = Vec::with_capacity(3);
    for k in 0..3 {
        let lo = greys.iter().map(|g| g.1[k]).fold(f64::INFINITY, f64::min);
        let hi = greys
            .iter()
            .map(|g| g.1[k])
            .fold(f64::NEG_INFINITY, f64::max);
        if !(hi > lo && hi > 0.0) {
            return None;
        }
        let tol = 0.01 * (hi - lo);
        for a in &greys {
            for b in &greys {
                if b.0 > RAMP_ORDER_RATIO * a.0 && a.1[k] > b.1[k] + tol {
                    return None;
                }
            }
        }
        // Isotonic regression (pool adjacent violators) of luminance on the channel value.
        let mut pts: Vec<(f64, f64)> = greys.iter().map(|g| (g.1[k], g.0)).collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut blocks: Vec<(f64, f64, f64)> = Vec::new(); // (sum x, sum y, n)
        for (x, y) in pts {
            blocks.push((x, y, 1.0));
            while blocks.len() > 1 {
                let n = blocks.len();
                let (a, b) = (blocks[n - 2], blocks[n - 1]);
                if a.1 / a.2 >= b.1 / b.2 {
                    blocks.pop();
                    blocks[n - 2] = (a.0 + b.0, a.1 + b.1, a.2 + b.2);
                } else {
                    break;
                }
            }
        }
        let curve: Vec<(f64, f64)> = blocks.iter().map(|b| (b.0 / b.2, b.1 / b.2)).collect();
        if curve.len() < 2 {
            return None;
        }
        curves.push(curve);
    }
    let seg = |a: (f64, f64), b: (f64, f64), x: f64| -> f64 {
        if b.0 > a.0 {
            a.1 + (x - a.0) * (b.1 - a.1) / (b.0 - a.0)
        } else {
            a.1
        }
    };
    let eval = |c: &[(f64, f64)], x: f64| -> f64 {
        let n = c.len();
        // Below the darkest grey: towards (0, 0) when the darkest grey is above zero.
        if x <= c[0].0 {
            return if c[0].0 > 0.0 && x >= 0.0 {
                c[0].1 * x / c[0].0
            } else {
                seg(c[0], c[1], x)
            };
        }
        let j = c.partition_point(|p| p.0 < x).clamp(1, n - 1);
        seg(c[j - 1], c[j], x)
    };
    Some(
        rgb.iter()
            .map(|v| v.map(|v| [0, 1, 2].map(|k| eval(&curves[k], v[k]))))
            .collect(),
    )
}

/// Checks that the usable patches match the reference (the better of a linear fit and a
/// tone-tolerant fit to it); the median ΔE00.
pub fn verify(ex: &Extraction, reference: &Reference) -> Result<f64, ChartError> {
    let rgb: Vec<Option<[f64; 3]>> = ex
        .patches
        .iter()
        .map(|p| p.usable().then_some(p.rgb))
        .collect();
    let usable = rgb.iter().filter(|v| v.is_some()).count();
    if usable < 8 {
        return Err(ChartError::Implausible(format!(
            "only {usable} of {} patches are usable (the others are clipped, too dark or non-uniform)",
            ex.patches.len()
        )));
    }
    let score = chart_score(&rgb, reference).ok_or_else(|| {
        ChartError::Implausible("the patch colours are degenerate (all alike?)".into())
    })?;
    if score > MATCH_LIMIT {
        return Err(ChartError::Implausible(format!(
            "the patch colours do not match reference {} (median ΔE00 {score:.1} after the best linear map, limit {MATCH_LIMIT}): wrong chart, corners in the wrong order, or not a chart",
            reference.name
        )));
    }
    Ok(score)
}
