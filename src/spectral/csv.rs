//! The spectral CSV reader.

use super::{SpectralError, SpectralTable};

/// Parses a spectral CSV: a header `wavelength,NAME,...` and one row per wavelength.
///
/// Blank lines and lines starting with `#` are skipped. Wavelengths must increase strictly; every row
/// must have as many cells as the header; every cell must be a finite number.
pub(crate) fn parse_csv(text: &str, source_name: &str) -> Result<SpectralTable, SpectralError> {
    let src = || source_name.to_string();
    let mut table = crate::csv_table::Table::new(text, source_name)?
        .ok_or_else(|| SpectralError::Empty { source_name: src() })?;
    let names: Vec<String> = table.header.iter().skip(1).cloned().collect();
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
    let mut parsed = Vec::with_capacity(expected);
    while let Some(row) = table.next_record()? {
        row.expect_len(expected)?;
        parsed.clear();
        for k in 0..expected {
            parsed.push(row.number(k)?);
        }
        if let Some(&previous) = wavelengths.last() {
            if parsed[0] <= previous {
                return Err(SpectralError::NonIncreasing {
                    source_name: src(),
                    line: row.line,
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
