//! DNG Camera Profiles (DCP): a writer, a reader, and an evaluator of the DNG profile pipeline
//! written from the specification (DNG 1.4, chapter 6), which `export` measures its DCP with.
//!
//! Why one file (about 1,700 lines, 260 of them tests; two `#[ignore]` diagnostics are in
//! `dcp_diag.rs`): the DCP writer, its TIFF container, the reader and the evaluator of the DNG
//! pipeline are one round trip: the export measures the profile it writes by reading it back and
//! running the DNG pipeline on it, and the tests pin the three together.
//!
//! # What is written
//! For each calibration illuminant `i` (one or two) of a model set
//! ([`Profile`]), with `w_i` the camera response the model
//! maps to its white `W_i`, the target is the model in white-balanced camera coordinates, adapted
//! to D50: `T_i(b) = Bradford(W_i → D50) · model_i(diag(w_i)·b) / Y(W_i)`, so `T_i(1, 1, 1) = D50`.
//! - **ForwardMatrix** `F_i`: the least-squares 3×3 of `T_i` over the training patches, with
//!   `F_i·(1, 1, 1) = D50` exactly (RawTherapee does not normalise it; the rationals are written
//!   with one entry per row adjusted so the row sums are D50's to 1e-6).
//! - **ProfileHueSatMap** `H_i` (hue × saturation × 1 value division): for each node `(h, s)` of
//!   linear ProPhoto RGB as HSV (at `v = 1`), the hue shift, saturation scale and value scale that
//!   take `F_i·b` to `T_i(b)`. `T_i` is exposure-invariant (NSRM, RPRM, LRM), so the map with one
//!   value division carries it exactly along the value axis; what remains is the grid and its
//!   bilinear interpolation. Nodes no camera colour reaches (a white-balanced camera channel below
//!   zero, or a model output that is not finite) are filled smoothly from their neighbours
//!   (harmonic fill), so the table is finite and smooth everywhere. Saturation 0 has
//!   `(0, 1, 1)`.
//! - **ColorMatrix** `C_i` (XYZ → camera, for the white-balance temperature only):
//!   `diag(w_i)·F_i⁻¹·Bradford(W_i → D50)`, which sends `W_i` to `w_i` exactly, normalised as the
//!   DNG SDK normalises (max of `C_i·D50` = 1).
//! - A linear ProfileToneCurve, no look table, ProfileEmbedPolicy "allow copying", names and
//!   copyright from the model's provenance.
//! - Two illuminants: a DCP interpolates between the temperatures of the lights it names
//!   (Standard light A = 2850 K, D65 = 6500 K), the model set between its own calibration
//!   temperatures (e.g. 2863 K and 6503 K). So each side carries the set extrapolated to its
//!   named light: the targets, ForwardMatrices and ColorMatrices of the two models mixed with the
//!   set's (unclamped, affine in 1/T) weights at that temperature; the DCP's interpolation then
//!   gives the set's weights in between (measured, D5100 LRM A + D65 at 3975 K: 0.061 → 0.0001
//!   max ΔE00).
//!
//! # What remains (measured; `cargo test --lib diag_dual -- --ignored --nocapture`)
//! - Colours outside ProPhoto after the ForwardMatrix: the DNG map works in ProPhoto HSV and
//!   clamps saturation at 1, so a colour with a negative ProPhoto channel is moved. One of 6196
//!   dense chromaticities at the StdA white of the D5100 set: 1.11 ΔE00 (LRM), 2.32 (NSRM 3);
//!   every other LRM sample ≤ 0.0001.
//! - NSRM's StdA side: 1.64 max ΔE00 inside ProPhoto at 600×55 (the D65 side: 0.12).
//! - Between the lights the DCP mixes map entries where the set mixes outputs: NSRM 3 at 3975 K,
//!   0.65 max.
//!
//! PRM is refused (not exposure-invariant: a map with one value division cannot carry it).

use super::ExportError;
use crate::spaces::{self, Mat3};
use crate::temperature::{self, D50_XY};
use nsrm::Kind;
use nsrm::{Calibration, Combination, FrameWhite, Profile};

/// Hue divisions (the map's hue axis, 0..360°) and saturation divisions (0..1) of the default map.
/// The error is mostly along hue (the HSV hue has kinks where the output crosses a sextant, so
/// bilinear interpolation converges only linearly there): on the D5100 NSRM 3 the dense-set
/// maximum is 0.56 ΔE00 at 90×30, 0.24 at 360×92, 0.16 at 480×69 and 0.11 at 600×55. 600×55×3 =
/// 99000 values stays under the 100000 per tag that exiftool lists without a warning.
pub(crate) const DEFAULT_HUE_DIVISIONS: usize = 600;
pub(crate) const DEFAULT_SAT_DIVISIONS: usize = 55;
/// Bounds on the map's divisions (the table is read into memory by readers).
pub(crate) const MAX_HUE_DIVISIONS: usize = 720;
pub(crate) const MAX_SAT_DIVISIONS: usize = 256;

/// The DNG `PCStoXYZ`: D50 at `Y = 1` from its chromaticity (0.3457, 0.3585).
pub(crate) fn d50() -> [f64; 3] {
    spaces::xy_to_xyz(D50_XY)
}

/// Linear ProPhoto (ROMM) RGB → XYZ (D50 white, `Y = 1`).
pub(crate) fn prophoto_to_xyz() -> Mat3 {
    spaces::rgb_to_xyz(
        [[0.7347, 0.2653], [0.1596, 0.8404], [0.0366, 0.0001]],
        D50_XY,
    )
}

/// EXIF LightSource values a DCP can name, with the temperature DNG readers give them (the DNG
/// SDK's `IlluminantToTemperature`, which RawTherapee copies).
pub(crate) const LIGHT_SOURCES: [(u16, &str, f64); 6] = [
    (17, "Standard light A", 2850.0),
    (24, "ISO studio tungsten", 3200.0),
    (23, "D50", 5000.0),
    (20, "D55", 5500.0),
    (21, "D65", 6500.0),
    (22, "D75", 7500.0),
];

/// How far (in mired) a model's calibration temperature may be from the light source that names
/// it in the DCP.
pub(crate) const NAME_TOLERANCE_MIRED: f64 = 6.0;

/// The light source naming a calibration temperature, or an error for one no DCP can name.
pub(crate) fn light_source_for(cct: f64) -> Result<(u16, &'static str, f64), ExportError> {
    let best = LIGHT_SOURCES
        .iter()
        .min_by(|a, b| {
            (1e6 / a.2 - 1e6 / cct)
                .abs()
                .total_cmp(&(1e6 / b.2 - 1e6 / cct).abs())
        })
        .copied()
        .expect("the table is not empty");
    if (1e6 / best.2 - 1e6 / cct).abs() > NAME_TOLERANCE_MIRED {
        return Err(ExportError::Usage(format!(
            "the calibration illuminant at {cct:.0} K is not one a DCP can name (Standard light A 2850 K, ISO studio tungsten 3200 K, D50, D55, D65, D75, each within {NAME_TOLERANCE_MIRED} mired): fit under one of those"
        )));
    }
    Ok(best)
}

/// EXIF LightSource "Other" (DNG 1.6): the light is given by its IlluminantData tag.
pub(crate) const OTHER_LIGHT: u16 = 255;

/// The light a calibration is named by in the DCP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NamedLight {
    /// EXIF LightSource (CalibrationIlluminant).
    pub code: u16,
    /// The chromaticity written as IlluminantData (for [`OTHER_LIGHT`] only).
    pub xy: Option<[f64; 2]>,
    /// The temperature a DNG reader gives it (K).
    pub cct: f64,
}

/// The light a single model fitted on a chart capture was shot under (its provenance's
/// estimate from the chart's neutrals), when its reference was not adapted to a named light.
fn captured_light(profile: &Profile) -> Option<([f64; 2], f64)> {
    if profile.is_dual() {
        return None;
    }
    let p = profile.models()[0].provenance();
    let c = p.capture.as_ref()?;
    match (p.illuminant.as_ref(), c.light_xy, c.light_cct) {
        (None, Some(xy), Some(t)) if t.is_finite() && t > 0.0 => Some((xy, t)),
        _ => None,
    }
}

/// The light naming calibration `cal`: the capture's light for a model fitted on a chart shot
/// (else the model's own white); a standard light source when within
/// [`NAME_TOLERANCE_MIRED`] of one, else DNG 1.6's Other with its chromaticity.
fn calibration_light(profile: &Profile, cal: &Calibration) -> NamedLight {
    let (xy, cct) = captured_light(profile).unwrap_or((cal.xy, cal.cct));
    match light_source_for(cct) {
        Ok((code, _, named)) => NamedLight {
            code,
            xy: None,
            cct: named,
        },
        Err(_) => NamedLight {
            code: OTHER_LIGHT,
            xy: Some(xy),
            cct,
        },
    }
}

