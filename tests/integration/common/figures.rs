//! Measured figures stored beside the tests (`tests/figures/<name>.csv`, one `key,value` per
//! line), so that an accuracy test holds each figure to a margin over what it measured instead
//! of one loose bound for all: [`hold`] fails a figure more than [`REGRESSION_MARGIN`] (plus
//! [`ABSOLUTE_MARGIN_M`]) above its stored value, so a 10 % regression fails. With
//! `UPDATE_BOUNDS=1` the figures are re-measured into the file instead and the ones that moved
//! by more than 1 % are printed (`bash scripts/update_test_bounds.sh` runs every such test). A
//! figure that got worse (higher) by more than 1 % is not stored unless
//! `UPDATE_BOUNDS_ALLOW_WORSE=1` is set too: it is printed as `worse:` and the script fails, so a
//! regression cannot be absorbed into the stored figures without being named.
//!
//! These figures are snapshots: measured from the code's own output, they catch a drift, never a
//! bug that was in when they were first measured. The oracles are elsewhere (docs/testing.md).

use std::collections::BTreeMap;
use std::sync::Mutex;

/// A figure fails above its stored value times this.
pub const REGRESSION_MARGIN: f64 = 1.10;
/// Plus this much (m for the RMSE figures): the smallest figures (1–2 cm) move by float noise
/// across machines.
pub const ABSOLUTE_MARGIN_M: f64 = 0.002;
/// A re-measured figure that changed by more than this fraction is listed; one that rose by more
/// is a worsening (see the module doc).
pub const MOVED: f64 = 0.01;

/// The files are read once per test process and rewritten under this lock (tests run on
/// parallel threads).
static FILES: Mutex<BTreeMap<String, BTreeMap<String, f64>>> = Mutex::new(BTreeMap::new());

fn path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/figures").join(format!("{name}.csv"))
}

fn read(name: &str) -> BTreeMap<String, f64> {
    let text = std::fs::read_to_string(path(name)).unwrap_or_default();
    text.lines()
        .filter_map(|line| {
            let (key, value) = line.rsplit_once(',')?;
            Some((key.to_string(), value.parse().ok()?))
        })
        .collect()
}

/// Whether this run re-measures the stored figures.
pub fn updating() -> bool {
    std::env::var_os("UPDATE_BOUNDS").is_some()
}

/// The stored figures of `name`.
pub fn stored(name: &str) -> BTreeMap<String, f64> {
    let mut files = FILES.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    files.entry(name.to_string()).or_insert_with(|| read(name)).clone()
}

/// The bound of a figure stored as `figure`.
pub fn bound(figure: f64) -> f64 {
    figure * REGRESSION_MARGIN + ABSOLUTE_MARGIN_M
}

/// Holds each measured `(key, value)` to its stored figure in `tests/figures/<name>.csv`, or
/// records them with `UPDATE_BOUNDS=1`. Returns one message per value above its bound or
/// without a stored figure.
pub fn hold(name: &str, measured: &[(String, f64)]) -> Vec<String> {
    let mut files = FILES.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let figures = files.entry(name.to_string()).or_insert_with(|| read(name));
    if updating() {
        let allow_worse = std::env::var_os("UPDATE_BOUNDS_ALLOW_WORSE").is_some();
        for (key, value) in measured {
            match figures.get(key) {
                Some(&old) if *value > old * (1.0 + MOVED) && !allow_worse => {
                    println!("worse: {name}: {key}: {old:.4} -> {value:.4} ({:+.1} %), not stored", 100.0 * (value / old - 1.0));
                    continue;
                }
                Some(&old) if (value / old - 1.0).abs() > MOVED => {
                    let kind = if *value > old { "worse" } else { "moved" };
                    println!("{kind}: {name}: {key}: {old:.4} -> {value:.4} ({:+.1} %)", 100.0 * (value / old - 1.0))
                }
                None => println!("new: {name}: {key}: {value:.4}"),
                _ => {}
            }
            figures.insert(key.clone(), *value);
        }
        let text: String = figures.iter().map(|(k, v)| format!("{k},{v:.6}\n")).collect();
        std::fs::write(path(name), text).expect("write the figures file");
        return Vec::new();
    }
    measured
        .iter()
        .filter_map(|(key, value)| match figures.get(key) {
            Some(&figure) if *value <= bound(figure) => None,
            Some(&figure) => Some(format!(
                "{key}: {value:.4}, above its measured figure {figure:.4} (+10 %; run `bash scripts/update_test_bounds.sh` after a change that moves it on purpose)"
            )),
            None => Some(format!("{key}: {value:.4}, no stored figure in tests/figures/{name}.csv (run `bash scripts/update_test_bounds.sh`)")),
        })
        .collect()
}

/// [`hold`] for one figure; panics when it fails.
pub fn hold_one(name: &str, key: &str, value: f64) {
    let failures = hold(name, &[(key.to_string(), value)]);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
