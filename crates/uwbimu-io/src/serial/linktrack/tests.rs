//! Tests: the vendor's own frames, encode → decode round trips, and the stream decoder on cut,
//! corrupt and random input.

#![allow(clippy::unwrap_used)]

use super::*;

/// `NodeFrame2` (0x55 0x04, 4 nodes) from nooploop-dev/nlink_parser, `test/test_nlink_parser.cpp`
/// (test `NLinkParser.linktrack`, the `g_msg_nodeframe2` case).
const VENDOR_NODE_FRAME2: &str = "55 04 ac 00 02 01 ba 66 1d 00 06 09 ff de 0a 00 df ff ff e8 03 00 \
    fa ff ff 1a 00 00 00 00 00 c0 12 00 00 00 00 00 00 00 27 ac e2 3c \
    56 ed 1c 3c d2 70 3b bd 32 57 66 3e 3b cb 1b 41 93 70 61 bd 25 b2 \
    6b 41 a1 22 6c 41 da da 6b 41 6d 23 e9 23 70 dd db f7 30 3f 5f d6 \
    31 3f ba 81 1e 3e 47 69 e2 bd 91 9b 40 40 c5 23 00 00 40 40 5c d5 \
    1c 00 00 00 1d 00 6d 13 04 01 00 6b 0c 00 b1 9f a6 66 1d 00 16 45 \
    01 01 ac 15 00 b4 a1 a6 66 1d 00 d3 01 01 02 48 1a 00 ca 9f a6 66 \
    1d 00 38 ba 01 03 2b 12 00 c6 a0 a6 66 1d 00 64 40 25";

/// `TagFrame0` (0x55 0x01) from nooploop-dev/nlink_parser, `test/test_nlink_parser.cpp`
/// (test `NLinkParser.linktrack`, the `g_msg_tagframe0` case).
const VENDOR_TAG_FRAME0: &str = "55 01 01 02 8e 0a 00 a5 ff ff e8 03 00 da ff ff fa ff ff 00 00 00 \
    35 0c 00 a3 15 00 cd 1a 00 4c 12 00 00 00 00 00 00 00 00 00 00 00 \
    00 00 27 ac e2 3c a2 7d 0b 3c d2 70 3b bd cf a5 80 3e 3e fc 1b 41 \
    1f a1 26 bd 26 5d 57 41 bd 80 57 41 3f 63 57 41 71 38 f5 25 44 fa \
    8a 22 28 bf 5a b7 00 be 20 4f 3d bf 1c 0b 52 3d f4 26 3d 40 0c ae \
    00 00 cb 17 01 00 f0 0b 10 ff 54 13 1d 48 00 00 bc fd";

fn hex(s: &str) -> Vec<u8> {
    s.split_whitespace().map(|b| u8::from_str_radix(b, 16).unwrap()).collect()
}

fn assert_near(got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() <= tol, "got {got:?}, want {want:?} (±{tol})");
    }
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

fn node_frame(id: u8, ranges: &[(u8, f64, f64, f64)]) -> NodeFrame2 {
    NodeFrame2 {
        role: 2,
        id,
        local_time_ms: 9157,
        system_time_ms: 1_926_842,
        eop_m: [0.06, 0.09, 2.55],
        position_m: [2.782, -0.033, 1.0],
        velocity_mps: [-0.0006, 0.0026, 0.0],
        gyro_rad_s: [0.0277, 0.0096, -0.0458],
        accel_mps2: [0.2249, 9.7371, -0.0550],
        angle_deg: [90.69, 91.93, -88.48],
        quaternion_wxyz: [0.6913, 0.6947, 0.1548, -0.1106],
        voltage_v: 4.973,
        nodes: ranges
            .iter()
            .map(|&(id, range_m, fp, rx)| NodeRange2 {
                role: 1,
                id,
                range_m,
                fp_rssi_dbm: fp,
                rx_rssi_dbm: rx,
                system_time_ms: 1_926_822,
            })
            .collect(),
    }
}

