//! Decoders and encoders of single frames: byte offsets, scale factors and the checksum.

use super::{
    LinkTrackError, LinkTrackFrame, NodeFrame2, NodeRange2, TagFrame0, FRAME_HEADER, NODE_FRAME2_FIXED_LEN, NODE_FRAME2_MARK,
    NODE_FRAME2_MAX_NODES, NODE_FRAME2_MIN_LEN, NODE_FRAME2_NODE_LEN, TAG_FRAME0_LEN, TAG_FRAME0_MARK,
};

// Scale factors: wire integer = value × scale.
const POS_SCALE: f64 = 1000.0;
const VEL_SCALE: f64 = 10000.0;
const DIS_SCALE: f64 = 1000.0;
const VOLTAGE_SCALE: f64 = 1000.0;
const ANGLE_SCALE: f64 = 100.0;
const EOP_SCALE: f64 = 100.0;
const RSSI_SCALE: f64 = -2.0;

// NodeFrame2 offsets (see `NodeFrame2`).
mod nf2 {
    pub const LENGTH: usize = 2;
    pub const ROLE: usize = 4;
    pub const ID: usize = 5;
    pub const SYSTEM_TIME: usize = 6;
    pub const EOP: usize = 10;
    pub const POS: usize = 13;
    pub const VEL: usize = 22;
    pub const GYRO: usize = 40;
    pub const ACC: usize = 52;
    pub const ANGLE: usize = 76;
    pub const QUAT: usize = 82;
    pub const LOCAL_TIME: usize = 102;
    pub const VOLTAGE: usize = 116;
    pub const NODE_COUNT: usize = 118;
    // Within one node block.
    pub const NODE_ROLE: usize = 0;
    pub const NODE_ID: usize = 1;
    pub const NODE_DIS: usize = 2;
    pub const NODE_FP_RSSI: usize = 5;
    pub const NODE_RX_RSSI: usize = 6;
    pub const NODE_SYSTEM_TIME: usize = 7;
}

// TagFrame0 offsets (see `TagFrame0`).
mod tf0 {
    pub const ID: usize = 2;
    pub const ROLE: usize = 3;
    pub const POS: usize = 4;
    pub const VEL: usize = 13;
    pub const DIS: usize = 22;
    pub const GYRO: usize = 46;
    pub const ACC: usize = 58;
    pub const ANGLE: usize = 82;
    pub const QUAT: usize = 88;
    pub const LOCAL_TIME: usize = 108;
    pub const SYSTEM_TIME: usize = 112;
    pub const EOP: usize = 117;
    pub const VOLTAGE: usize = 120;
}

/// The LinkTrack checksum of `bytes`: the low 8 bits of the sum of all of them. A frame is intact
/// when its last byte equals the checksum of the bytes before it.
pub fn checksum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0u8, |sum, &b| sum.wrapping_add(b))
}

/// Decodes one whole frame of a supported kind (`NodeFrame2` or `TagFrame0`, told apart by the
/// function mark at byte 1). `bytes` holds exactly the frame, checksum included; the header,
/// length and checksum are checked.
pub fn decode_frame(bytes: &[u8]) -> Result<LinkTrackFrame, LinkTrackError> {
    check_prefix(bytes)?;
    match bytes[1] {
        NODE_FRAME2_MARK => decode_node_frame2(bytes).map(LinkTrackFrame::NodeFrame2),
        TAG_FRAME0_MARK => decode_tag_frame0(bytes).map(LinkTrackFrame::TagFrame0),
        other => Err(LinkTrackError::UnknownFunction(other)),
    }
}