impl NamedLight {
    /// How messages name the light, as the file names it: `Standard light A (2850 K)`, or
    /// `Other: 2763 K, x 0.4512 y 0.4088 (IlluminantData)`.
    pub(crate) fn describe(&self) -> String {
        match (self.code, self.xy) {
            (OTHER_LIGHT, Some(xy)) => format!(
                "Other: {:.0} K, x {:.4} y {:.4} (IlluminantData)",
                self.cct, xy[0], xy[1]
            ),
            (code, _) => match LIGHT_SOURCES.iter().find(|l| l.0 == code) {
                Some(l) => format!("{} ({:.0} K)", l.1, l.2),
                None => format!("light source {code} ({:.0} K)", self.cct),
            },
        }
    }
}

/// One entry of a hue/saturation map: hue shift (degrees), saturation scale, value scale.
pub(crate) type HsmEntry = [f32; 3];

/// One calibration illuminant of a DCP, as written.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DcpSide {
    /// EXIF LightSource.
    pub illuminant: u16,
    /// The light's chromaticity, written as IlluminantData when `illuminant` is Other.
    pub illuminant_xy: Option<[f64; 2]>,
    /// ColorMatrix: XYZ → camera RGB (DNG convention).
    pub color_matrix: Mat3,
    /// ForwardMatrix: white-balanced camera RGB → XYZ D50.
    pub forward_matrix: Mat3,
    /// `hue_divisions × sat_divisions` entries, hue outer, saturation inner.
    pub hue_sat_map: Vec<HsmEntry>,
}

/// A DNG Camera Profile.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Dcp {
    /// UniqueCameraModel: the camera the profile is for.
    pub unique_camera_model: String,
    /// ProfileName.
    pub profile_name: String,
    /// ProfileCopyright.
    pub copyright: String,
    /// Hue divisions of the hue/saturation maps.
    pub hue_divisions: usize,
    /// Saturation divisions of the hue/saturation maps.
    pub sat_divisions: usize,
    /// One or two sides (two: ordered by temperature, as CalibrationIlluminant1/2).
    pub sides: Vec<DcpSide>,
    /// The ProfileToneCurve (x, y pairs); linear.
    pub tone_curve: Vec<[f32; 2]>,
}

/// The map's size.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcpOptions {
    /// Hue divisions (default 600).
    pub hue_divisions: usize,
    /// Saturation divisions (default 55).
    pub sat_divisions: usize,
}

impl Default for DcpOptions {
    fn default() -> Self {
        DcpOptions {
            hue_divisions: DEFAULT_HUE_DIVISIONS,
            sat_divisions: DEFAULT_SAT_DIVISIONS,
        }
    }
}

impl DcpOptions {
    /// Checks the options are in range (hue and saturation divisions), before any work.
    pub fn check(&self) -> Result<(), ExportError> {
        if !(6..=MAX_HUE_DIVISIONS).contains(&self.hue_divisions)
            || !(2..=MAX_SAT_DIVISIONS).contains(&self.sat_divisions)
        {
            return Err(ExportError::Usage(format!(
                "hue/saturation map {}×{} is out of range (hue 6..={MAX_HUE_DIVISIONS}, saturation 2..={MAX_SAT_DIVISIONS})",
                self.hue_divisions, self.sat_divisions
            )));
        }
        Ok(())
    }
}

/// The DNG SDK's RGB → HSV (`h` in `[0, 6)`, `v` = max).
pub(crate) fn rgb_to_hsv(c: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = c;
    let v = r.max(g).max(b);
    let gap = v - r.min(g).min(b);
    if gap > 0.0 {
        let mut h = if r == v {
            let h = (g - b) / gap;
            if h < 0.0 {
                h + 6.0
            } else {
                h
            }
        } else if g == v {
            2.0 + (b - r) / gap
        } else {
            4.0 + (r - g) / gap
        };
        if h >= 6.0 {
            h -= 6.0;
        }
        [h, gap / v, v]
    } else {
        [0.0, 0.0, v]
    }
}

/// The DNG SDK's HSV → RGB.
pub(crate) fn hsv_to_rgb(hsv: [f64; 3]) -> [f64; 3] {
    let [mut h, s, v] = hsv;
    if s > 0.0 {
        h = h.rem_euclid(6.0);
        let i = h.floor();
        let f = h - i;
        let p = v * (1.0 - s);
        let q = v * (1.0 - s * f);
        let t = v * (1.0 - s * (1.0 - f));
        match i as i32 {
            0 => [v, t, p],
            1 => [q, v, p],
            2 => [p, v, t],
            3 => [p, q, v],
            4 => [t, p, v],
            _ => [v, p, q],
        }
    } else {
        [v, v, v]
    }
}

/// Applies a hue/saturation map with one value division to linear ProPhoto RGB, as the DNG SDK's
/// `RefBaselineHueSatMap` does (bilinear in hue, wrapping, and saturation; `s` clipped at 1), the
/// entries given by index (`hue * sat_div + sat`), e.g. two maps mixed on the fly.
pub(crate) fn apply_hue_sat_map_with(
    entry: impl Fn(usize) -> [f64; 3],
    hue_div: usize,
    sat_div: usize,
    rgb: [f64; 3],
) -> [f64; 3] {
    let [h, s, v] = rgb_to_hsv(rgb);
    let h_scale = if hue_div < 2 {
        0.0
    } else {
        hue_div as f64 / 6.0
    };
    let s_scale = (sat_div - 1) as f64;
    let hs = h * h_scale;
    let ss = s * s_scale;
    let mut h0 = hs as usize;
    let s0 = (ss as usize).min(sat_div - 2);
    let mut h1 = h0 + 1;
    if h0 >= hue_div - 1 {
        h0 = hue_div - 1;
        h1 = 0;
    }
    let hf1 = hs - h0 as f64;
    let sf1 = ss - s0 as f64;
    let (hf0, sf0) = (1.0 - hf1, 1.0 - sf1);
    let e = |hi: usize, si: usize| entry(hi * sat_div + si);
    let (e00, e01, e10, e11) = (e(h0, s0), e(h1, s0), e(h0, s0 + 1), e(h1, s0 + 1));
    let mut out = [0.0; 3];
    for k in 0..3 {
        let a = hf0 * e00[k] + hf1 * e01[k];
        let b = hf0 * e10[k] + hf1 * e11[k];
        out[k] = sf0 * a + sf1 * b;
    }
    let hn = h + out[0] * (6.0 / 360.0);
    let sn = (s * out[1]).min(1.0);
    let vn = v * out[2];
    hsv_to_rgb([hn, sn, vn])
}

/// The white-balanced target of one model, adapted to D50 at `Y = 1`.
#[derive(Clone, Copy)]
struct Target<'a> {
    part: &'a nsrm::Model,
    /// Bradford(W → D50) / Y(W).
    adapt: Mat3,
    white_rgb: [f64; 3],
}

impl Target<'_> {
    fn eval(&self, b: [f64; 3]) -> [f64; 3] {
        let c = [0, 1, 2].map(|k| b[k] * self.white_rgb[k]);
        spaces::apply(&self.adapt, self.part.apply_f64(c))
    }
}

/// What one side of the DCP carries: the models' white-balanced targets mixed with the weights
/// the model set has at that side's named light (affine in 1/T, not clamped: a side named
/// "Standard light A" (2850 K) of a set calibrated at 2863 K and 6503 K is the set extrapolated
/// to 2850 K), so that the DCP's own interpolation between its named lights reproduces the set's
/// between its calibration temperatures.
struct Mix<'a> {
    parts: Vec<(f64, Target<'a>)>,
}

impl Mix<'_> {
    fn eval(&self, b: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (w, t) in &self.parts {
            let y = t.eval(b);
            for k in 0..3 {
                out[k] += w * y[k];
            }
        }
        out
    }
}

