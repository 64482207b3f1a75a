//! The unit tests of `fit.rs` (moved beside it to keep the file short).

use super::*;

#[test]
fn closed_form_leave_one_out_matches_refits() {
    // PRESS's residuals e_i / (1 − H_ii) are those of the ridge solve refitted without patch
    // i (standardisation weights held), for NSRM and RPRM at several λ.
    let data = crate::spectral::simulate_named(
        "nikon-d5100",
        "D65",
        "cc24",
        &crate::spectral::Grid::default(),
    )
    .unwrap();
    for (kind, order) in [(Kind::Nsrm, 3), (Kind::Rprm, 3)] {
        let t = terms(kind, order);
        let d = design(kind, &t, &data.labels, &data.rgb, &data.xyz).unwrap();
        let r = Reduced::new(kind, &t, &d, None);
        for lam in [1e-6, 1e-3, 0.1] {
            let full = r.solve_loo(lam).unwrap();
            let mut worst = 0.0f64;
            for i in 0..data.len() {
                let fold = Reduced {
                    g: r.g.clone().remove_row(i),
                    br: r.br.clone().remove_row(i),
                    wn: r.wn.clone(),
                    wxp: r.wxp.clone(),
                    constraint: None,
                };
                let z = fold.solve(lam).unwrap().0;
                let refit = r.g.row(i) * &z - r.br.row(i);
                let closed = full.residuals.row(i) / (1.0 - full.leverage[i]);
                let scale = refit.norm().max(1e-12);
                worst = worst.max((refit - closed).norm() / scale);
            }
            assert!(worst < 1e-6, "{kind} {order} λ {lam}: {worst:e}");
        }
    }
}

#[test]
fn f32_guard_raises_lambda_only_where_f32_cannot_evaluate_the_fit() {
    // RPRM 4 on the Nikon's rawtoaces-190: unregularised, its coefficients (about 1e7) cancel
    // in f32; the guard measures that, raises λ until the measured error is within the
    // tolerance, and says what changed.
    let data = crate::spectral::simulate_named(
        "nikon-d5100",
        "D65",
        "rawtoaces-190",
        &crate::spectral::Grid::default(),
    )
    .unwrap();
    let f = fit_with(Kind::Rprm, 4, &data, &FitOptions::default()).unwrap();
    let r = &f.report;
    assert_eq!(r.ridge_requested, Some(0.0), "{r:?}");
    assert!(r.ridge_lambda > 0.0 && f32_guard_grid().any(|l| l == r.ridge_lambda));
    let measured = r.f32_error_measured.unwrap();
    assert!(measured <= F32_TOLERANCE_DE00, "{measured}");
    let mut probe = data.rgb.clone();
    probe.extend(f32_probe(&data.rgb));
    assert_eq!(measured, f32_error_probe(&f.model, &probe));
    let c = r.f32_guard.unwrap();
    assert_eq!(c.lambda_before, 0.0);
    assert!(c.f32_error_before > F32_TOLERANCE_DE00, "{c:?}");
    // The fit as solved (the guard off) is the one the guard refused, unchanged.
    let plain = fit_with(Kind::Rprm, 4, &data, &FitOptions::default().unguarded()).unwrap();
    assert_eq!(plain.report.ridge_lambda, 0.0);
    assert_eq!(plain.report.f32_guard, None);
    assert_eq!(plain.report.f32_error_measured, Some(c.f32_error_before));
    let raw_measured = f32_error_measured(&plain.model, &data.rgb, &data.xyz);
    assert!(raw_measured > F32_TOLERANCE_DE00, "{raw_measured}");
    // What the guard kept is within the tolerance on the training patches too.
    assert!(f32_error_measured(&f.model, &data.rgb, &data.xyz) <= F32_TOLERANCE_DE00);
    // RPRM 3 here: its first-order bound is far above its measured error, which is within
    // the tolerance: left alone. NSRM 3 too.
    for kind in [Kind::Rprm, Kind::Nsrm] {
        let n = fit_with(kind, 3, &data, &FitOptions::default()).unwrap();
        assert_eq!(n.report.ridge_requested, None, "{kind}");
        assert_eq!(n.report.ridge_lambda, 0.0, "{kind}");
        assert!(n.report.f32_error_measured.unwrap() <= F32_TOLERANCE_DE00);
    }
}

