//! Fitting a model to training patches: least squares by SVD, with an optional equality
//! constraint (`--preserve-white`), Tikhonov regularisation on standardised terms (`--ridge`), white
//! balancing of NSRM's input (`--normalise white-balanced`), and a ΔE00 objective (`--objective
//! de00`, refined by Levenberg–Marquardt in [`super::refine`]).
//!
//! Why one file (about 1,250 lines): the fit is one pipeline (`Problem::new` → solve → guard →
//! report) over one design matrix; the ΔE00 refinement is `refine.rs`, the tests `fit_tests.rs`.
//!
//! # The least-squares problem
//! Each patch `i` gives a row `p(S_i)` of the design matrix `A` (n × L) and a target row `t_i`:
//! `XYZ_i` for LRM, PRM and RPRM, `XYZ_i / s_i` for NSRM (`s = R+G+B`). Every output channel `k`
//! solves `min ‖A m_k − t_k‖²` (`m_k` = row k of the matrix), by SVD with numpy's cut-off.
//!
//! * **Ridge** adds `λ Σ_j (w_j m_kj)²`, `w_j = ‖A_j‖` (each term standardised to unit norm over the
//!   training patches, so `λ` is dimensionless); NSRM's constant term is not penalised. `auto`
//!   chooses `λ` on a log grid `10^-12 … 10^1` (quarter decades) by generalised cross-validation,
//!   `GCV(λ) = n·RSS(λ) / (n − tr H(λ))²`; `auto-loo` by exact leave-one-out of the ridge solve,
//!   `PRESS(λ) = Σ_i ‖e_i‖² / (1 − H_ii)²` (the closed-form residual of patch `i` predicted by the
//!   solve without it, the standardisation weights `w_j` held at their all-patch values; tested
//!   against refits). GCV stays the default `auto`: it replaces each `H_ii` by their mean, so a
//!   single high-leverage patch (`H_ii → 1`) does not dominate the choice.
//! * **White preservation** requires `p(S_w)·m_k = t_w,k` exactly, for the reference white's camera
//!   RGB `S_w` and XYZ: a linear constraint (for NSRM, at the white's `(r, g)`). It is solved in the
//!   constraint's null space: `m_k = m_p,k + N z_k`, with `m_p,k` the minimum-norm solution of the
//!   constraint and `N` an orthonormal basis of `p(S_w)^⊥` (a Householder reflector).
//!
//! # Bounded, checked numerics
//! Every design entry and target is checked before the solve: finite, and 0 or
//! `1e-100 ≤ |v| ≤ 1e100` ([`DESIGN_LIMIT`]); a patch of `1e200` (PRM's `R³` overflows) or a channel
//! scaled by `1e-200` is refused with [`ModelError::OutOfRange`], naming the patch and the term.
//! Every SVD runs with an iteration limit ([`svd`]), failing with [`ModelError::NotConverged`]
//! rather than spinning.

use super::{features, refine, terms, Kind, Model, ModelError, Term, MAX_ORDER};
use crate::training::TrainingSet;
use nalgebra::{DMatrix, DVector, SVD};

/// The largest magnitude (and the reciprocal of the smallest non-zero one) a design entry or
/// target may have: squares and products of such numbers stay far inside f64's range.
pub(crate) const DESIGN_LIMIT: f64 = 1e100;

/// What the fit minimises.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    /// Σ‖M·p − t‖² (the paper's fit).
    LeastSquares,
    /// Σ ΔE00^power over the training patches (power ≥ 2; 2 is `de00`), starting from the
    /// least-squares solution.
    De00 {
        /// The exponent P (2 ≤ P ≤ 64).
        power: f64,
    },
}

impl Objective {
    /// Parses `ls`, `de00` or `de00:P` (P ≥ 2, at most 64).
    pub fn parse(s: &str) -> Result<Objective, ModelError> {
        let s = s.trim();
        let bad = || {
            ModelError::Spec(format!(
                "objective `{s}`: expected ls, de00 or de00:P with 2 ≤ P ≤ 64"
            ))
        };
        if s.eq_ignore_ascii_case("ls") {
            return Ok(Objective::LeastSquares);
        }
        if s.eq_ignore_ascii_case("de00") {
            return Ok(Objective::De00 { power: 2.0 });
        }
        let (head, p) = s.split_once(':').ok_or_else(bad)?;
        if !head.eq_ignore_ascii_case("de00") {
            return Err(bad());
        }
        let power: f64 = p.trim().parse().map_err(|_| bad())?;
        if !(2.0..=64.0).contains(&power) {
            return Err(bad());
        }
        Ok(Objective::De00 { power })
    }

    /// `ls`, `de00`, `de00:4`.
    pub fn name(&self) -> String {
        match self {
            Objective::LeastSquares => "ls".into(),
            Objective::De00 { power } if *power == 2.0 => "de00".into(),
            Objective::De00 { power } => format!("de00:{power}"),
        }
    }
}

/// The reference white of a fit: what `preserve_white` keeps exact and white balance divides by.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum White {
    /// The perfect white of the training illuminant ([`TrainingSet::white_rgb`] → `white_xyz`).
    #[default]
    Perfect,
    /// A named (neutral) training patch, with its own RGB and XYZ.
    Patch(String),
}

/// Tikhonov regularisation of the matrix.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Ridge {
    /// No regularisation (the paper's fit).
    #[default]
    None,
    /// A fixed λ ≥ 0 (on standardised terms).
    Lambda(f64),
    /// λ chosen by generalised cross-validation.
    Auto,
    /// λ chosen by exact (closed-form) leave-one-out of the ridge solve.
    AutoLoo,
}

impl Ridge {
    /// Parses `auto` or a number ≥ 0 (`0` is no regularisation).
    pub fn parse(s: &str) -> Result<Ridge, ModelError> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("auto") || s.eq_ignore_ascii_case("auto-gcv") {
            return Ok(Ridge::Auto);
        }
        if s.eq_ignore_ascii_case("auto-loo") {
            return Ok(Ridge::AutoLoo);
        }
        match s.parse::<f64>() {
            Ok(0.0) => Ok(Ridge::None),
            Ok(v) if v.is_finite() && v > 0.0 && v <= 1e12 => Ok(Ridge::Lambda(v)),
            _ => Err(ModelError::Spec(format!(
                "ridge `{s}`: expected auto (GCV), auto-loo or a number in [0, 1e12]"
            ))),
        }
    }
}

