//! Message payloads as bytes: the pieces of XCDR1 little-endian CDR every encoder uses (header,
//! strings, alignment), and an encoder per message we write that no sensor's io row owns
//! (`sensor_msgs/msg/Imu`, our `uwbimu_msgs` anchor-range and UWB-range messages) and the
//! `uwbimu.UwbRange` JSON; each sensor's message is encoded in its row
//! ([`crate::mapping::topics::SensorIo::encode`]). The recording writer
//! ([`crate::recordings::recording_out`]) and the topic converters use them.

use serde_json::json;
use uwbimu_vocabulary::records::ImuSample;

/// Splits non-negative seconds into (sec, nanosec, total ns).
pub(crate) fn split_time(t_s: f64) -> (u64, u64, u64) {
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
/// [`crate::mapping::topics::UWB_RANGE_MSG_NAME`]), stamped `(sec, nanosec)`, frame `uwb`.
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
/// layout of [`TDOA_MSG_NAME`](crate::mapping::topics::TDOA_MSG_NAME) and [`ANCHOR_RANGE_MSG`](crate::recordings::recording_out::ANCHOR_RANGE_MSG)).
pub(crate) fn id_pair_cdr(t_s: f64, anchor_i: &str, anchor_j: &str, value: f64) -> Vec<u8> {
    let mut b = cdr_with_header(t_s, "", 48);
    push_cdr_string(&mut b, anchor_i);
    push_cdr_string(&mut b, anchor_j);
    align8(&mut b);
    b.extend_from_slice(&value.to_le_bytes());
    b
}

/// One anchor-to-anchor range as XCDR1 little-endian [`ANCHOR_RANGE_MSG`](crate::recordings::recording_out::ANCHOR_RANGE_MSG).
pub fn anchor_range_cdr(t_s: f64, anchor_i: &str, anchor_j: &str, range_m: f64) -> Vec<u8> {
    id_pair_cdr(t_s, anchor_i, anchor_j, range_m)
}
