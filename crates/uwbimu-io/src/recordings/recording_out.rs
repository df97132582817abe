//! Writes a recording (e.g. the simulator's) as MCAP: IMU samples as CDR
//! `sensor_msgs/msg/Imu` with the ros2msg schema embedded, ranges as our JSON `uwbimu.UwbRange`,
//! the other sensors on the topics of [`sensor_topic`] (TDoA as CDR `uwbimu_msgs/msg/Tdoa`
//! ([`TDOA_MSG`]), heights as `sensor_msgs/msg/Range`, body velocities as `nav_msgs/msg/Odometry`),
//! anchor positions in the metadata record `uwbimu.anchors`. Zstd chunks; profile "" (JSON
//! channels are present). A log of anchor-to-anchor ranges, the anchor survey's input, is written
//! on its own ([`write_anchor_ranges_mcap`]).

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::{IoError as Error, IoResult as Result};
use mcap::records::{MessageHeader, Metadata};
use mcap::WriteOptions;
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use crate::files::anchors::ANCHORS_METADATA;
use crate::mapping::topics::{RawAnchorRange, ANCHOR_RANGE_MSG_NAME, TDOA_MSG_NAME, UWB_RANGE_JSON, UWB_RANGE_JSON_SCHEMA};
use crate::ros::payloads::{altitude_cdr, anchor_range_cdr, imu_cdr, odometry_cdr, range_json, split_time, tdoa_cdr};

/// The ros2msg text of a header's dependencies (`std_msgs/Header`, `builtin_interfaces/Time`),
/// appended to the definitions that have a header.
macro_rules! header_dependencies {
    () => {
        "================================================================================\nMSG: std_msgs/Header\n\
builtin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\nMSG: builtin_interfaces/Time\n\
int32 sec\nuint32 nanosec\n"
    };
}

/// The ros2msg text of `sensor_msgs/msg/Imu` with its dependencies.
pub const IMU_MSG: &str = concat!(
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
float64[9] linear_acceleration_covariance\n",
    header_dependencies!(),
    "================================================================================\nMSG: geometry_msgs/Quaternion\n\
float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n\
================================================================================\nMSG: geometry_msgs/Vector3\n\
float64 x\nfloat64 y\nfloat64 z\n"
);

/// The ros2msg text of our TDoA message [`TDOA_MSG_NAME`]: the fields of the Crazyflie `estTDOA`
/// event (`distanceDiff` = distance to anchor `idB` minus distance to anchor `idA`, m) with a
/// header and the anchor ids as text.
pub const TDOA_MSG: &str =
    concat!("std_msgs/Header header\nstring idA\nstring idB\nfloat64 distanceDiff\n", header_dependencies!());

/// The ros2msg text of our anchor-to-anchor range message [`ANCHOR_RANGE_MSG_NAME`]: a header,
/// the ids of the two anchors as text and the distance between them, m.
pub const ANCHOR_RANGE_MSG: &str =
    concat!("std_msgs/Header header\nstring anchor_i\nstring anchor_j\nfloat64 range\n", header_dependencies!());

/// The topic [`write_anchor_ranges_mcap`] writes anchor-to-anchor ranges to.
pub const ANCHOR_RANGE_TOPIC: &str = "/anchor_ranges";

/// The ros2msg text of `sensor_msgs/msg/Range` (Humble: without `variance`) with its dependencies.
pub const RANGE_MSG: &str = concat!(
    "uint8 ULTRASOUND=0\nuint8 INFRARED=1\nstd_msgs/Header header\nuint8 radiation_type\nfloat32 field_of_view\n\
float32 min_range\nfloat32 max_range\nfloat32 range\n",
    header_dependencies!()
);

/// The ros2msg text of `nav_msgs/msg/Odometry` with its dependencies.
pub const ODOMETRY_MSG: &str = concat!(
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
geometry_msgs/TwistWithCovariance twist\n",
    header_dependencies!(),
    "================================================================================\nMSG: geometry_msgs/PoseWithCovariance\n\
geometry_msgs/Pose pose\nfloat64[36] covariance\n\
================================================================================\nMSG: geometry_msgs/Pose\n\
geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n\
================================================================================\nMSG: geometry_msgs/Point\n\
float64 x\nfloat64 y\nfloat64 z\n\
================================================================================\nMSG: geometry_msgs/Quaternion\n\
float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n\
================================================================================\nMSG: geometry_msgs/TwistWithCovariance\n\
geometry_msgs/Twist twist\nfloat64[36] covariance\n\
================================================================================\nMSG: geometry_msgs/Twist\n\
geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n\
================================================================================\nMSG: geometry_msgs/Vector3\n\
float64 x\nfloat64 y\nfloat64 z\n"
);

