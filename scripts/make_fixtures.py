#!/usr/bin/env python3
"""Writes small MCAP test files with the PyPI ``mcap`` and ``mcap-ros2-support`` packages.

Each file holds a 4 s recording of a tag circling inside four anchors: ``sensor_msgs/msg/Imu``
(CDR) on ``/imu`` at 50 Hz and UWB ranges at 10 Hz per anchor, plus the anchor positions in the
metadata record ``uwbimu.anchors``. Kinds:

- ``zstd``, ``lz4``, ``none``: chunked and indexed, vendor message ``demo_msgs/msg/UwbArray``
  (``ranges[]`` of ``{uint16 id, float32 range_mm, uint8 valid}``, ranges in millimetres, every
  fifth range ``valid = 0``) on ``/uwb``;
- ``unindexed``: the same, uncompressed, without chunks, indexes or summary;
- ``out_of_order``: as ``zstd`` with the log times of some IMU messages shuffled within 0.1 s
  and one IMU message written 2 s late; stamps taken from the log time (the header stamps are 0);
- ``json``: ranges as ``uwbimu.UwbRange`` JSON on ``/uwb``;
- ``range``: ``sensor_msgs/msg/Range`` (with ``variance``), one topic per anchor, anchor id in
  ``header.frame_id``.

Usage: ``python scripts/make_fixtures.py OUT_DIR [KIND ...]`` (default: every kind).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from mcap.writer import CompressionType, IndexType, Writer
from mcap_ros2._dynamic import serialize_dynamic

KINDS = ["zstd", "lz4", "none", "unindexed", "out_of_order", "json", "range"]
ANCHORS = {"11": (0.0, 0.0, 2.0), "12": (6.0, 0.0, 0.5), "13": (6.0, 5.0, 2.0), "14": (0.0, 5.0, 0.5)}
T0_NS = 1_700_000_000_000_000_000
IMU_HZ, UWB_HZ, DURATION_S = 50, 10, 4.0
SEP = "=" * 80
# The dependency sections every message with a std_msgs/Header carries in its ros2msg schema.
HEADER_DEPS = f"""{SEP}
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
{SEP}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

IMU_MSG = f"""std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
{HEADER_DEPS}{SEP}
MSG: geometry_msgs/Quaternion
float64 x 0
float64 y 0
float64 z 0
float64 w 1
{SEP}
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
"""

UWB_MSG = f"""# A vendor-style UWB message: one entry per anchor.
std_msgs/Header header
UwbRange[] ranges
uint8 MAX_ANCHORS=8
{HEADER_DEPS}{SEP}
MSG: demo_msgs/UwbRange
uint16 id
float32 range_mm
uint8 valid
"""

RANGE_MSG = f"""uint8 ULTRASOUND=0
uint8 INFRARED=1
std_msgs/Header header
uint8 radiation_type
float32 field_of_view
float32 min_range
float32 max_range
float32 range
float32 variance
{HEADER_DEPS}"""

UWB_RANGE_SCHEMA = {
    "title": "uwbimu.UwbRange",
    "type": "object",
    "required": ["timestamp", "anchor_id", "range"],
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "anchor_id": {"type": "string"},
        "range": {"type": "number"},
        "variance": {"type": "number"},
    },
}


def tag_position(t: float) -> tuple[float, float, float]:
    """The tag circles (3, 2.5) with radius 1.5 m at 0.25 rev/s, 1 m high."""
    w = 2 * math.pi * 0.25
    return (3.0 + 1.5 * math.cos(w * t), 2.5 + 1.5 * math.sin(w * t), 1.0)


def imu_sample(k: int) -> tuple[int, list[float], list[float]]:
    """(time ns, specific force, angular rate): a level body turning with the tag (yaw rate w)."""
    t = k / IMU_HZ
    w = 2 * math.pi * 0.25
    centripetal = 1.5 * w * w  # towards the centre = body -x when the body x axis points outwards
    return T0_NS + round(t * 1e9), [-centripetal, 0.0, 9.80665], [0.0, 0.0, w]


def stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def true_range(t: float, anchor: str) -> float:
    p, a = tag_position(t), ANCHORS[anchor]
    return math.dist(p, a)


