//! The processing nodes the exports write (a subset of CLF's: Matrix, Range, Log in its camera
//! styles, LUT1D, LUT3D) and an evaluator of them, in f64 over the f32 values stored in the
//! files, with the interpolation each file declares.
//!
//! This evaluator is what `nsrm export` measures its approximation error with; OpenColorIO, which
//! reads the written files, is checked against it in the tests.

use nsrm::Mat3;

/// How a 3D LUT is interpolated between lattice points.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Interpolation {
    /// Trilinear: CLF's default, and what most .cube readers do unless told otherwise.
    #[cfg_attr(feature = "clap", value(name = "trilinear", alias = "linear"))]
    Trilinear,
    /// Tetrahedral: the cube is split into six tetrahedra along its main diagonal.
    #[cfg_attr(feature = "clap", value(name = "tetrahedral"))]
    Tetrahedral,
}

impl Interpolation {
    /// CLF's `interpolation` attribute value.
    pub(crate) fn clf_name(self) -> &'static str {
        match self {
            Interpolation::Trilinear => "trilinear",
            Interpolation::Tetrahedral => "tetrahedral",
        }
    }

    /// Parses `trilinear` / `tetrahedral` (for the unit test of the command line's values).
    pub fn parse(s: &str) -> Option<Interpolation> {
        match s.trim().to_ascii_lowercase().as_str() {
            "trilinear" | "linear" => Some(Interpolation::Trilinear),
            "tetrahedral" => Some(Interpolation::Tetrahedral),
            _ => None,
        }
    }
}

/// CLF's `cameraLinToLog` curve with base 2, `linSideSlope = 1`, `linSideOffset = 0`:
/// `y = log_slope · log2(x) + log_offset` above `break_x`, and below it the straight line that
/// continues the curve with the same value and slope (so it is C¹ and defined for 0 and negative
/// values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LogCurve {
    pub log_slope: f64,
    pub log_offset: f64,
    pub break_x: f64,
}

impl LogCurve {
    /// The curve mapping `0 → 0` and `hi → 1`, logarithmic from `lo` up (`0 < lo < hi`) and
    /// linear between 0 and `lo`.
    pub(crate) fn zero_to_one(lo: f64, hi: f64) -> LogCurve {
        // Linear part y = a·x with a = log_slope / (lo·ln 2) (slope continuity at the break), so
        // y(lo) = log_slope / ln 2; y(hi) = log_slope·(log2(hi/lo) + 1/ln 2) = 1.
        let inv_ln2 = std::f64::consts::LOG2_E;
        let log_slope = 1.0 / ((hi / lo).log2() + inv_ln2);
        let log_offset = log_slope * (inv_ln2 - lo.log2());
        LogCurve {
            log_slope,
            log_offset,
            break_x: lo,
        }
    }

    /// The slope of the linear segment (CLF's derived `linearSlope`).
    pub(crate) fn linear_slope(&self) -> f64 {
        self.log_slope / (self.break_x * std::f64::consts::LN_2)
    }

    fn y_at_break(&self) -> f64 {
        self.log_slope * self.break_x.log2() + self.log_offset
    }

    /// Linear → log.
    pub(crate) fn forward(&self, x: f64) -> f64 {
        if x > self.break_x {
            self.log_slope * x.log2() + self.log_offset
        } else {
            self.y_at_break() + self.linear_slope() * (x - self.break_x)
        }
    }

    /// Log → linear (the exact inverse of `forward`).
    pub(crate) fn inverse(&self, y: f64) -> f64 {
        let yb = self.y_at_break();
        if y > yb {
            ((y - self.log_offset) / self.log_slope).exp2()
        } else {
            self.break_x + (y - yb) / self.linear_slope()
        }
    }
}

/// A 1D LUT (the same table layout for every channel): `n` entries per channel over the input
/// domain `[lo, hi]`, linearly interpolated; inputs outside the domain are clamped to it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Lut1d {
    pub domain: [f64; 2],
    pub values: Vec<[f32; 3]>,
}

impl Lut1d {
    /// Samples `f` (one curve for the three channels) at `n` points over `domain`.
    pub(crate) fn sample(domain: [f64; 2], n: usize, f: impl Fn(f64) -> f64) -> Lut1d {
        let values = (0..n)
            .map(|i| {
                let x = domain[0] + (domain[1] - domain[0]) * i as f64 / (n - 1) as f64;
                let v = f(x) as f32;
                [v, v, v]
            })
            .collect();
        Lut1d { domain, values }
    }

    fn eval_channel(&self, c: usize, x: f64) -> f64 {
        let n = self.values.len();
        let t = ((x - self.domain[0]) / (self.domain[1] - self.domain[0])).clamp(0.0, 1.0);
        let p = t * (n - 1) as f64;
        let i = (p.floor() as usize).min(n - 2);
        let f = p - i as f64;
        let a = self.values[i][c] as f64;
        let b = self.values[i + 1][c] as f64;
        a + (b - a) * f
    }

