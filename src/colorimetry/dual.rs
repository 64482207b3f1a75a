//! Forward-mode derivatives of the colour conversions: a [`Real`] number type that the conversions
//! in [`super`] are written over, implemented by `f64` (plain values) and by [`Dual`] (a value with
//! its gradient with respect to `N` inputs).
//!
//! [`super::xyz_to_lab_generic`] and [`super::ciede2000_generic`] are generic over [`Real`], so the ΔE00 the
//! evaluation reports and the ΔE00 whose gradient the fit follows (`model::refine`) are one
//! definition: there is no second, hand-derived formula to drift from it.
//!
//! At the points where a function is not differentiable (`√0`, `hypot(0, 0)`, `atan2(0, 0)`) the
//! derivative is taken as 0; everywhere else it is exact (to rounding).

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The arithmetic the colour conversions need.
pub(crate) trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// A constant (zero derivative).
    fn cst(v: f64) -> Self;
    /// The value (for comparisons and branches).
    fn re(self) -> f64;
    fn sqrt(self) -> Self;
    fn cbrt(self) -> Self;
    fn powi(self, n: i32) -> Self;
    fn powf(self, e: f64) -> Self;
    fn hypot(self, other: Self) -> Self;
    fn atan2(self, other: Self) -> Self;
    fn sin(self) -> Self;
    fn cos(self) -> Self;
    fn exp(self) -> Self;
    fn to_degrees(self) -> Self;
    fn to_radians(self) -> Self;
}

impl Real for f64 {
    fn cst(v: f64) -> Self {
        v
    }
    fn re(self) -> f64 {
        self
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    fn cbrt(self) -> Self {
        f64::cbrt(self)
    }
    fn powi(self, n: i32) -> Self {
        f64::powi(self, n)
    }
    fn powf(self, e: f64) -> Self {
        f64::powf(self, e)
    }
    fn hypot(self, other: Self) -> Self {
        f64::hypot(self, other)
    }
    fn atan2(self, other: Self) -> Self {
        f64::atan2(self, other)
    }
    fn sin(self) -> Self {
        f64::sin(self)
    }
    fn cos(self) -> Self {
        f64::cos(self)
    }
    fn exp(self) -> Self {
        f64::exp(self)
    }
    fn to_degrees(self) -> Self {
        f64::to_degrees(self)
    }
    fn to_radians(self) -> Self {
        f64::to_radians(self)
    }
}

/// A value with its gradient with respect to `N` inputs (forward-mode automatic differentiation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// `∂v/∂input_k`.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// Input `k` of `N` with value `v` (gradient = unit vector `k`).
    pub(crate) fn var(v: f64, k: usize) -> Self {
        let mut d = [0.0; N];
        d[k] = 1.0;
        Dual { v, d }
    }

    /// `f(self)` given `f(v)` and `f'(v)`.
    fn chain(self, fv: f64, dfdv: f64) -> Self {
        let mut d = self.d;
        for x in d.iter_mut() {
            *x *= dfdv;
        }
        Dual { v: fv, d }
    }