/// `F` with `F·(1, 1, 1) = d50` minimising `Σ |T(b) − F·b|²` over `bs`.
fn constrained_forward_matrix(bs: &[[f64; 3]], ts: &[[f64; 3]], d50: [f64; 3]) -> Mat3 {
    let mut f = [[0.0; 3]; 3];
    for k in 0..3 {
        // f3 = d − f1 − f2: regress y − d·b3 on (b1 − b3, b2 − b3).
        let (mut a11, mut a12, mut a22, mut r1, mut r2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (b, t) in bs.iter().zip(ts) {
            let (x1, x2) = (b[0] - b[2], b[1] - b[2]);
            let y = t[k] - d50[k] * b[2];
            a11 += x1 * x1;
            a12 += x1 * x2;
            a22 += x2 * x2;
            r1 += x1 * y;
            r2 += x2 * y;
        }
        let det = a11 * a22 - a12 * a12;
        let (f1, f2) = if det.abs() > 1e-300 {
            ((r1 * a22 - r2 * a12) / det, (a11 * r2 - a12 * r1) / det)
        } else {
            (d50[k] / 3.0, d50[k] / 3.0)
        };
        f[k] = [f1, f2, d50[k] - f1 - f2];
    }
    f
}

/// A matrix as the signed rationals a DCP stores (denominator 10⁶), decoded back; with
/// `row_sums`, one entry of each row (its largest) is adjusted so the row sums to it.
fn quantise(m: &Mat3, row_sums: Option<[f64; 3]>) -> Mat3 {
    let mut out = [[0.0; 3]; 3];
    for i in 0..3 {
        let mut n = m[i].map(|v| (v * 1e6).round());
        if let Some(s) = row_sums {
            let want = (s[i] * 1e6).round();
            let j = (0..3)
                .max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs()))
                .unwrap_or(0);
            n[j] += want - (n[0] + n[1] + n[2]);
        }
        out[i] = n.map(|v| v / 1e6);
    }
    out
}

/// Builds one side's map: for each node, the shift/scales that take `F·b` to `T(b)`.
fn hue_sat_map(target: &Mix, f: &Mat3, opts: DcpOptions) -> Vec<HsmEntry> {
    let (hd, sd) = (opts.hue_divisions, opts.sat_divisions);
    let pp = prophoto_to_xyz();
    let pp_inv = spaces::invert(&pp);
    let to_b = spaces::mul(&spaces::invert(f), &pp);
    let mut vals = vec![[0.0f64, 1.0, 1.0]; hd * sd];
    let mut known = vec![false; hd * sd];
    for hi in 0..hd {
        for si in 0..sd {
            let idx = hi * sd + si;
            if si == 0 {
                known[idx] = true;
                continue;
            }
            let (h, s) = (hi as f64 * 6.0 / hd as f64, si as f64 / (sd - 1) as f64);
            let rgb = hsv_to_rgb([h, s, 1.0]);
            let b = spaces::apply(&to_b, rgb);
            if b.iter().any(|v| v.is_nan() || *v < 0.0) {
                continue;
            }
            let out = spaces::apply(&pp_inv, target.eval(b));
            if !out.iter().all(|v| v.is_finite()) {
                continue;
            }
            let o = rgb_to_hsv(out);
            if !(o[2] > 0.0 && o[1].is_finite()) {
                continue;
            }
            let mut dh = o[0] - h;
            if dh > 3.0 {
                dh -= 6.0;
            } else if dh < -3.0 {
                dh += 6.0;
            }
            vals[idx] = [dh * 60.0, o[1] / s, o[2]];
            known[idx] = true;
        }
    }
    harmonic_fill(&mut vals, &known, hd, sd);
    vals.iter().map(|v| v.map(|x| x as f32)).collect()
}

/// Fills the unknown nodes with the discrete harmonic interpolant of the known ones (hue wraps,
/// the last saturation reflects): smooth, finite, bounded by the known values.
fn harmonic_fill(vals: &mut [[f64; 3]], known: &[bool], hd: usize, sd: usize) {
    if known.iter().all(|k| *k) {
        return;
    }
    // Start from the mean of the known nodes.
    let mut mean = [0.0f64; 3];
    let mut n = 0.0f64;
    for (v, k) in vals.iter().zip(known) {
        if *k {
            for c in 0..3 {
                mean[c] += v[c];
            }
            n += 1.0;
        }
    }
    for c in 0..3 {
        mean[c] /= n.max(1.0);
    }
    for (v, k) in vals.iter_mut().zip(known) {
        if !*k {
            *v = mean;
        }
    }
    for _ in 0..4000 {
        let mut change = 0.0f64;
        for hi in 0..hd {
            for si in 1..sd {
                let idx = hi * sd + si;
                if known[idx] {
                    continue;
                }
                let hp = ((hi + 1) % hd) * sd + si;
                let hm = ((hi + hd - 1) % hd) * sd + si;
                let sm = hi * sd + si - 1;
                let sp = if si + 1 < sd { idx + 1 } else { sm };
                let mut new = [0.0; 3];
                for c in 0..3 {
                    new[c] = 0.25 * (vals[hp][c] + vals[hm][c] + vals[sm][c] + vals[sp][c]);
                    change = change.max((new[c] - vals[idx][c]).abs());
                }
                vals[idx] = new;
            }
        }
        if change < 1e-7 {
            break;
        }
    }
}

/// Builds the DCP of a model set.
///
/// `training[i]` holds model `i`'s training patches (camera RGB under its illuminant); one set
/// serves both models of a pair when only one is given. The steps: each model's target and own
/// matrices (`targets`, `matrices`), then per calibration a side (`side`) at the weights
/// of its named light (`mix_weights`), then the names (`profile_names`).
pub(crate) fn build(
    profile: &Profile,
    training: &[&[[f64; 3]]],
    opts: DcpOptions,
) -> Result<Dcp, ExportError> {
    opts.check()?;
    let kind = profile.models()[0].kind();
    if kind == Kind::Prm {
        return Err(ExportError::Usage(
            "a PRM is not exposure-invariant, so a DCP's hue/saturation map with one value division cannot carry it: export an NSRM, RPRM or LRM".into(),
        ));
    }
    if training.is_empty() || training.iter().any(|t| t.len() < 3) {
        return Err(ExportError::Usage(
            "the DCP's ForwardMatrix is fitted on the training patches' camera RGB".into(),
        ));
    }
    let targets = targets(profile);
    // Each model's colour matrix (XYZ → camera, for the white-balance temperature only):
    // `diag(w_i)·F_i⁻¹·Bradford(W_i → D50)` with its own ForwardMatrix, which sends `W_i` to
    // `w_i` exactly; normalised as the DNG SDK normalises (max of `C_i·D50` = 1).
    let mut forward = Vec::new();
    let mut colour = Vec::new();
    for (i, (t, cal)) in targets.iter().zip(profile.calibrations()).enumerate() {
        let training_rgb = training[i.min(training.len() - 1)];
        let one = Mix {
            parts: vec![(1.0, *t)],
        };
        // A chart capture's ColorMatrix sends the light it was shot under to its neutral.
        let light_white = captured_light(profile).map_or(t.part.white_xyz(), |(xy, _)| {
            spaces::xy_to_xyz(xy).map(|v| v * t.part.white_xyz()[1])
        });
        let (fm, cm) = matrices(&one, training_rgb, cal.white_rgb, light_white)?;
        forward.push(fm);
        colour.push(cm);
    }
    let mut sides = Vec::new();
    for (i, cal) in profile.calibrations().iter().enumerate() {
        let training_rgb = training[i.min(training.len() - 1)];
        let own = Own {
            forward: &forward,
            colour: &colour,
        };
        sides.push(side(profile, &targets, own, cal, training_rgb, opts)?);
    }
    if sides.len() == 2 && sides[0].illuminant == sides[1].illuminant {
        return Err(ExportError::Usage(format!(
            "both calibration illuminants are named {} in a DCP: they must be different lights",
            sides[0].illuminant
        )));
    }
    let (camera, name, copyright) = profile_names(profile);
    Ok(Dcp {
        unique_camera_model: camera,
        profile_name: ascii(&name),
        copyright: ascii(&copyright),
        hue_divisions: opts.hue_divisions,
        sat_divisions: opts.sat_divisions,
        sides,
        tone_curve: vec![[0.0, 0.0], [1.0, 1.0]],
    })
}

/// Each model's white-balanced target, adapted to D50 at `Y = 1`.
fn targets(profile: &Profile) -> Vec<Target<'_>> {
    let d50 = d50();
    profile
        .models()
        .iter()
        .zip(profile.calibrations())
        .map(|(m, cal)| {
            let w = m.white_xyz();
            Target {
                part: m,
                adapt: temperature::bradford_between(w, d50).map(|r| r.map(|v| v / w[1])),
                white_rgb: cal.white_rgb,
            }
        })
        .collect()
}

/// The models' weights at a light of temperature `named` (K): affine in 1/T through the set's
/// calibration temperatures, not clamped (see [`Mix`]); `[1]` for one model.
fn mix_weights(profile: &Profile, named: f64) -> Vec<f64> {
    if profile.is_dual() {
        let [t1, t2] = profile.temperatures();
        let a = (1.0 / named - 1.0 / t2) / (1.0 / t1 - 1.0 / t2);
        vec![a, 1.0 - a]
    } else {
        vec![1.0]
    }
}

