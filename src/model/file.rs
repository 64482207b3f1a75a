//! The model file: a versioned JSON document written by `nsrm fit` and read by `nsrm apply`,
//! `nsrm export-shader` and [`Model::load`].
//!
//! ```json
//! {
//!   "format": "nsrm-model", "version": 1,
//!   "kind": "nsrm", "order": 3,
//!   "terms": ["1", "r", "g", "r^2", "g^2", "r*g", "r^3", "g^3", "r*g^2", "r^2*g"],
//!   "matrix": [[...10 values...], [...], [...]],
//!   "input":  {"signal": "linear camera RGB, not white-balanced", "camera_scale": "..."},
//!             (a white-balanced NSRM adds "gains": [gR, gG, gB], multiplied into R, G, B before
//!             the terms, and is written as version 2)
//!   "output": {"space": "CIE XYZ", "xyz_scale": 100.0, "reference_white": [95.04, 100.0, 108.9]},
//!   "training": {"source": "spectral", "camera": "...", "illuminant": "...", "reflectances": "...",
//!                "grid": "400:700:10", "patches": ["patch1", ...]}
//! }
//! ```

use super::{Kind, Model, ModelError, MAX_ORDER};
use crate::training::Provenance;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The `format` field of every model file.
pub(crate) const FORMAT: &str = "nsrm-model";
/// The newest version written; files of a newer version are refused. A model is written with
/// the oldest version that holds it: 1 without input gains, 2 with them (`input.gains`, a
/// white-balanced NSRM), so builds that cannot apply gains refuse such a file by its version.
/// Version 3 is a two-illuminant file (`super::dual_illuminant`): a model document with the
/// second model added; [`Model::from_json`] refuses it with a message that says so.
pub(crate) const VERSION: u32 = 3;

/// The first version with `input.gains`.
const GAINS_VERSION: u32 = 2;

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Input {
    signal: String,
    camera_scale: String,
    /// Per-channel gains multiplied into R, G, B before the terms (version 2; absent: 1, 1, 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gains: Option<[f64; 3]>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Output {
    space: String,
    /// Y of the perfect white in the model's output.
    xyz_scale: f64,
    reference_white: [f64; 3],
}

#[derive(Debug, Serialize, Deserialize)]
struct Training {
    #[serde(flatten)]
    provenance: Provenance,
    #[serde(default)]
    patch_labels: Vec<String>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelFile {
    format: String,
    version: u32,
    kind: String,
    order: u8,
    terms: Vec<String>,
    matrix: Vec<Vec<f64>>,
    input: Input,
    output: Output,
    training: Training,
    /// How the matrix was fitted (absent in files written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fit: Option<super::fit::FitReport>,
    /// A two-illuminant file's second model and calibration record (read by
    /// `dual_illuminant::Profile`; refused here).
    #[serde(default, skip_serializing)]
    second_illuminant: Option<serde::de::IgnoredAny>,
    #[serde(default, skip_serializing, rename = "calibration_illuminants")]
    _calibration_illuminants: Option<serde::de::IgnoredAny>,
}

impl Model {
    /// The model as a JSON document (the `nsrm-model` format that `nsrm apply` reads).
    pub fn to_json(&self) -> String {
        let l = self.terms.len();
        let unit = self.has_unit_gains();
        let file = ModelFile {
            format: FORMAT.into(),
            version: if unit { 1 } else { GAINS_VERSION },
            kind: self.kind.name().into(),
            order: self.order,
            terms: self.term_names(),
            matrix: (0..3)
                .map(|i| self.matrix[i * l..(i + 1) * l].to_vec())
                .collect(),
            input: Input {
                signal: if unit {
                    "linear camera RGB, not white-balanced (raw channel ratios)".into()
                } else {
                    "linear camera RGB, not white-balanced; the model multiplies R, G, B by `gains` (the training white's response becomes 1, 1, 1) before the terms".into()
                },
                camera_scale: camera_scale(&self.provenance),
                gains: (!unit).then_some(self.input_gains),
            },
            output: Output {
                space: "CIE XYZ (1931 2°), relative to the training illuminant; apply divides by xyz_scale (the training white at the training exposure → Y = 1)".into(),
                xyz_scale: self.white_xyz[1],
                reference_white: self.white_xyz,
            },
            training: Training {
                provenance: self.provenance.clone(),
                patch_labels: self.patches.clone(),
            },
            fit: self.fit_report.clone(),
            second_illuminant: None,
            _calibration_illuminants: None,
        };
        let mut s = serde_json::to_string_pretty(&file).expect("a model serialises");
        s.push('\n');
        s
    }

