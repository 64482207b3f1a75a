//! Reference values of a chart: the maker's published values (built in) or a user's file
//! (CSV or CGATS), as CIE XYZ with the perfect white of the reference at `Y = 100`, in the chart's
//! cell order.

use super::{ChartError, ChartKind};
use nsrm::{lab_to_xyz, xyy_to_xyz};
use nsrm::{Concern, Param};
use std::path::Path;

/// Largest reference file read (bytes).
pub(crate) const MAX_REFERENCE_BYTES: u64 = 1 << 20;

/// XYZ of the D50 white, `Y = 100` (the white of the built-in references and the default of
/// Lab reference files).
pub(crate) fn d50_white() -> [f64; 3] {
    nsrm::d50_white()
}

/// Built-in references: (name, chart, CSV `label,x,y,Y,L,a,b`, D50, Y of the white = 1).
pub(crate) const BUILTIN: &[(&str, ChartKind, &str)] = &[
    (
        "cc24-after2014",
        ChartKind::Cc24,
        include_str!("../../../assets/chart_cc24_after2014_d50.csv"),
    ),
    (
        "cc24-before2014",
        ChartKind::Cc24,
        include_str!("../../../assets/chart_cc24_before2014_d50.csv"),
    ),
    (
        "sg-after2014",
        ChartKind::Sg,
        include_str!("../../../assets/chart_sg140_after2014_d50.csv"),
    ),
    (
        "sg-before2014",
        ChartKind::Sg,
        include_str!("../../../assets/chart_sg140_before2014_d50.csv"),
    ),
    (
        "spyder24-after2018",
        ChartKind::Spyder24,
        include_str!("../../../assets/chart_spyder24_after2018_d50.csv"),
    ),
    (
        "spyder24-before2018",
        ChartKind::Spyder24,
        include_str!("../../../assets/chart_spyder24_before2018_d50.csv"),
    ),
];

/// Reference colours of every patch of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The built-in name or the file's path.
    pub name: String,
    /// The chart the values are for.
    pub chart: ChartKind,
    /// XYZ per cell (index `r * columns + c`), perfect white `Y = 100`.
    pub xyz: Vec<[f64; 3]>,
    /// The reference white (`Y = 100`): D50 for the built-ins.
    pub white: [f64; 3],
}

impl Reference {
    /// The names of the built-in references, as `--reference` takes them.
    pub fn builtin_names() -> Vec<&'static str> {
        BUILTIN.iter().map(|b| b.0).collect()
    }

    /// A built-in reference by name, or a file (`.cie`/`.txt`/`.cgats`/`.ti3`: CGATS; else
    /// CSV). `white` is the reference white of a file's values (needed for Lab; XYZ files
    /// default to D50, the white of chart makers' tables).
    pub fn load(
        spec: &str,
        chart: ChartKind,
        white: Option<[f64; 3]>,
    ) -> Result<Reference, ChartError> {
        if let Some((name, kind, text)) = BUILTIN
            .iter()
            .find(|(n, _, _)| n.eq_ignore_ascii_case(spec))
        {
            if *kind != chart {
                return Err(ChartError::Reference(format!(
                    "reference `{name}` is for a {} chart, not {}",
                    kind.name(),
                    chart.name()
                )));
            }
            return Ok(builtin(name, chart, text));
        }
        let path = Path::new(spec);
        if !path.is_file() {
            let known: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
            return Err(ChartError::Reference(format!(
                "reference `{spec}` is neither a built-in ({}) nor a file",
                known.join(", ")
            )));
        }
        let len = std::fs::metadata(path)
            .map_err(|e| ChartError::Reference(format!("{spec}: {e}")))?
            .len();
        if len > MAX_REFERENCE_BYTES {
            return Err(ChartError::Reference(format!(
                "{spec}: {len} bytes; a reference file is at most {MAX_REFERENCE_BYTES} bytes"
            )));
        }
        let text = std::fs::read_to_string(path)
            .map_err(|e| ChartError::Reference(format!("{spec}: cannot read: {e}")))?;
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        let cgats = matches!(ext.as_str(), "cie" | "txt" | "cgats" | "ti3")
            || text.trim_start().starts_with("CGATS")
            || text.contains("BEGIN_DATA_FORMAT");
        let rows = if cgats {
            parse_cgats(&text, spec)?
        } else {
            parse_csv(&text, spec)?
        };
        from_rows(spec, chart, rows, white)
    }
}

