//! Property tests: the text parsers never panic, whatever they are given, and a mutated valid
//! file is either accepted or refused with an error (never a panic).

use nsrm::model::{fit, Kind, Model};
use nsrm::spectral::parse_csv;
use nsrm::TrainingSet;
use proptest::prelude::*;

const SPECTRAL: &str = "wavelength_nm,a,b\n400,0.1,0.2\n410,0.3,0.4\n420,0.5,0.6\n";
const MEASURED: &str = "label,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\np2,0.3,0.2,0.1,30,20,10\n";

fn mutate(base: &str, edits: &[(usize, u8)]) -> String {
    let mut bytes = base.as_bytes().to_vec();
    for &(pos, b) in edits {
        if bytes.is_empty() {
            break;
        }
        let i = pos % bytes.len();
        match b % 3 {
            0 => bytes[i] = b" ,\n0123456789.-eNa#x"[(b as usize / 3) % 20],
            1 => {
                bytes.remove(i);
            }
            _ => bytes.insert(i, b",\n9-"[(b as usize / 3) % 4]),
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

fn model_json() -> String {
    let data = nsrm::spectral::simulate_named(
        "nikon-d5100",
        "D65",
        "cc24",
        &nsrm::spectral::Grid::default(),
    )
    .unwrap();
    fit(Kind::Nsrm, 2, &data).unwrap().to_json()
}

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

    #[test]
    fn mutated_measured_csv_is_accepted_or_refused(edits in prop::collection::vec((0usize..1000, any::<u8>()), 1..6)) {
        let text = mutate(MEASURED, &edits);
        if let Ok(ts) = TrainingSet::parse_measured(&text, "fuzz.csv", None) {
            prop_assert!(ts.rgb.iter().flatten().chain(ts.xyz.iter().flatten()).all(|v| v.is_finite()));
        }
    }

    #[test]
    fn mutated_model_json_is_accepted_or_refused(edits in prop::collection::vec((0usize..100_000, any::<u8>()), 1..4)) {
        let text = mutate(&model_json(), &edits);
        if let Ok(m) = Model::from_json(&text, "fuzz.json") {
            prop_assert_eq!(m.matrix().len(), 3 * m.len_terms());
            prop_assert!(m.matrix().iter().all(|v| v.is_finite()));
        }
    }
}
