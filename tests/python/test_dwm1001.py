"""The DWM1001 ``dwm_loc_get`` decoder from Python: a hand-made response and encoded ones fed in
random pieces, encoder round trips, resynchronisation after garbage, a failed call, the counts
(docs/dwm1001.md)."""

from __future__ import annotations

import random
import struct

import pytest

import uwbimu_rs
from uwbimu_rs import DwmDecoder, encode_dwm_loc_get

# Tag mode, two anchors, written from the layout in the API guide (not with our encoder).
HAND_MADE_TAG = (
    bytes([0x40, 0x01, 0x00])
    + bytes([0x41, 0x0D])
    + struct.pack("<iiiB", 1500, -250, 1000, 77)
    + bytes([0x49, 1 + 2 * 20, 2])
    + struct.pack("<HIB", 0x0A01, 3210, 98)
    + struct.pack("<iiiB", 0, 0, 2500, 100)
    + struct.pack("<HIB", 0x0A02, 4500, 85)
    + struct.pack("<iiiB", 6000, -1000, 2400, 90)
)


def feed_in_pieces(decoder: DwmDecoder, data: bytes, rng: random.Random) -> list:
    out = []
    pos = 0
    while pos < len(data):
        n = rng.randint(1, 40)
        out += decoder.feed(data[pos : pos + n])
        pos += n
    return out


def test_exported_from_the_package() -> None:
    assert {"DwmDecoder", "encode_dwm_loc_get"} <= set(uwbimu_rs.__all__)


def test_hand_made_response_in_random_pieces() -> None:
    rng = random.Random(0)
    decoder = DwmDecoder()
    out = feed_in_pieces(decoder, HAND_MADE_TAG * 3, rng)
    assert len(out) == 3
    r = out[0]
    assert r["status"] == 0
    assert r["position"] == pytest.approx([1.5, -0.25, 1.0])
    assert r["position_quality"] == 77
    assert [a["anchor_id"] for a in r["ranges"]] == [0x0A01, 0x0A02]
    assert [a["range"] for a in r["ranges"]] == pytest.approx([3.21, 4.5])
    assert [a["quality"] for a in r["ranges"]] == [98, 85]
    assert r["ranges"][1]["anchor_position"] == pytest.approx([6.0, -1.0, 2.4])
    counts = decoder.counts
    assert counts["responses"] == 3 and counts["errors"] == 0 and counts["bytes_skipped"] == 0
    assert decoder.buffered == 0


def test_encoder_round_trip_tag_and_anchor() -> None:
    ranges = [(0x1234, 2.3456, 90, (1.0, 2.0, 3.0, 100)), (7, 0.0004, 10, None)]
    data = encode_dwm_loc_get((0.1234, -5.0, 1.25, 60), ranges)
    assert data[:3] == b"\x40\x01\x00" and data[3] == 0x41 and data[18] == 0x49
    (r,) = DwmDecoder().feed(data)
    assert r["position"] == pytest.approx([0.123, -5.0, 1.25]) and r["position_quality"] == 60
    assert [a["range"] for a in r["ranges"]] == pytest.approx([2.346, 0.0])
    assert r["ranges"][0]["anchor_position"] == pytest.approx([1.0, 2.0, 3.0])
    assert r["ranges"][1]["anchor_position"] == [0.0, 0.0, 0.0]
    data = encode_dwm_loc_get(None, [(0xDECA000000001234, 12.5, 70, None)], tag=False)
    assert data[3] == 0x48
    (r,) = DwmDecoder().feed(data)
    assert r["position"] is None and r["position_quality"] is None
    assert r["ranges"] == [{"anchor_id": 0xDECA000000001234, "range": 12.5, "quality": 70, "anchor_position": None}]


def test_too_many_ranges_raise() -> None:
    with pytest.raises(ValueError, match="12"):
        encode_dwm_loc_get(None, [(1, 1.0, 100, None)] * 13)


def test_garbage_and_a_failed_call() -> None:
    rng = random.Random(1)
    good = encode_dwm_loc_get((1.0, 2.0, 0.0, 50), [(1, 3.0, 100, (0.0, 0.0, 2.0, 100))])
    garbage = bytes(rng.choice([0x41, 0x49, 0x0D, rng.randrange(256)]) for _ in range(300)).replace(b"\x40", b"")
    decoder = DwmDecoder()
    out = feed_in_pieces(decoder, garbage + good + garbage + b"\x40\x01\x04" + HAND_MADE_TAG + garbage, rng)
    assert [r["status"] for r in out] == [0, 4, 0]
    assert out[0]["ranges"][0]["range"] == pytest.approx(3.0)
    assert out[1]["position"] is None and out[1]["ranges"] == []
    counts = decoder.counts
    assert counts["failed_calls"] == 1 and counts["responses"] == 3
    sizes = len(good) + 3 + len(HAND_MADE_TAG)
    assert counts["bytes_received"] == sizes + counts["bytes_skipped"] + decoder.buffered


def test_random_bytes_never_raise_and_stay_bounded() -> None:
    rng = random.Random(2)
    decoder = DwmDecoder()
    for _ in range(50):
        n = rng.randrange(2000)
        decoder.feed(bytes(rng.choice([0x40, 0x01, 0x00, 0x49, rng.randrange(256)]) for _ in range(n)))
        assert decoder.buffered <= 533
    assert "DwmDecoder(" in repr(decoder)