/// How NSRM's input is normalised before forming `s, r, g`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Normalise {
    /// Raw camera RGB (the paper).
    #[default]
    #[cfg_attr(feature = "clap", value(name = "raw"))]
    Raw,
    /// R, G, B divided by the training white's camera response (the white becomes (1, 1, 1)).
    #[cfg_attr(feature = "clap", value(name = "white-balanced", alias = "wb"))]
    WhiteBalanced,
}

impl Normalise {
    /// Parses `raw` or `white-balanced`.
    pub fn parse(s: &str) -> Result<Normalise, ModelError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "raw" => Ok(Normalise::Raw),
            "white-balanced" | "wb" => Ok(Normalise::WhiteBalanced),
            other => Err(ModelError::Spec(format!(
                "normalise `{other}`: expected raw or white-balanced"
            ))),
        }
    }

    /// `raw` or `white-balanced`.
    pub fn name(self) -> &'static str {
        match self {
            Normalise::Raw => "raw",
            Normalise::WhiteBalanced => "white-balanced",
        }
    }
}

/// Another evaluator of fitted models in f32 that the f32 guard measures beside this machine's
/// fast CPU kernel: the GPU shader, where an adapter is open (`nsrm::gpu::ShaderCheck`).
pub trait F32Evaluator: Send + Sync + std::fmt::Debug {
    /// What it evaluates on, for messages and the fit report (`GPU llvmpipe (…)`).
    fn name(&self) -> String;
    /// `model`'s f32 outputs (packed X, Y, Z) for the packed camera RGB `rgb`, or `None` when
    /// it could not evaluate.
    fn evaluate(&self, model: &Model, rgb: &[f32]) -> Option<Vec<f32>>;
}

/// Everything that defines a fit besides the kind and order. `Default` is the paper's fit.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// What the fit minimises.
    pub objective: Objective,
    /// Map [`FitOptions::white`] exactly to its reference XYZ.
    pub preserve_white: bool,
    /// The reference white that `preserve_white` keeps and white balance divides by.
    pub white: White,
    /// Tikhonov regularisation of the matrix.
    pub ridge: Ridge,
    /// NSRM's input normalisation.
    pub normalise: Normalise,
    /// The f32 guard: when evaluating the fitted model in f32 as `apply` does (the fast CPU
    /// kernel) measurably moves its output by more than [`F32_TOLERANCE_DE00`] on the training
    /// patches or on [`f32_probe`]'s in-gamut probe set, raise the ridge λ until it does not
    /// (`fit`'s default). `false` keeps the fit as solved (the paper's method: what `eval`
    /// evaluates unless asked for the guarded fits, and what an explicit `--ridge 0` asks for).
    pub f32_guard: bool,
    /// Where else the f32 error is measured (the GPU shader where an adapter is open): the guard
    /// decides on the larger of the CPU kernel's and this one's. `None`: the CPU kernel only.
    pub f32_also: Option<std::sync::Arc<dyn F32Evaluator>>,
}

impl PartialEq for FitOptions {
    /// The same fit: equal options, and the same `f32_also` evaluator (or none).
    fn eq(&self, o: &Self) -> bool {
        let also = match (&self.f32_also, &o.f32_also) {
            (None, None) => true,
            (Some(a), Some(b)) => std::sync::Arc::ptr_eq(a, b),
            _ => false,
        };
        also && self.objective == o.objective
            && self.preserve_white == o.preserve_white
            && self.white == o.white
            && self.ridge == o.ridge
            && self.normalise == o.normalise
            && self.f32_guard == o.f32_guard
    }
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            objective: Objective::LeastSquares,
            preserve_white: false,
            white: White::Perfect,
            ridge: Ridge::None,
            normalise: Normalise::Raw,
            f32_guard: true,
            f32_also: None,
        }
    }
}

impl FitOptions {
    /// These options without the f32 guard: the fit exactly as solved (the paper's method when
    /// the rest is the default).
    pub fn unguarded(&self) -> FitOptions {
        FitOptions {
            f32_guard: false,
            ..self.clone()
        }
    }
}

/// What the f32 guard changed in a fit: the λ it started from, and the fit before and after.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct F32GuardChange {
    /// The λ the options asked for (0: none).
    pub lambda_before: f64,
    /// The measured f32 evaluation error of the fit at that λ (ΔE00; what triggered the guard).
    pub f32_error_before: f64,
    /// In-sample ΔE00 mean and max of the fit at that λ.
    pub de00_mean_before: f64,
    /// See `de00_mean_before`.
    pub de00_max_before: f64,
    /// In-sample ΔE00 mean and max of the fit kept (at the raised λ).
    pub de00_mean_after: f64,
    /// See `de00_mean_after`.
    pub de00_max_after: f64,
}

/// What a fit did, for `fit`'s summary and the model file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FitReport {
    /// `ls`, `de00`, `de00:P`.
    pub objective: String,
    /// `none`, `perfect-white` or `patch:LABEL`.
    pub preserve_white: String,
    /// `raw` or `white-balanced`.
    pub normalise: String,
    /// The ridge λ used (0: none), and whether it was chosen automatically (by GCV, or by exact
    /// leave-one-out: `ridge_criterion`).
    pub ridge_lambda: f64,
    /// Whether λ was chosen automatically.
    pub ridge_auto: bool,
    /// `gcv` or `loo` when λ was chosen automatically (absent in older files: GCV).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ridge_criterion: Option<String>,
    /// Frobenius norm of the fitted matrix.
    pub coefficient_norm: f64,
    /// σ_max / σ_min of the design matrix `A` (the terms as fitted); `None` when it is singular.
    pub condition_number: Option<f64>,
    /// Input gains multiplied into camera RGB before the terms (white-balanced NSRM), else 1.
    pub input_gains: [f64; 3],
    /// In-sample Σ ΔE00^P at the least-squares start and at the end (ΔE00 objective only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub de00_start: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    /// In-sample Σ ΔE00^P at the end (ΔE00 objective only).
    pub de00_end: Option<f64>,
    /// Levenberg–Marquardt iterations (Jacobian evaluations), 0 for least squares.
    pub iterations: usize,
    /// A bound on the ΔE00 that evaluating the model in f32 (the fast CPU kernels, the shaders)
    /// can add to any training patch (`f32_error_bound`; a diagnostic, far above what is measured;
    /// absent in older files).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub f32_error_bound: Option<f64>,
    /// The measured f32 evaluation error: the largest ΔE00 between the fast CPU kernel's f32
    /// output and the f64 reference over the training patches and [`f32_probe`]'s probe set
    /// (`f32_error_probe`; what the guard decides on; absent in older files).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub f32_error_measured: Option<f64>,
    /// Where else the f32 error was measured ([`FitOptions::f32_also`]: the GPU the fit found);
    /// absent when only on the CPU kernel.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub f32_measured_on: Option<String>,
    /// What it measured there (included in `f32_error_measured`; infinite when it gave no
    /// output).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub f32_error_also: Option<f64>,
    /// The λ the options asked for (0: none), when the fit raised it to `ridge_lambda` so that the
    /// f32 evaluation error stays within [`F32_TOLERANCE_DE00`]; absent when it did not.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub ridge_requested: Option<f64>,
    /// What the f32 guard changed, when it raised λ; absent when it did not.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub f32_guard: Option<F32GuardChange>,
}

