//! The anchor id table (string or integer ids → anchor indices of the filter) and anchor
//! position files, read ([`read_anchor_file`]) and written ([`write_anchor_file`]): CSV (`id, x,
//! y, z`, header line optional), TOML (`id = [x, y, z]`, at top level or under `[anchors]`), JSON
//! (`{"id": [x, y, z]}` or `[{"id": .., "position": [..]}]`), and the MCAP metadata record
//! `uwbimu.anchors` (`id → "[x, y, z]"`).

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use crate::{IoError as Error, IoResult as Result};
use uwbimu_vocabulary::math::Vec3;

/// Name of the MCAP metadata record holding anchor positions.
pub const ANCHORS_METADATA: &str = "uwbimu.anchors";

/// Anchor ids in order of first appearance, with positions where known.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnchorTable {
    ids: Vec<String>,
    index: HashMap<String, usize>,
    positions: Vec<Option<Vec3>>,
}

impl AnchorTable {
    /// The table index of `id`, adding it if new.
    pub fn intern(&mut self, id: &str) -> usize {
        if let Some(i) = self.index.get(id) {
            return *i;
        }
        let i = self.ids.len();
        self.ids.push(id.to_string());
        self.index.insert(id.to_string(), i);
        self.positions.push(None);
        i
    }

    /// Sets the position of `id` unless it already has one.
    pub fn set_if_unknown(&mut self, id: &str, position: Vec3) {
        let i = self.intern(id);
        if self.positions[i].is_none() {
            self.positions[i] = Some(position);
        }
    }

    /// Every id, in table order.
    pub fn ids(&self) -> &[String] {
        &self.ids
    }

    /// Position of table entry `i`, if known.
    pub fn position(&self, i: usize) -> Option<Vec3> {
        self.positions.get(i).copied().flatten()
    }

    /// Whether any entry has a position.
    pub fn any_position(&self) -> bool {
        self.positions.iter().any(Option::is_some)
    }
}

fn file_error(path: &Path, reason: impl Into<String>) -> Error {
    Error::Format { what: format!("anchor file {}", path.display()), reason: reason.into() }
}

fn finite3(path: &Path, id: &str, v: &[f64]) -> Result<Vec3> {
    match v {
        [x, y, z] if v.iter().all(|a| a.is_finite()) => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(file_error(path, format!("anchor `{id}`: expected 3 finite numbers, got {v:?}"))),
    }
}

/// Reads anchor positions from a `.csv`, `.toml` or `.json` file (by extension).
///
/// # Errors
/// [`Error::Io`] if unreadable, [`Error::Format`] for bad content or an unknown extension.
pub fn read_anchor_file(path: &Path) -> Result<BTreeMap<String, Vec3>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path.display().to_string(), e))?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let mut out = BTreeMap::new();
    match ext.as_str() {
        "csv" => {
            for (n, line) in text.lines().enumerate() {
                let cells: Vec<&str> = line.split(',').map(str::trim).collect();
                if cells.iter().all(|c| c.is_empty()) {
                    continue;
                }
                let nums: Option<Vec<f64>> = cells.get(1..).and_then(|c| c.iter().map(|s| s.parse().ok()).collect());
                match nums {
                    Some(v) => {
                        out.insert(cells[0].to_string(), finite3(path, cells[0], &v)?);
                    }
                    None if n == 0 => {} // header
                    None => return Err(file_error(path, format!("line {}: expected `id, x, y, z`", n + 1))),
                }
            }
        }
        "toml" => {
            let value: toml::Table = toml::from_str(&text).map_err(|e| file_error(path, e.to_string()))?;
            let table = match value.get("anchors") {
                Some(toml::Value::Table(t)) => t.clone(),
                _ => value,
            };
            for (id, v) in &table {
                let nums: Option<Vec<f64>> = v
                    .as_array()
                    .and_then(|a| a.iter().map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64))).collect());
                let nums = nums.ok_or_else(|| file_error(path, format!("anchor `{id}`: expected [x, y, z]")))?;
                out.insert(id.clone(), finite3(path, id, &nums)?);
            }
        }
        "json" => {
            let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| file_error(path, e.to_string()))?;
            let nums = |v: &serde_json::Value| {
                v.as_array().map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect::<Vec<f64>>())
            };
            match &value {
                serde_json::Value::Object(map) => {
                    for (id, v) in map {
                        let p = nums(v).ok_or_else(|| file_error(path, format!("anchor `{id}`: expected [x, y, z]")))?;
                        out.insert(id.clone(), finite3(path, id, &p)?);
                    }
                }
                serde_json::Value::Array(items) => {
                    for item in items {
                        let id = item.get("id").map(json_id).ok_or_else(|| file_error(path, "list entry without `id`"))?;
                        let p = item
                            .get("position")
                            .and_then(nums)
                            .ok_or_else(|| file_error(path, format!("anchor `{id}`: expected `position`: [x, y, z]")))?;
                        out.insert(id.clone(), finite3(path, &id, &p)?);
                    }
                }
                _ => return Err(file_error(path, "expected an object or a list")),
            }
        }
        _ => return Err(file_error(path, format!("unknown extension `{ext}` (expected .csv, .toml or .json)"))),
    }
    if out.is_empty() {
        return Err(file_error(path, "no anchors"));
    }
    Ok(out)
}