fn tag_frame(id: u8) -> TagFrame0 {
    TagFrame0 {
        role: 2,
        id,
        position_m: [2.702, -0.091, 1.0],
        velocity_mps: [-0.0038, -0.0006, 0.0],
        distances_m: [3.125, 5.539, 6.861, 4.684, 0.0, 0.0, 0.0, 0.0],
        gyro_rad_s: [0.0277, 0.0085, -0.0458],
        accel_mps2: [0.2513, 9.7491, -0.0407],
        angle_deg: [144.49, 97.17, -14.68],
        quaternion_wxyz: [-0.6568, -0.1257, -0.7395, 0.0513],
        local_time_ms: 44556,
        system_time_ms: 71627,
        eop_m: [0.11, 0.16, 2.55],
        voltage_v: 4.948,
    }
}

// ---- The vendor's frames, with the values nlink_parser's test expects ----

#[test]
fn linktrack_vendor_node_frame2() {
    let bytes = hex(VENDOR_NODE_FRAME2);
    assert_eq!(bytes.len(), 172);
    let f = decode_node_frame2(&bytes).unwrap();
    assert_eq!((f.role, f.id), (2, 1));
    assert_near(&f.position_m, &[2.782, -0.033, 1.0], 1e-3);
    assert_near(&f.velocity_mps, &[-0.0006, 0.0026, 0.0], 1e-4);
    assert_near(&f.gyro_rad_s, &[0.02767, 0.00958, -0.04576], 1e-5);
    assert_near(&f.accel_mps2, &[0.224942, 9.73712, -0.05504], 1e-5);
    assert_near(&f.angle_deg, &[90.69, 91.93, -88.48], 0.01);
    assert_near(&f.quaternion_wxyz, &[0.691282, 0.694677, 0.154792, -0.110552], 1e-5);
    assert_near(&f.eop_m, &[0.06, 0.09, 2.55], 0.01);
    assert_eq!(f.local_time_ms, 9157);
    assert_eq!(f.system_time_ms, 1_926_842);
    assert_near(&[f.voltage_v], &[4.973], 1e-3);
    let ids: Vec<u8> = f.nodes.iter().map(|n| n.id).collect();
    assert_eq!(ids, [0, 1, 2, 3]);
    assert!(f.nodes.iter().all(|n| n.role == 1));
    let got = |g: fn(&NodeRange2) -> f64| f.nodes.iter().map(g).collect::<Vec<_>>();
    assert_near(&got(|n| n.range_m), &[3.179, 5.548, 6.728, 4.651], 1e-3);
    assert_near(&got(|n| n.fp_rssi_dbm), &[-88.5, -90.0, -101.0, -99.0], 1e-3);
    assert_near(&got(|n| n.rx_rssi_dbm), &[-79.5, -80.5, -79.5, -80.0], 1e-3);
    assert!(f.nodes.iter().all(|n| n.system_time_ms == 1_926_822));
    assert_eq!(decode_frame(&bytes).unwrap(), LinkTrackFrame::NodeFrame2(f));
}

#[test]
fn linktrack_vendor_tag_frame0() {
    let bytes = hex(VENDOR_TAG_FRAME0);
    assert_eq!(bytes.len(), TAG_FRAME0_LEN);
    let f = decode_tag_frame0(&bytes).unwrap();
    assert_eq!((f.role, f.id), (2, 1));
    assert_near(&f.position_m, &[2.702, -0.091, 1.0], 1e-3);
    assert_near(&f.velocity_mps, &[-0.0038, -0.0006, 0.0], 1e-4);
    assert_near(&f.distances_m, &[3.125, 5.539, 6.861, 4.684, 0.0, 0.0, 0.0, 0.0], 1e-3);
    assert_near(&f.gyro_rad_s, &[0.02767, 0.008514, -0.045762], 1e-5);
    assert_near(&f.accel_mps2, &[0.251265, 9.74908, -0.040681], 1e-5);
    assert_near(&f.angle_deg, &[144.49, 97.17, -14.68], 0.01);
    assert_near(&f.quaternion_wxyz, &[-0.656777, -0.125699, -0.739489, 0.0512801], 1e-5);
    assert_near(&f.eop_m, &[0.11, 0.16, 2.55], 0.01);
    assert_eq!(f.local_time_ms, 44556);
    assert_eq!(f.system_time_ms, 71627);
    assert_near(&[f.voltage_v], &[4.948], 1e-3);
    assert_eq!(decode_frame(&bytes).unwrap(), LinkTrackFrame::TagFrame0(f));
}

