//! Nooploop LinkTrack serial frames, as pure functions over bytes: the decoders and encoders of
//! `NodeFrame2` and `TagFrame0` ([`decode_frame`], [`encode_node_frame2`], [`encode_tag_frame0`])
//! and a resynchronising stream decoder for a serial port's byte stream ([`LinkTrackStream`]).
//! No I/O happens here; the caller reads the port and hands the bytes over.
//!
//! Every LinkTrack frame starts with the header byte `0x55` and a function mark saying which
//! frame it is, and ends with a checksum byte: the low 8 bits of the sum of every byte before it.
//! Multi-byte fields are little-endian. `int24` is a signed 24-bit integer in three bytes; the
//! scale factors (position ×1000, velocity ×10000, distance ×1000, voltage ×1000, angle ×100,
//! eop ×100, signal powers ÷ −2) follow the vendor's protocol and its public parser
//! (nooploop-dev/nlink_parser, whose unit-test frames the tests decode). The layouts are given
//! byte by byte on [`NodeFrame2`] and [`TagFrame0`]; see also `docs/linktrack.md`.

mod frames;
mod stream;
#[cfg(test)]
mod tests;

pub use frames::{checksum, decode_frame, decode_node_frame2, decode_tag_frame0, encode_node_frame2, encode_tag_frame0};
pub use stream::{LinkTrackCounts, LinkTrackStream};

/// The first byte of every LinkTrack frame.
pub const FRAME_HEADER: u8 = 0x55;
/// The function mark (second byte) of `NodeFrame2`.
pub const NODE_FRAME2_MARK: u8 = 0x04;
/// The function mark (second byte) of `TagFrame0`.
pub const TAG_FRAME0_MARK: u8 = 0x01;
/// The length of `TagFrame0`, bytes (fixed; the frame has no length field).
pub const TAG_FRAME0_LEN: usize = 128;
/// The bytes of `NodeFrame2` before its first node block.
pub const NODE_FRAME2_FIXED_LEN: usize = 119;
/// The bytes of one node block of `NodeFrame2`.
pub const NODE_FRAME2_NODE_LEN: usize = 13;
/// The most nodes one `NodeFrame2` can carry (its node count is one byte).
pub const NODE_FRAME2_MAX_NODES: usize = 255;
/// The shortest `NodeFrame2`, bytes: no nodes.
pub const NODE_FRAME2_MIN_LEN: usize = NODE_FRAME2_FIXED_LEN + 1;
/// The longest `NodeFrame2`, bytes: [`NODE_FRAME2_MAX_NODES`] nodes. The stream decoder rejects a
/// longer declared length at once.
pub const NODE_FRAME2_MAX_LEN: usize = NODE_FRAME2_FIXED_LEN + NODE_FRAME2_MAX_NODES * NODE_FRAME2_NODE_LEN + 1;

/// One node (usually an anchor) a `NodeFrame2` ranged to: a 13-byte block after the frame's
/// fixed part, at offset `119 + 13 i` for node `i`.
///
/// | bytes | field | type | scale |
/// |---|---|---|---|
/// | 0 | `role` | u8 | |
/// | 1 | `id` | u8 | |
/// | 2..5 | `range_m` | int24 | ÷ 1000 → m |
/// | 5 | `fp_rssi_dbm` | u8 | ÷ −2 → dBm |
/// | 6 | `rx_rssi_dbm` | u8 | ÷ −2 → dBm |
/// | 7..11 | `system_time_ms` | u32 | ms |
/// | 11..13 | reserved | | written as zeros |
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeRange2 {
    /// The node's role: 0 node, 1 anchor, 2 tag, 3 console, 4 DT master, 5 DT slave, 6 monitor.
    pub role: u8,
    /// The node's id.
    pub id: u8,
    /// The measured distance to the node, m (1 mm steps).
    pub range_m: f64,
    /// First-path received signal power, dBm (0.5 dB steps, 0 to −127.5).
    pub fp_rssi_dbm: f64,
    /// Total received signal power, dBm (0.5 dB steps, 0 to −127.5).
    pub rx_rssi_dbm: f64,
    /// The network (system) time of this node's measurement, ms.
    pub system_time_ms: u32,
}

