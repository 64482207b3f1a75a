//! Two-illuminant models: two fitted models of one kind and order, each with the illuminant it was
//! calibrated under, combined for a frame's white as the DNG specification combines its two
//! camera profiles.
//!
//! For a frame whose white has camera response `n`:
//! 1. each model `i` is applied to the frame's camera RGB re-balanced so that `n` lands on the
//!    camera response `w_i` of that model's calibration white, `diag(w_i / n)`;
//! 2. its output (XYZ relative to its illuminant) is adapted with Bradford from its calibration
//!    white to the frame's white;
//! 3. the two are mixed linearly in inverse colour temperature between the two calibration
//!    temperatures, clamped outside ([`dng_weight`]).
//!
//! A neutral of the frame therefore comes out neutral (the frame's white) at any temperature. The
//! calibration temperature of a model is the CCT of its own white ([`cct`]); `w_i` is the model's
//! inverse at its white (exact for a white-preserving fit's training white). The frame's white is
//! a chromaticity or a camera neutral ([`FrameWhite`]): a chromaticity's neutral is the camera's
//! response to that light, found by inverting the models mixed for its temperature ("the
//! interpolated XYZ → camera matrices" of the DNG; exact for LRM, Newton steps otherwise); a
//! neutral's chromaticity is found by the DNG fixed-point iteration ([`neutral_to_xy`]).
//!
//! # File
//! A two-illuminant model file is the first model's document (the lower temperature) with two
//! fields added: `"second_illuminant"`, the second model's complete document, and
//! `"calibration_illuminants"`, a description of both whites (chromaticity and CCT; informative,
//! recomputed on load). It is written as version 3; single-model files are unchanged and
//! [`Model::from_json`] refuses a two-illuminant one with a message that says so.

use super::{Kind, Model, ModelError};
use crate::colorimetry::spaces::{self, Mat3};
use crate::colorimetry::temperature::{
    bradford_between, cct, dng_weight, neutral_to_xy, xy_to_xyz, xyz_to_xy, TemperatureError,
};
use std::path::Path;

/// The version of a two-illuminant model file.
pub(crate) const DUAL_VERSION: u32 = 3;
/// The field holding the second model.
pub(crate) const SECOND_FIELD: &str = "second_illuminant";
const CALIBRATION_FIELD: &str = "calibration_illuminants";

/// Two calibration temperatures closer than this (in mired) cannot be interpolated between.
pub(crate) const MIN_MIRED_APART: f64 = 20.0;

/// The camera RGB that `model` maps to `xyz`: exact for LRM (its matrix inverted), a damped
/// Newton iteration on the f64 model otherwise. `None` when there is none (no convergence, a
/// non-finite or non-positive-signal answer).
pub fn invert(model: &Model, xyz: [f64; 3]) -> Option<[f64; 3]> {
    if !xyz.iter().all(|v| v.is_finite()) {
        return None;
    }
    if model.kind() == Kind::Lrm {
        let m = model.matrix();
        let mat: Mat3 = [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]];
        let x = spaces::apply(&spaces::invert(&mat), xyz);
        return x.iter().all(|v| v.is_finite()).then_some(x);
    }
    let scale = xyz.iter().map(|v| v.abs()).fold(0.0, f64::max);
    if scale == 0.0 {
        return Some([0.0; 3]);
    }
    // Start from a grey of about the right level; failing that (a PRM can fold over), follow the
    // straight path from that grey's own output to the target in small steps.
    let y0 = model.apply_f64([1.0; 3])[1];
    let x0 = if y0.is_finite() && y0 > 0.0 {
        [xyz[1] / y0; 3]
    } else {
        [1.0; 3]
    };
    if let Some(x) = newton(model, xyz, x0) {
        return Some(x);
    }
    let from = model.apply_f64(x0);
    let mut x = x0;
    let steps = 32;
    for i in 1..=steps {
        let t = i as f64 / steps as f64;
        let target = [0, 1, 2].map(|k| from[k] + t * (xyz[k] - from[k]));
        x = newton(model, target, x)?;
    }
    Some(x)
}