#[test]
fn linktrack_vendor_frames_reencode_to_their_fields() {
    // The encoder writes zeros in the reserved bytes, so the vendor frames come back equal
    // outside them: every decoded field, the length and the checksum of the new bytes.
    let nf2 = decode_node_frame2(&hex(VENDOR_NODE_FRAME2)).unwrap();
    let again = encode_node_frame2(&nf2).unwrap();
    assert_eq!(again.len(), 172);
    assert_eq!(decode_node_frame2(&again).unwrap(), nf2);
    let tf0 = decode_tag_frame0(&hex(VENDOR_TAG_FRAME0)).unwrap();
    assert_eq!(decode_tag_frame0(&encode_tag_frame0(&tf0)).unwrap(), tf0);
}

#[test]
fn linktrack_rejects_malformed_frames() {
    let good = hex(VENDOR_NODE_FRAME2);
    let mut bad_sum = good.clone();
    bad_sum[50] ^= 0x10;
    assert!(matches!(decode_frame(&bad_sum), Err(LinkTrackError::Checksum { .. })));
    assert!(matches!(decode_frame(&good[..100]), Err(LinkTrackError::TooShort { .. })));
    assert!(matches!(decode_frame(&good[..150]), Err(LinkTrackError::BadLength { .. })));
    let mut bad_count = good.clone();
    bad_count[118] = 5;
    assert!(matches!(decode_frame(&bad_count), Err(LinkTrackError::BadLength { declared: 172, expected: 185 })));
    let mut unknown = good.clone();
    unknown[1] = 0x02;
    assert_eq!(decode_frame(&unknown), Err(LinkTrackError::UnknownFunction(0x02)));
    assert_eq!(decode_frame(&[0x54, 0x04, 0, 0]), Err(LinkTrackError::BadHeader(0x54)));
    assert!(decode_frame(&[]).is_err());
    assert!(decode_frame(&[0x55]).is_err());
    let tag = hex(VENDOR_TAG_FRAME0);
    assert!(matches!(decode_tag_frame0(&tag[..127]), Err(LinkTrackError::TooShort { .. })));
    assert!(matches!(decode_tag_frame0(&[tag.clone(), vec![0]].concat()), Err(LinkTrackError::BadLength { .. })));
    assert_eq!(checksum(&tag[..127]), tag[127]);
}

// ---- Round trips on synthetic frames ----

