//! Writes a recording (e.g. the simulator's) as MCAP: IMU samples as CDR
//! `sensor_msgs/msg/Imu` with the ros2msg schema embedded, ranges as our JSON `uwbimu.UwbRange`,
//! each other sensor as its io row says ([`SensorIo::written`], [`SensorIo::encode`]: TDoA as
//! CDR `uwbimu_msgs/msg/Tdoa` on `/tdoa`, heights as `sensor_msgs/msg/Range` on `/altitude`, body
//! velocities as `nav_msgs/msg/Odometry` on `/odom`, …), anchor positions in the metadata record
//! `uwbimu.anchors`. Zstd chunks; profile "" (JSON channels are present). A log of
//! anchor-to-anchor ranges, the anchor survey's input, is written on its own
//! ([`write_anchor_ranges_mcap`]).

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::{IoError as Error, IoResult as Result};
use mcap::records::{MessageHeader, Metadata};
use mcap::WriteOptions;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use crate::files::anchors::ANCHORS_METADATA;
use crate::mapping::topics::{sensor_io, RawAnchorRange, SensorIo, ANCHOR_RANGE_MSG_NAME, UWB_RANGE_JSON, UWB_RANGE_JSON_SCHEMA};
use crate::ros::payloads::{anchor_range_cdr, imu_cdr, range_json, split_time};
use crate::ros::types::full_definition;

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

/// The ros2msg text of our anchor-to-anchor range message [`ANCHOR_RANGE_MSG_NAME`]: a header,
/// the ids of the two anchors as text and the distance between them, m.
pub const ANCHOR_RANGE_MSG: &str =
    concat!("std_msgs/Header header\nstring anchor_i\nstring anchor_j\nfloat64 range\n", header_dependencies!());

/// The topic [`write_anchor_ranges_mcap`] writes anchor-to-anchor ranges to.
pub const ANCHOR_RANGE_TOPIC: &str = "/anchor_ranges";

/// The streams [`write_recording_mcap`] writes, each time-ordered; anchor `k` is written with
/// the id `A{k}`.
#[derive(Debug, Clone, Copy, Default)]
pub struct RecordingStreams<'a> {
    /// IMU samples (topic `/imu`).
    pub imu: &'a [ImuSample],
    /// Ranges (topic `/uwb`, left out when there are TDoA and no ranges).
    pub ranges: &'a [RangeMeasurement],
    /// The other sensors' readings, in time order, each on its topic ([`SensorIo::written`]).
    pub observations: &'a [Observation],
    /// Anchor positions (the `uwbimu.anchors` metadata record), m.
    pub anchors: &'a [Vec3],
}

/// Writes the IMU samples (topic `/imu`), ranges (topic `/uwb`, with variance `range_std_m²`
/// when given) and the other sensors' readings (as their io row writes them, [`SensorIo`];
/// odometry readings of one time in one message) of `streams` in time order (at equal times IMU,
/// range, the others) plus the anchor metadata, in zstd chunks when `compress`. `label` names the
/// output in errors.
///
/// # Errors
/// [`Error::Mcap`] if writing fails.
pub fn write_recording_mcap<W: Write + Seek>(
    sink: W,
    label: &str,
    streams: &RecordingStreams<'_>,
    range_std_m: Option<f64>,
    compress: bool,
) -> Result<()> {
    let RecordingStreams { imu, ranges, observations, anchors } = *streams;
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
    let mut sensor_ch: BTreeMap<SensorKind, (u16, &dyn SensorIo)> = BTreeMap::new();
    for kind in SensorKind::ALL.iter().filter(|k| observations.iter().any(|o| o.kind() == **k)) {
        let row = sensor_io(*kind);
        let (topic, type_name) = row.written();
        let id = w.add_schema(type_name, "ros2msg", full_definition(type_name, &[])?.as_bytes()).map_err(err)?;
        sensor_ch.insert(*kind, (w.add_channel(id, topic, "cdr", &BTreeMap::new()).map_err(err)?, row));
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
                // Every observation's sensor has its channel (added above), and its row encodes it.
                let Some(&(channel_id, row)) = sensor_ch.get(&observations[k].kind()) else { continue };
                let Some((data, n)) = row.encode(&observations[k..]) else { continue };
                next[2] = k + n;
                (channel_id, data)
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
