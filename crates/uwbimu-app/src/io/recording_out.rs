//! Writes a recording (e.g. the simulator's) as MCAP: IMU samples as CDR
//! `sensor_msgs/msg/Imu` with the ros2msg schema embedded, ranges as our JSON `uwbimu.UwbRange`,
//! the other sensors on the topics of [`sensor_topic`] (TDoA as CDR `uwbimu_msgs/msg/Tdoa`
//! ([`TDOA_MSG`]), heights as `sensor_msgs/msg/Range`, body velocities as `nav_msgs/msg/Odometry`),
//! anchor positions in the metadata record `uwbimu.anchors`. Zstd chunks; profile "" (JSON
//! channels are present). A log of anchor-to-anchor ranges, the anchor survey's input, is written
//! on its own ([`write_anchor_ranges_mcap`]).

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use crate::io::{IoError as Error, IoResult as Result};
use mcap::records::{MessageHeader, Metadata};
use mcap::WriteOptions;
use serde_json::json;
use uwbimu_vocabulary::error::Error as CoreError;
use uwbimu_vocabulary::math::Vec3;
use uwbimu_vocabulary::records::{ImuSample, RangeMeasurement, TdoaMeasurement};
use uwbimu_vocabulary::sensors::{Observation, SensorKind};

use crate::io::anchors::ANCHORS_METADATA;
use crate::io::topics::{RawAnchorRange, ANCHOR_RANGE_MSG_NAME, TDOA_MSG_NAME, UWB_RANGE_JSON, UWB_RANGE_JSON_SCHEMA};

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
        SensorKind::Magnetometer => None,
    }
}

/// Splits non-negative seconds into (sec, nanosec, total ns).
fn split_time(t_s: f64) -> (u64, u64, u64) {
    let ns = (t_s.max(0.0) * 1e9).round() as u64;
    (ns / 1_000_000_000, ns % 1_000_000_000, ns)
}

/// Appends an XCDR1 little-endian string (aligned to 4 after the encapsulation header).
pub(crate) fn push_cdr_string(b: &mut Vec<u8>, text: &str) {
    while (b.len() - 4) % 4 != 0 {
        b.push(0);
    }
    b.extend_from_slice(&(text.len() as u32 + 1).to_le_bytes());
    b.extend_from_slice(text.as_bytes());
    b.push(0);
}

/// Starts an XCDR1 little-endian message: the encapsulation header and a `std_msgs/Header`.
pub(crate) fn cdr_with_header(t_s: f64, frame_id: &str, capacity: usize) -> Vec<u8> {
    let (sec, nsec, _) = split_time(t_s);
    let mut b = Vec::with_capacity(capacity);
    b.extend_from_slice(&[0, 1, 0, 0]);
    b.extend_from_slice(&(sec as i32).to_le_bytes());
    b.extend_from_slice(&(nsec as u32).to_le_bytes());
    push_cdr_string(&mut b, frame_id);
    b
}

/// One range as XCDR1 little-endian `uwbimu_msgs/msg/UwbRange` (see
/// [`crate::io::topics::UWB_RANGE_MSG_NAME`]), stamped `(sec, nanosec)`, frame `uwb`.
pub fn uwb_range_cdr((sec, nsec): (i32, u32), anchor_id: &str, range_m: f64, variance_m2: f64, tag: &str) -> Vec<u8> {
    let mut b = Vec::with_capacity(64);
    b.extend_from_slice(&[0, 1, 0, 0]);
    b.extend_from_slice(&sec.to_le_bytes());
    b.extend_from_slice(&nsec.to_le_bytes());
    push_cdr_string(&mut b, "uwb");
    push_cdr_string(&mut b, anchor_id);
    align8(&mut b);
    b.extend_from_slice(&range_m.to_le_bytes());
    b.extend_from_slice(&variance_m2.to_le_bytes());
    push_cdr_string(&mut b, tag);
    b
}

