//! Tests: responses written byte by byte from the API guide's layout, encode → decode round
//! trips, truncation, and the stream decoder on garbage, cut and random input. No vendor test
//! vectors were available.

#![allow(clippy::unwrap_used)]

use super::*;

fn le_i32(v: i32) -> [u8; 4] {
    v.to_le_bytes()
}

/// Tag mode, three anchors, written out by hand from the layout.
fn tag_response() -> Vec<u8> {
    let mut b = vec![0x40, 0x01, 0x00];
    // 0x41, 13: x 1234 mm, y -567 mm, z 890 mm, quality 87.
    b.extend_from_slice(&[0x41, 0x0D]);
    b.extend_from_slice(&[0xD2, 0x04, 0x00, 0x00]);
    b.extend_from_slice(&[0xC9, 0xFD, 0xFF, 0xFF]);
    b.extend_from_slice(&[0x7A, 0x03, 0x00, 0x00]);
    b.push(87);
    // 0x49, 1 + 3 × 20 = 61 = 0x3D, count 3.
    b.extend_from_slice(&[0x49, 0x3D, 0x03]);
    // Anchor 0x1A2B, 2500 mm, qf 100, at (0, 0, 2000) qf 100.
    b.extend_from_slice(&[0x2B, 0x1A, 0xC4, 0x09, 0x00, 0x00, 100]);
    b.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0, 0xD0, 0x07, 0, 0, 100]);
    // Anchor 0x0001, 4321 mm, qf 90, at (5000, -3000, 2100) qf 95.
    b.extend_from_slice(&[0x01, 0x00, 0xE1, 0x10, 0x00, 0x00, 90]);
    b.extend_from_slice(&[0x88, 0x13, 0, 0, 0x48, 0xF4, 0xFF, 0xFF, 0x34, 0x08, 0, 0, 95]);
    // Anchor 0xFFFF, 70000 mm (0x011170), qf 0, at (-1, 1, 0) qf 50.
    b.extend_from_slice(&[0xFF, 0xFF, 0x70, 0x11, 0x01, 0x00, 0]);
    b.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF, 0x01, 0, 0, 0, 0, 0, 0, 0, 50]);
    assert_eq!(b.len(), 3 + 15 + 2 + 61);
    b
}

/// Anchor mode, two entries, written out by hand from the layout.
fn anchor_response() -> Vec<u8> {
    let mut b = vec![0x40, 0x01, 0x00];
    // The anchor's own position: (-2000, 3000, 1500) mm, quality 100.
    b.extend_from_slice(&[0x41, 0x0D]);
    b.extend_from_slice(&le_i32(-2000));
    b.extend_from_slice(&[0xB8, 0x0B, 0x00, 0x00]);
    b.extend_from_slice(&[0xDC, 0x05, 0x00, 0x00]);
    b.push(100);
    // 0x48, 1 + 2 × 13 = 27 = 0x1B, count 2.
    b.extend_from_slice(&[0x48, 0x1B, 0x02]);
    // Address 0xDECA_0123_4567_89AB, 1000 mm, qf 75.
    b.extend_from_slice(&[0xAB, 0x89, 0x67, 0x45, 0x23, 0x01, 0xCA, 0xDE, 0xE8, 0x03, 0x00, 0x00, 75]);
    // Address 0x0000_0000_0000_5C2D, 123456 mm (0x01E240), qf 60.
    b.extend_from_slice(&[0x2D, 0x5C, 0, 0, 0, 0, 0, 0, 0x40, 0xE2, 0x01, 0x00, 60]);
    assert_eq!(b.len(), 3 + 15 + 2 + 27);
    b
}

fn pos(x_m: f64, y_m: f64, z_m: f64, quality: u8) -> DwmPosition {
    DwmPosition { x_m, y_m, z_m, quality }
}

#[test]
fn request_bytes() {
    assert_eq!(LOC_GET_REQUEST, [0x0C, 0x00]);
}

#[test]
fn decodes_hand_made_tag_response() {
    let loc = decode_loc_get(&tag_response()).unwrap();
    assert_eq!(loc.status, 0);
    assert_eq!(loc.position, Some(pos(1.234, -0.567, 0.890, 87)));
    assert_eq!(
        loc.ranges,
        vec![
            DwmRange { anchor_id: 0x1A2B, range_m: 2.5, quality: 100, anchor_position: Some(pos(0.0, 0.0, 2.0, 100)) },
            DwmRange { anchor_id: 1, range_m: 4.321, quality: 90, anchor_position: Some(pos(5.0, -3.0, 2.1, 95)) },
            DwmRange { anchor_id: 0xFFFF, range_m: 70.0, quality: 0, anchor_position: Some(pos(-0.001, 0.001, 0.0, 50)) },
        ]
    );
}

