//! The CIE 1931 2° standard observer: the colour-matching functions x̄, ȳ, z̄ (360–830 nm, 1 nm)
//! every XYZ of the library is integrated with. They are colorimetry's own data: the Planckian
//! locus ([`super::temperature::planckian_xy`]) integrates them here, and `spectral` resamples
//! them to its grids (`spectral::cie1931_cmf`).

use std::sync::OnceLock;

/// The table (`assets/SOURCES.md`): `wavelength_nm,xbar,ybar,zbar`.
const CSV: &str = include_str!("../../assets/cie1931_2deg_cmf.csv");

/// The table's source name in messages and provenance.
pub(crate) const SOURCE: &str = "builtin:cie1931_2deg";

/// Colour-matching functions: `values[k][i]` is x̄ (`k` = 0), ȳ or z̄ at `wavelengths[i]` nm.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Cmf {
    /// Strictly increasing, in nm.
    pub(crate) wavelengths: Vec<f64>,
    /// The columns' names in the table.
    pub(crate) names: [String; 3],
    pub(crate) values: [Vec<f64>; 3],
}

/// The CIE 1931 2° observer (read once).
pub(crate) fn cie1931() -> &'static Cmf {
    static CMF: OnceLock<Cmf> = OnceLock::new();
    CMF.get_or_init(|| parse(CSV).expect("the built-in observer parses (tested)"))
}

/// A table of four columns (wavelength and three functions), wavelengths strictly increasing.
fn parse(text: &str) -> Result<Cmf, String> {
    let mut table = crate::csv_table::Table::new(text, SOURCE)
        .map_err(|e| e.to_string())?
        .ok_or("an empty table")?;
    let names: [String; 3] = match &table.header[..] {
        [_, x, y, z] => [x.clone(), y.clone(), z.clone()],
        h => return Err(format!("{} columns, expected 4", h.len())),
    };
    let mut wavelengths: Vec<f64> = Vec::new();
    let mut values: [Vec<f64>; 3] = Default::default();
    while let Some(row) = table.next_record().map_err(|e| e.to_string())? {
        row.expect_len(4).map_err(|e| e.to_string())?;
        let w = row.number(0).map_err(|e| e.to_string())?;
        if wavelengths.last().is_some_and(|&last| w <= last) {
            return Err(format!(
                "line {}: wavelength {w} does not increase",
                row.line
            ));
        }
        wavelengths.push(w);
        for (k, column) in values.iter_mut().enumerate() {
            column.push(row.number(k + 1).map_err(|e| e.to_string())?);
        }
    }
    Ok(Cmf {
        wavelengths,
        names,
        values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_observer_spans_360_to_830_nm_and_peaks_where_cie_says() {
        let o = cie1931();
        assert_eq!(o.wavelengths.len(), 471);
        assert_eq!((o.wavelengths[0], o.wavelengths[470]), (360.0, 830.0));
        // ȳ is the photopic luminosity function: 1 at 555 nm.
        assert_eq!(o.values[1][555 - 360], 1.0);
        assert_eq!(o.names[1], "ybar");
    }

    #[test]
    fn malformed_tables_are_refused() {
        assert!(parse("wavelength_nm,x,y,z\n400,1,2,3\n401,1,2,3\n").is_ok());
        assert!(parse("wavelength_nm,x,y\n400,1,2\n").is_err());
        assert!(parse("wavelength_nm,x,y,z\n400,1,2,3\n400,1,2,3\n").is_err());
        assert!(parse("wavelength_nm,x,y,z\n400,1,2\n").is_err());
        assert!(parse("").is_err());
    }
}
