//! Criterion benches of the CPU frame path (`Model::apply_frame`, the fast f32 kernels of
//! `src/model/fast.rs`) on one thread (a one-thread rayon pool) and on rayon's global pool,
//! beside a memcpy of the same bytes (the ceiling a per-pixel kernel can reach). Throughput is in
//! pixels (`elem/s`). Two families, and the baseline code:
//! * `hand/…`: the programs a hand-written kernel declares (LRM, PRM 3, RPRM 3, NSRM 3);
//! * `plan/…`: programs no hand-written kernel matches, run by the generic product plan
//!   (`BlockKernel for Plan`): PRM, RPRM and NSRM at orders 2 and 4, and white-balanced NSRM 2
//!   (its gain step). Which kernel each model gets is pinned by the unit test
//!   `every_standard_model_gets_a_kernel_and_plans_fit` in `src/model/fast.rs`.
//! * `baseline/…`: the hand-written kernels' baseline code on one thread (no FMA; NSRM 3 and
//!   PRM 3 run their SSE2 kernels), what a CPU without AVX2 + FMA runs and what
//!   `FastModel::apply_baseline` runs on any CPU.
//!
//! The frame (2048×2048 packed RGB f32, 48 MiB) is larger than the caches. Each kernel run
//! corrects a fresh copy of it in place (the copy is made, and its pages faulted, outside the
//! timing), so a run reads and writes 48 MiB like the memcpy into a separate pre-faulted buffer,
//! done in the fast path's 64 Ki-pixel chunks on the same threads (`memcpy/…`; `memcpy-fresh/…`
//! copies out of a fresh copy, in the cache state the kernels' input is in). `cargo bench --bench kernels`;
//! `nsrm bench` measures the crate's kernels (into a second frame) in one run and prints ratios.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use nsrm::{fit_with, simulate_named, FitOptions, Grid, Kind, Normalise};
use nsrm::{FastModel, Frame, Layout, Threads};
use std::hint::black_box;
use std::time::Duration;

/// The benchmark frame and the memcpy reference, shared with `nsrm bench` (the file names the
/// library as `crate::`, which it is inside nsrm; here the root's imports stand for it).
#[path = "../crates/nsrm-cli/src/bench_aids.rs"]
mod bench_aids;
use bench_aids::{memcpy_chunked, synthetic_camera_rgb};

const WIDTH: usize = 2048;
const HEIGHT: usize = 2048;
/// The fast path's chunk: 64 Ki pixels of packed RGB.
const CHUNK_FLOATS: usize = 3 << 16;

fn kernels(c: &mut Criterion) {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let src = synthetic_camera_rgb(WIDTH, HEIGHT, Layout::Rgb, 0x5eed);
    let mut dst = Frame::new(WIDTH, HEIGHT, Layout::Rgb);
    dst.data.iter_mut().for_each(|v| *v = 1.0); // pre-fault
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let global = rayon::ThreadPoolBuilder::new().build().unwrap();

    let mut g = c.benchmark_group("kernels_2048x2048_rgb");
    g.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(3));
    let pools = [("1t", &one), ("all", &global)];
    for (name, pool) in pools {
        g.bench_function(format!("memcpy/{name}"), |b| {
            b.iter(|| {
                pool.install(|| {
                    memcpy_chunked(black_box(&src.data), &mut dst.data, CHUNK_FLOATS, true)
                })
            })
        });
        // The same copy out of a fresh copy of the frame, as the kernels below get theirs: its
        // last-written lines are still in the caches, dirty, and evicting them is in the timing.
        g.bench_function(format!("memcpy-fresh/{name}"), |b| {
            b.iter_batched_ref(
                || src.clone(),
                |frame| {
                    pool.install(|| {
                        memcpy_chunked(black_box(&frame.data), &mut dst.data, CHUNK_FLOATS, true)
                    })
                },
                BatchSize::LargeInput,
            )
        });
    }
    let plain = FitOptions::default();
    let balanced = FitOptions {
        normalise: Normalise::WhiteBalanced,
        ..FitOptions::default()
    };
    let cases = [
        ("hand", Kind::Lrm, 1, &plain, ""),
        ("hand", Kind::Prm, 3, &plain, ""),
        ("hand", Kind::Rprm, 3, &plain, ""),
        ("hand", Kind::Nsrm, 3, &plain, ""),
        ("plan", Kind::Prm, 2, &plain, ""),
        ("plan", Kind::Prm, 4, &plain, ""),
        ("plan", Kind::Rprm, 2, &plain, ""),
        ("plan", Kind::Rprm, 4, &plain, ""),
        ("plan", Kind::Nsrm, 2, &plain, ""),
        ("plan", Kind::Nsrm, 4, &plain, ""),
        ("plan", Kind::Nsrm, 2, &balanced, "wb"),
    ];
    for (family, kind, order, opts, wb) in cases {
        let model = fit_with(kind, order, &data, opts).unwrap().model;
        for (name, pool) in pools {
            g.bench_function(format!("{family}/{}{order}{wb}/{name}", kind.name()), |b| {
                b.iter_batched_ref(
                    || src.clone(),
                    |frame| pool.install(|| model.apply_frame(black_box(frame))),
                    BatchSize::LargeInput,
                )
            });
        }
        if family == "hand" {
            // The baseline code (no FMA; SSE2 kernels for NSRM 3 and PRM 3): what a CPU without
            // AVX2 + FMA runs, and what `FastModel::apply_baseline` runs on any CPU.
            let fast = FastModel::new(&model);
            g.bench_function(format!("baseline/{}{order}/1t", kind.name()), |b| {
                b.iter_batched_ref(
                    || src.clone(),
                    |frame| fast.apply_baseline(black_box(frame), Threads::Single),
                    BatchSize::LargeInput,
                )
            });
        }
    }
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