/// Damped Newton from `x` towards `model(x) = xyz`.
fn newton(model: &Model, xyz: [f64; 3], mut x: [f64; 3]) -> Option<[f64; 3]> {
    let scale = xyz.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1e-300);
    let resid = |x: [f64; 3]| {
        let y = model.apply_f64(x);
        [y[0] - xyz[0], y[1] - xyz[1], y[2] - xyz[2]]
    };
    let norm = |r: [f64; 3]| r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut r = resid(x);
    for _ in 0..100 {
        let n = norm(r);
        if !n.is_finite() {
            return None;
        }
        if n <= 1e-12 * scale {
            break;
        }
        let j = jacobian(model, x);
        let inv = spaces::invert(&j);
        let step = spaces::apply(&inv, r);
        if !step.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut t = 1.0;
        loop {
            let cand = [x[0] - t * step[0], x[1] - t * step[1], x[2] - t * step[2]];
            let rc = resid(cand);
            if norm(rc) < n || t < 1e-6 {
                x = cand;
                r = rc;
                break;
            }
            t *= 0.5;
        }
    }
    (norm(r) <= 1e-9 * scale && x.iter().all(|v| v.is_finite())).then_some(x)
}

/// The Jacobian of the f64 model at `x` (central differences).
fn jacobian(model: &Model, x: [f64; 3]) -> Mat3 {
    let mut j = [[0.0; 3]; 3];
    for c in 0..3 {
        let h = 1e-6 * x[c].abs().max(1e-3);
        let (mut a, mut b) = (x, x);
        a[c] += h;
        b[c] -= h;
        let (fa, fb) = (model.apply_f64(a), model.apply_f64(b));
        for k in 0..3 {
            j[k][c] = (fa[k] - fb[k]) / (2.0 * h);
        }
    }
    j
}

/// `model` evaluated on `diag(gains)·rgb`: the gains go into the input gains for NSRM (whose
/// chromaticities they change) and into the matrix columns for the other kinds (each term is a
/// monomial, or a root of one, so a positive gain per channel scales each column).
pub(crate) fn with_extra_gains(model: &Model, gains: [f64; 3]) -> Result<Model, ModelError> {
    if !gains.iter().all(|g| g.is_finite() && *g > 0.0) {
        return Err(ModelError::Invalid(format!(
            "white-balance gains {gains:?} must be finite and > 0"
        )));
    }
    if model.kind() == Kind::Nsrm {
        let g0 = model.input_gains();
        return model.clone().with_input_gains([
            g0[0] * gains[0],
            g0[1] * gains[1],
            g0[2] * gains[2],
        ]);
    }
    let l = model.len_terms();
    let mut m = model.matrix().to_vec();
    for (j, t) in model.terms().iter().enumerate() {
        let f: f64 = (0..3)
            .map(|c| gains[c].powf(t.exps[c] as f64 / t.root as f64))
            .product();
        for i in 0..3 {
            m[i * l + j] *= f;
        }
    }
    let mut out = model.clone();
    out.set_matrix(m)?;
    Ok(out)
}

/// `mat · model(rgb)`: a 3×3 folded into the model's matrix (exact for every kind).
pub(crate) fn premultiplied(model: &Model, mat: &Mat3) -> Result<Model, ModelError> {
    let l = model.len_terms();
    let src = model.matrix();
    let mut m = vec![0.0; 3 * l];
    for i in 0..3 {
        for j in 0..l {
            m[i * l + j] = (0..3).map(|k| mat[i][k] * src[k * l + j]).sum();
        }
    }
    let mut out = model.clone();
    out.set_matrix(m)?;
    Ok(out)
}

