//! The ΔE00 objective: Levenberg–Marquardt on `Σ ΔE00_i^P` over the training patches, starting from
//! the least-squares solution of [`super::fit`].
//!
//! The unknowns are the reduced coefficients `z` of [`super::fit::Reduced`], so a white constraint
//! holds exactly at every step. Each patch gives three residuals `ΔE00_i^(P/2−1)·v_i`, `v_i` the
//! CIEDE2000 difference written as a Euclidean vector ([`crate::colorimetry::ciede2000_vector`],
//! `‖v_i‖ = ΔE00_i`), so the squares sum to `ΔE00_i^P` and stay smooth where ΔE00 is small. The
//! Jacobian is analytic: `∂r_i/∂z_k = ∂r_i/∂XYZ_k · s_i · (A N)_i`, with `∂r/∂XYZ` by forward-mode
//! differentiation through Lab and CIEDE2000 ([`crate::colorimetry::delta_e00_vector_xyz_jacobian`]:
//! the same code as the ΔE00 the evaluation reports). With a ridge λ the penalty `λρ‖W m‖²` is kept, `ρ` being
//! the ratio of `Σ ΔE00^P` to the least-squares residual at the start, so the penalty weighs as much
//! against the data term as it did in the least-squares problem.
//!
//! Deterministic and bounded: at most [`MAX_ITERATIONS`] Jacobian evaluations, a step is taken only
//! if it lowers the objective, so the result is never worse in-sample than the start.

use super::fit::{Design, Reduced};
use super::ModelError;
use crate::colorimetry::{ciede2000, delta_e00_vector_xyz_jacobian, xyz_to_lab, Real};
use nalgebra::{DMatrix, DVector};

/// The most Jacobian evaluations one refinement makes.
pub(crate) const MAX_ITERATIONS: usize = 100;

/// The refinement's result.
pub(crate) struct Refined {
    pub z: DMatrix<f64>,
    /// Σ ΔE00^P in sample at the start and at the end.
    pub start: f64,
    pub end: f64,
    pub iterations: usize,
}

struct Problem<'a> {
    red: &'a Reduced,
    d: &'a Design,
    lab: Vec<[f64; 3]>,
    white: [f64; 3],
    power: f64,
    /// `√(λρ)`, 0 without ridge.
    pen: f64,
}

impl Problem<'_> {
    fn predictions(&self, z: &DMatrix<f64>) -> DMatrix<f64> {
        let x = self.red.full(z);
        let mut ax = &self.d.a * x;
        for (i, s) in self.d.scale.iter().enumerate() {
            for k in 0..3 {
                ax[(i, k)] *= s;
            }
        }
        ax
    }

    fn penalty(&self, z: &DMatrix<f64>) -> f64 {
        if self.pen == 0.0 {
            0.0
        } else {
            (&self.red.wn * z + &self.red.wxp).norm_squared() * self.pen * self.pen
        }
    }

    /// Σ ΔE00^P (data part) and the full objective.
    fn value(&self, z: &DMatrix<f64>) -> (f64, f64) {
        let pred = self.predictions(z);
        let data: f64 = (0..self.lab.len())
            .map(|i| {
                let p = [pred[(i, 0)], pred[(i, 1)], pred[(i, 2)]];
                ciede2000(xyz_to_lab(p, self.white), self.lab[i]).powf(self.power)
            })
            .sum();
        (data, data + self.penalty(z))
    }

    /// Residuals and Jacobian. Each patch gives three residuals `ΔE00^(P/2−1)·v`, `v` the
    /// [`ciede2000_vector`] (so their squares sum to `ΔE00^P` and they stay smooth where ΔE00 is
    /// small), then the penalty entries; columns are `z`, channel-major.
    fn linearise(&self, z: &DMatrix<f64>) -> (DVector<f64>, DMatrix<f64>) {
        let (n, lr) = self.red.g.shape();
        let l = self.red.wn.nrows();
        let pen_rows = if self.pen > 0.0 { 3 * l } else { 0 };
        let mut r = DVector::<f64>::zeros(3 * n + pen_rows);
        let mut j = DMatrix::<f64>::zeros(3 * n + pen_rows, 3 * lr);
        let pred = self.predictions(z);
        for i in 0..n {
            let p = [pred[(i, 0)], pred[(i, 1)], pred[(i, 2)]];
            let mut v = delta_e00_vector_xyz_jacobian(p, self.lab[i], self.white);
            if self.power != 2.0 {
                let e2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                let f = e2.powf(0.25 * (self.power - 2.0));
                v = v.map(|c| c * f);
            }
            let s = self.d.scale[i];
            for (c, vc) in v.iter().enumerate() {
                let row = 3 * i + c;
                r[row] = vc.v;
                for k in 0..3 {
                    let coef = vc.d[k] * s;
                    if coef != 0.0 {
                        for jj in 0..lr {
                            j[(row, k * lr + jj)] = coef * self.red.g[(i, jj)];
                        }
                    }
                }
            }
        }
        if pen_rows > 0 {
            let wz = &self.red.wn * z + &self.red.wxp;
            for k in 0..3 {
                for row in 0..l {
                    r[3 * n + k * l + row] = self.pen * wz[(row, k)];
                    for jj in 0..lr {
                        j[(3 * n + k * l + row, k * lr + jj)] = self.pen * self.red.wn[(row, jj)];
                    }
                }
            }
        }
        (r, j)
    }
}

