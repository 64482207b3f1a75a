//! Properties of the models: exposure invariance (LRM, RPRM, NSRM; not PRM), and agreement of
//! leave-one-out with a direct refit.

use nsrm::TrainingSet;
use nsrm::{fit, Kind, Model};
use nsrm::{fit_with, Fit, FitOptions, Normalise, Objective, Ridge};
use nsrm::{simulate_named, Grid};
use proptest::prelude::*;
use std::sync::OnceLock;

fn data() -> &'static TrainingSet {
    static D: OnceLock<TrainingSet> = OnceLock::new();
    D.get_or_init(|| {
        simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap()
    })
}

fn models() -> &'static Vec<Model> {
    static M: OnceLock<Vec<Model>> = OnceLock::new();
    M.get_or_init(|| {
        let mut v = Vec::new();
        for kind in Kind::ALL {
            for order in 1..=4 {
                if kind == Kind::Lrm && order > 1 {
                    continue;
                }
                v.push(fit(kind, order, data()).unwrap());
            }
        }
        v
    })
}

/// Every fit variant of the exposure-invariant kinds (order 3; NSRM also white-balanced), fitted
/// on the cc24 patches (the ΔE00 refinement is slow in a debug build on 190).
fn variants() -> &'static Vec<(String, Fit)> {
    static V: OnceLock<Vec<(String, Fit)>> = OnceLock::new();
    V.get_or_init(|| {
        let d = simulate_named("nikon-d5100", "TL865", "cc24", &Grid::default()).unwrap();
        let mut v = Vec::new();
        for kind in [Kind::Lrm, Kind::Rprm, Kind::Nsrm] {
            let mut opts = vec![
                FitOptions::default(),
                FitOptions {
                    objective: Objective::De00 { power: 2.0 },
                    ..Default::default()
                },
                FitOptions {
                    objective: Objective::De00 { power: 2.0 },
                    preserve_white: true,
                    ..Default::default()
                },
                FitOptions {
                    ridge: Ridge::Auto,
                    ..Default::default()
                },
            ];
            if kind == Kind::Nsrm {
                let wb: Vec<FitOptions> = opts
                    .iter()
                    .map(|o| FitOptions {
                        normalise: Normalise::WhiteBalanced,
                        ..o.clone()
                    })
                    .collect();
                opts.extend(wb);
            }
            for o in opts {
                v.push((format!("{kind}3 {o:?}"), fit_with(kind, 3, &d, &o).unwrap()));
            }
        }
        v
    })
}

fn rel_close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    let scale = a.iter().chain(&b).fold(0.0f64, |m, v| m.max(v.abs()));
    (0..3).all(|k| (a[k] - b[k]).abs() <= tol * scale.max(1e-300))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn exposure_invariance(
        r in 0.001f64..2.0, g in 0.001f64..2.0, b in 0.001f64..2.0,
        k in 0.01f64..100.0,
    ) {
        for m in models().iter().filter(|m| m.kind() != Kind::Prm) {
            let base = m.apply_f64([r, g, b]);
            let scaled = m.apply_f64([k * r, k * g, k * b]);
            let want = [k * base[0], k * base[1], k * base[2]];
            prop_assert!(rel_close(scaled, want, 1e-9),
                "{} order {}: f(kS) = {:?}, k·f(S) = {:?}", m.kind(), m.order(), scaled, want);
        }
    }

    #[test]
    fn exposure_invariance_of_every_fit_variant(
        r in 0.001f64..2.0, g in 0.001f64..2.0, b in 0.001f64..2.0,
        k in 0.01f64..100.0,
    ) {
        for (name, f) in variants() {
            let base = f.model.apply_f64([r, g, b]);
            let scaled = f.model.apply_f64([k * r, k * g, k * b]);
            let want = [k * base[0], k * base[1], k * base[2]];
            prop_assert!(rel_close(scaled, want, 1e-9),
                "{name}: f(kS) = {:?}, k·f(S) = {:?}", scaled, want);
        }
    }
}

#[test]
fn prm_is_not_exposure_invariant() {
    let s = data().rgb[10];
    for m in models()
        .iter()
        .filter(|m| m.kind() == Kind::Prm && m.order() >= 2)
    {
        let k = 2.0;
        let base = m.apply_f64(s);
        let scaled = m.apply_f64([k * s[0], k * s[1], k * s[2]]);
        let want = [k * base[0], k * base[1], k * base[2]];
        assert!(
            !rel_close(scaled, want, 1e-5),
            "PRM order {} looked exposure-invariant: {scaled:?} vs {want:?}",
            m.order()
        );
    }
}

#[test]
fn rprm_stays_finite_on_negative_channels() {
    for m in models().iter().filter(|m| m.kind() == Kind::Rprm) {
        let out = m.apply_f64([-0.02, 0.3, -0.001]);
        assert!(
            out.iter().all(|v| v.is_finite()),
            "order {}: {out:?}",
            m.order()
        );
    }
}

#[test]
fn in_sample_fit_is_a_least_squares_minimum() {
    // Perturbing any matrix entry of a least-squares fit cannot lower the residual.
    let d = data();
    for m in models() {
        let resid = |m: &Model| -> f64 {
            d.rgb
                .iter()
                .zip(&d.xyz)
                .map(|(c, x)| {
                    let y = m.apply_f64(*c);
                    let s = if m.kind() == Kind::Nsrm {
                        c.iter().sum::<f64>()
                    } else {
                        1.0
                    };
                    (0..3).map(|k| ((y[k] - x[k]) / s).powi(2)).sum::<f64>()
                })
                .sum()
        };
        let r0 = resid(m);
        for j in [0, m.matrix().len() / 2, m.matrix().len() - 1] {
            let mut perturbed = m.matrix().to_vec();
            perturbed[j] += 1e-4 * (1.0 + perturbed[j].abs());
            // The same kind and order with the perturbed matrix (plain fits: unit input gains).
            assert_eq!(m.input_gains(), [1.0; 3]);
            let p = Model::from_matrix(m.kind(), m.order(), perturbed).unwrap();
            assert!(
                resid(&p) >= r0 * (1.0 - 1e-12),
                "{} order {}",
                m.kind(),
                m.order()
            );
        }
    }
}
