//! Training data: camera RGB and reference XYZ per patch, simulated ([`crate::spectral::simulate`])
//! or measured by a user ([`TrainingSet::read_measured`]), and patch selection (`--patches`).

use crate::colorimetry::lab_to_xyz;
pub use crate::training_set::{CaptureProvenance, Provenance, TrainingSet};
use std::path::Path;

/// Errors from reading measured training data or selecting patches.
#[derive(Debug, thiserror::Error)]
pub enum TrainingError {
    /// A training data file could not be read.
    #[error("{source_name}: cannot read: {err}")]
    Io {
        /// The file the training data came from.
        source_name: String,
        /// The I/O error.
        err: std::io::Error,
    },
    /// A training data file is empty.
    #[error("{source_name}: the file is empty")]
    Empty {
        /// The file the training data came from.
        source_name: String,
    },
    /// A training data file's header is not one of the accepted forms.
    #[error(
        "{source_name}: header must be `label,R,G,B,X,Y,Z` or `label,R,G,B,L,a,b`, found `{found}`"
    )]
    Header {
        /// The file the training data came from.
        source_name: String,
        /// The header line found.
        found: String,
    },
    /// The file names no white (no `# white:` line) and none was given: X,Y,Z relative to an
    /// unknown white cannot be compared in Lab, nor adapted to an output space.
    #[error(
        "{source_name}: the file does not say which white its values are relative to (no `# white:` line); give the white (X,Y,Z, x,y, D50 or an illuminant name)"
    )]
    NeedsWhite {
        /// The file the training data came from.
        source_name: String,
    },
    /// The file's `# white:` line and the white given by the caller disagree.
    #[error(
        "{source_name}: the file says its white is {} but {} was given; drop one or make them agree",
        fmt_white(*file), fmt_white(*given)
    )]
    WhiteConflict {
        /// The file the training data came from.
        source_name: String,
        /// The white (XYZ) named by the file's `# white:` line.
        file: [f64; 3],
        /// The white (XYZ) given by the caller.
        given: [f64; 3],
    },
    /// A malformed CSV: a ragged row, a cell that is not a finite number.
    #[error(transparent)]
    Csv(#[from] crate::csv_table::CsvError),
    /// Two patches of a training data file have the same label.
    #[error("{source_name}: line {line}: duplicate label `{label}`")]
    DuplicateLabel {
        /// The file the training data came from.
        source_name: String,
        /// The line number of the second occurrence.
        line: usize,
        /// The repeated label.
        label: String,
    },
    /// A training data file has a header but no patches.
    #[error("{source_name}: has no patches")]
    NoRows {
        /// The file the training data came from.
        source_name: String,
    },
    /// The selection does not match the data (a label it lacks, a rectangle partly missing).
    #[error("invalid patch selection `{spec}`: {why}")]
    Patches {
        /// The selection as given.
        spec: String,
        /// Why it does not match the data.
        why: String,
    },
    /// The selection is malformed whatever the data (a usage error).
    #[error("invalid patch selection `{spec}`: {why}")]
    PatchSpec {
        /// The selection as given.
        spec: String,
        /// What is wrong with it.
        why: String,
    },
    /// A malformed white (given, or on a `# white:` line), or a second `# white:` line.
    #[error("invalid white `{spec}`: {why}")]
    White {
        /// The white as given.
        spec: String,
        /// What is wrong with it.
        why: String,
    },
    /// A white named by an illuminant file that cannot be read or used.
    #[error("white `{spec}`: {err}")]
    WhiteIlluminant {
        /// The white as given (an illuminant name or file).
        spec: String,
        /// Why the illuminant could not be read or used.
        err: crate::spectral::SpectralError,
    },
}

impl TrainingError {
    /// True for a malformed patch selection or white point, a white that is missing or that
    /// contradicts the file's.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            TrainingError::PatchSpec { .. }
                | TrainingError::White { .. }
                | TrainingError::NeedsWhite { .. }
                | TrainingError::WhiteConflict { .. }
        )
    }
}

