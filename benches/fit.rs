//! Criterion benches of fitting: every model kind at every order on 96 patches (the first 96 of
//! the built-in rawtoaces-190 set, Nikon D5100 under D65), and the leave-one-out evaluation on
//! them (96 fits each, in parallel). Each takes milliseconds. `cargo bench --bench fit`.

use criterion::{criterion_group, criterion_main, Criterion};
use nsrm::eval::{evaluate, Protocol};
use nsrm::model::{fit, Kind, MAX_ORDER};
use nsrm::spectral::{simulate_named, Grid};
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
}

criterion_group!(benches, fitting);
criterion_main!(benches);
