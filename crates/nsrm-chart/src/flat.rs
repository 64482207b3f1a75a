//! Uneven light on the chart. The irradiance over a chart is rarely uniform; it is estimated
//! either from a flat frame (a grey card or any uniform surface shot under the same light, same
//! framing) or from the chart's own neutral patches, and divided out of the patch readings.
//!
//! * [`from_flat_frame`]: the flat's mean over each patch's sampled area, per channel, normalised
//!   to 1 on average over the patches.
//! * [`from_neutrals`]: the neutral patches' measured/reference ratio `G / Y` fitted by a smooth
//!   low-order surface over chart coordinates — quadratic (`1, u, v, u², uv, v²`) when the neutrals
//!   span both directions well enough (the SG's border), else planar, else linear along the one
//!   direction they span (the CC24's bottom row) — evaluated at every patch and normalised to 1
//!   on average.
//!
//! The estimated non-uniformity is `max / min` of the factor over the patches.

use super::extract::{cell_means, sample_side, ExtractOptions, Extraction};
use super::reference::Reference;
use super::ChartError;
use nsrm::xyz_to_lab;
use nsrm::Frame;
use nsrm::Param;

/// Light factors per patch (per channel), to divide the readings by.
#[derive(Debug, Clone, PartialEq)]
pub struct Flat {
    /// `flat` or `neutrals`.
    pub method: String,
    /// The factor per patch and channel (mean 1 per channel).
    pub(crate) factors: Vec<[f64; 3]>,
    /// max / min of the (green) factor over the patches.
    pub nonuniformity: f64,
    /// Patches the surface was fitted on (`neutrals`).
    pub(crate) fitted_on: usize,
}

fn finish(method: &str, mut factors: Vec<[f64; 3]>, fitted_on: usize) -> Result<Flat, ChartError> {
    let n = factors.len() as f64;
    for k in 0..3 {
        let mean = factors.iter().map(|f| f[k]).sum::<f64>() / n;
        if !(mean > 0.0 && mean.is_finite()) {
            return Err(ChartError::Invalid(format!(
                "{method}: the light estimate is not positive"
            )));
        }
        for f in factors.iter_mut() {
            f[k] /= mean;
        }
    }
    if factors
        .iter()
        .flatten()
        .any(|&v| !(v > 0.05 && v.is_finite()))
    {
        return Err(ChartError::Implausible(format!(
            "{method}: the light varies more than 20× over the chart; not a usable flat"
        )));
    }
    let g: Vec<f64> = factors.iter().map(|f| f[1]).collect();
    let max = g.iter().copied().fold(f64::MIN, f64::max);
    let min = g.iter().copied().fold(f64::MAX, f64::min);
    Ok(Flat {
        method: method.to_string(),
        factors,
        nonuniformity: max / min,
        fitted_on,
    })
}

/// Light factors from a flat frame of the same size as the chart frame.
pub(crate) fn from_flat_frame(
    flat: &Frame,
    frame_size: (usize, usize),
    ex: &Extraction,
    opts: &ExtractOptions,
) -> Result<Flat, ChartError> {
    if (flat.width, flat.height) != frame_size {
        return Err(ChartError::value(
            Param::Flat,
            format!(
                "the flat frame is {}×{}, the chart frame {}×{}",
                flat.width, flat.height, frame_size.0, frame_size.1
            ),
        ));
    }
    let means = cell_means(flat, ex.chart, &ex.homography, sample_side(ex.chart, opts));
    let factors = means
        .into_iter()
        .map(|m| {
            m.ok_or_else(|| ChartError::value(Param::Flat, "a patch is outside the flat frame"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    finish("flat frame", factors, 0)
}

/// Light factors from the neutral patches (reference chroma C*ab < 4, unflagged).
pub(crate) fn from_neutrals(ex: &Extraction, reference: &Reference) -> Result<Flat, ChartError> {
    let kind = ex.chart;
    let mut pts = Vec::new();
    for (i, p) in ex.patches.iter().enumerate() {
        let lab = xyz_to_lab(reference.xyz[i], reference.white);
        if lab[1].hypot(lab[2]) < 4.0 && p.usable() && reference.xyz[i][1] > 1.0 {
            let c = kind.cell_centre(i);
            pts.push((c, p.rgb[1] / reference.xyz[i][1]));
        }
    }
    if pts.len() < 3 {
        return Err(ChartError::Implausible(format!(
            "light from the neutral patches: only {} of them are usable (3 are needed)",
            pts.len()
        )));
    }
    // Normalised chart coordinates in [-1, 1].
    let (cw, rh) = (kind.columns() as f64 / 2.0, kind.rows() as f64 / 2.0);
    let norm = |c: [f64; 2]| [(c[0] - cw) / cw, (c[1] - rh) / rh];
    let bases: [&[usize]; 4] = [&[0, 1, 2, 3, 4, 5], &[0, 1, 2], &[0, 1], &[0, 2]];
    let term = |t: usize, u: f64, v: f64| match t {
        0 => 1.0,
        1 => u,
        2 => v,
        3 => u * u,
        4 => u * v,
        _ => v * v,
    };
    let mut coef: Option<(Vec<usize>, Vec<f64>)> = None;
    for basis in bases {
        if pts.len() < basis.len() + 2 {
            continue;
        }
        let a = nalgebra::DMatrix::from_fn(pts.len(), basis.len(), |r, c| {
            let [u, v] = norm(pts[r].0);
            term(basis[c], u, v)
        });
        let b = nalgebra::DVector::from_iterator(pts.len(), pts.iter().map(|p| p.1));
        let svd = a.clone().svd(true, true);
        let sv = &svd.singular_values;
        let (smax, smin) = (sv.max(), sv.min());
        if !(smin > 0.05 * smax) {
            continue; // the neutrals do not span this basis
        }
        if let Ok(x) = svd.solve(&b, 1e-12) {
            coef = Some((basis.to_vec(), x.iter().copied().collect()));
            break;
        }
    }
    let factors: Vec<[f64; 3]> = match coef {
        Some((basis, x)) => (0..kind.cells())
            .map(|i| {
                let [u, v] = norm(kind.cell_centre(i));
                let f: f64 = basis.iter().zip(&x).map(|(&t, c)| c * term(t, u, v)).sum();
                [f; 3]
            })
            .collect(),
        None => {
            let mean = pts.iter().map(|p| p.1).sum::<f64>() / pts.len() as f64;
            vec![[mean; 3]; kind.cells()]
        }
    };
    finish("neutral patches", factors, pts.len())
}

/// Divides the readings by the light factors.
pub(crate) fn apply(ex: &mut Extraction, flat: &Flat) {
    for (p, f) in ex.patches.iter_mut().zip(&flat.factors) {
        for k in 0..3 {
            p.rgb[k] /= f[k];
            p.std[k] /= f[k];
        }
        p.flat = f[1];
    }
}
