//! The chart reader's JPEG path on arbitrary bytes (the seeds: JPEGs and damaged copies): the
//! structure check (end marker, data enough for the declared size) and the decoder behind it.
//! An error is fine; a panic, an abort, a hang or an allocation past the limits is a bug.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nsrm_chart::CaptureFrame;
use nsrm_io::{Encoding, Limits, ReadOptions};

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("nsrm-fuzz-{}.jpg", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let opts = ReadOptions {
        limits: Limits {
            max_pixels: 1 << 22,
        },
        ..ReadOptions::default()
    };
    let _ = CaptureFrame::open(&path, &opts, Encoding::Auto);
});
