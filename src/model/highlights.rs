//! Highlights that stay white: what happens to camera RGB at and just below the sensor's clip
//! level, before the model's pixel program.
//!
//! # Why
//! Where one channel of the sensor clips (a blown window, a specular highlight), the other two
//! keep rising until they clip too. The recorded ratio then says nothing about the scene's
//! colour: a fully clipped pixel is `(c_R, c_G, c_B)`, the clip levels, which for a raw file are
//! the same number in every channel. A model maps that to whatever colour the camera's raw
//! `(1, 1, 1)` is under the light it was fitted for: cyan or magenta, never white (the camera's
//! white under tungsten is about `(0.69, 1, 0.43)`). RawTherapee and darktable clip such pixels
//! to white by default.
//!
//! # The policy ([`Highlights`])
//! With clip levels `c` (per channel, in the model's input: the camera RGB the model reads) and
//! the model's camera neutral `w` (the camera RGB it maps to its white, [`camera_neutral`]):
//!
//! * the **brightest plausible neutral** is `n = k·w` with `k = min_i c_i / w_i`: the brightest
//!   grey the sensor records without clipping. The model maps it to its white (LRM, RPRM and NSRM
//!   scale with exposure; PRM, which does not, is solved again at that luminance:
//!   [`brightest_neutral`]);
//! * each pixel's **clip ratio** is `m = max_i x_i / c_i`, and its weight
//!   `t = smoothstep(BLEND_FROM, 1, m)` (0 below `BLEND_FROM` of the clip, 1 at or above it, a
//!   smooth cubic in between, so there is no edge where the blend starts);
//! * the pixel becomes `mix(x, n, t) = x·(1−t) + n·t`: unchanged below the blend, the brightest
//!   plausible neutral at or above the clip, a smooth desaturation in between;
//! * **non-finite pixels** (NaN or ±Inf in any channel) pass unchanged, so the pixel policy of
//!   [`super::pixel`] (NaN / Inf propagate) holds; black, negative and dark pixels are below the
//!   blend and unchanged too.
//!
//! The f64 [`Highlights::map`] is the reference; [`Highlights::map_f32`] is the f32 code of the
//! fast CPU kernels, the same operations in the same order as `shaders/highlights.wgsl`, which the
//! GPU path runs (its parameters are the uniform's `clip` and `neutral`, from
//! [`Highlights::uniform`]). A [`super::Model`] carries its policy ([`super::Model::with_highlights`]):
//! `apply_f64`, the fast CPU path and the GPU engine all read it from there.

use super::{Model, ModelError};

/// Where the blend towards the neutral starts, as a fraction of the clip level: 0.9 (0.15 stop
/// below the clip). Below it nothing changes.
pub(crate) const BLEND_FROM: f64 = 0.9;

/// The highlight policy of a model: clipped camera RGB goes to the brightest plausible neutral
/// (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Highlights {
    /// The clip level of each channel, in the model's input (camera RGB).
    clip: [f64; 3],
    /// The brightest plausible neutral `k·w` (camera RGB).
    neutral: [f64; 3],
}

impl Highlights {
    /// The policy for `model` (in its XYZ output, before an output space is folded in) with the
    /// sensor's clip levels `clip` in the model's input.
    pub(crate) fn for_model(model: &Model, clip: [f64; 3]) -> Result<Highlights, ModelError> {
        Highlights::for_parts(&[model], clip)
    }

    /// The policy for the sum of `parts` (one model, or a combination's; in XYZ) with clip
    /// levels `clip`: towards [`brightest_neutral`].
    pub(crate) fn for_parts(parts: &[&Model], clip: [f64; 3]) -> Result<Highlights, ModelError> {
        let neutral = brightest_neutral(parts, clip)?;
        if !neutral
            .iter()
            .all(|v| v.is_finite() && *v > 0.0 && (*v as f32).is_finite())
        {
            return Err(ModelError::NoNeutral(neutral));
        }
        Ok(Highlights { clip, neutral })
    }

    /// The brightest plausible neutral (camera RGB).
    #[cfg(test)]
    pub(crate) fn neutral(&self) -> [f64; 3] {
        self.neutral
    }