/// Decodes one `NodeFrame2` (layout on [`NodeFrame2`]). `bytes` holds exactly the frame: its
/// length field must equal `bytes.len()` and `120 + 13 n` for its node count `n`, and its last
/// byte the checksum of the others.
pub fn decode_node_frame2(bytes: &[u8]) -> Result<NodeFrame2, LinkTrackError> {
    check_prefix(bytes)?;
    if bytes[1] != NODE_FRAME2_MARK {
        return Err(LinkTrackError::UnknownFunction(bytes[1]));
    }
    if bytes.len() < NODE_FRAME2_MIN_LEN {
        return Err(LinkTrackError::TooShort { need: NODE_FRAME2_MIN_LEN, got: bytes.len() });
    }
    let declared = usize::from(u16::from_le_bytes(array(bytes, nf2::LENGTH)));
    if declared != bytes.len() {
        return Err(LinkTrackError::BadLength { declared, expected: bytes.len() });
    }
    let count = usize::from(bytes[nf2::NODE_COUNT]);
    let expected = node_frame2_len(count);
    if declared != expected {
        return Err(LinkTrackError::BadLength { declared, expected });
    }
    check_sum(bytes)?;
    let nodes = (0..count)
        .map(|i| {
            let b = &bytes[NODE_FRAME2_FIXED_LEN + i * NODE_FRAME2_NODE_LEN..][..NODE_FRAME2_NODE_LEN];
            NodeRange2 {
                role: b[nf2::NODE_ROLE],
                id: b[nf2::NODE_ID],
                range_m: f64::from(int24(b, nf2::NODE_DIS)) / DIS_SCALE,
                fp_rssi_dbm: f64::from(b[nf2::NODE_FP_RSSI]) / RSSI_SCALE,
                rx_rssi_dbm: f64::from(b[nf2::NODE_RX_RSSI]) / RSSI_SCALE,
                system_time_ms: u32::from_le_bytes(array(b, nf2::NODE_SYSTEM_TIME)),
            }
        })
        .collect();
    Ok(NodeFrame2 {
        role: bytes[nf2::ROLE],
        id: bytes[nf2::ID],
        local_time_ms: u32::from_le_bytes(array(bytes, nf2::LOCAL_TIME)),
        system_time_ms: u32::from_le_bytes(array(bytes, nf2::SYSTEM_TIME)),
        eop_m: eop(bytes, nf2::EOP),
        position_m: int24s(bytes, nf2::POS, POS_SCALE),
        velocity_mps: int24s(bytes, nf2::VEL, VEL_SCALE),
        gyro_rad_s: f32s(bytes, nf2::GYRO),
        accel_mps2: f32s(bytes, nf2::ACC),
        angle_deg: angles(bytes, nf2::ANGLE),
        quaternion_wxyz: f32s(bytes, nf2::QUAT),
        voltage_v: f64::from(u16::from_le_bytes(array(bytes, nf2::VOLTAGE))) / VOLTAGE_SCALE,
        nodes,
    })
}

/// Decodes one `TagFrame0` (layout on [`TagFrame0`]). `bytes` holds exactly the frame: 128 bytes,
/// the last one the checksum of the others.
pub fn decode_tag_frame0(bytes: &[u8]) -> Result<TagFrame0, LinkTrackError> {
    check_prefix(bytes)?;
    if bytes[1] != TAG_FRAME0_MARK {
        return Err(LinkTrackError::UnknownFunction(bytes[1]));
    }
    if bytes.len() < TAG_FRAME0_LEN {
        return Err(LinkTrackError::TooShort { need: TAG_FRAME0_LEN, got: bytes.len() });
    }
    if bytes.len() != TAG_FRAME0_LEN {
        return Err(LinkTrackError::BadLength { declared: bytes.len(), expected: TAG_FRAME0_LEN });
    }
    check_sum(bytes)?;
    Ok(TagFrame0 {
        role: bytes[tf0::ROLE],
        id: bytes[tf0::ID],
        position_m: int24s(bytes, tf0::POS, POS_SCALE),
        velocity_mps: int24s(bytes, tf0::VEL, VEL_SCALE),
        distances_m: int24s(bytes, tf0::DIS, DIS_SCALE),
        gyro_rad_s: f32s(bytes, tf0::GYRO),
        accel_mps2: f32s(bytes, tf0::ACC),
        angle_deg: angles(bytes, tf0::ANGLE),
        quaternion_wxyz: f32s(bytes, tf0::QUAT),
        local_time_ms: u32::from_le_bytes(array(bytes, tf0::LOCAL_TIME)),
        system_time_ms: u32::from_le_bytes(array(bytes, tf0::SYSTEM_TIME)),
        eop_m: eop(bytes, tf0::EOP),
        voltage_v: f64::from(u16::from_le_bytes(array(bytes, tf0::VOLTAGE))) / VOLTAGE_SCALE,
    })
}

