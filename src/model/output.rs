//! A model that writes the output space directly: the output-space matrix folded into its
//! matrix.

use super::{Model, ModelError};
use crate::colorimetry::{output_matrix, output_matrix_exact, spaces::OutputSpace};

/// The model with the output-space matrix ([`OutputSpace::from_xyz`], white at `Y = 1`) folded into its matrix: it maps camera RGB straight to the
/// output space (white `Y = 1`), on every apply path, with no extra pass over the pixels. This
/// is exact for all four kinds (each output is a linear combination of the same terms).
pub fn output_model(model: &Model, space: OutputSpace) -> Result<Model, ModelError> {
    let w = model.white_xyz();
    if !(w.iter().all(|v| v.is_finite()) && w[1] > 0.0) {
        return Err(ModelError::Invalid(format!(
            "the model's reference white {w:?} has no positive Y; cannot scale the output"
        )));
    }
    // A frame's white (a combination's) adapts exactly; only a model's own training white may
    // count as D65.
    let p = if model.has_frame_white() {
        output_matrix_exact(w, space)
    } else {
        output_matrix(w, space)
    };
    let l = model.len_terms();
    let mut folded = vec![0.0; 3 * l];
    for i in 0..3 {
        for j in 0..l {
            folded[i * l + j] = (0..3).map(|k| p[i][k] * model.matrix()[k * l + j]).sum();
        }
    }
    let mut out = model.clone();
    out.set_matrix(folded).map_err(|e| {
        ModelError::Invalid(format!("folding the output space into the model: {e}"))
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::colorimetry::spaces;
    use crate::model::Kind;

    #[test]
    fn output_model_matches_matrix_after_model() {
        let m = Model::from_matrix(Kind::Rprm, 2, (0..18).map(|i| 0.1 * i as f64).collect())
            .unwrap()
            .with_white_xyz([96.4, 100.0, 82.5])
            .unwrap();
        for space in OutputSpace::ALL.map(|(s, _)| s) {
            let folded = output_model(&m, space).unwrap();
            let p = output_matrix(m.white_xyz(), space);
            let rgb = [0.3, 0.5, 0.2];
            let want = spaces::apply(&p, m.apply_f64(rgb));
            let got = folded.apply_f64(rgb);
            for k in 0..3 {
                assert!((want[k] - got[k]).abs() < 1e-12, "{space:?}");
            }
        }
    }
}
