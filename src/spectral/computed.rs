//! Illuminants computed from a formula rather than read from a table: CIE standard illuminant A,
//! Planckian radiators (`P3200`) and CIE daylight at any temperature (`D50`, `D55`, `D75`,
//! `D4000`; D65 itself is the tabulated built-in).

use super::SpectralTable;

const DAYLIGHT_BASIS: &str = include_str!("../../assets/cie_daylight_basis.csv");

/// The names [`computed_illuminant`] takes, with their ranges (for messages).
pub(crate) static NAMES_AND_RANGES: std::sync::LazyLock<String> = std::sync::LazyLock::new(|| {
    use crate::colorimetry::temperature::{DAYLIGHT_FROM, MAX_CCT, MIN_CCT};
    format!(
        "A (StdA), D50, D55, D75, D<kelvin> (CIE daylight, {DAYLIGHT_FROM}..={MAX_CCT} K), \
         P<kelvin> (Planckian, {MIN_CCT}..={MAX_CCT} K)"
    )
});

/// An illuminant named by formula, or `None` for a name that is not one: `A` / `StdA` (CIE 15's
/// definition), `P<kelvin>` (Planck, 1000..=25000 K), `D<2 digits>` (CIE daylight at the digits ×
/// 100 × 1.4388/1.4380 K: D50, D55, D75) and `D<kelvin>` (CIE daylight, 4000..=25000 K).
pub(crate) fn computed_illuminant(name: &str) -> Option<SpectralTable> {
    let n = name.trim();
    let upper = n.to_ascii_uppercase();
    let wl: Vec<f64> = (300..=830).step_by(5).map(|w| w as f64).collect();
    let table = |values: Vec<f64>, label: &str| SpectralTable {
        source_name: format!("builtin:{label}"),
        wavelengths: wl.clone(),
        names: vec!["relative_power".into()],
        values: vec![values],
    };
    if upper == "A" || upper == "STDA" {
        // CIE 15: S_A(λ) = 100 (560/λ)^5 (e^(1.435e7/(2848·560)) − 1) / (e^(1.435e7/(2848 λ)) − 1).
        let c: f64 = 1.435e7 / 2848.0;
        let v = wl
            .iter()
            .map(|l| 100.0 * (560.0 / l).powi(5) * (c / 560.0).exp_m1() / (c / l).exp_m1())
            .collect();
        return Some(table(v, "A"));
    }
    if let Some(t) = upper.strip_prefix('P') {
        let t: f64 = t.parse().ok()?;
        if !(1000.0..=25000.0).contains(&t) {
            return None;
        }
        let c2 = 1.438_776_877e-2;
        let at = |l: f64| (l * 1e-9).powi(-5) / (c2 / (l * 1e-9 * t)).exp_m1();
        let norm = at(560.0);
        let v = wl.iter().map(|&l| 100.0 * at(l) / norm).collect();
        return Some(table(v, &format!("P{t}")));
    }
    if let Some(digits) = upper.strip_prefix('D') {
        if !digits.chars().all(|c| c.is_ascii_digit()) || digits.is_empty() {
            return None;
        }
        let v: f64 = digits.parse().ok()?;
        let t = match digits.len() {
            2 if ["50", "55", "75"].contains(&digits) => v * 100.0 * 1.4388 / 1.4380,
            4 | 5 => v,
            _ => return None,
        };
        let xy = crate::colorimetry::temperature::daylight_xy(t).ok()?;
        let basis = super::parse_csv(DAYLIGHT_BASIS, "builtin:cie_daylight_basis")
            .expect("built-in data parses (tested)");
        let (x, y) = (xy[0], xy[1]);
        let m = 0.0241 + 0.2562 * x - 0.7341 * y;
        let m1 = (-1.3515 - 1.7703 * x + 5.9114 * y) / m;
        let m2 = (0.0300 - 31.4424 * x + 30.0717 * y) / m;
        let v = wl
            .iter()
            .map(|&l| basis.value_at(0, l) + m1 * basis.value_at(1, l) + m2 * basis.value_at(2, l))
            .collect();
        return Some(table(v, &format!("D{digits}")));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spectral::{white_xyz, Grid, Illuminant};

    fn xy(name: &str) -> [f64; 2] {
        let ill = Illuminant::new(computed_illuminant(name).unwrap()).unwrap();
        let w = white_xyz(&ill, &Grid::parse("380:780:5").unwrap()).unwrap();
        let s = w[0] + w[1] + w[2];
        [w[0] / s, w[1] / s]
    }

    #[test]
    fn computed_lights_have_their_chromaticities() {
        // CIE 15: A 0.44757, 0.40745; D50 0.34567, 0.35850; D75 0.29902, 0.31485.
        for (name, want) in [
            ("A", [0.44757, 0.40745]),
            ("D50", [0.34567, 0.35850]),
            ("D75", [0.29902, 0.31485]),
        ] {
            let got = xy(name);
            assert!(
                (got[0] - want[0]).abs() < 5e-4 && (got[1] - want[1]).abs() < 5e-4,
                "{name}: {got:?}"
            );
        }
        let p = xy("P3200");
        let want = crate::colorimetry::temperature::planckian_xy(3200.0).unwrap();
        assert!((p[0] - want[0]).abs() < 5e-4 && (p[1] - want[1]).abs() < 5e-4);
        for bad in ["P10", "D12", "D66", "Dx", "Q5000", "P", "D3000"] {
            assert!(computed_illuminant(bad).is_none(), "{bad}");
        }
        // The message for a name out of range gives every form with its range.
        let e = Illuminant::from_name_or_path("D3000")
            .unwrap_err()
            .to_string();
        for want in [
            "`D3000`",
            "A (StdA)",
            "D50",
            "D<kelvin> (CIE daylight, 4000..=25000 K)",
            "P<kelvin> (Planckian, 1000..=25000 K)",
        ] {
            assert!(e.contains(want), "{want}: {e}");
        }
    }
}
