//! From the model's XYZ to the pixels written and shown: the output-space matrix (scene-linear,
//! the perfect white at `Y = 1`; `model::output_model` folds it into a model), the preview matrix to
//! linear sRGB, and the sRGB transfer function.

use super::spaces;
use super::spaces::{Mat3, OutputSpace};

/// The 3×3 matrix from the model's XYZ (perfect white at `Y = white[1]`, usually 100) to the
/// frames written: scene-linear with the perfect white at `Y = 1`, in `space`, Bradford-adapted
/// from the training white to the space's white (D65 for XYZ; see [`OutputSpace::from_xyz`]).
/// With [`OutputSpace::LinearSrgb`] this is XYZ → display (linear sRGB, white = 1).
pub fn output_matrix(white_xyz: [f64; 3], space: OutputSpace) -> Mat3 {
    let m = space.from_xyz(white_xyz);
    let k = 1.0 / white_xyz[1];
    m.map(|row| row.map(|v| v * k))
}

/// [`output_matrix`] for a frame's white (a combination's): adapted exactly
/// ([`OutputSpace::from_xyz_exact`]), never by the "counts as D65" shortcut.
pub(crate) fn output_matrix_exact(white_xyz: [f64; 3], space: OutputSpace) -> Mat3 {
    let m = space.from_xyz_exact(white_xyz);
    let k = 1.0 / white_xyz[1];
    m.map(|row| row.map(|v| v * k))
}

/// The matrix from pixels in `space` (as written by `nsrm apply`, white `Y = 1`, scene white
/// `white_xyz`) to linear sRGB (D65, white = 1): for previews.
pub fn to_linear_srgb(white_xyz: [f64; 3], space: OutputSpace) -> Mat3 {
    let srgb = OutputSpace::LinearSrgb.from_xyz(white_xyz);
    spaces::mul(&srgb, &spaces::invert(&space.from_xyz(white_xyz)))
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1) of a linear value in `[0, 1]`.
pub fn srgb_oetf(v: f64) -> f64 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A linear value as an 8-bit sRGB code: clipped to `[0, 1]`, [`srgb_oetf`], rounded; NaN is 0.
pub fn srgb8(v: f64) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    (srgb_oetf(v) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_matrix_maps_the_white() {
        // The training white maps to D65 with Y = 1 (XYZ, D65-referred) or to (1, 1, 1) (RGB).
        let w = [96.4, 100.0, 82.5];
        let xyz = spaces::apply(&output_matrix(w, OutputSpace::Xyz), w);
        let d65 = spaces::xy_to_xyz(spaces::D65_XY);
        assert!((0..3).all(|k| (xyz[k] - d65[k]).abs() < 1e-9), "{xyz:?}");
        let d65_grid = [95.04, 100.0, 108.88];
        assert_eq!(output_matrix(d65_grid, OutputSpace::Xyz)[1][1], 0.01);
        let rgb = spaces::apply(&output_matrix(w, OutputSpace::Acescg), w);
        assert!(rgb.iter().all(|v| (v - 1.0).abs() < 1e-9), "{rgb:?}");
    }

    #[test]
    fn preview_matrix_inverts_the_space() {
        let w = [95.047, 100.0, 108.883];
        let x = [0.2, 0.3, 0.4];
        let direct = spaces::apply(&to_linear_srgb(w, OutputSpace::Xyz), x);
        for space in [OutputSpace::Acescg, OutputSpace::Aces2065_1] {
            let in_space = spaces::apply(&space.from_xyz(w), x);
            let back = spaces::apply(&to_linear_srgb(w, space), in_space);
            for k in 0..3 {
                assert!((back[k] - direct[k]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn srgb_encoding_and_display_white() {
        assert_eq!(srgb_oetf(0.0), 0.0);
        assert!((srgb_oetf(1.0) - 1.0).abs() < 1e-12);
        assert!((srgb_oetf(0.18) - 0.4613561295).abs() < 1e-6);
        assert_eq!(
            [-1.0, 0.0, 0.18, 1.0, 2.0, f64::NAN].map(srgb8),
            [0, 0, 118, 255, 255, 0]
        );
        // The model's white maps to display white.
        let white = [96.4, 100.0, 82.5];
        let rgb = spaces::apply(&output_matrix(white, OutputSpace::LinearSrgb), white);
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-9, "{rgb:?}");
        }
    }
}
