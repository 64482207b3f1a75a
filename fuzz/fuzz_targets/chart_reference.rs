//! The chart reference readers (`--reference FILE`): CSV (`label` + `X,Y,Z` or `L,a,b`) and
//! CGATS (`SAMPLE_ID` + `XYZ_X/Y/Z` or `LAB_L/A/B`), for both charts. The first byte picks the
//! format and chart; the rest is the file.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nsrm_chart::{ChartKind, Reference};

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    let ext = if pick & 1 == 0 { "csv" } else { "cie" };
    let chart = if pick & 2 == 0 {
        ChartKind::Cc24
    } else {
        ChartKind::Sg
    };
    // A white given (any plausible one: D65) or the files' default (D50).
    let white = (pick & 4 != 0).then_some(nsrm::D65_WHITE_XYZ);
    let path = std::env::temp_dir().join(format!("nsrm-fuzz-{}.{ext}", std::process::id()));
    if std::fs::write(&path, body).is_err() {
        return;
    }
    let _ = Reference::load(&path.to_string_lossy(), chart, white);
});
