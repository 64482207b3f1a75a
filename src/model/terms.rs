//! The one definition of every model's terms.
//!
//! The fit, the CPU apply paths, the WGSL shaders (generated from [`Term`] lists, see
//! `crate::gpu::shader`) and the docs (`nsrm terms`) all read these tables.
//!
//! * **LRM** — `(R, G, B)`.
//! * **PRM** order n — every monomial `R^a G^b B^c` of degree 1..=n, no constant, ordered by degree,
//!   then as in [`MONOMIALS`].
//! * **RPRM** order n — for each degree d ≤ n, the degree-d monomials that do not reduce to a lower
//!   degree (exponent gcd 1), under a d-th root: `(R^a G^b B^c)^(1/d)` (Finlayson et al. 2015).
//!   Roots are sign-preserving, `sign(x)·|x|^(1/d)`, and computed per channel:
//!   `∛(R G²) = ∛R · (∛G)²`, which is the same number for any signs.
//! * **NSRM** order n — every monomial `r^a g^b` of degree 0..=n in the chromaticities
//!   `r = R/s, g = G/s, s = R+G+B`; the model predicts `(α, β, γ) = M·p` and outputs `s·(α, β, γ)`.

use super::Kind;

/// One term: `Π_c x_c^exps[c]` under a `root`-th root (`root = 1`: a plain monomial).
///
/// For LRM, PRM and RPRM the variables `x` are `(R, G, B)`; for NSRM they are `(r, g)` and
/// `exps[2]` is always 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Term {
    /// The exponents of the variables in the monomial.
    pub exps: [u8; 3],
    /// The root taken of the monomial (1: none; RPRM's terms take the degree-th root).
    pub root: u8,
}

impl Term {
    /// The degree of the monomial under the root.
    pub fn degree(&self) -> u8 {
        self.exps.iter().sum()
    }
}

/// PRM's degree-d monomials in (R, G, B), d = 1..=4, in the paper's order at d ≤ 3 (its eq. (3):
/// `…, RG², RB², GB², GR², BR², BG², RGB`). The order is part of the model file format (the
/// columns of its matrix); PRM files written before the eq. (3) order (`…, BG², BR², RGB`) are
/// converted by term name on load.
pub(crate) const MONOMIALS: [&[[u8; 3]]; 4] = [
    // d = 1: R, G, B
    &[[1, 0, 0], [0, 1, 0], [0, 0, 1]],
    // d = 2: R², G², B², RG, GB, BR
    &[
        [2, 0, 0],
        [0, 2, 0],
        [0, 0, 2],
        [1, 1, 0],
        [0, 1, 1],
        [1, 0, 1],
    ],
    // d = 3: R³, G³, B³, RG², RB², GB², GR², BR², BG², RGB
    &[
        [3, 0, 0],
        [0, 3, 0],
        [0, 0, 3],
        [1, 2, 0],
        [1, 0, 2],
        [0, 1, 2],
        [2, 1, 0],
        [2, 0, 1],
        [0, 2, 1],
        [1, 1, 1],
    ],
    // d = 4: R⁴, G⁴, B⁴, R³G, R³B, G³B, G³R, B³G, B³R, R²G², G²B², B²R², R²GB, G²BR, B²RG
    &[
        [4, 0, 0],
        [0, 4, 0],
        [0, 0, 4],
        [3, 1, 0],
        [3, 0, 1],
        [0, 3, 1],
        [1, 3, 0],
        [0, 1, 3],
        [1, 0, 3],
        [2, 2, 0],
        [0, 2, 2],
        [2, 0, 2],
        [2, 1, 1],
        [1, 2, 1],
        [1, 1, 2],
    ],
];

