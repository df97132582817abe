//! The user's description of a recording: which topic holds what, the field paths of vendor UWB
//! messages, where anchor positions and ground truth come from, and the time source. Read from
//! the `[mapping]` table of a replay TOML file, or from a Python dict (as JSON).

mod check;
pub mod field_path;
pub mod reorder;
pub mod topics;

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::{IoError as Error, IoResult as Result};
use serde::{Deserialize, Serialize};
use uwbimu_vocabulary::config::MAX_TAGS;
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
    /// Path of the id of the tag that measured the range (e.g. `tag_id`), or `topic` for one
    /// topic per tag; None: every range is tag 0 (the JSON `uwbimu.UwbRange` carries its own
    /// `tag`).
    pub tag: Option<String>,
    /// The tag ids in the order of `mounting.lever_arm` (tag index = position in this list);
    /// None: an id must be the tag index itself (`0`, `1`, ...). A range of another tag is
    /// dropped and counted ([`crate::ReadStats::unknown_tag`]).
    pub tag_ids: Option<Vec<String>>,
}

impl UwbMapping {
    /// The tag index of the tag id `id` ([`UwbMapping::tag_ids`]; None: an id that is not a tag).
    /// A range without a tag id is tag 0.
    pub fn tag_index(&self, id: Option<&str>) -> Option<usize> {
        let Some(id) = id else { return Some(0) };
        match &self.tag_ids {
            Some(ids) => ids.iter().position(|t| t == id),
            None => id.parse::<usize>().ok().filter(|&k| k < MAX_TAGS),
        }
    }
}

/// Default path of an anchor-to-anchor range's first anchor id: the field of our
/// `uwbimu_msgs/msg/AnchorRange` ([`crate::recordings::recording_out::ANCHOR_RANGE_MSG`]).
pub const ANCHOR_RANGE_I_DEFAULT: &str = "anchor_i";
/// Default path of an anchor-to-anchor range's second anchor id (our message's field).
pub const ANCHOR_RANGE_J_DEFAULT: &str = "anchor_j";
/// Default path of an anchor-to-anchor range (our message's field).
pub const ANCHOR_RANGE_DEFAULT: &str = "range";

/// How anchor-to-anchor range messages are read (section `[mapping.anchor_ranges]`), the input
/// of the anchor survey (`uwbimu-replay survey`). A message (or each element of an array, with
/// paths such as `ranges[].from`) gives the ids of two anchors and the distance between them. The
/// defaults are the fields of our `uwbimu_msgs/msg/AnchorRange` (`anchor_i`, `anchor_j`,
/// `range`). The anchor rows (anchor 0 is the origin of the survey's frame) are `anchor_ids` when
/// given; else, in natural order (`A2` before `A10`), the ids of the mapping's anchor table
/// (`anchors.positions`, else `anchors.file`: the ids the replay maps UWB ranges through) or,
/// without one, every id a usable pair names (a stray device's too). A pair naming an id outside
/// the rows is dropped and counted.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AnchorRangeMapping {
    /// Anchor-to-anchor range topics (empty: every channel with our
    /// `uwbimu_msgs/msg/AnchorRange` schema).
    #[serde(default)]
    pub topics: Vec<String>,
    /// Path of the id of the first anchor; default [`ANCHOR_RANGE_I_DEFAULT`].
    pub anchor_i: Option<String>,
    /// Path of the id of the second anchor; default [`ANCHOR_RANGE_J_DEFAULT`].
    pub anchor_j: Option<String>,
    /// Path of the range; default [`ANCHOR_RANGE_DEFAULT`].
    pub range: Option<String>,
    /// Path of the stamp (`sec`/`nanosec` message); default `header.stamp` when present.
    pub stamp: Option<String>,
    /// Factor from the message's unit to metres (0.001 for mm).
    pub scale: Option<f64>,
    /// The anchor ids in row order (row 0 first); None: see the struct's doc.
    pub anchor_ids: Option<Vec<String>>,
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
    /// [`crate::files::truth_file::TRUTH_COLUMNS`].
    pub file: Option<PathBuf>,
}

