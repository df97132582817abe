"""The LinkTrack decoder from Python: a vendor frame fed in random pieces, encoder round trips,
resynchronisation after garbage and a bad checksum, the counts (docs/linktrack.md)."""

from __future__ import annotations

import random

import pytest

import uwbimu_rs
from uwbimu_rs import LinkTrackDecoder, encode_linktrack_node_frame2

# NodeFrame2 (0x55 0x04, 4 nodes) from nooploop-dev/nlink_parser, test/test_nlink_parser.cpp
# (test NLinkParser.linktrack, the g_msg_nodeframe2 case), with the values that test expects.
VENDOR_NODE_FRAME2 = bytes.fromhex(
    "55 04 ac 00 02 01 ba 66 1d 00 06 09 ff de 0a 00 df ff ff e8 03 00 "
    "fa ff ff 1a 00 00 00 00 00 c0 12 00 00 00 00 00 00 00 27 ac e2 3c "
    "56 ed 1c 3c d2 70 3b bd 32 57 66 3e 3b cb 1b 41 93 70 61 bd 25 b2 "
    "6b 41 a1 22 6c 41 da da 6b 41 6d 23 e9 23 70 dd db f7 30 3f 5f d6 "
    "31 3f ba 81 1e 3e 47 69 e2 bd 91 9b 40 40 c5 23 00 00 40 40 5c d5 "
    "1c 00 00 00 1d 00 6d 13 04 01 00 6b 0c 00 b1 9f a6 66 1d 00 16 45 "
    "01 01 ac 15 00 b4 a1 a6 66 1d 00 d3 01 01 02 48 1a 00 ca 9f a6 66 "
    "1d 00 38 ba 01 03 2b 12 00 c6 a0 a6 66 1d 00 64 40 25"
)

# TagFrame0 (0x55 0x01) from the same file, the g_msg_tagframe0 case.
VENDOR_TAG_FRAME0 = bytes.fromhex(
    "55 01 01 02 8e 0a 00 a5 ff ff e8 03 00 da ff ff fa ff ff 00 00 00 "
    "35 0c 00 a3 15 00 cd 1a 00 4c 12 00 00 00 00 00 00 00 00 00 00 00 "
    "00 00 27 ac e2 3c a2 7d 0b 3c d2 70 3b bd cf a5 80 3e 3e fc 1b 41 "
    "1f a1 26 bd 26 5d 57 41 bd 80 57 41 3f 63 57 41 71 38 f5 25 44 fa "
    "8a 22 28 bf 5a b7 00 be 20 4f 3d bf 1c 0b 52 3d f4 26 3d 40 0c ae "
    "00 00 cb 17 01 00 f0 0b 10 ff 54 13 1d 48 00 00 bc fd"
)


def feed_in_pieces(decoder: LinkTrackDecoder, data: bytes, rng: random.Random) -> list:
    frames = []
    pos = 0
    while pos < len(data):
        n = rng.randint(1, 40)
        frames += decoder.feed(data[pos : pos + n])
        pos += n
    return frames


def test_exported_from_the_package() -> None:
    assert {"LinkTrackDecoder", "encode_linktrack_node_frame2"} <= set(uwbimu_rs.__all__)


def test_vendor_frames_in_random_pieces() -> None:
    rng = random.Random(0)
    decoder = LinkTrackDecoder()
    frames = feed_in_pieces(decoder, VENDOR_NODE_FRAME2 + VENDOR_TAG_FRAME0 + VENDOR_NODE_FRAME2, rng)
    assert [f["kind"] for f in frames] == ["node_frame2", "tag_frame0", "node_frame2"]
    f = frames[0]
    assert (f["id"], f["role"], f["local_time_ms"], f["system_time_ms"]) == (1, 2, 9157, 1926842)
    assert f["position"] == pytest.approx([2.782, -0.033, 1.0], abs=1e-3)
    assert f["gyro"] == pytest.approx([0.02767, 0.00958, -0.04576], abs=1e-5)
    assert f["accel"] == pytest.approx([0.224942, 9.73712, -0.05504], abs=1e-5)
    assert f["quaternion"] == pytest.approx([0.691282, 0.694677, 0.154792, -0.110552], abs=1e-5)
    assert f["voltage"] == pytest.approx(4.973, abs=1e-3)
    assert [n["id"] for n in f["nodes"]] == [0, 1, 2, 3]
    assert [n["range"] for n in f["nodes"]] == pytest.approx([3.179, 5.548, 6.728, 4.651], abs=1e-3)
    assert [n["fp_rssi"] for n in f["nodes"]] == pytest.approx([-88.5, -90.0, -101.0, -99.0], abs=1e-3)
    assert [n["rx_rssi"] for n in f["nodes"]] == pytest.approx([-79.5, -80.5, -79.5, -80.0], abs=1e-3)
    t = frames[1]
    assert (t["id"], t["role"], t["local_time_ms"], t["system_time_ms"]) == (1, 2, 44556, 71627)
    assert t["distances"] == pytest.approx([3.125, 5.539, 6.861, 4.684, 0, 0, 0, 0], abs=1e-3)
    assert t["position"] == pytest.approx([2.702, -0.091, 1.0], abs=1e-3)
    assert "nodes" not in t and "distances" not in f
    counts = decoder.counts
    assert counts["frames"] == 3 and counts["node_frame2"] == 2 and counts["tag_frame0"] == 1
    assert counts["checksum_errors"] == 0 and counts["bytes_skipped"] == 0 and decoder.buffered == 0


