//! Ground-truth CSV files: time (s) and position (m) per line. With a header row the columns are
//! found by name, each under one of the spellings of [`TRUTH_COLUMNS`] (`t,x,y,z` or
//! `t_s,x_m,y_m,z_m`; further columns are ignored); without one the first four columns are
//! `t, x, y, z`.

use std::path::Path;

use crate::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::math::Vec3;

/// The columns of a ground-truth table (time s, then position m) and the names each may have in
/// a header row: the CLI's `--ground-truth`, `uwbimu_rs.replay(ground_truth=...)` and
/// `uwbimu_rs.metrics.evaluate` on a DataFrame accept all of them.
pub const TRUTH_COLUMNS: [[&str; 2]; 4] = [["t", "t_s"], ["x", "x_m"], ["y", "y_m"], ["z", "z_m"]];

/// The accepted spellings, for messages: `t or t_s, x or x_m, y or y_m, z or z_m`.
fn spellings() -> String {
    TRUTH_COLUMNS.iter().map(|names| names.join(" or ")).collect::<Vec<_>>().join(", ")
}

/// The indices of the truth columns in a header row.
fn header_indices(header: &str) -> std::result::Result<[usize; 4], String> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut out = [0; 4];
    for (slot, accepted) in out.iter_mut().zip(TRUTH_COLUMNS) {
        *slot = names
            .iter()
            .position(|n| accepted.contains(n))
            .ok_or_else(|| format!("header `{header}` has no column {}; expected {}", accepted.join(" or "), spellings()))?;
    }
    Ok(out)
}

/// Reads a ground-truth CSV into (time s, position m), sorted by time (stable: repeated times, a
/// truth taken at each range of an epoch, stay in file order; the metrics average them,
/// `uwbimu_app::metrics::interpolate_positions`).
///
/// # Errors
/// [`Error::Io`] if unreadable; [`Error::Format`] naming the file and line for a header without
/// the truth columns, a row whose values are not finite numbers, or a file without samples.
pub fn read_truth_csv(path: &Path) -> Result<Vec<(f64, Vec3)>> {
    use std::io::BufRead;
    let io = |e: std::io::Error| Error::io(path.display().to_string(), e);
    let file = std::io::BufReader::new(std::fs::File::open(path).map_err(io)?);
    let bad = |reason: String| Error::Format { what: format!("ground truth {}", path.display()), reason };
    let mut columns = [0, 1, 2, 3];
    let mut first_row = true;
    let mut out = Vec::new();
    for (n, line) in file.lines().enumerate() {
        let line = line.map_err(io)?;
        let line = line.as_str();
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let value = |k: usize| fields.get(columns[k]).and_then(|s| s.parse::<f64>().ok()).filter(|v| v.is_finite());
        let row = [value(0), value(1), value(2), value(3)];
        match row {
            [Some(t), Some(x), Some(y), Some(z)] => out.push((t, Vec3::new(x, y, z))),
            _ if first_row => columns = header_indices(line).map_err(|r| bad(format!("line {}: {r}", n + 1)))?,
            _ => return Err(bad(format!("line {}: expected finite numbers in the columns {}", n + 1, spellings()))),
        }
        first_row = false;
    }
    if out.is_empty() {
        return Err(bad("no samples".into()));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(name: &str, text: &str) -> Result<Vec<(f64, Vec3)>> {
        let path = std::env::temp_dir().join(format!("uwbimu_truth_{}_{name}.csv", std::process::id()));
        std::fs::write(&path, text).map_err(|e| Error::io("scratch", e))?;
        read_truth_csv(&path)
    }

    #[test]
    fn both_spellings_and_no_header_read_the_same() {
        let rows = "0.0,1,2,3\n0.1,1.5,2,3\n";
        let plain = read("plain", rows).ok();
        assert_eq!(plain.as_ref().map(Vec::len), Some(2));
        assert_eq!(read("short", &format!("t,x,y,z\n{rows}")).ok(), plain);
        assert_eq!(read("units", &format!("t_s,x_m,y_m,z_m\n{rows}")).ok(), plain);
        // Columns are found by name: a reordered header with an extra column reads the same.
        let reordered = "q,z_m,t_s,y_m,x_m\n9,3,0.0,2,1\n9,3,0.1,2,1.5\n";
        assert_eq!(read("reordered", reordered).ok(), plain);
    }

    #[test]
    fn a_header_without_the_columns_or_a_bad_row_names_the_line() {
        let e = read("vive", "t_header_s,t_bag_s,x_m,y_m,z_m\n1,1,0,0,0\n").err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("line 1") && e.contains("t or t_s"), "{e}");
        let e = read("nan", "t,x,y,z\n0,1,2,3\n0.1,nan,2,3\n").err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("line 3"), "{e}");
        assert!(read("empty", "t,x,y,z\n").is_err());
    }
}