impl TrainingSet {
    /// The patches at `indices`, in that order.
    ///
    /// # Panics
    /// If an index is out of range (`indices` are the caller's own, like a slice index; a
    /// selection from user input goes through [`select`](Self::select), which checks it).
    pub fn subset(&self, indices: &[usize]) -> TrainingSet {
        let mut out = TrainingSet {
            labels: indices.iter().map(|&i| self.labels[i].clone()).collect(),
            rgb: indices.iter().map(|&i| self.rgb[i]).collect(),
            xyz: indices.iter().map(|&i| self.xyz[i]).collect(),
            white_xyz: self.white_xyz,
            white_rgb: self.white_rgb,
            provenance: self.provenance.clone(),
        };
        // A capture's recorded patches follow the selection (a model carries what it was fitted on).
        if out
            .provenance
            .capture
            .as_ref()
            .is_some_and(|c| c.training.is_some())
        {
            out.record_patches();
        }
        out
    }

    /// Keeps the patches chosen by `spec` (see `select_patches`: labels, `A1,B2`, ranges `B2:M9`, `all`).
    pub fn select(&self, spec: &str) -> Result<TrainingSet, TrainingError> {
        let idx = select_patches(&self.labels, spec)?;
        let mut out = self.subset(&idx);
        if spec.trim() != "all" {
            out.provenance.patches = Some(spec.trim().to_string());
        }
        Ok(out)
    }

    /// Reads measured patches: a CSV with header `label,R,G,B,X,Y,Z` or `label,R,G,B,L,a,b`, the
    /// values relative to a white that the file names on a comment line before the header,
    /// `# white: X,Y,Z` (any form [`parse_white`] reads; `chart extract` writes it), or that the
    /// caller gives (`white`, XYZ). One of the two is needed — there is no silent default — and
    /// when both are there they must agree (to 1e-6 of Y).
    pub fn read_measured(
        path: &Path,
        white: Option<[f64; 3]>,
    ) -> Result<TrainingSet, TrainingError> {
        let source_name = path.display().to_string();
        let text = crate::limits::read_text(path).map_err(|err| TrainingError::Io {
            source_name: source_name.clone(),
            err,
        })?;
        Self::parse_measured(&text, &source_name, white)
    }

