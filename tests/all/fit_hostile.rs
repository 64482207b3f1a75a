//! Issue 8, family 4: no fit hangs. A training patch of 1e200 (PRM's terms overflow) or a camera
//! channel scaled by 1e-200 is refused before the SVD with a typed error naming the patch and the
//! term; every solver is bounded (see `model::fit`).

use nsrm::{fit, Kind, ModelError};
use nsrm::{fit_with, FitOptions, Objective, Ridge};
use nsrm::{simulate_named, Grid};

fn data() -> nsrm::TrainingSet {
    simulate_named("nikon-d5100", "D65", "cc24", &Grid::default()).unwrap()
}

fn all_models() -> Vec<(Kind, u8)> {
    Kind::ALL
        .into_iter()
        .flat_map(|k| (1..=4).map(move |o| (k, o)))
        .filter(|&(k, o)| (k != Kind::Lrm || o == 1) && !(k == Kind::Prm && o == 4))
        .collect()
}

#[test]
fn a_huge_patch_is_refused_by_every_model_and_variant() {
    let mut d = data();
    d.rgb[5] = [1e200, 0.3, 0.2];
    let variants = [
        FitOptions::default(),
        FitOptions {
            objective: Objective::De00 { power: 2.0 },
            ridge: Ridge::Auto,
            ..Default::default()
        },
    ];
    for (kind, order) in all_models() {
        for opts in &variants {
            match fit_with(kind, order, &d, opts) {
                Err(ModelError::OutOfRange { label, what, value }) => {
                    assert_eq!(label, d.labels[5]);
                    let a = value.abs();
                    assert!(
                        !value.is_finite() || !(1e-100..=1e100).contains(&a),
                        "{what} = {value:e}"
                    );
                }
                other => panic!("{kind}{order}: {other:?}"),
            }
        }
    }
    let e = fit(Kind::Prm, 3, &d).unwrap_err().to_string();
    assert!(
        e.contains(&d.labels[5]) && e.contains("term R = 1.000e200"),
        "{e}"
    );
    // 1e60 is in range as a channel, but PRM's R² is not; LRM fits it.
    d.rgb[5] = [1e60, 0.3, 0.2];
    let e = fit(Kind::Prm, 2, &d).unwrap_err().to_string();
    assert!(e.contains("term R^2 = 1.000e120"), "{e}");
    fit(Kind::Lrm, 1, &d).unwrap();
}

#[test]
fn a_channel_scaled_by_1e_minus_200_is_refused() {
    let mut d = data();
    for c in d.rgb.iter_mut() {
        c[2] *= 1e-200;
    }
    for (kind, order) in all_models() {
        if kind == Kind::Nsrm {
            // NSRM's terms are r and g: a vanishing B only changes s, and the fit is well-posed.
            fit(kind, order, &d).unwrap();
            continue;
        }
        let e = fit(kind, order, &d).unwrap_err();
        assert!(
            matches!(e, ModelError::OutOfRange { .. }),
            "{kind}{order}: {e}"
        );
        assert!(e.to_string().contains("outside the range"), "{e}");
    }
    // Huge XYZ targets are refused too.
    let mut d = data();
    d.xyz[3] = [1e120, 1.0, 1.0];
    let e = fit(Kind::Lrm, 1, &d).unwrap_err();
    assert!(
        matches!(&e, ModelError::OutOfRange { what, .. } if what == "target X"),
        "{e}"
    );
}

#[test]
fn infinite_and_nan_data_are_refused_not_solved() {
    for bad in [f64::INFINITY, f64::NAN] {
        let mut d = data();
        d.rgb[0][1] = bad;
        for (kind, order) in all_models() {
            assert!(
                matches!(fit(kind, order, &d), Err(ModelError::NonFinite { .. })),
                "{kind}{order}"
            );
        }
    }
}
