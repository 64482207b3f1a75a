//! The pixel program: what every apply path (the f64 reference, the fast CPU kernels, the WGSL
//! shaders and the exported shaders) does with a pixel, described once ([`Program`]) and printed
//! or evaluated from that description.
//!
//! # The one description
//! A [`Program`] is the per-pixel program of a model kind: a short list of [`Step`]s (the policy,
//! [`Program::steps_of`]) over the kind's term list ([`super::terms::terms`], the one table of
//! terms):
//!
//! ```text
//! LRM, PRM, RPRM:  Combine                             y = M·p(R, G, B)
//! NSRM:            Gain → Normalise → Combine → Rescale
//!                  x = gains⊙(R, G, B); s = x₀+x₁+x₂, s ≤ 0 → (0, 0, 0); y = s·M·p(x₀/s, x₁/s)
//! ```
//!
//! Every back end reads it; none spells a kind's policy by hand:
//! * the f64 evaluator [`Program::features`] / [`Program::eval`] (what
//!   [`super::Model::apply_f64`] and the fit's design matrix run);
//! * the WGSL printer (`crate::gpu::shader`: `fn correct` step by step, `model_terms` from the
//!   term list; only the frame files and the root helpers stay hand-written WGSL);
//! * the DCTL printer (`crate::export::dctl`);
//! * the fast CPU kernels ([`super::fast`]): the generic kernel's policy flags and product plan are
//!   read from the program; each hand-written SIMD kernel declares the steps and the terms (in its
//!   own order) its arithmetic computes, and is chosen only when they are the program's, with its
//!   matrix columns permuted by the index map derived from the program's term order (a unit test
//!   there holds each kernel's arithmetic to its declaration).
//!
//! A new [`Step`] is a compile error in every printer until each spells it (they `match` the
//! steps exhaustively). `tests/all/pixel_policy.rs` holds every printer to the f64 evaluator on
//! the awkward pixels, for every kind and order and white-balanced NSRM; unit tests beside each
//! printer run programs that are *not* a kind's (another policy over another term list) through it,
//! so a printer that read the kind instead of the program would fail.
//!
//! # The policy the standard programs encode
//! * **NaN / ±Inf** in any channel propagate: the output is not finite. Nothing is clamped or hidden.
//! * **NSRM's normalisation** is `s = R+G+B`, `r = R/s`, `g = G/s` ([`nsrm_signal`]). When
//!   `s ≤ 0` (black, or noise around black) the chromaticities are undefined and the output is
//!   `(0, 0, 0)`, the limit of `s·(α,β,γ)` as `s → 0⁺`. `s = NaN` is not `≤ 0`: it flows on and the
//!   output is NaN.
//! * **Input gains** (white-balanced NSRM) multiply R, G, B first; the rest holds for the gained
//!   pixel. Other kinds have no gain step (their gains are 1 by construction).
//! * **Negative channels** are used as they are: LRM and PRM take them in their polynomials; NSRM
//!   takes them in `r, g` as long as `s > 0`; RPRM takes sign-preserving roots
//!   ([`signed_root`], `sign(x)·|x|^(1/d)`), so its output stays finite. A root term is the
//!   product of per-channel roots, `∛(R G²) = ∛R·(∛G)²`, the same number for any signs.
//! * **Values far outside the training range** (HDR highlights) are not clamped: LRM, RPRM and NSRM
//!   scale exactly with exposure, `f(kS) = k·f(S)` for `k > 0`; PRM extrapolates its polynomial.
//!
//! `policy_tests.rs` (the f64 reference, the fast kernels) and `tests/all/pixel_policy.rs` (the
//! GPU, the DCTL) hold each path to these rules on the awkward pixels (zeros,
//! `s < 0`, `s = 0` with non-zero channels, negatives, NaN, ±Inf, huge and tiny values).

use super::terms::{expand, Term};
use super::Kind;

/// One step of a pixel program. The variables `x` start as the camera's `(R, G, B)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Step {
    /// `x ← (g_R·x₀, g_G·x₁, g_B·x₂)`: the model's input gains (1, 1, 1 unless white-balanced).
    Gain,
    /// The signal `s = x₀+x₁+x₂`. When `s ≤ 0` the program ends with `(0, 0, 0)` (the black
    /// rule; NaN is not `≤ 0` and flows on); otherwise `x ← (x₀/s, x₁/s, 0)`, the chromaticities.
    Normalise,
    /// `y = M·p(x)`: the terms of the term list (products of sign-preserving per-channel roots,
    /// [`super::terms::term_factors`]) combined by the 3×L matrix.
    Combine,
    /// `y ← s·y` (after [`Step::Normalise`]).
    Rescale,
}

