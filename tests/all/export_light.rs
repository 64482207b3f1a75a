//! The light `nsrm export --format dcp` names in its message is the light the DCP names
//! (issue 36): one function decides the calibration illuminant for both. On the real Canon DNG
//! (a chart under tungsten-like light, a model whose own white is D50) the file and the message
//! both name the chart's light, never the model's 5001 K white.

use crate::common::{self, chart_dng, nsrm_ok as ok};

/// The temperature in the profile name written into the DCP (`… 2763K chart light`).
fn profile_name_kelvin(dcp: &[u8]) -> Option<String> {
    let text = String::from_utf8_lossy(dcp);
    let end = text.find("K chart light")?;
    let start = text[..end].rfind(' ')? + 1;
    Some(text[start..end].to_string())
}

#[test]
fn the_export_message_names_the_light_the_dcp_names() {
    let dng = chart_dng();
    if !dng.exists() {
        common::skip(&format!("{} is absent", dng.display()));
        return;
    }
    let dir = common::tempdir("export-light");
    ok(
        &dir,
        &[
            "calibrate",
            dng.to_str().unwrap(),
            "-o",
            "cal",
            "--kind",
            "lrm",
        ],
    );
    let o = ok(
        &dir,
        &[
            "export",
            "--model",
            "cal/model.json",
            "--format",
            "dcp",
            "-o",
            "c.dcp",
        ],
    );
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stderr),
        String::from_utf8_lossy(&o.stdout)
    );
    let k = profile_name_kelvin(&std::fs::read(dir.join("c.dcp")).unwrap())
        .expect("the profile name names the chart's light");
    let named = format!("Other: {k} K");
    assert!(
        said.contains(&format!("DNG camera profile ({named}")),
        "{named}: {said}"
    );
    assert!(
        said.contains(&format!("at the calibration white, {named}")),
        "{named}: {said}"
    );
    assert!(!said.contains("5001 K"), "{said}");
}
