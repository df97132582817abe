//! Ground-truth CSV files: `t_s, x, y, z` per line (m; a header line is skipped; further columns
//! are ignored).

use std::path::Path;

use crate::io::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::math::Vec3;

/// Reads a ground-truth CSV into (time s, position m), sorted by time.
///
/// # Errors
/// [`Error::Io`] if unreadable, [`Error::Format`] for a line that is not 4 numbers or an empty
/// file.
pub fn read_truth_csv(path: &Path) -> Result<Vec<(f64, Vec3)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path.display().to_string(), e))?;
    let bad = |reason: String| Error::Format { what: format!("ground truth {}", path.display()), reason };
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let nums: Option<Vec<f64>> = line.split(',').take(4).map(|s| s.trim().parse().ok()).collect();
        match nums.as_deref() {
            Some([t, x, y, z]) if [t, x, y, z].iter().all(|v| v.is_finite()) => out.push((*t, Vec3::new(*x, *y, *z))),
            None if n == 0 => {}
            _ => return Err(bad(format!("line {}: expected `t_s, x, y, z`", n + 1))),
        }
    }
    if out.is_empty() {
        return Err(bad("no samples".into()));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out.dedup_by(|a, b| a.0 == b.0);
    Ok(out)
}