fn builtin(name: &str, chart: ChartKind, text: &str) -> Reference {
    let mut xyz = vec![[0.0; 3]; chart.cells()];
    let mut table = nsrm::csv_table::Table::new(text, name)
        .expect("built-in reference parses (tested)")
        .expect("built-in reference has a header (tested)");
    while let Some(row) = table.next_record().expect("built-in rows (tested)") {
        let i = chart
            .index_of(row.text(0).expect("built-in labels (tested)"))
            .expect("built-in labels match (tested)");
        let v: Vec<f64> = (1..4)
            .map(|k| row.number(k).expect("built-in numbers (tested)"))
            .collect();
        xyz[i] = xyy_to_xyz(v[0], v[1], 100.0 * v[2]);
    }
    Reference {
        name: name.to_string(),
        chart,
        xyz,
        white: d50_white(),
    }
}

/// Values as read: label and three numbers, XYZ or Lab.
struct Rows {
    labels: Vec<String>,
    values: Vec<[f64; 3]>,
    lab: bool,
}

fn parse_csv(text: &str, src: &str) -> Result<Rows, ChartError> {
    let err = |why: String| ChartError::Reference(format!("{src}: {why}"));
    let mut table =
        nsrm::csv_table::Table::new(text, src)?.ok_or_else(|| err("the file is empty".into()))?;
    let cols = &table.header;
    let find = |name: &str, exact: bool| {
        cols.iter().position(|c| {
            if exact {
                c == name
            } else {
                c.eq_ignore_ascii_case(name)
            }
        })
    };
    let label = find("label", false).ok_or_else(|| err("no `label` column".into()))?;
    let (idx, lab) = match (find("X", false), find("Y", false), find("Z", false)) {
        (Some(x), Some(y), Some(z)) => ([x, y, z], false),
        _ => match (find("L", false), find("a", true), find("b", true)) {
            (Some(l), Some(a), Some(b)) => ([l, a, b], true),
            _ => {
                return Err(err(format!(
                    "header `{}`: expected `label` and `X,Y,Z` or `L,a,b` columns",
                    table.header_text()
                )))
            }
        },
    };
    let expected = cols.len();
    let mut rows = Rows {
        labels: Vec::new(),
        values: Vec::new(),
        lab,
    };
    while let Some(row) = table.next_record()? {
        row.expect_len(expected)?;
        let mut v = [0.0; 3];
        for k in 0..3 {
            v[k] = row.number(idx[k])?;
        }
        rows.labels.push(row.text(label)?.to_string());
        rows.values.push(v);
    }
    Ok(rows)
}

fn number(s: &str) -> Option<f64> {
    s.trim().parse::<f64>().ok().filter(|v| v.is_finite())
}

/// CGATS.17 text (`BEGIN_DATA_FORMAT` … `END_DATA_FORMAT`, `BEGIN_DATA` … `END_DATA`), as
/// ArgyllCMS `.cie`/`.ti3` and chart makers' reference files: `SAMPLE_ID` (or `SAMPLE_NAME`)
/// with `XYZ_X XYZ_Y XYZ_Z` or `LAB_L LAB_A LAB_B`.
fn parse_cgats(text: &str, src: &str) -> Result<Rows, ChartError> {
    let err = |why: String| ChartError::Reference(format!("{src}: {why}"));
    let mut fields: Option<Vec<String>> = None;
    let mut data: Vec<Vec<String>> = Vec::new();
    let mut state = 0; // 0 header, 1 format, 2 data
    for (n, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        match state {
            0 if line.starts_with("BEGIN_DATA_FORMAT") => {
                state = 1;
                fields = Some(Vec::new());
            }
            0 if line.starts_with("BEGIN_DATA") => state = 2,
            1 if line.starts_with("END_DATA_FORMAT") => state = 0,
            1 => fields
                .as_mut()
                .expect("set on BEGIN_DATA_FORMAT")
                .extend(line.split_whitespace().map(str::to_string)),
            2 if line.starts_with("END_DATA") => state = 3,
            2 => {
                let cells = split_cgats(line);
                let want = fields.as_ref().map_or(0, Vec::len);
                if cells.len() != want {
                    return Err(err(format!(
                        "line {}: {} fields, the data format names {want}",
                        n + 1,
                        cells.len()
                    )));
                }
                data.push(cells);
            }
            _ => {}
        }
    }
    let fields = fields.ok_or_else(|| err("no BEGIN_DATA_FORMAT section".into()))?;
    if state != 3 {
        return Err(err("no complete BEGIN_DATA … END_DATA section".into()));
    }
    let find = |n: &str| fields.iter().position(|f| f.eq_ignore_ascii_case(n));
    let id = find("SAMPLE_ID")
        .or_else(|| find("SAMPLE_NAME"))
        .ok_or_else(|| err("no SAMPLE_ID field".into()))?;
    // Prefer SAMPLE_NAME as label when both exist and SAMPLE_ID is a bare number.
    let (idx, lab) = match (find("XYZ_X"), find("XYZ_Y"), find("XYZ_Z")) {
        (Some(x), Some(y), Some(z)) => ([x, y, z], false),
        _ => match (find("LAB_L"), find("LAB_A"), find("LAB_B")) {
            (Some(l), Some(a), Some(b)) => ([l, a, b], true),
            _ => return Err(err("no XYZ_X/Y/Z or LAB_L/A/B fields".into())),
        },
    };
    let mut rows = Rows {
        labels: Vec::new(),
        values: Vec::new(),
        lab,
    };
    for (r, cells) in data.iter().enumerate() {
        let mut v = [0.0; 3];
        for k in 0..3 {
            v[k] = number(&cells[idx[k]]).ok_or_else(|| {
                err(format!(
                    "data row {}: `{}` is not a finite number",
                    r + 1,
                    cells[idx[k]]
                ))
            })?;
        }
        rows.labels.push(cells[id].clone());
        rows.values.push(v);
    }
    Ok(rows)
}