    /// The input whose interpolated output on channel `c` is `y` (the table must be increasing):
    /// the exact inverse of the piecewise-linear function the file declares.
    pub(crate) fn inverse(&self, c: usize, y: f64) -> f64 {
        let n = self.values.len();
        let v = |i: usize| self.values[i][c] as f64;
        let step = (self.domain[1] - self.domain[0]) / (n - 1) as f64;
        if y <= v(0) {
            return self.domain[0];
        }
        if y >= v(n - 1) {
            return self.domain[1];
        }
        // The last i with v(i) <= y.
        let (mut lo, mut hi) = (0usize, n - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if v(mid) <= y {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (a, b) = (v(lo), v(lo + 1));
        let f = if b > a { (y - a) / (b - a) } else { 0.0 };
        self.domain[0] + (lo as f64 + f) * step
    }
}

/// A 3D LUT of `size³` RGB entries over the unit cube, stored with **blue changing fastest**
/// (CLF's order): entry `(r, g, b)` is `values[(r·size + g)·size + b]`. Inputs are clamped to
/// [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Lut3d {
    pub size: usize,
    pub values: Vec<[f32; 3]>,
    pub interpolation: Interpolation,
}

impl Lut3d {
    /// Samples `f` at the lattice points `(i, j, k) / (size − 1)`.
    pub(crate) fn sample(
        size: usize,
        interpolation: Interpolation,
        f: impl Fn([f64; 3]) -> [f64; 3] + Sync,
    ) -> Lut3d {
        let n = size;
        let step = 1.0 / (n - 1) as f64;
        let values = (0..n * n * n)
            .map(|idx| {
                let (r, g, b) = (idx / (n * n), (idx / n) % n, idx % n);
                let out = f([r as f64 * step, g as f64 * step, b as f64 * step]);
                [out[0] as f32, out[1] as f32, out[2] as f32]
            })
            .collect();
        Lut3d {
            size,
            values,
            interpolation,
        }
    }

    fn at(&self, r: usize, g: usize, b: usize) -> [f64; 3] {
        let v = self.values[(r * self.size + g) * self.size + b];
        [v[0] as f64, v[1] as f64, v[2] as f64]
    }

    /// Interpolates the LUT at `x` (each channel clamped to [0, 1]).
    pub(crate) fn eval(&self, x: [f64; 3]) -> [f64; 3] {
        let n = self.size;
        let mut i = [0usize; 3];
        let mut f = [0f64; 3];
        for c in 0..3 {
            let p = x[c].clamp(0.0, 1.0) * (n - 1) as f64;
            i[c] = (p.floor() as usize).min(n - 2);
            f[c] = p - i[c] as f64;
        }
        let c = |dr: usize, dg: usize, db: usize| self.at(i[0] + dr, i[1] + dg, i[2] + db);
        let [fr, fg, fb] = f;
        let mut out = [0.0; 3];
        match self.interpolation {
            Interpolation::Trilinear => {
                for dr in 0..2 {
                    for dg in 0..2 {
                        for db in 0..2 {
                            let w = (if dr == 1 { fr } else { 1.0 - fr })
                                * (if dg == 1 { fg } else { 1.0 - fg })
                                * (if db == 1 { fb } else { 1.0 - fb });
                            let v = c(dr, dg, db);
                            for k in 0..3 {
                                out[k] += w * v[k];
                            }
                        }
                    }
                }
            }
            Interpolation::Tetrahedral => {
                // The tetrahedron containing f, from the order of its coordinates; the weights
                // walk the cube's edges from (0,0,0) to (1,1,1).
                let (w, corners): ([f64; 4], [(usize, usize, usize); 4]) = if fr > fg {
                    if fg > fb {
                        (
                            [1.0 - fr, fr - fg, fg - fb, fb],
                            [(0, 0, 0), (1, 0, 0), (1, 1, 0), (1, 1, 1)],
                        )
                    } else if fr > fb {
                        (
                            [1.0 - fr, fr - fb, fb - fg, fg],
                            [(0, 0, 0), (1, 0, 0), (1, 0, 1), (1, 1, 1)],
                        )
                    } else {
                        (
                            [1.0 - fb, fb - fr, fr - fg, fg],
                            [(0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1)],
                        )
                    }
                } else if fb > fg {
                    (
                        [1.0 - fb, fb - fg, fg - fr, fr],
                        [(0, 0, 0), (0, 0, 1), (0, 1, 1), (1, 1, 1)],
                    )
                } else if fb > fr {
                    (
                        [1.0 - fg, fg - fb, fb - fr, fr],
                        [(0, 0, 0), (0, 1, 0), (0, 1, 1), (1, 1, 1)],
                    )
                } else {
                    (
                        [1.0 - fg, fg - fr, fr - fb, fb],
                        [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 1, 1)],
                    )
                };
                for (wk, (dr, dg, db)) in w.iter().zip(corners) {
                    let v = c(dr, dg, db);
                    for k in 0..3 {
                        out[k] += wk * v[k];
                    }
                }
            }
        }
        out
    }
}

