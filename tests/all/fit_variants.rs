//! Fit variants beyond the paper (issue 11): ΔE00 objective, white preservation, ridge, white-balanced
//! NSRM. Each property here can fail: the objective must go down, the white must be exact, the pinned
//! figure must match an independent oracle.

use nsrm::delta_e00_xyz;
use nsrm::Kind;
use nsrm::{evaluate_with, Protocol};
use nsrm::{fit_with, Fit, FitOptions, FitWhite, Normalise, Objective, Ridge};
use nsrm::{simulate_named, Grid};

/// Every built-in illuminant.
const ILLUMINANTS: [&str; 6] = ["D65", "FL3.15", "FL7", "TL865", "LED-B5", "LED-YAG"];
use nsrm::TrainingSet;

use crate::common;
use common::sg_path;

fn de00(power: f64) -> FitOptions {
    FitOptions {
        objective: Objective::De00 { power },
        ..Default::default()
    }
}

fn in_sample(f: &Fit, data: &TrainingSet) -> Vec<f64> {
    data.rgb
        .iter()
        .zip(&data.xyz)
        .map(|(c, x)| delta_e00_xyz(f.model.apply_f64(*c), *x, data.white_xyz))
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn de00_lowers_the_in_sample_mean_of_every_kind_under_every_builtin_illuminant() {
    for ill in ILLUMINANTS {
        // Every second patch of the 190 keeps the debug-build test fast; it holds on all 190 too
        // (`nsrm eval --variants --in-sample`). Σ ΔE00² is not the mean: on every third patch
        // (64), PRM3 under LED-B5 ends 0.3 % above least squares in mean (and below in RMS).
        let all = simulate_named("nikon-d5100", ill, "rawtoaces-190", &Grid::default()).unwrap();
        let data = all.subset(&(0..all.len()).step_by(2).collect::<Vec<_>>());
        for kind in Kind::ALL {
            let ls = fit_with(kind, 3, &data, &FitOptions::default()).unwrap();
            let de = fit_with(kind, 3, &data, &de00(2.0)).unwrap();
            let (a, b) = (mean(&in_sample(&ls, &data)), mean(&in_sample(&de, &data)));
            eprintln!("{ill} {kind}: in-sample mean ΔE00 ls {a:.4}, de00 {b:.4}");
            assert!(b < a, "{ill} {kind}: de00 {b} is not below ls {a}");
        }
    }
}

#[test]
fn de00_is_never_worse_than_its_start_and_deterministic() {
    let data = simulate_named("nikon-d5100", "TL865", "cc24", &Grid::default()).unwrap();
    let combos = [
        (Kind::Lrm, 1),
        (Kind::Prm, 2),
        (Kind::Rprm, 3),
        (Kind::Nsrm, 2),
        (Kind::Nsrm, 3),
    ];
    for (kind, order) in combos {
        {
            let variants = [
                de00(2.0),
                de00(4.0),
                FitOptions {
                    preserve_white: true,
                    ..de00(2.0)
                },
                FitOptions {
                    ridge: Ridge::Auto,
                    ..de00(3.0)
                },
            ];
            for opts in variants {
                let Objective::De00 { power } = opts.objective else {
                    unreachable!()
                };
                let f = fit_with(kind, order, &data, &opts).unwrap();
                let r = &f.report;
                let start = FitOptions {
                    objective: Objective::LeastSquares,
                    ..opts.clone()
                };
                let s = fit_with(kind, order, &data, &start).unwrap();
                if r.ridge_requested.is_some() || s.report.ridge_requested.is_some() {
                    // The f32 guard raised λ for one of the two (the least-squares start of the
                    // refinement is then not the least-squares fit): the refinement is still
                    // never worse than its own start.
                    assert!(
                        r.de00_end.unwrap() <= r.de00_start.unwrap(),
                        "{kind}{order}"
                    );
                    assert!(r.f32_error_measured.unwrap() <= nsrm::F32_TOLERANCE_DE00);
                    continue;
                }
                let obj = |f: &Fit| {
                    in_sample(f, &data)
                        .iter()
                        .map(|e| e.powf(power))
                        .sum::<f64>()
                };
                let (s0, s1) = (obj(&s), obj(&f));
                assert!(
                    (r.de00_start.unwrap() - s0).abs() <= 1e-9 * s0,
                    "{kind}{order} {opts:?}"
                );
                assert!((r.de00_end.unwrap() - s1).abs() <= 1e-9 * s0.max(1.0));
                if opts.ridge == Ridge::None {
                    assert!(s1 <= s0, "{kind}{order} {opts:?}: {s1} > {s0}");
                }
                assert!(r.iterations >= 1 && r.iterations <= 100);
                if kind == Kind::Nsrm {
                    let again = fit_with(kind, order, &data, &opts).unwrap();
                    assert_eq!(again.model.matrix(), f.model.matrix(), "not deterministic");
                }
            }
        }
    }
}

#[test]
fn preserve_white_maps_the_white_exactly() {
    let data = simulate_named("nikon-d5100", "LED-B5", "cc24", &Grid::default()).unwrap();
    let w_rgb = data.white_rgb.unwrap();
    let neutral = "white 9.5 (.05 D)";
    let ni = data.labels.iter().position(|l| l == neutral).unwrap();
    for kind in Kind::ALL {
        for objective in [Objective::LeastSquares, Objective::De00 { power: 2.0 }] {
            for ridge in [Ridge::None, Ridge::Auto] {
                let opts = FitOptions {
                    objective,
                    preserve_white: true,
                    ridge,
                    ..Default::default()
                };
                let f = fit_with(kind, 3, &data, &opts).unwrap();
                let d = delta_e00_xyz(f.model.apply_f64(w_rgb), data.white_xyz, data.white_xyz);
                assert!(d <= 1e-6, "{kind} {objective:?} {ridge:?}: white ΔE00 {d}");
                let opts = FitOptions {
                    white: FitWhite::Patch(neutral.into()),
                    ..opts
                };
                let f = fit_with(kind, 3, &data, &opts).unwrap();
                let d = delta_e00_xyz(
                    f.model.apply_f64(data.rgb[ni]),
                    data.xyz[ni],
                    data.white_xyz,
                );
                assert!(d <= 1e-6, "{kind} {objective:?}: patch {neutral} ΔE00 {d}");
            }
        }
        // Without the constraint the white is not exact: the test above can fail.
        let f = fit_with(kind, 3, &data, &FitOptions::default()).unwrap();
        let d = delta_e00_xyz(f.model.apply_f64(w_rgb), data.white_xyz, data.white_xyz);
        assert!(d > 1e-4, "{kind}: unconstrained white ΔE00 {d}");
    }
    let e = fit_with(
        Kind::Nsrm,
        3,
        &data,
        &FitOptions {
            preserve_white: true,
            white: FitWhite::Patch("nope".into()),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("nope"), "{e}");
}

#[test]
fn ridge_shrinks_coefficients_and_auto_picks_from_the_grid() {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let norm = |ridge| {
        fit_with(
            Kind::Rprm,
            3,
            &data,
            &FitOptions {
                ridge,
                ..Default::default()
            },
        )
        .unwrap()
        .report
    };
    let ls = norm(Ridge::None);
    let r1 = norm(Ridge::Lambda(1e-6));
    let r2 = norm(Ridge::Lambda(1e-3));
    assert!(ls.coefficient_norm > r1.coefficient_norm && r1.coefficient_norm > r2.coefficient_norm);
    // Unregularised, RPRM 3's coefficients here are large, but f32 evaluates them as apply does
    // within F32_TOLERANCE_DE00 (measured; issue 35: the guard decides on measured error, not on
    // the first-order bound, which had raised λ here): the fit is left as solved.
    assert_eq!(ls.ridge_requested, None, "{ls:?}");
    assert_eq!(ls.ridge_lambda, 0.0, "{ls:?}");
    assert!(ls.f32_error_measured.unwrap() <= nsrm::F32_TOLERANCE_DE00);
    let auto = norm(Ridge::Auto);
    assert!(auto.ridge_auto && auto.ridge_lambda > 0.0);
    // λ is one of the grid's (unit test `model::fit::tests::auto_ridge_picks_from_the_grid`).
    assert!(auto.coefficient_norm < r1.coefficient_norm, "{auto:?}");
    // The condition number is that of the design, whatever the regularisation.
    assert_eq!(ls.condition_number, auto.condition_number);
    assert!(ls.condition_number.unwrap() > 1e4);
    assert_eq!(auto.ridge_criterion.as_deref(), Some("gcv"));
    // Exact leave-one-out picks from the same grid (the unit test) and also shrinks the coefficients.
    let loo = norm(Ridge::AutoLoo);
    assert!(loo.ridge_auto && loo.ridge_lambda > 0.0);
    assert_eq!(loo.ridge_criterion.as_deref(), Some("loo"));
    assert!(loo.coefficient_norm < r1.coefficient_norm, "{loo:?}");
    eprintln!(
        "RPRM3 rawtoaces-190 D65: λ GCV {:e} (norm {:.1}), λ LOO {:e} (norm {:.1})",
        auto.ridge_lambda, auto.coefficient_norm, loo.ridge_lambda, loo.coefficient_norm
    );
}

#[test]
fn white_balanced_nsrm_is_raw_nsrm_on_balanced_input() {
    let data = simulate_named("nikon-d5100", "FL7", "cc24", &Grid::default()).unwrap();
    let wb = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let f = fit_with(Kind::Nsrm, 3, &data, &wb).unwrap();
    let w = data.white_rgb.unwrap();
    assert_eq!(f.report.input_gains, [1.0 / w[0], 1.0 / w[1], 1.0 / w[2]]);
    let mut balanced = data.clone();
    for c in balanced.rgb.iter_mut() {
        *c = [c[0] / w[0], c[1] / w[1], c[2] / w[2]];
    }
    let raw = fit_with(Kind::Nsrm, 3, &balanced, &FitOptions::default()).unwrap();
    for (a, b) in f.model.matrix().iter().zip(raw.model.matrix()) {
        assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0));
    }
    // It differs from raw NSRM, and is refused for the other kinds.
    let plain = fit_with(Kind::Nsrm, 3, &data, &FitOptions::default()).unwrap();
    assert!(plain.model.matrix() != f.model.matrix());
    assert!(fit_with(Kind::Rprm, 3, &data, &wb).is_err());
}

#[test]
fn white_balanced_nsrm3_sg_inner_96_d65_leave_one_out_matches_the_oracle() {
    let Some(path) = sg_path() else { return };
    let data = simulate_named(
        "nikon-d5100",
        "D65",
        path.to_str().unwrap(),
        &Grid::default(),
    )
    .unwrap()
    .select("B2:M9")
    .unwrap();
    assert_eq!(data.len(), 96);
    let opts = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..Default::default()
    };
    let r = evaluate_with(Kind::Nsrm, 3, &data, Protocol::LeaveOneOut, "D65", &opts).unwrap();
    let s = r.stats;
    eprintln!(
        "white-balanced NSRM3: {:.4} / {:.4} / {:.4}",
        s.mean, s.median, s.max
    );
    for (got, want) in [(s.mean, 0.752), (s.median, 0.574), (s.max, 3.072)] {
        assert!((got - want).abs() <= 0.01, "{got} vs {want}");
    }
}