def write(path: Path, kind: str) -> None:
    compression = {"lz4": CompressionType.LZ4, "none": CompressionType.NONE, "unindexed": CompressionType.NONE}.get(
        kind, CompressionType.ZSTD
    )
    unindexed = kind == "unindexed"
    with open(path, "wb") as f:
        w = Writer(
            f,
            compression=compression,
            chunk_size=4096,
            use_chunking=not unindexed,
            index_types=IndexType.NONE if unindexed else IndexType.ALL,
            use_summary_offsets=not unindexed,
            use_statistics=not unindexed,
            repeat_channels=not unindexed,
            repeat_schemas=not unindexed,
        )
        w.start(profile="" if kind == "json" else "ros2", library="uwbimu_rs make_fixtures")
        imu_schema = w.register_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_MSG.encode())
        imu_ch = w.register_channel("/imu", "cdr", imu_schema)
        imu_enc = serialize_dynamic("sensor_msgs/msg/Imu", IMU_MSG)["sensor_msgs/msg/Imu"]
        w.add_metadata("uwbimu.anchors", {k: json.dumps(list(v)) for k, v in ANCHORS.items()})
        messages: list[tuple[int, int, bytes]] = []  # (log time, channel, data)
        header_zero = kind == "out_of_order"
        n_imu = int(DURATION_S * IMU_HZ)
        for k in range(n_imu):
            ns, f_b, w_b = imu_sample(k)
            msg = {
                "header": {"stamp": stamp(0 if header_zero else ns), "frame_id": "imu_link"},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": [-1.0] + [0.0] * 8,
                "angular_velocity": dict(zip("xyz", w_b)),
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": dict(zip("xyz", f_b)),
                "linear_acceleration_covariance": [0.0] * 9,
            }
            messages.append((ns, imu_ch, imu_enc(msg)))
        n_uwb = int(DURATION_S * UWB_HZ)
        ids = list(ANCHORS)
        if kind == "json":
            schema = w.register_schema("uwbimu.UwbRange", "jsonschema", json.dumps(UWB_RANGE_SCHEMA).encode())
            ch = w.register_channel("/uwb", "json", schema)
            for k in range(n_uwb):
                t = k / UWB_HZ + 0.005
                ns = T0_NS + round(t * 1e9)
                for a in ids:
                    body = {"timestamp": {"sec": ns // 10**9, "nsec": ns % 10**9}, "anchor_id": a, "range": true_range(t, a), "variance": 0.01}
                    messages.append((ns, ch, json.dumps(body).encode()))
        elif kind == "range":
            schema = w.register_schema("sensor_msgs/msg/Range", "ros2msg", RANGE_MSG.encode())
            enc = serialize_dynamic("sensor_msgs/msg/Range", RANGE_MSG)["sensor_msgs/msg/Range"]
            chans = {a: w.register_channel(f"/uwb/{a}", "cdr", schema) for a in ids}
            for k in range(n_uwb):
                t = k / UWB_HZ + 0.005
                ns = T0_NS + round(t * 1e9)
                for a in ids:
                    msg = {
                        "header": {"stamp": stamp(ns), "frame_id": a},
                        "radiation_type": 2,
                        "field_of_view": 0.0,
                        "min_range": 0.0,
                        "max_range": 100.0,
                        "range": true_range(t, a),
                        "variance": 0.01,
                    }
                    messages.append((ns, chans[a], enc(msg)))
        else:
            schema = w.register_schema("demo_msgs/msg/UwbArray", "ros2msg", UWB_MSG.encode())
            enc = serialize_dynamic("demo_msgs/msg/UwbArray", UWB_MSG)["demo_msgs/msg/UwbArray"]
            ch = w.register_channel("/uwb", "cdr", schema)
            count = 0
            for k in range(n_uwb):
                t = k / UWB_HZ + 0.005
                ns = T0_NS + round(t * 1e9)
                entries = []
                for a in ids:
                    count += 1
                    entries.append({"id": int(a), "range_mm": true_range(t, a) * 1000.0, "valid": 0 if count % 5 == 0 else 1})
                msg = {"header": {"stamp": stamp(0 if header_zero else ns), "frame_id": "uwb"}, "ranges": entries}
                messages.append((ns, ch, enc(msg)))
        messages.sort(key=lambda m: m[0])
        if kind == "out_of_order":
            # Swap neighbouring IMU messages (20 ms apart, inside the window) and send one 2 s late.
            imu_idx = [i for i, m in enumerate(messages) if m[1] == imu_ch]
            order = list(range(len(messages)))
            for j in range(10, 60, 10):
                a, b = imu_idx[j], imu_idx[j + 1]
                order[a], order[b] = order[b], order[a]
            late = imu_idx[5]
            order.remove(late)
            insert_at = next(i for i, m in enumerate(order) if messages[m][0] > messages[late][0] + 2_000_000_000)
            order.insert(insert_at, late)
            messages = [messages[i] for i in order]
        for seq, (ns, ch, data) in enumerate(messages):
            w.add_message(ch, log_time=ns, data=data, publish_time=ns, sequence=seq)
        w.finish()


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    for kind in argv[1:] or KINDS:
        if kind not in KINDS:
            print(f"unknown kind {kind!r}; allowed: {', '.join(KINDS)}", file=sys.stderr)
            return 2
        write(out / f"{kind}.mcap", kind)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