#[test]
fn probe_set_is_inside_the_training_chromaticities_at_several_exposures() {
    let rgb = [
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 2.0],
        [0.2, 0.3, 0.5],
    ];
    let p = f32_probe(&rgb);
    let bright = 2.0;
    let sums: Vec<f64> = p.iter().map(|c| c.iter().sum()).collect();
    for k in 0..=PROBE_STOPS {
        let s = bright * 0.5f64.powi(k);
        assert!(sums.iter().any(|v| (v - s).abs() < 1e-12), "{k}");
    }
    assert!(sums.iter().all(|v| *v <= bright + 1e-12 && *v > 0.0));
    assert!(p.iter().flatten().all(|v| *v >= 0.0));
    // Dense: many more points than patches.
    assert!(p.len() > 100 * rgb.len(), "{}", p.len());
    // Outside the hull: a patch set on one side leaves the other side out.
    let narrow = [[1.0, 1.0, 1.0], [1.2, 1.0, 1.0], [1.0, 1.2, 1.0]];
    for c in f32_probe(&narrow) {
        let s: f64 = c.iter().sum();
        assert!(c[2] / s <= 1.0 / 3.0 + 1e-9, "{c:?}");
    }
    assert!(f32_probe(&[]).is_empty());
}

#[test]
fn option_parsing() {
    assert_eq!(Objective::parse("ls").unwrap(), Objective::LeastSquares);
    assert_eq!(
        Objective::parse("DE00").unwrap(),
        Objective::De00 { power: 2.0 }
    );
    assert_eq!(
        Objective::parse("de00:4").unwrap(),
        Objective::De00 { power: 4.0 }
    );
    for bad in ["de00:1", "de00:x", "l2", "de00:", "de00:1e9", "de00:NaN"] {
        assert!(Objective::parse(bad).is_err(), "{bad}");
    }
    assert_eq!(Objective::De00 { power: 4.0 }.name(), "de00:4");
    assert_eq!(Ridge::parse("auto").unwrap(), Ridge::Auto);
    assert_eq!(Ridge::parse("auto-gcv").unwrap(), Ridge::Auto);
    assert_eq!(Ridge::parse("AUTO-LOO").unwrap(), Ridge::AutoLoo);
    assert_eq!(Ridge::parse("0").unwrap(), Ridge::None);
    assert_eq!(Ridge::parse("1e-3").unwrap(), Ridge::Lambda(1e-3));
    for bad in ["-1", "inf", "x", "1e13"] {
        assert!(Ridge::parse(bad).is_err(), "{bad}");
    }
    assert_eq!(
        Normalise::parse("white-balanced").unwrap(),
        Normalise::WhiteBalanced
    );
    assert!(Normalise::parse("balanced").is_err());
}

#[test]
fn svd_is_bounded_and_refuses_non_finite_matrices() {
    let mut a = DMatrix::<f64>::from_fn(6, 3, |i, j| (i * 3 + j) as f64 + 1.0);
    assert!(svd(a.clone(), true).is_ok());
    a[(2, 1)] = f64::INFINITY;
    assert!(matches!(svd(a, true), Err(ModelError::NotConverged { .. })));
}

#[test]
fn householder_basis_is_orthonormal_and_orthogonal_to_the_constraint() {
    let c = [0.3, -1.2, 0.7, 2.0, 0.01];
    let k = Constraint::new(&c, [1.0, 2.0, 3.0]).unwrap();
    let cv = DVector::from_column_slice(&c);
    let ntn = k.basis.transpose() * &k.basis;
    assert!((ntn - DMatrix::identity(4, 4)).norm() < 1e-14);
    assert!((k.basis.transpose() * &cv).norm() < 1e-14);
    let got = k.xp.transpose() * cv;
    for (g, w) in got.iter().zip([1.0, 2.0, 3.0]) {
        assert!((g - w).abs() < 1e-14);
    }
}

/// Automatic λ (GCV and exact leave-one-out) is one of [`lambda_grid`]'s values (the rest of
/// this check, the shrinking, is `tests/all/fit_variants.rs`'
/// `ridge_shrinks_coefficients_and_auto_picks_from_the_grid`).
#[test]
fn auto_ridge_picks_from_the_grid() {
    let data = crate::spectral::simulate_named(
        "nikon-d5100",
        "D65",
        "rawtoaces-190",
        &crate::spectral::Grid::default(),
    )
    .unwrap();
    for (ridge, criterion) in [(Ridge::Auto, "gcv"), (Ridge::AutoLoo, "loo")] {
        let opts = FitOptions {
            ridge,
            ..Default::default()
        };
        let r = fit_with(Kind::Rprm, 3, &data, &opts).unwrap().report;
        assert!(r.ridge_auto && r.ridge_lambda > 0.0, "{r:?}");
        assert_eq!(r.ridge_criterion.as_deref(), Some(criterion));
        assert!(lambda_grid().any(|l| l == r.ridge_lambda), "{r:?}");
    }
}