/// Each model's own ForwardMatrix and ColorMatrix.
#[derive(Clone, Copy)]
struct Own<'a> {
    forward: &'a [Mat3],
    colour: &'a [Mat3],
}

/// The DCP side of calibration `cal`: its named light, the models' matrices mixed at that
/// light's weights (the ForwardMatrix refitted on the mixed target over `training_rgb` for a
/// pair), quantised, and the hue/saturation map of the mixed target.
fn side(
    profile: &Profile,
    targets: &[Target],
    own: Own,
    cal: &Calibration,
    training_rgb: &[[f64; 3]],
    opts: DcpOptions,
) -> Result<DcpSide, ExportError> {
    let d50 = d50();
    let light = calibration_light(profile, cal);
    let weights = mix_weights(profile, light.cct);
    let mix = Mix {
        parts: targets
            .iter()
            .zip(&weights)
            .map(|(t, w)| (*w, *t))
            .collect(),
    };
    let mut fm = [[0.0; 3]; 3];
    let mut cm = [[0.0; 3]; 3];
    for (k, w) in weights.iter().enumerate() {
        for r in 0..3 {
            for c in 0..3 {
                fm[r][c] += w * own.forward[k][r][c];
                cm[r][c] += w * own.colour[k][r][c];
            }
        }
    }
    // Refit the ForwardMatrix on the mixed target (exact for LRM, where it is the mix).
    let bs: Vec<[f64; 3]> = training_rgb
        .iter()
        .map(|c| [0, 1, 2].map(|k| c[k] / cal.white_rgb[k]))
        .collect();
    let ts: Vec<[f64; 3]> = bs.iter().map(|b| mix.eval(*b)).collect();
    if ts.iter().flatten().all(|v| v.is_finite()) && weights.len() > 1 {
        fm = constrained_forward_matrix(&bs, &ts, d50);
    }
    let fm = quantise(&fm, Some(d50));
    if !spaces::invert(&fm).iter().flatten().all(|v| v.is_finite()) {
        return Err(ExportError::Model("its ForwardMatrix is singular".into()));
    }
    let cm = quantise(&cm, None);
    let hsm = hue_sat_map(&mix, &fm, opts);
    Ok(DcpSide {
        illuminant: light.code,
        illuminant_xy: light.xy,
        color_matrix: cm,
        forward_matrix: fm,
        hue_sat_map: hsm,
    })
}

/// The DCP's camera name (from the first model's provenance), profile name (kind, order,
/// camera, calibration temperatures) and copyright line, before the ASCII folding.
fn profile_names(profile: &Profile) -> (String, String, String) {
    let m0 = &profile.models()[0];
    let p = m0.provenance();
    // A capture's camera as the raw file names it (rawler's normalised make and model, Adobe's
    // spelling), else the simulated camera's name.
    let camera = p
        .capture
        .as_ref()
        .and_then(|c| c.camera.clone())
        .or_else(|| p.camera.as_deref().map(nsrm::display_name))
        .unwrap_or_else(|| "camera".into());
    let lights: Vec<String> = match captured_light(profile) {
        Some((_, t)) => vec![format!("{t:.0}K chart light")],
        None => profile
            .calibrations()
            .iter()
            .map(|c| format!("{:.0}K", c.cct))
            .collect(),
    };
    let name = format!(
        "nsrm {}{} {} {}",
        m0.kind(),
        m0.order(),
        camera,
        lights.join("+")
    );
    let copyright = format!(
        "Generated by nsrm {} from {}",
        env!("CARGO_PKG_VERSION"),
        super::provenance_line(m0)
    );
    (camera, name, copyright)
}

/// One model's ForwardMatrix (constrained least squares of its white-balanced target over its
/// training patches, rows summing to D50) and normalised ColorMatrix.
fn matrices(
    target: &Mix,
    training_rgb: &[[f64; 3]],
    white_rgb: [f64; 3],
    white_xyz: [f64; 3],
) -> Result<(Mat3, Mat3), ExportError> {
    let d50 = d50();
    let bs: Vec<[f64; 3]> = training_rgb
        .iter()
        .map(|c| [0, 1, 2].map(|k| c[k] / white_rgb[k]))
        .collect();
    let ts: Vec<[f64; 3]> = bs.iter().map(|b| target.eval(*b)).collect();
    if !ts.iter().flatten().all(|v| v.is_finite()) {
        return Err(ExportError::Model(
            "the model is not finite on its training patches".into(),
        ));
    }
    let fm = quantise(&constrained_forward_matrix(&bs, &ts, d50), Some(d50));
    let f_inv = spaces::invert(&fm);
    if !f_inv.iter().flatten().all(|v| v.is_finite()) {
        return Err(ExportError::Model("its ForwardMatrix is singular".into()));
    }
    let wdiag = [
        [white_rgb[0], 0.0, 0.0],
        [0.0, white_rgb[1], 0.0],
        [0.0, 0.0, white_rgb[2]],
    ];
    let adapt1 = temperature::bradford_between(white_xyz, d50);
    let cm = spaces::mul(&wdiag, &spaces::mul(&f_inv, &adapt1));
    let mx = spaces::apply(&cm, d50)
        .iter()
        .cloned()
        .fold(f64::MIN, f64::max);
    if !(mx.is_finite() && mx > 0.0) {
        return Err(ExportError::Model(
            "the model's camera response to D50 is not positive: it has no neutral a DCP can white-balance by".into(),
        ));
    }
    Ok((fm, cm.map(|r| r.map(|v| v / mx))))
}

/// DNG 1.6 IlluminantData of a chromaticity: type 0 (x, y), then x and y as URATIONALs.
fn illuminant_data(xy: [f64; 2]) -> Vec<u8> {
    let mut v = 0u16.to_le_bytes().to_vec();
    for c in xy {
        let den = 1_000_000u32;
        let num = (c.clamp(0.0, 1.0) * f64::from(den)).round() as u32;
        v.extend_from_slice(&num.to_le_bytes());
        v.extend_from_slice(&den.to_le_bytes());
    }
    v
}

fn ascii(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii() && !c.is_ascii_control() {
                c
            } else {
                '_'
            }
        })
        .collect()
}

impl Dcp {
    /// The temperatures of the sides' light sources.
    pub(crate) fn temperatures(&self) -> Vec<f64> {
        self.sides
            .iter()
            .map(|s| {
                LIGHT_SOURCES
                    .iter()
                    .find(|l| l.0 == s.illuminant)
                    .map(|l| l.2)
                    .or_else(|| s.illuminant_xy.and_then(|xy| temperature::cct(xy).ok()))
                    .unwrap_or(5000.0)
            })
            .collect()
    }

    /// The weight of side 1 for a chromaticity (DNG rule with the light sources' temperatures).
    fn weight_at(&self, xy: [f64; 2]) -> f64 {
        if self.sides.len() < 2 {
            return 1.0;
        }
        let t = self.temperatures();
        match temperature::cct(xy) {
            Ok(c) => temperature::dng_weight(c, t[0], t[1]),
            Err(_) => 1.0,
        }
    }

