//! Writes a recording (e.g. the simulator's) as MCAP: IMU samples as CDR
//! `sensor_msgs/msg/Imu` with the ros2msg schema embedded, ranges as our JSON `uwbimu.UwbRange`,
//! anchor positions in the metadata record `uwbimu.anchors`. Zstd chunks; profile "" (JSON
//! channels are present).

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use mcap::records::{MessageHeader, Metadata};
use mcap::WriteOptions;
use serde_json::json;

use crate::error::{Error, Result};
use crate::io::anchors::ANCHORS_METADATA;
use crate::io::topics::{UWB_RANGE_JSON, UWB_RANGE_JSON_SCHEMA};
use crate::math::Vec3;
use crate::records::{ImuSample, RangeMeasurement};

/// The ros2msg text of `sensor_msgs/msg/Imu` with its dependencies.
pub const IMU_MSG: &str = "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\ngeometry_msgs/Vector3 linear_acceleration\n\
float64[9] linear_acceleration_covariance\n\
================================================================================\nMSG: std_msgs/Header\n\
builtin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\nMSG: builtin_interfaces/Time\n\
int32 sec\nuint32 nanosec\n\
================================================================================\nMSG: geometry_msgs/Quaternion\n\
float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n\
================================================================================\nMSG: geometry_msgs/Vector3\n\
float64 x\nfloat64 y\nfloat64 z\n";

/// Splits non-negative seconds into (sec, nanosec, total ns).
fn split_time(t_s: f64) -> (u64, u64, u64) {
    let ns = (t_s.max(0.0) * 1e9).round() as u64;
    (ns / 1_000_000_000, ns % 1_000_000_000, ns)
}

/// One IMU sample as XCDR1 little-endian `sensor_msgs/msg/Imu` (frame `imu_link`, identity
/// orientation with covariance[0] = −1 meaning "no orientation").
pub fn imu_cdr(s: &ImuSample) -> Vec<u8> {
    let (sec, nsec, _) = split_time(s.t_s);
    let mut b = Vec::with_capacity(324);
    b.extend_from_slice(&[0, 1, 0, 0]);
    b.extend_from_slice(&(sec as i32).to_le_bytes());
    b.extend_from_slice(&(nsec as u32).to_le_bytes());
    let frame = b"imu_link\0";
    b.extend_from_slice(&(frame.len() as u32).to_le_bytes());
    b.extend_from_slice(frame);
    while (b.len() - 4) % 8 != 0 {
        b.push(0);
    }
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

/// One range as `uwbimu.UwbRange` JSON.
pub fn range_json(t_s: f64, anchor_id: &str, range_m: f64, variance_m2: Option<f64>) -> Vec<u8> {
    let (sec, nsec, _) = split_time(t_s);
    let mut v = json!({"timestamp": {"sec": sec, "nsec": nsec}, "anchor_id": anchor_id, "range": range_m});
    if let Some(var) = variance_m2 {
        v["variance"] = json!(var);
    }
    v.to_string().into_bytes()
}

/// Writes IMU samples (topic `/imu`) and ranges (topic `/uwb`, anchor ids `A0`, `A1`, …) plus
/// the anchor metadata, in zstd chunks when `compress`. `label` names the output in errors.
///
/// # Errors
/// [`Error::Io`] if writing fails.
pub fn write_recording_mcap<W: Write + Seek>(
    sink: W,
    label: &str,
    imu: &[ImuSample],
    ranges: &[RangeMeasurement],
    anchors: &[Vec3],
    range_std_m: Option<f64>,
    compress: bool,
) -> Result<()> {
    let err = |e: mcap::McapError| Error::Io { path: label.to_string(), reason: e.to_string() };
    let mut w =
        WriteOptions::new().profile("").compression(compress.then_some(mcap::Compression::Zstd)).create(sink).map_err(err)?;
    let imu_schema = w.add_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_MSG.as_bytes()).map_err(err)?;
    let imu_ch = w.add_channel(imu_schema, "/imu", "cdr", &BTreeMap::new()).map_err(err)?;
    let uwb_schema = w.add_schema(UWB_RANGE_JSON, "jsonschema", UWB_RANGE_JSON_SCHEMA.as_bytes()).map_err(err)?;
    let uwb_ch = w.add_channel(uwb_schema, "/uwb", "json", &BTreeMap::new()).map_err(err)?;
    let metadata = anchors.iter().enumerate().map(|(i, a)| (format!("A{i}"), format!("[{}, {}, {}]", a.x, a.y, a.z))).collect();
    w.write_metadata(&Metadata { name: ANCHORS_METADATA.into(), metadata }).map_err(err)?;
    let variance = range_std_m.map(|s| s * s);
    let (mut i, mut j, mut sequence) = (0, 0, 0u32);
    while i < imu.len() || j < ranges.len() {
        let take_imu = j >= ranges.len() || (i < imu.len() && imu[i].t_s <= ranges[j].t_s);
        let (channel_id, t, data) = if take_imu {
            i += 1;
            (imu_ch, imu[i - 1].t_s, imu_cdr(&imu[i - 1]))
        } else {
            let r = &ranges[j];
            j += 1;
            (uwb_ch, r.t_s, range_json(r.t_s, &format!("A{}", r.anchor), r.range_m, variance))
        };
        sequence += 1;
        let ns = split_time(t).2;
        w.write_to_known_channel(&MessageHeader { channel_id, sequence, log_time: ns, publish_time: ns }, &data).map_err(err)?;
    }
    w.finish().map_err(err)?;
    Ok(())
}
