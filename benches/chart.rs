//! Criterion bench of chart detection + patch extraction on a 24-Mpixel frame (6000×4000, the
//! size of a typical APS-C raw), the figure issue 10 asks for (≤ 2 s on the 2-core machine).
//!
//! The scenes are rendered once, in memory, with `nsrm::chart::render_scene` (the same renderer
//! as `nsrm render-scene --envelope`): a CC24 scene (seed 3: the chart covers 7.6 % of the frame,
//! tilted 21°) and an SG scene (seed 5, spectra from `../shared/data/colorchecker_sg_140.csv`
//! when that file is there; skipped otherwise). Reading the file is not timed (`nsrm bench` and
//! the EXR benches measure it). `cargo bench --features chart --bench chart`.

use criterion::{criterion_group, criterion_main, Criterion};
use nsrm::chart::render_scene as render;
use nsrm::chart::{detect, extract, ChartColours, ChartKind, DetectOptions, ExtractOptions};
use nsrm::chart::{Reference, SceneOptions};
use std::hint::black_box;
use std::time::Duration;

const WIDTH: usize = 6000;
const HEIGHT: usize = 4000;
const SG_SPECTRA: &str = "../shared/data/colorchecker_sg_140.csv";

fn chart(c: &mut Criterion) {
    let mut g = c.benchmark_group("chart_6000x4000");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(10));
    for (kind, refl, seed) in [
        (ChartKind::Cc24, None, 3u64),
        (ChartKind::Sg, Some(SG_SPECTRA), 5),
    ] {
        if refl.is_some_and(|p| !std::path::Path::new(p).exists()) {
            eprintln!("{SG_SPECTRA} not found: the SG bench is skipped");
            continue;
        }
        let colours = ChartColours::simulate(kind, "nikon-d5100", "D65", refl).unwrap();
        let reference = Reference::load(kind.default_reference(), kind, None).unwrap();
        let opts = SceneOptions::envelope(&colours, WIDTH, HEIGHT, seed);
        let (frame, _, _) = render(&colours, &opts).unwrap();
        let d = detect(&frame, &reference, &DetectOptions::default())
            .map_err(|f| f.error)
            .unwrap();
        g.bench_function(format!("{}/detect", kind.name()), |b| {
            b.iter(|| detect(black_box(&frame), &reference, &DetectOptions::default()).is_ok())
        });
        g.bench_function(format!("{}/extract", kind.name()), |b| {
            b.iter(|| {
                extract(
                    black_box(&frame),
                    &reference,
                    &d.homography,
                    &ExtractOptions::default(),
                )
                .unwrap()
            })
        });
        g.bench_function(format!("{}/detect+extract", kind.name()), |b| {
            b.iter(|| {
                let d = detect(black_box(&frame), &reference, &DetectOptions::default())
                    .map_err(|f| f.error)
                    .unwrap();
                extract(
                    &frame,
                    &reference,
                    &d.homography,
                    &ExtractOptions::default(),
                )
                .unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, chart);
criterion_main!(benches);