/// RPRM's degree-d monomials before the irreducibility filter: the paper's eq. (4) order at d ≤ 3
/// (`…, ∛RG², ∛RB², ∛GB², ∛GR², ∛BG², ∛BR², ∛RGB`, Finlayson et al. 2015), which differs from
/// eq. (3) in the last two cube-root terms; d = 4 as [`MONOMIALS`].
pub(crate) const ROOT_MONOMIALS: [&[[u8; 3]]; 4] = [
    MONOMIALS[0],
    MONOMIALS[1],
    &[
        [3, 0, 0],
        [0, 3, 0],
        [0, 0, 3],
        [1, 2, 0],
        [1, 0, 2],
        [0, 1, 2],
        [2, 1, 0],
        [0, 2, 1],
        [2, 0, 1],
        [1, 1, 1],
    ],
    MONOMIALS[3],
];

/// Degree-d monomials in (r, g), d = 0..=4, in the paper's order at d ≤ 3 (its eq. (8)):
/// pure powers first, then the mixed terms with rising power of r.
pub(crate) const CHROMA_MONOMIALS: [&[[u8; 2]]; 5] = [
    &[[0, 0]],
    &[[1, 0], [0, 1]],
    &[[2, 0], [0, 2], [1, 1]],
    &[[3, 0], [0, 3], [1, 2], [2, 1]],
    &[[4, 0], [0, 4], [1, 3], [2, 2], [3, 1]],
];

/// The highest order any model supports.
pub const MAX_ORDER: u8 = 4;

fn gcd(a: u8, b: u8) -> u8 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The terms of `kind` at `order` (1..=[`MAX_ORDER`]; LRM ignores the order).
///
/// Panics if `order` is out of range; [`super::Model`] and the fit check it first.
pub fn terms(kind: Kind, order: u8) -> Vec<Term> {
    assert!(
        (1..=MAX_ORDER).contains(&order),
        "order {order} out of range"
    );
    let mono = |e: &[u8; 3], root| Term { exps: *e, root };
    match kind {
        Kind::Lrm => MONOMIALS[0].iter().map(|e| mono(e, 1)).collect(),
        Kind::Prm => MONOMIALS[..order as usize]
            .iter()
            .flat_map(|list| list.iter().map(|e| mono(e, 1)))
            .collect(),
        Kind::Rprm => ROOT_MONOMIALS[..order as usize]
            .iter()
            .enumerate()
            .flat_map(|(i, list)| {
                let d = i as u8 + 1;
                list.iter()
                    .filter(move |e| gcd(gcd(e[0], e[1]), e[2]) == 1)
                    .map(move |e| mono(e, d))
            })
            .collect(),
        Kind::Nsrm => CHROMA_MONOMIALS[..=order as usize]
            .iter()
            .flat_map(|list| {
                list.iter().map(|e| Term {
                    exps: [e[0], e[1], 0],
                    root: 1,
                })
            })
            .collect(),
    }
}

/// A readable name for a term: `R`, `G*B`, `R^2*G`, `sqrt(R*G)`, `cbrt(R*G^2)`, `root4(R^3*G)`,
/// `1`, `r`, `r*g^2`.
pub fn term_name(kind: Kind, t: &Term) -> String {
    let vars: [&str; 3] = if kind == Kind::Nsrm {
        ["r", "g", "-"]
    } else {
        ["R", "G", "B"]
    };
    let mut parts = Vec::new();
    for (v, &e) in vars.iter().zip(&t.exps) {
        match e {
            0 => {}
            1 => parts.push(v.to_string()),
            e => parts.push(format!("{v}^{e}")),
        }
    }
    let mono = if parts.is_empty() {
        "1".to_string()
    } else {
        parts.join("*")
    };
    match t.root {
        1 => mono,
        2 => format!("sqrt({mono})"),
        3 => format!("cbrt({mono})"),
        d => format!("root{d}({mono})"),
    }
}

pub(crate) use super::pixel::signed_root;

/// The factors of a term, one per unit of exponent, as `(variable, root)`: the term is the product
/// of `signed_root(x[variable], root)` over them (1 for none), which is what [`expand`] computes.
/// Code generators (the WGSL of `gpu`'s printer, `nsrm-export`'s DCTL) spell each factor in
/// their language, so every back end follows this one definition.
pub fn term_factors(t: &Term) -> Vec<(usize, u8)> {
    t.exps
        .iter()
        .enumerate()
        .flat_map(|(c, &e)| std::iter::repeat_n((c, t.root), e as usize))
        .collect()
}