#[test]
fn decodes_hand_made_anchor_response() {
    let loc = decode_loc_get(&anchor_response()).unwrap();
    assert_eq!(loc.position, Some(pos(-2.0, 3.0, 1.5, 100)));
    assert_eq!(
        loc.ranges,
        vec![
            DwmRange { anchor_id: 0xDECA_0123_4567_89AB, range_m: 1.0, quality: 75, anchor_position: None },
            DwmRange { anchor_id: 0x5C2D, range_m: 123.456, quality: 60, anchor_position: None },
        ]
    );
}

#[test]
fn non_zero_return_value_is_kept() {
    assert_eq!(decode_loc_get(&[0x40, 0x01, 0x04]), Err(DwmError::Status(4)));
    let mut s = DwmStream::new();
    let mut out = Vec::new();
    s.push_into(&[0x40, 0x01, 0x02], &mut out);
    assert_eq!(out, vec![DwmLocation { status: 2, position: None, ranges: vec![] }]);
    assert_eq!(s.counts().failed_calls, 1);
    assert_eq!(encode_loc_get(&out[0], true).unwrap(), vec![0x40, 0x01, 0x02]);
}

#[test]
fn rejects_bad_start_and_lengths_and_skips_unknown() {
    assert_eq!(decode_loc_get(&[0x41, 0x01, 0x00]), Err(DwmError::BadStart(0x41, 0x01)));
    // Position of 12 bytes.
    let mut b = vec![0x40, 0x01, 0x00, 0x41, 0x0C];
    b.extend_from_slice(&[0; 12]);
    assert!(matches!(decode_loc_get(&b), Err(DwmError::BadLength { tlv: 0x41, declared: 12, expected: 13 })));
    // Range block claiming 2 anchors in a length for 1.
    let mut b = vec![0x40, 0x01, 0x00, 0x49, 21, 2];
    b.extend_from_slice(&[0; 20]);
    assert!(matches!(decode_loc_get(&b), Err(DwmError::BadLength { tlv: 0x49, declared: 21, expected: 41 })));
    // An unknown TLV between the position and the ranges is skipped.
    let tag = tag_response();
    let mut b = tag[..18].to_vec();
    b.extend_from_slice(&[0x55, 0x03, 1, 2, 3]);
    b.extend_from_slice(&tag[18..]);
    assert_eq!(decode_loc_get(&b).unwrap(), decode_loc_get(&tag).unwrap());
    // Two responses run together.
    let mut b = tag.clone();
    b.extend_from_slice(&tag);
    assert_eq!(decode_loc_get(&b), Err(DwmError::SecondReturnValue(tag.len())));
}

#[test]
fn truncation_at_every_byte_is_an_error_never_a_panic() {
    for full in [tag_response(), anchor_response()] {
        for cut in 0..full.len() {
            let r = decode_loc_get(&full[..cut]);
            // Cutting right after the return value or after the position leaves a shorter,
            // well-formed response.
            if cut == 3 || cut == 18 {
                assert!(r.is_ok(), "cut {cut}: {r:?}");
            } else {
                assert!(matches!(r, Err(DwmError::Truncated { .. })), "cut {cut}: {r:?}");
            }
        }
    }
}

#[test]
fn round_trips_tag_and_anchor() {
    let tag = DwmLocation {
        status: 0,
        position: Some(pos(12.345, -6.789, 0.5, 42)),
        ranges: (0..TAG_MAX_RANGES as u64)
            .map(|i| DwmRange {
                anchor_id: 0x100 + i,
                range_m: (1000 + i * 777) as f64 / 1000.0,
                quality: (i * 7) as u8,
                anchor_position: Some(pos(i as f64, -(i as f64) - 0.25, 2.0, 100)),
            })
            .collect(),
    };
    let bytes = encode_loc_get(&tag, true).unwrap();
    assert_eq!(decode_loc_get(&bytes).unwrap(), tag);
    let anchor = DwmLocation {
        status: 0,
        position: None,
        ranges: (0..ANCHOR_MAX_RANGES as u64)
            .map(|i| DwmRange { anchor_id: u64::MAX - i, range_m: i as f64 * 1.5, quality: 99, anchor_position: None })
            .collect(),
    };
    let bytes = encode_loc_get(&anchor, false).unwrap();
    assert_eq!(decode_loc_get(&bytes).unwrap(), anchor);
    // The encoder writes what was written by hand.
    assert_eq!(encode_loc_get(&decode_loc_get(&tag_response()).unwrap(), true).unwrap(), tag_response());
    assert_eq!(encode_loc_get(&decode_loc_get(&anchor_response()).unwrap(), false).unwrap(), anchor_response());
    // Too many ranges.
    let mut over = anchor.clone();
    over.ranges.push(over.ranges[0]);
    assert_eq!(encode_loc_get(&over, false), Err(DwmError::TooManyRanges { got: 20, max: 19 }));
    assert!(matches!(encode_loc_get(&over, true), Err(DwmError::TooManyRanges { max: 12, .. })));
}

