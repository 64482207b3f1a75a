//! Property tests of the spectral CSV parser (crate-private; once in `tests/all/parsers_fuzz.rs`):
//! it never panics, whatever it is given, and a mutated valid file is either accepted, well formed,
//! or refused with an error.

use super::parse_csv;
use crate::kit::mutate;
use proptest::prelude::*;

const SPECTRAL: &str = "wavelength_nm,a,b\n400,0.1,0.2\n410,0.3,0.4\n420,0.5,0.6\n";

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn spectral_csv_never_panics(text in ".{0,200}") {
        let _ = parse_csv(&text, "fuzz.csv");
    }

    #[test]
    fn mutated_spectral_csv_is_accepted_or_refused(edits in prop::collection::vec((0usize..1000, any::<u8>()), 1..6)) {
        let text = mutate(SPECTRAL, &edits);
        if let Ok(t) = parse_csv(&text, "fuzz.csv") {
            // Whatever was accepted is well formed.
            prop_assert!(t.wavelengths.windows(2).all(|w| w[0] < w[1]));
            prop_assert!(t.values.iter().all(|c| c.len() == t.wavelengths.len()));
            prop_assert!(t.values.iter().flatten().all(|v| v.is_finite()));
        }
    }

    /// (From `tests/all/harden_fuzz.rs`: `Grid::parse`, `len` and `wavelengths` are crate-private.)
    #[test]
    fn grids_parse_or_refuse(spec in "[0-9.e:+-]{0,30}|\\PC{0,20}") {
        if let Ok(g) = super::Grid::parse(&spec) {
            prop_assert!(g.len() <= 100_000);
            prop_assert_eq!(g.wavelengths().len(), g.len());
        }
    }
}