/// `NodeFrame2` (header `0x55`, function mark `0x04`): one node's state, its IMU and its ranges to
/// the other nodes; variable length, `119 + 13 n + 1` bytes for `n` nodes.
///
/// | bytes | field | type | scale |
/// |---|---|---|---|
/// | 0 | header `0x55` | u8 | |
/// | 1 | function mark `0x04` | u8 | |
/// | 2..4 | frame length (whole frame) | u16 | bytes |
/// | 4 | `role` | u8 | |
/// | 5 | `id` | u8 | |
/// | 6..10 | `system_time_ms` | u32 | ms |
/// | 10..13 | `eop_m` x, y, z | 3 × u8 | ÷ 100 → m |
/// | 13..22 | `position_m` x, y, z | 3 × int24 | ÷ 1000 → m |
/// | 22..31 | `velocity_mps` x, y, z | 3 × int24 | ÷ 10000 → m/s |
/// | 31..40 | reserved | | |
/// | 40..52 | `gyro_rad_s` x, y, z | 3 × f32 | rad/s |
/// | 52..64 | `accel_mps2` x, y, z | 3 × f32 | m/s² |
/// | 64..76 | reserved | | |
/// | 76..82 | `angle_deg` roll, pitch, yaw | 3 × i16 | ÷ 100 → ° |
/// | 82..98 | `quaternion_wxyz` w, x, y, z | 4 × f32 | |
/// | 98..102 | reserved | | |
/// | 102..106 | `local_time_ms` | u32 | ms |
/// | 106..116 | reserved | | |
/// | 116..118 | `voltage_v` | u16 | ÷ 1000 → V |
/// | 118 | valid node count `n` (= `nodes.len()`) | u8 | |
/// | 119.. | `nodes`, 13 bytes each ([`NodeRange2`]) | | |
/// | last | checksum | u8 | sum of all bytes before, mod 256 |
///
/// The decoder requires the length field to equal `120 + 13 n`; reserved bytes are read over and
/// written as zeros.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeFrame2 {
    /// The sending node's role: 0 node, 1 anchor, 2 tag, 3 console, 4 DT master, 5 DT slave,
    /// 6 monitor.
    pub role: u8,
    /// The sending node's id.
    pub id: u8,
    /// The node's own clock since power-up, ms.
    pub local_time_ms: u32,
    /// The network (system) time, shared by the nodes, ms.
    pub system_time_ms: u32,
    /// Estimated precision of `position_m` per axis, m (0.01 m steps, at most 2.55).
    pub eop_m: [f64; 3],
    /// Position x, y, z in the LinkTrack frame, m (1 mm steps).
    pub position_m: [f64; 3],
    /// Velocity x, y, z, m/s (0.1 mm/s steps).
    pub velocity_mps: [f64; 3],
    /// Gyroscope x, y, z, rad/s (single precision on the wire).
    pub gyro_rad_s: [f64; 3],
    /// Accelerometer x, y, z, m/s² (single precision on the wire).
    pub accel_mps2: [f64; 3],
    /// Euler angles roll, pitch, yaw, degrees (0.01° steps).
    pub angle_deg: [f64; 3],
    /// Attitude quaternion w, x, y, z (single precision on the wire).
    pub quaternion_wxyz: [f64; 4],
    /// Supply voltage, V (1 mV steps).
    pub voltage_v: f64,
    /// The nodes ranged to, in frame order (the frame's valid node count is their number).
    pub nodes: Vec<NodeRange2>,
}