/// A fitted model with its input gains and report.
#[derive(Debug, Clone)]
pub struct Fit {
    /// The fitted model.
    pub model: Model,
    /// What the fit did (also in [`Model::fit_report`]).
    pub report: FitReport,
}

impl Fit {
    /// Applies the model, input gains included (f64 reference): [`Model::apply_f64`].
    pub fn apply_f64(&self, rgb: [f64; 3]) -> [f64; 3] {
        self.model.apply_f64(rgb)
    }
}

/// The design of a fit: term rows, targets and output scales of the (gain-adjusted) patches.
pub(crate) struct Design {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    /// Output scale per patch (`s` for NSRM, 1 otherwise).
    pub scale: Vec<f64>,
}

fn check_range(label: &str, what: &dyn Fn() -> String, v: f64) -> Result<(), ModelError> {
    let a = v.abs();
    if v.is_finite() && (a == 0.0 || (1.0 / DESIGN_LIMIT..=DESIGN_LIMIT).contains(&a)) {
        Ok(())
    } else {
        Err(ModelError::OutOfRange {
            label: label.to_string(),
            what: what(),
            value: v,
        })
    }
}

/// Builds and checks the design for `rgb` (already multiplied by the gains) and `xyz`.
pub(crate) fn design(
    kind: Kind,
    terms: &[Term],
    labels: &[String],
    rgb: &[[f64; 3]],
    xyz: &[[f64; 3]],
) -> Result<Design, ModelError> {
    let (n, l) = (rgb.len(), terms.len());
    let mut a = DMatrix::<f64>::zeros(n, l);
    let mut b = DMatrix::<f64>::zeros(n, 3);
    let mut scale = Vec::with_capacity(n);
    let mut p = vec![0.0; l];
    for i in 0..n {
        let label = &labels[i];
        if rgb[i].iter().chain(&xyz[i]).any(|v| !v.is_finite()) {
            return Err(ModelError::NonFinite {
                label: label.clone(),
                rgb: rgb[i],
                xyz: xyz[i],
            });
        }
        let s =
            features(kind, terms, rgb[i], &mut p).ok_or_else(|| ModelError::NonPositiveSignal {
                label: label.clone(),
                sum: rgb[i].iter().sum(),
            })?;
        for (j, v) in p.iter().enumerate() {
            check_range(
                label,
                &|| format!("term {}", super::term_name(kind, &terms[j])),
                *v,
            )?;
            a[(i, j)] = *v;
        }
        for k in 0..3 {
            let t = xyz[i][k] / s;
            check_range(label, &|| format!("target {}", ["X", "Y", "Z"][k]), t)?;
            b[(i, k)] = t;
        }
        scale.push(s);
    }
    Ok(Design { a, b, scale })
}

/// SVD with an iteration limit: never spins on a pathological matrix.
pub(crate) fn svd(
    a: DMatrix<f64>,
    vectors: bool,
) -> Result<SVD<f64, nalgebra::Dyn, nalgebra::Dyn>, ModelError> {
    let dim = a.nrows().min(a.ncols());
    let max_iter = 200 + 100 * dim;
    if a.iter().any(|v| !v.is_finite()) {
        return Err(ModelError::NotConverged {
            what: "SVD (the matrix is not finite)",
            iterations: 0,
        });
    }
    a.try_svd(vectors, vectors, f64::EPSILON * 5.0, max_iter)
        .ok_or(ModelError::NotConverged {
            what: "SVD",
            iterations: max_iter,
        })
}

/// numpy's default cut-off for small singular values: `σ ≤ ε·max(rows, cols)·σ_max`.
fn cutoff(svd: &SVD<f64, nalgebra::Dyn, nalgebra::Dyn>, rows: usize, cols: usize) -> f64 {
    f64::EPSILON * rows.max(cols) as f64 * svd.singular_values.max()
}

/// Minimum-norm least-squares solution of `A·X ≈ B` by (bounded) SVD with numpy's cut-off.
#[cfg(test)]
pub(crate) fn lstsq(a: DMatrix<f64>, b: &DMatrix<f64>) -> Result<DMatrix<f64>, ModelError> {
    let (n, l) = a.shape();
    let svd = svd(a, true)?;
    let eps = cutoff(&svd, n, l);
    svd.solve(b, eps).map_err(|_| ModelError::Degenerate)
}

/// An equality constraint `cᵀ m_k = d_k` for every output channel, in null-space form.
pub(crate) struct Constraint {
    /// The particular (minimum-norm) solution, L × 3.
    pub xp: DMatrix<f64>,
    /// Orthonormal basis of `c^⊥`, L × (L−1).
    pub basis: DMatrix<f64>,
}

impl Constraint {
    fn new(c: &[f64], d: [f64; 3]) -> Result<Constraint, ModelError> {
        let l = c.len();
        let norm2: f64 = c.iter().map(|v| v * v).sum();
        if !(norm2 > 0.0 && norm2.is_finite()) {
            return Err(ModelError::Invalid(
                "the white's terms are all zero: the constraint is empty".into(),
            ));
        }
        let mut xp = DMatrix::<f64>::zeros(l, 3);
        for j in 0..l {
            for k in 0..3 {
                xp[(j, k)] = c[j] * d[k] / norm2;
            }
        }
        // Householder reflector H = I − 2vvᵀ/(vᵀv), v = c + sign(c₀)‖c‖e₀: H e₀ ∥ c, so H's
        // other columns are an orthonormal basis of c^⊥.
        let norm = norm2.sqrt();
        let mut v = c.to_vec();
        v[0] += if c[0] >= 0.0 { norm } else { -norm };
        let vv: f64 = v.iter().map(|x| x * x).sum();
        let mut basis = DMatrix::<f64>::zeros(l, l - 1);
        for col in 1..l {
            for row in 0..l {
                let id = if row == col { 1.0 } else { 0.0 };
                basis[(row, col - 1)] = id - 2.0 * v[row] * v[col] / vv;
            }
        }
        Ok(Constraint { xp, basis })
    }
}

