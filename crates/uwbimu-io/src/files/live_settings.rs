//! The `[live]` table of the replay file: what the live node (`uwbimu-live`) needs beyond the
//! mapping — the DDS domain, the ROS 2 types of the input topics and where their `.msg` files
//! are, the output topics and frame ids, the publishing and diagnostics rates, when a sensor
//! counts as silent, how long it watches before choosing its model, and the lag of its
//! fixed-lag smoothed pose.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::mapping::topics::SENSORS;
use crate::ros::types::full_definition;
use uwbimu_vocabulary::error::Error as CoreError;

use crate::{IoError as Error, IoResult as Result, Mapping};

/// The `[live]` table (every key optional).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LiveSettings {
    /// DDS domain id, the `ROS_DOMAIN_ID` of the ROS 2 graph.
    pub domain_id: u32,
    /// ROS 2 type (`pkg/msg/Type`) of an input topic, by topic. Unlisted: `sensor_msgs/msg/Imu`
    /// for the IMU, for a sensor's topic the first type its io row reads
    /// ([`crate::mapping::topics::SensorIo::reads`]: `uwbimu_msgs/msg/Tdoa` for TDoA,
    /// `sensor_msgs/msg/Range` for altitude, `nav_msgs/msg/Odometry` for odometry, …); a UWB
    /// topic's type is learnt from its publishers.
    pub types: BTreeMap<String, String>,
    /// Folders with the `.msg` files of types not bundled, as a ROS 2 workspace lays them out
    /// (`<dir>/<pkg>/msg/<Type>.msg`); relative to the replay file.
    pub msg_paths: Vec<PathBuf>,
    /// Output topic of `geometry_msgs/msg/PoseWithCovarianceStamped`.
    pub pose_topic: String,
    /// Output topic of `nav_msgs/msg/Odometry`.
    pub odometry_topic: String,
    /// Output topic of `diagnostic_msgs/msg/DiagnosticArray`.
    pub diagnostics_topic: String,
    /// The navigation frame id (`header.frame_id` of the outputs).
    pub map_frame: String,
    /// The body frame id (`child_frame_id` of the odometry).
    pub base_frame: String,
    /// Most poses published per second (0: one per filter step).
    pub publish_rate_hz: f64,
    /// Seconds between diagnostics messages.
    pub diagnostics_period_s: f64,
    /// A sensor that has sent nothing for this long (wall clock, s) is reported silent.
    pub silent_after_s: f64,
    /// Seconds of data (sensor time) the node watches before choosing its model (`best`'s
    /// model choice); 0 keeps the configuration as given.
    pub choose_after_s: f64,
    /// Baud rate of a LinkTrack serial port.
    pub linktrack_baud: u32,
    /// Subscribe reliable with the whole history kept: a reliable publisher then loses no sample
    /// to a busy node (its latency grows instead), but a best-effort one (ROS 2's sensor-data
    /// profile) is no longer matched. False: best effort, keep last 1000, matching both.
    pub reliable_inputs: bool,
    /// Lag of the fixed-lag smoothed pose, s (finite, ≥ 0; the streaming classes' `lag_s`,
    /// `FixedLag` of `uwbimu_estimation::pipeline`); None (the key absent): none published.
    pub lag_s: Option<f64>,
    /// Output topic of the fixed-lag smoothed `geometry_msgs/msg/PoseWithCovarianceStamped`
    /// (published only with `lag_s`).
    pub smoothed_pose_topic: String,
}

impl Default for LiveSettings {
    fn default() -> Self {
        Self {
            domain_id: 0,
            types: BTreeMap::new(),
            msg_paths: Vec::new(),
            pose_topic: "/uwbimu/pose".into(),
            odometry_topic: "/uwbimu/odometry".into(),
            diagnostics_topic: "/diagnostics".into(),
            map_frame: "map".into(),
            base_frame: "base_link".into(),
            publish_rate_hz: 0.0,
            diagnostics_period_s: 1.0,
            silent_after_s: 1.0,
            choose_after_s: 60.0,
            linktrack_baud: 921_600,
            reliable_inputs: false,
            lag_s: None,
            smoothed_pose_topic: "/uwbimu/pose_smoothed".into(),
        }
    }
}

/// One input topic of the node: its name, ROS 2 type and full `.msg` definition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Subscription {
    /// ROS 2 topic name (`/imu`).
    pub topic: String,
    /// ROS 2 type (`sensor_msgs/msg/Imu`); None for a UWB topic whose type is not named.
    pub type_name: Option<String>,
    /// The definition with its dependencies, as an MCAP `ros2msg` schema carries it; None when
    /// the type is not named or its `.msg` is found nowhere.
    pub definition: Option<String>,
}

