//! The Academy/SMPTE Common LUT Format (SMPTE ST 2136-1, Academy CLF v3): a `ProcessList` of
//! the nodes of a [`LutExport`], all in 32-bit float.

use super::nodes::{LogCurve, Node};
use super::{provenance_line, ErrorReport, LutExport};
use std::fmt::Write as _;

/// Escapes text for XML element content and attribute values.
pub(crate) fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && !matches!(c, '\n' | '\t') => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// The `ProcessList` id: `urn:nsrm:<kind><order>:<camera>:<illuminant>:<space>:<digest>`, the digest
/// (FNV-1a of the model's matrix and the LUT options) telling different fits apart.
pub(crate) fn process_list_id(e: &LutExport) -> String {
    let p = e.model.provenance();
    let clean = |s: &str| -> String {
        nsrm::display_name(s)
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '.' {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    let mut h: u64 = 0xcbf29ce484222325;
    let mut feed = |bytes: &[u8]| {
        for b in bytes {
            h ^= *b as u64;
            h = h.wrapping_mul(0x100000001b3);
        }
    };
    for v in e.model.matrix() {
        feed(&v.to_le_bytes());
    }
    feed(&(e.options.size as u64).to_le_bytes());
    feed(&e.options.stops[0].to_le_bytes());
    feed(&e.options.stops[1].to_le_bytes());
    feed(e.space.name().as_bytes());
    format!(
        "urn:nsrm:{}{}:{}:{}:{}:{:016x}",
        e.model.kind().name(),
        e.model.order(),
        clean(p.camera.as_deref().unwrap_or("camera")),
        clean(p.illuminant.as_deref().unwrap_or("illuminant")),
        e.space.name(),
        h
    )
}

fn log_params(s: &mut String, c: &LogCurve) {
    let _ = writeln!(
        s,
        "    <LogParams base=\"2\" linSideSlope=\"1\" linSideOffset=\"0\" logSideSlope=\"{}\" logSideOffset=\"{}\" linSideBreak=\"{}\"/>",
        c.log_slope, c.log_offset, c.break_x
    );
}

/// The CLF document for `e`; `report` (the measured error) goes into the `Description`.
pub(crate) fn write(e: &LutExport, report: Option<&ErrorReport>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let name = format!(
        "{} to {} ({})",
        super::camera_space_name(&e.model),
        e.space.name(),
        e.space.interop_id()
    );
    let _ = writeln!(
        s,
        r#"<ProcessList id="{}" name="{}" compCLFversion="3.0">"#,
        xml_escape(&process_list_id(e)),
        xml_escape(&name)
    );
    let _ = writeln!(
        s,
        "  <Description>nsrm {}: {}</Description>",
        env!("CARGO_PKG_VERSION"),
        xml_escape(&provenance_line(&e.model))
    );
    let method = if e.exact {
        "exact: one Matrix node (the model is linear)".to_string()
    } else {
        let [lo, hi] = e.options.stops;
        format!(
            "approximation: Range clamp to [0, 2^{hi}], cameraLinToLog shaper (log2 from 2^{} up, linear below, 0 to 0), LUT3D {n}x{n}x{n} {} sampled from the f64 model of log2-encoded L^-1 f(S), cameraLogToLin, Matrix L; accurate range 2^{lo}..2^{hi} per camera channel (training white G = 1); outside it the LUT clamps",
            lo - super::TOE_STOPS,
            e.options.interpolation.clf_name(),
            n = e.options.size
        )
    };
    let _ = writeln!(s, "  <Description>{}</Description>", xml_escape(&method));
    if let Some(r) = report {
        let _ = writeln!(
            s,
            "  <Description>Measured error against the exact model (ΔE00, CIEDE2000, in the model's XYZ with the training white, scaled with exposure): {}</Description>",
            xml_escape(&r.summary())
        );
    }
    let _ = writeln!(
        s,
        "  <InputDescriptor>Linear camera RGB, not white-balanced: the perfect white under the training illuminant has G = 1</InputDescriptor>"
    );
    let _ = writeln!(
        s,
        "  <OutputDescriptor>{}: scene-linear, the training white at Y = 1 (as nsrm's apply writes it in output space {})</OutputDescriptor>",
        e.space.interop_id(),
        e.space.name()
    );
    for (i, node) in e.nodes.iter().enumerate() {
        let id = format!("n{}", i + 1);
        match node {
            Node::Matrix(m) => {
                let _ = writeln!(
                    s,
                    r#"  <Matrix id="{id}" inBitDepth="32f" outBitDepth="32f">"#
                );
                let _ = writeln!(s, r#"    <Array dim="3 3">"#);
                for row in m {
                    let _ = writeln!(s, "      {} {} {}", row[0], row[1], row[2]);
                }
                let _ = writeln!(s, "    </Array>\n  </Matrix>");
            }
            Node::Clamp { lo, hi } => {
                let _ = writeln!(
                    s,
                    r#"  <Range id="{id}" inBitDepth="32f" outBitDepth="32f" style="Clamp">"#
                );
                let _ = writeln!(
                    s,
                    "    <minInValue>{lo}</minInValue>\n    <maxInValue>{hi}</maxInValue>\n    <minOutValue>{lo}</minOutValue>\n    <maxOutValue>{hi}</maxOutValue>\n  </Range>"
                );
            }
            Node::Log { curve, inverse } => {
                let style = if *inverse {
                    "cameraLogToLin"
                } else {
                    "cameraLinToLog"
                };
                let _ = writeln!(
                    s,
                    r#"  <Log id="{id}" inBitDepth="32f" outBitDepth="32f" style="{style}">"#
                );
                log_params(&mut s, curve);
                let _ = writeln!(s, "  </Log>");
            }
            Node::Lut1d(l) => {
                // Not produced for CLF (the Log node is exact), but written correctly if asked.
                let _ = writeln!(
                    s,
                    r#"  <LUT1D id="{id}" inBitDepth="32f" outBitDepth="32f">"#
                );
                let _ = writeln!(s, r#"    <Array dim="{} 3">"#, l.values.len());
                for v in &l.values {
                    let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
                }
                let _ = writeln!(s, "    </Array>\n  </LUT1D>");
            }
            Node::Lut3d(l) => {
                let _ = writeln!(
                    s,
                    r#"  <LUT3D id="{id}" inBitDepth="32f" outBitDepth="32f" interpolation="{}">"#,
                    l.interpolation.clf_name()
                );
                let n = l.size;
                let _ = writeln!(s, r#"    <Array dim="{n} {n} {n} 3">"#);
                for v in &l.values {
                    let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
                }
                let _ = writeln!(s, "    </Array>\n  </LUT3D>");
            }
        }
    }
    let _ = writeln!(s, "</ProcessList>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LutOptions;
    use nsrm::OutputSpace;
    use nsrm::{fit, Kind};
    use nsrm::{simulate_named, Grid};

    #[test]
    fn structure_of_matrix_and_lut_documents() {
        let d = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default()).unwrap();
        let lrm = fit(Kind::Lrm, 1, &d).unwrap();
        let e = LutExport::clf(&lrm, OutputSpace::Acescg, LutOptions::default(), &d.rgb).unwrap();
        let r = e.measure(&d.rgb).unwrap();
        let doc = write(&e, Some(&r));
        assert!(doc.contains(r#"compCLFversion="3.0""#));
        assert!(
            doc.contains(r#"id="urn:nsrm:lrm1:nikon-d5100:D65:acescg:"#),
            "{doc}"
        );
        assert_eq!(doc.matches("<Matrix").count(), 1);
        assert!(!doc.contains("LUT3D"));
        assert!(doc.contains("Measured error"));
        let m = fit(Kind::Nsrm, 2, &d).unwrap();
        let o = LutOptions {
            size: 5,
            ..Default::default()
        };
        let e = LutExport::clf(&m, OutputSpace::Xyz, o, &d.rgb).unwrap();
        let doc = write(&e, None);
        for tag in [
            "<Range",
            "cameraLinToLog",
            "<LUT3D",
            "cameraLogToLin",
            "<Matrix",
        ] {
            assert!(doc.contains(tag), "{tag}");
        }
        assert!(doc.contains(r#"interpolation="tetrahedral""#));
        assert!(doc.contains(r#"<Array dim="5 5 5 3">"#));
        // 125 lattice lines of three numbers.
        let body = doc.split(r#"<Array dim="5 5 5 3">"#).nth(1).unwrap();
        let lines: Vec<&str> = body
            .lines()
            .skip(1)
            .take_while(|l| !l.contains("</Array>"))
            .collect();
        assert_eq!(lines.len(), 125);
        assert!(lines.iter().all(|l| l.split_whitespace().count() == 3));
        assert_eq!(xml_escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }
}