/// The reduced, possibly regularised least-squares problem in the unknowns `z` (L × 3, or
/// (L−1) × 3 under a constraint): data rows `G z ≈ B_r` and penalty rows.
pub(crate) struct Reduced {
    /// `A N` (or `A`), n × L_r.
    pub g: DMatrix<f64>,
    /// `B − A m_p` (or `B`), n × 3.
    pub br: DMatrix<f64>,
    /// Penalty weights `diag(w)·N` (or `diag(w)`), L × L_r, and offsets `diag(w)·m_p`, L × 3.
    pub wn: DMatrix<f64>,
    pub wxp: DMatrix<f64>,
    pub constraint: Option<Constraint>,
}

impl Reduced {
    pub(crate) fn new(
        kind: Kind,
        terms: &[Term],
        d: &Design,
        constraint: Option<Constraint>,
    ) -> Reduced {
        let l = d.a.ncols();
        let w: Vec<f64> = (0..l)
            .map(|j| {
                if kind == Kind::Nsrm && terms[j].degree() == 0 {
                    0.0
                } else {
                    d.a.column(j).norm()
                }
            })
            .collect();
        let wdiag = DMatrix::from_diagonal(&DVector::from_vec(w));
        match &constraint {
            Some(c) => Reduced {
                g: &d.a * &c.basis,
                br: &d.b - &d.a * &c.xp,
                wn: &wdiag * &c.basis,
                wxp: &wdiag * &c.xp,
                constraint,
            },
            None => Reduced {
                g: d.a.clone(),
                br: d.b.clone(),
                wn: wdiag,
                wxp: DMatrix::zeros(l, 3),
                constraint: None,
            },
        }
    }

    /// The full matrix (L × 3) from reduced unknowns.
    pub(crate) fn full(&self, z: &DMatrix<f64>) -> DMatrix<f64> {
        match &self.constraint {
            Some(c) => &c.xp + &c.basis * z,
            None => z.clone(),
        }
    }

    /// Solves for `z` at ridge `lambda` (0: plain least squares); returns `z`, the data residual
    /// sum of squares and the trace of the hat matrix (the effective number of parameters).
    fn solve(&self, lambda: f64) -> Result<(DMatrix<f64>, f64, f64), ModelError> {
        self.solve_loo(lambda).map(|r| (r.z, r.rss, r.trace))
    }

    /// [`solve`](Self::solve) with the diagonal of the hat matrix and the residuals, for the
    /// closed-form leave-one-out residuals `e_i / (1 − H_ii)`.
    fn solve_loo(&self, lambda: f64) -> Result<RidgeSolve, ModelError> {
        let (n, lr) = self.g.shape();
        let l = self.wn.nrows();
        let (k, rhs) = if lambda > 0.0 {
            let sl = lambda.sqrt();
            let mut k = DMatrix::<f64>::zeros(n + l, lr);
            k.rows_mut(0, n).copy_from(&self.g);
            k.rows_mut(n, l).copy_from(&(&self.wn * sl));
            let mut rhs = DMatrix::<f64>::zeros(n + l, 3);
            rhs.rows_mut(0, n).copy_from(&self.br);
            rhs.rows_mut(n, l).copy_from(&(&self.wxp * -sl));
            (k, rhs)
        } else {
            (self.g.clone(), self.br.clone())
        };
        let rows = k.nrows();
        let svd = svd(k, true)?;
        let eps = cutoff(&svd, rows, lr);
        let z = svd.solve(&rhs, eps).map_err(|_| ModelError::Degenerate)?;
        let u = svd.u.as_ref().expect("computed");
        let mut leverage = vec![0.0; n];
        for (c, s) in svd.singular_values.iter().enumerate() {
            if *s > eps {
                for (i, h) in leverage.iter_mut().enumerate() {
                    *h += u[(i, c)] * u[(i, c)];
                }
            }
        }
        let trace = leverage.iter().sum();
        let residuals = &self.g * &z - &self.br;
        let rss = residuals.norm_squared();
        Ok(RidgeSolve {
            z,
            rss,
            trace,
            leverage,
            residuals,
        })
    }

    /// `PRESS(λ) = Σ_i ‖e_i‖² / (1 − H_ii)²` and the solution, or `None` for the solution when
    /// some patch has leverage 1 (its left-out residual is undefined).
    fn press(&self, lambda: f64) -> Result<(DMatrix<f64>, Option<f64>), ModelError> {
        let r = self.solve_loo(lambda)?;
        let mut press = 0.0;
        for (i, h) in r.leverage.iter().enumerate() {
            let d = 1.0 - h;
            if d <= 1e-12 {
                return Ok((r.z, None));
            }
            press += r.residuals.row(i).norm_squared() / (d * d);
        }
        Ok((r.z, Some(press)))
    }
}

/// One ridge solve with what the λ criteria need.
struct RidgeSolve {
    z: DMatrix<f64>,
    rss: f64,
    trace: f64,
    /// `H_ii`, the diagonal of the data block of the hat matrix.
    leverage: Vec<f64>,
    /// `G z − B_r`, n × 3.
    residuals: DMatrix<f64>,
}

/// The λ grid of `--ridge auto`: 10^-12 … 10^1 in quarter decades.
pub(crate) fn lambda_grid() -> impl Iterator<Item = f64> {
    (0..=52).map(|i| 10f64.powf(-12.0 + 0.25 * i as f64))
}

