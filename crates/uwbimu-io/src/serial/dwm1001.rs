//! Qorvo/Decawave DWM1001 UART TLV API, the `dwm_loc_get` call, as pure functions over bytes:
//! the request ([`LOC_GET_REQUEST`]), the decoder and encoder of one whole response
//! ([`decode_loc_get`], [`encode_loc_get`]) and a resynchronising stream decoder for a serial
//! port's byte stream ([`DwmStream`]). No I/O happens here; the caller writes the request, reads
//! the port and hands the bytes over.
//!
//! Every TLV frame is a type byte, a length byte and that many value bytes; integers are
//! little-endian. The response to `dwm_loc_get` is a sequence of TLV frames:
//!
//! | TLV | length | value |
//! |---|---|---|
//! | `0x40` return value | 1 | u8: 0 ok, 1 unknown command or broken TLV frame, 2 internal error, 3 invalid parameter, 4 busy, 5 operation not permitted |
//! | `0x41` position | 13 | x, y, z i32 (mm), quality factor u8 (0–100) |
//! | `0x49` anchors, positions and distances (tag node) | 1 + 20 n | count n u8, then per anchor: short address u16, distance u32 (mm), distance quality u8, anchor x, y, z i32 (mm), anchor position quality u8 |
//! | `0x48` distances (anchor node) | 1 + 13 n | count n u8, then per entry: address u64, distance u32 (mm), quality u8 |
//!
//! A failed call answers with the return value frame alone. The layout follows the public
//! "DWM1001 Firmware API Guide" and was checked against public host code; see `docs/dwm1001.md`
//! for the sources and what is assumed.

use crate::serial::resync::{push_frames, Framing, Scan};

/// The `dwm_loc_get` request: TLV type `0x0C`, length 0.
pub const LOC_GET_REQUEST: [u8; 2] = [0x0C, 0x00];
/// TLV type of the return value frame that starts every response.
pub const TLV_RET_VAL: u8 = 0x40;
/// TLV type of the node's own position.
pub const TLV_POS_XYZ: u8 = 0x41;
/// TLV type of the distances block of an anchor node (64-bit addresses, no positions).
pub const TLV_RNG_AN_DIST: u8 = 0x48;
/// TLV type of the distances block of a tag node (16-bit addresses and anchor positions).
pub const TLV_RNG_AN_POS_DIST: u8 = 0x49;
/// The value length of a position frame, bytes.
pub const POSITION_LEN: usize = 13;
/// The bytes of one entry of a `0x49` (tag) block.
pub const TAG_ENTRY_LEN: usize = 20;
/// The bytes of one entry of a `0x48` (anchor) block.
pub const ANCHOR_ENTRY_LEN: usize = 13;
/// The most entries a `0x49` block can carry (its length is one byte).
pub const TAG_MAX_RANGES: usize = (255 - 1) / TAG_ENTRY_LEN;
/// The most entries a `0x48` block can carry (its length is one byte).
pub const ANCHOR_MAX_RANGES: usize = (255 - 1) / ANCHOR_ENTRY_LEN;
/// The longest response [`DwmStream`] accepts, bytes: the return value, a position, one range
/// block and one more TLV of the greatest length. A candidate running longer is rejected.
pub const MAX_RESPONSE_LEN: usize = 3 + (2 + POSITION_LEN) + 2 * (2 + 255);

/// A position with its quality factor, as the module reports it (metres, 1 mm steps on the wire).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DwmPosition {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
    /// z, m.
    pub z_m: f64,
    /// Quality factor, percent (0–100 by the guide; any byte is kept as read).
    pub quality: u8,
}

/// One distance from a `0x49` (tag) or `0x48` (anchor) block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DwmRange {
    /// The other node's UWB address: the 16-bit short address widened (tag block) or the 64-bit
    /// address (anchor block).
    pub anchor_id: u64,
    /// The distance, m (1 mm steps on the wire).
    pub range_m: f64,
    /// The distance quality factor (0–100 by the guide).
    pub quality: u8,
    /// The anchor's position (tag block); `None` in an anchor block.
    pub anchor_position: Option<DwmPosition>,
}

