//! The pixel policy: what every apply path (the f64 reference, the fast CPU kernels, the WGSL
//! shaders and the exported shaders) does with a pixel, defined once.
//!
//! * **NaN / ±Inf** in any channel propagate: the output is not finite. Nothing is clamped or hidden.
//! * **NSRM's normalisation** is `s = R+G+B`, `r = R/s`, `g = G/s` ([`nsrm_signal`]). When
//!   `s ≤ 0` (black, or noise around black) the chromaticities are undefined and the output is
//!   `(0, 0, 0)`, the limit of `s·(α,β,γ)` as `s → 0⁺`. `s = NaN` is not `≤ 0`: it flows on and the
//!   output is NaN.
//! * **Negative channels** are used as they are: LRM and PRM take them in their polynomials; NSRM
//!   takes them in `r, g` as long as `s > 0`; RPRM takes sign-preserving roots
//!   ([`signed_root`], `sign(x)·|x|^(1/d)`), so its output stays finite. A root term is the
//!   product of per-channel roots, `∛(R G²) = ∛R·(∛G)²`, the same number for any signs.
//! * **Values far outside the training range** (HDR highlights) are not clamped: LRM, RPRM and NSRM
//!   scale exactly with exposure, `f(kS) = k·f(S)` for `k > 0`; PRM extrapolates its polynomial.
//!
//! The f64 reference ([`super::Model::apply_f64`]) is written with these functions; the f32
//! kernels of [`super::fast`] and the shaders spell the same rules in their own arithmetic, and
//! `policy_tests.rs` and `tests/all/pixel_policy.rs` hold each of them to this module on the awkward pixels (zeros,
//! `s < 0`, `s = 0` with non-zero channels, negatives, NaN, ±Inf, huge and tiny values).

/// NSRM's signal and chromaticities `(s, r, g)` of a camera RGB, or `None` when `s ≤ 0` (the
/// output is then `(0, 0, 0)`). NaN is not `≤ 0`: it is returned and propagates.
#[inline]
pub(crate) fn nsrm_signal(rgb: [f64; 3]) -> Option<(f64, f64, f64)> {
    let s = rgb[0] + rgb[1] + rgb[2];
    if s <= 0.0 {
        None
    } else {
        Some((s, rgb[0] / s, rgb[1] / s))
    }
}

/// Sign-preserving d-th root: `sign(x)·|x|^(1/d)`; `±0 → ±0`, `±∞ → ±∞`, NaN stays NaN.
#[inline]
pub(crate) fn signed_root(x: f64, d: u8) -> f64 {
    match d {
        1 => x,
        2 => x.abs().sqrt().copysign(x),
        3 => x.cbrt(),
        4 => x.abs().sqrt().sqrt().copysign(x),
        d => x.abs().powf(1.0 / d as f64).copysign(x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nsrm_signal_rules() {
        assert_eq!(nsrm_signal([0.0; 3]), None);
        assert_eq!(nsrm_signal([-1.0, 0.5, 0.25]), None);
        // s = 0 with non-zero channels is still black.
        assert_eq!(nsrm_signal([1.0, -1.0, 0.0]), None);
        let (s, r, g) = nsrm_signal([2.0, 1.0, 1.0]).unwrap();
        assert_eq!((s, r, g), (4.0, 0.5, 0.25));
        // Negative channels with s > 0 are used as they are.
        let (s, r, g) = nsrm_signal([-1.0, 2.0, 1.0]).unwrap();
        assert_eq!((s, r, g), (2.0, -0.5, 1.0));
        let (s, r, _) = nsrm_signal([f64::NAN, 1.0, 1.0]).unwrap();
        assert!(s.is_nan() && r.is_nan());
        let (s, r, _) = nsrm_signal([f64::INFINITY, 1.0, 1.0]).unwrap();
        assert!(s.is_infinite() && r.is_nan());
        // +Inf and -Inf together: s = NaN, not ≤ 0, so it propagates.
        let (s, _, _) = nsrm_signal([f64::INFINITY, f64::NEG_INFINITY, 1.0]).unwrap();
        assert!(s.is_nan());
        assert_eq!(nsrm_signal([f64::NEG_INFINITY, 1.0, 1.0]), None);
    }

    #[test]
    fn signed_roots() {
        assert_eq!(signed_root(-8.0, 3), -2.0);
        assert_eq!(signed_root(-4.0, 2), -2.0);
        assert_eq!(signed_root(-16.0, 4), -2.0);
        assert_eq!(signed_root(-32.0, 5), -2.0);
        assert_eq!(signed_root(3.5, 1), 3.5);
        for d in 1..=5 {
            assert_eq!(signed_root(0.0, d).to_bits(), 0.0f64.to_bits(), "{d}");
            assert_eq!(signed_root(-0.0, d).to_bits(), (-0.0f64).to_bits(), "{d}");
            assert_eq!(signed_root(f64::INFINITY, d), f64::INFINITY);
            assert_eq!(signed_root(f64::NEG_INFINITY, d), f64::NEG_INFINITY);
            assert!(signed_root(f64::NAN, d).is_nan());
        }
    }
}
