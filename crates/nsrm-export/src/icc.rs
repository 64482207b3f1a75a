//! ICC input profiles (version 2, device class `scnr`): camera RGB → PCS XYZ (D50), written with
//! Little CMS 2 (the `lcms2` crate) and evaluated with it.
//!
//! # What is written
//! The PCS is the model's output adapted from its white `W` to the ICC D50 with Bradford and
//! scaled so that `W` lands on the PCS white: `P(c) = Bradford(W → D50) · model(c) / Y(W)`.
//!
//! **Device values.** An ICC profile's device values run from 0 to 1 and an ICC CLUT has no
//! headroom above that, so the camera RGB is normalised: device `d = c / s`, where `s` is the
//! largest channel of `w`, the camera response the model maps to its white (`w` found by
//! inverting the model, exactly for LRM). The model's white so sits at device `w / s` (its
//! largest channel at 1.0) and maps exactly to the PCS white; anything brighter than the white in
//! any channel clips. The exposure range the profile covers is `2^lo .. 1` of that scale
//! (default `lo = −6`: below that the 16-bit PCS XYZ of a lut16 costs
//! more than 0.3 ΔE00 on dark saturated colours).
//!
//! * **LRM** (a 3×3 matrix) is written as matrix/TRC: `rXYZ`, `gXYZ`, `bXYZ` are the columns of
//!   `Bradford · M · s / Y(W)` and the three TRCs are the identity (gamma 1). Exact up to the
//!   s15Fixed16 encoding of the columns.
//! * **PRM, RPRM, NSRM** are written as `A2B0`, a `lut16Type` (the version-2 LUT): per-channel
//!   input curves (4096 entries) holding a logarithmic shaper (`0 → 0`, log2 from
//!   `2^(lo − 2)` up to `1 → 1`, linear below), a 3D CLUT (default 65³) sampled at the exact
//!   inverse of the input curves as they interpolate, and per-channel output curves (4096
//!   entries) decoding a logarithmic encoding of each PCS channel with the same log slope over
//!   `2^(lo − 1) .. 1.99997` (the largest XYZ a lut16 can carry). The CLUT so interpolates a
//!   function that shifts by `t` when the input shifts by `t` along the grey axis (an
//!   exposure-invariant model is exactly so), which keeps the lattice error small across the
//!   whole exposure range.
//!
//! Tags: `desc` and `cprt` from the model's provenance, `wtpt` = D50 and `chad` = the Bradford
//! matrix from the model's white to D50 (the ICC convention for a profile whose white was
//! adapted), and the colorants/TRCs or `A2B0` above. Header: version 2.1 (ArgyllCMS 2.3 refuses
//! version 4), class input, colour space RGB, PCS XYZ.
//!
//! # Measured error
//! [`render`] reads the written bytes back with Little CMS and evaluates them with its float
//! transform (device RGB → `*XYZ`, relative colorimetric): the same code path `transicc`
//! takes. A lut16 is evaluated by Little CMS in 16-bit steps (the input rounded to 1/65535 and
//! the PCS XYZ to 1/32768), which is what limits the darkest exposures. The ΔE00 against the
//! exact model is reported on the training patches and the dense in-gamut set
//! (`measure_fn`) as for the other exports, each sample judged against the PCS white
//! scaled to its exposure.

use super::nodes::LogCurve;
use super::{ErrorReport, ExportError};
use crate::spaces::{self, Mat3};
use lcms2::{
    CIExyY, CIExyYTRIPLE, ColorSpaceSignature, Intent, Locale, PixelFormat, Profile,
    ProfileClassSignature, Tag, TagSignature, ToneCurve, Transform, CIEXYZ, MLU,
};
use nsrm::{Kind, Model};

