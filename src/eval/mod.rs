//! Evaluation: leave-one-out (the paper's protocol) and in-sample ΔE00 statistics.

#[cfg(feature = "plot")]
pub mod plot;

use crate::colorimetry::delta_e00_xyz;
use crate::model::fit::{fit_with, FitOptions};
use crate::model::{Kind, ModelError};
use crate::training::TrainingSet;
use rayon::prelude::*;
use serde::Serialize;

/// How predictions are made for the statistics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protocol {
    /// Fit on N−1 patches, predict the one left out, for every patch.
    LeaveOneOut,
    /// Fit on all patches, predict each of them.
    InSample,
}

/// ΔE00 of one patch.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct PatchError {
    /// The patch's label.
    pub label: String,
    /// Its ΔE00 (CIEDE2000) between prediction and reference.
    #[serde(rename = "dE00")]
    pub de00: f64,
}

/// Summary statistics of ΔE00 over the patches.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Stats {
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// 95th percentile (linear interpolation between order statistics).
    pub p95: f64,
    /// Maximum.
    pub max: f64,
}

impl Stats {
    /// Mean, median, 95th percentile (linear interpolation between order statistics, as numpy's
    /// default) and maximum. `values` must not be empty.
    pub fn of(values: &[f64]) -> Stats {
        assert!(!values.is_empty());
        let mut v = values.to_vec();
        v.sort_by(|a, b| a.total_cmp(b));
        let pct = |q: f64| {
            let pos = q * (v.len() - 1) as f64;
            let lo = pos.floor() as usize;
            let hi = pos.ceil() as usize;
            v[lo] + (pos - lo as f64) * (v[hi] - v[lo])
        };
        Stats {
            mean: v.iter().sum::<f64>() / v.len() as f64,
            median: pct(0.5),
            p95: pct(0.95),
            max: v[v.len() - 1],
        }
    }
}

/// The evaluation of one model kind and order on one training set.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EvalResult {
    /// The label of the training set (its illuminant), as the caller gave it.
    pub illuminant: String,
    /// The model kind (`LRM`, `PRM`, `RPRM`, `NSRM`).
    pub model: String,
    /// The order evaluated (LRM: 1).
    pub order: u8,
    /// The number of terms L.
    pub terms: usize,
    /// ΔE00 statistics over the patches.
    #[serde(flatten)]
    pub stats: Stats,
    /// ΔE00 of every patch, in the training set's order.
    pub per_patch: Vec<PatchError>,
    /// Whether the fits evaluated were the f32-guarded ones ([`FitOptions::f32_guard`]); `false`
    /// is the paper's method (each fit exactly as solved).
    pub f32_guard: bool,
    /// How many of the fits evaluated (leave-one-out: one per fold; in-sample: one) would not
    /// survive f32 evaluation as `apply` does it: their measured f32 error
    /// (`model::fit::f32_error_probe`) exceeds [`crate::F32_TOLERANCE_DE00`].
    pub f32_unsafe_fits: usize,
    /// The number of fits evaluated.
    pub fits: usize,
    /// The largest measured f32 error over the fits evaluated (ΔE00).
    pub f32_error_max: f64,
}

/// The measured f32 error of a fit ([`crate::model::fit::FitReport::f32_error_measured`]).
fn f32_error_of(f: &crate::model::fit::Fit) -> f64 {
    f.report.f32_error_measured.unwrap_or(f64::NAN)
}

