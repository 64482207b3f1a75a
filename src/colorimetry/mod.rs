//! Colorimetry: CIE XYZ ↔ CIELAB, CIEDE2000, and (in [`spaces`]) the matrices from XYZ to output
//! RGB spaces with chromatic adaptation.

pub mod spaces;

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
pub fn xyz_to_lab(xyz: [f64; 3], white: [f64; 3]) -> [f64; 3] {
    let f = |t: f64| {
        if t > EPS {
            t.cbrt()
        } else {
            (KAPPA * t + 16.0) / 116.0
        }
    };
    let fx = f(xyz[0] / white[0]);
    let fy = f(xyz[1] / white[1]);
    let fz = f(xyz[2] / white[2]);
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
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

/// CIEDE2000 colour difference (Sharma, Wu & Dalal 2005) with kL = kC = kH = 1.
pub fn ciede2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let c1 = a1.hypot(b1);
    let c2 = a2.hypot(b2);
    let cbar = 0.5 * (c1 + c2);
    let cbar7 = cbar.powi(7);
    let g = 0.5 * (1.0 - (cbar7 / (cbar7 + 25f64.powi(7))).sqrt());
    let a1p = (1.0 + g) * a1;
    let a2p = (1.0 + g) * a2;
    let c1p = a1p.hypot(b1);
    let c2p = a2p.hypot(b2);
    let hue = |b: f64, a: f64| {
        if b == 0.0 && a == 0.0 {
            0.0
        } else {
            let h = b.atan2(a).to_degrees();
            if h < 0.0 {
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
    let dhp = if c1p * c2p == 0.0 {
        0.0
    } else {
        let d = h2p - h1p;
        if d > 180.0 {
            d - 360.0
        } else if d < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    let dhp_big = 2.0 * (c1p * c2p).sqrt() * (dhp.to_radians() / 2.0).sin();

    let lbarp = 0.5 * (l1 + l2);
    let cbarp = 0.5 * (c1p + c2p);
    let hbarp = if c1p * c2p == 0.0 {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        0.5 * (h1p + h2p)
    } else if h1p + h2p < 360.0 {
        0.5 * (h1p + h2p + 360.0)
    } else {
        0.5 * (h1p + h2p - 360.0)
    };
    let t = 1.0 - 0.17 * (hbarp - 30.0).to_radians().cos()
        + 0.24 * (2.0 * hbarp).to_radians().cos()
        + 0.32 * (3.0 * hbarp + 6.0).to_radians().cos()
        - 0.20 * (4.0 * hbarp - 63.0).to_radians().cos();
    let dtheta = 30.0 * (-((hbarp - 275.0) / 25.0).powi(2)).exp();
    let cbarp7 = cbarp.powi(7);
    let rc = 2.0 * (cbarp7 / (cbarp7 + 25f64.powi(7))).sqrt();
    let l50 = (lbarp - 50.0).powi(2);
    let sl = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let sc = 1.0 + 0.045 * cbarp;
    let sh = 1.0 + 0.015 * cbarp * t;
    let rt = -(2.0 * dtheta * PI / 180.0).sin() * rc;
    let tl = dlp / sl;
    let tc = dcp / sc;
    let th = dhp_big / sh;
    (tl * tl + tc * tc + th * th + rt * tc * th).sqrt()
}

/// ΔE00 between two XYZ colours, each converted to Lab with the same reference white.
pub fn delta_e00_xyz(xyz1: [f64; 3], xyz2: [f64; 3], white: [f64; 3]) -> f64 {
    ciede2000(xyz_to_lab(xyz1, white), xyz_to_lab(xyz2, white))
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
    fn ciede2000_symmetric_and_zero() {
        let a = [50.0, 2.6772, -79.7751];
        let b = [50.0, 0.0, -82.7485];
        assert_eq!(ciede2000(a, a), 0.0);
        assert!((ciede2000(a, b) - ciede2000(b, a)).abs() < 1e-12);
    }
}
