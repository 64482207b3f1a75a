//! Criterion benches of the CPU frame path (`Model::apply_frame`, the fast f32 kernels of
//! `src/model/fast.rs`) on one thread (a one-thread rayon pool) and on rayon's global pool,
//! beside a memcpy of the same bytes (the ceiling a per-pixel kernel can reach). Throughput is in
//! pixels (`elem/s`). Two families:
//! * `hand/…`: the programs a hand-written kernel declares (LRM, PRM 3, RPRM 3, NSRM 3);
//! * `plan/…`: programs no hand-written kernel matches, run by the generic product plan
//!   (`BlockKernel for Plan`): PRM, RPRM and NSRM at orders 2 and 4, and white-balanced NSRM 2
//!   (its gain step). Which kernel each model gets is pinned by the unit test
//!   `every_standard_model_gets_a_kernel_and_plans_fit` in `src/model/fast.rs`.
//!
//! The frame (2048×2048 packed RGB f32, 48 MiB) is larger than the caches. Each kernel run
//! corrects a fresh copy of it in place (the copy is made, and its pages faulted, outside the
//! timing), so a run reads and writes 48 MiB like the memcpy into a separate pre-faulted buffer,
//! done in the fast path's 64 Ki-pixel chunks on the same threads. `cargo bench --bench kernels`;
//! `nsrm bench` measures the crate's kernels (into a second frame) in one run and prints ratios.
//!
//! The kernels' own cost, without memory: `l2_256x128_rgb/…/1t` corrects a 256×128 frame (384 KiB
//! of packed RGB f32, in the per-core L2 with its destination) into a second frame on the calling
//! thread ([`FastModel::apply_into`], what `nsrm bench` times), for the hand-written kernels. For
//! `perf record`/`perf stat`, the same loop runs without criterion when `NSRM_L2_REPS` is set:
//! `NSRM_L2_REPS=20000 NSRM_L2_KIND=nsrm3 target/release/deps/kernels-…` fits the model, runs that
//! many repetitions and prints the pixels, the time and Mpixel/s (cycles per pixel, where the CPU
//! exposes cycle counters: the cycles of a run minus those of a run with `NSRM_L2_REPS=0`, over
//! the pixels).

use criterion::{criterion_group, BatchSize, Criterion, Throughput};
use nsrm::{fit_with, simulate_named, FitOptions, Grid, Kind, Normalise};
use nsrm::{FastModel, Frame, Layout, Model, Threads};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// The benchmark frame and the memcpy reference, shared with `nsrm bench` (the file names the
/// library as `crate::`, which it is inside nsrm; here the root's imports stand for it).
#[path = "../crates/nsrm-cli/src/bench_aids.rs"]
mod bench_aids;
use bench_aids::{memcpy_chunked, synthetic_camera_rgb};

const WIDTH: usize = 2048;
const HEIGHT: usize = 2048;
/// The fast path's chunk: 64 Ki pixels of packed RGB.
const CHUNK_FLOATS: usize = 3 << 16;
/// The L2-resident frame: 256×128 packed RGB f32 (384 KiB in, 384 KiB out).
const L2_SIZE: (usize, usize) = (256, 128);

/// The hand-written kernels' models, by the name `FastModel::kernel_name` gives them.
fn hand_model(name: &str) -> Model {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let (kind, order) = match name {
        "linear" => (Kind::Lrm, 1),
        "prm3" => (Kind::Prm, 3),
        "rprm3" => (Kind::Rprm, 3),
        "nsrm3" => (Kind::Nsrm, 3),
        other => panic!("NSRM_L2_KIND={other}: linear, prm3, rprm3 or nsrm3"),
    };
    fit_with(kind, order, &data, &FitOptions::default())
        .unwrap()
        .model
}

/// `NSRM_L2_REPS` set: the L2 loop alone (for `perf`), then exit.
fn l2_loop(reps: usize) {
    let name = std::env::var("NSRM_L2_KIND").unwrap_or_else(|_| "nsrm3".into());
    let fast = FastModel::new(&hand_model(&name));
    assert_eq!(fast.kernel_name(), name);
    let (w, h) = L2_SIZE;
    let src = synthetic_camera_rgb(w, h, Layout::Rgb, 0x5eed);
    let mut dst = Frame::new(w, h, Layout::Rgb);
    let t = Instant::now();
    for _ in 0..reps {
        fast.apply_into(black_box(&src), &mut dst, Threads::Single)
            .unwrap();
        black_box(&mut dst);
    }
    let secs = t.elapsed().as_secs_f64();
    let pixels = (reps * w * h) as f64;
    println!(
        "{name}: {pixels:e} pixels in {secs:.3} s: {:.1} Mpixel/s",
        pixels / secs.max(1e-9) / 1e6
    );
}

/// The hand-written kernels on the L2-resident frame, one thread.
fn l2(c: &mut Criterion) {
    let (w, h) = L2_SIZE;
    let src = synthetic_camera_rgb(w, h, Layout::Rgb, 0x5eed);
    let mut dst = Frame::new(w, h, Layout::Rgb);
    let mut g = c.benchmark_group("l2_256x128_rgb");
    g.throughput(Throughput::Elements((w * h) as u64));
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(2));
    for name in ["linear", "prm3", "rprm3", "nsrm3"] {
        let fast = FastModel::new(&hand_model(name));
        g.bench_function(format!("{name}/1t"), |b| {
            b.iter(|| {
                fast.apply_into(black_box(&src), &mut dst, Threads::Single)
                    .unwrap()
            })
        });
    }
    g.finish();
}

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
    }
    g.finish();
}

criterion_group!(benches, l2, kernels);

fn main() {
    if let Ok(reps) = std::env::var("NSRM_L2_REPS") {
        return l2_loop(reps.parse().expect("NSRM_L2_REPS: a count"));
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