/// Fits `kind` at `order` with `opts` (least squares by SVD, optionally ridge, white-preserving or ΔE00-refined).
///
/// The steps: `Problem::new` checks the order and the patch count, takes the input gains and
/// builds the design and the white constraint; `Problem::solve` picks λ and solves the
/// (regularised) least squares; `Problem::finish` refines under the ΔE00 objective, builds the
/// model and measures the error of evaluating it in f32 as `apply` does ([`f32_error_probe`]);
/// `Problem::guard_f32` then, when that measured error exceeds [`F32_TOLERANCE_DE00`] and
/// [`FitOptions::f32_guard`] is on, raises λ until it does not.
pub fn fit_with(
    kind: Kind,
    order: u8,
    data: &TrainingSet,
    opts: &FitOptions,
) -> Result<Fit, ModelError> {
    let problem = Problem::new(kind, order, data, opts)?;
    let (lambda, z) = problem.solve(opts.ridge)?;
    let first = problem.finish(lambda, z)?;
    let (solved, change) = problem.guard_f32(first)?;
    Ok(problem.report(solved, change))
}

/// The ΔE00 by which evaluating a fitted model in f32 (fast CPU kernels, shaders) may move its
/// output, at most: [`fit_with`] raises the ridge λ until the measured [`f32_error_probe`] is
/// within it, so that `apply` reproduces the in-sample ΔE00 the fit reports to within 0.01.
pub const F32_TOLERANCE_DE00: f64 = 0.01;

/// The ridge λ [`fit_with`] tries, in order, when a fit's f32 evaluation error is too large: 10^-16
/// … 10^2 in quarter decades (above the λ the options asked for).
pub(crate) fn f32_guard_grid() -> impl Iterator<Item = f64> {
    (0..=72).map(|i| 10f64.powf(-16.0 + 0.25 * i as f64))
}

/// A fit in progress: the checked inputs, the design and the reduced problem.
struct Problem<'a> {
    kind: Kind,
    order: u8,
    terms: Vec<Term>,
    data: &'a TrainingSet,
    opts: &'a FitOptions,
    gains: [f64; 3],
    d: Design,
    reduced: Reduced,
    condition_number: Option<f64>,
    /// The design's SVD with its vectors when the fit is plain least squares (no constraint, no
    /// ridge asked for): the one SVD the paper's fit needs, reused by [`Problem::solve`].
    plain: Option<SVD<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    /// The camera RGB the f32 error is measured on: the training patches and [`f32_probe`]'s.
    probe: Vec<[f64; 3]>,
}

/// A solved fit: the model (report not yet attached), the λ it was solved at, and the ΔE00
/// objective's start, end and iterations.
struct Solved {
    model: Model,
    lambda: f64,
    de00: Option<(f64, f64)>,
    iterations: usize,
    f32_bound: f64,
    /// The measured f32 error of the model: the larger of [`f32_error_probe`] and the
    /// [`FitOptions::f32_also`] evaluator's (what the guard decides on).
    f32_measured: f64,
    /// The [`FitOptions::f32_also`] evaluator's measurement, when there is one.
    f32_also: Option<f64>,
}