/// The ICC PCS illuminant (ICC.1, 7.2.16), as the header and `wtpt` carry it.
pub(crate) const D50: [f64; 3] = [0.9642, 1.0, 0.8249];
/// The largest XYZ a lut16 carries (u1Fixed15: `0xFFFF / 0x8000`).
pub(crate) const PCS_MAX: f64 = 65535.0 / 32768.0;
/// Entries of each input and output curve of the lut16 (the format's maximum).
pub(crate) const CURVE_ENTRIES: usize = 4096;
/// Stops below the bottom of the range at which the input shaper's logarithmic part starts.
pub(crate) const TOE_STOPS: f64 = 2.0;
/// The default bottom of the exposure range, log2 of device units (the white's largest channel
/// is device 1.0).
pub const DEFAULT_LO: f64 = -6.0;
/// The CLUT sizes accepted (lut16 allows up to 255; the file is `6·n³` bytes).
pub(crate) const CLUT_SIZES: std::ops::RangeInclusive<usize> = 2..=129;

/// How the profile of a nonlinear model is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IccOptions {
    /// CLUT points per axis (default 65).
    pub size: usize,
    /// log2 of the bottom of the exposure range in device units (the top is 0: the white).
    pub lo: f64,
}

impl Default for IccOptions {
    fn default() -> Self {
        IccOptions {
            size: 65,
            lo: DEFAULT_LO,
        }
    }
}

impl IccOptions {
    /// Checks the options are in range (CLUT size, input range), before any work.
    pub fn check(&self) -> Result<(), ExportError> {
        if !CLUT_SIZES.contains(&self.size) {
            return Err(ExportError::Usage(format!(
                "CLUT size {} is out of range ({}..={})",
                self.size,
                CLUT_SIZES.start(),
                CLUT_SIZES.end()
            )));
        }
        if !(self.lo.is_finite() && (-16.0..=-1.0).contains(&self.lo)) {
            return Err(ExportError::Usage(format!(
                "exposure range 2^{}..2^0 is invalid (need −16 ≤ lo ≤ −1; an ICC CLUT has no headroom above its white, so the top is 0)",
                self.lo
            )));
        }
        Ok(())
    }

    /// The input shaper (device value → CLUT coordinate).
    pub(crate) fn shaper(&self) -> LogCurve {
        LogCurve::zero_to_one((self.lo - TOE_STOPS).exp2(), 1.0)
    }

    /// The encoding of a PCS channel in the CLUT: the same log slope as [`shaper`](Self::shaper)
    /// up to [`PCS_MAX`].
    pub(crate) fn encoding(&self) -> LogCurve {
        LogCurve::zero_to_one((self.lo - TOE_STOPS + 1.0).exp2(), PCS_MAX)
    }
}

/// The model's PCS: `Bradford(W → D50) / Y(W)`, applied to the model's XYZ output.
pub(crate) fn pcs_matrix(model: &Model) -> Result<Mat3, ExportError> {
    let w = model.white_xyz();
    if !(w.iter().all(|v| v.is_finite() && *v > 0.0)) {
        return Err(ExportError::Model(format!(
            "its reference white {w:?} is not positive"
        )));
    }
    let a = nsrm::bradford_between(w, D50);
    Ok(a.map(|r| r.map(|v| v / w[1])))
}

/// The camera RGB scale `s` (device = camera / s) and the device white `w / s`.
pub(crate) fn device_scale(model: &Model) -> Result<(f64, [f64; 3]), ExportError> {
    let w = nsrm::invert_model(model, model.white_xyz())
        .filter(|c| c.iter().all(|v| v.is_finite() && *v > 0.0))
        .ok_or_else(|| {
            ExportError::Model(
                "no positive camera response maps to the model's white: there is nothing to scale the device values by".into(),
            )
        })?;
    let s = w.iter().cloned().fold(0.0, f64::max);
    Ok((s, w.map(|v| v / s)))
}

/// A built profile.
#[derive(Debug, Clone)]
pub(crate) struct IccProfile {
    /// The ICC file.
    pub bytes: Vec<u8>,
    /// Matrix/TRC (LRM) rather than a CLUT.
    pub exact: bool,
    /// Device = camera RGB / `scale`.
    pub scale: f64,
    /// The model's white in device values (largest channel 1).
    pub device_white: [f64; 3],
    /// CLUT points per axis (nonlinear kinds).
    pub clut_size: Option<usize>,
    pub options: IccOptions,
}

