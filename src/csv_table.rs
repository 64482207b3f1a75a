//! The one CSV reader of the crate: spectra, measured patches and chart references are all read
//! through `Table` (on the `csv` crate), and fail with one error type, [`CsvError`].
//!
//! The rules, the same for every file: a leading UTF-8 byte-order mark is dropped; lines end in
//! `\n` or `\r\n`; blank lines and lines whose first non-blank character is `#` are skipped; cells
//! are trimmed; the first line kept is the header; standard CSV quoting (`"a,b"`) is understood.
//! Rows may have any number of cells: the caller checks the count
//! (`Record::expect_len`) so that the error names the line.

use thiserror::Error;

/// A CSV that cannot be read, naming the file (`source_name`) and the 1-based line.
#[derive(Debug, Error)]
pub enum CsvError {
    /// Malformed CSV (an unclosed quote) or text that is not UTF-8.
    #[error("{source_name}: line {line}: {why}")]
    Syntax {
        /// The file (or built-in table) read.
        source_name: String,
        /// The 1-based line.
        line: usize,
        /// What is wrong.
        why: String,
    },
    /// A row whose cell count differs from the header's.
    #[error("{source_name}: line {line}: {found} cells, expected {expected}")]
    Ragged {
        /// The file (or built-in table) read.
        source_name: String,
        /// The 1-based line.
        line: usize,
        /// Cells in the row.
        found: usize,
        /// Cells in the header.
        expected: usize,
    },
    /// A cell that should hold a number and does not.
    #[error("{source_name}: line {line}, column `{column}`: `{cell}` is not a number")]
    NotANumber {
        /// The file (or built-in table) read.
        source_name: String,
        /// The 1-based line.
        line: usize,
        /// The column's header.
        column: String,
        /// The cell as written.
        cell: String,
    },
    /// A number that is infinite or NaN.
    #[error("{source_name}: line {line}, column `{column}`: `{cell}` is not finite")]
    NonFinite {
        /// The file (or built-in table) read.
        source_name: String,
        /// The 1-based line.
        line: usize,
        /// The column's header.
        column: String,
        /// The cell as written.
        cell: String,
    },
}

/// A CSV text being read: its header, then its data rows one at a time (the row's storage is
/// reused, so reading allocates nothing per row).
pub struct Table<'a> {
    source_name: &'a str,
    reader: csv::Reader<&'a [u8]>,
    /// The text read (after the byte-order mark), for line numbers: the `csv` crate counts
    /// records, not lines, past blank ones.
    bytes: &'a [u8],
    /// Line of the byte at `counted`.
    line_at: (usize, usize),
    record: csv::ByteRecord,
    /// The header's cells, trimmed.
    pub header: Vec<String>,
    /// The header's 1-based line.
    pub header_line: usize,
}

/// One data row of a [`Table`].
pub struct Record<'r> {
    source_name: &'r str,
    header: &'r [String],
    record: &'r csv::ByteRecord,
    /// The row's 1-based line.
    pub line: usize,
}

fn configured(text: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .from_reader(text)
}

/// A row that holds no data: a blank line, or a comment after leading blanks (`csv` itself skips
/// empty lines and lines starting with `#`).
fn is_blank_or_comment(record: &csv::ByteRecord) -> bool {
    match record.get(0) {
        None => true,
        Some(first) => {
            let first = first.trim_ascii();
            (record.len() == 1 && first.is_empty()) || first.starts_with(b"#")
        }
    }
}

impl<'a> Table<'a> {
    /// Starts reading `text`; `None` when it holds no line with data (not even a header).
    pub fn new(text: &'a str, source_name: &'a str) -> Result<Option<Self>, CsvError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text).as_bytes();
        let mut table = Table {
            source_name,
            reader: configured(text),
            bytes: text,
            line_at: (0, 1),
            record: csv::ByteRecord::new(),
            header: Vec::new(),
            header_line: 0,
        };
        if !table.advance()? {
            return Ok(None);
        }
        table.header_line = table.line();
        table.header = (0..table.record.len())
            .map(|k| cell(source_name, table.header_line, &table.record, k).map(str::to_string))
            .collect::<Result<_, _>>()?;
        Ok(Some(table))
    }

    /// The header as one line, cells joined by `,` (for messages).
    pub fn header_text(&self) -> String {
        self.header.join(",")
    }

    /// The line of the current record: newlines counted up to its first byte, from where the
    /// previous count stopped (linear in the text in all).
    fn line(&mut self) -> usize {
        let at = self
            .record
            .position()
            .map_or(0, |p| p.byte() as usize)
            .min(self.bytes.len());
        self.record_line(at)
    }

    /// The line of the first byte of the record that the reader began to read at byte `at`: the
    /// reader reports where it started, before the line ends, blank lines and comment lines it
    /// skipped, so those are skipped here too.
    fn record_line(&mut self, mut at: usize) -> usize {
        let b = self.bytes;
        loop {
            while at < b.len() && b[at].is_ascii_whitespace() {
                at += 1;
            }
            let line_start = at == 0 || b[at - 1] == b'\n';
            if at < b.len() && b[at] == b'#' && line_start {
                at = b[at..]
                    .iter()
                    .position(|&c| c == b'\n')
                    .map_or(b.len(), |p| at + p + 1);
            } else {
                break;
            }
        }
        self.line_of(at)
    }

    fn line_of(&mut self, at: usize) -> usize {
        let (from, line) = self.line_at;
        if at >= from {
            let n = self.bytes[from..at].iter().filter(|&&b| b == b'\n').count();
            self.line_at = (at, line + n);
        }
        self.line_at.1
    }

    /// Reads the next row with data into `self.record`; false at the end.
    fn advance(&mut self) -> Result<bool, CsvError> {
        loop {
            match self.reader.read_byte_record(&mut self.record) {
                Ok(false) => return Ok(false),
                Ok(true) if is_blank_or_comment(&self.record) => continue,
                Ok(true) => return Ok(true),
                Err(e) => {
                    let at = e.position().map_or(0, |p| p.byte() as usize);
                    let line = self.line_of(at.min(self.bytes.len()));
                    return Err(CsvError::Syntax {
                        source_name: self.source_name.to_string(),
                        line,
                        why: e.to_string(),
                    });
                }
            }
        }
    }

    /// The next data row, or `None` at the end of the text.
    pub fn next_record(&mut self) -> Result<Option<Record<'_>>, CsvError> {
        if !self.advance()? {
            return Ok(None);
        }
        let line = self.line();
        Ok(Some(Record {
            source_name: self.source_name,
            header: &self.header,
            record: &self.record,
            line,
        }))
    }
}