impl<'a> Problem<'a> {
    /// Step 1: checks the order and the patch count, takes the input gains (white-balanced NSRM),
    /// builds and checks the design and the white constraint, and the design's condition number.
    fn new(
        kind: Kind,
        order: u8,
        data: &'a TrainingSet,
        opts: &'a FitOptions,
    ) -> Result<Problem<'a>, ModelError> {
        if !(1..=MAX_ORDER).contains(&order) {
            return Err(ModelError::Order(order));
        }
        let order = kind.effective_order(order);
        let terms = terms(kind, order);
        let (l, n) = (terms.len(), data.len());
        if n < l {
            return Err(ModelError::TooFewPatches {
                kind,
                order,
                terms: l,
                patches: n,
            });
        }
        let gains = input_gains(kind, data, opts)?;
        let rgb: Vec<[f64; 3]> = data.rgb.iter().map(|c| gain(*c, gains)).collect();
        let d = design(kind, &terms, &data.labels, &rgb, &data.xyz)?;
        let constraint = white_constraint(kind, &terms, data, opts, gains)?;
        let plain = constraint.is_none() && opts.ridge == Ridge::None;
        let a_svd = svd(d.a.clone(), plain)?;
        let sv = &a_svd.singular_values;
        let (smax, smin) = (sv.max(), sv.min());
        let reduced = Reduced::new(kind, &terms, &d, constraint);
        let mut probe = data.rgb.clone();
        probe.extend(f32_probe(&data.rgb));
        Ok(Problem {
            kind,
            order,
            terms,
            data,
            opts,
            gains,
            d,
            reduced,
            condition_number: (smin > 0.0).then(|| smax / smin),
            plain: plain.then_some(a_svd),
            probe,
        })
    }

    /// Step 2: the ridge λ (fixed, or chosen by GCV or leave-one-out) and the reduced unknowns
    /// solved at it.
    fn solve(&self, ridge: Ridge) -> Result<(f64, DMatrix<f64>), ModelError> {
        let n = self.data.len() as f64;
        let r = &self.reduced;
        match ridge {
            Ridge::None => match &self.plain {
                Some(a_svd) => {
                    let (rows, cols) = self.d.a.shape();
                    let eps = cutoff(a_svd, rows, cols);
                    let z = a_svd
                        .solve(&self.d.b, eps)
                        .map_err(|_| ModelError::Degenerate)?;
                    Ok((0.0, z))
                }
                None => Ok((0.0, r.solve(0.0)?.0)),
            },
            Ridge::Lambda(lam) => Ok((lam, r.solve(lam)?.0)),
            Ridge::Auto => best_on_grid(|lam| {
                let (z, rss, tr) = r.solve(lam)?;
                let dof = n - tr;
                Ok((dof > 0.0).then(|| (n * rss / (dof * dof), z)))
            }),
            Ridge::AutoLoo => best_on_grid(|lam| {
                let (z, press) = r.press(lam)?;
                Ok(press.map(|p| (p, z)))
            }),
        }
    }

    /// Step 3: refines `z` under the ΔE00 objective (if asked), builds the model, and bounds its
    /// f32 evaluation error on the training patches.
    fn finish(&self, lambda: f64, z: DMatrix<f64>) -> Result<Solved, ModelError> {
        let (z, de00, iterations) = match self.opts.objective {
            Objective::LeastSquares => (z, None, 0),
            Objective::De00 { power } => {
                let r = refine::refine(
                    &self.reduced,
                    &self.d,
                    &z,
                    lambda,
                    power,
                    &self.data.xyz,
                    self.data.white_xyz,
                )?;
                (r.z, Some((r.start, r.end)), r.iterations)
            }
        };
        let x = self.reduced.full(&z);
        let l = self.terms.len();
        let mut matrix = vec![0.0; 3 * l];
        for i in 0..3 {
            for j in 0..l {
                matrix[i * l + j] = x[(j, i)];
            }
        }
        if matrix.iter().any(|v| !super::finite_in_f32(*v)) {
            return Err(ModelError::Degenerate);
        }
        let model = Model {
            kind: self.kind,
            order: self.order,
            terms: self.terms.clone(),
            matrix,
            white_xyz: self.data.white_xyz,
            provenance: self.data.provenance.clone(),
            patches: self.data.labels.clone(),
            fit_report: None,
            input_gains: super::UNIT_GAINS,
            frame_white: false,
            highlights: None,
        }
        .with_input_gains(self.gains)?;
        let f32_bound = f32_error_bound(&model, &self.data.rgb, &self.data.xyz);
        let cpu = f32_error_probe(&model, &self.probe);
        let f32_also = self
            .opts
            .f32_also
            .as_ref()
            .map(|e| f32_error_on(e.as_ref(), &model, &self.probe));
        Ok(Solved {
            model,
            lambda,
            de00,
            iterations,
            f32_bound,
            f32_measured: cpu.max(f32_also.unwrap_or(0.0)),
            f32_also,
        })
    }

    /// Step 4: keeps `first` if the f32 guard is off or its measured f32 evaluation error is
    /// within [`F32_TOLERANCE_DE00`]; otherwise refits at the smallest λ of [`f32_guard_grid`]
    /// above `first`'s whose measured error is (bisection: the error falls as λ grows), returning
    /// it with what changed. A fit that no λ of the grid makes safe is refused with
    /// [`ModelError::F32Unstable`].
    fn guard_f32(&self, first: Solved) -> Result<(Solved, Option<F32GuardChange>), ModelError> {
        if !self.opts.f32_guard || first.f32_measured <= F32_TOLERANCE_DE00 {
            return Ok((first, None));
        }
        let grid: Vec<f64> = f32_guard_grid().filter(|g| *g > first.lambda).collect();
        let at = |lam: f64| {
            self.reduced
                .solve(lam)
                .and_then(|(z, ..)| self.finish(lam, z))
        };
        let mut best: Option<Solved> = None;
        let (mut lo, mut hi) = (0, grid.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            let s = at(grid[mid])?;
            if s.f32_measured <= F32_TOLERANCE_DE00 {
                hi = mid;
                best = Some(s);
            } else {
                lo = mid + 1;
            }
        }
        match best {
            Some(s) => {
                let (mean_before, max_before) = self.in_sample(&first.model);
                let (mean_after, max_after) = self.in_sample(&s.model);
                let change = F32GuardChange {
                    lambda_before: first.lambda,
                    f32_error_before: first.f32_measured,
                    de00_mean_before: mean_before,
                    de00_max_before: max_before,
                    de00_mean_after: mean_after,
                    de00_max_after: max_after,
                };
                Ok((s, Some(change)))
            }
            None => Err(ModelError::F32Unstable {
                kind: self.kind,
                order: self.order,
                bound: first.f32_measured,
                tolerance: F32_TOLERANCE_DE00,
            }),
        }
    }

    /// In-sample ΔE00 mean and max of `model` on the training patches (f64).
    fn in_sample(&self, model: &Model) -> (f64, f64) {
        let d = self.data;
        let de: Vec<f64> = d
            .rgb
            .iter()
            .zip(&d.xyz)
            .map(|(c, x)| crate::colorimetry::delta_e00_xyz(model.apply_f64(*c), *x, d.white_xyz))
            .collect();
        let mean = de.iter().sum::<f64>() / de.len().max(1) as f64;
        (mean, de.iter().copied().fold(0.0, f64::max))
    }

    /// Step 5: the report, attached to the model.
    fn report(&self, s: Solved, change: Option<F32GuardChange>) -> Fit {
        let opts = self.opts;
        let coefficient_norm = s.model.matrix.iter().map(|v| v * v).sum::<f64>().sqrt();
        let report = FitReport {
            objective: opts.objective.name(),
            preserve_white: match (opts.preserve_white, &opts.white) {
                (false, _) => "none".into(),
                (true, White::Perfect) => "perfect-white".into(),
                (true, White::Patch(l)) => format!("patch:{l}"),
            },
            normalise: opts.normalise.name().into(),
            ridge_lambda: s.lambda,
            ridge_auto: matches!(opts.ridge, Ridge::Auto | Ridge::AutoLoo),
            ridge_criterion: match opts.ridge {
                Ridge::Auto => Some("gcv".into()),
                Ridge::AutoLoo => Some("loo".into()),
                _ => None,
            },
            coefficient_norm,
            condition_number: self.condition_number,
            input_gains: self.gains,
            de00_start: s.de00.map(|d| d.0),
            de00_end: s.de00.map(|d| d.1),
            iterations: s.iterations,
            f32_error_bound: Some(s.f32_bound),
            f32_error_measured: Some(s.f32_measured),
            f32_measured_on: s.f32_also.and(opts.f32_also.as_ref()).map(|e| e.name()),
            f32_error_also: s.f32_also,
            ridge_requested: change.map(|c| c.lambda_before),
            f32_guard: change,
        };
        let mut model = s.model;
        model.fit_report = Some(report.clone());
        Fit { model, report }
    }
}

/// The λ of [`lambda_grid`] with the smallest criterion (`None`: not defined at that λ).
fn best_on_grid(
    mut criterion: impl FnMut(f64) -> Result<Option<(f64, DMatrix<f64>)>, ModelError>,
) -> Result<(f64, DMatrix<f64>), ModelError> {
    let mut best: Option<(f64, f64, DMatrix<f64>)> = None;
    for lam in lambda_grid() {
        if let Some((c, z)) = criterion(lam)? {
            if best.as_ref().is_none_or(|b| c < b.1) {
                best = Some((lam, c, z));
            }
        }
    }
    best.map(|(lam, _, z)| (lam, z))
        .ok_or(ModelError::Degenerate)
}

fn gain(c: [f64; 3], g: [f64; 3]) -> [f64; 3] {
    [c[0] * g[0], c[1] * g[1], c[2] * g[2]]
}

