//! The EXR reader (`nsrm apply`'s decoder) on arbitrary bytes: an error is fine, a panic, an
//! abort, a hang or an allocation past the limits is a bug.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nsrm_io::{Decoded, Limits, ReadOptions};

fuzz_target!(|data: &[u8]| {
    // The readers take paths (they seek, map and bound by the file's size): one scratch file
    // per process.
    let path = std::env::temp_dir().join(format!("nsrm-fuzz-{}.exr", std::process::id()));
    if std::fs::write(&path, data).is_err() {
        return;
    }
    let opts = ReadOptions {
        layer: None,
        // Small enough that a valid huge header is refused rather than decoded slowly.
        limits: Limits {
            max_pixels: 1 << 22,
        },
        ..ReadOptions::default()
    };
    let _ = Decoded::read(&path, &opts);
});