    /// Parses and validates a model document; `origin` names it in errors.
    pub fn from_json(text: &str, origin: &str) -> Result<Model, ModelError> {
        let bad = |why: String| ModelError::Invalid(format!("{origin}: {why}"));
        // A UTF-8 byte-order mark (editors on Windows add one) is not JSON, but harmless.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let f: ModelFile = serde_json::from_str(text).map_err(|err| ModelError::Parse {
            path: origin.to_string(),
            err,
        })?;
        if f.second_illuminant.is_some() {
            return Err(bad(
                "the file holds two calibration illuminants (two models): read it as a two-illuminant model, which is combined for a frame's white".into(),
            ));
        }
        if f.format != FORMAT {
            return Err(bad(format!(
                "format is `{}`, expected `{FORMAT}`",
                f.format
            )));
        }
        if f.version == 0 || f.version > VERSION {
            return Err(bad(format!(
                "version {} is not supported (this build reads up to {VERSION})",
                f.version
            )));
        }
        let kind = Kind::parse(&f.kind).map_err(|e| bad(e.to_string()))?;
        if !(1..=MAX_ORDER).contains(&f.order) {
            return Err(bad(format!("order {} is out of range (1..=4)", f.order)));
        }
        if f.matrix.len() != 3 {
            return Err(bad(format!(
                "the matrix has {} rows, expected 3",
                f.matrix.len()
            )));
        }
        let order = kind.effective_order(f.order);
        let names: Vec<String> = super::terms(kind, order)
            .iter()
            .map(|t| super::term_name(kind, t))
            .collect();
        let l = names.len();
        if let Some(r) = f.matrix.iter().position(|r| r.len() != l) {
            return Err(bad(format!(
                "matrix row {r} has {} values, expected {l}",
                f.matrix[r].len()
            )));
        }
        // The columns follow the file's term list; a file whose list is this build's in another
        // order (PRM 3 and 4 before they took the paper's eq. (3) order) is converted by name.
        let columns = column_order(&f.terms, &names).ok_or_else(|| {
            bad(format!(
                "the term list {:?} does not match {kind} order {order}: {names:?}",
                f.terms
            ))
        })?;
        let flat: Vec<f64> = f
            .matrix
            .iter()
            .flat_map(|row| columns.iter().map(|&j| row[j]))
            .collect();
        let model = Model::from_matrix(kind, f.order, flat).map_err(|e| match e {
            ModelError::Invalid(why) => bad(why),
            e => e,
        })?;
        if !(f.output.xyz_scale.is_finite() && f.output.xyz_scale > 0.0) {
            return Err(bad(format!("invalid xyz_scale {}", f.output.xyz_scale)));
        }
        let model = model
            .with_white_xyz(f.output.reference_white)
            .map_err(|e| bad(e.to_string()))?;
        let gains = match f.input.gains {
            None => super::UNIT_GAINS,
            Some(_) if f.version < GAINS_VERSION => {
                return Err(bad(format!(
                    "input gains need version {GAINS_VERSION}, the file says version {}",
                    f.version
                )))
            }
            Some(g) => g,
        };
        let model = model.with_input_gains(gains).map_err(|e| match e {
            ModelError::Invalid(why) => bad(why),
            e => e,
        })?;
        if let Some(r) = &f.fit {
            if r.input_gains != gains {
                return Err(bad(format!(
                    "the fit report's input gains {:?} differ from the input gains {gains:?}",
                    r.input_gains
                )));
            }
        }
        let mut model = model.with_training(f.training.provenance, f.training.patch_labels);
        model.fit_report = f.fit;
        Ok(model)
    }

    /// Reads and validates a model file.
    pub fn load(path: &Path) -> Result<Model, ModelError> {
        let origin = path.display().to_string();
        let text = crate::limits::read_text(path).map_err(|err| ModelError::Io {
            path: origin.clone(),
            err,
        })?;
        Model::from_json(&text, &origin)
    }
}