#[test]
fn linktrack_node_frame2_round_trip_quantises_to_the_wire_steps() {
    let mut rng = Lcg(7);
    for n in [0usize, 1, 4, 16, 255] {
        let ranges: Vec<_> = (0..n)
            .map(|i| {
                let r = f64::from(rng.next_u32() % 100_000_000) * 1e-6; // 0 .. 100 m, µm steps
                let fp = -f64::from(rng.next_u32() % 1_280) * 0.1; // 0 .. −127.9 dBm
                let rx = -f64::from(rng.next_u32() % 1_275) * 0.1;
                (i as u8, r, fp, rx)
            })
            .collect();
        let frame = node_frame(3, &ranges);
        let bytes = encode_node_frame2(&frame).unwrap();
        assert_eq!(bytes.len(), 120 + 13 * n);
        assert_eq!(usize::from(u16::from_le_bytes([bytes[2], bytes[3]])), bytes.len());
        assert_eq!(checksum(&bytes[..bytes.len() - 1]), bytes[bytes.len() - 1]);
        let back = decode_node_frame2(&bytes).unwrap();
        assert_eq!(back.nodes.len(), n);
        for (b, f) in back.nodes.iter().zip(&frame.nodes) {
            assert_eq!((b.role, b.id, b.system_time_ms), (f.role, f.id, f.system_time_ms));
            assert!((b.range_m - f.range_m).abs() <= 0.0005 + 1e-12, "{b:?} {f:?}");
            assert!((b.fp_rssi_dbm - f.fp_rssi_dbm.max(-127.5)).abs() <= 0.25 + 1e-12, "{b:?} {f:?}");
            assert!((b.rx_rssi_dbm - f.rx_rssi_dbm.max(-127.5)).abs() <= 0.25 + 1e-12, "{b:?} {f:?}");
        }
        assert_eq!((back.role, back.id, back.local_time_ms, back.system_time_ms), (2, 3, 9157, 1_926_842));
        assert_near(&back.position_m, &frame.position_m, 0.0005);
        assert_near(&back.velocity_mps, &frame.velocity_mps, 0.00005);
        assert_near(&back.gyro_rad_s, &frame.gyro_rad_s, 1e-7);
        assert_near(&back.accel_mps2, &frame.accel_mps2, 1e-6);
        assert_near(&back.quaternion_wxyz, &frame.quaternion_wxyz, 1e-7);
        assert_near(&back.angle_deg, &frame.angle_deg, 0.005);
        assert_near(&back.eop_m, &frame.eop_m, 0.005);
        assert_near(&[back.voltage_v], &[frame.voltage_v], 0.0005);
        // Decoded values lie on the wire's grid, so they encode to the same bytes.
        assert_eq!(encode_node_frame2(&back).unwrap(), bytes);
    }
    let too_many = node_frame(1, &vec![(0, 1.0, -80.0, -80.0); 256]);
    assert_eq!(encode_node_frame2(&too_many), Err(LinkTrackError::TooManyNodes(256)));
}

#[test]
fn linktrack_tag_frame0_round_trip_quantises_to_the_wire_steps() {
    let frame = TagFrame0 { distances_m: [0.0004, 1.2345, 8388.607, 0.0, 12.0, 3.0015, 7.7777, 99.9999], ..tag_frame(9) };
    let bytes = encode_tag_frame0(&frame);
    assert_eq!(bytes.len(), TAG_FRAME0_LEN);
    let back = decode_tag_frame0(&bytes).unwrap();
    assert_eq!((back.role, back.id, back.local_time_ms, back.system_time_ms), (2, 9, 44556, 71627));
    assert_near(&back.distances_m, &frame.distances_m, 0.0005 + 1e-9);
    assert_near(&back.position_m, &frame.position_m, 0.0005);
    assert_near(&back.velocity_mps, &frame.velocity_mps, 0.00005);
    assert_near(&back.gyro_rad_s, &frame.gyro_rad_s, 1e-7);
    assert_near(&back.accel_mps2, &frame.accel_mps2, 1e-6);
    assert_near(&back.quaternion_wxyz, &frame.quaternion_wxyz, 1e-7);
    assert_near(&back.angle_deg, &frame.angle_deg, 0.005);
    assert_near(&back.eop_m, &frame.eop_m, 0.005);
    assert_eq!(encode_tag_frame0(&back), bytes);
}