/// Predicted XYZ for every patch under `protocol`, fitting with `opts`, each with the measured
/// f32 error of the fit that predicted it. Leave-one-out runs the whole procedure (objective,
/// white constraint, λ choice, white balance, the f32 guard if `opts` asks for it) inside every
/// fold, folds in parallel.
pub(crate) fn predict_with(
    kind: Kind,
    order: u8,
    data: &TrainingSet,
    protocol: Protocol,
    opts: &FitOptions,
) -> Result<Vec<([f64; 3], f64)>, ModelError> {
    match protocol {
        Protocol::InSample => {
            let f = fit_with(kind, order, data, opts)?;
            let e = f32_error_of(&f);
            Ok(data.rgb.iter().map(|c| (f.apply_f64(*c), e)).collect())
        }
        Protocol::LeaveOneOut => (0..data.len())
            .into_par_iter()
            .map(|i| {
                let rest: Vec<usize> = (0..data.len()).filter(|&j| j != i).collect();
                let mut fold_opts = opts.clone();
                // A named white patch that is left out cannot serve as its own fold's white: the
                // fold that predicts it is fitted without the constraint (and raw, for NSRM).
                if let crate::model::fit::White::Patch(label) = &opts.white {
                    if &data.labels[i] == label {
                        fold_opts.preserve_white = false;
                        fold_opts.normalise = crate::model::fit::Normalise::Raw;
                    }
                }
                let f = fit_with(kind, order, &data.subset(&rest), &fold_opts)?;
                Ok((f.apply_f64(data.rgb[i]), f32_error_of(&f)))
            })
            .collect(),
    }
}

/// ΔE00 statistics of `kind` at `order` on `data`; `illuminant` labels the result. The fits are
/// the paper's: least squares by SVD, exactly as solved (no f32 guard).
pub fn evaluate(
    kind: Kind,
    order: u8,
    data: &TrainingSet,
    protocol: Protocol,
    illuminant: &str,
) -> Result<EvalResult, ModelError> {
    evaluate_with(
        kind,
        order,
        data,
        protocol,
        illuminant,
        &FitOptions::default().unguarded(),
    )
}

/// [`evaluate`] with a fit variant (its [`FitOptions::f32_guard`] says whether the guarded fits
/// are evaluated; the result counts the fits that would not survive f32 evaluation either way).
pub fn evaluate_with(
    kind: Kind,
    order: u8,
    data: &TrainingSet,
    protocol: Protocol,
    illuminant: &str,
    opts: &FitOptions,
) -> Result<EvalResult, ModelError> {
    let order = kind.effective_order(order);
    let min = match protocol {
        Protocol::LeaveOneOut => 2,
        Protocol::InSample => 1,
    };
    if data.len() < min {
        return Err(ModelError::TooFewPatches {
            kind,
            order,
            terms: crate::model::terms(kind, order).len(),
            patches: data.len().saturating_sub(min - 1),
        });
    }
    let pred = predict_with(kind, order, data, protocol, opts)?;
    let per_patch: Vec<PatchError> = data
        .labels
        .iter()
        .zip(&pred)
        .zip(&data.xyz)
        .map(|((label, (p, _)), t)| PatchError {
            label: label.clone(),
            de00: delta_e00_xyz(*p, *t, data.white_xyz),
        })
        .collect();
    let values: Vec<f64> = per_patch.iter().map(|p| p.de00).collect();
    let errors: Vec<f64> = match protocol {
        Protocol::LeaveOneOut => pred.iter().map(|p| p.1).collect(),
        Protocol::InSample => pred.first().map(|p| p.1).into_iter().collect(),
    };
    // A NaN error (not measured) counts as not surviving.
    let unsafe_fit = |e: &f64| e.is_nan() || *e > crate::model::fit::F32_TOLERANCE_DE00;
    Ok(EvalResult {
        illuminant: illuminant.to_string(),
        model: kind.name().to_string(),
        order,
        terms: crate::model::terms(kind, order).len(),
        stats: Stats::of(&values),
        per_patch,
        f32_guard: opts.f32_guard,
        f32_unsafe_fits: errors.iter().filter(|e| unsafe_fit(e)).count(),
        fits: errors.len(),
        f32_error_max: errors.iter().copied().fold(0.0, f64::max),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_match_numpy_conventions() {
        let s = Stats::of(&[4.0, 1.0, 3.0, 2.0]);
        assert_eq!(s.mean, 2.5);
        assert_eq!(s.median, 2.5);
        assert_eq!(s.max, 4.0);
        // numpy.percentile([1,2,3,4], 95) = 3.85
        assert!((s.p95 - 3.85).abs() < 1e-12);
        let s = Stats::of(&[7.0]);
        assert_eq!((s.mean, s.median, s.p95, s.max), (7.0, 7.0, 7.0, 7.0));
    }
}
