//! Colorimetry: CIE XYZ ↔ CIELAB, CIEDE2000, (in [`spaces`]) the matrices from XYZ to output
//! RGB spaces with chromatic adaptation, and (in [`output`]) the output-space scaling, the
//! preview / display matrices and the sRGB transfer function. Every colour conversion of the
//! library (io, export, chart, the embedding example) is one of these.

pub(crate) mod dual;
pub(crate) mod observer;
pub(crate) mod output;
pub(crate) mod spaces;
pub(crate) mod temperature;

pub(crate) use dual::{Dual, Real};
pub(crate) use output::{output_matrix, output_matrix_exact};

/// CIE D65 white point (2° observer), Y = 100; used when measured XYZ data names no white.
pub const D65_WHITE_XYZ: [f64; 3] = [95.047, 100.0, 108.883];

const EPS: f64 = 216.0 / 24389.0;
const KAPPA: f64 = 24389.0 / 27.0;

/// CIE xyY → XYZ (same scale as `big_y`). A chromaticity with `y = 0` gives zeros.
pub fn xyy_to_xyz(x: f64, y: f64, big_y: f64) -> [f64; 3] {
    if y == 0.0 {
        return [0.0; 3];
    }
    [x * big_y / y, big_y, (1.0 - x - y) * big_y / y]
}

/// CIE XYZ → CIELAB relative to the reference white `white` (same scale as `xyz`).
///
/// ```
/// let lab = nsrm::xyz_to_lab([95.047, 100.0, 108.883], nsrm::D65_WHITE_XYZ);
/// assert!((lab[0] - 100.0).abs() < 1e-9 && lab[1].abs() < 1e-9 && lab[2].abs() < 1e-9);
/// ```
pub fn xyz_to_lab(xyz: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    xyz_to_lab_generic(xyz, white)
}

/// [`xyz_to_lab`] generic over [`Real`]: with [`Dual`] inputs it also returns the derivatives
/// (see [`dual`]).
pub(crate) fn xyz_to_lab_generic<T: Real>(xyz: [T; 3], white: [f64; 3]) -> [T; 3] {
    let f = |t: T| {
        if t.re() > EPS {
            t.cbrt()
        } else {
            (t * KAPPA + 16.0) / 116.0
        }
    };
    let fx = f(xyz[0] / white[0]);
    let fy = f(xyz[1] / white[1]);
    let fz = f(xyz[2] / white[2]);
    [fy * 116.0 - 16.0, (fx - fy) * 500.0, (fy - fz) * 200.0]
}

/// CIELAB → CIE XYZ, the inverse of [`xyz_to_lab`].
pub fn lab_to_xyz(lab: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = fy + lab[1] / 500.0;
    let fz = fy - lab[2] / 200.0;
    let finv = |f: f64| {
        let f3 = f * f * f;
        if f3 > EPS {
            f3
        } else {
            (116.0 * f - 16.0) / KAPPA
        }
    };
    let yr = if lab[0] > KAPPA * EPS {
        fy * fy * fy
    } else {
        lab[0] / KAPPA
    };
    [finv(fx) * white[0], yr * white[1], finv(fz) * white[2]]
}

/// CIEDE2000 colour difference (Sharma, Wu & Dalal 2005) with kL = kC = kH = 1: the ΔE00 every
/// evaluation reports.
pub fn ciede2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    ciede2000_generic(lab1, lab2)
}

/// [`ciede2000`] generic over [`Real`]: with [`Dual`] inputs it also returns the gradient (see
/// [`dual`]).
pub(crate) fn ciede2000_generic<T: Real>(lab1: [T; 3], lab2: [T; 3]) -> T {
    let [tl, tc, th, rt] = ciede2000_parts(lab1, lab2);
    (tl * tl + tc * tc + th * th + rt * tc * th).sqrt()
}

/// CIEDE2000 as a Euclidean norm: a vector `v` with `‖v‖ = ΔE00`,
/// `v = (ΔL'/S_L, ΔC'/S_C + R_T/2·ΔH'/S_H, ΔH'/S_H·√(1 − R_T²/4))` (`|R_T| ≤ 2`). Smooth where
/// ΔE00 = 0, unlike the norm itself: the residuals a Gauss–Newton fit of ΣΔE00² wants.
pub(crate) fn ciede2000_vector<T: Real>(lab1: [T; 3], lab2: [T; 3]) -> [T; 3] {
    let [tl, tc, th, rt] = ciede2000_parts(lab1, lab2);
    let k = (T::cst(1.0) - rt * rt * 0.25).sqrt();
    [tl, tc + rt * th * 0.5, th * k]
}

