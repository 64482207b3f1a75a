//! The measured-patch CSV reader (`--training patches.csv`: `label,R,G,B,X,Y,Z`).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = nsrm::TrainingSet::parse_measured(text, "fuzz.csv", None);
    let _ = nsrm::TrainingSet::parse_measured(text, "fuzz.csv", Some([96.42, 100.0, 82.49]));
});