fn cell<'r>(
    source_name: &str,
    line: usize,
    record: &'r csv::ByteRecord,
    k: usize,
) -> Result<&'r str, CsvError> {
    std::str::from_utf8(record.get(k).unwrap_or_default().trim_ascii()).map_err(|_| {
        CsvError::Syntax {
            source_name: source_name.to_string(),
            line,
            why: format!("cell {} is not UTF-8", k + 1),
        }
    })
}

/// Parses a finite `f64` from a trimmed cell (std's parser on the bytes; `inf`/`NaN` refused).
pub(crate) fn finite(bytes: &[u8]) -> Option<f64> {
    std::str::from_utf8(bytes)
        .ok()?
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
}

impl<'r> Record<'r> {
    /// The number of cells.
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.record.len()
    }

    /// Fails with [`CsvError::Ragged`] unless the row has `expected` cells.
    pub fn expect_len(&self, expected: usize) -> Result<(), CsvError> {
        if self.record.len() == expected {
            Ok(())
        } else {
            Err(CsvError::Ragged {
                source_name: self.source_name.to_string(),
                line: self.line,
                found: self.record.len(),
                expected,
            })
        }
    }

    /// Cell `k` as bytes, trimmed (empty past the end).
    pub(crate) fn bytes(&self, k: usize) -> &'r [u8] {
        self.record.get(k).unwrap_or_default().trim_ascii()
    }

    /// Cell `k` as text (empty past the end).
    pub fn text(&self, k: usize) -> Result<&'r str, CsvError> {
        cell(self.source_name, self.line, self.record, k)
    }

    /// Cell `k` as a finite number; the error names the header's column `k`.
    pub fn number(&self, k: usize) -> Result<f64, CsvError> {
        let bytes = self.bytes(k);
        if let Some(v) = finite(bytes) {
            return Ok(v);
        }
        let cell = String::from_utf8_lossy(bytes).into_owned();
        let column = self.header.get(k).cloned().unwrap_or_default();
        let source_name = self.source_name.to_string();
        let line = self.line;
        Err(if cell.parse::<f64>().is_ok() {
            CsvError::NonFinite {
                source_name,
                line,
                column,
                cell,
            }
        } else {
            CsvError::NotANumber {
                source_name,
                line,
                column,
                cell,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(text: &str) -> (Vec<String>, Vec<(usize, Vec<String>)>) {
        let mut t = Table::new(text, "t.csv").unwrap().unwrap();
        assert_eq!(t.header_line, 3);
        let mut out = Vec::new();
        while let Some(r) = t.next_record().unwrap() {
            let cells = (0..r.len())
                .map(|k| r.text(k).unwrap().to_string())
                .collect();
            out.push((r.line, cells));
        }
        (t.header.clone(), out)
    }

    #[test]
    fn skips_blanks_and_comments_and_counts_lines() {
        let (h, r) = rows("\u{feff}# c\n\n a , b \r\n  # indented\n   \n1,2\r\n\n3,\"x,y\"\n");
        assert_eq!(h, vec!["a", "b"]);
        assert_eq!(r[0], (6, vec!["1".into(), "2".into()]));
        assert_eq!(r[1], (8, vec!["3".into(), "x,y".into()]));
        assert!(Table::new("# only\n\n", "t.csv").unwrap().is_none());
        let (_, r) = rows("#\n# \"q\n  a\n1\n# c\n  \n\n2\n");
        assert_eq!(r, vec![(4, vec!["1".into()]), (8, vec!["2".into()])]);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let mut t = Table::new("a,b\n1,2\n3\n4,x\n5,inf\n", "t.csv")
            .unwrap()
            .unwrap();
        t.next_record().unwrap().unwrap().expect_len(2).unwrap();
        let e = t.next_record().unwrap().unwrap().expect_len(2).unwrap_err();
        assert_eq!(e.to_string(), "t.csv: line 3: 1 cells, expected 2");
        let e = t.next_record().unwrap().unwrap().number(1).unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.csv: line 4, column `b`: `x` is not a number"
        );
        let e = t.next_record().unwrap().unwrap().number(1).unwrap_err();
        assert!(e.to_string().contains("line 5") && e.to_string().contains("not finite"));
    }
}