/// A small seeded linear congruential generator (Knuth's MMIX constants).
struct Lcg(u64);

impl Lcg {
    fn next_u32(&mut self) -> u32 {
        self.0 = self.0.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 33) as u32
    }
    fn below(&mut self, n: usize) -> usize {
        self.next_u32() as usize % n
    }
    fn byte(&mut self) -> u8 {
        (self.next_u32() >> 8) as u8
    }
}

fn feed_in_pieces(s: &mut DwmStream, data: &[u8], rng: &mut Lcg) -> Vec<DwmLocation> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < data.len() {
        let n = (1 + rng.below(40)).min(data.len() - at);
        s.push_into(&data[at..at + n], &mut out);
        at += n;
    }
    out
}

#[test]
fn stream_with_garbage_before_and_between() {
    let garbage: &[u8] = &[0x00, 0xFF, 0x41, 0x0D, 0x13, 0x49, 0x37, 0x40, 0x02, 0x99];
    let mut data = garbage.to_vec();
    data.extend_from_slice(&tag_response());
    data.extend_from_slice(garbage);
    data.extend_from_slice(&anchor_response());
    data.extend_from_slice(&[0x40, 0x01, 0x04]);
    data.extend_from_slice(&tag_response());
    data.extend_from_slice(garbage);
    let mut rng = Lcg(11);
    let mut s = DwmStream::new();
    let out = feed_in_pieces(&mut s, &data, &mut rng);
    let tag = decode_loc_get(&tag_response()).unwrap();
    let anchor = decode_loc_get(&anchor_response()).unwrap();
    let failed = DwmLocation { status: 4, position: None, ranges: vec![] };
    assert_eq!(out, vec![tag.clone(), anchor, failed, tag]);
    let c = s.counts();
    assert_eq!(c.responses, 4);
    assert_eq!(c.failed_calls, 1);
    assert_eq!(c.bytes_received, data.len() as u64);
    let response_bytes = (2 * tag_response().len() + anchor_response().len() + 3) as u64;
    assert_eq!(c.bytes_received, response_bytes + c.bytes_skipped + s.buffered_len() as u64);
    // The trailing garbage: all but its last bytes skipped, nothing left waiting for a response.
    assert!(s.buffered_len() <= 1);
}

#[test]
fn stream_resynchronises_after_a_cut_response() {
    let tag = tag_response();
    // Cut inside the range block, then a whole response: the cut one is rejected (its block
    // length disagrees with the bytes that follow) or swallowed; the whole one must come out.
    let mut data = tag[..30].to_vec();
    data.extend_from_slice(&[0x00; 300]);
    data.extend_from_slice(&tag);
    let mut s = DwmStream::new();
    let mut out = Vec::new();
    s.push_into(&data, &mut out);
    assert_eq!(out.last(), Some(&decode_loc_get(&tag).unwrap()));
    // A response cut right after its position ends at the next start.
    let mut data = tag[..18].to_vec();
    data.extend_from_slice(&tag);
    let mut s = DwmStream::new();
    let mut out = Vec::new();
    s.push_into(&data, &mut out);
    let whole = decode_loc_get(&tag).unwrap();
    assert_eq!(out, vec![DwmLocation { status: 0, position: whole.position, ranges: vec![] }, whole]);
    // A position of the wrong length is rejected and counted.
    let mut data = vec![0x40, 0x01, 0x00, 0x41, 0x0C];
    data.extend_from_slice(&[0x11; 12]);
    data.extend_from_slice(&tag);
    let mut s = DwmStream::new();
    let mut out = Vec::new();
    s.push_into(&data, &mut out);
    assert_eq!(out, vec![decode_loc_get(&tag).unwrap()]);
    assert_eq!(s.counts().errors, 1);
}

#[test]
fn random_bytes_never_panic_and_stay_bounded() {
    let mut rng = Lcg(2024);
    let mut s = DwmStream::new();
    let mut out = Vec::new();
    let mut total = 0u64;
    for round in 0..3000 {
        let n = rng.below(600);
        // Bias towards the bytes the decoder looks at, so candidates happen often.
        let chunk: Vec<u8> = (0..n)
            .map(|_| match rng.below(8) {
                0 => 0x40,
                1 => 0x01,
                2 => 0x00,
                3 => [0x41, 0x48, 0x49, 0x0D][rng.below(4)],
                _ => rng.byte(),
            })
            .collect();
        total += n as u64;
        s.push_into(&chunk, &mut out);
        assert!(s.buffered_len() <= MAX_RESPONSE_LEN + 1, "round {round}: {}", s.buffered_len());
        let _ = decode_loc_get(&chunk);
        for cut in 0..chunk.len().min(64) {
            let _ = decode_loc_get(&chunk[cut..]);
        }
    }
    let c = s.counts();
    assert_eq!(c.bytes_received, total);
    assert_eq!(c.responses, out.len() as u64);
    assert!(c.responses > 0);
}
