//! Writes named columns ([`crate::columns::Columns`]) as a CSV file with a header line.

use std::io::Write;
use std::path::Path;

use crate::io::{IoError as Error, IoResult as Result};

use crate::columns::Columns;
use crate::io::atomic_file::write_atomically;

/// Writes `cols` (all of one length) to `path`, through a temporary file renamed when complete
/// ([`write_atomically`]).
///
/// # Errors
/// [`Error::Io`] if the file cannot be written.
pub fn write_columns_csv(path: &Path, cols: &Columns) -> Result<()> {
    write_atomically(path, |out| write_rows(out, path, cols))
}

fn write_rows(out: &mut impl Write, path: &Path, cols: &Columns) -> Result<()> {
    let io = |e: std::io::Error| Error::io(path.display().to_string(), e);
    let names: Vec<&str> = cols.iter().map(|c| c.0).collect();
    writeln!(out, "{}", names.join(",")).map_err(io)?;
    let rows = cols.first().map_or(0, |c| c.1.len());
    let mut line = String::new();
    for r in 0..rows {
        line.clear();
        for (k, (_, values)) in cols.iter().enumerate() {
            if k > 0 {
                line.push(',');
            }
            line.push_str(&values[r].to_string());
        }
        writeln!(out, "{line}").map_err(io)?;
    }
    out.flush().map_err(io)
}
