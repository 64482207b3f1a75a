//! The spectral CSV reader.

use super::{SpectralError, SpectralTable};

/// Parses a spectral CSV: a header `wavelength,NAME,...` and one row per wavelength.
///
/// Blank lines and lines starting with `#` are skipped. Wavelengths must increase strictly; every row
/// must have as many cells as the header; every cell must be a finite number.
pub fn parse_csv(text: &str, source_name: &str) -> Result<SpectralTable, SpectralError> {
    let src = || source_name.to_string();
    let mut lines = crate::limits::csv_lines(text);
    let (_, header) = lines
        .next()
        .ok_or_else(|| SpectralError::Empty { source_name: src() })?;
    let header = header.trim_start_matches('\u{feff}');
    let names: Vec<String> = header
        .split(',')
        .skip(1)
        .map(|s| s.trim().to_string())
        .collect();
    if names.is_empty() {
        return Err(SpectralError::NoColumns { source_name: src() });
    }
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(SpectralError::DuplicateColumn {
                source_name: src(),
                column: n.clone(),
            });
        }
    }
    let expected = names.len() + 1;
    let mut wavelengths = Vec::new();
    let mut values = vec![Vec::new(); names.len()];
    for (line, row) in lines {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if cells.len() != expected {
            return Err(SpectralError::Ragged {
                source_name: src(),
                line,
                found: cells.len(),
                expected,
            });
        }
        let mut parsed = Vec::with_capacity(expected);
        for (k, cell) in cells.iter().enumerate() {
            let column = if k == 0 {
                "wavelength".to_string()
            } else {
                names[k - 1].clone()
            };
            let v: f64 = cell.parse().map_err(|_| SpectralError::NotANumber {
                source_name: src(),
                line,
                column: column.clone(),
                cell: cell.to_string(),
            })?;
            if !v.is_finite() {
                return Err(SpectralError::NonFinite {
                    source_name: src(),
                    line,
                    column,
                });
            }
            parsed.push(v);
        }
        if let Some(&previous) = wavelengths.last() {
            if parsed[0] <= previous {
                return Err(SpectralError::NonIncreasing {
                    source_name: src(),
                    line,
                    wavelength: parsed[0],
                    previous,
                });
            }
        }
        wavelengths.push(parsed[0]);
        for (col, v) in values.iter_mut().zip(&parsed[1..]) {
            col.push(*v);
        }
    }
    if wavelengths.is_empty() {
        return Err(SpectralError::NoRows { source_name: src() });
    }
    Ok(SpectralTable {
        source_name: source_name.to_string(),
        wavelengths,
        names,
        values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse_csv(text, "f.csv").unwrap_err().to_string()
    }

    #[test]
    fn parses_and_skips_comments() {
        let t = parse_csv("# c\nnm,a,b\r\n400,1,2\n\n410,3,4\n", "f.csv").unwrap();
        assert_eq!(t.names, vec!["a", "b"]);
        assert_eq!(t.wavelengths, vec![400.0, 410.0]);
        assert_eq!(t.values[1], vec![2.0, 4.0]);
    }

    #[test]
    fn errors_are_clear() {
        assert!(err("").contains("empty"));
        assert!(err("nm\n400\n").contains("no spectrum columns"));
        assert!(err("nm,a\n").contains("no data rows"));
        let e = err("nm,a,b\n400,1,2\n410,3\n");
        assert!(e.contains("line 3") && e.contains("2 cells"), "{e}");
        let e = err("nm,a\n400,x\n");
        assert!(e.contains("`x`") && e.contains("column `a`"), "{e}");
        let e = err("nm,a\n410,1\n400,2\n");
        assert!(e.contains("does not increase"), "{e}");
        assert!(err("nm,a\n400,NaN\n").contains("not finite"));
        assert!(err("nm,a,a\n400,1,1\n").contains("duplicate"));
        assert!(err("nm,a\n400,1\n400,2\n").contains("does not increase"));
    }
}
