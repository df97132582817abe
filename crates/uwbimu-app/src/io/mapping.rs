//! The user's description of a recording: which topic holds what, the field paths of vendor UWB
//! messages, where anchor positions and ground truth come from, and the time source. Read from
//! the `[mapping]` table of a replay TOML file, or from a Python dict (as JSON).

mod check;

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::io::{IoError as Error, IoResult as Result};
use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::error::Error as CoreError;

/// Which clock stamps a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeSource {
    /// The header stamp when the message has a non-zero one, else the MCAP log time.
    #[default]
    Header,
    /// Always the MCAP log time (receive time in rosbag2).
    Log,
}

impl TimeSource {
    /// Parses `header` or `log`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "header" => Ok(Self::Header),
            "log" => Ok(Self::Log),
            _ => Err(CoreError::unknown_option("time source", s, ["header", "log"]).into()),
        }
    }
}

/// Where `sensor_msgs/msg/Range` messages get their anchor id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AnchorFrom {
    /// `header.frame_id`.
    #[default]
    FrameId,
    /// The topic name.
    Topic,
}

/// How UWB range messages are read.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct UwbMapping {
    /// Range topics (empty: every channel with a recognised range schema, or the one channel
    /// the field paths fit).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the range (e.g. `ranges[].range`, `dis_arr[]`); default `range`.
    pub range: Option<String>,
    /// Path of the anchor id (e.g. `ranges[].id`), or `index` for per-anchor arrays (the array
    /// index is the id).
    pub anchor_id: Option<String>,
    /// Validity condition (e.g. `ranges[].ra == 1`); ranges failing it are dropped and counted.
    pub valid: Option<String>,
    /// Path of the anchor position carried by the message (e.g. `ranges[].pos`).
    pub anchor_position: Option<String>,
    /// Path of the range variance, m² before scaling (sensor_msgs/Range: `variance` when the
    /// schema has it).
    pub variance: Option<String>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to metres (0.001 for mm).
    pub scale: Option<f64>,
    /// sensor_msgs/Range: take the anchor id from `frame_id` (default) or the topic.
    #[serde(default)]
    pub anchor_from: AnchorFrom,
}

/// Default path of a TDoA's anchor i: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_ANCHOR_I_DEFAULT: &str = "idA";
/// Default path of a TDoA's anchor j: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_ANCHOR_J_DEFAULT: &str = "idB";
/// Default path of a TDoA's distance difference: the Crazyflie estimator's `estTDOA` event field.
pub const TDOA_DEFAULT: &str = "distanceDiff";

/// How TDoA messages are read (section `[mapping.tdoa]`). A message (or each element of an
/// array, with paths such as `tdoa[].idA`) gives anchor ids i and j and `d_ij = ‖p − a_j‖ −
/// ‖p − a_i‖` — the Crazyflie convention: `distanceDiff` is the distance to anchor `idB` minus
/// the distance to anchor `idA`. The defaults are the field names of the Crazyflie `estTDOA`
/// event (`idA`, `idB`, `distanceDiff`), which the recordings we write also use.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TdoaMapping {
    /// TDoA topics (empty: every channel with our `uwbimu_msgs/msg/Tdoa` schema).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the id of anchor i; default [`TDOA_ANCHOR_I_DEFAULT`].
    pub anchor_i: Option<String>,
    /// Path of the id of anchor j; default [`TDOA_ANCHOR_J_DEFAULT`].
    pub anchor_j: Option<String>,
    /// Path of `d_ij`; default [`TDOA_DEFAULT`].
    pub tdoa: Option<String>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to metres (0.001 for mm).
    pub scale: Option<f64>,
}

/// Where anchor positions come from (first match wins: `positions`, `file`, the MCAP metadata
/// record `uwbimu.anchors`, the `topic`, positions carried by range messages).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AnchorMapping {
    /// Inline positions: id → [x, y, z], m.
    pub positions: Option<BTreeMap<String, [f64; 3]>>,
    /// A TOML, CSV or JSON file of positions (see `io::anchors`).
    pub file: Option<PathBuf>,
    /// A topic listing anchors (e.g. `/anchor_list`).
    pub topic: Option<String>,
    /// Path of the id in the anchor topic (e.g. `anchor[].id`).
    pub id: Option<String>,
    /// Path of the position in the anchor topic (e.g. `anchor[].position`).
    pub position: Option<String>,
}

/// Where ground truth comes from.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct GroundTruthMapping {
    /// A PoseStamped / TransformStamped / Odometry topic (or any message with a point at
    /// `position`).
    pub topic: Option<String>,
    /// Path of the position (default by schema: `pose.position`, `transform.translation`,
    /// `pose.pose.position`).
    pub position: Option<String>,
    /// A CSV file of time (s) and position (m); header row optional, column names as in
    /// [`crate::io::truth_file::TRUTH_COLUMNS`].
    pub file: Option<PathBuf>,
}