fn lcms_err(what: &str) -> impl Fn(lcms2::Error) -> ExportError + '_ {
    move |e| ExportError::Model(format!("Little CMS: {what}: {e}"))
}

fn ascii(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_graphic() || c == ' ' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn mlu(text: &str) -> MLU {
    let mut m = MLU::new(1);
    m.set_text_ascii(&ascii(text), Locale::none());
    m
}

fn xyz(v: [f64; 3]) -> CIEXYZ {
    CIEXYZ {
        X: v[0],
        Y: v[1],
        Z: v[2],
    }
}

/// The input curve as a 16-bit table, strictly increasing.
fn input_table(opts: &IccOptions) -> Result<Vec<u16>, ExportError> {
    let c = opts.shaper();
    let t: Vec<u16> = (0..CURVE_ENTRIES)
        .map(|i| {
            let x = i as f64 / (CURVE_ENTRIES - 1) as f64;
            (c.forward(x).clamp(0.0, 1.0) * 65535.0).round() as u16
        })
        .collect();
    if t.windows(2).any(|p| p[1] <= p[0]) {
        return Err(ExportError::Usage(format!(
            "the exposure range 2^{}..2^0 is too wide for a 16-bit input curve",
            opts.lo
        )));
    }
    Ok(t)
}

/// The device value at which the piecewise-linear 16-bit table `t` reaches `u` (0..1).
fn table_inverse(t: &[u16], u: f64) -> f64 {
    let target = u * 65535.0;
    let n = t.len();
    let i = t.partition_point(|&v| (v as f64) < target);
    if i == 0 {
        return 0.0;
    }
    if i >= n {
        return 1.0;
    }
    let (a, b) = (t[i - 1] as f64, t[i] as f64);
    let f = (target - a) / (b - a);
    ((i - 1) as f64 + f) / (n - 1) as f64
}

/// The `lut16Type` (`mft2`) tag of the CLUT pipeline, as ICC.1:2001 lays it out.
fn mft2(input: &[u16], clut: &[u16], n: usize, output: &[u16]) -> Vec<u8> {
    let mut b = Vec::with_capacity(52 + 12 * CURVE_ENTRIES + 2 * clut.len());
    b.extend_from_slice(b"mft2");
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&[3, 3, n as u8, 0]);
    for i in 0..9 {
        let v: i32 = if i % 4 == 0 { 0x10000 } else { 0 };
        b.extend_from_slice(&v.to_be_bytes());
    }
    b.extend_from_slice(&(CURVE_ENTRIES as u16).to_be_bytes());
    b.extend_from_slice(&(CURVE_ENTRIES as u16).to_be_bytes());
    for _ in 0..3 {
        for v in input {
            b.extend_from_slice(&v.to_be_bytes());
        }
    }
    for v in clut {
        b.extend_from_slice(&v.to_be_bytes());
    }
    for _ in 0..3 {
        for v in output {
            b.extend_from_slice(&v.to_be_bytes());
        }
    }
    b
}

/// A minimal version-2 input profile holding one `A2B0` tag, for Little CMS to parse the tag
/// into a pipeline (the `lcms2` crate builds no pipelines stage by stage).
fn carrier(tag: &[u8]) -> Vec<u8> {
    let size = 128 + 4 + 12 + tag.len();
    let mut h = vec![0u8; 128];
    h[0..4].copy_from_slice(&(size as u32).to_be_bytes());
    h[8..12].copy_from_slice(&0x0210_0000u32.to_be_bytes());
    h[12..16].copy_from_slice(b"scnr");
    h[16..20].copy_from_slice(b"RGB ");
    h[20..24].copy_from_slice(b"XYZ ");
    h[36..40].copy_from_slice(b"acsp");
    for (k, v) in D50.iter().enumerate() {
        let f = (v * 65536.0).round() as i32;
        h[68 + 4 * k..72 + 4 * k].copy_from_slice(&f.to_be_bytes());
    }
    h.extend_from_slice(&1u32.to_be_bytes());
    h.extend_from_slice(b"A2B0");
    h.extend_from_slice(&144u32.to_be_bytes());
    h.extend_from_slice(&(tag.len() as u32).to_be_bytes());
    h.extend_from_slice(tag);
    h
}