    /// [`read_measured`](Self::read_measured) on text.
    pub fn parse_measured(
        text: &str,
        source_name: &str,
        white: Option<[f64; 3]>,
    ) -> Result<TrainingSet, TrainingError> {
        let src = || source_name.to_string();
        let file_white = white_in_header(text, source_name)?;
        let white_xyz = match (file_white, white) {
            (Some(f), Some(g)) if !same_white(f, g) => {
                return Err(TrainingError::WhiteConflict {
                    source_name: src(),
                    file: f,
                    given: g,
                })
            }
            (Some(f), _) => f,
            (None, Some(g)) => g,
            (None, None) => return Err(TrainingError::NeedsWhite { source_name: src() }),
        };
        let mut table = crate::csv_table::Table::new(text, source_name)?
            .ok_or_else(|| TrainingError::Empty { source_name: src() })?;
        let cols = &table.header;
        let is = |names: [&str; 7]| {
            cols.len() == 7
                && cols
                    .iter()
                    .zip(names)
                    .all(|(c, n)| c.eq_ignore_ascii_case(n))
        };
        let lab = if is(["label", "R", "G", "B", "X", "Y", "Z"]) {
            false
        } else if cols.len() == 7
            && cols[0].eq_ignore_ascii_case("label")
            && cols[1..4]
                .iter()
                .zip(["R", "G", "B"])
                .all(|(c, n)| c.eq_ignore_ascii_case(n))
            && cols[4] == "L"
            && cols[5] == "a"
            && cols[6] == "b"
        {
            true
        } else {
            return Err(TrainingError::Header {
                source_name: src(),
                found: table.header_text(),
            });
        };
        // Room for every row up front (a row is at least 14 bytes, so a text of blank lines
        // reserves no more than a text of rows would need): no regrowth while 10⁶ rows load.
        let rows = (text.bytes().filter(|&b| b == b'\n').count() + 1).min(text.len() / 14 + 1);
        let mut labels: Vec<String> = Vec::with_capacity(rows);
        let mut lines: Vec<usize> = Vec::with_capacity(rows);
        let mut rgb = Vec::with_capacity(rows);
        let mut xyz = Vec::with_capacity(rows);
        let mut failed = None;
        loop {
            let row = match table.next_record() {
                Ok(Some(row)) => row,
                Ok(None) => break,
                Err(e) => {
                    failed = Some(e);
                    break;
                }
            };
            let parsed = row.expect_len(7).and_then(|()| {
                let mut v = [0.0; 6];
                for (k, v) in v.iter_mut().enumerate() {
                    *v = row.number(k + 1)?;
                }
                Ok((row.text(0)?.to_string(), v))
            });
            match parsed {
                Ok((label, v)) => {
                    labels.push(label);
                    lines.push(row.line);
                    rgb.push([v[0], v[1], v[2]]);
                    let t = [v[3], v[4], v[5]];
                    xyz.push(if lab { lab_to_xyz(t, white_xyz) } else { t });
                }
                Err(e) => {
                    failed = Some(e);
                    break;
                }
            }
        }
        // Duplicates among the rows read (before the failed row, if one failed: the first error
        // in the file's order is the one reported). A hash set, not a scan of the labels so far:
        // 10⁶ rows load in about a second.
        let mut seen: std::collections::HashSet<&str> =
            std::collections::HashSet::with_capacity(labels.len());
        for (label, &line) in labels.iter().zip(&lines) {
            if !seen.insert(label) {
                return Err(TrainingError::DuplicateLabel {
                    source_name: src(),
                    line,
                    label: label.clone(),
                });
            }
        }
        drop(seen);
        if let Some(e) = failed {
            return Err(e.into());
        }
        if labels.is_empty() {
            return Err(TrainingError::NoRows { source_name: src() });
        }
        Ok(TrainingSet {
            labels,
            rgb,
            xyz,
            white_xyz,
            white_rgb: None,
            provenance: Provenance {
                source: "measured".into(),
                reflectances: Some(source_name.to_string()),
                ..Default::default()
            },
        })
    }
}

/// `X,Y,Z` as the patch CSV's `# white:` line and messages write it (shortest round-trip
/// decimals, so reading it back gives the same numbers).
pub fn fmt_white(w: [f64; 3]) -> String {
    format!("{},{},{}", w[0], w[1], w[2])
}

/// The comment line that names a patch CSV's white, e.g. `# white: 96.42,100,82.49\n`.
pub fn white_line(w: [f64; 3]) -> String {
    format!("# white: {}\n", fmt_white(w))
}

/// Two whites that are the same to 1e-6 of their Y.
fn same_white(a: [f64; 3], b: [f64; 3]) -> bool {
    let tol = 1e-6 * a[1].abs().max(b[1].abs());
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
}

/// The white named by a `# white: …` comment line before a CSV's header (`None` without one).
/// Two such lines, or one that does not parse, are errors.
pub(crate) fn white_in_header(
    text: &str,
    source_name: &str,
) -> Result<Option<[f64; 3]>, TrainingError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut found: Option<[f64; 3]> = None;
    for line in text.lines() {
        let t = line.trim();
        if t.is_empty() {
            continue;
        }
        let Some(comment) = t.strip_prefix('#') else {
            break; // the header: the white line comes before it
        };
        let comment = comment.trim_start();
        let Some(rest) = comment
            .get(..6)
            .filter(|k| k.eq_ignore_ascii_case("white:"))
            .map(|_| &comment[6..])
        else {
            continue;
        };
        let w = parse_white(rest.trim()).map_err(|e| TrainingError::White {
            spec: rest.trim().to_string(),
            why: format!("{source_name}: `# white:` line: {e}"),
        })?;
        if found.is_some() {
            return Err(TrainingError::White {
                spec: rest.trim().to_string(),
                why: format!("{source_name}: a second `# white:` line"),
            });
        }
        found = Some(w);
    }
    Ok(found)
}