/// The whole mapping.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Mapping {
    /// Clock used to order messages.
    #[serde(default)]
    pub time_source: TimeSource,
    /// Messages up to this much older than the newest one seen are put back in order; older ones
    /// are counted and dropped, s.
    #[serde(default = "default_window")]
    pub reorder_window_s: f64,
    /// IMU topic (default: the only `sensor_msgs/msg/Imu` channel).
    pub imu_topic: Option<String>,
    /// UWB range messages.
    #[serde(default)]
    pub uwb: UwbMapping,
    /// TDoA messages.
    #[serde(default)]
    pub tdoa: TdoaMapping,
    /// Anchor positions.
    #[serde(default)]
    pub anchors: AnchorMapping,
    /// Ground truth (optional).
    #[serde(default)]
    pub ground_truth: GroundTruthMapping,
}

fn default_window() -> f64 {
    uwbimu_estimation::pipeline::DEFAULT_REORDER_WINDOW_S
}

impl Default for Mapping {
    fn default() -> Self {
        Self {
            time_source: TimeSource::Header,
            reorder_window_s: default_window(),
            imu_topic: None,
            uwb: UwbMapping::default(),
            tdoa: TdoaMapping::default(),
            anchors: AnchorMapping::default(),
            ground_truth: GroundTruthMapping::default(),
        }
    }
}

impl Mapping {
    /// This mapping with `overrides` (JSON text of a mapping table, the Python `mapping=` dict)
    /// merged in: a key given replaces that key (`null` clears it), a nested table (`uwb`,
    /// `anchors`, `ground_truth`, ...) merges key by key, and every other key keeps its value.
    ///
    /// # Errors
    /// [`Error::Mapping`] for text that is not a JSON object, unknown keys or wrong types, naming
    /// the key path of the overrides.
    pub fn merged_with_json(&self, overrides: &str) -> Result<Self> {
        let overrides: serde_json::Value =
            serde_json::from_str(overrides).map_err(|e| Error::Mapping { field: "mapping".into(), reason: e.to_string() })?;
        check::check(&overrides)?;
        let mut merged =
            serde_json::to_value(self).map_err(|e| Error::Mapping { field: "mapping".into(), reason: e.to_string() })?;
        merge_json(&mut merged, overrides);
        Self::from_value(merged)
    }

    /// Reads a mapping from a tree of keys (a parsed JSON text or TOML table), checked key by
    /// key first so that an error names the key path, what is allowed there and the closest key.
    ///
    /// # Errors
    /// [`Error::Mapping`] for unknown keys, wrong types or bad numbers.
    pub fn from_value(value: serde_json::Value) -> Result<Self> {
        check::check(&value)?;
        let m: Self =
            serde_json::from_value(value).map_err(|e| Error::Mapping { field: String::new(), reason: e.to_string() })?;
        m.validate()
    }

    /// Checks the numeric settings.
    ///
    /// # Errors
    /// [`Error::Mapping`] for a negative window or a non-positive scale.
    pub fn validate(self) -> Result<Self> {
        if !(self.reorder_window_s.is_finite() && self.reorder_window_s >= 0.0) {
            return Err(Error::Mapping {
                field: "reorder_window_s".into(),
                reason: format!("must be >= 0, got {}", self.reorder_window_s),
            });
        }
        for (field, scale) in [("uwb.scale", self.uwb.scale), ("tdoa.scale", self.tdoa.scale)] {
            if let Some(s) = scale {
                if !(s.is_finite() && s > 0.0) {
                    return Err(Error::Mapping { field: field.into(), reason: format!("must be > 0, got {s}") });
                }
            }
        }
        Ok(self)
    }
}

/// Merges `overrides` into `base`: objects key by key (recursively), anything else replaced.
fn merge_json(base: &mut serde_json::Value, overrides: serde_json::Value) {
    match (base, overrides) {
        (serde_json::Value::Object(base), serde_json::Value::Object(overrides)) => {
            for (key, value) in overrides {
                match base.get_mut(&key) {
                    Some(slot) => merge_json(slot, value),
                    None => {
                        base.insert(key, value);
                    }
                }
            }
        }
        (slot, value) => *slot = value,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_merge_key_by_key() {
        let base = Mapping::default()
            .merged_with_json(r#"{"imu_topic": "/imu", "uwb": {"topics": ["/uwb"], "scale": 0.001}}"#)
            .unwrap_or_default();
        let merged = base.merged_with_json(r#"{"uwb": {"range": "ranges[].range"}, "ground_truth": {"file": "gt.csv"}}"#);
        let merged = merged.unwrap_or_default();
        assert_eq!(merged.imu_topic.as_deref(), Some("/imu"));
        assert_eq!((merged.uwb.topics.as_slice(), merged.uwb.scale), (["/uwb".to_string()].as_slice(), Some(0.001)));
        assert_eq!(merged.uwb.range.as_deref(), Some("ranges[].range"));
        assert_eq!(merged.ground_truth.file.as_deref(), Some(std::path::Path::new("gt.csv")));
        let cleared = merged.merged_with_json(r#"{"imu_topic": null}"#).unwrap_or_default();
        assert_eq!(cleared.imu_topic, None);
        for bad in [r#"{"uwbb": {}}"#, r#"{"uwb": {"scale": -1}}"#, "[1]", "{"] {
            assert!(matches!(base.merged_with_json(bad), Err(Error::Mapping { .. })), "{bad}");
        }
    }
}