/// Builds the profile of `model` (one illuminant): the header, the tags every profile has
/// (`common_tags`), then for LRM the colorants and TRCs (`matrix_tags`), for the others the
/// CLUT sampled from the model (`sample_clut`) written as a lut16 `A2B0` (`lut_tag`).
pub(crate) fn build(model: &Model, opts: IccOptions) -> Result<IccProfile, ExportError> {
    opts.check()?;
    let a = pcs_matrix(model)?;
    let (s, device_white) = device_scale(model)?;
    let pcs = |d: [f64; 3]| spaces::apply(&a, model.apply_f64(d.map(|v| v * s)));

    let mut p = Profile::new_placeholder();
    p.set_version(2.1);
    p.set_device_class(ProfileClassSignature::InputClass);
    p.set_color_space(ColorSpaceSignature::RgbData);
    p.set_pcs(ColorSpaceSignature::XYZData);
    p.set_header_rendering_intent(Intent::Perceptual);
    let mut ok = common_tags(&mut p, model, s, device_white);
    let exact = model.kind() == Kind::Lrm;
    let mut clut_size = None;
    if exact {
        ok = matrix_tags(&mut p, pcs)? && ok;
    } else {
        let input = input_table(&opts)?;
        let clut = sample_clut(&opts, &input, pcs)?;
        ok = lut_tag(&mut p, &opts, &input, &clut)? && ok;
        clut_size = Some(opts.size);
    }
    if !ok {
        return Err(ExportError::Model(
            "Little CMS refused one of the profile's tags".into(),
        ));
    }
    let bytes = p.icc().map_err(lcms_err("serialising the profile"))?;
    Ok(IccProfile {
        bytes,
        exact,
        scale: s,
        device_white,
        clut_size,
        options: opts,
    })
}

/// The tags of every profile: `desc` (the camera space, its scale `s` and white at device
/// `device_white`), `cprt` (the provenance), `wtpt` (D50) and `chad` (Bradford from the model's
/// white to D50). False when Little CMS refused one.
fn common_tags(p: &mut Profile, model: &Model, s: f64, device_white: [f64; 3]) -> bool {
    let name = super::camera_space_name(model);
    let desc = mlu(&format!(
        "{name} (camera RGB / {s:.6}: white at device {:.4} {:.4} {:.4})",
        device_white[0], device_white[1], device_white[2]
    ));
    let cprt = mlu(&format!(
        "Written by nsrm; {}",
        super::provenance_line(model)
    ));
    let wtpt = xyz(D50);
    let chad_m = nsrm::bradford_between(model.white_xyz(), D50);
    // `chad` is a 3×3 s15Fixed16 array; the crate passes it to Little CMS through the type with
    // the same layout (nine f64s, row by row).
    let row = |r: [f64; 3]| CIExyY {
        x: r[0],
        y: r[1],
        Y: r[2],
    };
    let chad = CIExyYTRIPLE {
        Red: row(chad_m[0]),
        Green: row(chad_m[1]),
        Blue: row(chad_m[2]),
    };
    p.write_tag(TagSignature::ProfileDescriptionTag, Tag::MLU(&desc))
        && p.write_tag(TagSignature::CopyrightTag, Tag::MLU(&cprt))
        && p.write_tag(TagSignature::MediaWhitePointTag, Tag::CIEXYZ(&wtpt))
        && p.write_tag(
            TagSignature::ChromaticAdaptationTag,
            Tag::CIExyYTRIPLE(&chad),
        )
}