/// The input gains of a fit: 1 unless NSRM is white-balanced, then the reciprocal of the
/// white's camera response (the perfect white's, or a named patch's).
fn input_gains(kind: Kind, data: &TrainingSet, opts: &FitOptions) -> Result<[f64; 3], ModelError> {
    if opts.normalise == Normalise::Raw {
        return Ok(super::UNIT_GAINS);
    }
    if kind != Kind::Nsrm {
        return Err(ModelError::Invalid(format!(
            "white-balanced normalisation is defined for NSRM only, not {kind}"
        )));
    }
    let w = match &opts.white {
        White::Patch(label) => patch_rgb(data, label)?,
        White::Perfect => data.white_rgb.ok_or(ModelError::NoWhite)?,
    };
    if w.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(ModelError::Invalid(format!(
            "the white's camera response {w:?} is not positive: it cannot be balanced"
        )));
    }
    Ok([1.0 / w[0], 1.0 / w[1], 1.0 / w[2]])
}

/// The white constraint of `--preserve-white` (`None` without it): the white's terms (its camera
/// RGB times the gains) must map exactly to its XYZ (scaled like the targets).
fn white_constraint(
    kind: Kind,
    terms: &[Term],
    data: &TrainingSet,
    opts: &FitOptions,
    gains: [f64; 3],
) -> Result<Option<Constraint>, ModelError> {
    if !opts.preserve_white {
        return Ok(None);
    }
    let (w_rgb, w_xyz, label) = match &opts.white {
        White::Patch(label) => {
            let i = patch_index(data, label)?;
            (data.rgb[i], data.xyz[i], label.clone())
        }
        White::Perfect => (
            data.white_rgb.ok_or(ModelError::NoWhite)?,
            data.white_xyz,
            "perfect white".to_string(),
        ),
    };
    let wd = design(kind, terms, &[label], &[gain(w_rgb, gains)], &[w_xyz])?;
    let c: Vec<f64> = wd.a.row(0).iter().copied().collect();
    Constraint::new(&c, [wd.b[(0, 0)], wd.b[(0, 1)], wd.b[(0, 2)]]).map(Some)
}

/// Unit roundoff of f32 (`2^-24`).
const F32_UNIT: f64 = 1.0 / 16_777_216.0;

/// The λ of [`f32_error_bound`]'s probabilistic bound (exceeded with probability `2·e^(-λ²/2)`).
const F32_CONFIDENCE: f64 = 6.0;

/// A bound on how much evaluating `model` in f32 (as the fast CPU kernels and the shaders do,
/// from camera RGB rounded to f32) can change the ΔE00 of any of the patches `rgb` against its
/// reference `xyz`, to first order: the largest over the patches.
///
/// Error analysis of `y_k = s·Σ_j m_kj·t_j` in the standard model of rounding: the product
/// `x_j = m_kj·t_j` of a term of degree `d_j` passes through at most `n_j = 6 + 5·d_j + L`
/// roundings of relative size `≤ u = 2^-24` (the input's rounding to f32, the roots — the CPU's
/// cube root is within 2.2 u, the shaders' refined `pow` about as close — the products, NSRM's
/// division by `s`, the coefficient's rounding, and a sum of L products). Taken as independent
/// (Higham & Mary's probabilistic analysis, Hoeffding's inequality), the error of `y_k` exceeds
/// `e_k = 6·s·u·√(Σ_j n_j·x_j²)` with a probability below `2·e^-18 ≈ 3e-8`; the worst case
/// `s·u·Σ_j n_j·|x_j|` is reached only if every rounding goes the same way, and is far too
/// pessimistic to judge a model by. The ΔE00 moves by at most `‖J·δy‖ ≤ ‖|J|·e‖`, `J` the
/// Jacobian of the CIEDE2000 difference vector (whose norm is ΔE00) with respect to XYZ. Patches
/// NSRM maps to 0 (`s ≤ 0`) add nothing. `tests/all/fit_apply_agree.rs` holds the CPU and GPU
/// paths to what this promises.
pub(crate) fn f32_error_bound(model: &Model, rgb: &[[f64; 3]], xyz: &[[f64; 3]]) -> f64 {
    let white = model.white_xyz();
    let l = model.len_terms();
    let weight: Vec<f64> = model
        .terms()
        .iter()
        .map(|t| (6 + 5 * t.degree() as usize + l) as f64)
        .collect();
    let mut p = vec![0.0; l];
    let mut worst = 0.0f64;
    for (c, x) in rgb.iter().zip(xyz) {
        let Some(s) = model.features_of(*c, &mut p) else {
            continue;
        };
        let mut y = [0.0; 3];
        let mut e = [0.0; 3];
        for k in 0..3 {
            for (j, m) in model.row(k).iter().enumerate() {
                y[k] += s * m * p[j];
                e[k] += weight[j] * (m * p[j]).powi(2);
            }
            e[k] = F32_CONFIDENCE * F32_UNIT * s.abs() * e[k].sqrt();
        }
        let lab = crate::colorimetry::xyz_to_lab(*x, white);
        let jac = crate::colorimetry::delta_e00_vector_xyz_jacobian(y, lab, white);
        let moved: f64 = jac
            .iter()
            .map(|v| {
                let r: f64 = (0..3).map(|k| v.d[k].abs() * e[k]).sum();
                r * r
            })
            .sum::<f64>()
            .sqrt();
        // A non-finite bound (a patch at the edge of Lab's domain) counts as too large.
        worst = if moved.is_finite() {
            worst.max(moved)
        } else {
            f64::INFINITY
        };
    }
    worst
}

/// How much the fast CPU path (f32, this machine's kernels) moves the ΔE00 of the patches `rgb`
/// against their references `xyz`, measured: the largest `|ΔE00(f32) − ΔE00(f64)|`, the camera RGB
/// rounded to f32 as a frame holds it. [`f32_error_bound`] bounds it on every back end.
#[cfg(test)]
pub(crate) fn f32_error_measured(model: &Model, rgb: &[[f64; 3]], xyz: &[[f64; 3]]) -> f64 {
    use crate::frame::{Frame, Layout};
    let data: Vec<f32> = rgb.iter().flat_map(|c| c.map(|v| v as f32)).collect();
    let Some(mut frame) = Frame::from_data(rgb.len(), 1, Layout::Rgb, data) else {
        return f64::NAN;
    };
    super::fast::FastModel::new(model).apply(&mut frame, super::fast::Threads::Single);
    let white = model.white_xyz();
    let de = crate::colorimetry::delta_e00_xyz;
    rgb.iter()
        .zip(xyz)
        .zip(frame.data.chunks_exact(3))
        .map(|((c, x), y)| {
            let fast = [y[0] as f64, y[1] as f64, y[2] as f64];
            (de(fast, *x, white) - de(model.apply_f64(*c), *x, white)).abs()
        })
        .fold(0.0, f64::max)
}