/// The `camera_scale` line: simulated data's perfect white has G = 1; a capture's camera RGB
/// is as recorded, its perfect white at the G its neutral patches imply.
fn camera_scale(p: &Provenance) -> String {
    let what = match &p.capture {
        Some(c) if c.white_g.is_finite() => format!(
            "camera RGB as recorded in the capture: the perfect white under its light has G = {:.6} (from the neutral patches)",
            c.white_g
        ),
        Some(_) => "camera RGB as recorded in the capture".into(),
        None => "the perfect white under the training illuminant has G = 1".into(),
    };
    format!("{what}; that response (the training white at the training exposure) is what apply writes at Y = 1, with or without a frame white")
}

/// For each term of `want`, the index of the same-named term in `file`; `None` unless `file` is a
/// permutation of `want`.
fn column_order(file: &[String], want: &[String]) -> Option<Vec<usize>> {
    if file.len() != want.len() {
        return None;
    }
    let index: std::collections::HashMap<&str, usize> = file
        .iter()
        .enumerate()
        .map(|(j, n)| (n.as_str(), j))
        .collect();
    if index.len() != file.len() {
        return None; // a repeated name
    }
    want.iter()
        .map(|n| index.get(n.as_str()).copied())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Model {
        let mut m =
            Model::from_matrix(Kind::Nsrm, 3, (0..30).map(|i| i as f64 * 0.5).collect()).unwrap();
        m.white_xyz = [95.0, 100.0, 108.0];
        m.patches = vec!["a".into(), "b".into()];
        m.provenance.source = "spectral".into();
        m.provenance.illuminant = Some("builtin:D65".into());
        m
    }

    #[test]
    fn round_trip() {
        let m = model();
        let back = Model::from_json(&m.to_json(), "m.json").unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn round_trip_is_bit_exact_for_arbitrary_values() {
        let mut m = model();
        let mut x = 0.123_456_789_f64;
        for v in m.matrix.iter_mut() {
            x = (x * 3.987_654_321).fract() + 1e-3;
            *v = (x - 0.5) * 1e3 / 7.0;
        }
        let back = Model::from_json(&m.to_json(), "m.json").unwrap();
        assert_eq!(back.matrix, m.matrix);
    }

    #[test]
    fn files_in_the_old_term_order_are_converted_by_name() {
        // PRM 3 and 4 as written before the eq. (3) order: the degree-3 terms BR² and BG² were the
        // other way round.
        for (kind, order, a, b) in [
            (Kind::Prm, 3, "R^2*B", "G^2*B"),
            (Kind::Prm, 4, "R^2*B", "G^2*B"),
        ] {
            let l = super::super::terms(kind, order).len();
            let matrix = (0..3 * l).map(|i| i as f64 + 0.25).collect();
            let m = Model::from_matrix(kind, order, matrix).unwrap();
            let names = m.term_names();
            let (ia, ib) = (
                names.iter().position(|n| n == a).unwrap(),
                names.iter().position(|n| n == b).unwrap(),
            );
            assert_eq!(ib, ia + 1, "{kind}: {names:?}");
            // Rewrite the file with the two names and their columns swapped.
            let mut doc: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
            doc["terms"].as_array_mut().unwrap().swap(ia, ib);
            for row in doc["matrix"].as_array_mut().unwrap() {
                row.as_array_mut().unwrap().swap(ia, ib);
            }
            let back = Model::from_json(&doc.to_string(), "old.json").unwrap();
            assert_eq!(back.matrix, m.matrix, "{kind}");
            let rgb = [0.3, 0.5, 0.2];
            assert_eq!(back.apply_f64(rgb), m.apply_f64(rgb));
        }
    }

    #[test]
    fn input_gains_round_trip_bit_exact_as_version_2() {
        let gains = [1.0 / 0.4730123456789, 1.0, 1.0 / 0.711987654321];
        let m = model().with_input_gains(gains).unwrap();
        let text = m.to_json();
        assert!(text.contains("\"version\": 2"), "{text}");
        assert!(text.contains("\"gains\""), "{text}");
        let back = Model::from_json(&text, "m.json").unwrap();
        assert_eq!(
            back.input_gains().map(f64::to_bits),
            gains.map(f64::to_bits)
        );
        assert_eq!(back, m);
        // Unit gains: no field, version 1 (readable by builds without gains).
        let plain = model().to_json();
        assert!(plain.contains("\"version\": 1") && !plain.contains("\"gains\""));
        assert!(Model::from_json(&plain, "m.json").unwrap().has_unit_gains());
    }

    #[test]
    fn invalid_input_gains_are_refused() {
        let good = model()
            .with_input_gains([2.25, 1.0, 1.5])
            .unwrap()
            .to_json();
        assert!(good.contains("2.25,"), "{good}");
        for (bad, want) in [
            ("0.0,", "invalid input gains"),
            ("-2.0,", "invalid input gains"),
            ("1e300,", "invalid input gains"),
        ] {
            let text = good.replacen("2.25,", bad, 1);
            let e = Model::from_json(&text, "m.json").unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("m.json"), "{bad}: {e}");
        }
        // NaN is not JSON.
        let e = Model::from_json(&good.replacen("2.25,", "NaN,", 1), "m.json").unwrap_err();
        assert!(e.to_string().contains("not a model file"), "{e}");
        // Gains in a version-1 file, and on a model kind that takes none.
        let v1 = good.replace("\"version\": 2", "\"version\": 1");
        let e = Model::from_json(&v1, "m.json").unwrap_err().to_string();
        assert!(e.contains("need version 2"), "{e}");
        let lrm = Model::from_matrix(Kind::Lrm, 1, vec![0.5; 9])
            .unwrap()
            .to_json();
        let with = lrm.replace("\"version\": 1", "\"version\": 2").replace(
            "\"camera_scale\"",
            "\"gains\": [2.0, 1.0, 1.0],\n    \"camera_scale\"",
        );
        let e = Model::from_json(&with, "m.json").unwrap_err().to_string();
        assert!(e.contains("only NSRM takes input gains"), "{e}\n{with}");
        // Unit gains written out explicitly are fine.
        let unit = lrm.replace(
            "\"camera_scale\"",
            "\"gains\": [1.0, 1.0, 1.0],\n    \"camera_scale\"",
        );
        assert!(
            Model::from_json(&unit.replace("\"version\": 1", "\"version\": 2"), "m.json").is_ok()
        );
    }

    #[test]
    fn invalid_files_are_refused_clearly() {
        let good = model().to_json();
        let cases = [
            (good.replace("\"nsrm\"", "\"xyz\""), "unknown model kind"),
            (good.replace("\"order\": 3", "\"order\": 7"), "order 7"),
            (
                good.replace("\"version\": 1", "\"version\": 9"),
                "version 9",
            ),
            (good.replace("\"r^2*g\"", "\"g^2*r\""), "term list"),
            (good.replace("\"r^2*g\"", "\"r*g^2\""), "term list"),
            (good.replacen("0.5,", "NaN,", 1), "not a model file"),
            (good.replacen("0.5,", "", 1), "values"),
            ("{".to_string(), "not a model file"),
            (good.replace("nsrm-model", "other"), "format"),
        ];
        for (text, want) in cases {
            let e = Model::from_json(&text, "m.json").unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("m.json"), "{want}: {e}");
        }
        let e = Model::load(Path::new("/nonexistent/m.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot read"), "{e}");
    }

    /// Once in `tests/all/harden_inputs.rs`; in `model` (not `limits`, the bottom room) since
    /// it reads through the training and model files, which sit above the cap.
    #[test]
    fn oversized_text_inputs_are_refused_by_the_cap() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.csv");
        let f = std::fs::File::create(&big).unwrap();
        // Sparse: 65 MiB without writing them.
        f.set_len(crate::limits::MAX_TEXT_BYTES + (1 << 20))
            .unwrap();
        let e = crate::TrainingSet::read_measured(&big, None).unwrap_err();
        assert!(
            e.to_string()
                .contains("larger than the 64 MiB limit for text inputs"),
            "{e}"
        );
        assert!(e.to_string().contains("big.csv"), "{e}");
        let e = crate::Model::load(&big).unwrap_err();
        assert!(e.to_string().contains("64 MiB"), "{e}");
    }
}