/// Encodes `frame` as one `NodeFrame2`, checksum included: the inverse of
/// [`decode_node_frame2`] up to the wire's quantisation (each value rounded to its step, floats
/// to single precision). Values beyond a field's range saturate at its limit and NaN becomes 0;
/// reserved bytes are zeros. Fails with [`LinkTrackError::TooManyNodes`] for more than 255 nodes.
pub fn encode_node_frame2(frame: &NodeFrame2) -> Result<Vec<u8>, LinkTrackError> {
    let count = frame.nodes.len();
    if count > NODE_FRAME2_MAX_NODES {
        return Err(LinkTrackError::TooManyNodes(count));
    }
    let len = node_frame2_len(count);
    let mut out = vec![0u8; len];
    out[0] = FRAME_HEADER;
    out[1] = NODE_FRAME2_MARK;
    // `len` is at most 3435 (255 nodes), so it fits the u16 length field.
    put(&mut out, nf2::LENGTH, &u16::try_from(len).unwrap_or(u16::MAX).to_le_bytes());
    out[nf2::ROLE] = frame.role;
    out[nf2::ID] = frame.id;
    put(&mut out, nf2::SYSTEM_TIME, &frame.system_time_ms.to_le_bytes());
    put_eop(&mut out, nf2::EOP, &frame.eop_m);
    put_int24s(&mut out, nf2::POS, &frame.position_m, POS_SCALE);
    put_int24s(&mut out, nf2::VEL, &frame.velocity_mps, VEL_SCALE);
    put_f32s(&mut out, nf2::GYRO, &frame.gyro_rad_s);
    put_f32s(&mut out, nf2::ACC, &frame.accel_mps2);
    put_angles(&mut out, nf2::ANGLE, &frame.angle_deg);
    put_f32s(&mut out, nf2::QUAT, &frame.quaternion_wxyz);
    put(&mut out, nf2::LOCAL_TIME, &frame.local_time_ms.to_le_bytes());
    put(&mut out, nf2::VOLTAGE, &quantise_u16(frame.voltage_v * VOLTAGE_SCALE).to_le_bytes());
    out[nf2::NODE_COUNT] = u8::try_from(count).unwrap_or(u8::MAX);
    for (i, node) in frame.nodes.iter().enumerate() {
        let at = NODE_FRAME2_FIXED_LEN + i * NODE_FRAME2_NODE_LEN;
        out[at + nf2::NODE_ROLE] = node.role;
        out[at + nf2::NODE_ID] = node.id;
        put(&mut out, at + nf2::NODE_DIS, &int24_bytes(node.range_m * DIS_SCALE));
        out[at + nf2::NODE_FP_RSSI] = quantise_u8(node.fp_rssi_dbm * RSSI_SCALE);
        out[at + nf2::NODE_RX_RSSI] = quantise_u8(node.rx_rssi_dbm * RSSI_SCALE);
        put(&mut out, at + nf2::NODE_SYSTEM_TIME, &node.system_time_ms.to_le_bytes());
    }
    seal(&mut out);
    Ok(out)
}

/// Encodes `frame` as one 128-byte `TagFrame0`, checksum included: the inverse of
/// [`decode_tag_frame0`] up to the wire's quantisation (each value rounded to its step, floats to
/// single precision). Values beyond a field's range saturate at its limit and NaN becomes 0;
/// reserved bytes are zeros.
pub fn encode_tag_frame0(frame: &TagFrame0) -> Vec<u8> {
    let mut out = vec![0u8; TAG_FRAME0_LEN];
    out[0] = FRAME_HEADER;
    out[1] = TAG_FRAME0_MARK;
    out[tf0::ID] = frame.id;
    out[tf0::ROLE] = frame.role;
    put_int24s(&mut out, tf0::POS, &frame.position_m, POS_SCALE);
    put_int24s(&mut out, tf0::VEL, &frame.velocity_mps, VEL_SCALE);
    put_int24s(&mut out, tf0::DIS, &frame.distances_m, DIS_SCALE);
    put_f32s(&mut out, tf0::GYRO, &frame.gyro_rad_s);
    put_f32s(&mut out, tf0::ACC, &frame.accel_mps2);
    put_angles(&mut out, tf0::ANGLE, &frame.angle_deg);
    put_f32s(&mut out, tf0::QUAT, &frame.quaternion_wxyz);
    put(&mut out, tf0::LOCAL_TIME, &frame.local_time_ms.to_le_bytes());
    put(&mut out, tf0::SYSTEM_TIME, &frame.system_time_ms.to_le_bytes());
    put_eop(&mut out, tf0::EOP, &frame.eop_m);
    put(&mut out, tf0::VOLTAGE, &quantise_u16(frame.voltage_v * VOLTAGE_SCALE).to_le_bytes());
    seal(&mut out);
    out
}

/// The length of a `NodeFrame2` with `count` nodes, bytes.
pub(super) fn node_frame2_len(count: usize) -> usize {
    NODE_FRAME2_FIXED_LEN + count * NODE_FRAME2_NODE_LEN + 1
}

/// Checks that `bytes` has a header byte and a function mark.
fn check_prefix(bytes: &[u8]) -> Result<(), LinkTrackError> {
    match bytes {
        [FRAME_HEADER, _, ..] => Ok(()),
        [other, _, ..] => Err(LinkTrackError::BadHeader(*other)),
        _ => Err(LinkTrackError::TooShort { need: 2, got: bytes.len() }),
    }
}