/// One `dwm_loc_get` response.
#[derive(Debug, Clone, PartialEq)]
pub struct DwmLocation {
    /// The return value: 0 ok (as [`decode_loc_get`] gives it); the stream also hands out failed
    /// calls with their non-zero code and nothing else.
    pub status: u8,
    /// The node's own position (`0x41`), if the response carries one.
    pub position: Option<DwmPosition>,
    /// The distances of the range blocks, in wire order (empty if there is none).
    pub ranges: Vec<DwmRange>,
}

/// Why a byte slice is not one well-formed, successful `dwm_loc_get` response.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum DwmError {
    /// The slice ends inside a TLV frame (or before the return value).
    #[error("DWM1001 response: truncated at byte {at} of {len}")]
    Truncated {
        /// Offset of the frame that does not fit.
        at: usize,
        /// Bytes given.
        len: usize,
    },
    /// The slice does not start with the return value frame `0x40 0x01`.
    #[error("DWM1001 response: starts {0:#04x} {1:#04x}, expected 0x40 0x01")]
    BadStart(u8, u8),
    /// The module answered with a non-zero return value (the code is kept).
    #[error("DWM1001 response: return value {0} (not ok)")]
    Status(u8),
    /// A frame's length disagrees with its type (position not 13) or with its entry count.
    #[error("DWM1001 response: TLV {tlv:#04x} has length {declared}, {expected} expected")]
    BadLength {
        /// The TLV type.
        tlv: u8,
        /// Its length byte.
        declared: usize,
        /// The length its type and count imply.
        expected: usize,
    },
    /// A second return value frame inside the response (two responses run together).
    #[error("DWM1001 response: a second return value frame at byte {0}")]
    SecondReturnValue(usize),
    /// More ranges than one block can carry (encoding).
    #[error("DWM1001 response: {got} ranges, at most {max} fit in one block")]
    TooManyRanges {
        /// Ranges given.
        got: usize,
        /// The block's capacity.
        max: usize,
    },
}