/// How a sensor's readings are written: (topic, schema name, ros2msg text); None for a sensor
/// without a message yet (the magnetometer). Reading them back needs the topic in the mapping
/// (`[mapping.altitude] topics = ["/altitude"]`, `[mapping.odometry] topics = ["/odom"]`), except
/// TDoA, whose schema is recognised.
pub fn sensor_topic(kind: SensorKind) -> Option<(&'static str, &'static str, &'static str)> {
    match kind {
        SensorKind::Tdoa => Some(("/tdoa", TDOA_MSG_NAME, TDOA_MSG)),
        SensorKind::Altitude => Some(("/altitude", "sensor_msgs/msg/Range", RANGE_MSG)),
        SensorKind::Odometry => Some(("/odom", "nav_msgs/msg/Odometry", ODOMETRY_MSG)),
        SensorKind::Magnetometer | SensorKind::PoseFix => None,
    }
}

/// The streams [`write_recording_mcap`] writes, each time-ordered; anchor `k` is written with
/// the id `A{k}`.
#[derive(Debug, Clone, Copy, Default)]
pub struct RecordingStreams<'a> {
    /// IMU samples (topic `/imu`).
    pub imu: &'a [ImuSample],
    /// Ranges (topic `/uwb`, left out when there are TDoA and no ranges).
    pub ranges: &'a [RangeMeasurement],
    /// The other sensors' readings, in time order, each on its topic ([`sensor_topic`]).
    pub observations: &'a [Observation],
    /// Anchor positions (the `uwbimu.anchors` metadata record), m.
    pub anchors: &'a [Vec3],
}