    /// The variables of an input vector: `[var(x[0], 0), var(x[1], 1), …]`.
    pub(crate) fn vars(x: [f64; N]) -> [Self; N] {
        std::array::from_fn(|k| Dual::var(x[k], k))
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Dual {
            v: self.v + o.v,
            d: std::array::from_fn(|k| self.d[k] + o.d[k]),
        }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Dual {
            v: self.v - o.v,
            d: std::array::from_fn(|k| self.d[k] - o.d[k]),
        }
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[allow(clippy::suspicious_arithmetic_impl)] // the product rule
    fn mul(self, o: Self) -> Self {
        Dual {
            v: self.v * o.v,
            d: std::array::from_fn(|k| self.d[k] * o.v + self.v * o.d[k]),
        }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let q = self.v * inv;
        Dual {
            v: self.v / o.v,
            d: std::array::from_fn(|k| (self.d[k] - q * o.d[k]) * inv),
        }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    fn neg(self) -> Self {
        Dual {
            v: -self.v,
            d: self.d.map(|x| -x),
        }
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    fn add(self, o: f64) -> Self {
        Dual {
            v: self.v + o,
            d: self.d,
        }
    }
}

impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    fn sub(self, o: f64) -> Self {
        Dual {
            v: self.v - o,
            d: self.d,
        }
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    fn mul(self, o: f64) -> Self {
        Dual {
            v: self.v * o,
            d: self.d.map(|x| x * o),
        }
    }
}

impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    fn div(self, o: f64) -> Self {
        Dual {
            v: self.v / o,
            d: self.d.map(|x| x / o),
        }
    }
}

impl<const N: usize> Real for Dual<N> {
    fn cst(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }
    fn re(self) -> f64 {
        self.v
    }
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, if s > 0.0 { 0.5 / s } else { 0.0 })
    }
    fn cbrt(self) -> Self {
        let c = self.v.cbrt();
        self.chain(c, if c != 0.0 { 1.0 / (3.0 * c * c) } else { 0.0 })
    }
    fn powi(self, n: i32) -> Self {
        let dv = if n == 0 {
            0.0
        } else {
            n as f64 * self.v.powi(n - 1)
        };
        self.chain(self.v.powi(n), dv)
    }
    fn powf(self, e: f64) -> Self {
        let dv = if e == 0.0 {
            0.0
        } else if self.v == 0.0 {
            if e > 1.0 {
                0.0
            } else {
                f64::INFINITY
            }
        } else {
            e * self.v.powf(e - 1.0)
        };
        self.chain(self.v.powf(e), if dv.is_finite() { dv } else { 0.0 })
    }
    fn hypot(self, o: Self) -> Self {
        let h = self.v.hypot(o.v);
        if h == 0.0 {
            return Dual::cst(0.0);
        }
        Dual {
            v: h,
            d: std::array::from_fn(|k| (self.v * self.d[k] + o.v * o.d[k]) / h),
        }
    }
    /// `self.atan2(o)` = the angle of `(o, self)`, as `f64::atan2` (self is y).
    fn atan2(self, o: Self) -> Self {
        let r2 = self.v * self.v + o.v * o.v;
        let v = self.v.atan2(o.v);
        if r2 == 0.0 {
            return Dual::cst(v);
        }
        Dual {
            v,
            d: std::array::from_fn(|k| (o.v * self.d[k] - self.v * o.d[k]) / r2),
        }
    }
    fn sin(self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    fn cos(self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn to_degrees(self) -> Self {
        self.chain(self.v.to_degrees(), 180.0 / std::f64::consts::PI)
    }
    fn to_radians(self) -> Self {
        self.chain(self.v.to_radians(), std::f64::consts::PI / 180.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences: the test oracle for every derivative here.
    fn fd(f: impl Fn(f64) -> f64, x: f64) -> f64 {
        let h = 1e-6 * x.abs().max(1.0);
        (f(x + h) - f(x - h)) / (2.0 * h)
    }

    #[test]
    fn elementary_derivatives_match_finite_differences() {
        type D = Dual<1>;
        type Case = (fn(D) -> D, fn(f64) -> f64, f64);
        let cases: [Case; 11] = [
            (|x| x.powf(1.7), |x| x.powf(1.7), 0.8),
            (|x| x.sqrt(), f64::sqrt, 2.3),
            (|x| x.cbrt(), f64::cbrt, -1.7),
            (|x| x.powi(7), |x| x.powi(7), 0.9),
            (|x| x.hypot(x * 2.0 + 1.0), |x| x.hypot(2.0 * x + 1.0), 0.4),
            (
                |x| (x * 3.0).atan2(x - 2.0),
                |x| (3.0 * x).atan2(x - 2.0),
                0.5,
            ),
            (|x| x.sin() * x.cos(), |x| x.sin() * x.cos(), 1.2),
            (|x| (-x * x).exp(), |x| (-x * x).exp(), 0.7),
            (|x| x.to_degrees(), f64::to_degrees, 0.3),
            (
                |x| x.to_radians() / (x + 1.0),
                |x| x.to_radians() / (x + 1.0),
                40.0,
            ),
            (
                |x| (x - 1.0) * (x + 2.0) / x,
                |x| (x - 1.0) * (x + 2.0) / x,
                1.5,
            ),
        ];
        for (i, (fd_, f, x)) in cases.iter().enumerate() {
            let got = fd_(D::var(*x, 0));
            assert!((got.v - f(*x)).abs() < 1e-12, "case {i}: value");
            let want = fd(f, *x);
            assert!(
                (got.d[0] - want).abs() < 1e-6 * want.abs().max(1.0),
                "case {i}: {} vs {want}",
                got.d[0]
            );
        }
    }

    #[test]
    fn non_differentiable_points_give_zero() {
        type D = Dual<1>;
        assert_eq!(D::var(0.0, 0).sqrt().d, [0.0]);
        assert_eq!(D::var(0.0, 0).hypot(D::cst(0.0)).d, [0.0]);
        assert_eq!(D::var(0.0, 0).atan2(D::cst(0.0)).d, [0.0]);
    }
}
