//! The camera-raw reader on arbitrary bytes named `.dng` (the seeds: lossless-JPEG DNGs and
//! damaged copies): the IFD scan, the lossless-JPEG stream check and rawler behind them. An
//! error is fine; a panic, an abort, a hang or an allocation past the limits is a bug.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nsrm_io::{Demosaic, Limits, ReadOptions};

fuzz_target!(|data: &[u8]| {
    let path = std::env::temp_dir().join(format!("nsrm-fuzz-{}.dng", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let opts = ReadOptions {
        layer: None,
        // Small enough that a valid huge header is refused rather than decoded slowly.
        limits: Limits {
            max_pixels: 1 << 22,
        },
        demosaic: Demosaic::Half,
    };
    let _ = nsrm_io::Decoded::read(&path, &opts);
});