fn rd_u16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn rd_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn rd_i32(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn rd_u64(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(a)
}

/// Reads 13 position bytes (x, y, z i32 mm, quality u8) at `at`; the caller checked the length.
fn rd_position(b: &[u8], at: usize) -> DwmPosition {
    DwmPosition {
        x_m: f64::from(rd_i32(b, at)) / 1000.0,
        y_m: f64::from(rd_i32(b, at + 4)) / 1000.0,
        z_m: f64::from(rd_i32(b, at + 8)) / 1000.0,
        quality: b[at + 12],
    }
}

/// The value length a range block of type `tlv` must have, given its value (count first);
/// `None` for an empty value.
fn range_block_len(tlv: u8, value: &[u8]) -> Option<usize> {
    let entry = if tlv == TLV_RNG_AN_POS_DIST { TAG_ENTRY_LEN } else { ANCHOR_ENTRY_LEN };
    value.first().map(|&n| 1 + usize::from(n) * entry)
}

/// Decodes the value of a range block (checked length) into `out`.
fn decode_range_block(tlv: u8, value: &[u8], out: &mut Vec<DwmRange>) {
    let n = value.first().copied().map_or(0, usize::from);
    for i in 0..n {
        if tlv == TLV_RNG_AN_POS_DIST {
            let at = 1 + i * TAG_ENTRY_LEN;
            out.push(DwmRange {
                anchor_id: u64::from(rd_u16(value, at)),
                range_m: f64::from(rd_u32(value, at + 2)) / 1000.0,
                quality: value[at + 6],
                anchor_position: Some(rd_position(value, at + 7)),
            });
        } else {
            let at = 1 + i * ANCHOR_ENTRY_LEN;
            out.push(DwmRange {
                anchor_id: rd_u64(value, at),
                range_m: f64::from(rd_u32(value, at + 8)) / 1000.0,
                quality: value[at + 12],
                anchor_position: None,
            });
        }
    }
}

/// Checks one TLV frame of a response body: `Ok(())` if its type is known and its length right,
/// or its type is unknown (to be skipped).
fn check_tlv(tlv: u8, value: &[u8]) -> Result<(), DwmError> {
    match tlv {
        TLV_POS_XYZ if value.len() != POSITION_LEN => {
            Err(DwmError::BadLength { tlv, declared: value.len(), expected: POSITION_LEN })
        }
        TLV_RNG_AN_DIST | TLV_RNG_AN_POS_DIST => match range_block_len(tlv, value) {
            Some(expected) if expected == value.len() => Ok(()),
            expected => Err(DwmError::BadLength { tlv, declared: value.len(), expected: expected.unwrap_or(1) }),
        },
        _ => Ok(()),
    }
}

/// Decodes one whole `dwm_loc_get` response: `0x40 0x01 0x00`, then TLV frames to the end of
/// `bytes`. A `0x41` frame gives the position (a later one replaces an earlier one), each `0x49`
/// or `0x48` block appends its ranges, frames of other types are skipped.
///
/// # Errors
/// [`DwmError::Truncated`] if `bytes` ends inside a frame, [`DwmError::BadStart`] if it does not
/// start with `0x40 0x01`, [`DwmError::Status`] with the code if the return value is not 0,
/// [`DwmError::BadLength`] if a position is not 13 bytes or a range block's length is not
/// `1 + count × entry`, [`DwmError::SecondReturnValue`] for another `0x40` frame. Never panics.
pub fn decode_loc_get(bytes: &[u8]) -> Result<DwmLocation, DwmError> {
    let len = bytes.len();
    if len < 3 {
        return Err(DwmError::Truncated { at: 0, len });
    }
    if bytes[0] != TLV_RET_VAL || bytes[1] != 1 {
        return Err(DwmError::BadStart(bytes[0], bytes[1]));
    }
    if bytes[2] != 0 {
        return Err(DwmError::Status(bytes[2]));
    }
    let mut loc = DwmLocation { status: 0, position: None, ranges: Vec::new() };
    let mut at = 3;
    while at < len {
        let Some(&vlen) = bytes.get(at + 1) else {
            return Err(DwmError::Truncated { at, len });
        };
        let Some(value) = bytes.get(at + 2..at + 2 + usize::from(vlen)) else {
            return Err(DwmError::Truncated { at, len });
        };
        let tlv = bytes[at];
        check_tlv(tlv, value)?;
        match tlv {
            TLV_RET_VAL => return Err(DwmError::SecondReturnValue(at)),
            TLV_POS_XYZ => loc.position = Some(rd_position(value, 0)),
            TLV_RNG_AN_DIST | TLV_RNG_AN_POS_DIST => decode_range_block(tlv, value, &mut loc.ranges),
            _ => {}
        }
        at += 2 + usize::from(vlen);
    }
    Ok(loc)
}

/// Metres to whole millimetres, rounded; saturates at the i32 range, NaN gives 0.
fn mm_i32(m: f64) -> i32 {
    (m * 1000.0).round() as i32
}

/// Metres to whole millimetres, rounded; saturates at the u32 range (negative gives 0), NaN 0.
fn mm_u32(m: f64) -> u32 {
    (m * 1000.0).round() as u32
}

fn put_position(out: &mut Vec<u8>, p: &DwmPosition) {
    out.extend_from_slice(&mm_i32(p.x_m).to_le_bytes());
    out.extend_from_slice(&mm_i32(p.y_m).to_le_bytes());
    out.extend_from_slice(&mm_i32(p.z_m).to_le_bytes());
    out.push(p.quality);
}

/// Encodes `loc` as the module would answer `dwm_loc_get`: the return value `0x40 0x01 status`;
/// if the status is 0, the position frame `0x41` (when `loc.position` is `Some`) and one range
/// block, `0x49` for a tag node (`tag`) or `0x48` for an anchor node, always (count 0 if there
/// are no ranges). The inverse of [`decode_loc_get`] up to rounding to whole millimetres, for
/// values that fit: a tag block writes the low 16 bits of `anchor_id` and a missing anchor
/// position as zeros with quality 0, an anchor block drops anchor positions; lengths saturate at
/// the i32 (positions) or u32 (distances, negative to 0) range. A non-zero status is written
/// alone, as a failed call is.
///
/// # Errors
/// [`DwmError::TooManyRanges`] for more than [`TAG_MAX_RANGES`] (tag) or [`ANCHOR_MAX_RANGES`]
/// (anchor) ranges.
pub fn encode_loc_get(loc: &DwmLocation, tag: bool) -> Result<Vec<u8>, DwmError> {
    let max = if tag { TAG_MAX_RANGES } else { ANCHOR_MAX_RANGES };
    if loc.ranges.len() > max {
        return Err(DwmError::TooManyRanges { got: loc.ranges.len(), max });
    }
    let mut out = vec![TLV_RET_VAL, 1, loc.status];
    if loc.status != 0 {
        return Ok(out);
    }
    if let Some(p) = &loc.position {
        out.extend_from_slice(&[TLV_POS_XYZ, POSITION_LEN as u8]);
        put_position(&mut out, p);
    }
    let entry = if tag { TAG_ENTRY_LEN } else { ANCHOR_ENTRY_LEN };
    let n = loc.ranges.len();
    // n ≤ max keeps 1 + n × entry ≤ 255 and n ≤ 255.
    out.extend_from_slice(&[if tag { TLV_RNG_AN_POS_DIST } else { TLV_RNG_AN_DIST }, (1 + n * entry) as u8, n as u8]);
    for r in &loc.ranges {
        if tag {
            out.extend_from_slice(&(r.anchor_id as u16).to_le_bytes());
            out.extend_from_slice(&mm_u32(r.range_m).to_le_bytes());
            out.push(r.quality);
            let zero = DwmPosition { x_m: 0.0, y_m: 0.0, z_m: 0.0, quality: 0 };
            put_position(&mut out, r.anchor_position.as_ref().unwrap_or(&zero));
        } else {
            out.extend_from_slice(&r.anchor_id.to_le_bytes());
            out.extend_from_slice(&mm_u32(r.range_m).to_le_bytes());
            out.push(r.quality);
        }
    }
    Ok(out)
}

/// What a [`DwmStream`] has seen since it was made. Every byte pushed is, in the end, part of a
/// handed-out response, skipped, or still buffered: `bytes_received` = bytes of responses +
/// `bytes_skipped` + [`DwmStream::buffered_len`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct DwmCounts {
    /// Bytes pushed in.
    pub bytes_received: u64,
    /// Responses handed out (successful and failed calls).
    pub responses: u64,
    /// Of `responses`, those with a non-zero return value.
    pub failed_calls: u64,
    /// Candidates (`0x40 0x01` starts) rejected: a position not 13 bytes, a range block whose
    /// length disagrees with its count, or a response running past [`MAX_RESPONSE_LEN`].
    pub errors: u64,
    /// Bytes dropped while looking for the next response: garbage, and the first byte of each
    /// rejected candidate.
    pub bytes_skipped: u64,
}