/// Writes the IMU samples (topic `/imu`), ranges (topic `/uwb`, with variance `range_std_m²`
/// when given) and the other sensors' readings (their [`sensor_topic`]; odometry readings of one
/// time in one message) of `streams` in time order (at equal times IMU, range, the others) plus
/// the anchor metadata, in zstd chunks when `compress`. `label` names the output in errors.
///
/// # Errors
/// [`Error::Io`] if writing fails; [`CoreError::InvalidCall`] for readings of a sensor without a
/// message ([`sensor_topic`]).
pub fn write_recording_mcap<W: Write + Seek>(
    sink: W,
    label: &str,
    streams: &RecordingStreams<'_>,
    range_std_m: Option<f64>,
    compress: bool,
) -> Result<()> {
    let RecordingStreams { imu, ranges, observations, anchors } = *streams;
    if let Some(o) = observations.iter().find(|o| sensor_topic(o.kind()).is_none()) {
        return Err(CoreError::InvalidCall(format!("{} cannot be written to MCAP yet", o.kind().info().label)).into());
    }
    let err = |source: mcap::McapError| Error::Mcap { path: label.to_string(), source };
    let mut w =
        WriteOptions::new().profile("").compression(compress.then_some(mcap::Compression::Zstd)).create(sink).map_err(err)?;
    let imu_schema = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_MSG.as_bytes()).map_err(err)?;
    let imu_ch = w.add_channel(imu_schema, "/imu", "cdr", &BTreeMap::new()).map_err(err)?;
    let mut uwb_ch = None;
    if !ranges.is_empty() || !observations.iter().any(|o| o.kind() == SensorKind::Tdoa) {
        let uwb_schema = w.add_schema(UWB_RANGE_JSON, "jsonschema", UWB_RANGE_JSON_SCHEMA.as_bytes()).map_err(err)?;
        uwb_ch = Some(w.add_channel(uwb_schema, "/uwb", "json", &BTreeMap::new()).map_err(err)?);
    }
    let mut sensor_ch = BTreeMap::new();
    for kind in SensorKind::ALL.iter().filter(|k| observations.iter().any(|o| o.kind() == **k)) {
        let Some((topic, schema, text)) = sensor_topic(*kind) else { continue };
        let id = w.add_schema(schema, "ros2msg", text.as_bytes()).map_err(err)?;
        sensor_ch.insert(*kind, w.add_channel(id, topic, "cdr", &BTreeMap::new()).map_err(err)?);
    }
    let metadata = anchors.iter().enumerate().map(|(i, a)| (format!("A{i}"), format!("[{}, {}, {}]", a.x, a.y, a.z))).collect();
    w.write_metadata(&Metadata { name: ANCHORS_METADATA.into(), metadata }).map_err(err)?;
    let variance = range_std_m.map(|s| s * s);
    let (mut next, mut sequence) = ([0usize; 3], 0u32);
    loop {
        let times = [
            imu.get(next[0]).map(|s| s.t_s),
            ranges.get(next[1]).map(|r| r.t_s),
            observations.get(next[2]).map(Observation::t_s),
        ];
        // The stream with the earliest next message; the first one wins ties.
        let Some((stream, t)) = (0..3).filter_map(|k| Some((k, times[k]?))).min_by(|a, b| a.1.total_cmp(&b.1)) else {
            break;
        };
        let k = next[stream];
        next[stream] += 1;
        let (channel_id, data) = match stream {
            0 => (imu_ch, imu_cdr(&imu[k])),
            1 => {
                let Some(uwb) = uwb_ch else { continue }; // no ranges: never reached
                (uwb, range_json(t, &format!("A{}", ranges[k].anchor), ranges[k].range_m, variance, ranges[k].tag))
            }
            _ => {
                let o = observations[k];
                let data = match o {
                    Observation::Tdoa(m) => tdoa_cdr(&m),
                    Observation::Altitude(a) => altitude_cdr(t, a.z_m),
                    Observation::Odometry(_) => {
                        // The readings of one time, one per axis, make one message.
                        let same_time = |o: &&Observation| matches!(o, Observation::Odometry(r) if r.t_s == t);
                        let mut velocity = [f64::NAN; 3];
                        for o in observations[k..].iter().take_while(same_time) {
                            if let Observation::Odometry(r) = o {
                                velocity[r.axis] = r.speed_mps;
                            }
                        }
                        next[2] = k + observations[k..].iter().take_while(same_time).count();
                        odometry_cdr(t, velocity)
                    }
                    Observation::Magnetometer(_) | Observation::PoseFix(_) => continue,
                };
                (sensor_ch.get(&o.kind()).copied().unwrap_or(imu_ch), data)
            }
        };
        sequence += 1;
        let ns = split_time(t).2;
        w.write_to_known_channel(&MessageHeader { channel_id, sequence, log_time: ns, publish_time: ns }, &data).map_err(err)?;
    }
    w.finish().map_err(err)?;
    Ok(())
}

/// Writes anchor-to-anchor ranges `(time s, range)`, in the order given, as CDR
/// [`ANCHOR_RANGE_MSG`] on [`ANCHOR_RANGE_TOPIC`] (log time = header stamp), in zstd chunks when
/// `compress`; the file holds nothing else. `label` names the output in errors.
///
/// # Errors
/// [`Error::Mcap`] if writing fails.
pub fn write_anchor_ranges_mcap<W: Write + Seek>(
    sink: W,
    label: &str,
    ranges: &[(f64, RawAnchorRange)],
    compress: bool,
) -> Result<()> {
    let err = |source: mcap::McapError| Error::Mcap { path: label.to_string(), source };
    let mut w =
        WriteOptions::new().profile("").compression(compress.then_some(mcap::Compression::Zstd)).create(sink).map_err(err)?;
    let schema = w.add_schema(ANCHOR_RANGE_MSG_NAME, "ros2msg", ANCHOR_RANGE_MSG.as_bytes()).map_err(err)?;
    let channel_id = w.add_channel(schema, ANCHOR_RANGE_TOPIC, "cdr", &BTreeMap::new()).map_err(err)?;
    for (sequence, (t_s, r)) in (1u32..).zip(ranges) {
        let ns = split_time(*t_s).2;
        let data = anchor_range_cdr(*t_s, &r.anchor_i, &r.anchor_j, r.range_m);
        w.write_to_known_channel(&MessageHeader { channel_id, sequence, log_time: ns, publish_time: ns }, &data).map_err(err)?;
    }
    w.finish().map_err(err)?;
    Ok(())
}