/// One calibration illuminant of a model: its white's chromaticity, CCT and camera response.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The white's CIE 1931 chromaticity.
    pub xy: [f64; 2],
    /// Its correlated colour temperature (K).
    pub cct: f64,
    /// The camera RGB the model maps to its white (`invert(model, white_xyz)`).
    pub white_rgb: [f64; 3],
}

impl Calibration {
    /// The calibration of a model: its white, and the camera response it maps to that white,
    /// which must be positive in every channel (a re-balance divides by it).
    pub fn of(model: &Model) -> Result<Calibration, ModelError> {
        let w = model.white_xyz();
        let xy = xyz_to_xy(w).ok_or_else(|| {
            ModelError::Invalid(format!("the model's white {w:?} is not a colour"))
        })?;
        let t = cct(xy).map_err(|e| ModelError::Invalid(e.to_string()))?;
        let white_rgb = invert(model, w).filter(|c| c.iter().all(|v| *v > 0.0)).ok_or_else(|| {
            ModelError::Invalid(format!(
                "no positive camera response maps to the model's white {w:?}: it has no neutral to white-balance by"
            ))
        })?;
        Ok(Calibration {
            xy,
            cct: t,
            white_rgb,
        })
    }
}

/// How close (xy distance) a frame's white must be to a model's training white to be that white
/// (the chromaticity found for a camera neutral by iteration is within about 1e-9 of it).
const OWN_WHITE_XY: f64 = 1e-7;

/// The white of a frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrameWhite {
    /// A chromaticity (a bare temperature is turned into one by
    /// the CIE daylight / Planckian locus).
    Xy([f64; 2]),
    /// The camera response to the frame's white (e.g. a raw file's as-shot neutral), any scale.
    Neutral([f64; 3]),
}

/// One or two calibrated models, ordered by temperature.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    models: Vec<Model>,
    calibrations: Vec<Calibration>,
    /// Per model: the factor that scales its camera response to D50 (`Y = 1`) to a maximum of 1,
    /// as the DNG SDK normalises its colour matrices before interpolating them.
    norms: Vec<f64>,
}

/// A model set combined for one white: the parts sum to the output.
#[derive(Debug, Clone, PartialEq)]
pub struct Combination {
    /// Each part is a whole model (re-balance, Bradford and weight folded in) with the frame's
    /// white as its white; the output is their sum.
    pub parts: Vec<Model>,
    /// The weight of the lower-temperature model (1 for a single model).
    pub weight: f64,
    /// The frame's white: its chromaticity,
    pub xy: [f64; 2],
    /// its correlated colour temperature (K),
    pub cct: f64,
    /// the camera's response to it (G = 1),
    pub neutral: [f64; 3],
    /// and its XYZ (Y = 100).
    pub white_xyz: [f64; 3],
}

impl Combination {
    /// The combined output for one camera RGB (f64 reference).
    pub fn apply_f64(&self, rgb: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for p in &self.parts {
            let y = p.apply_f64(rgb);
            for k in 0..3 {
                out[k] += y[k];
            }
        }
        out
    }
}

fn spec(msg: String) -> ModelError {
    ModelError::Spec(msg)
}

impl Profile {
    /// A single model (the white-balanced application of one model).
    pub fn single(model: Model) -> Result<Profile, ModelError> {
        let c = Calibration::of(&model)?;
        // One model: the neutral's scale does not matter, no normalisation is needed.
        Ok(Profile {
            models: vec![model],
            calibrations: vec![c],
            norms: vec![1.0],
        })
    }