/// One processing step, as written into the files.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Node {
    /// `out = M · in`.
    Matrix(Mat3),
    /// Clamp every channel to `[lo, hi]` (a CLF `Range` whose in and out bounds are equal).
    Clamp {
        lo: f64,
        hi: f64,
    },
    /// CLF `Log`, style `cameraLinToLog` (`inverse = false`) or `cameraLogToLin`.
    Log {
        curve: LogCurve,
        inverse: bool,
    },
    Lut1d(Lut1d),
    Lut3d(Lut3d),
}

impl Node {
    /// Applies the node to one RGB triple.
    pub(crate) fn eval(&self, x: [f64; 3]) -> [f64; 3] {
        match self {
            Node::Matrix(m) => nsrm::apply_mat3(m, x),
            Node::Clamp { lo, hi } => x.map(|v| v.clamp(*lo, *hi)),
            Node::Log { curve, inverse } => x.map(|v| {
                if *inverse {
                    curve.inverse(v)
                } else {
                    curve.forward(v)
                }
            }),
            Node::Lut1d(l) => [
                l.eval_channel(0, x[0]),
                l.eval_channel(1, x[1]),
                l.eval_channel(2, x[2]),
            ],
            Node::Lut3d(l) => l.eval(x),
        }
    }
}

/// Applies a chain of nodes in order.
pub(crate) fn eval_chain(nodes: &[Node], x: [f64; 3]) -> [f64; 3] {
    nodes.iter().fold(x, |v, n| n.eval(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_curve_round_trips_and_is_c1() {
        let c = LogCurve::zero_to_one(2f64.powi(-12), 16.0);
        assert!(c.forward(0.0).abs() < 1e-15);
        assert!((c.forward(16.0) - 1.0).abs() < 1e-12);
        let b = c.break_x;
        let (below, above) = (c.forward(b * (1.0 - 1e-9)), c.forward(b * (1.0 + 1e-9)));
        assert!((below - above).abs() < 1e-9);
        let d = |x: f64| (c.forward(x * (1.0 + 1e-7)) - c.forward(x * (1.0 - 1e-7))) / (2e-7 * x);
        assert!((d(b * 1.001) / c.linear_slope() - 1.0).abs() < 2e-3);
        for x in [-0.01, 0.0, 1e-5, b, 0.001, 0.18, 1.0, 7.0, 16.0, 40.0] {
            let back = c.inverse(c.forward(x));
            assert!((back - x).abs() <= 1e-12 * x.abs().max(1e-3), "{x} {back}");
        }
    }

    #[test]
    fn lut1d_inverse_is_exact_on_its_own_interpolation() {
        let c = LogCurve::zero_to_one(2f64.powi(-10), 16.0);
        let l = Lut1d::sample([0.0, 16.0], 1024, |x| c.forward(x));
        for y in [0.0, 0.01, 0.3, 0.5, 0.77, 0.999] {
            let x = l.inverse(1, y);
            assert!((l.eval_channel(1, x) - y).abs() < 1e-6, "{y}");
        }
    }

    /// A LUT sampled from an affine map reproduces it exactly with either interpolation; a
    /// product (x·y·z) is reproduced by trilinear interpolation but not by tetrahedral, which
    /// tells the two apart (the OCIO test relies on that difference being visible).
    #[test]
    fn lut3d_interpolations() {
        let affine = |x: [f64; 3]| [0.5 * x[0] + 0.2 * x[1] - x[2], x[1] + 0.1, 2.0 * x[2]];
        let prod = |x: [f64; 3]| [x[0] * x[1] * x[2], 0.0, 0.0];
        for interp in [Interpolation::Trilinear, Interpolation::Tetrahedral] {
            let l = Lut3d::sample(5, interp, affine);
            for p in [
                [0.1, 0.7, 0.3],
                [0.9, 0.2, 0.6],
                [0.33, 0.33, 0.34],
                [1.2, -0.5, 0.5],
            ] {
                let got = l.eval(p);
                let want = affine(p.map(|v: f64| v.clamp(0.0, 1.0)));
                for k in 0..3 {
                    assert!((got[k] - want[k]).abs() < 1e-6, "{interp:?} {p:?}");
                }
            }
        }
        let tri = Lut3d::sample(2, Interpolation::Trilinear, prod);
        let tet = Lut3d::sample(2, Interpolation::Tetrahedral, prod);
        let p = [0.5, 0.5, 0.5];
        assert!((tri.eval(p)[0] - 0.125).abs() < 1e-12);
        // Tetrahedral: on the diagonal it interpolates (0,0,0) and (1,1,1) only.
        assert!((tet.eval(p)[0] - 0.5).abs() < 1e-12);
        // The order of the stored values: blue fastest.
        let l = Lut3d::sample(3, Interpolation::Trilinear, |x| x);
        assert_eq!(l.values[1], [0.0, 0.0, 0.5]);
        assert_eq!(l.values[3], [0.0, 0.5, 0.0]);
        assert_eq!(l.values[9], [0.5, 0.0, 0.0]);
    }
}
