//! Criterion benches of fitting: every model kind at every order on 96 patches (the first 96 of
//! the built-in rawtoaces-190 set, Nikon D5100 under D65), and the leave-one-out evaluation on
//! them (96 fits each, in parallel), and leave-one-out of the fit variants (ΔE00 objective, white
//! preservation, ridge auto by GCV and by exact leave-one-out, white-balanced NSRM).
//! `cargo bench --bench fit`.

use criterion::{criterion_group, criterion_main, Criterion};
use nsrm::{evaluate, evaluate_with, Protocol};
use nsrm::{fit, Kind, MAX_ORDER};
use nsrm::{simulate_named, Grid};
use nsrm::{FitOptions, Normalise, Objective, Ridge};
use std::hint::black_box;
use std::time::Duration;

/// Every (kind, order) once: LRM has one order.
fn combos() -> Vec<(Kind, u8)> {
    Kind::ALL
        .into_iter()
        .flat_map(|k| (1..=MAX_ORDER).map(move |o| (k, o)))
        .filter(|&(k, o)| k != Kind::Lrm || o == 1)
        .collect()
}

fn fitting(c: &mut Criterion) {
    let all = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let data = all.subset(&(0..96).collect::<Vec<_>>());

    let mut g = c.benchmark_group("fit_96_patches");
    g.sample_size(20);
    g.warm_up_time(Duration::from_millis(300));
    g.measurement_time(Duration::from_secs(1));
    for (kind, order) in combos() {
        g.bench_function(format!("{}{order}", kind.name()), |b| {
            b.iter(|| fit(kind, order, black_box(&data)).unwrap())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("leave_one_out_96_patches");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(300));
    g.measurement_time(Duration::from_secs(2));
    for (kind, order) in combos() {
        g.bench_function(format!("{}{order}", kind.name()), |b| {
            b.iter(|| {
                evaluate(kind, order, black_box(&data), Protocol::LeaveOneOut, "D65").unwrap()
            })
        });
    }
    g.finish();

    // The fit variants (issue 11): leave-one-out runs the whole procedure in every fold.
    let mut g = c.benchmark_group("leave_one_out_96_patches_variants");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(300));
    g.measurement_time(Duration::from_secs(3));
    let de00 = FitOptions {
        objective: Objective::De00 { power: 2.0 },
        ..Default::default()
    };
    let variants = [
        ("nsrm3_de00", Kind::Nsrm, de00.clone()),
        (
            "nsrm3_de00_preserve_white",
            Kind::Nsrm,
            FitOptions {
                preserve_white: true,
                ..de00.clone()
            },
        ),
        (
            "nsrm3_ridge_auto",
            Kind::Nsrm,
            FitOptions {
                ridge: Ridge::Auto,
                ..Default::default()
            },
        ),
        (
            "nsrm3_ridge_auto_loo",
            Kind::Nsrm,
            FitOptions {
                ridge: Ridge::AutoLoo,
                ..Default::default()
            },
        ),
        (
            "nsrm3_white_balanced",
            Kind::Nsrm,
            FitOptions {
                normalise: Normalise::WhiteBalanced,
                ..Default::default()
            },
        ),
        ("rprm3_de00", Kind::Rprm, de00),
    ];
    for (name, kind, opts) in variants {
        g.bench_function(name, |b| {
            b.iter(|| {
                evaluate_with(
                    kind,
                    3,
                    black_box(&data),
                    Protocol::LeaveOneOut,
                    "D65",
                    &opts,
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, fitting);
criterion_main!(benches);