    /// Two models of the same kind and order under different illuminants, in either order (they
    /// are sorted by temperature).
    pub fn dual(a: Model, b: Model) -> Result<Profile, ModelError> {
        if a.kind() != b.kind() || a.order() != b.order() {
            return Err(spec(format!(
                "two models of different kinds cannot be combined: {} order {} and {} order {}",
                a.kind(),
                a.order(),
                b.kind(),
                b.order()
            )));
        }
        if a.kind() == Kind::Prm {
            return Err(spec(
                "a PRM is not exposure-invariant, so re-balancing it by a frame's white changes its output with exposure: combine NSRM, RPRM or LRM models".into(),
            ));
        }
        let (ca, cb) = (Calibration::of(&a)?, Calibration::of(&b)?);
        let apart = (1e6 / ca.cct - 1e6 / cb.cct).abs();
        if apart < MIN_MIRED_APART {
            return Err(spec(format!(
                "the two models' calibration illuminants are {:.0} K and {:.0} K, {apart:.1} mired apart: at least {MIN_MIRED_APART} mired are needed to interpolate between them",
                ca.cct, cb.cct
            )));
        }
        let (na, nb) = (norm_of(&a)?, norm_of(&b)?);
        let mut v = vec![(a, ca, na), (b, cb, nb)];
        v.sort_by(|x, y| x.1.cct.total_cmp(&y.1.cct));
        let mut out = Profile {
            models: Vec::new(),
            calibrations: Vec::new(),
            norms: Vec::new(),
        };
        for (m, c, n) in v {
            out.models.push(m);
            out.calibrations.push(c);
            out.norms.push(n);
        }
        Ok(out)
    }

    /// The models, lower temperature first.
    pub fn models(&self) -> &[Model] {
        &self.models
    }

    /// The models' calibration illuminants, in the order of [`Profile::models`].
    pub fn calibrations(&self) -> &[Calibration] {
        &self.calibrations
    }

    /// Whether the profile holds two models (else one).
    pub fn is_dual(&self) -> bool {
        self.models.len() == 2
    }

    /// The calibration temperatures (the same twice for one model).
    pub fn temperatures(&self) -> [f64; 2] {
        let t = |i: usize| self.calibrations[i.min(self.models.len() - 1)].cct;
        [t(0), t(1)]
    }

    /// The weight of the first model at temperature `t`.
    pub(crate) fn weight(&self, t: f64) -> f64 {
        if self.is_dual() {
            let [t1, t2] = self.temperatures();
            dng_weight(t, t1, t2)
        } else {
            1.0
        }
    }

    fn weights(&self, w: f64) -> Vec<f64> {
        if self.is_dual() {
            vec![w, 1.0 - w]
        } else {
            vec![1.0]
        }
    }

    /// The camera response (normalised as the DNG normalises its matrices) to XYZ `xyz` with the
    /// models mixed by weight `w`: `Σ c_i · k_i · model_i⁻¹(xyz)`.
    pub(crate) fn xyz_to_camera(&self, xyz: [f64; 3], w: f64) -> Option<[f64; 3]> {
        let mut out = [0.0; 3];
        for ((m, k), c) in self.models.iter().zip(&self.norms).zip(self.weights(w)) {
            if c == 0.0 {
                continue;
            }
            let cam = invert(m, xyz)?;
            for j in 0..3 {
                out[j] += c * k * cam[j];
            }
        }
        Some(out)
    }