/// `(ΔL'/S_L, ΔC'/S_C, ΔH'/S_H, R_T)` of CIEDE2000.
fn ciede2000_parts<T: Real>(lab1: [T; 3], lab2: [T; 3]) -> [T; 4] {
    use std::f64::consts::PI;
    let one = T::cst(1.0);
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let c1 = a1.hypot(b1);
    let c2 = a2.hypot(b2);
    let cbar = (c1 + c2) * 0.5;
    let cbar7 = cbar.powi(7);
    let g = (one - (cbar7 / (cbar7 + 25f64.powi(7))).sqrt()) * 0.5;
    let a1p = (g + 1.0) * a1;
    let a2p = (g + 1.0) * a2;
    let c1p = a1p.hypot(b1);
    let c2p = a2p.hypot(b2);
    let hue = |b: T, a: T| {
        if b.re() == 0.0 && a.re() == 0.0 {
            T::cst(0.0)
        } else {
            let h = b.atan2(a).to_degrees();
            if h.re() < 0.0 {
                h + 360.0
            } else {
                h
            }
        }
    };
    let h1p = hue(b1, a1p);
    let h2p = hue(b2, a2p);

    let dlp = l2 - l1;
    let dcp = c2p - c1p;
    let zero_chroma = (c1p * c2p).re() == 0.0;
    let dhp = if zero_chroma {
        T::cst(0.0)
    } else {
        let d = h2p - h1p;
        if d.re() > 180.0 {
            d - 360.0
        } else if d.re() < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    let dhp_big = (c1p * c2p).sqrt() * (dhp.to_radians() / 2.0).sin() * 2.0;

    let lbarp = (l1 + l2) * 0.5;
    let cbarp = (c1p + c2p) * 0.5;
    let hbarp = if zero_chroma {
        h1p + h2p
    } else if (h1p - h2p).re().abs() <= 180.0 {
        (h1p + h2p) * 0.5
    } else if (h1p + h2p).re() < 360.0 {
        (h1p + h2p + 360.0) * 0.5
    } else {
        (h1p + h2p - 360.0) * 0.5
    };
    let t = one - (hbarp - 30.0).to_radians().cos() * 0.17
        + (hbarp * 2.0).to_radians().cos() * 0.24
        + (hbarp * 3.0 + 6.0).to_radians().cos() * 0.32
        - (hbarp * 4.0 - 63.0).to_radians().cos() * 0.20;
    let dtheta = (-((hbarp - 275.0) / 25.0).powi(2)).exp() * 30.0;
    let cbarp7 = cbarp.powi(7);
    let rc = (cbarp7 / (cbarp7 + 25f64.powi(7))).sqrt() * 2.0;
    let l50 = (lbarp - 50.0).powi(2);
    let sl = l50 * 0.015 / (l50 + 20.0).sqrt() + 1.0;
    let sc = cbarp * 0.045 + 1.0;
    let sh = cbarp * 0.015 * t + 1.0;
    let rt = -(dtheta * 2.0 * PI / 180.0).sin() * rc;
    let tl = dlp / sl;
    let tc = dcp / sc;
    let th = dhp_big / sh;
    [tl, tc, th, rt]
}

/// ΔE00 between two XYZ colours, each converted to Lab with the same reference white.
pub fn delta_e00_xyz(xyz1: [f64; 3], xyz2: [f64; 3], white: [f64; 3]) -> f64 {
    ciede2000(xyz_to_lab(xyz1, white), xyz_to_lab(xyz2, white))
}

/// ΔE00 between a predicted XYZ and a reference Lab colour, with its gradient with respect to the
/// predicted X, Y, Z (forward-mode through [`xyz_to_lab`] and [`ciede2000`]; 0 where ΔE00 = 0).
#[cfg(test)]
pub(crate) fn delta_e00_xyz_grad(
    xyz: [f64; 3],
    reference_lab: [f64; 3],
    white: [f64; 3],
) -> (f64, [f64; 3]) {
    let lab = xyz_to_lab_generic(Dual::<3>::vars(xyz), white);
    let d = ciede2000_generic(lab, reference_lab.map(Dual::cst));
    (d.v, d.d)
}

/// [`ciede2000_vector`] between a predicted XYZ and a reference Lab colour, with its Jacobian with
/// respect to the predicted X, Y, Z (forward-mode through [`xyz_to_lab`]).
pub(crate) fn delta_e00_vector_xyz_jacobian(
    xyz: [f64; 3],
    reference_lab: [f64; 3],
    white: [f64; 3],
) -> [Dual<3>; 3] {
    let lab = xyz_to_lab_generic(Dual::<3>::vars(xyz), white);
    ciede2000_vector(lab, reference_lab.map(Dual::cst))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_round_trip_and_white() {
        let w = D65_WHITE_XYZ;
        let lab = xyz_to_lab(w, w);
        assert!((lab[0] - 100.0).abs() < 1e-12 && lab[1].abs() < 1e-12 && lab[2].abs() < 1e-12);
        for xyz in [[20.0, 30.0, 40.0], [0.1, 0.2, 0.05], [90.0, 50.0, 3.0]] {
            let back = lab_to_xyz(xyz_to_lab(xyz, w), w);
            for k in 0..3 {
                assert!((back[k] - xyz[k]).abs() < 1e-9 * xyz[k].max(1.0));
            }
        }
    }

    #[test]
    fn delta_e00_gradient_matches_finite_differences() {
        let w = D65_WHITE_XYZ;
        // Ordinary colours, a dark one (linear branch of Lab), near-neutral ones and a hue across
        // the 0°/360° seam.
        let cases = [
            ([20.0, 30.0, 40.0], [22.0, 29.0, 35.0]),
            ([0.3, 0.4, 0.2], [0.5, 0.45, 0.3]),
            ([95.0, 100.0, 108.0], [94.0, 100.5, 109.5]),
            ([40.0, 30.0, 32.0], [36.0, 30.0, 28.0]),
            ([60.0, 50.0, 10.0], [55.0, 52.0, 12.0]),
        ];
        for (pred, reference) in cases {
            let rl = xyz_to_lab(reference, w);
            let (d, g) = delta_e00_xyz_grad(pred, rl, w);
            assert!((d - delta_e00_xyz(pred, reference, w)).abs() < 1e-12);
            for k in 0..3 {
                let h = 1e-6 * pred[k];
                let mut p = pred;
                p[k] += h;
                let up = delta_e00_xyz(p, reference, w);
                p[k] -= 2.0 * h;
                let down = delta_e00_xyz(p, reference, w);
                let fd = (up - down) / (2.0 * h);
                assert!(
                    (g[k] - fd).abs() <= 1e-5 * fd.abs().max(1e-3),
                    "{pred:?} vs {reference:?}, d/dXYZ[{k}]: {} vs {fd}",
                    g[k]
                );
            }
        }
        // The vector form: its norm is ΔE00, its Jacobian matches finite differences.
        for (pred, reference) in cases {
            let rl = xyz_to_lab(reference, w);
            let v = delta_e00_vector_xyz_jacobian(pred, rl, w);
            let norm = v.iter().map(|c| c.v * c.v).sum::<f64>().sqrt();
            assert!((norm - delta_e00_xyz(pred, reference, w)).abs() < 1e-12);
            for k in 0..3 {
                let h = 1e-6 * pred[k];
                let vec_at = |x: [f64; 3]| ciede2000_vector(xyz_to_lab(x, w), rl);
                let (mut up, mut down) = (pred, pred);
                up[k] += h;
                down[k] -= h;
                for c in 0..3 {
                    let fd = (vec_at(up)[c] - vec_at(down)[c]) / (2.0 * h);
                    assert!((v[c].d[k] - fd).abs() <= 1e-5 * fd.abs().max(1e-3));
                }
            }
        }
        // At ΔE00 = 0 the gradient is taken as 0 (the square root has no derivative there).
        let (d, g) = delta_e00_xyz_grad([20.0, 30.0, 40.0], xyz_to_lab([20.0, 30.0, 40.0], w), w);
        assert_eq!((d, g), (0.0, [0.0; 3]));
    }

    #[test]
    fn ciede2000_symmetric_and_zero() {
        let a = [50.0, 2.6772, -79.7751];
        let b = [50.0, 0.0, -82.7485];
        assert_eq!(ciede2000(a, a), 0.0);
        assert!((ciede2000(a, b) - ciede2000(b, a)).abs() < 1e-12);
    }
}