/// How far evaluating `model` in f32 exactly as `apply` does (the fast CPU kernel on this
/// machine, from camera RGB rounded to f32 as a frame holds it) moves its output from the f64
/// reference, measured: the largest ΔE00 between the two over `rgb` (under the model's white).
/// A non-finite output counts as infinitely far. Camera RGB the model does not map (NSRM's
/// `s ≤ 0`) is skipped.
pub(crate) fn f32_error_probe(model: &Model, rgb: &[[f64; 3]]) -> f64 {
    use crate::frame::{Frame, Layout};
    if rgb.is_empty() {
        return 0.0;
    }
    let data: Vec<f32> = rgb.iter().flat_map(|c| c.map(|v| v as f32)).collect();
    let Some(mut frame) = Frame::from_data(rgb.len(), 1, Layout::Rgb, data) else {
        return f64::INFINITY;
    };
    super::fast::FastModel::new(model).apply(&mut frame, super::fast::Threads::Single);
    f32_error_of(model, rgb, &frame.data)
}

/// [`f32_error_probe`] measured on `evaluator` instead of the CPU kernel (infinite when it gives
/// no output, or not one per pixel).
fn f32_error_on(evaluator: &dyn F32Evaluator, model: &Model, rgb: &[[f64; 3]]) -> f64 {
    if rgb.is_empty() {
        return 0.0;
    }
    let data: Vec<f32> = rgb.iter().flat_map(|c| c.map(|v| v as f32)).collect();
    match evaluator.evaluate(model, &data) {
        Some(out) if out.len() == data.len() => f32_error_of(model, rgb, &out),
        _ => f64::INFINITY,
    }
}

/// The largest ΔE00 between `out` (f32 outputs, packed X, Y, Z) and `model`'s f64 reference
/// over `rgb`, as [`f32_error_probe`] measures it.
fn f32_error_of(model: &Model, rgb: &[[f64; 3]], out: &[f32]) -> f64 {
    let white = model.white_xyz();
    let mut p = vec![0.0; model.len_terms()];
    let mut worst = 0.0f64;
    let in_f32 = |v: &[f64; 3]| v.iter().all(|x| x.abs() <= f32::MAX as f64);
    for (c, y) in rgb.iter().zip(out.chunks_exact(3)) {
        // Camera RGB a frame cannot hold, or an output beyond f32's range, is not a question of
        // f32 precision: only what f32 can represent is measured.
        if !in_f32(c) || model.features_of(*c, &mut p).is_none() {
            continue;
        }
        let exact = model.apply_f64(*c);
        if !in_f32(&exact) {
            continue;
        }
        let fast = [y[0] as f64, y[1] as f64, y[2] as f64];
        let d = crate::colorimetry::delta_e00_xyz(fast, exact, white);
        worst = if d.is_finite() {
            worst.max(d)
        } else {
            f64::INFINITY
        };
    }
    worst
}

/// Grid steps per chromaticity axis of [`f32_probe`].
const PROBE_STEPS: usize = 32;

/// Exposures of [`f32_probe`], relative to the brightest training patch: 1, 1/2, …, 1/16.
const PROBE_STOPS: i32 = 4;

/// A dense in-gamut probe set for the f32 guard: camera RGB on a regular grid of camera
/// chromaticities `(R, G)/(R+G+B)` ([`PROBE_STEPS`] per axis over the training patches' range)
/// inside the convex hull of the training patches' chromaticities (the hull's corners included),
/// each at the brightest patch's `R+G+B` times 1, 1/2, …, 2^-[`PROBE_STOPS`]. Patches with
/// `R+G+B ≤ 0` or a negative channel are left out of the hull; fewer than three distinct
/// chromaticities give the patches' own chromaticities only.
pub(crate) fn f32_probe(rgb: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let pts: Vec<[f64; 2]> = rgb
        .iter()
        .filter(|c| c.iter().all(|v| v.is_finite() && *v >= 0.0) && c.iter().sum::<f64>() > 0.0)
        .map(|c| {
            let s: f64 = c.iter().sum();
            [c[0] / s, c[1] / s]
        })
        .collect();
    let bright = rgb
        .iter()
        .map(|c| c.iter().sum::<f64>())
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max);
    if pts.is_empty() || bright <= 0.0 {
        return Vec::new();
    }
    let hull = convex_hull(&pts);
    let mut chroma: Vec<[f64; 2]> = hull.clone();
    if hull.len() >= 3 {
        let (lo, hi) = pts.iter().fold(([1.0f64; 2], [0.0f64; 2]), |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        });
        for i in 0..=PROBE_STEPS {
            for j in 0..=PROBE_STEPS {
                let t =
                    |k: usize, a: usize| lo[a] + (hi[a] - lo[a]) * k as f64 / PROBE_STEPS as f64;
                let p = [t(i, 0), t(j, 1)];
                if inside_hull(&hull, p) {
                    chroma.push(p);
                }
            }
        }
    } else {
        chroma = pts;
    }
    (0..=PROBE_STOPS)
        .flat_map(|k| {
            let s = bright * 0.5f64.powi(k);
            chroma
                .iter()
                .map(move |c| [c[0] * s, c[1] * s, (1.0 - c[0] - c[1]).max(0.0) * s])
        })
        .collect()
}

/// The convex hull of `pts`, counter-clockwise (Andrew's monotone chain), without collinear points.
fn convex_hull(pts: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p = pts.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Whether `q` is inside (or on) the counter-clockwise convex polygon `hull`.
fn inside_hull(hull: &[[f64; 2]], q: [f64; 2]) -> bool {
    (0..hull.len()).all(|i| {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]) >= -1e-12
    })
}

fn patch_index(data: &TrainingSet, label: &str) -> Result<usize, ModelError> {
    data.labels.iter().position(|l| l == label).ok_or_else(|| {
        ModelError::Invalid(format!(
            "white patch `{label}` is not among the training patches"
        ))
    })
}

fn patch_rgb(data: &TrainingSet, label: &str) -> Result<[f64; 3], ModelError> {
    Ok(data.rgb[patch_index(data, label)?])
}

#[cfg(test)]
#[path = "fit_tests.rs"]
mod tests;
