//! The spectral data built into the binary (`assets/`, see `assets/SOURCES.md`).

use super::{parse_csv, SpectralTable};

/// Built-in cameras: (name, CSV text).
pub(crate) const CAMERAS: &[(&str, &str)] = &[(
    "nikon-d5100",
    include_str!("../../assets/nikon_d5100_npl_darrodi2015.csv"),
)];

/// Built-in illuminants: (name, CSV text).
pub(crate) const ILLUMINANTS: &[(&str, &str)] = &[
    ("D65", include_str!("../../assets/illuminant_D65.csv")),
    ("FL3.15", include_str!("../../assets/illuminant_FL3.15.csv")),
    ("FL7", include_str!("../../assets/illuminant_FL7.csv")),
    ("FL2", include_str!("../../assets/illuminant_FL2.csv")),
    ("FL11", include_str!("../../assets/illuminant_FL11.csv")),
    ("LED-B3", include_str!("../../assets/illuminant_LED-B3.csv")),
    ("TL865", include_str!("../../assets/illuminant_TL865.csv")),
    ("LED-B5", include_str!("../../assets/illuminant_LED-B5.csv")),
    (
        "LED-YAG",
        include_str!("../../assets/illuminant_LED-YAG.csv"),
    ),
];

/// Built-in reflectance sets: (name, CSV text).
pub(crate) const REFLECTANCES: &[(&str, &str)] = &[
    (
        "rawtoaces-190",
        include_str!("../../assets/rawtoaces_190_patches.csv"),
    ),
    (
        "cc24",
        include_str!("../../assets/cc24_babelcolor_average.csv"),
    ),
];

fn lookup(list: &[(&str, &str)], name: &str) -> Option<SpectralTable> {
    list.iter()
        .find(|(n, _)| n.eq_ignore_ascii_case(name))
        .map(|(n, text)| {
            parse_csv(text, &format!("builtin:{n}")).expect("built-in data parses (tested)")
        })
}

/// A built-in camera by name (case-insensitive).
pub(crate) fn builtin_camera(name: &str) -> Option<SpectralTable> {
    lookup(CAMERAS, name)
}

/// A built-in illuminant by name (case-insensitive).
pub(crate) fn builtin_illuminant(name: &str) -> Option<SpectralTable> {
    lookup(ILLUMINANTS, name)
}

/// A built-in reflectance set by name (case-insensitive).
pub(crate) fn builtin_reflectances(name: &str) -> Option<SpectralTable> {
    lookup(REFLECTANCES, name)
}

/// The CIE 1931 2° standard observer colour-matching functions x̄, ȳ, z̄ (360–830 nm, 1 nm):
/// colorimetry's table (`colorimetry::observer`) as a spectral table.
pub(crate) fn cie1931_cmf() -> SpectralTable {
    let o = crate::colorimetry::observer::cie1931();
    SpectralTable {
        source_name: crate::colorimetry::observer::SOURCE.to_string(),
        wavelengths: o.wavelengths.clone(),
        names: o.names.to_vec(),
        values: o.values.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_parses() {
        for list in [CAMERAS, ILLUMINANTS, REFLECTANCES] {
            for (name, text) in list {
                parse_csv(text, name).unwrap();
            }
        }
        assert_eq!(cie1931_cmf().names.len(), 3);
        // Colorimetry's observer is the asset, read as every spectral CSV is read.
        let asset = include_str!("../../assets/cie1931_2deg_cmf.csv");
        assert_eq!(
            cie1931_cmf(),
            parse_csv(asset, "builtin:cie1931_2deg").unwrap()
        );
        assert_eq!(
            builtin_reflectances("rawtoaces-190").unwrap().names.len(),
            190
        );
        assert_eq!(builtin_reflectances("CC24").unwrap().names.len(), 24);
        assert_eq!(builtin_camera("nikon-d5100").unwrap().names.len(), 3);
        for (n, _) in ILLUMINANTS {
            assert_eq!(builtin_illuminant(n).unwrap().names.len(), 1);
        }
    }
}