/// Writes anchor positions (`ids[k]` at `positions[k]`, m, rounded to 0.1 mm) as a file
/// [`read_anchor_file`] reads back, by extension: `.csv` (`id,x_m,y_m,z_m` then a row per
/// anchor), `.toml` (`[anchors]`, `"id" = [x, y, z]`) or `.json` (`{"id": [x, y, z]}`). The
/// file is replaced only once complete ([`crate::files::atomic_file::write_atomically`]).
///
/// # Errors
/// [`Error::Format`] for an unknown extension, ids and positions of different lengths, a
/// non-finite position or an id given twice; [`Error::Io`] if writing fails.
pub fn write_anchor_file(path: &Path, ids: &[String], positions: &[Vec3]) -> Result<()> {
    let fail = |reason: String| Error::Format { what: format!("anchor file {}", path.display()), reason };
    if ids.len() != positions.len() {
        return Err(fail(format!("{} ids for {} positions", ids.len(), positions.len())));
    }
    if let Some(k) = positions.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
        return Err(fail(format!("anchor `{}`: position {:?} is not finite", ids[k], positions[k].as_slice())));
    }
    let xyz: BTreeMap<String, [f64; 3]> =
        ids.iter().zip(positions).map(|(id, p)| (id.clone(), [p.x, p.y, p.z].map(|v| (v * 1e4).round() / 1e4))).collect();
    if xyz.len() != ids.len() {
        return Err(fail("an anchor id is given twice".into()));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let text = match ext.as_str() {
        "csv" => {
            if let Some(id) = ids.iter().find(|id| id.contains([',', '\n'])) {
                return Err(fail(format!("anchor id `{id}` holds a comma or a line break: write .toml or .json")));
            }
            let mut text = String::from("id,x_m,y_m,z_m\n");
            for (id, [x, y, z]) in ids.iter().map(|id| (id, xyz[id])) {
                text += &format!("{id},{x},{y},{z}\n");
            }
            text
        }
        "toml" => toml::to_string(&BTreeMap::from([("anchors", &xyz)])).map_err(|e| fail(e.to_string()))?,
        "json" => serde_json::to_string_pretty(&xyz).map_err(|e| fail(e.to_string()))? + "\n",
        _ => return Err(fail(format!("unknown extension `{ext}` (expected .csv, .toml or .json)"))),
    };
    crate::files::atomic_file::write_atomically(path, |file| {
        std::io::Write::write_all(file, text.as_bytes()).map_err(|e| Error::io(path.display(), e))
    })
}