def test_encoder_round_trip() -> None:
    nodes = [(0, 3.1794, -88.4, -79.6), (7, 12.0, -101.0, -80.25), (255, 0.0, 0.0, -127.5)]
    data = encode_linktrack_node_frame2(
        4, 123_456, [0.01, -0.02, 0.03], [0.1, 0.2, 9.81], nodes, system_time_ms=99, position=[1.0, 2.0, 0.5]
    )
    assert isinstance(data, bytes) and len(data) == 120 + 13 * len(nodes)
    assert data[-1] == sum(data[:-1]) % 256
    (f,) = LinkTrackDecoder().feed(data)
    assert f["kind"] == "node_frame2"
    assert (f["id"], f["role"], f["local_time_ms"], f["system_time_ms"]) == (4, 2, 123_456, 99)
    assert f["gyro"] == pytest.approx([0.01, -0.02, 0.03], rel=1e-6)
    assert f["accel"] == pytest.approx([0.1, 0.2, 9.81], rel=1e-6)
    assert f["position"] == pytest.approx([1.0, 2.0, 0.5], abs=5e-4)
    assert f["quaternion"] == [1.0, 0.0, 0.0, 0.0] and f["velocity"] == [0.0, 0.0, 0.0]
    assert f["voltage"] == pytest.approx(5.0)
    for n, (anchor, r, fp, rx) in zip(f["nodes"], nodes):
        assert n["id"] == anchor and n["role"] == 1 and n["system_time_ms"] == 99
        assert n["range"] == pytest.approx(r, abs=5e-4)
        assert n["fp_rssi"] == pytest.approx(fp, abs=0.25) and n["rx_rssi"] == pytest.approx(rx, abs=0.25)


def test_too_many_nodes_raise() -> None:
    with pytest.raises(ValueError, match="255"):
        encode_linktrack_node_frame2(1, 0, [0, 0, 0], [0, 0, 9.8], [(1, 1.0, -80.0, -80.0)] * 256)


def test_resync_after_garbage_and_a_bad_checksum() -> None:
    rng = random.Random(1)
    good = encode_linktrack_node_frame2(2, 10, [0, 0, 0], [0, 0, 9.8], [(1, 4.2, -85.0, -80.0)])
    corrupt = bytearray(VENDOR_NODE_FRAME2)
    corrupt[40] ^= 0xFF
    garbage = bytes(rng.randrange(256) for _ in range(500)) + b"\x55\x99\x55"
    decoder = LinkTrackDecoder()
    frames = feed_in_pieces(decoder, garbage + bytes(corrupt) + good + garbage + VENDOR_TAG_FRAME0, rng)
    assert [f["kind"] for f in frames] == ["node_frame2", "tag_frame0"]
    assert frames[0]["nodes"][0]["range"] == pytest.approx(4.2)
    counts = decoder.counts
    assert counts["checksum_errors"] >= 1 and counts["unknown_frames"] >= 2
    assert counts["bytes_received"] == len(good) + len(VENDOR_TAG_FRAME0) + counts["bytes_skipped"] + decoder.buffered


def test_random_bytes_never_raise_and_stay_bounded() -> None:
    rng = random.Random(2)
    decoder = LinkTrackDecoder()
    for _ in range(50):
        decoder.feed(bytes(rng.choice([0x55, 0x04, 0x01, rng.randrange(256)]) for _ in range(rng.randrange(2000))))
        assert decoder.buffered < 3435
    assert "LinkTrackDecoder(" in repr(decoder)