/// Writes the term values of one pixel into `out` (the f64 reference expansion).
///
/// For NSRM, `rgb` must already be the chromaticities `(r, g, _)`.
pub(crate) fn expand(terms: &[Term], vars: [f64; 3], out: &mut [f64]) {
    debug_assert_eq!(terms.len(), out.len());
    for (t, o) in terms.iter().zip(out.iter_mut()) {
        let mut v = 1.0;
        for (&x, &e) in vars.iter().zip(&t.exps) {
            if e > 0 {
                let base = if t.root == 1 {
                    x
                } else {
                    signed_root(x, t.root)
                };
                v *= base.powi(e as i32);
            }
        }
        *o = v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(kind: Kind, order: u8) -> Vec<String> {
        terms(kind, order)
            .iter()
            .map(|t| term_name(kind, t))
            .collect()
    }

    /// The term names are the model file format: frozen here for every kind and order.
    #[test]
    fn term_names_are_frozen_for_every_kind_and_order() {
        const FROZEN: [(Kind, u8, &str); 12] = [
            (Kind::Prm, 1, "R G B"),
            (Kind::Rprm, 1, "R G B"),
            (Kind::Nsrm, 1, "1 r g"),
            (Kind::Prm, 2, "R G B R^2 G^2 B^2 R*G G*B R*B"),
            (Kind::Rprm, 2, "R G B sqrt(R*G) sqrt(G*B) sqrt(R*B)"),
            (Kind::Nsrm, 2, "1 r g r^2 g^2 r*g"),
            (Kind::Prm, 3, "R G B R^2 G^2 B^2 R*G G*B R*B R^3 G^3 B^3 R*G^2 R*B^2 G*B^2 R^2*G R^2*B G^2*B R*G*B"),
            (Kind::Rprm, 3, "R G B sqrt(R*G) sqrt(G*B) sqrt(R*B) cbrt(R*G^2) cbrt(R*B^2) cbrt(G*B^2) cbrt(R^2*G) cbrt(G^2*B) cbrt(R^2*B) cbrt(R*G*B)"),
            (Kind::Nsrm, 3, "1 r g r^2 g^2 r*g r^3 g^3 r*g^2 r^2*g"),
            (Kind::Prm, 4, "R G B R^2 G^2 B^2 R*G G*B R*B R^3 G^3 B^3 R*G^2 R*B^2 G*B^2 R^2*G R^2*B G^2*B R*G*B R^4 G^4 B^4 R^3*G R^3*B G^3*B R*G^3 G*B^3 R*B^3 R^2*G^2 G^2*B^2 R^2*B^2 R^2*G*B R*G^2*B R*G*B^2"),
            (Kind::Rprm, 4, "R G B sqrt(R*G) sqrt(G*B) sqrt(R*B) cbrt(R*G^2) cbrt(R*B^2) cbrt(G*B^2) cbrt(R^2*G) cbrt(G^2*B) cbrt(R^2*B) cbrt(R*G*B) root4(R^3*G) root4(R^3*B) root4(G^3*B) root4(R*G^3) root4(G*B^3) root4(R*B^3) root4(R^2*G*B) root4(R*G^2*B) root4(R*G*B^2)"),
            (Kind::Nsrm, 4, "1 r g r^2 g^2 r*g r^3 g^3 r*g^2 r^2*g r^4 g^4 r*g^3 r^2*g^2 r^3*g"),
        ];
        for order in 1..=4 {
            assert_eq!(names(Kind::Lrm, order), ["R", "G", "B"]);
        }
        for (kind, order, want) in FROZEN {
            assert_eq!(names(kind, order).join(" "), want, "{kind:?} order {order}");
        }
    }

    #[test]
    fn paper_order_3_term_lists() {
        assert_eq!(names(Kind::Lrm, 3), ["R", "G", "B"]);
        assert_eq!(
            names(Kind::Prm, 3),
            [
                "R", "G", "B", "R^2", "G^2", "B^2", "R*G", "G*B", "R*B", "R^3", "G^3", "B^3",
                "R*G^2", "R*B^2", "G*B^2", "R^2*G", "R^2*B", "G^2*B", "R*G*B"
            ]
        );
        assert_eq!(
            names(Kind::Rprm, 3),
            [
                "R",
                "G",
                "B",
                "sqrt(R*G)",
                "sqrt(G*B)",
                "sqrt(R*B)",
                "cbrt(R*G^2)",
                "cbrt(R*B^2)",
                "cbrt(G*B^2)",
                "cbrt(R^2*G)",
                "cbrt(G^2*B)",
                "cbrt(R^2*B)",
                "cbrt(R*G*B)"
            ]
        );
        assert_eq!(
            names(Kind::Nsrm, 3),
            ["1", "r", "g", "r^2", "g^2", "r*g", "r^3", "g^3", "r*g^2", "r^2*g"]
        );
    }

    #[test]
    fn term_counts_every_order() {
        let count = |k, o| terms(k, o).len();
        for o in 1..=4 {
            assert_eq!(count(Kind::Lrm, o), 3);
        }
        assert_eq!(
            (1..=4).map(|o| count(Kind::Prm, o)).collect::<Vec<_>>(),
            [3, 9, 19, 34]
        );
        assert_eq!(
            (1..=4).map(|o| count(Kind::Rprm, o)).collect::<Vec<_>>(),
            [3, 6, 13, 22]
        );
        assert_eq!(
            (1..=4).map(|o| count(Kind::Nsrm, o)).collect::<Vec<_>>(),
            [3, 6, 10, 15]
        );
        // Every list is free of duplicates, and each degree's monomial list is complete.
        for (d, list) in MONOMIALS.iter().enumerate() {
            let d = d as u8 + 1;
            let n = (d as usize + 1) * (d as usize + 2) / 2;
            assert_eq!(list.len(), n);
            for (i, e) in list.iter().enumerate() {
                assert_eq!(e.iter().sum::<u8>(), d);
                assert!(!list[..i].contains(e));
            }
        }
        for (root, plain) in ROOT_MONOMIALS.iter().zip(&MONOMIALS) {
            assert_eq!(root.len(), plain.len());
            assert!(root.iter().all(|e| plain.contains(e)));
        }
        for (d, list) in CHROMA_MONOMIALS.iter().enumerate() {
            assert_eq!(list.len(), d + 1);
            for (i, e) in list.iter().enumerate() {
                assert_eq!((e[0] + e[1]) as usize, d);
                assert!(!list[..i].contains(e));
            }
        }
    }

    #[test]
    fn term_factors_multiply_to_the_term() {
        let x = [0.3, -0.7, 1.9];
        for kind in [Kind::Prm, Kind::Rprm, Kind::Nsrm] {
            let list = terms(kind, 4);
            let mut want = vec![0.0; list.len()];
            expand(&list, x, &mut want);
            for (t, w) in list.iter().zip(want) {
                let got: f64 = term_factors(t)
                    .iter()
                    .map(|&(c, r)| signed_root(x[c], r))
                    .product();
                assert!((got - w).abs() < 1e-12, "{kind:?} {t:?}");
                assert_eq!(term_factors(t).len(), t.degree() as usize);
            }
        }
    }

    #[test]
    fn root_terms_are_products_of_channel_roots() {
        // A root term of a product equals the product of per-channel roots, whatever the signs.
        let mut out = [0.0];
        expand(
            &[Term {
                exps: [1, 2, 0],
                root: 3,
            }],
            [-2.0, -3.0, 5.0],
            &mut out,
        );
        let direct = (-2.0f64 * 9.0).cbrt();
        assert!((out[0] - direct).abs() < 1e-12, "{} {}", out[0], direct);
    }
}