/// Pads an XCDR1 message to the next 8-byte boundary (before a float64).
pub(crate) fn align8(b: &mut Vec<u8>) {
    while (b.len() - 4) % 8 != 0 {
        b.push(0);
    }
}

/// One IMU sample as XCDR1 little-endian `sensor_msgs/msg/Imu` (frame `imu_link`, identity
/// orientation with `covariance[0] = −1` meaning "no orientation").
pub fn imu_cdr(s: &ImuSample) -> Vec<u8> {
    let mut b = cdr_with_header(s.t_s, "imu_link", 324);
    align8(&mut b);
    let mut doubles = [0.0f64; 37];
    doubles[3] = 1.0; // orientation w
    doubles[4] = -1.0; // orientation unknown
    doubles[13..16].copy_from_slice(s.gyro.as_slice());
    doubles[25..28].copy_from_slice(s.accel.as_slice());
    for d in doubles {
        b.extend_from_slice(&d.to_le_bytes());
    }
    b
}

/// One range as `uwbimu.UwbRange` JSON; a tag beyond 0 is written as its index (`"tag": "1"`).
pub fn range_json(t_s: f64, anchor_id: &str, range_m: f64, variance_m2: Option<f64>, tag: usize) -> Vec<u8> {
    let (sec, nsec, _) = split_time(t_s);
    let mut v = json!({"timestamp": {"sec": sec, "nsec": nsec}, "anchor_id": anchor_id, "range": range_m});
    if let Some(var) = variance_m2 {
        v["variance"] = json!(var);
    }
    if tag > 0 {
        v["tag"] = json!(tag.to_string());
    }
    v.to_string().into_bytes()
}

/// A message of two anchor ids and a float64 after the header, as XCDR1 little-endian (the
/// layout of [`TDOA_MSG`] and [`ANCHOR_RANGE_MSG`]).
fn id_pair_cdr(t_s: f64, anchor_i: &str, anchor_j: &str, value: f64) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "", 48);
    push_cdr_string(&mut b, anchor_i);
    push_cdr_string(&mut b, anchor_j);
    align8(&mut b);
    b.extend_from_slice(&value.to_le_bytes());
    b
}

/// One TDoA as XCDR1 little-endian [`TDOA_MSG`], anchor ids `A{i}`, `A{j}`.
pub fn tdoa_cdr(m: &TdoaMeasurement) -> Vec<u8> {
    id_pair_cdr(m.t_s, &format!("A{}", m.anchor_i), &format!("A{}", m.anchor_j), m.tdoa_m)
}

/// One anchor-to-anchor range as XCDR1 little-endian [`ANCHOR_RANGE_MSG`].
pub fn anchor_range_cdr(t_s: f64, anchor_i: &str, anchor_j: &str, range_m: f64) -> Vec<u8> {
    id_pair_cdr(t_s, anchor_i, anchor_j, range_m)
}

/// One height as XCDR1 little-endian [`RANGE_MSG`] (frame `altimeter`, infrared), `range = z`;
/// its limits are wide open (`±f32::MAX`), as a simulated height may be negative.
pub fn altitude_cdr(t_s: f64, z_m: f64) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "altimeter", 48);
    b.push(1); // radiation_type INFRARED
    while (b.len() - 4) % 4 != 0 {
        b.push(0);
    }
    for v in [0.0, -f32::MAX, f32::MAX, z_m as f32] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

/// One body velocity as XCDR1 little-endian [`ODOMETRY_MSG`] (frames `odom` → `base_link`,
/// identity pose, zero covariances), NaN for an axis not measured.
pub fn odometry_cdr(t_s: f64, velocity: [f64; 3]) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "odom", 720);
    push_cdr_string(&mut b, "base_link");
    align8(&mut b);
    let mut doubles = [0.0f64; 85];
    doubles[6] = 1.0; // orientation w
    doubles[43..46].copy_from_slice(&velocity);
    for d in doubles {
        b.extend_from_slice(&d.to_le_bytes());
    }
    b
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
                    Observation::Magnetometer(_) => continue,
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