/// A linear model as matrix/TRC: the colorants are `pcs` of the device primaries, the TRCs
/// the identity. False when Little CMS refused a tag; an error when a colorant is no
/// s15Fixed16 number.
fn matrix_tags(p: &mut Profile, pcs: impl Fn([f64; 3]) -> [f64; 3]) -> Result<bool, ExportError> {
    let cols = [0, 1, 2].map(|k| {
        let mut e = [0.0; 3];
        e[k] = 1.0;
        xyz(pcs(e))
    });
    let gamma = ToneCurve::new(1.0);
    let ok = p.write_tag(TagSignature::RedColorantTag, Tag::CIEXYZ(&cols[0]))
        && p.write_tag(TagSignature::GreenColorantTag, Tag::CIEXYZ(&cols[1]))
        && p.write_tag(TagSignature::BlueColorantTag, Tag::CIEXYZ(&cols[2]))
        && p.write_tag(TagSignature::RedTRCTag, Tag::ToneCurve(&gamma))
        && p.write_tag(TagSignature::GreenTRCTag, Tag::ToneCurve(&gamma))
        && p.write_tag(TagSignature::BlueTRCTag, Tag::ToneCurve(&gamma));
    if !cols.iter().all(|c| {
        [c.X, c.Y, c.Z]
            .iter()
            .all(|v| v.is_finite() && v.abs() < 32767.0)
    }) {
        return Err(ExportError::Model(
            "its matrix columns are not finite s15Fixed16 numbers".into(),
        ));
    }
    Ok(ok)
}

/// The lut16's CLUT (`opts.size`³ nodes, red slowest, 16-bit): `pcs` at the device values the
/// `input` curves map to the lattice, in the PCS encoding. An error when `pcs` is not finite at
/// some node.
fn sample_clut(
    opts: &IccOptions,
    input: &[u16],
    pcs: impl Fn([f64; 3]) -> [f64; 3],
) -> Result<Vec<u16>, ExportError> {
    let n = opts.size;
    let enc = opts.encoding();
    let nodes: Vec<f64> = (0..n)
        .map(|j| table_inverse(input, j as f64 / (n - 1) as f64))
        .collect();
    let mut clut = Vec::with_capacity(3 * n * n * n);
    let mut bad = 0usize;
    let mut first_bad = None;
    for (ir, &r) in nodes.iter().enumerate() {
        for (ig, &g) in nodes.iter().enumerate() {
            for (ib, &b) in nodes.iter().enumerate() {
                let v = pcs([r, g, b]);
                if !v.iter().all(|x| x.is_finite()) {
                    bad += 1;
                    first_bad.get_or_insert((ir, ig, ib, v));
                }
                for x in v {
                    let e = if x.is_finite() { enc.forward(x) } else { 0.0 };
                    clut.push((e.clamp(0.0, 1.0) * 65535.0).round() as u16);
                }
            }
        }
    }
    if let Some((ir, ig, ib, v)) = first_bad {
        return Err(ExportError::Model(format!(
            "its output is not finite at {bad} of the {} CLUT nodes (the first at device RGB {:.4} {:.4} {:.4}: {v:?}): it explodes over the profile's range 2^{}..2^0 of the white",
            n * n * n,
            nodes[ir],
            nodes[ig],
            nodes[ib],
            opts.lo
        )));
    }
    Ok(clut)
}

/// Writes `A2B0`: the lut16 of the `input` curves, the `clut` and output curves decoding the
/// PCS encoding, passed through Little CMS (which reads it back from a carrier profile as a
/// pipeline). False when Little CMS refused the tag.
fn lut_tag(
    p: &mut Profile,
    opts: &IccOptions,
    input: &[u16],
    clut: &[u16],
) -> Result<bool, ExportError> {
    let enc = opts.encoding();
    let output: Vec<u16> = (0..CURVE_ENTRIES)
        .map(|i| {
            let x = enc.inverse(i as f64 / (CURVE_ENTRIES - 1) as f64);
            (x.clamp(0.0, PCS_MAX) * 32768.0).round() as u16
        })
        .collect();
    let carrier_profile = Profile::new_icc(&carrier(&mft2(input, clut, opts.size, &output)))
        .map_err(lcms_err("reading the lut16 back"))?;
    let Tag::Pipeline(pipe) = carrier_profile.read_tag(TagSignature::AToB0Tag) else {
        return Err(ExportError::Model(
            "Little CMS did not read the lut16 back as a pipeline".into(),
        ));
    };
    Ok(p.write_tag(TagSignature::AToB0Tag, Tag::Pipeline(pipe)))
}

