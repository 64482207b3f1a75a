//! The Resolve `.cube` dialect (read by DaVinci Resolve, OpenColorIO and most grading tools): a 1D
//! shaper (`LUT_1D_SIZE`, `LUT_1D_INPUT_RANGE`) applied first, then a 3D LUT (`LUT_3D_SIZE`,
//! `LUT_3D_INPUT_RANGE`, red changing fastest). The format declares no interpolation; the table
//! is measured for the one [`LutOptions::interpolation`](super::LutOptions) names.

use super::nodes::Node;
use super::{provenance_line, ErrorReport, ExportError, LutExport};
use std::fmt::Write as _;

/// The `.cube` text of a [`LutExport::cube`] chain; `report` goes into the `#` header.
pub(crate) fn write(e: &LutExport, report: Option<&ErrorReport>) -> Result<String, ExportError> {
    let (shaper, lut) = match e.nodes.as_slice() {
        [Node::Lut1d(s), Node::Lut3d(l)] => (s, l),
        _ => {
            return Err(ExportError::Model(
                "a .cube file holds a 1D shaper and a 3D LUT; this chain is not one".into(),
            ))
        }
    };
    let mut s = String::new();
    let one_line = |t: &str| t.replace(['\n', '\r'], " ");
    let _ = writeln!(
        s,
        "# nsrm {}: {}",
        env!("CARGO_PKG_VERSION"),
        one_line(&provenance_line(&e.model))
    );
    let _ = writeln!(
        s,
        "# Input: linear camera RGB, not white-balanced (training white G = 1). Output: {} ({}), scene-linear, training white at Y = 1, as nsrm's apply writes it in output space {}.",
        e.space.name(),
        e.space.interop_id(),
        e.space.name()
    );
    let [lo, hi] = e.options.stops;
    let _ = writeln!(
        s,
        "# 1D shaper ({} entries over [0, 2^{hi}], log2 from 2^{} up) then 3D LUT {n}x{n}x{n}, sampled and measured for {} interpolation (set your reader to it); accurate range 2^{lo}..2^{hi} per channel.",
        shaper.values.len(),
        lo - super::TOE_STOPS,
        lut.interpolation.clf_name(),
        n = lut.size
    );
    if let Some(r) = report {
        let _ = writeln!(
            s,
            "# Measured error against the exact model (ΔE00): {}",
            one_line(&r.summary())
        );
    }
    // No TITLE: OpenColorIO's Resolve reader refuses the tag (the Iridas dialect has it).
    let _ = writeln!(
        s,
        "# {} to {}",
        super::camera_space_name(&e.model),
        e.space.name()
    );
    let _ = writeln!(s, "LUT_1D_SIZE {}", shaper.values.len());
    let _ = writeln!(
        s,
        "LUT_1D_INPUT_RANGE {} {}",
        shaper.domain[0], shaper.domain[1]
    );
    let _ = writeln!(s, "LUT_3D_SIZE {}", lut.size);
    let _ = writeln!(s, "LUT_3D_INPUT_RANGE 0.0 1.0");
    for v in &shaper.values {
        let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
    }
    let n = lut.size;
    for b in 0..n {
        for g in 0..n {
            for r in 0..n {
                let v = lut.values[(r * n + g) * n + b];
                let _ = writeln!(s, "{} {} {}", v[0], v[1], v[2]);
            }
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LutOptions;
    use nsrm::OutputSpace;
    use nsrm::{fit, Kind};
    use nsrm::{simulate_named, Grid};

    #[test]
    fn header_sizes_and_red_fastest_order() {
        let d = simulate_named("nikon-d5100", "D65", "cc24", &Grid::default()).unwrap();
        let m = fit(Kind::Rprm, 2, &d).unwrap();
        let o = LutOptions {
            size: 3,
            shaper_size: 16,
            ..Default::default()
        };
        let e = LutExport::cube(&m, OutputSpace::LinearSrgb, o).unwrap();
        let text = write(&e, None).unwrap();
        assert!(text.contains("LUT_1D_SIZE 16\n"));
        assert!(text.contains("LUT_1D_INPUT_RANGE 0 16\n"), "{text}");
        assert!(text.contains("LUT_3D_SIZE 3\n"));
        let rows: Vec<Vec<f32>> = text
            .lines()
            .filter(|l| l.starts_with(|c: char| c.is_ascii_digit() || c == '-'))
            .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
            .collect();
        assert_eq!(rows.len(), 16 + 27);
        let lut = e.lut3d().unwrap();
        // Row 1 of the 3D table is (r, g, b) = (1, 0, 0): stored at (1·3 + 0)·3 + 0 = 9.
        assert_eq!(rows[16 + 1], lut.values[9].to_vec());
        assert_eq!(rows[16 + 3], lut.values[3].to_vec());
        assert_eq!(rows[16 + 9], lut.values[1].to_vec());
    }
}