    /// The f64 reference: one camera RGB through the policy.
    pub(crate) fn map(&self, x: [f64; 3]) -> [f64; 3] {
        if !x.iter().all(|v| v.is_finite()) {
            return x;
        }
        let m = (0..3)
            .map(|i| x[i] / self.clip[i])
            .fold(f64::NEG_INFINITY, f64::max);
        let t = smoothstep(BLEND_FROM, 1.0, m);
        if t <= 0.0 {
            return x;
        }
        [0, 1, 2].map(|i| x[i] * (1.0 - t) + self.neutral[i] * t)
    }

    /// The f32 code the fast CPU kernels run, operation for operation `shaders/highlights.wgsl`.
    #[inline]
    pub(crate) fn map_f32(p: &HighlightsF32, x: [f32; 3]) -> [f32; 3] {
        if !x.iter().all(|v| v.is_finite()) {
            return x;
        }
        let m = (x[0] / p.clip[0])
            .max(x[1] / p.clip[1])
            .max(x[2] / p.clip[2]);
        let t = smoothstep_f32(BLEND_FROM as f32, 1.0, m);
        if t <= 0.0 {
            return x;
        }
        [0, 1, 2].map(|i| x[i] * (1.0 - t) + p.neutral[i] * t)
    }

    /// The f32 parameters of the fast CPU path and the shader.
    pub fn to_f32(self) -> HighlightsF32 {
        HighlightsF32 {
            clip: self.clip.map(|v| v as f32),
            neutral: self.neutral.map(|v| v as f32),
        }
    }

    /// The shader uniform's two vectors (`shaders/model_uniform.wgsl`): `clip` with `w = 1`
    /// (the policy is on) and `neutral`. [`uniform_off`] when there is no policy.
    #[cfg(feature = "gpu")]
    pub(crate) fn uniform(policy: Option<&Highlights>) -> [[f32; 4]; 2] {
        match policy {
            Some(h) => {
                let p = h.to_f32();
                [
                    [p.clip[0], p.clip[1], p.clip[2], 1.0],
                    [p.neutral[0], p.neutral[1], p.neutral[2], 0.0],
                ]
            }
            None => uniform_off(),
        }
    }
}

/// The uniform's two vectors with no policy (`clip.w = 0`: the shader passes pixels unchanged).
#[cfg(feature = "gpu")]
pub(crate) fn uniform_off() -> [[f32; 4]; 2] {
    [[1.0, 1.0, 1.0, 0.0], [0.0; 4]]
}

/// [`Highlights`] in f32, as the fast kernels and the shader hold it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HighlightsF32 {
    /// The clip levels `c`, per channel, in the model's input.
    pub clip: [f32; 3],
    /// The camera RGB a clipped pixel is pulled to (the brightest neutral under the clip).
    pub neutral: [f32; 3],
}

impl HighlightsF32 {
    /// Runs the policy over whole pixels of `data` (`C` channels each, alpha untouched).
    pub fn apply<const C: usize>(&self, data: &mut [f32]) {
        for px in data.chunks_exact_mut(C) {
            let y = Highlights::map_f32(self, [px[0], px[1], px[2]]);
            px[..3].copy_from_slice(&y);
        }
    }
}