    /// The XYZ whose mixed camera response ([`xyz_to_camera`](Self::xyz_to_camera)) is `rgb`
    /// (Newton from the models' mixed forward output; exact for LRM in one step).
    pub(crate) fn camera_to_xyz(&self, rgb: [f64; 3], w: f64) -> Option<[f64; 3]> {
        let mut x = [0.0; 3];
        for ((m, k), c) in self.models.iter().zip(&self.norms).zip(self.weights(w)) {
            let y = m.apply_f64(rgb.map(|v| v / k));
            for j in 0..3 {
                x[j] += c * y[j];
            }
        }
        let scale = x.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1e-300);
        let rscale = rgb.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1e-300);
        for _ in 0..50 {
            let f = self.xyz_to_camera(x, w)?;
            let r = [f[0] - rgb[0], f[1] - rgb[1], f[2] - rgb[2]];
            if r.iter().map(|v| v.abs()).fold(0.0, f64::max) <= 1e-13 * rscale {
                return Some(x);
            }
            let mut j = [[0.0; 3]; 3];
            for c in 0..3 {
                let h = 1e-6 * scale;
                let (mut a, mut b) = (x, x);
                a[c] += h;
                b[c] -= h;
                let (fa, fb) = (self.xyz_to_camera(a, w)?, self.xyz_to_camera(b, w)?);
                for k in 0..3 {
                    j[k][c] = (fa[k] - fb[k]) / (2.0 * h);
                }
            }
            let step = spaces::apply(&spaces::invert(&j), r);
            if !step.iter().all(|v| v.is_finite()) {
                return None;
            }
            for c in 0..3 {
                x[c] -= step[c];
            }
        }
        let f = self.xyz_to_camera(x, w)?;
        let err = (0..3).map(|c| (f[c] - rgb[c]).abs()).fold(0.0, f64::max);
        (err <= 1e-9 * rscale).then_some(x)
    }

    /// The camera neutral (G = 1) of a light of chromaticity `xy`: the models' inverse at that
    /// light's XYZ, mixed for its temperature.
    pub(crate) fn neutral_for_xy(&self, xy: [f64; 2]) -> Result<[f64; 3], TemperatureError> {
        let t = cct(xy)?;
        let w = self.weight(t);
        let n = self
            .xyz_to_camera(xy_to_xyz(xy), w)
            .filter(|n| n.iter().all(|v| v.is_finite() && *v > 0.0))
            .ok_or_else(|| {
                TemperatureError::Range(format!(
                    "the camera has no positive response to a light at x, y = {:.4}, {:.4}",
                    xy[0], xy[1]
                ))
            })?;
        Ok(n.map(|v| v / n[1]))
    }

    /// The chromaticity of a camera neutral, by the DNG fixed-point iteration.
    pub(crate) fn xy_for_neutral(&self, neutral: [f64; 3]) -> Result<[f64; 2], TemperatureError> {
        neutral_to_xy(neutral, self.temperatures(), |n, w| {
            self.camera_to_xyz(n, w)
        })
    }

    /// The models combined for a frame's white (DNG's interpolation by inverse temperature), on
    /// DNG's scale: the frame's camera neutral at `G = 1` maps to the white at `Y = 100`.
    pub fn combine(&self, white: FrameWhite) -> Result<Combination, ModelError> {
        self.combine_scaled(white, false)
    }

    /// [`Profile::combine`] on the models' own scale, as `apply --white` writes it: the frame's
    /// neutral at the training white's exposure (its green equal to that of the camera response
    /// each model maps to its training white) maps to the white at `Y = 100`, as that response
    /// does without a white. At a model's own training white the combination is the model.
    pub fn combine_for_apply(&self, white: FrameWhite) -> Result<Combination, ModelError> {
        self.combine_scaled(white, true)
    }

    fn combine_scaled(
        &self,
        white: FrameWhite,
        training_exposure: bool,
    ) -> Result<Combination, ModelError> {
        let te = |e: TemperatureError| spec(e.to_string());
        let (xy, neutral) = match white {
            FrameWhite::Xy(xy) => (xy, self.neutral_for_xy(xy).map_err(te)?),
            FrameWhite::Neutral(n) => {
                if !n.iter().all(|v| v.is_finite() && *v > 0.0) {
                    return Err(spec(format!(
                        "the camera neutral {n:?} must be finite and > 0 in every channel"
                    )));
                }
                let xy = self.xy_for_neutral(n).map_err(te)?;
                (xy, n.map(|v| v / n[1]))
            }
        };
        let t = cct(xy).map_err(te)?;
        let w = self.weight(t);
        let white_xyz = xy_to_xyz(xy).map(|v| v * 100.0);
        let mut parts = Vec::new();
        for ((m, cal), c) in self
            .models
            .iter()
            .zip(&self.calibrations)
            .zip(self.weights(w))
        {
            if c == 0.0 {
                continue;
            }
            // Re-balance: the frame's neutral (at G = 1, or at the training white's exposure)
            // becomes the training white's response.
            let exposure = if training_exposure {
                cal.white_rgb[1]
            } else {
                1.0
            };
            let gains = [0, 1, 2].map(|k| cal.white_rgb[k] / (neutral[k] * exposure));
            let balanced = with_extra_gains(m, gains)?;
            // Model i's white (Y = its white's Y) → the frame's white at Y = 100.
            let adapt = bradford_between(m.white_xyz(), white_xyz);
            let k = c * 100.0 / m.white_xyz()[1];
            let mat = adapt.map(|row| row.map(|v| v * k));
            let part = premultiplied(&balanced, &mat)?;
            // The frame's white adapts exactly to the output space's, unless it is this model's
            // own training white (which may count as D65, as without `--white`).
            let own = (xy[0] - cal.xy[0]).hypot(xy[1] - cal.xy[1]) <= OWN_WHITE_XY;
            parts.push(if own && c == 1.0 {
                part.with_white_xyz(white_xyz)?
            } else {
                part.with_frame_white(white_xyz)?
            });
        }
        Ok(Combination {
            parts,
            weight: w,
            xy,
            cct: t,
            neutral,
            white_xyz,
        })
    }

    /// The file: one model's document as is, two models as the first's with the second added.
    pub fn to_json(&self) -> String {
        if !self.is_dual() {
            return self.models[0].to_json();
        }
        let mut doc: serde_json::Value =
            serde_json::from_str(&self.models[0].to_json()).expect("a model document is JSON");
        let second: serde_json::Value =
            serde_json::from_str(&self.models[1].to_json()).expect("a model document is JSON");
        let cal: Vec<serde_json::Value> = self
            .calibrations
            .iter()
            .map(|c| {
                serde_json::json!({
                    "xy": c.xy,
                    "cct_kelvin": (c.cct * 10.0).round() / 10.0,
                    "camera_white": c.white_rgb,
                })
            })
            .collect();
        let o = doc.as_object_mut().expect("a model document is an object");
        o.insert("version".into(), DUAL_VERSION.into());
        o.insert(CALIBRATION_FIELD.into(), cal.into());
        o.insert(SECOND_FIELD.into(), second);
        let mut s = serde_json::to_string_pretty(&doc).expect("serialises");
        s.push('\n');
        s
    }

    /// Parses a model file holding one or two models.
    pub(crate) fn from_json(text: &str, origin: &str) -> Result<Profile, ModelError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut doc: serde_json::Value =
            serde_json::from_str(text).map_err(|err| ModelError::Parse {
                path: origin.to_string(),
                err,
            })?;
        // A model that parses but has no calibration (an all-zero matrix): the file named.
        let single = |m: Model| {
            Profile::single(m).map_err(|e| match e {
                ModelError::Invalid(why) => ModelError::Invalid(format!("{origin}: {why}")),
                e => e,
            })
        };
        let Some(o) = doc.as_object_mut() else {
            return Model::from_json(text, origin).and_then(single);
        };
        let Some(second) = o.remove(SECOND_FIELD) else {
            return Model::from_json(text, origin).and_then(single);
        };
        o.remove(CALIBRATION_FIELD);
        let first = Model::from_json(&doc.to_string(), origin)?;
        let second = Model::from_json(&second.to_string(), &format!("{origin} ({SECOND_FIELD})"))?;
        Profile::dual(first, second).map_err(|e| ModelError::Invalid(format!("{origin}: {e}")))
    }

    /// Reads a model file holding one or two models.
    pub fn load(path: &Path) -> Result<Profile, ModelError> {
        let origin = path.display().to_string();
        let text = crate::limits::read_text(path).map_err(|err| ModelError::Io {
            path: origin.clone(),
            err,
        })?;
        Profile::from_json(&text, &origin)
    }
}