#[test]
fn linktrack_encoders_saturate_out_of_range_values() {
    let mut frame = node_frame(1, &[(0, 1e9, -500.0, 10.0), (1, -1e9, f64::NAN, -60.0)]);
    frame.voltage_v = -1.0;
    frame.angle_deg = [1e9, -1e9, f64::NAN];
    frame.eop_m = [3.0, -1.0, f64::NAN];
    let back = decode_node_frame2(&encode_node_frame2(&frame).unwrap()).unwrap();
    assert_near(&[back.nodes[0].range_m, back.nodes[1].range_m], &[8388.607, -8388.608], 1e-9);
    assert_near(&[back.nodes[0].fp_rssi_dbm, back.nodes[0].rx_rssi_dbm], &[-127.5, 0.0], 1e-9);
    assert_near(&[back.nodes[1].fp_rssi_dbm, back.nodes[1].rx_rssi_dbm], &[0.0, -60.0], 1e-9);
    assert_near(&back.angle_deg, &[327.67, -327.68, 0.0], 1e-9);
    assert_near(&back.eop_m, &[2.55, 0.0, 0.0], 1e-9);
    assert_near(&[back.voltage_v], &[0.0], 1e-9);
}

// ---- The stream decoder ----

/// Frames pushed to `stream` piece by piece, all the frames out.
fn feed(stream: &mut LinkTrackStream, pieces: &[&[u8]]) -> Vec<LinkTrackFrame> {
    let mut out = Vec::new();
    for p in pieces {
        stream.push_into(p, &mut out);
    }
    out
}

fn mixed_stream() -> (Vec<u8>, Vec<LinkTrackFrame>) {
    let frames = vec![
        decode_frame(&hex(VENDOR_NODE_FRAME2)).unwrap(),
        decode_frame(&hex(VENDOR_TAG_FRAME0)).unwrap(),
        LinkTrackFrame::NodeFrame2(
            decode_node_frame2(&encode_node_frame2(&node_frame(5, &[(7, 2.5, -85.0, -80.0)])).unwrap()).unwrap(),
        ),
    ];
    let bytes =
        [hex(VENDOR_NODE_FRAME2), hex(VENDOR_TAG_FRAME0), encode_node_frame2(&node_frame(5, &[(7, 2.5, -85.0, -80.0)])).unwrap()]
            .concat();
    (bytes, frames)
}

#[test]
fn linktrack_stream_decodes_frames_split_at_every_byte() {
    let (bytes, frames) = mixed_stream();
    for cut in 0..=bytes.len() {
        let mut s = LinkTrackStream::new();
        let out = feed(&mut s, &[&bytes[..cut], &bytes[cut..]]);
        assert_eq!(out, frames, "cut at {cut}");
        assert_eq!(s.buffered_len(), 0);
        assert_eq!(s.counts().bytes_skipped, 0);
    }
    let mut s = LinkTrackStream::new();
    let singles: Vec<&[u8]> = bytes.chunks(1).collect();
    assert_eq!(feed(&mut s, &singles), frames);
    let c = s.counts();
    assert_eq!((c.frames, c.node_frame2, c.tag_frame0, c.checksum_errors, c.bytes_received), (3, 2, 1, 0, bytes.len() as u64));
}

#[test]
fn linktrack_stream_skips_garbage_before_and_between_frames() {
    let (_, frames) = mixed_stream();
    let garbage: &[u8] = &[0x00, 0x55, 0x55, 0x04, 0xff, 0x13, 0x55, 0x01, 0x02, 0x55, 0x99, 0xaa];
    let nf2 = hex(VENDOR_NODE_FRAME2);
    let tf0 = hex(VENDOR_TAG_FRAME0);
    let third = encode_node_frame2(&node_frame(5, &[(7, 2.5, -85.0, -80.0)])).unwrap();
    let bytes = [garbage, &nf2, garbage, &tf0, &garbage[..3], &third].concat();
    let mut s = LinkTrackStream::new();
    assert_eq!(feed(&mut s, &[&bytes]), frames);
    let c = s.counts();
    assert_eq!(c.frames, 3);
    assert_eq!(c.bytes_skipped, (2 * garbage.len() + 3) as u64);
    assert_eq!(s.buffered_len(), 0);
    // The `0x55 0x99` pairs are unknown marks; `0x55 0x04 0xff 0x13` a length out of range.
    assert!(c.unknown_frames >= 2 && c.bad_lengths >= 1, "{c:?}");
}