/// Evaluates an ICC input profile with Little CMS: device RGB (0..1) → PCS XYZ (D50, `Y = 1`
/// at the white), relative colorimetric, as `transicc -t 1 -o '*XYZ'` does.
pub(crate) struct Evaluator {
    transform: Transform<[f64; 3], [f64; 3]>,
}

impl Evaluator {
    pub(crate) fn new(bytes: &[u8]) -> Result<Evaluator, ExportError> {
        let input = Profile::new_icc(bytes).map_err(lcms_err("reading the profile"))?;
        let transform = Transform::new(
            &input,
            PixelFormat::RGB_DBL,
            &Profile::new_xyz(),
            PixelFormat::XYZ_DBL,
            Intent::RelativeColorimetric,
        )
        .map_err(lcms_err("building a transform"))?;
        Ok(Evaluator { transform })
    }

    pub(crate) fn eval(&self, device: [f64; 3]) -> [f64; 3] {
        let mut out = [[0.0; 3]];
        self.transform.transform_pixels(&[device], &mut out);
        out[0]
    }
}

/// The camera-unit range a profile covers: `[lo + log2 s, log2 s]`.
pub(crate) fn camera_stops(p: &IccProfile) -> [f64; 2] {
    let top = p.scale.log2();
    [p.options.lo + top, top]
}

/// How far above [`PCS_MAX`] a model's output on the in-gamut samples may go before the model is
/// taken to explode over the range (below that, such samples are only left out of the measure).
pub(crate) const EXPLODE_FACTOR: f64 = 2.0;

/// The ΔE00 of the written profile (evaluated by Little CMS) against the exact model, on the
/// training patches and the dense in-gamut set across the profile's range. Samples whose exact
/// output is brighter than a lut16 can carry (a PCS channel above [`PCS_MAX`]; an in-gamut
/// chromaticity at the white's exposure can be) are left out and counted in `out_of_range`
/// with the samples outside the device range. Refuses a model whose output on those samples is
/// not finite or passes [`EXPLODE_FACTOR`] × [`PCS_MAX`]: it explodes over the range.
pub(crate) fn measure(
    p: &IccProfile,
    model: &Model,
    training_rgb: &[[f64; 3]],
) -> Result<ErrorReport, ExportError> {
    if training_rgb.is_empty() {
        return Err(ExportError::Usage(
            "measuring the profile's error needs the training patches' camera RGB".into(),
        ));
    }
    let a = pcs_matrix(model)?;
    let ev = Evaluator::new(&p.bytes)?;
    let exploded = std::cell::Cell::new(0usize);
    let first = std::cell::Cell::new(None::<([f64; 3], [f64; 3])>);
    // Every sample's ΔE00, or None when its exact output is above what the PCS carries.
    let values = std::cell::RefCell::new(Vec::new());
    let report = super::measure_fn(training_rgb, camera_stops(p), true, |c, k| {
        let exact = spaces::apply(&a, model.apply_f64(c));
        if !exact
            .iter()
            .all(|v| v.is_finite() && *v <= EXPLODE_FACTOR * PCS_MAX)
        {
            exploded.set(exploded.get() + 1);
            if first.get().is_none() {
                first.set(Some((c, exact)));
            }
        }
        if !exact.iter().all(|v| *v <= PCS_MAX) {
            values.borrow_mut().push(None);
            return 0.0;
        }
        let got = ev.eval(c.map(|v| v / p.scale));
        let d = nsrm::delta_e00_xyz(exact, got, D50.map(|v| v * k));
        let d = if d.is_finite() { d } else { f64::INFINITY };
        values.borrow_mut().push(Some(d));
        d
    });
    if let Some((c, x)) = first.get() {
        return Err(ExportError::Model(format!(
            "its output leaves what an ICC profile can carry (finite PCS XYZ up to {PCS_MAX:.5}, the white at Y = 1) by more than {EXPLODE_FACTOR}× at {} of the {} training and in-gamut samples across the range 2^{}..2^0 of the white (e.g. camera RGB {:.4} {:.4} {:.4} → XYZ {:.4} {:.4} {:.4}): it explodes over the range",
            exploded.get(),
            report.training.count + report.dense.count,
            p.options.lo,
            c[0],
            c[1],
            c[2],
            x[0],
            x[1],
            x[2]
        )));
    }
    let values = values.into_inner();
    let stats = |v: &[Option<f64>]| {
        let kept: Vec<f64> = v.iter().flatten().copied().collect();
        let count = kept.len();
        super::ErrorStats {
            count,
            mean: if count == 0 {
                0.0
            } else {
                kept.iter().sum::<f64>() / count as f64
            },
            max: kept.iter().cloned().fold(0.0, f64::max),
        }
    };
    let n = training_rgb.len().min(values.len());
    let (tr, dense) = values.split_at(n);
    let bright = values.iter().filter(|v| v.is_none()).count();
    Ok(ErrorReport {
        training: stats(tr),
        dense: stats(dense),
        exposures: report.exposures,
        out_of_range: report.out_of_range + bright,
    })
}