impl Step {
    /// One line saying what the step does, for the comments of printed code.
    pub fn describe(self) -> &'static str {
        match self {
            Step::Gain => "multiply R, G, B by the input gains (1, 1, 1 unless white-balanced)",
            Step::Normalise => {
                "s = R+G+B; s <= 0 (black, noise around black) gives 0; NaN flows on; x = (R/s, G/s)"
            }
            Step::Combine => "y = M·p(x), the terms from nsrm::model::terms",
            Step::Rescale => "y = s·y",
        }
    }
}

/// The steps of a plain polynomial model (LRM, PRM, RPRM).
const PLAIN: &[Step] = &[Step::Combine];
/// The steps of NSRM.
const NORMALISED: &[Step] = &[Step::Gain, Step::Normalise, Step::Combine, Step::Rescale];

/// The per-pixel program of a model: its [`Step`]s over its term list. The one description every
/// apply path and code printer follows (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Program<'a> {
    /// The kind (names the variables in printed comments: `R, G, B` or `r, g`).
    pub kind: Kind,
    /// The steps, in order.
    pub steps: &'static [Step],
    /// The terms [`Step::Combine`] combines, in matrix-column order.
    pub terms: &'a [Term],
}

impl<'a> Program<'a> {
    /// The steps of `kind`: the pixel policy, written once.
    pub fn steps_of(kind: Kind) -> &'static [Step] {
        match kind {
            Kind::Lrm | Kind::Prm | Kind::Rprm => PLAIN,
            Kind::Nsrm => NORMALISED,
        }
    }

    /// The program of `kind` over `terms` (its term list, from [`super::terms::terms`]).
    pub fn new(kind: Kind, terms: &'a [Term]) -> Program<'a> {
        let p = Program {
            kind,
            steps: Program::steps_of(kind),
            terms,
        };
        debug_assert_eq!(p.check(), Ok(()));
        p
    }

    /// Another policy over a term list: for tests that hold the printers to the description
    /// rather than to a kind.
    pub fn custom(
        kind: Kind,
        steps: &'static [Step],
        terms: &'a [Term],
    ) -> Result<Program<'a>, String> {
        let p = Program { kind, steps, terms };
        p.check().map(|()| p)
    }

    /// Whether the program has `step`.
    pub fn has(&self, step: Step) -> bool {
        self.steps.contains(&step)
    }

    /// A program is well formed when its steps are, in this order, an optional `Gain`, an
    /// optional `Normalise`, `Combine`, and `Rescale` only if there is a `Normalise`; after
    /// `Normalise` the terms read `x₀, x₁` only; every root is 1..=4. Every printer relies on it.
    pub fn check(&self) -> Result<(), String> {
        const ORDER: [Step; 4] = [Step::Gain, Step::Normalise, Step::Combine, Step::Rescale];
        let rank = |s: &Step| ORDER.iter().position(|o| o == s).unwrap_or(0);
        if !self.steps.windows(2).all(|w| rank(&w[0]) < rank(&w[1])) {
            return Err(format!(
                "{:?}: steps run Gain, Normalise, Combine, Rescale, each at most once",
                self.steps
            ));
        }
        if !self.has(Step::Combine) {
            return Err("no Combine step".into());
        }
        if self.has(Step::Rescale) && !self.has(Step::Normalise) {
            return Err("Rescale without Normalise".into());
        }
        if self.has(Step::Normalise) && self.terms.iter().any(|t| t.exps[2] != 0) {
            return Err("a term reads x2 after Normalise".into());
        }
        if let Some(t) = self.terms.iter().find(|t| !(1..=4).contains(&t.root)) {
            return Err(format!("{t:?}: roots are 1..=4"));
        }
        Ok(())
    }

    /// The f64 evaluation up to the matrix: writes the term values of `rgb` into `p` (length L)
    /// and returns the output scale (`s` where the program rescales, else 1), or `None` when
    /// [`Step::Normalise`]'s black rule ends the program (the output is then `(0, 0, 0)`).
    pub fn features(&self, gains: [f64; 3], rgb: [f64; 3], p: &mut [f64]) -> Option<f64> {
        let mut x = rgb;
        let mut s = 1.0;
        let mut scale = 1.0;
        for step in self.steps {
            match step {
                Step::Gain => x = [x[0] * gains[0], x[1] * gains[1], x[2] * gains[2]],
                Step::Normalise => {
                    let (sig, r, g) = nsrm_signal(x)?;
                    s = sig;
                    x = [r, g, 0.0];
                }
                Step::Combine => expand(self.terms, x, p),
                Step::Rescale => scale = s,
            }
        }
        Some(scale)
    }

    /// The f64 evaluation of the program on one pixel: `matrix` row-major 3×L, `p` a term buffer
    /// (length L). The reference every other path is held to.
    pub fn eval(&self, matrix: &[f64], gains: [f64; 3], rgb: [f64; 3], p: &mut [f64]) -> [f64; 3] {
        let Some(scale) = self.features(gains, rgb, p) else {
            return [0.0; 3];
        };
        let l = self.terms.len();
        let mut out = [0.0; 3];
        for (i, o) in out.iter_mut().enumerate() {
            *o = scale
                * matrix[i * l..(i + 1) * l]
                    .iter()
                    .zip(p.iter())
                    .map(|(m, x)| m * x)
                    .sum::<f64>();
        }
        out
    }

    /// The distinct per-channel roots `(channel, degree > 1)` the terms use, sorted: what a printer
    /// computes once before the terms.
    pub fn roots(&self) -> Vec<(usize, u8)> {
        let mut v: Vec<(usize, u8)> = self
            .terms
            .iter()
            .flat_map(super::terms::term_factors)
            .filter(|(_, r)| *r > 1)
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

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

    use crate::model::terms::{terms, MAX_ORDER};

    #[test]
    fn every_standard_program_is_well_formed() {
        for kind in Kind::ALL {
            for order in 1..=MAX_ORDER {
                let t = terms(kind, kind.effective_order(order));
                let p = Program::new(kind, &t);
                assert_eq!(p.check(), Ok(()), "{kind} {order}");
                assert_eq!(p.has(Step::Normalise), kind == Kind::Nsrm);
                assert_eq!(p.has(Step::Gain), kind == Kind::Nsrm);
                assert_eq!(p.has(Step::Rescale), kind == Kind::Nsrm);
                assert_eq!(p.roots().is_empty(), kind != Kind::Rprm || order == 1);
            }
        }
    }

    #[test]
    fn malformed_programs_are_refused() {
        let lin = terms(Kind::Lrm, 1);
        let chroma = terms(Kind::Nsrm, 2);
        let cases: [(&'static [Step], &Vec<Term>); 7] = [
            (&[Step::Gain][..], &chroma),
            (&[Step::Combine, Step::Gain], &chroma),
            (&[Step::Combine, Step::Combine], &chroma),
            (&[Step::Normalise, Step::Gain, Step::Combine], &chroma),
            (&[Step::Combine, Step::Rescale], &chroma),
            (&[Step::Normalise, Step::Rescale, Step::Combine], &chroma),
            (&[Step::Normalise, Step::Combine], &lin),
        ];
        for (steps, terms) in cases {
            assert!(
                Program::custom(Kind::Nsrm, steps, terms).is_err(),
                "{steps:?}"
            );
        }
        let bad_root = [Term {
            exps: [1, 0, 0],
            root: 5,
        }];
        assert!(Program::custom(Kind::Rprm, &[Step::Combine], &bad_root).is_err());
    }

    /// The evaluator runs the steps it is given, not a kind's: each step changes the result as
    /// it says.
    #[test]
    fn the_evaluator_interprets_each_step() {
        let t = terms(Kind::Nsrm, 2); // 1 r g r² g² rg
        let m: Vec<f64> = (0..18).map(|i| 0.25 + 0.5 * i as f64).collect();
        let gains = [2.0, 1.0, 0.5];
        let rgb = [0.2, 0.3, 0.6];
        let mut p = vec![0.0; t.len()];
        let dot = |k: usize, p: &[f64]| (0..6).map(|j| m[k * 6 + j] * p[j]).sum::<f64>();
        let full = Program::new(Kind::Nsrm, &t);
        // Gain, then s = 0.4 + 0.3 + 0.3 = 1, r = 0.4, g = 0.3.
        let y = full.eval(&m, gains, rgb, &mut p);
        let want_p = [1.0, 0.4, 0.3, 0.16, 0.09, 0.12];
        for k in 0..3 {
            assert!((y[k] - dot(k, &want_p)).abs() < 1e-12);
        }
        // Without Gain: s = 1.1, and the output is scaled by it.
        let no_gain = Program::custom(
            Kind::Nsrm,
            &[Step::Normalise, Step::Combine, Step::Rescale],
            &t,
        )
        .unwrap();
        let y = no_gain.eval(&m, gains, rgb, &mut p);
        let (r, g) = (0.2 / 1.1, 0.3 / 1.1);
        let want_p = [1.0, r, g, r * r, g * g, r * g];
        for k in 0..3 {
            assert!((y[k] - 1.1 * dot(k, &want_p)).abs() < 1e-12);
        }
        // Without Rescale: the chromaticity model itself.
        let no_rescale =
            Program::custom(Kind::Nsrm, &[Step::Normalise, Step::Combine], &t).unwrap();
        let y = no_rescale.eval(&m, gains, rgb, &mut p);
        for k in 0..3 {
            assert!((y[k] - dot(k, &want_p)).abs() < 1e-12);
        }
        // The black rule belongs to Normalise: without it, s ≤ 0 is not black.
        let plain = Program::custom(Kind::Nsrm, &[Step::Combine], &t).unwrap();
        assert_eq!(full.eval(&m, gains, [-0.2, 0.1, 0.0], &mut p), [0.0; 3]);
        assert_ne!(plain.eval(&m, gains, [-0.2, 0.1, 0.0], &mut p), [0.0; 3]);
    }

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