/// Minimises `Σ ΔE00^power` (+ the kept ridge penalty) from `z0`. See the [module docs](self).
pub(crate) fn refine(
    red: &Reduced,
    d: &Design,
    z0: &DMatrix<f64>,
    lambda: f64,
    power: f64,
    xyz: &[[f64; 3]],
    white: [f64; 3],
) -> Result<Refined, ModelError> {
    let lab: Vec<[f64; 3]> = xyz.iter().map(|x| xyz_to_lab(*x, white)).collect();
    let mut pb = Problem {
        red,
        d,
        lab,
        white,
        power,
        pen: 0.0,
    };
    let (start, _) = pb.value(z0);
    if !start.is_finite() {
        return Err(ModelError::Degenerate);
    }
    if lambda > 0.0 {
        let rss = (&red.g * z0 - &red.br).norm_squared();
        if rss > 0.0 {
            pb.pen = (lambda * start / rss).sqrt();
        }
    }
    let lr = red.g.ncols();
    let q = 3 * lr;
    let mut z = z0.clone();
    let (mut data, mut obj) = pb.value(&z);
    let mut mu = 1e-3;
    let mut iterations = 0;
    'outer: while iterations < MAX_ITERATIONS {
        iterations += 1;
        let (r, jac) = pb.linearise(&z);
        let jtj = jac.tr_mul(&jac);
        let g = jac.tr_mul(&r);
        if g.amax() <= 1e-15 * (1.0 + obj) {
            break;
        }
        let dmax = (0..q).map(|c| jtj[(c, c)]).fold(0.0f64, f64::max);
        if !(dmax > 0.0 && dmax.is_finite()) {
            break;
        }
        loop {
            let mut m = jtj.clone();
            for c in 0..q {
                m[(c, c)] += mu * jtj[(c, c)].max(1e-12 * dmax);
            }
            let step = match m.cholesky() {
                Some(ch) => ch.solve(&(-&g)),
                None => {
                    mu *= 4.0;
                    if mu > 1e12 {
                        break 'outer;
                    }
                    continue;
                }
            };
            let mut zn = z.clone();
            for k in 0..3 {
                for jj in 0..lr {
                    zn[(jj, k)] += step[k * lr + jj];
                }
            }
            let (dn, on) = pb.value(&zn);
            if on.is_finite() && on < obj {
                let gain = obj - on;
                z = zn;
                data = dn;
                obj = on;
                mu = (mu / 3.0).max(1e-12);
                if gain <= 1e-10 * obj {
                    break 'outer;
                }
                break;
            }
            mu *= 4.0;
            if mu > 1e12 {
                break 'outer;
            }
        }
    }
    Ok(Refined {
        z,
        start,
        end: data,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::fit::{design, Reduced};
    use crate::model::{terms, Kind};

    /// The analytic Jacobian against central differences of the residuals (the test oracle).
    #[test]
    fn jacobian_matches_finite_differences() {
        let data = crate::spectral::simulate_named(
            "nikon-d5100",
            "D65",
            "cc24",
            &crate::spectral::Grid::default(),
        )
        .unwrap();
        for (kind, order, power, lambda) in [
            (Kind::Nsrm, 2, 2.0, 0.0),
            (Kind::Rprm, 2, 3.0, 1e-3),
            (Kind::Lrm, 1, 2.0, 0.0),
        ] {
            let t = terms(kind, order);
            let d = design(kind, &t, &data.labels, &data.rgb, &data.xyz).unwrap();
            let red = Reduced::new(kind, &t, &d, None);
            let z = crate::model::fit::lstsq(d.a.clone(), &d.b).unwrap();
            let lab = data
                .xyz
                .iter()
                .map(|x| xyz_to_lab(*x, data.white_xyz))
                .collect();
            let pb = Problem {
                red: &red,
                d: &d,
                lab,
                white: data.white_xyz,
                power,
                pen: lambda.sqrt(),
            };
            let (r0, j) = pb.linearise(&z);
            // Residuals square-sum to the objective.
            let (_, obj) = pb.value(&z);
            assert!((r0.norm_squared() - obj).abs() < 1e-9 * obj);
            let lr = red.g.ncols();
            for k in 0..3 {
                for jj in 0..lr {
                    let h = 1e-6 * z[(jj, k)].abs().max(1e-3);
                    let (mut up, mut down) = (z.clone(), z.clone());
                    up[(jj, k)] += h;
                    down[(jj, k)] -= h;
                    let fd = (pb.linearise(&up).0 - pb.linearise(&down).0) / (2.0 * h);
                    let col = j.column(k * lr + jj);
                    let err = (&fd - col).amax();
                    assert!(
                        err <= 1e-4 * fd.amax().max(1e-6),
                        "{kind} {order} P={power} column {k},{jj}: {err} vs {}",
                        fd.amax()
                    );
                }
            }
        }
    }
}