/// Checks the last byte of a (non-empty) frame against the checksum of the others.
fn check_sum(bytes: &[u8]) -> Result<(), LinkTrackError> {
    match bytes.split_last() {
        Some((&got, body)) => {
            let computed = checksum(body);
            if got == computed {
                Ok(())
            } else {
                Err(LinkTrackError::Checksum { got, computed })
            }
        }
        None => Err(LinkTrackError::TooShort { need: 1, got: 0 }),
    }
}

/// `N` bytes of `b` from `at`; zeros where `b` ends first (callers check the length before).
fn array<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(s) = b.get(at..at + N) {
        out.copy_from_slice(s);
    }
    debug_assert!(at + N <= b.len(), "read past the frame");
    out
}

/// The signed little-endian 24-bit integer at `at`.
fn int24(b: &[u8], at: usize) -> i32 {
    let [x0, x1, x2] = array::<3>(b, at);
    // Into the top three bytes of an i32, then an arithmetic shift back: sign extension.
    i32::from_le_bytes([0, x0, x1, x2]) >> 8
}

/// `N` consecutive int24 values from `at`, each divided by `scale`.
fn int24s<const N: usize>(b: &[u8], at: usize, scale: f64) -> [f64; N] {
    std::array::from_fn(|i| f64::from(int24(b, at + 3 * i)) / scale)
}

/// `N` consecutive little-endian f32 values from `at`.
fn f32s<const N: usize>(b: &[u8], at: usize) -> [f64; N] {
    std::array::from_fn(|i| f64::from(f32::from_le_bytes(array(b, at + 4 * i))))
}

/// Three i16 angles from `at`, degrees.
fn angles(b: &[u8], at: usize) -> [f64; 3] {
    std::array::from_fn(|i| f64::from(i16::from_le_bytes(array(b, at + 2 * i))) / ANGLE_SCALE)
}

/// Three u8 precisions from `at`, m.
fn eop(b: &[u8], at: usize) -> [f64; 3] {
    std::array::from_fn(|i| f64::from(array::<1>(b, at + i)[0]) / EOP_SCALE)
}

/// Copies `src` into `out` at `at` (in range by construction).
fn put(out: &mut [u8], at: usize, src: &[u8]) {
    if let Some(dst) = out.get_mut(at..at + src.len()) {
        dst.copy_from_slice(src);
    }
    debug_assert!(at + src.len() <= out.len(), "write past the frame");
}

/// Writes the checksum of all bytes before the last into the last.
fn seal(out: &mut [u8]) {
    if let Some((last, body)) = out.split_last_mut() {
        *last = checksum(body);
    }
}

/// `x` rounded to the nearest int24 (saturating; NaN → 0), as its three little-endian bytes.
fn int24_bytes(x: f64) -> [u8; 3] {
    const MAX: f64 = 8_388_607.0;
    const MIN: f64 = -8_388_608.0;
    // `as` saturates and maps NaN to 0; the clamp keeps it within 24 bits.
    let v = x.round().clamp(MIN, MAX) as i32;
    let [b0, b1, b2, _] = v.to_le_bytes();
    [b0, b1, b2]
}

fn put_int24s(out: &mut [u8], at: usize, values: &[f64], scale: f64) {
    for (i, &v) in values.iter().enumerate() {
        put(out, at + 3 * i, &int24_bytes(v * scale));
    }
}

fn put_f32s(out: &mut [u8], at: usize, values: &[f64]) {
    for (i, &v) in values.iter().enumerate() {
        put(out, at + 4 * i, &(v as f32).to_le_bytes());
    }
}

fn put_angles(out: &mut [u8], at: usize, values: &[f64; 3]) {
    for (i, &v) in values.iter().enumerate() {
        // `as` saturates at the i16 limits and maps NaN to 0.
        put(out, at + 2 * i, &((v * ANGLE_SCALE).round() as i16).to_le_bytes());
    }
}

fn put_eop(out: &mut [u8], at: usize, values: &[f64; 3]) {
    for (i, &v) in values.iter().enumerate() {
        put(out, at + i, &[quantise_u8(v * EOP_SCALE)]);
    }
}

/// `x` rounded to the nearest u8 (saturating; NaN → 0).
fn quantise_u8(x: f64) -> u8 {
    x.round() as u8
}

/// `x` rounded to the nearest u16 (saturating; NaN → 0).
fn quantise_u16(x: f64) -> u16 {
    x.round() as u16
}