    fn mix(&self, w: f64, f: impl Fn(&DcpSide) -> Mat3) -> Mat3 {
        if self.sides.len() < 2 {
            return f(&self.sides[0]);
        }
        let (a, b) = (f(&self.sides[0]), f(&self.sides[1]));
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = w * a[i][j] + (1.0 - w) * b[i][j];
            }
        }
        m
    }

    /// The white balance chromaticity of a camera neutral (DNG `NeutralToXY`).
    pub(crate) fn neutral_to_xy(&self, neutral: [f64; 3]) -> Result<[f64; 2], ExportError> {
        let t = self.temperatures();
        let temps = [t[0], *t.last().expect("a side")];
        temperature::neutral_to_xy(neutral, temps, |n, w| {
            let cm = self.mix(w, |s| s.color_matrix);
            let inv = spaces::invert(&cm);
            let x = spaces::apply(&inv, n);
            x.iter().all(|v| v.is_finite()).then_some(x)
        })
        .map_err(|e| ExportError::Usage(e.to_string()))
    }

    /// The DNG profile pipeline for one camera RGB with the frame's camera neutral: white balance
    /// by the neutral (normalised to G = 1), the interpolated ForwardMatrix (normalised to D50),
    /// the interpolated hue/saturation map in linear ProPhoto RGB; XYZ D50 with the neutral at
    /// `Y = 1`. Returns the XYZ and the weight of side 1.
    // Only the judges beside the code read and evaluate a written DCP (`dcp_tests.rs`, the tests here).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn eval(
        &self,
        rgb: [f64; 3],
        neutral: [f64; 3],
    ) -> Result<([f64; 3], f64), ExportError> {
        let xy = self.neutral_to_xy(neutral)?;
        let w = self.weight_at(xy);
        Ok((self.eval_weighted(rgb, neutral, w), w))
    }

    /// [`eval`](Self::eval) at a given weight of side 1.
    // Only the judges beside the code read and evaluate a written DCP (`dcp_tests.rs`, the tests here).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn eval_weighted(&self, rgb: [f64; 3], neutral: [f64; 3], w: f64) -> [f64; 3] {
        self.at_weight(w).eval(rgb, neutral)
    }

    /// The pipeline at a weight of side 1, its matrices and mixed map computed once (for
    /// evaluating many colours).
    pub(crate) fn at_weight(&self, w: f64) -> Pipeline {
        let mut fm = self.mix(w, |s| s.forward_matrix);
        // The SDK normalises the ForwardMatrix so that (1, 1, 1) maps to D50.
        let one = spaces::apply(&fm, [1.0; 3]);
        let d = d50();
        for i in 0..3 {
            for j in 0..3 {
                fm[i][j] *= d[i] / one[i];
            }
        }
        let pp = prophoto_to_xyz();
        let map: Vec<[f64; 3]> = if self.sides.len() < 2 {
            self.sides[0]
                .hue_sat_map
                .iter()
                .map(|e| e.map(f64::from))
                .collect()
        } else {
            let (a, b) = (&self.sides[0].hue_sat_map, &self.sides[1].hue_sat_map);
            // The SDK interpolates the two tables entry by entry (in f32).
            a.iter()
                .zip(b)
                .map(|(x, y)| {
                    [0, 1, 2].map(|k| (w * x[k] as f64 + (1.0 - w) * y[k] as f64) as f32 as f64)
                })
                .collect()
        };
        Pipeline {
            to_prophoto: spaces::mul(&spaces::invert(&pp), &fm),
            prophoto_to_xyz: pp,
            map,
            hue_divisions: self.hue_divisions,
            sat_divisions: self.sat_divisions,
        }
    }

    /// The DCP file: little-endian TIFF-like with the `RC` magic, one IFD.
    pub(crate) fn to_bytes(&self) -> Vec<u8> {
        let mut entries: Vec<(u16, u16, u32, Vec<u8>)> = Vec::new();
        let ascii_v = |s: &str| {
            let mut v = s.as_bytes().to_vec();
            v.push(0);
            v
        };
        let srat = |m: &Mat3| {
            let mut v = Vec::new();
            for r in m {
                for x in r {
                    v.extend_from_slice(&((x * 1e6).round() as i32).to_le_bytes());
                    v.extend_from_slice(&1_000_000i32.to_le_bytes());
                }
            }
            v
        };
        let floats = |m: &[HsmEntry]| {
            let mut v = Vec::with_capacity(m.len() * 12);
            for e in m {
                for x in e {
                    v.extend_from_slice(&x.to_le_bytes());
                }
            }
            v
        };
        let long = |x: u32| x.to_le_bytes().to_vec();
        let short = |x: u16| x.to_le_bytes().to_vec();
        entries.push((
            50708,
            2,
            self.unique_camera_model.len() as u32 + 1,
            ascii_v(&self.unique_camera_model),
        ));
        for (i, s) in self.sides.iter().enumerate() {
            let i = i as u16;
            entries.push((50721 + i, 10, 9, srat(&s.color_matrix)));
            entries.push((50778 + i, 3, 1, short(s.illuminant)));
            entries.push((
                50938 + i,
                11,
                (s.hue_sat_map.len() * 3) as u32,
                floats(&s.hue_sat_map),
            ));
            entries.push((50964 + i, 10, 9, srat(&s.forward_matrix)));
            if let Some(xy) = s.illuminant_xy.filter(|_| s.illuminant == OTHER_LIGHT) {
                entries.push((52533 + i, 7, 18, illuminant_data(xy)));
            }
        }
        entries.push((
            50936,
            2,
            self.profile_name.len() as u32 + 1,
            ascii_v(&self.profile_name),
        ));
        let mut dims = Vec::new();
        for d in [self.hue_divisions as u32, self.sat_divisions as u32, 1] {
            dims.extend_from_slice(&d.to_le_bytes());
        }
        entries.push((50937, 4, 3, dims));
        let mut tc = Vec::new();
        for p in &self.tone_curve {
            tc.extend_from_slice(&p[0].to_le_bytes());
            tc.extend_from_slice(&p[1].to_le_bytes());
        }
        entries.push((50940, 11, (self.tone_curve.len() * 2) as u32, tc));
        entries.push((50941, 4, 1, long(0)));
        entries.push((
            50942,
            2,
            self.copyright.len() as u32 + 1,
            ascii_v(&self.copyright),
        ));
        entries.push((51107, 4, 1, long(0)));
        entries.sort_by_key(|e| e.0);
        let n = entries.len();
        let ifd_len = 2 + 12 * n + 4;
        let mut data_off = 8 + ifd_len;
        let mut out = Vec::new();
        out.extend_from_slice(b"IIRC");
        out.extend_from_slice(&8u32.to_le_bytes());
        out.extend_from_slice(&(n as u16).to_le_bytes());
        let mut blobs = Vec::new();
        for (tag, typ, count, bytes) in &entries {
            out.extend_from_slice(&tag.to_le_bytes());
            out.extend_from_slice(&typ.to_le_bytes());
            out.extend_from_slice(&count.to_le_bytes());
            if bytes.len() <= 4 {
                let mut v = bytes.clone();
                v.resize(4, 0);
                out.extend_from_slice(&v);
            } else {
                out.extend_from_slice(&(data_off as u32).to_le_bytes());
                let mut v = bytes.clone();
                if v.len() % 2 == 1 {
                    v.push(0);
                }
                data_off += v.len();
                blobs.push(v);
            }
        }
        out.extend_from_slice(&0u32.to_le_bytes());
        for b in blobs {
            out.extend_from_slice(&b);
        }
        out
    }

    /// Reads a DCP (or the profile tags of a DNG-like IFD): every size is checked against the
    /// file before it is read.
    // Only the judges beside the code read and evaluate a written DCP (`dcp_tests.rs`, the tests here).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn parse(bytes: &[u8]) -> Result<Dcp, ExportError> {
        let tags = DcpTags::read(bytes)?;
        let (hd, sd) = tags.map_dimensions()?;
        let mut sides = Vec::new();
        for i in 0..2u16 {
            if let Some(side) = tags.side(i, hd * sd)? {
                sides.push(side);
            }
        }
        if sides.is_empty() {
            return Err(not_dcp("no ColorMatrix1"));
        }
        let tone_curve = tags
            .floats(50940)
            .map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]).collect())
            .unwrap_or_default();
        Ok(Dcp {
            unique_camera_model: tags.text(50708),
            profile_name: tags.text(50936),
            copyright: tags.text(50942),
            hue_divisions: hd,
            sat_divisions: sd,
            sides,
            tone_curve,
        })
    }
}

/// Why bytes are not a DCP [`Dcp::parse`] reads.
fn not_dcp(why: &str) -> ExportError {
    ExportError::Model(format!("not a DCP: {why}"))
}

/// The tags of a DCP's first IFD: tag → (type, count, value bytes); tags of unknown types are
/// skipped.
struct DcpTags<'a>(std::collections::HashMap<u16, (u16, usize, &'a [u8])>);

