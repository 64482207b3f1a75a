//! Criterion benches of the fast CPU path (`nsrm::model::fast`): LRM, PRM 3, RPRM 3 and NSRM 3 on
//! one thread and on rayon's global pool, beside a memcpy of the same bytes (the ceiling a
//! per-pixel kernel can reach). Throughput is in pixels (`elem/s`).
//!
//! The frame (2048×2048 packed RGB f32, 48 MiB each way) is larger than the caches; the kernels
//! write into a separate pre-faulted frame, the memcpy into a separate pre-faulted buffer, both
//! in the fast path's 64 Ki-pixel chunks. `cargo bench --bench kernels`; `nsrm bench` measures the
//! same in one run and prints ratios.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use nsrm::model::fast::{FastModel, Threads};
use nsrm::model::{fit, Kind};
use nsrm::spectral::{simulate_named, Grid};
use nsrm::{Frame, Layout};
use std::hint::black_box;
use std::time::Duration;

/// The benchmark frame and the memcpy reference, shared with `nsrm bench` (the file names the
/// library as `crate::`, which it is inside nsrm; here the root's imports stand for it).
#[allow(unused_imports)]
use nsrm::model;
#[path = "../src/cli/bench_aids.rs"]
mod bench_aids;
use bench_aids::{memcpy_chunked, synthetic_camera_rgb};

const WIDTH: usize = 2048;
const HEIGHT: usize = 2048;

fn kernels(c: &mut Criterion) {
    let data = simulate_named("nikon-d5100", "D65", "rawtoaces-190", &Grid::default()).unwrap();
    let src = synthetic_camera_rgb(WIDTH, HEIGHT, Layout::Rgb, 0x5eed);
    let mut dst = Frame::new(WIDTH, HEIGHT, Layout::Rgb);
    dst.data.iter_mut().for_each(|v| *v = 1.0); // pre-fault

    let mut g = c.benchmark_group("kernels_2048x2048_rgb");
    g.throughput(Throughput::Elements((WIDTH * HEIGHT) as u64));
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(3));
    let threads = [("1t", Threads::Single), ("all", Threads::All)];
    for (name, th) in threads {
        g.bench_function(format!("memcpy/{name}"), |b| {
            b.iter(|| memcpy_chunked(black_box(&src.data), &mut dst.data, 3, th))
        });
    }
    for (kind, order) in [
        (Kind::Lrm, 1),
        (Kind::Prm, 3),
        (Kind::Rprm, 3),
        (Kind::Nsrm, 3),
    ] {
        let model = fit(kind, order, &data).unwrap();
        let fast = FastModel::new(&model);
        for (name, th) in threads {
            g.bench_function(format!("{}{order}/{name}", kind.name()), |b| {
                b.iter(|| fast.apply_into(black_box(&src), &mut dst, th).unwrap())
            });
        }
    }
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