#[test]
fn linktrack_stream_loses_a_cut_frame_and_decodes_the_next() {
    let nf2 = hex(VENDOR_NODE_FRAME2);
    let tf0 = hex(VENDOR_TAG_FRAME0);
    for cut in [1usize, 2, 4, 50, 118, 119, 171] {
        for next in [&nf2, &tf0] {
            let bytes = [&nf2[..cut], next.as_slice()].concat();
            let mut s = LinkTrackStream::new();
            let mut out = feed(&mut s, &[&bytes]);
            // Whatever the cut frame swallowed, the next frame is found once more bytes come.
            out.extend(feed(&mut s, &[&nf2]));
            let want = decode_frame(next).unwrap();
            assert!(out.len() >= 2 && out[0] == want, "cut {cut}: {out:?}");
            assert_eq!(out[out.len() - 1], decode_frame(&nf2).unwrap());
        }
    }
}

#[test]
fn linktrack_stream_counts_a_bad_checksum_and_decodes_the_next_frame() {
    let mut corrupt = hex(VENDOR_NODE_FRAME2);
    corrupt[60] ^= 0x01;
    let tf0 = hex(VENDOR_TAG_FRAME0);
    let mut s = LinkTrackStream::new();
    let out = feed(&mut s, &[&[corrupt.as_slice(), &tf0].concat()]);
    assert_eq!(out, vec![decode_frame(&tf0).unwrap()]);
    let c = s.counts();
    assert_eq!((c.frames, c.checksum_errors, c.bytes_skipped), (1, 1, corrupt.len() as u64));
    assert_eq!(c.bytes_received, c.bytes_skipped + tf0.len() as u64);
}

#[test]
fn linktrack_stream_survives_random_bytes_with_a_bounded_buffer() {
    let (frames_bytes, _) = mixed_stream();
    let mut rng = Lcg(2024);
    let mut s = LinkTrackStream::new();
    let mut decoded_bytes = 0u64;
    let mut max_buffer = 0;
    for round in 0..400 {
        // Random bytes, biased towards 0x55 and the known marks so candidates are frequent.
        let len = rng.below(3000);
        let mut junk: Vec<u8> = (0..len)
            .map(|_| match rng.below(8) {
                0 => 0x55,
                1 => [0x01, 0x04][rng.below(2)],
                _ => rng.byte(),
            })
            .collect();
        if round % 10 == 0 {
            junk.extend_from_slice(&frames_bytes);
        }
        let mut pos = 0;
        while pos < junk.len() {
            let n = 1 + rng.below(700);
            let piece = &junk[pos..(pos + n).min(junk.len())];
            s.push(piece, &mut |f| {
                decoded_bytes += match f {
                    LinkTrackFrame::NodeFrame2(f) => (120 + 13 * f.nodes.len()) as u64,
                    LinkTrackFrame::TagFrame0(_) => TAG_FRAME0_LEN as u64,
                }
            });
            pos += piece.len();
            max_buffer = max_buffer.max(s.buffered_len());
        }
    }
    assert!(max_buffer < NODE_FRAME2_MAX_LEN, "buffer grew to {max_buffer}");
    let c = s.counts();
    assert!(c.frames >= 3, "{c:?}");
    assert!(c.checksum_errors > 0 && c.bad_lengths > 0 && c.unknown_frames > 0, "{c:?}");
    assert_eq!(c.bytes_received, decoded_bytes + c.bytes_skipped + s.buffered_len() as u64, "{c:?}");
    // A single huge push of garbage is handled in bounded pieces too.
    let huge: Vec<u8> = (0..200_000).map(|_| rng.byte()).collect();
    s.push(&huge, &mut |_| {});
    assert!(s.buffered_len() < NODE_FRAME2_MAX_LEN);
}
