//! Criterion benches of the CPU frame path (`Model::apply_frame`, the fast f32 kernels of
//! `src/model/fast.rs`) on one thread (a one-thread rayon pool) and on rayon's global pool,
//! beside a memcpy of the same bytes (the ceiling a per-pixel kernel can reach). Throughput is in
//! pixels (`elem/s`). Two families, the baseline code and the into path:
//! * `hand/…`: the programs a hand-written kernel declares (LRM, PRM 3, RPRM 3, NSRM 3);
//! * `plan/…`: programs no hand-written kernel matches, run by the generic product plan
//!   (`BlockKernel for Plan`): PRM, RPRM and NSRM at orders 2 and 4, and white-balanced NSRM 2
//!   (its gain step). Which kernel each model gets is pinned by the unit test
//!   `every_standard_model_gets_a_kernel_and_plans_fit` in `src/model/fast.rs`;
//! * `baseline/…`: the hand-written kernels' baseline code on one thread (no FMA; NSRM 3 and
//!   PRM 3 run their SSE2 kernels), what a CPU without AVX2 + FMA runs and what
//!   `FastModel::apply_baseline` runs on any CPU;
//! * `into/…`: the hand-written kernels into a second frame (`FastModel::apply_into`), with the
//!   memcpy rows' buffers and access pattern exactly: these over `memcpy/…` are the like-for-like
//!   ratio, the one `nsrm bench` prints.
//!
//! The frame (4096×2048 packed RGB f32, 96 MiB, `nsrm bench`'s default) is well beyond the last
//! cache level: at 2048×2048 (48 MiB, this bench until 2026-12-07) a host with a 32 MiB L3 kept
//! part of the repeated memcpy's source there, which the kernels' rows never got. `memcpy/…`
//! copies it into a separate pre-faulted buffer in the fast path's 64 Ki-pixel chunks on the same
//! threads. The `hand/`, `plan/` and `baseline/` rows correct a frame in place, as
//! `Model::apply_frame` does, each run on a buffer just rewritten from the source outside the
//! timing (one buffer for all runs: a fresh allocation for each run, this bench until
//! 2026-12-07, made even a memcpy out of it 0.6–0.7× as fast on a 2-vCPU VM); `memcpy-fresh/…`
//! copies out of such a buffer. In place a kernel moves two frames' bytes where a memcpy moves
//! three (the destination's lines are read for ownership), so those rows can beat `memcpy/…`.
//! `cargo bench --bench kernels`; `nsrm bench` measures the kernels into a second frame with the
//! memcpy interleaved, and prints the ratios.

use criterion::{criterion_group, criterion_main, Bencher, Criterion, Throughput};
use nsrm::{fit_with, simulate_named, FitOptions, Grid, Kind, Normalise};
use nsrm::{FastModel, Frame, Layout, Threads};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// The benchmark frame and the memcpy reference, shared with `nsrm bench` (the file names the
/// library as `crate::`, which it is inside nsrm; here the root's imports stand for it).
#[path = "../crates/nsrm-cli/src/bench_aids.rs"]
mod bench_aids;
use bench_aids::{memcpy_chunked, synthetic_camera_rgb};

const WIDTH: usize = 4096;
const HEIGHT: usize = 2048;
/// The fast path's chunk: 64 Ki pixels of packed RGB.
const CHUNK_FLOATS: usize = 3 << 16;

fn kernels(c: &mut Criterion) {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let src = synthetic_camera_rgb(WIDTH, HEIGHT, Layout::Rgb, 0x5eed);
    let mut dst = Frame::new(WIDTH, HEIGHT, Layout::Rgb);
    dst.data.iter_mut().for_each(|v| *v = 1.0); // pre-fault
    let mut work = src.clone();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let global = rayon::ThreadPoolBuilder::new().build().unwrap();

    let mut g = c.benchmark_group(format!("kernels_{WIDTH}x{HEIGHT}_rgb"));
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
        // The same copy out of a freshly rewritten frame, as the in-place rows below get theirs:
        // its last-written lines are still in the caches, dirty, and evicting them is timed.
        g.bench_function(format!("memcpy-fresh/{name}"), |b| {
            fresh(b, &src, &mut work, |frame| {
                pool.install(|| memcpy_chunked(&frame.data, &mut dst.data, CHUNK_FLOATS, true))
            })
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
                fresh(b, &src, &mut work, |frame| {
                    pool.install(|| model.apply_frame(frame))
                })
            });
        }
        if family == "hand" {
            // Into a second frame: the memcpy rows' buffers and access pattern exactly, so these
            // rows over `memcpy/…` are the like-for-like ratio (what `nsrm bench` prints).
            let fast = FastModel::new(&model);
            for (name, pool) in pools {
                g.bench_function(format!("into/{}{order}/{name}", kind.name()), |b| {
                    b.iter(|| {
                        pool.install(|| {
                            fast.apply_into(black_box(&src), &mut dst, Threads::All)
                                .expect("same-size frames")
                        })
                    })
                });
            }
            // The baseline code (no FMA; SSE2 kernels for NSRM 3 and PRM 3): what a CPU without
            // AVX2 + FMA runs, and what `FastModel::apply_baseline` runs on any CPU.
            g.bench_function(format!("baseline/{}{order}/1t", kind.name()), |b| {
                fresh(b, &src, &mut work, |frame| {
                    fast.apply_baseline(frame, Threads::Single)
                })
            });
        }
    }
    g.finish();
}

/// Times `f` on `work` rewritten from `src` before each run (the copy untimed): a frame in the
/// state a decoder leaves it, corrected in place as `Model::apply_frame` does. One buffer for
/// every run, so no run pays for fresh pages.
fn fresh(b: &mut Bencher, src: &Frame, work: &mut Frame, mut f: impl FnMut(&mut Frame)) {
    b.iter_custom(|iters| {
        let mut spent = Duration::ZERO;
        for _ in 0..iters {
            work.data.copy_from_slice(&src.data);
            let start = Instant::now();
            f(black_box(&mut *work));
            spent += start.elapsed();
        }
        spent
    })
}

criterion_group!(benches, kernels);
criterion_main!(benches);