/// Splits a CGATS data line on white space, keeping "quoted strings" whole.
fn split_cgats(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut any = false;
    for ch in line.chars() {
        match ch {
            '"' => {
                quoted = !quoted;
                any = true;
            }
            c if c.is_whitespace() && !quoted => {
                if any {
                    out.push(std::mem::take(&mut cur));
                    any = false;
                }
            }
            c => {
                cur.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(cur);
    }
    out
}

/// The least lightness range (L*, the lightest patch less the darkest) and the least chroma
/// (C*ab of the most colourful patch) a chart reference must have: every real chart has a white
/// and a black patch and saturated colours; a constant or all-zero table would "match" any
/// frame and place the labels at random.
const MIN_LIGHTNESS_RANGE: f64 = 20.0;
const MIN_CHROMA: f64 = 10.0;

/// Refuses a reference whose patches cannot be told apart (all zero, constant, grey only).
fn check_not_degenerate(xyz: &[[f64; 3]], white: [f64; 3]) -> Result<(), String> {
    if xyz.iter().flatten().any(|v| !v.is_finite()) {
        return Err("a patch has a value that is not a finite number".into());
    }
    let lab: Vec<[f64; 3]> = xyz.iter().map(|v| nsrm::xyz_to_lab(*v, white)).collect();
    let (lo, hi) = lab.iter().fold((f64::MAX, f64::MIN), |(lo, hi), l| {
        (lo.min(l[0]), hi.max(l[0]))
    });
    let chroma = lab.iter().map(|l| l[1].hypot(l[2])).fold(0.0, f64::max);
    if hi - lo < MIN_LIGHTNESS_RANGE || chroma < MIN_CHROMA {
        return Err(format!(
            "its patches are nearly alike (lightness L* {lo:.1}..{hi:.1}, largest chroma \
             {chroma:.1}); a chart reference needs light and dark patches (L* range ≥ \
             {MIN_LIGHTNESS_RANGE}) and colours (chroma ≥ {MIN_CHROMA}), or its labels cannot \
             be placed"
        ));
    }
    Ok(())
}

fn from_rows(
    src: &str,
    chart: ChartKind,
    rows: Rows,
    white: Option<[f64; 3]>,
) -> Result<Reference, ChartError> {
    let err = |why: String| ChartError::Reference(format!("{src}: {why}"));
    if rows.lab && white.is_none() {
        // Lab tables of chart makers are D50; say so rather than guess silently.
        return Err(ChartError::Param {
            concern: Concern::Remedy(Param::ReferenceWhite),
            why: format!(
                "{src}: Lab values need their reference white: give it as X,Y,Z or an illuminant (D50 for X-Rite tables)"
            ),
        });
    }
    let white = white.unwrap_or_else(d50_white);
    let mut xyz: Vec<Option<[f64; 3]>> = vec![None; chart.cells()];
    let mut unknown = Vec::new();
    for (label, v) in rows.labels.iter().zip(&rows.values) {
        match chart.index_of(label) {
            Some(i) if xyz[i].is_some() => {
                return Err(err(format!("patch `{label}` is listed twice")));
            }
            Some(i) => xyz[i] = Some(*v),
            None => unknown.push(label.clone()),
        }
    }
    let labels = chart.labels();
    let missing: Vec<&str> = (0..chart.cells())
        .filter(|&i| xyz[i].is_none())
        .map(|i| labels[i].as_str())
        .collect();
    if !unknown.is_empty() || !missing.is_empty() {
        let show = |v: &[&str]| {
            let mut s = v.iter().take(8).copied().collect::<Vec<_>>().join(", ");
            if v.len() > 8 {
                s.push_str(&format!(", … ({} in all)", v.len()));
            }
            s
        };
        let unknown: Vec<&str> = unknown.iter().map(String::as_str).collect();
        return Err(err(format!(
            "its labels do not match a {} chart{}{}",
            chart.name(),
            if unknown.is_empty() {
                String::new()
            } else {
                format!("; not on the chart: {}", show(&unknown))
            },
            if missing.is_empty() {
                String::new()
            } else {
                format!("; missing: {}", show(&missing))
            }
        )));
    }
    let mut xyz: Vec<[f64; 3]> = xyz.into_iter().map(|v| v.expect("checked")).collect();
    if rows.lab {
        for v in xyz.iter_mut() {
            *v = lab_to_xyz(*v, white);
        }
    } else {
        // XYZ in 0..1 (perfect white Y = 1) is scaled to the Y = 100 convention.
        let ymax = xyz.iter().map(|v| v[1]).fold(f64::MIN, f64::max);
        if ymax <= 1.5 {
            for v in xyz.iter_mut() {
                *v = v.map(|x| x * 100.0);
            }
        }
    }
    if xyz.iter().any(|v| v[1] < 0.0 || v[1] > 150.0) {
        return Err(err(
            "a patch has Y outside 0..150 (perfect white = 100)".into()
        ));
    }
    check_not_degenerate(&xyz, white).map_err(err)?;
    Ok(Reference {
        name: src.to_string(),
        chart,
        xyz,
        white,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nsrm::{delta_e00_xyz, xyz_to_lab};

    #[test]
    fn builtins_parse_and_match_their_lab() {
        for (name, chart, text) in BUILTIN {
            let r = Reference::load(name, *chart, None).unwrap();
            assert_eq!(r.xyz.len(), chart.cells());
            // The files carry Lab beside xyY: both agree.
            for line in text.lines().skip(1).filter(|l| !l.is_empty()) {
                let c: Vec<&str> = line.split(',').collect();
                let i = chart.index_of(c[0]).unwrap();
                let lab: Vec<f64> = c[4..7].iter().map(|s| s.parse().unwrap()).collect();
                let got = xyz_to_lab(r.xyz[i], r.white);
                for k in 0..3 {
                    assert!(
                        (got[k] - lab[k]).abs() < 0.05,
                        "{name} {}: {got:?} {lab:?}",
                        c[0]
                    );
                }
            }
        }
        let e = Reference::load("sg-after2014", ChartKind::Cc24, None).unwrap_err();
        assert!(e.to_string().contains("sg chart"), "{e}");
        assert!(Reference::load("nope", ChartKind::Cc24, None).is_err());
    }

    #[test]
    fn csv_and_cgats_files() {
        let dir = tempfile::tempdir().unwrap();
        let builtin = Reference::load("cc24-after2014", ChartKind::Cc24, None).unwrap();
        // CSV with Lab, in shuffled order, labelled by number.
        let mut csv = String::from("label,L,a,b\n");
        for i in (0..24).rev() {
            let lab = xyz_to_lab(builtin.xyz[i], builtin.white);
            csv.push_str(&format!("{},{},{},{}\n", i + 1, lab[0], lab[1], lab[2]));
        }
        let p = dir.path().join("ref.csv");
        std::fs::write(&p, &csv).unwrap();
        let ps = p.to_str().unwrap();
        assert!(Reference::load(ps, ChartKind::Cc24, None).is_err());
        let r = Reference::load(ps, ChartKind::Cc24, Some(d50_white())).unwrap();
        for i in 0..24 {
            assert!(delta_e00_xyz(r.xyz[i], builtin.xyz[i], r.white) < 1e-6);
        }
        // CGATS with XYZ and quoted names.
        let mut cg = String::from(
            "CGATS.17\nORIGINATOR \"test\"\nNUMBER_OF_FIELDS 4\nBEGIN_DATA_FORMAT\nSAMPLE_ID XYZ_X XYZ_Y XYZ_Z\nEND_DATA_FORMAT\nNUMBER_OF_SETS 24\nBEGIN_DATA\n",
        );
        for i in 0..24 {
            let v = builtin.xyz[i];
            cg.push_str(&format!(
                "\"{}\" {} {} {}\n",
                ChartKind::Cc24.label(i % 6, i / 6),
                v[0],
                v[1],
                v[2]
            ));
        }
        cg.push_str("END_DATA\n");
        let p = dir.path().join("ref.cie");
        std::fs::write(&p, &cg).unwrap();
        let r = Reference::load(p.to_str().unwrap(), ChartKind::Cc24, None).unwrap();
        assert_eq!(r.xyz, builtin.xyz);
        // Labels that do not match the chart.
        let bad = cg.replace("\"24 black 2\"", "\"25 purple 2\"");
        std::fs::write(&p, &bad).unwrap();
        let e = Reference::load(p.to_str().unwrap(), ChartKind::Cc24, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("25 purple 2") && e.contains("24 black 2"), "{e}");
        let e = Reference::load(p.to_str().unwrap(), ChartKind::Sg, None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("do not match a sg chart"), "{e}");
    }
}
