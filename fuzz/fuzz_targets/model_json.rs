//! The model file parser (`--model m.json`) on arbitrary text, and applying what it accepts.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(m) = nsrm::Model::from_json(text, "fuzz.json") {
        // An accepted model must apply without panicking and round-trip through its JSON.
        let _ = m.apply_f64([0.2, 0.5, 0.3]);
        let again = nsrm::Model::from_json(&m.to_json(), "again.json");
        assert!(again.is_ok(), "a model written by to_json is refused: {again:?}");
    }
});