/// A JSON id: strings as they are, numbers in decimal.
pub fn json_id(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Parses the entries of an `uwbimu.anchors` metadata record (`id → "[x, y, z]"` or `"x, y, z"`).
///
/// # Errors
/// [`Error::Format`] for an entry that is not 3 finite numbers.
pub fn parse_anchor_metadata(entries: &BTreeMap<String, String>) -> Result<BTreeMap<String, Vec3>> {
    entries
        .iter()
        .map(|(id, text)| {
            let nums: Option<Vec<f64>> =
                text.trim().trim_start_matches('[').trim_end_matches(']').split(',').map(|s| s.trim().parse().ok()).collect();
            match nums.as_deref() {
                Some([x, y, z]) if [x, y, z].iter().all(|a| a.is_finite()) => Ok((id.clone(), Vec3::new(*x, *y, *z))),
                _ => Err(Error::Format {
                    what: format!("metadata `{ANCHORS_METADATA}`"),
                    reason: format!("anchor `{id}`: expected \"[x, y, z]\", got {text:?}"),
                }),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_csv_toml_json_and_metadata() {
        let dir = std::env::temp_dir().join(format!("uwbimu_anchors_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let files = [
            ("a.csv", "anchor_id,x_m,y_m,z_m\n7475,0,0,0\nA2,5.5,0,1\n"),
            ("a.toml", "[anchors]\n7475 = [0, 0, 0]\nA2 = [5.5, 0.0, 1]\n"),
            ("a.json", "[{\"id\": 7475, \"position\": [0, 0, 0]}, {\"id\": \"A2\", \"position\": [5.5, 0, 1]}]"),
        ];
        for (name, text) in files {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            let a = read_anchor_file(&p).unwrap();
            assert_eq!(a.len(), 2, "{name}");
            assert_eq!(a["A2"], Vec3::new(5.5, 0.0, 1.0), "{name}");
            assert_eq!(a["7475"], Vec3::zeros(), "{name}");
        }
        std::fs::write(dir.join("bad.csv"), "1,2,3\n").unwrap();
        assert!(read_anchor_file(&dir.join("bad.csv")).is_err());
        let meta = BTreeMap::from([("x".to_string(), "[1, 2, 3]".to_string())]);
        assert_eq!(parse_anchor_metadata(&meta).unwrap()["x"], Vec3::new(1.0, 2.0, 3.0));
        let bad = BTreeMap::from([("x".to_string(), "[1, 2]".to_string())]);
        assert!(parse_anchor_metadata(&bad).is_err());
    }

    #[test]
    fn written_files_read_back() {
        let dir = std::env::temp_dir().join(format!("uwbimu_anchors_out_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ids = vec!["A0".to_string(), "7475".to_string(), "a b".to_string()];
        let positions = [Vec3::new(0.0, 0.0, 2.4), Vec3::new(9.81234567, -0.5, 2.6), Vec3::new(1.0, 2.0, 3.0)];
        for ext in ["csv", "toml", "json"] {
            let p = dir.join(format!("out.{ext}"));
            write_anchor_file(&p, &ids, &positions).unwrap();
            let back = read_anchor_file(&p).unwrap();
            assert_eq!(back.len(), 3, "{ext}");
            assert_eq!(back["7475"], Vec3::new(9.8123, -0.5, 2.6), "{ext}");
            assert_eq!(back["a b"], positions[2], "{ext}");
        }
        assert!(write_anchor_file(&dir.join("out.txt"), &ids, &positions).is_err());
        assert!(write_anchor_file(&dir.join("out.csv"), &ids[..2], &positions).is_err());
        let twice = vec!["A0".to_string(); 3];
        assert!(write_anchor_file(&dir.join("out.csv"), &twice, &positions).is_err());
    }

    #[test]
    fn table_keeps_first_position() {
        let mut t = AnchorTable::default();
        assert_eq!(t.intern("b"), 0);
        t.set_if_unknown("a", Vec3::x());
        t.set_if_unknown("a", Vec3::y());
        assert_eq!(t.position(1), Some(Vec3::x()));
        assert_eq!(t.position(0), None);
        assert_eq!(t.ids(), ["b", "a"]);
    }
}