/// Declares [`Mapping`] with a section per sensor io row (the rows of `sensor_rows!`, each its
/// sensor's table `[mapping.<name>]`), its `Default`, and [`SENSOR_SECTIONS`].
macro_rules! mapping {
    ($($(#[doc = $doc:literal])* $name:ident: $kind:ident => $row:ident($section:ident),)+) => {
        /// The whole mapping.
        #[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
        #[serde(deny_unknown_fields)]
        pub struct Mapping {
            /// Clock used to order messages.
            #[serde(default)]
            pub time_source: TimeSource,
            /// Messages up to this much older than the newest one seen are put back in order;
            /// older ones are counted and dropped, s.
            #[serde(default = "default_window")]
            pub reorder_window_s: f64,
            /// IMU topic (default: the only `sensor_msgs/msg/Imu` channel).
            pub imu_topic: Option<String>,
            /// UWB range messages.
            #[serde(default)]
            pub uwb: UwbMapping,
            $($(#[doc = $doc])* #[serde(default)] pub $name: topics::$section,)+
            /// Anchor-to-anchor range messages (read by the anchor survey only).
            #[serde(default)]
            pub anchor_ranges: AnchorRangeMapping,
            /// Anchor positions.
            #[serde(default)]
            pub anchors: AnchorMapping,
            /// Ground truth (optional).
            #[serde(default)]
            pub ground_truth: GroundTruthMapping,
        }

        impl Default for Mapping {
            fn default() -> Self {
                Self {
                    time_source: TimeSource::Header,
                    reorder_window_s: default_window(),
                    imu_topic: None,
                    uwb: UwbMapping::default(),
                    $($name: topics::$section::default(),)+
                    anchor_ranges: AnchorRangeMapping::default(),
                    anchors: AnchorMapping::default(),
                    ground_truth: GroundTruthMapping::default(),
                }
            }
        }

        /// The sensors' sections of [`Mapping`], each with the checker of its keys.
        const SENSOR_SECTIONS: &[(&str, check::Checker)] = &[$((stringify!($name), check::leaves::<topics::$section>),)+];
    };
}
topics::sensor_rows!(mapping);

fn default_window() -> f64 {
    uwbimu_vocabulary::config::DEFAULT_REORDER_WINDOW_S
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

    /// Checks the numeric settings, the tag ids, the anchor rows of the anchor ranges and each
    /// sensor's section ([`topics::SensorIo::validate`]).
    ///
    /// # Errors
    /// [`Error::Mapping`] for a negative window, a non-positive scale, more tag ids than tags or
    /// a repeated one, an empty or repeated `anchor_ranges.anchor_ids`, a sensor's section that
    /// does not validate (a bad odometry axis, a zero altitude scale, …).
    pub fn validate(self) -> Result<Self> {
        if !(self.reorder_window_s.is_finite() && self.reorder_window_s >= 0.0) {
            return Err(Error::Mapping {
                field: "reorder_window_s".into(),
                reason: format!("must be >= 0, got {}", self.reorder_window_s),
            });
        }
        topics::positive("uwb.scale", self.uwb.scale)?;
        topics::positive("anchor_ranges.scale", self.anchor_ranges.scale)?;
        for row in topics::SENSORS {
            row.validate(&self)?;
        }
        if let Some(ids) = &self.uwb.tag_ids {
            let repeated = ids.iter().enumerate().find(|(i, id)| ids[..*i].contains(id));
            if ids.is_empty() || ids.len() > MAX_TAGS || repeated.is_some() {
                return Err(Error::Mapping {
                    field: "uwb.tag_ids".into(),
                    reason: format!("give 1 to {MAX_TAGS} distinct tag ids, one per `mounting.lever_arm` row, got {ids:?}"),
                });
            }
        }
        if let Some(ids) = &self.anchor_ranges.anchor_ids {
            if ids.is_empty() || ids.iter().enumerate().any(|(i, id)| ids[..i].contains(id)) {
                return Err(Error::Mapping {
                    field: "anchor_ranges.anchor_ids".into(),
                    reason: format!("give distinct anchor ids, one per row (row 0 first), got {ids:?}"),
                });
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
