//! Criterion bench of chart reading on a 24-Mpixel frame (6000×4000, the size of a typical APS-C
//! raw), the figure issue 10 asks for (≤ 2 s on the 2-core machine), through the library's one
//! reading call, `nsrm_chart::read`: found by detection (detection + patch extraction + the
//! reference check) and at the scene's true corners (extraction + the check; detection alone is
//! the difference).
//!
//! The scenes are rendered once with `nsrm_chart::render_scene` (the same renderer as `nsrm
//! render-scene --envelope`): a CC24 scene (seed 3: the chart covers 7.6 % of the frame, tilted
//! 21°) and an SG scene (seed 5, spectra from `../shared/data/colorchecker_sg_140.csv` when that
//! file is there; skipped otherwise), written to a temporary float EXR and decoded once
//! (`CaptureFrame::open`). Writing, reading and hashing the file are not timed (`nsrm bench` and
//! the EXR benches measure them). `cargo bench --features chart --bench chart`.

use criterion::{criterion_group, criterion_main, Criterion};
use nsrm_chart::render_scene as render;
use nsrm_chart::SceneOptions;
use nsrm_chart::{read, CaptureFrame, ChartColours, ChartKind, ReadingOptions, Reference};
use nsrm_io::{Decoded, Encoding, FileFormat, ReadOptions, WriteOptions};
use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

const WIDTH: usize = 6000;
const HEIGHT: usize = 4000;
const SG_SPECTRA: &str = "../shared/data/colorchecker_sg_140.csv";

fn chart(c: &mut Criterion) {
    let mut g = c.benchmark_group("chart_6000x4000");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(10));
    let dir = tempfile::tempdir().unwrap();
    for (kind, reference, refl, seed) in [
        (ChartKind::Cc24, "cc24-after2014", None, 3u64),
        (ChartKind::Sg, "sg-after2014", Some(SG_SPECTRA), 5),
    ] {
        if refl.is_some_and(|p| !std::path::Path::new(p).exists()) {
            eprintln!("{SG_SPECTRA} not found: the SG bench is skipped");
            continue;
        }
        let colours = ChartColours::simulate(kind, "nikon-d5100", "D65", refl).unwrap();
        let reference = Reference::load(reference, kind, None).unwrap();
        let opts = SceneOptions::envelope(&colours, WIDTH, HEIGHT, seed);
        let (frame, _, truth) = render(&colours, &opts).unwrap();
        let path = dir.path().join(format!("{kind:?}.exr"));
        let write = WriteOptions {
            format: FileFormat::Exr,
            half: false,
            compression: nsrm_io::ExrCompression::None,
            space: nsrm::OutputSpace::Xyz,
            ..Default::default()
        };
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        Decoded::from(frame)
            .write_to(&path, &write, &mut file)
            .unwrap();
        drop(file);
        let frame =
            Arc::new(CaptureFrame::open(&path, &ReadOptions::default(), Encoding::Linear).unwrap());
        let detected = ReadingOptions::default();
        let at_corners = ReadingOptions {
            corners: Some(truth.corners),
            ..Default::default()
        };
        g.bench_function(format!("{kind:?}/read"), |b| {
            b.iter(|| read(black_box(&frame), &reference, &detected).unwrap())
        });
        g.bench_function(format!("{kind:?}/read_at_corners"), |b| {
            b.iter(|| read(black_box(&frame), &reference, &at_corners).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, chart);
criterion_main!(benches);