/// Decodes `dwm_loc_get` responses from a byte stream delivered in pieces of any size.
///
/// The TLV API gives no overall length, so a response is delimited by this rule: it starts at
/// `0x40 0x01 s`. If `s` is not 0 the response is those three bytes (a failed call). Otherwise
/// TLV frames follow and the response ends right after the first complete `0x49` or `0x48`
/// block, or just before the next `0x40 0x01` found where a frame would start. A `0x41` frame
/// must be 13 bytes long and a range block `1 + count × entry`, else the candidate is rejected;
/// frames of other types are skipped once all their bytes are here, as long as the response
/// stays within [`MAX_RESPONSE_LEN`] bytes. A rejected candidate costs one byte: the decoder
/// skips the `0x40` and searches again from the next byte. Bytes before a start are skipped.
/// Nothing panics on any input, and the buffer holds at most [`MAX_RESPONSE_LEN`] + 1 bytes
/// between calls (a response of the greatest length and the byte after it).
#[derive(Debug, Clone, Default)]
pub struct DwmStream {
    buf: Vec<u8>,
    counts: DwmCounts,
}

impl DwmStream {
    /// An empty decoder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends `bytes` and calls `out` with every response completed, in stream order. Bytes of
    /// an incomplete response at the end stay buffered for the next call.
    pub fn push(&mut self, bytes: &[u8], out: &mut impl FnMut(DwmLocation)) {
        self.counts.bytes_received += bytes.len() as u64;
        let skipped = push_frames(&mut self.buf, bytes, MAX_RESPONSE_LEN, &mut Responses { counts: &mut self.counts, out });
        self.counts.bytes_skipped += skipped;
        debug_assert!(self.buf.len() <= MAX_RESPONSE_LEN + 1, "buffer above one response");
    }