impl<'a> DcpTags<'a> {
    /// Reads the little-endian header (`IIRC`, or a TIFF's `II*`) and the first IFD, each tag's
    /// value inside `bytes`.
    fn read(bytes: &'a [u8]) -> Result<DcpTags<'a>, ExportError> {
        if bytes.len() < 8
            || &bytes[0..2] != b"II"
            || (bytes[2..4] != *b"RC" && bytes[2..4] != [42, 0])
        {
            return Err(not_dcp("no little-endian `IIRC` header"));
        }
        let u16_at = |o: usize| -> Result<u16, ExportError> {
            bytes
                .get(o..o + 2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .ok_or_else(|| not_dcp("truncated"))
        };
        let u32_at = |o: usize| -> Result<u32, ExportError> {
            bytes
                .get(o..o + 4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .ok_or_else(|| not_dcp("truncated"))
        };
        let ifd = u32_at(4)? as usize;
        let n = u16_at(ifd)? as usize;
        let mut tags = std::collections::HashMap::new();
        for i in 0..n {
            let e = ifd + 2 + 12 * i;
            let (tag, typ, count) = (u16_at(e)?, u16_at(e + 2)?, u32_at(e + 4)? as usize);
            let size = match typ {
                1 | 2 | 7 => 1,
                3 => 2,
                4 | 9 | 11 => 4,
                5 | 10 | 12 => 8,
                _ => continue,
            };
            let len = count
                .checked_mul(size)
                .ok_or_else(|| not_dcp("tag size overflows"))?;
            let off = if len <= 4 {
                e + 8
            } else {
                u32_at(e + 8)? as usize
            };
            let data = bytes
                .get(
                    off..off
                        .checked_add(len)
                        .ok_or_else(|| not_dcp("tag offset overflows"))?,
                )
                .ok_or_else(|| not_dcp("a tag points past the end of the file"))?;
            tags.insert(tag, (typ, count, data));
        }
        Ok(DcpTags(tags))
    }

    /// An ASCII tag's text (empty when absent).
    fn text(&self, t: u16) -> String {
        self.0
            .get(&t)
            .map(|(_, _, d)| {
                String::from_utf8_lossy(d)
                    .trim_end_matches('\0')
                    .to_string()
            })
            .unwrap_or_default()
    }

    /// A matrix tag (9 signed rationals, row by row).
    fn mat(&self, t: u16) -> Result<Option<Mat3>, ExportError> {
        let Some((typ, count, d)) = self.0.get(&t) else {
            return Ok(None);
        };
        if *typ != 10 || *count != 9 {
            return Err(not_dcp(&format!("tag {t} is not 9 signed rationals")));
        }
        let mut m = [[0.0; 3]; 3];
        for k in 0..9 {
            let num = i32::from_le_bytes(d[8 * k..8 * k + 4].try_into().expect("4 bytes"));
            let den = i32::from_le_bytes(d[8 * k + 4..8 * k + 8].try_into().expect("4 bytes"));
            if den == 0 {
                return Err(not_dcp(&format!("tag {t} has a zero denominator")));
            }
            m[k / 3][k % 3] = num as f64 / den as f64;
        }
        Ok(Some(m))
    }

    /// A float tag's values (`None` when absent or of another type).
    fn floats(&self, t: u16) -> Option<Vec<f32>> {
        self.0
            .get(&t)
            .filter(|(typ, _, _)| *typ == 11)
            .map(|(_, _, d)| {
                d.chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            })
    }

    /// The hue/saturation map's hue and saturation divisions (one value division only; `(0, 0)`
    /// without a map).
    fn map_dimensions(&self) -> Result<(usize, usize), ExportError> {
        let dims = self
            .0
            .get(&50937)
            .filter(|(typ, count, _)| *typ == 4 && *count == 3)
            .map(|(_, _, d)| {
                [0, 1, 2].map(|k| {
                    u32::from_le_bytes(d[4 * k..4 * k + 4].try_into().expect("4")) as usize
                })
            });
        match dims {
            Some([h, s, 1]) if h >= 1 && s >= 2 => Ok((h, s)),
            Some(d) => Err(not_dcp(&format!(
                "hue/saturation map dimensions {d:?} (only one value division is read)"
            ))),
            None => Ok((0, 0)),
        }
    }

    /// Side `i` (0 or 1) when its ColorMatrix is there: with its ForwardMatrix, calibration
    /// illuminant and hue/saturation map of `entries` entries.
    fn side(&self, i: u16, entries: usize) -> Result<Option<DcpSide>, ExportError> {
        let Some(cm) = self.mat(50721 + i)? else {
            return Ok(None);
        };
        let fm = self
            .mat(50964 + i)?
            .ok_or_else(|| not_dcp("a ColorMatrix without its ForwardMatrix"))?;
        let ill = self
            .0
            .get(&(50778 + i))
            .filter(|(typ, _, _)| *typ == 3)
            .map(|(_, _, d)| u16::from_le_bytes([d[0], d[1]]))
            .unwrap_or(0);
        let map = match self.floats(50938 + i) {
            Some(v) if v.len() == entries * 3 => {
                v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
            }
            Some(_) => {
                return Err(not_dcp(
                    "the hue/saturation map's size does not match its dimensions",
                ))
            }
            None => Vec::new(),
        };
        let illuminant_xy = self
            .0
            .get(&(52533 + i))
            .filter(|(typ, _, d)| *typ == 7 && d.len() >= 18 && d[0..2] == [0, 0])
            .map(|(_, _, d)| {
                let r = |o: usize| {
                    let n = u32::from_le_bytes([d[o], d[o + 1], d[o + 2], d[o + 3]]);
                    let q = u32::from_le_bytes([d[o + 4], d[o + 5], d[o + 6], d[o + 7]]);
                    f64::from(n) / f64::from(q.max(1))
                };
                [r(2), r(10)]
            });
        Ok(Some(DcpSide {
            illuminant: ill,
            illuminant_xy,
            color_matrix: cm,
            forward_matrix: fm,
            hue_sat_map: map,
        }))
    }
}

/// A DCP's profile pipeline at one weight of its sides (see [`Dcp::at_weight`]).
#[derive(Debug, Clone)]
pub(crate) struct Pipeline {
    /// ProPhoto⁻¹ · the mixed, normalised ForwardMatrix.
    to_prophoto: Mat3,
    prophoto_to_xyz: Mat3,
    map: Vec<[f64; 3]>,
    hue_divisions: usize,
    sat_divisions: usize,
}

impl Pipeline {
    /// White balance by the neutral (normalised to G = 1), the ForwardMatrix, the hue/saturation
    /// map in linear ProPhoto RGB; XYZ D50 with the neutral at `Y = 1`.
    pub(crate) fn eval(&self, rgb: [f64; 3], neutral: [f64; 3]) -> [f64; 3] {
        let n = neutral.map(|v| v / neutral[1]);
        let b = [0, 1, 2].map(|k| rgb[k] / n[k]);
        let rgb_pp = spaces::apply(&self.to_prophoto, b);
        let out = apply_hue_sat_map_with(
            |i| self.map[i],
            self.hue_divisions,
            self.sat_divisions,
            rgb_pp,
        );
        spaces::apply(&self.prophoto_to_xyz, out)
    }
}

/// The ΔE00 (D50-referred, the white scaled with exposure) of the DCP against the combined model,
/// for the frame whites `whites`: the first model's training patches, white-balanced by its
/// calibration white (`b = c / w`), are put under each frame white (`b · n`); the error at a
/// sample is the worst over the whites. Measured on those patches and on the dense in-gamut set
/// built from them (`measure_fn`).
pub(crate) fn measure(
    dcp: &Dcp,
    profile: &Profile,
    whites: &[FrameWhite],
    training_rgb: &[[f64; 3]],
    stops: [f64; 2],
) -> Result<super::ErrorReport, ExportError> {
    let d50 = d50();
    let w0 = profile.calibrations()[0].white_rgb;
    let mut combos: Vec<(Combination, Mat3, Pipeline)> = Vec::new();
    for w in whites {
        let c = profile
            .combine(*w)
            .map_err(|e| ExportError::Model(e.to_string()))?;
        let adapt = temperature::bradford_between(c.white_xyz, d50).map(|r| r.map(|v| v / 100.0));
        // The DCP's weight for this white, found once.
        let xy = dcp.neutral_to_xy(c.neutral)?;
        let weight = dcp.weight_at(xy);
        combos.push((c, adapt, dcp.at_weight(weight)));
    }
    let balanced: Vec<[f64; 3]> = training_rgb
        .iter()
        .map(|c| [0, 1, 2].map(|k| c[k] / w0[k]))
        .collect();
    let report = super::measure_fn(&balanced, stops, false, |b, k| {
        let mut worst = 0.0f64;
        for (c, adapt, pipeline) in &combos {
            let rgb = [0, 1, 2].map(|j| b[j] * c.neutral[j]);
            let exact = spaces::apply(adapt, c.apply_f64(rgb));
            let approx = pipeline.eval(rgb, c.neutral);
            let d = nsrm::delta_e00_xyz(exact, approx, d50.map(|v| v * k));
            worst = worst.max(if d.is_finite() { d } else { f64::INFINITY });
        }
        worst
    });
    Ok(report)
}

/// The ΔE00 (D50-referred) of a single-model DCP against the model as `nsrm apply` runs it
/// without a white (no re-balancing), for a raw file white-balanced by the training white's
/// camera response `white` (a DNG maps that neutral exactly to D50, whether or not the model maps
/// it to its white): the training patches and the training white itself, and the dense in-gamut
/// set built from the patches. Exposure is normalised on both sides: the training white's green
/// is the DCP's `G = 1` (its `Y = 1`) and the model's training exposure (its white `Y = 1`).
pub(crate) fn measure_unbalanced(
    dcp: &Dcp,
    model: &nsrm::Model,
    white: [f64; 3],
    training_rgb: &[[f64; 3]],
    stops: [f64; 2],
) -> Result<super::ErrorReport, ExportError> {
    if !(white.iter().all(|v| v.is_finite() && *v > 0.0)) {
        return Err(ExportError::Model(format!(
            "the training white's camera response {white:?} is not positive"
        )));
    }
    let d50 = d50();
    let n = white.map(|v| v / white[1]);
    let xy = dcp.neutral_to_xy(n)?;
    let pipeline = dcp.at_weight(dcp.weight_at(xy));
    let mw = model.white_xyz();
    let adapt = temperature::bradford_between(mw, d50).map(|r| r.map(|v| v / mw[1]));
    let mut samples = training_rgb.to_vec();
    samples.push(white);
    let report = super::measure_fn(&samples, stops, false, |p, k| {
        let exact = spaces::apply(&adapt, model.apply_f64(p));
        let approx = pipeline.eval(p.map(|v| v / white[1]), n);
        let d = nsrm::delta_e00_xyz(exact, approx, d50.map(|v| v * k));
        if d.is_finite() {
            d
        } else {
            f64::INFINITY
        }
    });
    Ok(report)
}

/// What [`render`] built and measured.
#[derive(Debug, Clone)]
pub struct DcpWritten {
    /// The error of the profile against the model set, over every white measured, and for a
    /// single model the error against the model applied without a white (`unbalanced`): the
    /// worse of the two per sample set. What `max_de00` is held to.
    pub report: super::ErrorReport,
    /// For a single model whose training white's camera response is known: the error of the
    /// profile, on a raw file white-balanced by that response, against the model as `nsrm apply`
    /// runs it without `--white` ([`measure_unbalanced`]; includes the white's own error).
    pub unbalanced: Option<super::ErrorReport>,
    /// The error against the re-balanced model alone (as `apply --white` runs it).
    pub rebalanced: super::ErrorReport,
    /// The frame whites the error was measured at (described).
    pub whites: Vec<String>,
    /// Per model: ΔE00 between the model's output for its training white's camera response and
    /// its white, when that response is known (a DCP maps the neutral exactly to D50, so it
    /// cannot follow a model that misses its own white).
    pub white_miss: Vec<Option<f64>>,
    /// The lights the file names (CalibrationIlluminant1/2), described: the same function
    /// decides both (`calibration_light`).
    pub illuminants: Vec<String>,
    /// Hue divisions of the maps written.
    pub hue_divisions: usize,
    /// Saturation divisions of the maps written.
    pub sat_divisions: usize,
}

/// One model's training patches for the export: camera RGB, and the camera response of the
/// training white when known.
#[derive(Debug, Clone)]
pub struct DcpTraining {
    /// Camera RGB of the training patches.
    pub rgb: Vec<[f64; 3]>,
    /// The camera response of the training white, when known.
    pub white_rgb: Option<[f64; 3]>,
}

/// Builds and measures the DCP of a model set and returns its bytes, writing nothing. The error
/// is measured with [`Dcp::eval`]'s pipeline against the combined model at each calibration
/// white and, for two illuminants, at a white halfway between them in mired, and checked against
/// `max_de00`.
pub fn render(
    profile: &Profile,
    training: &[DcpTraining],
    opts: DcpOptions,
    stops: [f64; 2],
    max_de00: Option<f64>,
) -> Result<(Vec<u8>, DcpWritten), ExportError> {
    super::check_max_de00(max_de00)?;
    let sets: Vec<&[[f64; 3]]> = training.iter().map(|t| t.rgb.as_slice()).collect();
    let dcp = build(profile, &sets, opts)?;
    let mut whites: Vec<(FrameWhite, String)> = profile
        .calibrations()
        .iter()
        .map(|c| {
            (
                FrameWhite::Neutral(c.white_rgb),
                format!(
                    "the calibration white, {}",
                    calibration_light(profile, c).describe()
                ),
            )
        })
        .collect();
    if profile.is_dual() {
        let [t1, t2] = profile.temperatures();
        let mid = 2.0 / (1.0 / t1 + 1.0 / t2);
        let xy = temperature::temperature_xy(mid).map_err(|e| ExportError::Model(e.to_string()))?;
        whites.push((FrameWhite::Xy(xy), format!("a {mid:.0} K light")));
    }
    let fw: Vec<FrameWhite> = whites.iter().map(|w| w.0).collect();
    let rebalanced = measure(&dcp, profile, &fw, sets[0], stops)?;
    // A single model is also applied without a white: a DNG white-balanced by the training
    // white then differs from it wherever re-balancing moves the model (its own white first).
    let unbalanced = match (
        profile.is_dual(),
        training.first().and_then(|t| t.white_rgb),
    ) {
        (false, Some(w)) => Some(measure_unbalanced(
            &dcp,
            &profile.models()[0],
            w,
            sets[0],
            stops,
        )?),
        _ => None,
    };
    let report = match &unbalanced {
        Some(u) => rebalanced.worst(u),
        None => rebalanced.clone(),
    };
    report.check_limit(max_de00)?;
    let white_miss = profile
        .models()
        .iter()
        .enumerate()
        .map(|(i, m)| {
            training
                .get(i)
                .and_then(|t| t.white_rgb)
                .map(|w| nsrm::delta_e00_xyz(m.apply_f64(w), m.white_xyz(), m.white_xyz()))
        })
        .collect();
    let written = DcpWritten {
        report,
        unbalanced,
        rebalanced,
        whites: whites.into_iter().map(|w| w.1).collect(),
        white_miss,
        illuminants: profile
            .calibrations()
            .iter()
            .map(|c| calibration_light(profile, c).describe())
            .collect(),
        hue_divisions: dcp.hue_divisions,
        sat_divisions: dcp.sat_divisions,
    };
    Ok((dcp.to_bytes(), written))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm::{fit_with, FitOptions};
    use nsrm::{simulate_named, Grid};

    fn fitted(kind: Kind, ill: &str) -> (nsrm::Model, nsrm::TrainingSet) {
        let d = simulate_named("nikon-d5100", ill, "rawtoaces-190", &Grid::default()).unwrap();
        let o = FitOptions {
            preserve_white: true,
            ..Default::default()
        };
        (fit_with(kind, 3, &d, &o).unwrap().model, d)
    }

    #[test]
    fn hsv_round_trips() {
        for c in [
            [0.2, 0.5, 0.1],
            [0.9, 0.1, 0.4],
            [0.3, 0.3, 0.3],
            [0.0, 0.2, 0.7],
        ] {
            let back = hsv_to_rgb(rgb_to_hsv(c));
            for k in 0..3 {
                assert!((back[k] - c[k]).abs() < 1e-12, "{c:?} {back:?}");
            }
        }
    }

    #[test]
    fn single_nsrm_dcp_follows_the_model_and_round_trips() {
        let (m, d) = fitted(Kind::Nsrm, "D65");
        let p = Profile::single(m).unwrap();
        let dcp = build(&p, &[d.rgb.as_slice()], DcpOptions::default()).unwrap();
        let s = &dcp.sides[0];
        assert_eq!(s.illuminant, 21);
        let one = spaces::apply(&s.forward_matrix, [1.0; 3]);
        for k in 0..3 {
            assert!((one[k] - d50()[k]).abs() < 2e-6, "{one:?}");
        }
        for h in 0..dcp.hue_divisions {
            assert_eq!(s.hue_sat_map[h * dcp.sat_divisions], [0.0, 1.0, 1.0]);
        }
        assert!(s.hue_sat_map.iter().flatten().all(|v| v.is_finite()));
        let r = measure(
            &dcp,
            &p,
            &[FrameWhite::Neutral(p.calibrations()[0].white_rgb)],
            &d.rgb,
            [-1.0, 0.5],
        )
        .unwrap();
        assert!(r.dense.count > 1000, "{}", r.summary());
        assert!(r.max() < 0.3, "{}", r.summary());
        println!("single NSRM 3 DCP: {}", r.summary());
        let back = Dcp::parse(&dcp.to_bytes()).unwrap();
        assert_eq!(back, dcp);
        // A coarse map is measured as coarse.
        let coarse = build(
            &p,
            &[d.rgb.as_slice()],
            DcpOptions {
                hue_divisions: 12,
                sat_divisions: 4,
            },
        )
        .unwrap();
        let rc = measure(
            &coarse,
            &p,
            &[FrameWhite::Neutral(p.calibrations()[0].white_rgb)],
            &d.rgb,
            [-1.0, 0.5],
        )
        .unwrap();
        assert!(
            rc.max() > 3.0 * r.max(),
            "{} vs {}",
            rc.summary(),
            r.summary()
        );
    }

    #[test]
    fn dual_dcp_and_refusals() {
        let (a, da) = fitted(Kind::Nsrm, "A");
        let (b, db) = fitted(Kind::Nsrm, "D65");
        let p = Profile::dual(b, a).unwrap();
        let dcp = build(
            &p,
            &[da.rgb.as_slice(), db.rgb.as_slice()],
            DcpOptions::default(),
        )
        .unwrap();
        assert_eq!(
            dcp.sides.iter().map(|s| s.illuminant).collect::<Vec<_>>(),
            [17, 21]
        );
        let xy = temperature::temperature_xy(4000.0).unwrap();
        let r = measure(&dcp, &p, &[FrameWhite::Xy(xy)], &da.rgb, [-1.0, 0.5]).unwrap();
        assert!(r.max() < 1.0, "{}", r.summary());
        let (prm, dp) = fitted(Kind::Prm, "D65");
        let e = build(
            &Profile::single(prm).unwrap(),
            &[dp.rgb.as_slice()],
            DcpOptions::default(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("exposure-invariant"), "{e}");
        // A light no EXIF light source names (4000 K, 20 mired from the nearest) is written as
        // DNG 1.6's Other with its chromaticity in IlluminantData (issue 36: it was refused).
        let (m4, d4) = fitted(Kind::Nsrm, "P4000");
        let cal = Calibration::of(&m4).unwrap();
        let dcp = build(
            &Profile::single(m4).unwrap(),
            &[d4.rgb.as_slice()],
            DcpOptions::default(),
        )
        .unwrap();
        assert_eq!(dcp.sides[0].illuminant, OTHER_LIGHT);
        let back = Dcp::parse(&dcp.to_bytes()).unwrap();
        let xy = back.sides[0]
            .illuminant_xy
            .expect("IlluminantData1 read back");
        assert!((xy[0] - cal.xy[0]).abs() < 1e-6 && (xy[1] - cal.xy[1]).abs() < 1e-6);
        assert!(
            (back.temperatures()[0] - cal.cct).abs() < 1.0,
            "{:?}",
            back.temperatures()
        );
        // A light near a standard one is named by it, with no IlluminantData.
        assert!(dcp_tags_have_no_illuminant_data(
            &build(
                &p,
                &[da.rgb.as_slice(), db.rgb.as_slice()],
                DcpOptions::default()
            )
            .unwrap()
        ));
    }

    fn dcp_tags_have_no_illuminant_data(d: &Dcp) -> bool {
        let back = Dcp::parse(&d.to_bytes()).unwrap();
        back.sides
            .iter()
            .all(|s| s.illuminant_xy.is_none() && s.illuminant != OTHER_LIGHT)
    }

    #[test]
    fn a_pairs_weights_are_affine_in_reciprocal_temperature() {
        let (a, _) = fitted(Kind::Lrm, "A");
        let (b, _) = fitted(Kind::Lrm, "D65");
        let p = Profile::dual(b, a).unwrap();
        let [t1, t2] = p.temperatures();
        let w1 = mix_weights(&p, t1);
        let w2 = mix_weights(&p, t2);
        assert!((w1[0] - 1.0).abs() < 1e-12 && w1[1].abs() < 1e-12, "{w1:?}");
        assert!(w2[0].abs() < 1e-12 && (w2[1] - 1.0).abs() < 1e-12, "{w2:?}");
        // Halfway in 1/T is half and half; beyond t1 it extrapolates.
        let mid = mix_weights(&p, 2.0 / (1.0 / t1 + 1.0 / t2));
        assert!((mid[0] - 0.5).abs() < 1e-12, "{mid:?}");
        let beyond = mix_weights(&p, t1 - 100.0);
        assert!(beyond[0] > 1.0 && beyond[1] < 0.0, "{beyond:?}");
        assert_eq!(targets(&p).len(), 2);
        let (_, name, copyright) = profile_names(&p);
        assert!(
            name.starts_with("nsrm LRM") && name.contains("K+"),
            "{name}"
        );
        assert!(copyright.starts_with("Generated by nsrm"), "{copyright}");
        let single = Profile::single(fitted(Kind::Lrm, "D65").0).unwrap();
        assert_eq!(mix_weights(&single, 5000.0), [1.0]);
    }

    /// A little-endian `IIRC` file of `tags` (tag, type, count, value bytes), values after the IFD.
    fn dcp_bytes(tags: &[(u16, u16, u32, Vec<u8>)]) -> Vec<u8> {
        let mut b = b"IIRC".to_vec();
        b.extend_from_slice(&8u32.to_le_bytes());
        b.extend_from_slice(&(tags.len() as u16).to_le_bytes());
        let mut data_at = 8 + 2 + 12 * tags.len() + 4;
        let mut data = Vec::new();
        for (tag, typ, count, v) in tags {
            b.extend_from_slice(&tag.to_le_bytes());
            b.extend_from_slice(&typ.to_le_bytes());
            b.extend_from_slice(&count.to_le_bytes());
            if v.len() <= 4 {
                let mut inline = v.clone();
                inline.resize(4, 0);
                b.extend_from_slice(&inline);
            } else {
                b.extend_from_slice(&(data_at as u32).to_le_bytes());
                data.extend_from_slice(v);
                data_at += v.len();
            }
        }
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&data);
        b
    }

    fn rationals(m: [[i32; 3]; 3], den: i32) -> Vec<u8> {
        m.iter()
            .flatten()
            .flat_map(|v| [v.to_le_bytes(), den.to_le_bytes()].concat())
            .collect()
    }

    #[test]
    fn dcp_tags_read_text_matrices_and_sides() {
        let id = [[2, 0, 0], [0, 2, 0], [0, 0, 2]];
        let bytes = dcp_bytes(&[
            (50708, 2, 4, b"cam\0".to_vec()),
            (50721, 10, 9, rationals(id, 2)),
            (50964, 10, 9, rationals(id, 4)),
            (50778, 3, 1, 21u16.to_le_bytes().to_vec()),
        ]);
        let tags = DcpTags::read(&bytes).unwrap();
        assert_eq!(tags.text(50708), "cam");
        assert_eq!(tags.text(1), "");
        assert_eq!(tags.map_dimensions().unwrap(), (0, 0));
        let side = tags.side(0, 0).unwrap().unwrap();
        assert_eq!(side.color_matrix, nsrm::MAT3_IDENTITY);
        assert_eq!(side.forward_matrix[1], [0.0, 0.5, 0.0]);
        assert_eq!(side.illuminant, 21);
        assert!(tags.side(1, 0).unwrap().is_none());
        let dcp = Dcp::parse(&bytes).unwrap();
        assert_eq!(
            (dcp.unique_camera_model.as_str(), dcp.sides.len()),
            ("cam", 1)
        );
    }

    #[test]
    fn malformed_dcp_tags_are_errors() {
        assert!(DcpTags::read(b"MM\0*\0\0\0\x08").is_err());
        let zero = dcp_bytes(&[(50721, 10, 9, rationals([[1; 3]; 3], 0))]);
        let e = DcpTags::read(&zero).unwrap().mat(50721).unwrap_err();
        assert!(e.to_string().contains("zero denominator"), "{e}");
        let lonely = dcp_bytes(&[(50721, 10, 9, rationals([[1; 3]; 3], 1))]);
        assert!(
            Dcp::parse(&lonely).is_err(),
            "a ColorMatrix without its ForwardMatrix"
        );
        let dims: Vec<u8> = [7u32, 4, 2].iter().flat_map(|v| v.to_le_bytes()).collect();
        let two_values = dcp_bytes(&[(50937, 4, 3, dims)]);
        assert!(DcpTags::read(&two_values)
            .unwrap()
            .map_dimensions()
            .is_err());
        let mut cut = dcp_bytes(&[(50721, 10, 9, rationals([[1; 3]; 3], 1))]);
        cut.truncate(cut.len() - 8);
        assert!(DcpTags::read(&cut).is_err(), "a value past the end");
        assert!(Dcp::parse(&dcp_bytes(&[(50708, 2, 4, b"cam\0".to_vec())])).is_err());
    }
}

// Two `#[ignore]` diagnostics run by hand (`cargo test -p nsrm-export --lib diag -- --ignored
// --nocapture`): where a one-illuminant DCP's worst patch is, and where a two-illuminant DCP's
// error comes from.
#[cfg(test)]
#[path = "dcp_diag.rs"]
mod diagnostics;