/// The D50 white of chart makers' tables and ICC profiles (CIE 1931 2°, x 0.345703,
/// y 0.358539), `Y = 100`.
pub fn d50_white() -> [f64; 3] {
    crate::colorimetry::xyy_to_xyz(0.345703, 0.358539, 100.0)
}

/// Parses a white point, the one syntax every white of the crate takes:
/// * `X,Y,Z` — three finite numbers, Y > 0 (e.g. `96.42,100,82.49`);
/// * `x,y` — a chromaticity (0 < x, 0 < y, x + y < 1), at `Y = 100`;
/// * `D50` — x 0.345703, y 0.358539, Y = 100;
/// * a built-in illuminant name (`D65`, `FL7`, `TL865`, …) or an illuminant CSV file: the
///   perfect white under it on the default grid, `Y = 100`.
pub fn parse_white(spec: &str) -> Result<[f64; 3], TrainingError> {
    let spec_t = spec.trim();
    let err = |why: String| TrainingError::White {
        spec: spec.to_string(),
        why,
    };
    if spec_t.contains(',') {
        let v: Vec<f64> = spec_t
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| err("expected X,Y,Z or x,y (numbers)".into()))?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(err("values must be finite".into()));
        }
        return match v[..] {
            [x, y, z] if y > 0.0 => Ok([x, y, z]),
            [_, _, _] => Err(err("Y must be positive".into())),
            [x, y] if x > 0.0 && y > 0.0 && x + y < 1.0 => {
                Ok(crate::colorimetry::xyy_to_xyz(x, y, 100.0))
            }
            [_, _] => Err(err(
                "a chromaticity x,y needs 0 < x, 0 < y, x + y < 1".into()
            )),
            _ => Err(err("expected X,Y,Z or x,y (numbers)".into())),
        };
    }
    if spec_t.eq_ignore_ascii_case("d50") {
        return Ok(d50_white());
    }
    if spec_t.is_empty() {
        return Err(err(
            "expected X,Y,Z, x,y, D50 or an illuminant name or file".into(),
        ));
    }
    let file_err = |e: crate::spectral::SpectralError| TrainingError::WhiteIlluminant {
        spec: spec.to_string(),
        err: e,
    };
    let ill = crate::spectral::Illuminant::from_name_or_path(spec_t).map_err(|e| match e {
        e @ crate::spectral::SpectralError::UnknownName { .. } => {
            err(format!("{e} (or give X,Y,Z, x,y or D50)"))
        }
        e => file_err(e),
    })?;
    crate::spectral::white_xyz(&ill, &crate::spectral::Grid::default()).map_err(file_err)
}

/// Splits a chart label such as `B12` into its column letters and row number.
fn split_label(label: &str) -> Option<(&str, u32)> {
    let pos = label.find(|c: char| c.is_ascii_digit())?;
    let (col, row) = label.split_at(pos);
    if col.is_empty() || !col.chars().all(|c| c.is_ascii_alphabetic()) {
        return None;
    }
    Some((col, row.parse().ok()?))
}

/// Column letters as a number: A = 1, …, Z = 26, AA = 27; `None` past `u32` (checked, so a
/// label such as `AAAAAAAA1` is an error, not an overflow).
fn column_index(col: &str) -> Option<u32> {
    col.chars().try_fold(0u32, |acc, c| {
        acc.checked_mul(26)?
            .checked_add(c.to_ascii_uppercase() as u32 - 'A' as u32 + 1)
    })
}

/// The most patches a `B2:M9` rectangle may hold (charts have hundreds).
pub(crate) const MAX_RECTANGLE: u64 = 1 << 20;