/// WGSL's `smoothstep`: `t = clamp((x − lo)/(hi − lo), 0, 1)`, `t²(3 − 2t)`.
fn smoothstep(lo: f64, hi: f64, x: f64) -> f64 {
    let t = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// [`smoothstep`] in f32.
fn smoothstep_f32(lo: f32, hi: f32, x: f32) -> f32 {
    let t = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn check_clip(clip: [f64; 3]) -> Result<(), ModelError> {
    if clip
        .iter()
        .all(|c| c.is_finite() && *c > 0.0 && (*c as f32).is_finite())
    {
        Ok(())
    } else {
        Err(ModelError::ClipLevel(clip))
    }
}

/// How clipped highlights are handled (`--highlights`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum HighlightMode {
    /// Clipped pixels to the brightest plausible neutral (white), blended in just below the clip.
    #[cfg_attr(feature = "clap", value(name = "clip"))]
    Clip,
    /// The raw mapping, whatever colour it gives.
    #[cfg_attr(feature = "clap", value(name = "keep"))]
    Keep,
}

impl HighlightMode {
    /// Every mode with its name.
    pub const ALL: [(HighlightMode, &'static str); 2] =
        [(HighlightMode::Clip, "clip"), (HighlightMode::Keep, "keep")];

    /// Parses `clip` or `keep` (the flag's values are checked against it).
    pub fn parse(s: &str) -> Option<HighlightMode> {
        Self::ALL
            .iter()
            .find(|(_, n)| n.eq_ignore_ascii_case(s.trim()))
            .map(|(m, _)| *m)
    }
}

/// The clip level a frame's highlights are handled at, or `None` to keep the raw mapping:
/// * `Keep` → `None`;
/// * a level given (`level`, every channel) → that level, for every frame;
/// * else the frame's own (a camera raw file's white level, `frame`) → that;
/// * else (EXR, TIFF, JPEG: no level known) → `None` by default, and an error when `Clip` was
///   asked for explicitly ([`ModelError::NoClipLevel`]).
pub(crate) fn frame_clip(
    mode: Option<HighlightMode>,
    level: Option<f64>,
    frame: Option<[f32; 3]>,
) -> Result<Option<[f64; 3]>, ModelError> {
    if mode == Some(HighlightMode::Keep) {
        return Ok(None);
    }
    if let Some(v) = level {
        check_clip([v; 3])?;
        return Ok(Some([v; 3]));
    }
    match (frame, mode) {
        (Some(c), _) => Ok(Some(c.map(f64::from))),
        (None, Some(HighlightMode::Clip)) => Err(ModelError::NoClipLevel),
        (None, _) => Ok(None),
    }
}

/// The camera RGB that the sum of `parts` (one model, or the models a two-illuminant
/// combination sums) maps to the white of the first at `Y = 1` (the training white at the
/// training exposure), started from the grey whose output has `Y = 1` ([`neutral_at`]). The
/// models are in XYZ (no output space folded in), their highlight policy not applied.
pub(crate) fn camera_neutral(parts: &[&Model]) -> Result<[f64; 3], ModelError> {
    let y1 = sum_of(parts, [1.0; 3])[1];
    let s = if y1.is_finite() && y1 > 0.0 {
        1.0 / y1
    } else {
        1.0
    };
    neutral_at(parts, 1.0, [s; 3])
}

/// The brightest plausible neutral for clip levels `clip`: the camera RGB that `parts` map to
/// their white, at the luminance where its largest channel (relative to its clip level) is at the
/// clip. For LRM, RPRM and NSRM (which scale with exposure) the neutral at `Y = 1` scaled by
/// `k = min_i clip_i / w_i`; PRM is solved again at that luminance until its largest channel is
/// at the clip (a few fixed-point steps; where the solve fails there, the scaled neutral).
pub(crate) fn brightest_neutral(parts: &[&Model], clip: [f64; 3]) -> Result<[f64; 3], ModelError> {
    check_clip(clip)?;
    let w = camera_neutral(parts)?;
    let ratio = |n: [f64; 3]| {
        (0..3)
            .map(|i| n[i] / clip[i])
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let k = 1.0 / ratio(w);
    let mut n = w.map(|v| v * k);
    let mut y = k;
    for _ in 0..8 {
        let Ok(m) = neutral_at(parts, y, n) else {
            break;
        };
        let r = ratio(m);
        n = m;
        if (r - 1.0).abs() < 1e-12 {
            break;
        }
        y /= r;
    }
    // Exactly at the clip, whatever the last step left.
    let r = ratio(n);
    Ok(n.map(|v| v / r))
}

/// The sum of `parts`' outputs (f64, no highlight policy).
fn sum_of(parts: &[&Model], x: [f64; 3]) -> [f64; 3] {
    let mut y = [0.0; 3];
    for m in parts {
        let p = m.apply_f64_plain(x);
        for k in 0..3 {
            y[k] += p[k];
        }
    }
    y
}

/// The camera RGB that the sum of `parts` maps to `y` times the first's white (at `Y = 1`):
/// Newton's method on the f64 reference (a numerical Jacobian, steps halved until the residual
/// falls) from `start`. Errors when it does not converge or the answer has a channel at or
/// below 0.
fn neutral_at(parts: &[&Model], y: f64, start: [f64; 3]) -> Result<[f64; 3], ModelError> {
    let Some(first) = parts.first() else {
        return Err(ModelError::NoNeutral([f64::NAN; 3]));
    };
    let wx = first.white_xyz();
    let target = wx.map(|v| y * v / wx[1]);
    let f = |x: [f64; 3]| -> [f64; 3] {
        let o = sum_of(parts, x);
        [o[0] - target[0], o[1] - target[1], o[2] - target[2]]
    };
    let norm = |r: [f64; 3]| r.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut x = start;
    let mut r = f(x);
    for _ in 0..100 {
        if norm(r) < 1e-12 * y {
            break;
        }
        let Some(step) = newton_step(&f, x, r) else {
            break;
        };
        let mut lambda = 1.0;
        let mut improved = false;
        while lambda > 1e-6 {
            let cand = [0, 1, 2].map(|i| x[i] - lambda * step[i]);
            let rc = f(cand);
            if norm(rc) < norm(r) {
                x = cand;
                r = rc;
                improved = true;
                break;
            }
            lambda *= 0.5;
        }
        if !improved {
            break;
        }
    }
    let converged = norm(r) <= 1e-9 * y; // false for NaN
    if !converged || !x.iter().all(|v| v.is_finite() && *v > 0.0) {
        return Err(ModelError::NoNeutral(x));
    }
    Ok(x)
}

/// One Newton step `J⁻¹·r` at `x` (central differences), or `None` when `J` is singular.
fn newton_step(f: &impl Fn([f64; 3]) -> [f64; 3], x: [f64; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let mut j = [[0.0; 3]; 3];
    for c in 0..3 {
        let h = 1e-6 * x[c].abs().max(1e-6);
        let (mut a, mut b) = (x, x);
        a[c] += h;
        b[c] -= h;
        let (fa, fb) = (f(a), f(b));
        for (row, (p, q)) in j.iter_mut().zip(fa.iter().zip(fb.iter())) {
            row[c] = (p - q) / (2.0 * h);
        }
    }
    let det = j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1])
        - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0]);
    if !det.is_finite() || det.abs() < 1e-300 {
        return None;
    }
    let col = |k: usize| -> [[f64; 3]; 3] {
        let mut m = j;
        for (row, v) in m.iter_mut().zip(r.iter()) {
            row[k] = *v;
        }
        m
    };
    let d3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    Some([0, 1, 2].map(|k| d3(col(k)) / det))
}

/// What a batch does with each frame's highlights: the mode and level asked for, and the models
/// it applies (summed; in XYZ, no output space folded in).
#[derive(Debug, Clone)]
pub struct FrameHighlights {
    mode: Option<HighlightMode>,
    level: Option<f64>,
    parts: Vec<Model>,
}

impl FrameHighlights {
    /// The policy asked for (`mode`, `level`: a level given holds for every frame, else each
    /// frame's own clip level is used, and `Keep` turns the policy off) for the sum of `parts`.
    pub fn new(
        mode: Option<HighlightMode>,
        level: Option<f64>,
        parts: &[&Model],
    ) -> FrameHighlights {
        FrameHighlights {
            mode,
            level,
            parts: parts.iter().map(|m| (*m).clone()).collect(),
        }
    }

    /// The policy for a frame whose own clip level is `frame` (a camera raw file's), for the
    /// models given, or `parts` in place of them where the models change per frame (a
    /// combination for the frame's white). `None`: the raw mapping is kept.
    pub fn policy(
        &self,
        frame: Option<[f32; 3]>,
        parts: Option<&[Model]>,
    ) -> Result<Option<Highlights>, ModelError> {
        let Some(clip) = frame_clip(self.mode, self.level, frame)? else {
            return Ok(None);
        };
        let parts: Vec<&Model> = parts.unwrap_or(&self.parts).iter().collect();
        Highlights::for_parts(&parts, clip).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colorimetry::xyz_to_lab;
    use crate::kit::{fitted_models, policy_frame, policy_pixels, simulated};
    use crate::model::fast::{FastModel, Threads};
    use crate::{fit, Frame, Kind, Layout};

    /// a*, b* of a model output (XYZ, white at Y = 1) against the model's white.
    fn chroma(model: &Model, xyz: [f64; 3]) -> f64 {
        let w = model.white_xyz().map(|v| v / model.white_xyz()[1]);
        let lab = xyz_to_lab(xyz, w);
        lab[1].hypot(lab[2])
    }

    /// Tungsten light: the camera's white is far from (1, 1, 1), as on the real DNG.
    fn tungsten_models() -> Vec<Model> {
        let data = simulated("A", "cc24");
        Kind::ALL
            .iter()
            .map(|&k| fit(k, if k == Kind::Lrm { 1 } else { 2 }, &data).unwrap())
            .collect()
    }

    #[test]
    fn the_camera_neutral_maps_to_the_white() {
        for m in fitted_models().iter().chain(&tungsten_models()) {
            let w = camera_neutral(&[m]).unwrap();
            let y = m.apply_f64(w);
            let white = m.white_xyz().map(|v| v / m.white_xyz()[1]);
            for k in 0..3 {
                assert!((y[k] - white[k]).abs() < 1e-9, "{} {w:?}: {y:?}", m.kind());
            }
        }
    }

    /// A synthetic sensor clipping at known levels: fully and partly clipped pixels come out
    /// neutral with the policy, coloured without it; pixels below the blend are untouched.
    #[test]
    fn clipped_pixels_go_neutral_at_a_known_clip_level() {
        let clip = [0.8, 0.8, 0.8];
        for m in tungsten_models() {
            let h = Highlights::for_model(&m, clip).unwrap();
            let with = m.clone().with_highlights(Some(clip)).unwrap();
            // All three channels clipped, two clipped, one clipped (G, the brightest under A).
            for x in [
                [0.8, 0.8, 0.8],
                [0.8, 0.8, 0.5],
                [0.55, 0.8, 0.3],
                [0.9, 1.2, 0.85],
            ] {
                let clipped = chroma(&m, with.apply_f64(x));
                assert!(clipped < 0.5, "{} {x:?}: chroma {clipped}", m.kind());
            }
            let keep = chroma(&m, m.apply_f64(clip));
            assert!(keep > 10.0, "{}: the raw mapping's chroma {keep}", m.kind());
            // The brightest plausible neutral has a channel at the clip and none above it.
            let n = h.neutral();
            assert!((0..3).all(|i| n[i] <= clip[i] * (1.0 + 1e-12)));
            assert!((0..3).any(|i| (n[i] - clip[i]).abs() < 1e-12));
            // Below the blend (0.9 of the clip) nothing changes, bit for bit.
            for x in [[0.5, 0.7, 0.3], [0.1, 0.2, 0.05], [0.71, 0.71, 0.71]] {
                assert_eq!(with.apply_f64(x), m.apply_f64(x), "{x:?}");
            }
        }
    }

    /// The blend is continuous: along a ramp through the blend start and the clip, no step
    /// between neighbours is much larger than the ramp's own step.
    #[test]
    fn the_blend_has_no_edge() {
        let h = Highlights {
            clip: [1.0; 3],
            neutral: [0.6, 1.0, 0.4],
        };
        let colour = [0.3, 1.0, 0.9];
        let n = 2000;
        let mut last = h.map(colour.map(|v| v * 0.8));
        for i in 1..=n {
            let k = 0.8 + 0.4 * i as f64 / n as f64;
            let y = h.map(colour.map(|v| v * k));
            let step = (0..3).map(|c| (y[c] - last[c]).abs()).fold(0.0, f64::max);
            assert!(step < 20.0 * 0.4 / n as f64, "k = {k}: step {step}");
            last = y;
        }
        assert_eq!(last, h.neutral());
    }

    /// NaN, ±Inf, black, negatives and dark pixels: the policy changes none of them, so the
    /// pixel policy holds with it as without.
    #[test]
    fn the_pixel_policy_is_unchanged() {
        for m in fitted_models() {
            let with = m.clone().with_highlights(Some([1.0; 3])).unwrap();
            for (name, x) in policy_pixels(m.kind()) {
                let x = x.map(f64::from);
                let m_max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                if x.iter().all(|v| v.is_finite()) && m_max >= BLEND_FROM {
                    continue; // a bright pixel: the policy's business
                }
                let (a, b) = (m.apply_f64(x), with.apply_f64(x));
                for k in 0..3 {
                    assert!(
                        a[k].to_bits() == b[k].to_bits() || (a[k].is_nan() && b[k].is_nan()),
                        "{} {name} {x:?}: {a:?} vs {b:?}",
                        m.kind()
                    );
                }
            }
            let f = policy_frame(&policy_pixels(m.kind()));
            let (mut a, mut b) = (f.clone(), f.clone());
            FastModel::new(&with).apply(&mut a, Threads::Single);
            with.apply_frame_f64(&mut b);
            for (p, q) in a.data.iter().zip(&b.data) {
                assert!(p.is_nan() == q.is_nan() && (p.is_finite() == q.is_finite()));
            }
        }
    }

    /// The fast CPU path runs the policy as the f64 reference does, on pixels spread across
    /// the blend and the clip (RGB and RGBA, alpha untouched).
    #[test]
    fn the_fast_path_follows_the_reference() {
        for m in tungsten_models() {
            let with = m.clone().with_highlights(Some([0.9, 0.95, 1.0])).unwrap();
            for layout in [Layout::Rgb, Layout::Rgba] {
                let ch = layout.channels();
                let n = 3000;
                let mut f = Frame::new(n, 1, layout);
                for (i, px) in f.data.chunks_exact_mut(ch).enumerate() {
                    let k = 0.5 + 0.7 * i as f32 / n as f32;
                    let hue = (i % 7) as f32 / 7.0;
                    px[0] = k * (0.3 + 0.7 * hue);
                    px[1] = k;
                    px[2] = k * (1.0 - 0.6 * hue);
                    if ch == 4 {
                        px[3] = i as f32;
                    }
                }
                let (mut fast, mut refr) = (f.clone(), f.clone());
                FastModel::new(&with).apply(&mut fast, Threads::All);
                with.apply_frame_f64(&mut refr);
                let mut changed = 0;
                let mut plain = f.clone();
                FastModel::new(&m).apply(&mut plain, Threads::All);
                for (i, ((a, b), p)) in fast
                    .data
                    .chunks_exact(ch)
                    .zip(refr.data.chunks_exact(ch))
                    .zip(plain.data.chunks_exact(ch))
                    .enumerate()
                {
                    for k in 0..3 {
                        let tol = 1e-5 * b[k].abs().max(1e-2);
                        assert!(
                            (a[k] - b[k]).abs() <= tol,
                            "{} {i}: {a:?} vs {b:?}",
                            m.kind()
                        );
                    }
                    if ch == 4 {
                        assert_eq!(a[3].to_bits(), f.data[i * 4 + 3].to_bits());
                    }
                    if (0..3).any(|k| (a[k] - p[k]).abs() > 1e-3 * p[k].abs()) {
                        changed += 1;
                    }
                }
                assert!(
                    changed > n / 4,
                    "{}: the policy changed {changed} pixels",
                    m.kind()
                );
            }
        }
    }

    #[test]
    fn which_frames_are_clipped() {
        use HighlightMode::{Clip, Keep};
        let raw = Some([1.0f32, 0.98, 1.0]);
        assert_eq!(
            frame_clip(None, None, raw).unwrap(),
            Some([1.0, 0.98f32 as f64, 1.0])
        );
        assert_eq!(frame_clip(Some(Keep), Some(2.0), raw).unwrap(), None);
        assert_eq!(frame_clip(None, Some(2.0), raw).unwrap(), Some([2.0; 3]));
        assert_eq!(frame_clip(None, Some(2.0), None).unwrap(), Some([2.0; 3]));
        // EXR / TIFF: kept by default; clipping asked for needs a level.
        assert_eq!(frame_clip(None, None, None).unwrap(), None);
        assert!(matches!(
            frame_clip(Some(Clip), None, None),
            Err(ModelError::NoClipLevel)
        ));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e39] {
            assert!(matches!(
                frame_clip(None, Some(bad), raw),
                Err(ModelError::ClipLevel(_))
            ));
        }
        assert_eq!(HighlightMode::parse(" CLIP"), Some(Clip));
        assert_eq!(HighlightMode::parse("reconstruct"), None);
    }
}
