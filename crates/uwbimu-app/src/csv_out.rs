//! Writes rows of numbers as a CSV file with a header line: row by row ([`CsvRowWriter`]) or from
//! named columns ([`crate::columns::Columns`], [`write_columns_csv`]).

use std::io::Write;
use std::path::Path;

use uwbimu_io::files::atomic_file::write_atomically;
use uwbimu_io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::error::Error as CoreError;

use crate::columns::Columns;

/// Writes a CSV file one row at a time: the header when created, then each row as its values
/// (`f64::to_string`) separated by commas, one line per row.
#[derive(Debug)]
pub struct CsvRowWriter<W: Write> {
    out: W,
    label: String,
    width: usize,
    line: String,
}

impl<W: Write> CsvRowWriter<W> {
    /// Writes the header line, `names` separated by commas, to `out`; `label` names the output
    /// in errors.
    ///
    /// # Errors
    /// [`Error::Io`] if writing fails.
    pub fn new(mut out: W, label: &str, names: &[&str]) -> Result<Self> {
        writeln!(out, "{}", names.join(",")).map_err(|e| Error::io(label, e))?;
        Ok(Self { out, label: label.to_string(), width: names.len(), line: String::new() })
    }

    /// Writes one line of `row`, which has one value per header name.
    ///
    /// # Errors
    /// [`CoreError::InvalidCall`] if `row` has another length than the header, [`Error::Io`] if
    /// writing fails.
    pub fn push(&mut self, row: &[f64]) -> Result<()> {
        if row.len() != self.width {
            let reason = format!("{}: a row of {} values under a header of {} names", self.label, row.len(), self.width);
            return Err(CoreError::InvalidCall(reason).into());
        }
        self.line.clear();
        for (k, value) in row.iter().enumerate() {
            if k > 0 {
                self.line.push(',');
            }
            self.line.push_str(&value.to_string());
        }
        writeln!(self.out, "{}", self.line).map_err(|e| Error::io(&self.label, e))
    }

    /// Flushes the output and returns it.
    ///
    /// # Errors
    /// [`Error::Io`] if flushing fails.
    pub fn finish(mut self) -> Result<W> {
        self.out.flush().map_err(|e| Error::io(&self.label, e))?;
        Ok(self.out)
    }
}

/// Writes `cols` (all of one length) to `path` through a [`CsvRowWriter`], by a temporary file
/// renamed when complete ([`write_atomically`]).
///
/// # Errors
/// [`Error::Io`] if the file cannot be written.
pub fn write_columns_csv(path: &Path, cols: &Columns) -> Result<()> {
    write_atomically(path, |out| {
        let names: Vec<&str> = cols.iter().map(|c| c.0).collect();
        let mut csv = CsvRowWriter::new(out, &path.display().to_string(), &names)?;
        let rows = cols.first().map_or(0, |c| c.1.len());
        let mut row = Vec::with_capacity(cols.len());
        for r in 0..rows {
            row.clear();
            row.extend(cols.iter().map(|(_, values)| values[r]));
            csv.push(&row)?;
        }
        csv.finish().map(drop)
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn rows_are_written_as_f64_to_string_under_the_header() {
        let mut csv = CsvRowWriter::new(Vec::new(), "t", &["t", "x", "y"]).unwrap();
        csv.push(&[0.1, -2.0, f64::NAN]).unwrap();
        csv.push(&[1e21, 1.5e-7, f64::INFINITY]).unwrap();
        let text = String::from_utf8(csv.finish().unwrap()).unwrap();
        assert_eq!(text, "t,x,y\n0.1,-2,NaN\n1000000000000000000000,0.00000015,inf\n");
    }

    #[test]
    fn a_row_of_another_width_is_refused() {
        let mut csv = CsvRowWriter::new(Vec::new(), "t", &["t", "x"]).unwrap();
        assert!(matches!(csv.push(&[1.0]), Err(Error::Core(CoreError::InvalidCall(_)))));
        assert_eq!(csv.finish().unwrap(), b"t,x\n");
    }

    #[test]
    fn columns_are_written_row_by_row() {
        let dir = std::env::temp_dir().join(format!("uwbimu_csv_out_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cols.csv");
        write_columns_csv(&path, &vec![("t", vec![0.0, 0.5]), ("x", vec![1.25, -3.0])]).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "t,x\n0,1.25\n0.5,-3\n");
        write_columns_csv(&path, &Vec::new()).unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "\n");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