/// `1 / max(model⁻¹(D50, Y = 1))`: the DNG SDK's normalisation of a colour matrix.
fn norm_of(model: &Model) -> Result<f64, ModelError> {
    let d50 = xy_to_xyz(crate::colorimetry::temperature::D50_XY);
    let scale = model.white_xyz()[1];
    let c = invert(model, d50.map(|v| v * scale))
        .ok_or_else(|| ModelError::Invalid("the model has no camera response to D50".into()))?;
    let m = c.iter().cloned().fold(f64::MIN, f64::max);
    if m.is_finite() && m > 0.0 {
        Ok(1.0 / m)
    } else {
        Err(ModelError::Invalid(format!(
            "the model's camera response to D50, {c:?}, is not positive"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::fit::{fit_with, FitOptions};
    use crate::spectral::{simulate, Camera, Grid, Illuminant, Reflectances};
    use crate::training::TrainingSet;

    /// A Planckian illuminant table (relative power) on 380..780 nm.
    fn planck(t: f64) -> Illuminant {
        let w: Vec<f64> = (380..=780).step_by(5).map(|v| v as f64).collect();
        let v: Vec<f64> = w
            .iter()
            .map(|l| {
                let l = l * 1e-9;
                l.powi(-5) / ((1.438_776_877e-2 / (l * t)).exp_m1()) * 1e-14
            })
            .collect();
        Illuminant::new(crate::spectral::SpectralTable {
            source_name: format!("planck-{t}"),
            wavelengths: w,
            names: vec!["E".into()],
            values: vec![v],
        })
        .unwrap()
    }

    fn data(ill: &Illuminant) -> TrainingSet {
        simulate(
            &Camera::from_name_or_path("nikon-d5100").unwrap(),
            ill,
            &Reflectances::from_name_or_path("rawtoaces-190").unwrap(),
            &Grid::default(),
        )
        .unwrap()
    }

    fn fitted(kind: Kind, d: &TrainingSet) -> Model {
        let o = FitOptions {
            preserve_white: true,
            ..Default::default()
        };
        fit_with(kind, 3, d, &o).unwrap().model
    }

    #[test]
    fn inversion_is_exact_for_lrm_and_converges_for_the_others() {
        let d = data(&Illuminant::from_name_or_path("D65").unwrap());
        for kind in Kind::ALL {
            let m = fitted(kind, &d);
            for &rgb in d.rgb.iter().step_by(17) {
                let x = m.apply_f64(rgb);
                let back = invert(&m, x).unwrap();
                let y = m.apply_f64(back);
                for k in 0..3 {
                    assert!((y[k] - x[k]).abs() < 1e-8 * x[1].abs().max(1.0), "{kind}");
                }
            }
            // The white-preserving fit maps the training white exactly.
            let c = Calibration::of(&m).unwrap();
            let w = d.white_rgb.unwrap();
            for k in 0..3 {
                assert!(
                    (c.white_rgb[k] - w[k]).abs() < 1e-6,
                    "{kind} {:?} {w:?}",
                    c.white_rgb
                );
            }
        }
    }

    #[test]
    fn gains_and_matrices_fold_exactly() {
        let d = data(&Illuminant::from_name_or_path("D65").unwrap());
        let g = [1.3, 1.0, 0.7];
        let mat = [[0.9, 0.1, 0.0], [0.05, 1.0, -0.02], [0.0, 0.03, 1.1]];
        for kind in Kind::ALL {
            let m = fitted(kind, &d);
            let f = premultiplied(&with_extra_gains(&m, g).unwrap(), &mat).unwrap();
            for &rgb in d.rgb.iter().step_by(31) {
                let want = spaces::apply(
                    &mat,
                    m.apply_f64([rgb[0] * g[0], rgb[1] * g[1], rgb[2] * g[2]]),
                );
                let got = f.apply_f64(rgb);
                for k in 0..3 {
                    assert!(
                        (got[k] - want[k]).abs() < 1e-9 * want[1].abs().max(1.0),
                        "{kind}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_grey_under_a_light_between_the_two_comes_out_neutral() {
        let (a, d65) = (
            planck(2856.0),
            Illuminant::from_name_or_path("D65").unwrap(),
        );
        let mid = planck(4000.0);
        let cam = Camera::from_name_or_path("nikon-d5100").unwrap();
        let refl = Reflectances::from_name_or_path("cc24").unwrap();
        let grey = simulate(&cam, &mid, &refl, &Grid::default()).unwrap();
        for kind in [Kind::Lrm, Kind::Rprm, Kind::Nsrm] {
            let p = Profile::dual(fitted(kind, &data(&d65)), fitted(kind, &data(&a)))
                .unwrap_or_else(|e| panic!("{kind}: {e}"));
            assert!(p.temperatures()[0] < 3000.0 && p.temperatures()[1] > 6000.0);
            // The frame's white: the camera's real response to the 4000 K light.
            let n = grey.white_rgb.unwrap();
            let c = p.combine(FrameWhite::Neutral(n)).unwrap();
            assert!((c.cct - 4000.0).abs() < 150.0, "{kind}: {}", c.cct);
            assert!(c.weight > 0.1 && c.weight < 0.9);
            assert_eq!(c.parts.len(), 2);
            // The neutral patches (cc24 19..24, not perfectly flat) come out as they are under
            // that light, a* and b* within half a unit.
            for i in 18..24 {
                let out = crate::colorimetry::xyz_to_lab(c.apply_f64(grey.rgb[i]), c.white_xyz);
                let want = crate::colorimetry::xyz_to_lab(grey.xyz[i], grey.white_xyz);
                assert!(
                    (out[1] - want[1]).abs() < 0.5 && (out[2] - want[2]).abs() < 0.5,
                    "{kind} patch {i}: {out:?} vs {want:?}"
                );
            }
            // The neutral itself is exactly the white.
            let w = c.apply_f64(n);
            for k in 0..3 {
                assert!((w[k] - c.white_xyz[k]).abs() < 1e-6 * 100.0, "{kind} {w:?}");
            }
            // A chromaticity's neutral gives that chromaticity back.
            let xy = crate::colorimetry::temperature::temperature_xy(4500.0).unwrap();
            let nn = p.neutral_for_xy(xy).unwrap();
            let back = p.xy_for_neutral(nn).unwrap();
            assert!(
                (back[0] - xy[0]).abs() < 1e-6 && (back[1] - xy[1]).abs() < 1e-6,
                "{kind}"
            );
        }
    }

    #[test]
    fn refusals_and_file_round_trip() {
        let d = data(&Illuminant::from_name_or_path("D65").unwrap());
        let da = data(&planck(2856.0));
        let e = Profile::dual(fitted(Kind::Nsrm, &d), fitted(Kind::Rprm, &da)).unwrap_err();
        assert!(
            e.to_string().contains("different kinds") && e.is_usage(),
            "{e}"
        );
        let e = Profile::dual(fitted(Kind::Prm, &d), fitted(Kind::Prm, &da)).unwrap_err();
        assert!(
            e.to_string().contains("exposure-invariant") && e.is_usage(),
            "{e}"
        );
        let e = Profile::dual(fitted(Kind::Nsrm, &d), fitted(Kind::Nsrm, &d)).unwrap_err();
        assert!(e.to_string().contains("mired"), "{e}");
        let p = Profile::dual(fitted(Kind::Nsrm, &d), fitted(Kind::Nsrm, &da)).unwrap();
        let text = p.to_json();
        assert!(text.contains(SECOND_FIELD) && text.contains("\"version\": 3"));
        let back = Profile::from_json(&text, "dual.json").unwrap();
        assert_eq!(back.models(), p.models());
        // A single-model reader refuses it clearly; single files still load as one model.
        let e = Model::from_json(&text, "dual.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("two calibration illuminants"), "{e}");
        let single = Profile::from_json(&p.models()[0].to_json(), "one.json").unwrap();
        assert!(!single.is_dual());
    }
}