    /// [`push`](Self::push), appending the responses to `responses`.
    pub fn push_into(&mut self, bytes: &[u8], responses: &mut Vec<DwmLocation>) {
        self.push(bytes, &mut |r| responses.push(r));
    }

    /// The counts so far.
    pub fn counts(&self) -> DwmCounts {
        self.counts
    }

    /// Bytes held back: the start of a response not yet complete.
    pub fn buffered_len(&self) -> usize {
        self.buf.len()
    }

    /// Drops the buffered bytes (e.g. after reopening the port); the counts stay.
    pub fn clear(&mut self) {
        self.buf.clear();
    }
}

/// The DWM1001 part of the scan: the stream's counts and where its responses go.
struct Responses<'a, F> {
    counts: &'a mut DwmCounts,
    out: &'a mut F,
}

impl<F: FnMut(DwmLocation)> Framing for Responses<'_, F> {
    const START: u8 = TLV_RET_VAL;

    /// Classifies the bytes from a `0x40` byte, counting a rejection.
    fn classify(&mut self, rest: &[u8]) -> Scan {
        let (Some(&l), Some(&s)) = (rest.get(1), rest.get(2)) else {
            return if rest.get(1).is_some_and(|&l| l != 1) { Scan::Reject } else { Scan::Incomplete };
        };
        if l != 1 {
            return Scan::Reject;
        }
        if s != 0 {
            return Scan::Whole(3);
        }
        let mut at = 3;
        loop {
            let Some(&tlv) = rest.get(at) else { return Scan::Incomplete };
            let Some(&vlen) = rest.get(at + 1) else { return Scan::Incomplete };
            if tlv == TLV_RET_VAL && vlen == 1 {
                return Scan::Whole(at);
            }
            let end = at + 2 + usize::from(vlen);
            if end > MAX_RESPONSE_LEN {
                self.counts.errors += 1;
                return Scan::Reject;
            }
            let Some(value) = rest.get(at + 2..end) else { return Scan::Incomplete };
            if tlv == TLV_RET_VAL || check_tlv(tlv, value).is_err() {
                self.counts.errors += 1;
                return Scan::Reject;
            }
            if tlv == TLV_RNG_AN_DIST || tlv == TLV_RNG_AN_POS_DIST {
                return Scan::Whole(end);
            }
            at = end;
        }
    }
    /// Decodes a response that passed [`Self::classify`] (a failed call as its status alone),
    /// counts it and hands it out.
    fn take(&mut self, bytes: &[u8]) -> bool {
        let loc = match decode_loc_get(bytes) {
            Ok(loc) => loc,
            Err(DwmError::Status(s)) => {
                self.counts.failed_calls += 1;
                DwmLocation { status: s, position: None, ranges: Vec::new() }
            }
            // Unreachable after `classify`'s checks; treat as a rejected start.
            Err(_) => {
                self.counts.errors += 1;
                return false;
            }
        };
        self.counts.responses += 1;
        (self.out)(loc);
        true
    }
}

#[cfg(test)]
mod tests;