impl LiveSettings {
    /// Parses the `[live]` table.
    ///
    /// # Errors
    /// [`Error::Mapping`] (field `live`) for unknown keys or wrong types, or numbers out of range
    /// (`lag_s` negative or not finite among them).
    pub fn from_value(value: serde_json::Value) -> Result<Self> {
        let s: Self = serde_json::from_value(value)
            .map_err(|e| Error::from(CoreError::InvalidConfig { field: "live".into(), reason: e.to_string() }))?;
        let positive = [("live.diagnostics_period_s", s.diagnostics_period_s), ("live.silent_after_s", s.silent_after_s)];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return Err(CoreError::InvalidConfig { field: field.into(), reason: format!("must be > 0, got {v}") }.into());
            }
        }
        let lag = s.lag_s.map(|v| ("live.lag_s", v));
        for (field, v) in
            [("live.publish_rate_hz", s.publish_rate_hz), ("live.choose_after_s", s.choose_after_s)].into_iter().chain(lag)
        {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CoreError::InvalidConfig { field: field.into(), reason: format!("must be >= 0, got {v}") }.into());
            }
        }
        Ok(s)
    }

    /// Whether the node finds its topics on the graph: the mapping names no UWB or TDoA topic,
    /// so every publication whose type the mapping can read is taken, as a file read takes
    /// every channel.
    pub fn discovers(mapping: &Mapping) -> bool {
        mapping.uwb.topics.is_empty() && mapping.tdoa.topics.is_empty()
    }

    /// The topics to subscribe to for `mapping`, with their types and definitions: the IMU
    /// topic (`imu_topic`, default `/imu` unless the node [discovers](Self::discovers) its
    /// topics), then the UWB topics, then each sensor's (in the registry's order, [`SENSORS`]).
    /// A UWB topic without a type in `live.types` has none (the node learns it from the graph);
    /// a type whose `.msg` is found nowhere has no definition.
    pub fn subscriptions(&self, mapping: &Mapping) -> Vec<Subscription> {
        let imu = mapping.imu_topic.clone().or_else(|| (!Self::discovers(mapping)).then(|| "/imu".to_string()));
        let mut wanted: Vec<(String, Option<&str>)> = imu.into_iter().map(|t| (t, Some("sensor_msgs/msg/Imu"))).collect();
        wanted.extend(mapping.uwb.topics.iter().map(|t| (t.clone(), None)));
        for row in SENSORS {
            wanted.extend(row.topics(mapping).iter().map(|t| (t.clone(), row.reads().first().copied())));
        }
        wanted
            .into_iter()
            .map(|(topic, default)| {
                let type_name = self.types.get(&topic).map(String::as_str).or(default).map(str::to_string);
                let definition = type_name.as_deref().and_then(|t| full_definition(t, &self.msg_paths).ok());
                Subscription { topic, type_name, definition }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_unknown_keys_and_subscriptions() {
        let s =
            LiveSettings::from_value(serde_json::json!({"domain_id": 3, "types": {"/uwb": "sensor_msgs/msg/Range"}})).unwrap();
        assert_eq!((s.domain_id, s.map_frame.as_str(), s.choose_after_s), (3, "map", 60.0));
        let e = LiveSettings::from_value(serde_json::json!({"domain": 3})).unwrap_err().to_string();
        assert!(e.contains("unknown field `domain`"), "{e}");
        assert!(LiveSettings::from_value(serde_json::json!({"silent_after_s": 0})).is_err());
        assert_eq!((s.lag_s, s.smoothed_pose_topic.as_str()), (None, "/uwbimu/pose_smoothed"));
        assert_eq!(LiveSettings::from_value(serde_json::json!({"lag_s": 1.5})).unwrap().lag_s, Some(1.5));
        let e = LiveSettings::from_value(serde_json::json!({"lag_s": -1.0})).unwrap_err().to_string();
        assert!(e.contains("live.lag_s"), "{e}");
        let mut mapping = Mapping::default();
        assert!(LiveSettings::discovers(&mapping) && s.subscriptions(&mapping).is_empty());
        mapping.uwb.topics = vec!["/uwb".into(), "/ranges".into(), "/vendor".into()];
        let vendor = LiveSettings::from_value(
            serde_json::json!({"types": {"/uwb": "sensor_msgs/msg/Range", "/vendor": "vendor/msg/Ranges"}}),
        )
        .unwrap();
        assert!(!LiveSettings::discovers(&mapping));
        let subs = vendor.subscriptions(&mapping);
        let names: Vec<(&str, Option<&str>, bool)> =
            subs.iter().map(|s| (s.topic.as_str(), s.type_name.as_deref(), s.definition.is_some())).collect();
        assert_eq!(
            names,
            [
                ("/imu", Some("sensor_msgs/msg/Imu"), true),
                ("/uwb", Some("sensor_msgs/msg/Range"), true),
                ("/ranges", None, false),
                ("/vendor", Some("vendor/msg/Ranges"), false),
            ]
        );
    }
}
