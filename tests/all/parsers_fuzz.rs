//! Property tests: the text parsers never panic, whatever they are given, and a mutated valid
//! file is either accepted or refused with an error (never a panic). The spectral CSV parser's
//! share is a unit test (`src/spectral/fuzz_tests.rs`): the parser is crate-private.

use nsrm::TrainingSet;
use nsrm::{fit, Kind, Model};
use proptest::prelude::*;

use crate::common::mutate;

const MEASURED: &str = "label,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\np2,0.3,0.2,0.1,30,20,10\n";

fn model_json() -> String {
    let data = nsrm::simulate_named("nikon-d5100", "D65", "cc24", &nsrm::Grid::default()).unwrap();
    fit(Kind::Nsrm, 2, &data).unwrap().to_json()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

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
            prop_assert_eq!(m.matrix().len(), 3 * m.term_names().len());
            prop_assert!(m.matrix().iter().all(|v| v.is_finite()));
        }
    }
}