/// What [`render`] built and measured.
#[derive(Debug, Clone)]
pub struct IccWritten {
    /// The error of the profile against the model.
    pub report: ErrorReport,
    /// Matrix/TRC (an LRM: exact) rather than a CLUT.
    pub exact: bool,
    /// Device = camera RGB / `scale`.
    pub scale: f64,
    /// The model's white in device values (largest channel 1).
    pub device_white: [f64; 3],
    /// CLUT points per axis (nonlinear kinds).
    pub clut_size: Option<usize>,
    /// log2 of the bottom of the exposure range in device units.
    pub lo: f64,
    /// The profile's size in bytes.
    pub bytes: usize,
}

/// Builds and measures the ICC profile of `model` and returns its bytes, writing nothing;
/// `max_de00` is checked against the measured error.
pub fn render(
    model: &Model,
    opts: IccOptions,
    training_rgb: &[[f64; 3]],
    max_de00: Option<f64>,
) -> Result<(Vec<u8>, IccWritten), ExportError> {
    super::check_max_de00(max_de00)?;
    let p = build(model, opts)?;
    let report = measure(&p, model, training_rgb)?;
    report.check_limit(max_de00)?;
    let written = IccWritten {
        report,
        exact: p.exact,
        scale: p.scale,
        device_white: p.device_white,
        clut_size: p.clut_size,
        lo: opts.lo,
        bytes: p.bytes.len(),
    };
    Ok((p.bytes, written))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm::{simulate_named, Grid};

    fn data() -> nsrm::TrainingSet {
        simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap()
    }

    #[test]
    fn input_table_inverse_hits_the_lattice() {
        let o = IccOptions::default();
        let t = input_table(&o).unwrap();
        assert_eq!(t[0], 0);
        assert_eq!(t[CURVE_ENTRIES - 1], 65535);
        for j in 0..=64 {
            let u = j as f64 / 64.0;
            let d = table_inverse(&t, u);
            // Forward through the piecewise-linear table.
            let p = d * (CURVE_ENTRIES - 1) as f64;
            let i = (p.floor() as usize).min(CURVE_ENTRIES - 2);
            let f = p - i as f64;
            let back = (t[i] as f64 + f * (t[i + 1] as f64 - t[i] as f64)) / 65535.0;
            assert!((back - u).abs() < 1e-9, "{u} → {d} → {back}");
        }
    }

    #[test]
    fn lrm_profile_is_a_matrix_and_nearly_exact() {
        let d = data();
        let m = nsrm::fit(Kind::Lrm, 1, &d).unwrap();
        let p = build(&m, IccOptions::default()).unwrap();
        assert!(p.exact);
        let prof = Profile::new_icc(&p.bytes).unwrap();
        assert!(prof.is_matrix_shaper());
        assert_eq!(prof.version().floor(), 2.0);
        let r = measure(&p, &m, &d.rgb).unwrap();
        assert!(r.dense.count > 1000, "{}", r.summary());
        assert!(r.max() < 0.01, "{}", r.summary());
        // The model's white is the PCS white.
        let ev = Evaluator::new(&p.bytes).unwrap();
        let w = ev.eval(p.device_white);
        for k in 0..3 {
            assert!((w[k] - D50[k]).abs() < 2e-4, "{w:?}");
        }
    }

    #[test]
    fn nsrm_profile_is_a_lut16_within_its_report() {
        let d = data();
        let m = nsrm::fit(Kind::Nsrm, 3, &d).unwrap();
        let p = build(&m, IccOptions::default()).unwrap();
        assert!(!p.exact);
        let prof = Profile::new_icc(&p.bytes).unwrap();
        assert!(prof.has_tag(TagSignature::AToB0Tag));
        assert!(!prof.is_matrix_shaper());
        // lut16Type ('mft2') in the file.
        assert!(p.bytes.windows(4).any(|w| w == b"mft2"));
        let r = measure(&p, &m, &d.rgb).unwrap();
        assert!(r.max() < 1.0, "{}", r.summary());
        assert!(r.max() > 0.0);
        // A coarse CLUT is measured as coarse.
        let coarse = build(
            &m,
            IccOptions {
                size: 9,
                ..Default::default()
            },
        )
        .unwrap();
        let rc = measure(&coarse, &m, &d.rgb).unwrap();
        assert!(
            rc.max() > 2.0 * r.max(),
            "{} vs {}",
            rc.summary(),
            r.summary()
        );
    }

    #[test]
    fn an_exploding_model_is_refused() {
        let d = data();
        let m = nsrm::fit(Kind::Prm, 3, &d).unwrap();
        let mut mat = m.matrix().to_vec();
        let l = m.len_terms();
        // Blow up the last (cubic) term of every row.
        for i in 0..3 {
            mat[i * l + l - 1] = 1e6;
        }
        let mut bad = m.clone();
        bad.set_matrix(mat).unwrap();
        let e = build(&bad, IccOptions::default())
            .and_then(|p| measure(&p, &bad, &d.rgb))
            .unwrap_err();
        assert!(e.to_string().contains("explodes"), "{e}");
    }

    #[test]
    fn the_clut_samples_the_model_at_the_lattice_and_refuses_what_explodes() {
        let o = IccOptions {
            size: 3,
            ..Default::default()
        };
        let input = input_table(&o).unwrap();
        let clut = sample_clut(&o, &input, |d| d).unwrap();
        assert_eq!(clut.len(), 3 * 27);
        // The corners: device black → 0, device white → the encoding of 1.
        assert_eq!(&clut[..3], &[0, 0, 0]);
        let one = (o.encoding().forward(1.0).clamp(0.0, 1.0) * 65535.0).round() as u16;
        assert_eq!(&clut[78..], &[one; 3]);
        // Red is the slowest axis: node (0, 0, 2) is blue only.
        assert_eq!((clut[6], clut[7], clut[8]), (0, 0, one));
        let e =
            sample_clut(&o, &input, |d| if d[0] > 0.9 { [f64::NAN; 3] } else { d }).unwrap_err();
        assert!(e.to_string().contains("at 9 of the 27 CLUT nodes"), "{e}");
    }

    #[test]
    fn matrix_tags_refuse_colorants_beyond_s15fixed16() {
        let mut p = Profile::new_placeholder();
        assert!(matrix_tags(&mut p, |d| d).unwrap());
        assert!(p.has_tag(TagSignature::GreenColorantTag));
        let mut p = Profile::new_placeholder();
        assert!(matrix_tags(&mut p, |d| d.map(|v| v * 1e5)).is_err());
    }
}
