//! The engine's crate-private parts (bench timing, the device choice with its reason), once in
//! `gpu_tests.rs`. Without an adapter these tests print `SKIP: no GPU adapter ...` and pass,
//! unless `CI=true`, where they fail.

use super::gpu_tests::engine;
use super::{open, open_device, CpuReason, DeviceChoice, GpuError, GpuOptions, Opened};
use crate::kit::{awkward_frame as random_frame, training};
use crate::{fit, Kind, Layout, Model};

fn model(kind: Kind, order: u8) -> Model {
    fit(kind, order, training()).unwrap()
}

#[test]
fn timing_and_bandwidth_are_reported() {
    let Some(mut e) = engine(None) else { return };
    eprintln!("adapter: {}", e.adapter_name());
    // 2 Mpixel RGBA by default (two tiles, so upload, compute and read-back overlap);
    // NSRM_GPU_TEST_MPIXELS=16 for a longer run.
    let mpx: usize = std::env::var("NSRM_GPU_TEST_MPIXELS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let mut frame = random_frame(1024, 1024 * mpx, Layout::Rgba, 3);
    let n = frame.pixels() as f64 / 1e6;
    for kind in [Kind::Nsrm, Kind::Rprm] {
        let m = model(kind, 3);
        e.apply(&m, &mut frame).unwrap(); // warm-up: pipeline and buffers
        let t = e.timed_apply(&m, &mut frame).unwrap();
        assert!(t.total_seconds > 0.0);
        if e.has_timestamps() {
            let k = t.kernel_seconds.expect("timestamps are supported");
            assert!(k > 0.0 && k.is_finite());
            eprintln!(
                "{kind} 3, {n:.1} Mpixel RGBA: kernel {:.1} Mpixel/s, with upload and read-back {:.1} Mpixel/s",
                n / k,
                n / t.total_seconds
            );
        } else {
            assert!(t.kernel_seconds.is_none());
        }
    }
    match e.copy_bandwidth(64 << 20).unwrap() {
        Some(bw) => {
            assert!(bw > 0.0 && bw.is_finite());
            eprintln!("buffer copy: {:.2} GB/s", bw / 1e9);
        }
        None => eprintln!("buffer copy: no timestamps inside encoders"),
    }
}

#[test]
fn open_follows_the_device_choice() {
    assert!(open(DeviceChoice::Cpu, &GpuOptions::default())
        .unwrap()
        .is_none());
    let Some(e) = engine(None) else { return };
    // `Auto` takes a hardware adapter, never a software rasteriser (lavapipe) unless named, and
    // says why it chose the CPU.
    let software = e.context().adapter.get_info().device_type == wgpu::DeviceType::Cpu;
    match open_device(DeviceChoice::Auto, &GpuOptions::default()).unwrap() {
        Opened::Gpu(a) => {
            assert!(
                !software,
                "auto took the software adapter {}",
                a.adapter_name()
            );
            assert_eq!(a.adapter_name(), e.adapter_name());
        }
        Opened::Cpu(why) => {
            assert!(
                software,
                "auto left the hardware adapter {}",
                e.adapter_name()
            );
            assert!(
                matches!(&why, CpuReason::SoftwareOnly { adapter } if *adapter == e.adapter_name()),
                "{why}"
            );
        }
    }
    assert!(open(DeviceChoice::Gpu, &GpuOptions::default())
        .unwrap()
        .is_some());
    // The adapter chosen by a name substring (case-insensitive).
    let name = e.adapter_name();
    let part = name.split_whitespace().next().unwrap().to_uppercase();
    let opts = GpuOptions {
        adapter: Some(part),
        tile_pixels: None,
    };
    for choice in [DeviceChoice::Gpu, DeviceChoice::Auto] {
        // Named, even a software adapter is taken by `Auto`.
        assert_eq!(open(choice, &opts).unwrap().unwrap().adapter_name(), name);
    }
    let opts = GpuOptions {
        adapter: Some("no-such-adapter-xyz".into()),
        tile_pixels: None,
    };
    for choice in [DeviceChoice::Auto, DeviceChoice::Gpu] {
        let err = open(choice, &opts).unwrap_err();
        assert!(matches!(err, GpuError::AdapterNotFound { .. }), "{err}");
        assert!(err.to_string().contains(&name), "{err}");
    }
}