/// The label of the one patch `spec` names (for `--white-patch`): the full label (`19 white
/// 9.5`), its number (`19`, the label's first word), or its name (`white 9.5`, or a word of it
/// that only one label has: `white`); case-insensitive. An error lists the candidates when
/// none or several match.
pub fn resolve_patch(labels: &[String], spec: &str) -> Result<String, TrainingError> {
    let s = spec.trim().to_lowercase();
    let err = |why: String| TrainingError::Patches {
        spec: spec.to_string(),
        why,
    };
    if let Some(l) = labels.iter().find(|l| l.to_lowercase() == s) {
        return Ok(l.clone());
    }
    let number = |l: &str| l.split_whitespace().next().unwrap_or("").to_lowercase();
    let name = |l: &str| {
        l.split_once(' ')
            .map(|(_, n)| n.trim().to_lowercase())
            .unwrap_or_default()
    };
    let tiers: [&dyn Fn(&str) -> bool; 3] = [
        &|l| number(l) == s || number(l).trim_start_matches('0') == s.trim_start_matches('0'),
        &|l| name(l) == s,
        &|l| name(l).split_whitespace().any(|w| w == s),
    ];
    for matches in tiers {
        let found: Vec<&String> = labels.iter().filter(|l| matches(l)).collect();
        match found.len() {
            0 => continue,
            1 => return Ok(found[0].clone()),
            _ => {
                return Err(err(format!(
                    "it names {} patches ({}): give the full label",
                    found.len(),
                    found
                        .iter()
                        .map(|l| l.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )))
            }
        }
    }
    Err(err(format!(
        "no training patch has that label, number or name (the patches: {}{})",
        labels
            .iter()
            .take(30)
            .cloned()
            .collect::<Vec<_>>()
            .join(", "),
        if labels.len() > 30 { ", …" } else { "" }
    )))
}

/// Chooses patches by `spec`, returning indices into `labels` in the labels' own order.
///
/// * `all` — every patch;
/// * `B2:M9` — a rectangle of chart labels: columns B..M × rows 2..9 (every label in it must exist);
/// * `A1,C3,patch7` — a list of labels.
pub(crate) fn select_patches(labels: &[String], spec: &str) -> Result<Vec<usize>, TrainingError> {
    let spec_t = spec.trim();
    let err = |why: String| TrainingError::Patches {
        spec: spec.to_string(),
        why,
    };
    let malformed = |why: String| TrainingError::PatchSpec {
        spec: spec.to_string(),
        why,
    };
    if spec_t.eq_ignore_ascii_case("all") {
        return Ok((0..labels.len()).collect());
    }
    if let Some((a, b)) = spec_t.split_once(':') {
        let (ca, ra) = split_label(a.trim())
            .ok_or_else(|| malformed(format!("`{a}` is not a chart label like B2")))?;
        let (cb, rb) = split_label(b.trim())
            .ok_or_else(|| malformed(format!("`{b}` is not a chart label like M9")))?;
        let too_long =
            |l: &str| malformed(format!("`{l}`: the column letters are too many to count"));
        let c0 = column_index(ca).ok_or_else(|| too_long(a.trim()))?;
        let c1 = column_index(cb).ok_or_else(|| too_long(b.trim()))?;
        let (c0, c1) = (c0.min(c1), c0.max(c1));
        let (r0, r1) = (ra.min(rb), ra.max(rb));
        // In u64: both spans are at most 2^32, so the product cannot overflow.
        let expected = (u64::from(c1 - c0) + 1) * (u64::from(r1 - r0) + 1);
        if expected > MAX_RECTANGLE {
            return Err(malformed(format!(
                "the rectangle holds {expected} patches, more than the limit of {MAX_RECTANGLE}"
            )));
        }
        if expected > labels.len() as u64 {
            return Err(err(format!(
                "the rectangle holds {expected} patches but the data has only {} patches",
                labels.len()
            )));
        }
        let idx: Vec<usize> = labels
            .iter()
            .enumerate()
            .filter(|(_, l)| {
                split_label(l).is_some_and(|(c, r)| {
                    column_index(c).is_some_and(|c| c >= c0 && c <= c1 && r >= r0 && r <= r1)
                })
            })
            .map(|(i, _)| i)
            .collect();
        if idx.len() as u64 != expected {
            return Err(err(format!(
                "the rectangle holds {expected} patches but the data has {} of them (labels must be column letter + row number, e.g. B2)",
                idx.len()
            )));
        }
        return Ok(idx);
    }
    let by_name: std::collections::HashMap<&str, usize> = labels
        .iter()
        .enumerate()
        .map(|(i, l)| (l.as_str(), i))
        .collect();
    let mut idx = Vec::new();
    let mut listed = std::collections::HashSet::new();
    for name in spec_t.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let i = *by_name
            .get(name)
            .ok_or_else(|| err(format!("no patch named `{name}`")))?;
        if !listed.insert(i) {
            return Err(err(format!("`{name}` is listed twice")));
        }
        idx.push(i);
    }
    if idx.is_empty() {
        return Err(err("no patches named".into()));
    }
    idx.sort_unstable();
    Ok(idx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sg_labels() -> Vec<String> {
        let mut v = Vec::new();
        for c in 'A'..='N' {
            for r in 1..=10 {
                v.push(format!("{c}{r}"));
            }
        }
        v
    }

    /// `--white-patch` takes the label, the number or the name (issue 36: `19` was refused).
    #[test]
    fn a_patch_is_named_by_label_number_or_name() {
        let cc24: Vec<String> = [
            "01 dark skin",
            "18 cyan",
            "19 white 9.5",
            "20 neutral 8",
            "21 neutral 6.5",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        for spec in ["19 white 9.5", "19", "white 9.5", "white", "WHITE", " 19 "] {
            assert_eq!(
                resolve_patch(&cc24, spec).unwrap(),
                "19 white 9.5",
                "{spec}"
            );
        }
        assert_eq!(resolve_patch(&cc24, "1").unwrap(), "01 dark skin");
        let e = resolve_patch(&cc24, "neutral").unwrap_err().to_string();
        assert!(
            e.contains("20 neutral 8") && e.contains("21 neutral 6.5"),
            "{e}"
        );
        let e = resolve_patch(&cc24, "magenta").unwrap_err().to_string();
        assert!(e.contains("no training patch"), "{e}");
        assert_eq!(resolve_patch(&sg_labels(), "d4").unwrap(), "D4");
    }

    #[test]
    fn rectangle_selects_inner_96() {
        let l = sg_labels();
        let idx = select_patches(&l, "B2:M9").unwrap();
        assert_eq!(idx.len(), 96);
        assert_eq!(l[idx[0]], "B2");
        assert_eq!(l[idx[95]], "M9");
        assert!(!idx
            .iter()
            .any(|&i| l[i].starts_with('A') || l[i].ends_with("10")));
        assert_eq!(select_patches(&l, "all").unwrap().len(), 140);
        assert_eq!(select_patches(&l, "C3, A1").unwrap(), vec![0, 22]);
        assert!(select_patches(&l, "B2:P9").is_err());
        assert!(select_patches(&l, "Z9").is_err());
        assert!(select_patches(&l, "A1,A1").is_err());
    }

    #[test]
    fn measured_xyz_and_lab() {
        let t = "label,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\np2,0.3,0.2,0.1,30,20,10\n";
        // No white named, none given: refused, not assumed.
        let e = TrainingSet::parse_measured(t, "m.csv", None).unwrap_err();
        assert!(matches!(e, TrainingError::NeedsWhite { .. }), "{e}");
        let d65 = crate::colorimetry::D65_WHITE_XYZ;
        let ts = TrainingSet::parse_measured(t, "m.csv", Some(d65)).unwrap();
        assert_eq!(ts.len(), 2);
        assert_eq!(ts.xyz[1], [30.0, 20.0, 10.0]);
        assert_eq!(ts.white_xyz, d65);
        let t = "label,R,G,B,L,a,b\np1,0.1,0.2,0.3,100,0,0\n";
        assert!(TrainingSet::parse_measured(t, "m.csv", None)
            .unwrap_err()
            .to_string()
            .contains("white"));
        let w = [95.047, 100.0, 108.883];
        let ts = TrainingSet::parse_measured(t, "m.csv", Some(w)).unwrap();
        for k in 0..3 {
            assert!((ts.xyz[0][k] - w[k]).abs() < 1e-9);
        }
        let bad = "label,R,G,B,X,Y,Z\np1,0.1,x,0.3,10,20,30\n";
        let e = TrainingSet::parse_measured(bad, "m.csv", Some(d65))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 2") && e.contains("`G`"), "{e}");
        let bad = "label,R,G,B,X,Y\n";
        assert!(TrainingSet::parse_measured(bad, "m.csv", None).is_err());
        let bad = "label,R,G,B,X,Y,Z\n";
        assert!(TrainingSet::parse_measured(bad, "m.csv", None).is_err());
    }

    #[test]
    fn white_parse() {
        assert_eq!(parse_white("95,100,108").unwrap(), [95.0, 100.0, 108.0]);
        assert!(parse_white("95,0,108").is_err());
        assert!(parse_white("95,100").is_err()); // not a chromaticity
        assert!(parse_white("1,2,3,4").is_err());
        assert!(parse_white("nan,100,1").is_err());
        // x,y at Y = 100.
        let w = parse_white("0.3127, 0.329").unwrap();
        assert!(
            (w[1] - 100.0).abs() < 1e-12 && (w[0] - 95.0456).abs() < 1e-3,
            "{w:?}"
        );
        // D50 in any case, and the same white as its chromaticity.
        let d50 = parse_white("d50").unwrap();
        assert_eq!(d50, parse_white("0.345703,0.358539").unwrap());
        assert!(
            (d50[0] - 96.42).abs() < 0.01 && (d50[2] - 82.49).abs() < 0.01,
            "{d50:?}"
        );
        // Every built-in illuminant, by name.
        for name in ["D65", "FL3.15", "FL7", "TL865", "LED-B5", "LED-YAG", "d65"] {
            let w = parse_white(name).unwrap();
            assert!((w[1] - 100.0).abs() < 1e-9, "{name}: {w:?}");
        }
        // Computed daylights are illuminants too (D55); an unknown name is refused with the forms.
        assert!((parse_white("D55").unwrap()[1] - 100.0).abs() < 1e-9);
        let e = parse_white("not-a-light").unwrap_err().to_string();
        assert!(e.contains("not-a-light") && e.contains("X,Y,Z"), "{e}");
    }

    #[test]
    fn the_white_line_is_read_back_exactly() {
        let w = d50_white();
        let t = format!(
            "# patches read by nsrm\n{}label,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\n",
            white_line(w)
        );
        let ts = TrainingSet::parse_measured(&t, "m.csv", None).unwrap();
        assert_eq!(ts.white_xyz, w);
        // The same white given again is fine; another one is a conflict.
        assert!(TrainingSet::parse_measured(&t, "m.csv", Some(w)).is_ok());
        let d65 = crate::colorimetry::D65_WHITE_XYZ;
        let e = TrainingSet::parse_measured(&t, "m.csv", Some(d65)).unwrap_err();
        assert!(matches!(e, TrainingError::WhiteConflict { .. }), "{e}");
        // Any white form on the line; a name is read as --white reads it.
        let t = "#white: D65\nlabel,R,G,B,L,a,b\np1,0.1,0.2,0.3,100,0,0\n";
        let ts = TrainingSet::parse_measured(t, "m.csv", None).unwrap();
        assert_eq!(ts.white_xyz, parse_white("D65").unwrap());
        // A white line after the header is a plain comment; two before it, or a bad one, are errors.
        let t = "label,R,G,B,X,Y,Z\n# white: D50\np1,0.1,0.2,0.3,10,20,30\n";
        assert!(TrainingSet::parse_measured(t, "m.csv", None).is_err());
        let t = "# white: D50\n# white: D65\nlabel,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\n";
        assert!(TrainingSet::parse_measured(t, "m.csv", None).is_err());
        let t = "# white: 1,0,1\nlabel,R,G,B,X,Y,Z\np1,0.1,0.2,0.3,10,20,30\n";
        let e = TrainingSet::parse_measured(t, "m.csv", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.csv") && e.contains("white"), "{e}");
    }
}