/// `TagFrame0` (header `0x55`, function mark `0x01`): a tag's position, its distances to up to
/// eight anchors and its IMU; fixed length 128 bytes, no length field.
///
/// | bytes | field | type | scale |
/// |---|---|---|---|
/// | 0 | header `0x55` | u8 | |
/// | 1 | function mark `0x01` | u8 | |
/// | 2 | `id` | u8 | |
/// | 3 | `role` | u8 | |
/// | 4..13 | `position_m` x, y, z | 3 × int24 | ÷ 1000 → m |
/// | 13..22 | `velocity_mps` x, y, z | 3 × int24 | ÷ 10000 → m/s |
/// | 22..46 | `distances_m` to anchors 0..8 | 8 × int24 | ÷ 1000 → m |
/// | 46..58 | `gyro_rad_s` x, y, z | 3 × f32 | rad/s |
/// | 58..70 | `accel_mps2` x, y, z | 3 × f32 | m/s² |
/// | 70..82 | reserved | | |
/// | 82..88 | `angle_deg` roll, pitch, yaw | 3 × i16 | ÷ 100 → ° |
/// | 88..104 | `quaternion_wxyz` w, x, y, z | 4 × f32 | |
/// | 104..108 | reserved | | |
/// | 108..112 | `local_time_ms` | u32 | ms |
/// | 112..116 | `system_time_ms` | u32 | ms |
/// | 116 | reserved | | |
/// | 117..120 | `eop_m` x, y, z | 3 × u8 | ÷ 100 → m |
/// | 120..122 | `voltage_v` | u16 | ÷ 1000 → V |
/// | 122..127 | reserved | | |
/// | 127 | checksum | u8 | sum of all bytes before, mod 256 |
///
/// Note the order: `id` comes before `role` here, after it in `NodeFrame2`.
#[derive(Debug, Clone, PartialEq)]
pub struct TagFrame0 {
    /// The tag's role (2 for a tag).
    pub role: u8,
    /// The tag's id.
    pub id: u8,
    /// Position x, y, z in the LinkTrack frame, m (1 mm steps).
    pub position_m: [f64; 3],
    /// Velocity x, y, z, m/s (0.1 mm/s steps).
    pub velocity_mps: [f64; 3],
    /// Distances to anchors 0 to 7, m (1 mm steps; 0 where there is none).
    pub distances_m: [f64; 8],
    /// Gyroscope x, y, z, rad/s (single precision on the wire).
    pub gyro_rad_s: [f64; 3],
    /// Accelerometer x, y, z, m/s² (single precision on the wire).
    pub accel_mps2: [f64; 3],
    /// Euler angles roll, pitch, yaw, degrees (0.01° steps).
    pub angle_deg: [f64; 3],
    /// Attitude quaternion w, x, y, z (single precision on the wire).
    pub quaternion_wxyz: [f64; 4],
    /// The tag's own clock since power-up, ms.
    pub local_time_ms: u32,
    /// The network (system) time, ms.
    pub system_time_ms: u32,
    /// Estimated precision of `position_m` per axis, m (0.01 m steps, at most 2.55).
    pub eop_m: [f64; 3],
    /// Supply voltage, V (1 mV steps).
    pub voltage_v: f64,
}

/// One decoded LinkTrack frame, of the kinds this module reads.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkTrackFrame {
    /// A `NodeFrame2` (function mark `0x04`).
    NodeFrame2(NodeFrame2),
    /// A `TagFrame0` (function mark `0x01`).
    TagFrame0(TagFrame0),
}

/// Why a byte slice is not one well-formed frame of a kind this module reads.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum LinkTrackError {
    /// The slice is shorter than the frame needs.
    #[error("LinkTrack frame: {got} bytes, at least {need} needed")]
    TooShort {
        /// Bytes needed.
        need: usize,
        /// Bytes given.
        got: usize,
    },
    /// The first byte is not `0x55`.
    #[error("LinkTrack frame: header byte {0:#04x}, expected 0x55")]
    BadHeader(u8),
    /// The function mark is not one of a frame this module reads.
    #[error("LinkTrack frame: unsupported function mark {0:#04x}")]
    UnknownFunction(u8),
    /// The frame's length (its length field, or the fixed length of its kind) disagrees with the
    /// slice or with its node count.
    #[error("LinkTrack frame: length {declared} declared, {expected} expected")]
    BadLength {
        /// The length the frame declares (or the slice's length for a fixed-length frame).
        declared: usize,
        /// The length the slice or the node count implies.
        expected: usize,
    },
    /// The checksum byte is not the sum of the bytes before it.
    #[error("LinkTrack frame: checksum {got:#04x}, computed {computed:#04x}")]
    Checksum {
        /// The frame's last byte.
        got: u8,
        /// The low 8 bits of the sum of the bytes before it.
        computed: u8,
    },
    /// More nodes than one `NodeFrame2` can carry (encoding).
    #[error("LinkTrack NodeFrame2: {0} nodes, at most 255 fit in one frame")]
    TooManyNodes(usize),
}
